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

The fit: (Y, eta_n0) minimise the largest |e_n,mdr(v_n) - e_n,table| over the table's points and
check points between them (:func:`check_points`; the root mean square at the points breaks ties),
e_n,mdr from LAMMPS itself (a ball at each normal speed v_n against the plane, every pair of a pass
in one LAMMPS run; LAMMPS' e_n of an oblique impact is its normal impact's at v_n, measured to 1e-4
with the Mindlin tangential model): a grid of 13 values of ln Y over [1e8, 1e11] Pa x 6 of eta_n0,
then three passes of 9 x 9 over +-1 step of the previous grid around its best. mdr's e_n is the
damping's alone below its yield speed V_y and drops there by ~0.06 at once (then rises ~0.01 before
it falls: measured at Y 0.98 GPa, eta_n0 0.19, v_n 1.50 -> 1.55 m/s: 0.8475 -> 0.7915), so the
residual is not smooth in Y; held to the table's points alone a fit puts that drop between two of
them (0.042 at the points, 0.095 between). On the plastic rig's table (0.5, 2, 6 m/s x 0, 40 deg):
Y 0.965 GPa, eta_n0 0.211, largest difference 0.055 at the points and between, rms 0.033 (the
former 13 x 6 + 5 x 3 + 5 x 3 least-squares passes at the points only: 0.062, rms 0.033, and 0.089
between them); ~60 s on the loaded 2-core machine.

