"""LAMMPS' plastic ``mdr`` law fitted to a table's e_n over speed: its yield stress.

The mdr normal model (Zunker & Kamrin, J. Mech. Phys. Solids 183 (2024) 105492) is an elastic -
perfectly plastic contact: below the yield stress Y the Hertz contact, above it a plastic zone
that keeps the energy, so e_n falls with the impact speed as a plastic table's does (Thornton's
e ~ v^(-1/4) well above yield), where the Hertz-dashpot law has one e_n at every speed.

Its elastic part is the scene's materials: LAMMPS' mdr wall (``fix wall/gran/region``, a rigid
plane) uses E / (1 - nu^2) as the contact modulus (measured: an elastic 15 mm steel ball's F_max
at 3 m/s is the Hertz value of that modulus within 0.02 %), so E = (1 - nu^2) E*_materials.
No surface energy (no adhesion), psi_b = 0.5 (LAMMPS' example; the bulk response it triggers needs
far larger deformations than an impact's). Damping class 1, eta_n = eta_n0 (m k_mdr)^(1/2): a
table's e_n stays below 1 below yield (the block's vibration keeps energy), which plasticity alone
cannot give, so eta_n0 is fitted with Y.

The fit: (Y, eta_n0) minimise the largest |e_n,mdr(v_n) - e_n,table| over the table's normal-
incidence e_n (its 0 deg column, where it has two speeds or more; else every point) and check
points between its speeds (:func:`check_points`: BETWEEN_POINTS a gap, the table's e_n interpolated
in ln v_n; the root mean square at the points breaks ties), e_n,mdr from LAMMPS itself (a ball at
each normal speed v_n against the plane, every pair of a pass in one LAMMPS run): a grid of 13
values of ln Y over [1e8, 1e11] Pa x 6 of eta_n0, then seven passes of 9 x 9 over +-2 steps of the
previous grid around its best (last step Y x 1.005, eta_n0 0.001; the good pairs lie on a ridge,
eta_n0 rising with Y, that +-1 step loses). A normal law's e_n at an oblique impact is its normal
impact's at v_n = v cos a (LAMMPS' mdr with the Mindlin tangential model: to 1e-4), where a
finite-element table's is not: its oblique points are run at the fitted law and reported apart
(MdrLaw.worst_oblique), not fitted. mdr's e_n is the damping's alone below its yield speed V_y, one
value e_0 at every speed, and drops there by ~0.06 at once (then rises ~0.01 before it falls), so
the residual is not smooth in Y and a fit puts that drop where nothing checks it, between the
table's points or between check points; so the score also holds e_0 against the table's e_n at
the first check point past the drop (:func:`largest_difference`), and the fitted law's reported
difference comes from one more run at VERIFY_POINTS speeds a gap.

On the plastic rig's table (0.5, 2, 6 m/s x 0, 40 deg): Y 0.922 GPa, eta_n0 0.194, e_n within
0.0465 at normal incidence over 0.5-6 m/s (rms 0.039 at the points), the 40 deg points within
0.029; ~160 s. mdr cannot follow it to 0.03: below V_y its e_n is one value where the table's falls,
and above V_y it falls faster (v^(-0.24) against v^(-0.14)); no (Y, eta_n0) of a 41 x 33 map does
better than 0.044. The damping cannot help: LAMMPS takes no damping but its mdr class with mdr
(velocity, viscoelastic, tsuji, ... stop at init), and its class 2 (eta_n = eta_n0 kg/s) makes e_n
rise with speed below V_y; mapped, its best is 0.041 (Y 0.826 GPa, 261 kg/s; the 40 deg points
0.052 off, and a dashpot in kg/s does not scale with the ball). Above V_y both classes fall as
v^(-0.24), undamped mdr as v^(-0.26): that slope alone keeps a law 0.035 off the table's 2 or 6 m/s
point. The measurements, and the settings tried: docs/development/module-notes.md.
"""

from __future__ import annotations

import math
import shutil
from collections.abc import Callable
from pathlib import Path
from typing import NamedTuple

import numpy as np

from .files import ExportedLaw, source_lines
from .lammps import SETUP_MDR, lammps_executable, wall_line
from .table_input import ContactTable
from .wall_impacts import CASE_STEPS, impact_cases, run_cases

