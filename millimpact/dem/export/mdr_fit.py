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

The fit: (Y, eta_n0) minimise the sum over the table's points of (e_n,mdr(v_n) - e_n,table)^2,
e_n,mdr from LAMMPS itself (a ball at each point's normal speed v_n against the plane, every pair of
a pass in one LAMMPS run): a grid of 13 values of ln Y over [1e8, 1e11] Pa x 6 of eta_n0, then two
finer passes of 5 x 3 around the best. The plastic rig's table (0.5-6 m/s x 0, 40 deg): 23 s.
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
from .wall_impacts import CASE_STEPS, impact_cases, run_cases

#: the yield stresses searched (Pa)
Y_RANGE = (1e8, 1e11)
#: mdr's critical confinement ratio psi_b (LAMMPS' example value)
PSI_B = 0.5
#: the damping coefficients eta_n0 of the first pass
ETA_GRID = (0.0, 0.1, 0.2, 0.3, 0.45, 0.6)
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
    rms: float  #: root mean square of e_n,mdr - e_n,table
    worst: float  #: largest |e_n,mdr - e_n,table|

    def coefficients(self) -> str:
        """The ``pair_coeff * *`` model (and the wall's)."""
        return mdr_coefficients(self.young, self.poisson, self.yield_stress, self.damping, self.friction)


def mdr_coefficients(young: float, poisson: float, y: float, eta: float, friction: float) -> str:
    """mdr's ``pair_coeff`` model: E nu Y (no surface energy) psi_b eta_n0, damping class 1, Mindlin."""
    return (
        f"mdr {young:.6g} {poisson:g} {y:.6g} 0.0 {PSI_B:g} {eta:.6g} damping mdr 1 "
        f"tangential mindlin NULL 0.0 {friction:g}"
    )


def _grid_e_n(law: ExportedLaw, young: float, pairs: list[tuple[float, float]], workdir: Path) -> list[np.ndarray]:
    """mdr's e_n at the table's normal speeds for each (Y, eta_n0) of ``pairs``: one LAMMPS run."""
    t = law.table
    vn = t.normal_speed.ravel()
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
    e = np.array([r["restitution_normal"] for r in rows]).reshape(len(pairs), -1)
    return [row.reshape(t.normal_speed.shape) for row in e]


def fit_mdr(law: ExportedLaw, workdir: Path, on_progress: Callable[[str], None] | None = None) -> MdrLaw:
    """The mdr law whose yield stress (and damping) fit the table's e_n over speed (module docstring)."""
    t = law.table
    young = (1.0 - t.poisson**2) * t.e_star_materials
    target = np.minimum(t.e_n, 1.0)
    best: tuple[float, tuple[float, float], np.ndarray] | None = None  # (cost, (Y, eta_n0), e_n)
    ys = np.exp(np.linspace(math.log(Y_RANGE[0]), math.log(Y_RANGE[1]), 13))
    etas = np.array(ETA_GRID)
    for stage in range(3):
        pairs = [(float(y), float(eta)) for y in ys for eta in etas]
        run_dir = workdir / f"grid{stage}"
        for pair, e in zip(pairs, _grid_e_n(law, young, pairs, run_dir)):
            cost = float(np.sum((e - target) ** 2))
            if best is None or cost < best[0]:
                best = (cost, pair, e)
        shutil.rmtree(run_dir)
        assert best is not None, "every pass's grid has at least one (Y, eta_n0) pair"
        (y0, eta0), e = best[1], best[2]
        if on_progress is not None:
            on_progress(
                f"mdr fit, pass {stage + 1}/3: Y {y0:.4g} Pa, eta_n0 {eta0:.3g}: "
                f"rms e_n difference {np.sqrt(np.mean((e - target) ** 2)):.4f}"
            )
        ratio = (ys[1] / ys[0]) ** 0.5
        ys = y0 * ratio ** np.linspace(-1, 1, 5)
        step = (etas[1] - etas[0]) / 2 if len(etas) > 1 else 0.01
        etas = np.maximum(eta0 + step * np.array([-1.0, 0.0, 1.0]), 0.0)
    assert best is not None, "three passes ran"
    cost, (y, eta), e = best
    return MdrLaw(
        young,
        t.poisson,
        y,
        eta,
        t.friction,
        e,
        target,
        float(np.sqrt(np.mean((e - target) ** 2))),
        float(np.max(np.abs(e - target))),
    )


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
        "# (damping mdr 1) are FITTED: least squares of e_n over the table's points (LAMMPS itself, a ball at",
        "# each point's normal speed); law parameters, not the liner's yield stress.",
        *source_lines(t, "#")[:-1],
        f"# Fit residual: rms e_n difference {mdr.rms:.4f}, largest {mdr.worst:.4f}.",
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