What limits it (measured on that table): mdr's e_n is the damping's below its yield speed V_y and
then falls ever faster, d ln e / d ln v from 0 to -0.3 within a factor ~5 of V_y, where the table
falls as v^(-0.11) to v^(-0.16) over 0.4-6 m/s; fitted to the three 0 deg points alone (and no
check points) the best largest difference is 0.029. And the table's e_n depends on the angle as well: its 40 deg points
lie 0.02-0.04 below its 0 deg e_n(v_n), which no normal law follows. At the six points alone, neither
the damping class 2 (eta_n constant: 0.057 at best on a 36 x 31 grid) nor psi_b as a third
parameter (the bulk response it triggers brings e_n back towards 1 above ~6 m/s; 0.043) does
better than class 1 (0.042); nor does a big mdr sphere for the plane (its e_n falls more gently
but it is not the liner's geometry).
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
#: values per parameter in each refining pass, and the number of those passes
REFINE_POINTS, REFINE_PASSES = 9, 3
#: speeds checked between two neighbouring speeds of a table's angle (check_points)
BETWEEN_POINTS = 3
#: steps a case runs: a plastic contact lasts longer than the elastic t_c its time step comes from
MDR_STEPS = 5 * CASE_STEPS


class MdrLaw(NamedTuple):
    """The fitted mdr law (SI) and how well it follows the table."""

    young: float  #: E of the mdr input, Pa
    poisson: float
    yield_stress: float  #: Y, Pa
    damping: float  #: eta_n0 of mdr's damping class 1
    friction: float
    e_n_fit: np.ndarray  #: mdr's e_n at each table point (normal impact at its v_n)
    e_n_table: np.ndarray
    rms: float  #: root mean square of e_n,mdr - e_n,table at the table's points
    worst: float  #: largest |e_n,mdr - e_n,table| at the table's points
    worst_between: float  #: largest |e_n,mdr - e_n,table| over the points and between them (check_points)

    def coefficients(self) -> str:
        """The ``pair_coeff * *`` model (and the wall's)."""
        return mdr_coefficients(self.young, self.poisson, self.yield_stress, self.damping, self.friction)


def mdr_coefficients(young: float, poisson: float, y: float, eta: float, friction: float) -> str:
    """mdr's ``pair_coeff`` model: E nu Y (no surface energy) psi_b eta_n0, damping class 1, Mindlin."""
    return (
        f"mdr {young:.6g} {poisson:g} {y:.6g} 0.0 {PSI_B:g} {eta:.6g} damping mdr 1 "
        f"tangential mindlin NULL 0.0 {friction:g}"
    )


def check_points(t: ContactTable) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The normal speeds the fit holds mdr to (m/s), their e_n, and which are the table's own points.

    The table's points, and per angle BETWEEN_POINTS speeds evenly spaced in ln v_n between each two
    neighbouring speeds, their e_n interpolated linearly in ln v_n (mdr's e_n jumps at its yield
    speed: held to the points alone, the fit puts that jump between them).
    """
    vn, e_n, own = [], [], []
    for j in range(t.normal_speed.shape[1]):
        v, e = t.normal_speed[:, j], np.minimum(t.e_n[:, j], 1.0)
        for i in range(len(v)):
            vn.append(v[i])
            e_n.append(e[i])
            own.append(True)
            if i + 1 < len(v):
                ln_v = np.log(v[i]) + np.log(v[i + 1] / v[i]) * np.arange(1, BETWEEN_POINTS + 1) / (BETWEEN_POINTS + 1)
                vn += list(np.exp(ln_v))
                e_n += list(np.interp(ln_v, np.log(v), e))
                own += [False] * BETWEEN_POINTS
    return np.array(vn), np.array(e_n), np.array(own)


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


def fit_mdr(t: ContactTable, workdir: Path, on_progress: Callable[[str], None] | None = None) -> MdrLaw:
    """The mdr law whose yield stress and damping fit table ``t``'s e_n over speed (module docstring)."""
    young = (1.0 - t.poisson**2) * t.e_star_materials
    vn, target, own = check_points(t)
    best: tuple[tuple[float, float], tuple[float, float], np.ndarray] | None = None  # (score, (Y, eta_n0), e_n)
    ln_y = np.linspace(math.log(Y_RANGE[0]), math.log(Y_RANGE[1]), Y_POINTS)
    etas = np.array(ETA_GRID)
    for stage in range(1 + REFINE_PASSES):
        pairs = [(float(math.exp(ly)), float(eta)) for ly in ln_y for eta in etas]
        run_dir = workdir / f"grid{stage}"
        for pair, e in zip(pairs, _grid_e_n(t, young, pairs, vn, run_dir)):
            d = e - target
            score = (float(np.max(np.abs(d))), float(np.sqrt(np.mean(d[own] ** 2))))
            if best is None or score < best[0]:
                best = (score, pair, e)
        shutil.rmtree(run_dir)
        assert best is not None, "every pass's grid has at least one (Y, eta_n0) pair"
        (worst, rms), (y0, eta0) = best[0], best[1]
        if on_progress is not None:
            on_progress(
                f"mdr fit, pass {stage + 1}/{1 + REFINE_PASSES}: Y {y0:.4g} Pa, eta_n0 {eta0:.3g}: "
                f"largest e_n difference {worst:.4f}, rms at the table's points {rms:.4f}"
            )
        # the next pass: REFINE_POINTS values over +-1 step of this grid around its best
        span = np.linspace(-1.0, 1.0, REFINE_POINTS)
        ln_y = math.log(y0) + (ln_y[1] - ln_y[0]) * span
        eta_step = float(np.min(np.diff(etas)))
        etas = np.unique(np.maximum(eta0 + eta_step * span, 0.0))
    assert best is not None, "the passes ran"
    (worst, rms), (y, eta), e = best
    # the table's points, in the table's grid order (check_points lists them angle by angle)
    shape = t.normal_speed.shape
    e_fit = e[own].reshape(shape[1], shape[0]).T
    e_tab = target[own].reshape(shape[1], shape[0]).T
    return MdrLaw(young, t.poisson, y, eta, t.friction, e_fit, e_tab, rms, float(np.max(np.abs(e_fit - e_tab))), worst)


def write_lammps_mdr(folder: Path, law: ExportedLaw, mdr: MdrLaw) -> Path:
    """``contact_law_lammps_mdr.in``: the mdr law (type 1 ball, type 2 liner) and its fit."""
    t = law.table
    coeff = mdr.coefficients()
    lines = [
        "# millimpact contact law for LAMMPS (22 Jul 2025 or later: pair_style granular with the mdr normal model",
        "# of Zunker & Kamrin 2024, an elastic - perfectly plastic contact): atom type 1 = ball, type 2 = liner.",
        "# mdr needs: atom_style sphere 1, newton off, and the liner as fix wall/gran/region with the same model.",
        f"# E = (1 - nu^2) E*_materials = {mdr.young:.6g} Pa (mdr's rigid wall uses E / (1 - nu^2)), no adhesion,",
        f"# psi_b {PSI_B:g}. The yield stress Y = {mdr.yield_stress:.6g} Pa and the damping eta_n0 = {mdr.damping:.4g}",
        "# (damping mdr 1) are FITTED: the largest e_n difference at the table's points and between them made least",
        "# (LAMMPS itself, a ball at each normal speed); law parameters, not the liner's yield stress. mdr's e_n",
        "# jumps down by ~0.06 at its yield speed and is the damping's alone below it.",
        *source_lines(t, "#")[:-1],
        f"# Fit residual: rms e_n difference {mdr.rms:.4f}, largest {mdr.worst:.4f} (at the table's points);",
        f"# largest {mdr.worst_between:.4f} between them (the table's e_n interpolated in ln v_n per angle).",
        "# Table point: V (m/s), angle (deg), v_n (m/s): e_n table / mdr",
    ]
    for i, s in enumerate(t.speeds):
        for j, a in enumerate(t.angles):
            lines.append(
                f"#   {s:g}, {a:g}, {t.normal_speed[i, j]:.4g}: {mdr.e_n_table[i, j]:.4f} / {mdr.e_n_fit[i, j]:.4f}"
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