#: the yield stresses searched (Pa)
Y_RANGE = (1e8, 1e11)
#: mdr's critical confinement ratio psi_b (LAMMPS' example value)
PSI_B = 0.5
#: the damping coefficients eta_n0 of the first pass
ETA_GRID = (0.0, 0.1, 0.2, 0.3, 0.45, 0.6)
#: the number of values of ln Y in the first pass
Y_POINTS = 13
#: values per parameter in each refining pass, the steps of the previous grid they span on each side
#: of its best, and the number of those passes
REFINE_POINTS, REFINE_SPAN, REFINE_PASSES = 9, 2, 7
#: speeds the fit scores between two neighbouring speeds of a fitted angle (check_points)
BETWEEN_POINTS = 15
#: speeds the fitted law is checked at between two neighbouring speeds (its reported difference)
VERIFY_POINTS = 63
#: mdr's e_n below its yield speed is one value (measured: within 1e-5 over 0.5-1.3 m/s); farther off is above it
FLAT_TOLERANCE = 1e-4
#: steps a case runs: a plastic contact lasts longer than the elastic t_c its time step comes from
MDR_STEPS = 5 * CASE_STEPS


class MdrLaw(NamedTuple):
    """The fitted mdr law (SI) and how well it follows the table."""

    young: float  #: E of the mdr input, Pa
    poisson: float
    yield_stress: float  #: Y, Pa
    damping: float  #: eta_n0 of mdr's damping class 1
    friction: float
    e_n_fit: np.ndarray  #: mdr's e_n at each table point (normal impact at its v_n), [speed, angle]
    e_n_table: np.ndarray
    fitted: np.ndarray  #: which table points the fit holds mdr to (:func:`fitted_columns`), [speed, angle]
    rms: float  #: root mean square of e_n,mdr - e_n,table at the fitted points
    worst: float  #: largest |e_n,mdr - e_n,table| at the fitted points
    #: largest |e_n,mdr - e_n,table| over the fitted points and VERIFY_POINTS speeds between each two
    worst_between: float
    worst_oblique: float  #: largest |e_n,mdr - e_n,table| at the points not fitted (oblique); NaN if none

    def coefficients(self) -> str:
        """The ``pair_coeff * *`` model (and the wall's)."""
        return mdr_coefficients(self.young, self.poisson, self.yield_stress, self.damping, self.friction)


def mdr_coefficients(young: float, poisson: float, y: float, eta: float, friction: float) -> str:
    """mdr's ``pair_coeff`` model: E nu Y (no surface energy) psi_b eta_n0, damping class 1, Mindlin."""
    return (
        f"mdr {young:.6g} {poisson:g} {y:.6g} 0.0 {PSI_B:g} {eta:.6g} damping mdr 1 "
        f"tangential mindlin NULL 0.0 {friction:g}"
    )


def fitted_columns(t: ContactTable) -> list[int]:
    """The angles (columns of ``t``) the fit holds mdr to: normal incidence alone where the table has
    it at two speeds or more, else every angle.

    A normal law's e_n at an oblique impact is its normal impact's at v_n = v cos a (LAMMPS' mdr with
    Mindlin: to 1e-4), where a finite-element table's oblique e_n lies below its 0 deg e_n(v_n)
    (module docstring); those points are reported, not fitted.
    """
    normal = [j for j, a in enumerate(t.angles) if abs(a) < 1e-9]
    return normal if normal and len(t.speeds) >= 2 else list(range(len(t.angles)))


def check_points(t: ContactTable, between: int | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The normal speeds the fit holds mdr to (m/s), their e_n, and which are the table's own points.

    The points of the fitted angles (:func:`fitted_columns`), and per angle ``between`` speeds
    (default BETWEEN_POINTS) evenly spaced in ln v_n between each two neighbouring speeds, their e_n
    interpolated linearly in ln v_n (mdr's e_n jumps at its yield speed: held to the points alone,
    the fit puts that jump between them); angle by angle, speeds increasing.
    """
    between = BETWEEN_POINTS if between is None else between
    vn, e_n, own = [], [], []
    for j in fitted_columns(t):
        v, e = t.normal_speed[:, j], np.minimum(t.e_n[:, j], 1.0)
        for i in range(len(v)):
            vn.append(v[i])
            e_n.append(e[i])
            own.append(True)
            if i + 1 < len(v):
                ln_v = np.log(v[i]) + np.log(v[i + 1] / v[i]) * np.arange(1, between + 1) / (between + 1)
                vn += list(np.exp(ln_v))
                e_n += list(np.interp(ln_v, np.log(v), e))
                own += [False] * between
    return np.array(vn), np.array(e_n), np.array(own)


def largest_difference(e: np.ndarray, target: np.ndarray, vn: np.ndarray) -> float:
    """The largest |e_n,mdr - e_n,table| (mdr's ``e`` against ``target``) at the check points ``vn``
    (:func:`check_points`' order) and where mdr may still have its below-yield e_n between them.

    Below its yield speed V_y mdr's e_n is the damping's alone, one value e_0 at every speed, and at
    V_y it drops by ~0.06 (module docstring). Where the two slowest check points of an angle share
    e_0 (below yield), V_y lies between the last check point at e_0 and the next one, anywhere:
    there e_0 meets the table's e_n down to the next point's (the table's e_n falls with speed), so
    |e_0 - e_n,table| there counts too; else the fit would hide the drop between two check points.
    """
    worst = float(np.max(np.abs(e - target)))
    starts = np.flatnonzero(np.diff(vn, prepend=np.inf) < 0)  # each fitted angle's slowest speed
    for a, b in zip(starts, [*starts[1:], len(vn)]):
        below = np.abs(e[a:b] - e[a]) < FLAT_TOLERANCE
        if b - a < 3 or not below[1] or below.all():
            continue
        k = a + int(np.argmin(below))  # the first check point past V_y
        worst = max(worst, float(abs(e[a] - target[k])))
    return worst


def _grid_e_n(
    t: ContactTable, young: float, pairs: list[tuple[float, float]], vn: np.ndarray, workdir: Path
) -> np.ndarray:
    """mdr's e_n at the normal speeds ``vn`` for each (Y, eta_n0) of ``pairs`` (rows): one LAMMPS run."""
    base = impact_cases([(v, 0.0, v) for v in vn], t.ball_mass, t.radius, t.e_star_materials)
    cases, laws, walls = [], [], []
    for y, eta in pairs:
        coeff = mdr_coefficients(young, t.poisson, y, eta, t.friction)
        for c in base:
            cases.append(dict(c, steps=MDR_STEPS))
            laws.append(f"pair_style granular\npair_coeff * * {coeff}")
            walls.append(wall_line(coeff, mdr=True))
    rows = run_cases(
        [lammps_executable()], workdir, cases, t.radius, t.ball_density, SETUP_MDR, laws, walls, timeout=1800, halt=True
    )
    return np.array([r["restitution_normal"] for r in rows]).reshape(len(pairs), len(vn))


def _search(
    t: ContactTable,
    young: float,
    vn: np.ndarray,
    target: np.ndarray,
    own: np.ndarray,
    workdir: Path,
    on_progress: Callable[[str], None] | None,
) -> tuple[float, float]:
    """The grid passes (module docstring): the (Y Pa, eta_n0) of the best score, the largest
    difference at ``vn`` (:func:`largest_difference`) and then the rms at the table's own points ``own``."""
    best: tuple[tuple[float, float], tuple[float, float]] | None = None
    ln_y = np.linspace(math.log(Y_RANGE[0]), math.log(Y_RANGE[1]), Y_POINTS)
    etas = np.array(ETA_GRID)
    for stage in range(1 + REFINE_PASSES):
        pairs = [(float(math.exp(ly)), float(eta)) for ly in ln_y for eta in etas]
        run_dir = workdir / f"grid{stage}"
        for pair, e in zip(pairs, _grid_e_n(t, young, pairs, vn, run_dir)):
            score = (largest_difference(e, target, vn), float(np.sqrt(np.mean((e - target)[own] ** 2))))
            if best is None or score < best[0]:
                best = (score, pair)
        shutil.rmtree(run_dir)
        assert best is not None, "every pass's grid has at least one (Y, eta_n0) pair"
        (worst, rms), (y0, eta0) = best
        if on_progress is not None:
            on_progress(
                f"mdr fit, pass {stage + 1}/{1 + REFINE_PASSES}: Y {y0:.4g} Pa, eta_n0 {eta0:.3g}: "
                f"largest e_n difference {worst:.4f}, rms at the table's points {rms:.4f}"
            )
        # the next pass: REFINE_POINTS values over +-REFINE_SPAN steps of this grid around its best
        span = np.linspace(-REFINE_SPAN, REFINE_SPAN, REFINE_POINTS)
        ln_y = math.log(y0) + (ln_y[1] - ln_y[0]) * span
        eta_step = float(np.min(np.diff(etas)))
        etas = np.unique(np.maximum(eta0 + eta_step * span, 0.0))
    assert best is not None, "the passes ran"
    return best[1]


def fit_mdr(t: ContactTable, workdir: Path, on_progress: Callable[[str], None] | None = None) -> MdrLaw:
    """The mdr law whose yield stress and damping fit table ``t``'s e_n over speed (module docstring).

    Fitted at normal incidence where the table has it (:func:`fitted_columns`). The fitted law is
    then run once more (one LAMMPS run) at VERIFY_POINTS speeds between the fitted points, where
    its reported difference comes from, and at the points not fitted, reported apart.
    """
    young = (1.0 - t.poisson**2) * t.e_star_materials
    vn, target, own = check_points(t)
    y, eta = _search(t, young, vn, target, own, workdir, on_progress)
    columns = fitted_columns(t)
    fitted = np.zeros(t.normal_speed.shape, dtype=bool)
    fitted[:, columns] = True
    vn, target, own = check_points(t, VERIFY_POINTS)
    e = _grid_e_n(t, young, [(y, eta)], np.concatenate([vn, t.normal_speed[~fitted]]), workdir / "verify")[0]
    e_fit = np.empty(t.normal_speed.shape)
    # check_points lists the fitted points angle by angle, speeds increasing
    e_fit[:, columns] = e[: len(vn)][own].reshape(len(columns), len(t.speeds)).T
    e_fit[~fitted] = e[len(vn) :]
    e_tab = np.minimum(t.e_n, 1.0)
    d = np.abs(e_fit - e_tab)
    return MdrLaw(
        young,
        t.poisson,
        y,
        eta,
        t.friction,
        e_fit,
        e_tab,
        fitted,
        float(np.sqrt(np.mean(d[fitted] ** 2))),
        float(np.max(d[fitted])),
        largest_difference(e[: len(vn)], target, vn),
        float(np.max(d[~fitted])) if not fitted.all() else math.nan,
    )


def write_lammps_mdr(folder: Path, law: ExportedLaw, mdr: MdrLaw) -> Path:
    """``contact_law_lammps_mdr.in``: the mdr law (type 1 ball, type 2 liner) and its fit."""
    t = law.table
    coeff = mdr.coefficients()
    oblique = not mdr.fitted.all()
    which = "the table's normal-incidence points" if oblique else "the table's points"
    lines = [
        "# millimpact contact law for LAMMPS (22 Jul 2025 or later: pair_style granular with the mdr normal model",
        "# of Zunker & Kamrin 2024, an elastic - perfectly plastic contact): atom type 1 = ball, type 2 = liner.",
        "# mdr needs: atom_style sphere 1, newton off, and the liner as fix wall/gran/region with the same model.",
        f"# E = (1 - nu^2) E*_materials = {mdr.young:.6g} Pa (mdr's rigid wall uses E / (1 - nu^2)), no adhesion,",
        f"# psi_b {PSI_B:g}. The yield stress Y = {mdr.yield_stress:.6g} Pa and the damping eta_n0 = {mdr.damping:.4g}",
        "# (damping mdr 1) are FITTED to the table's e_n over speed by LAMMPS itself (a ball at each normal speed):",
        f"# the largest difference at {which} and between them made least.",
        "# Law parameters, not the liner's yield stress. mdr's e_n jumps down by ~0.06 at its yield speed and is",
        "# the damping's alone below it.",
        *source_lines(t, "#")[:-1],
        f"# Fit residual: rms e_n difference {mdr.rms:.4f}, largest {mdr.worst:.4f} (at {which});",
        f"# largest {mdr.worst_between:.4f} at and between them (the table's e_n interpolated in ln v_n per angle).",
    ]
    if oblique:
        lines += [
            "# Oblique points, not fitted: mdr's e_n there is its normal impact's at v_n = v cos a; the table's",
            f"# differs by up to {mdr.worst_oblique:.4f}: a dependence on the angle that no normal law follows.",
        ]
    lines.append("# Table point: V (m/s), angle (deg), v_n (m/s): e_n table / mdr")
    for i, s in enumerate(t.speeds):
        for j, a in enumerate(t.angles):
            lines.append(
                f"#   {s:g}, {a:g}, {t.normal_speed[i, j]:.4g}: {mdr.e_n_table[i, j]:.4f} / {mdr.e_n_fit[i, j]:.4f}"
                + ("" if mdr.fitted[i, j] else " (not fitted)")
            )
    lines += [
        "",
        "pair_style granular",
        f"pair_coeff * * {coeff}",
        "# the liner as a granular region wall with the same model, e.g. a plane z = 0:",
        "# region liner_plane plane 0 0 0 0 0 1 side in units box",
        f"# fix liner all wall/gran/region granular {coeff} region liner_plane",
        "",
    ]
    path = folder / "contact_law_lammps_mdr.in"
    path.write_text("\n".join(lines))
    return path
