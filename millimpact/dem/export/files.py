"""The contact law of a table, fitted per DEM code and written as files ready to include.

Per table point (impact speed V, angle a): the Hertz-dashpot law (:mod:`millimpact.theory.hertz_dashpot`) that gives
the table's e_n and F_max at its normal speed - damping ratio zeta from e_n, then the Hertz
coefficient k_no = (4/3) E* R^(1/2) from F_max. The tangential law is Mindlin's stiffness
k_t / k_n = 4 G* / E* of the scene's materials (Johnson 1985, section 7.2) with the scene's
Coulomb mu and no tangential damping (the finite-element contact has none).

- Yade (``contact_law_yade.py``): the whole grid; a PyRunner sets each new ball-liner interaction's
  k_no, betan, k_so and friction from its impact speed and angle (velocity-dependent e_n).
- LIGGGHTS (``contact_law_liggghts.in``) and LAMMPS (``contact_law_lammps.in``): one constant
  law per material pair (their Hertz models take constants): the table's mean zeta and the E*
  that fits every F_max (least squares in log F); each file says the normal-speed band where
  that constant law stays within 0.02 of e_n and 5 % of F_max, and the error at every point.
"""

from __future__ import annotations

import datetime
import json
import math
from collections.abc import Callable
from pathlib import Path
from typing import NamedTuple

import numpy as np

from ... import __version__
from ...errors import InputError
from ...theory.hertz_dashpot import code_restitution_for_damping, peak_force_factor, point_law, restitution_of_damping
from .table_input import ContactTable

#: a constant law "holds" at a table point within these (the round trip's tolerances: docs/dem.md)
BAND_E_N, BAND_F_MAX = 0.02, 0.05
#: Yade material labels the exported law recognises
BALL_MATERIAL, LINER_MATERIAL = "millimpact_ball", "millimpact_liner"
CODES = ("yade", "liggghts", "lammps")
RUNTIME = Path(__file__).with_name("yade_scripts") / "contact_law_runtime.py"


class ExportedLaw(NamedTuple):
    """The fitted laws of a table: per grid point [speed, angle] and the constant one."""

    table: ContactTable
    zeta: np.ndarray
    e_star: np.ndarray  #: Pa
    e_in: np.ndarray  #: the codes' restitution input of relation (1)
    e_n_law: np.ndarray
    peak_force_law: np.ndarray  #: N
    zeta_const: float
    e_star_const: float  #: Pa
    e_in_const: float
    e_n_const: np.ndarray  #: what the constant law gives at each point
    peak_force_const: np.ndarray
    band: tuple[float, float] | None  #: normal speeds (m/s) where the constant law holds, or None


def fit_law(t: ContactTable) -> ExportedLaw:
    """Fit the per-point laws and the constant law of table ``t`` (module docstring)."""
    shape = t.e_n.shape
    try:
        pts = [
            [
                point_law(min(t.e_n[i, j], 1.0), t.peak_force[i, j], t.normal_speed[i, j], t.ball_mass, t.radius)
                for j in range(shape[1])
            ]
            for i in range(shape[0])
        ]
    except ValueError as exc:
        raise InputError(f"TABLE_DIR {t.folder}: restitution_normal {exc}") from None
    grab = lambda k: np.array([[getattr(p, k) for p in row] for row in pts])  # noqa: E731
    zeta_c = float(np.mean(grab("zeta")))
    phi = peak_force_factor(zeta_c)
    unit = phi * (t.ball_mass * t.normal_speed**2) ** 0.6 * (4.0 / 3.0 * math.sqrt(t.radius)) ** 0.4
    # F = unit E*^(2/5): least squares in log F
    e_star_c = float(math.exp(np.mean(np.log(t.peak_force / unit)) / 0.4))
    e_n_c = np.full(shape, restitution_of_damping(zeta_c))
    f_c = unit * e_star_c**0.4
    holds = (np.abs(e_n_c - np.minimum(t.e_n, 1.0)) <= BAND_E_N) & (np.abs(f_c / t.peak_force - 1) <= BAND_F_MAX)
    band = None
    if holds.any():
        lo, hi = float(t.normal_speed[holds].min()), float(t.normal_speed[holds].max())
        inside = (t.normal_speed >= lo) & (t.normal_speed <= hi)
        band = (lo, hi) if holds[inside].all() else None
    return ExportedLaw(
        t,
        grab("zeta"),
        grab("e_star"),
        grab("e_in"),
        grab("restitution"),
        grab("peak_force"),
        zeta_c,
        e_star_c,
        code_restitution_for_damping(zeta_c),
        e_n_c,
        f_c,
        band,
    )


def law_at(t: ContactTable) -> Callable[[float, float], dict[str, float]]:
    """The exported law of table ``t`` as a function of (impact speed |v| in m/s, angle from the face
    normal in deg), giving ``{"e_n", "e_t", "f_max"}`` (F_max in N): the law the Yade export's runtime
    applies and an adaptive table's checks measure (:func:`millimpact.studies.table_adaptive.export_law`
    over ``t``'s grid). Each grid point's Hertz-dashpot zeta (from its e_n) and E* (from its F_max at
    its normal speed), as :func:`fit_law` fits them; zeta and E* bilinear in (ln speed, angle), held
    at the nearest edge outside the grid; then e_n = e(zeta) and F_max = phi(zeta) k_no^(2/5)
    (m v_n^2)^(3/5), k_no = (4/3) E* R^(1/2), v_n = v cos(angle). e_t (left to the DEM code's
    Mindlin-Coulomb law) is the table's, bilinear: NaN on a cell with a normal-incidence corner."""
    from ...studies.table_adaptive import export_law

    law = export_law(t.ball_mass, t.radius)
    speeds, angles = [float(v) for v in t.speeds], [float(a) for a in t.angles]
    grid = {
        (v, a): {"e_n": float(t.e_n[i, j]), "e_t": float(t.e_t[i, j]), "f_max": float(t.peak_force[i, j])}
        for i, v in enumerate(speeds)
        for j, a in enumerate(angles)
    }
    return lambda v, a: law(speeds, angles, grid, v, a)


def source_lines(t: ContactTable, comment: str) -> list[str]:
    """The header lines naming the table the law comes from (and, for an adaptive table, the
    largest error of its law that the table's checks measured)."""
    return [
        f"{comment} From the millimpact contact table {t.folder.resolve()}",
        f"{comment}   scene {t.scene_name}, method {t.method}, millimpact {t.version}; exported by millimpact "
        f"{__version__} on {datetime.date.today().isoformat()}",
        f"{comment}   {len(t.speeds)} speeds ({', '.join(f'{s:g}' for s in t.speeds)} m/s) x {len(t.angles)} angles "
        f"({', '.join(f'{a:g}' for a in t.angles)} deg from the face normal), ball radius {t.radius:g} m, "
        f"mass {t.ball_mass:.5g} kg",
        f"{comment} Units: SI (m, kg, s, N, Pa). Normal law of every code here: F_n = max(0, k_no delta^1.5 + zeta "
        f"(m k_no)^0.5 delta^0.25 d(delta)/dt), k_no = (4/3) E* R^0.5 (docs/dem.md).",
        *checked_lines(t, comment),
    ]


def checked_lines(t: ContactTable, comment: str) -> list[str]:
    """An adaptive table's measured interpolation error: the largest error of the law (zeta and E*
    bilinear in ln speed and angle) at the finite-element cases that checked it."""
    a = t.adaptive
    if a is None:
        return []
    from ...studies.table_report import largest_errors_text, percent

    state = "reached" if a["reached"] else f"NOT reached (budget of {a['max_cases']} cases spent)"
    return [
        f"{comment} Interpolation error checked at {a['checks']} of the table's cases between its grid's: largest "
        f"{largest_errors_text(a)}; tolerance {a['tolerance']:g} (F_max {percent(a['tolerance_peak_force_rel'])}) "
        f"{state} (the table's checks.csv)."
    ]


def _band_lines(law: ExportedLaw, comment: str) -> list[str]:
    t = law.table
    out = [
        f"{comment} Constant law: zeta {law.zeta_const:.5f} (restitution input e = {law.e_in_const:.5f} gives "
        f"e_n = {restitution_of_damping(law.zeta_const):.4f}), E* {law.e_star_const:.5g} Pa."
    ]
    if law.band:
        out.append(
            f"{comment} VALID for normal impact speeds {law.band[0]:.3g}-{law.band[1]:.3g} m/s (the table points "
            f"where it is within {BAND_E_N} of e_n and {BAND_F_MAX:.0%} of F_max); outside that band e_n and F_max "
            "follow the table only as far as they stay constant."
        )
    else:
        out.append(
            f"{comment} NOT VALID across the table: no contiguous band of normal speeds keeps it within "
            f"{BAND_E_N} of e_n and {BAND_F_MAX:.0%} of F_max; a velocity-dependent law (Yade export) is needed."
        )
    out.append(
        f"{comment} Table point: V (m/s), angle (deg), v_n (m/s): e_n table / constant law, F_max table / constant law (N)"
    )
    for i, s in enumerate(t.speeds):
        for j, a in enumerate(t.angles):
            out.append(
                f"{comment}   {s:g}, {a:g}, {t.normal_speed[i, j]:.4g}: {t.e_n[i, j]:.4f} / {law.e_n_const[i, j]:.4f}, "
                f"{t.peak_force[i, j]:.5g} / {law.peak_force_const[i, j]:.5g}"
            )
    return out


#: the law is embedded as JSON (the mill reads it back so); these make its null, true and false
#: Python too
JSON_NAMES = "null, true, false = None, True, False  # the JSON below, read as Python\n"


def law_data(law: ExportedLaw) -> dict:
    """The grid law as the JSON the Yade file embeds (``MILLIMPACT_LAW``)."""
    t = law.table
    i_med = int(np.argsort(law.zeta.ravel())[law.zeta.size // 2])
    return {
        "source_table": str(t.folder.resolve()),
        "scene": t.scene_name,
        "method": t.method,
        "millimpact_version": t.version,
        "units": "SI: m, kg, s, N, Pa",
        "speeds_m_s": t.speeds.tolist(),
        "angles_deg": t.angles.tolist(),
        "ball_radius_m": t.radius,
        "zeta": law.zeta.tolist(),
        "e_star_Pa": law.e_star.tolist(),
        "restitution_normal_table": np.minimum(t.e_n, 1.0).tolist(),
        "peak_normal_force_N_table": t.peak_force.tolist(),
        "friction": t.friction,
        "tangential_stiffness_ratio": t.tangential_stiffness_ratio,
        "interpolation_checked": t.adaptive
        and {k: t.adaptive[k] for k in ("tolerance", "reached", "checks", "largest_checked_error")},
        "yade": {
            "ball_material": BALL_MATERIAL,
            "liner_material": LINER_MATERIAL,
            # Ip2's E = Y / (2 (1 - nu^2)) for two equal materials: the constant law's E*
            "young_Pa": 2.0 * (1.0 - t.poisson**2) * law.e_star_const,
            "poisson": t.poisson,
            "ball_density_kg_m3": t.ball_density,
            "liner_density_kg_m3": t.target_density,
            "betan_default": float(law.zeta.ravel()[i_med] / math.sqrt(6.0)),
            "betas_per_betan": 0.0,
        },
    }


def write_yade(folder: Path, law: ExportedLaw) -> Path:
    """``contact_law_yade.py``: the grid law for Yade, to ``exec`` in a Yade script."""
    t = law.table
    head = [
        "# millimpact contact law for Yade 2023.02a: Hertz-Mindlin (Ip2_FrictMat_FrictMat_MindlinPhys +",
        "# Law2_ScGeom_MindlinPhys_Mindlin) with a velocity-dependent restitution set per interaction.",
        *source_lines(t, "#"),
        "# Use in a Yade script:",
        "#   exec(open('contact_law_yade.py').read())",
        "#   ball = O.materials.append(millimpact_ball_material())     # give the balls this material",
        "#   liner = O.materials.append(millimpact_liner_material())   # and the liner (walls, facets) this one",
        "#   O.engines = [ForceResetter(), InsertionSortCollider([...]),",
        "#                InteractionLoop([...], [millimpact_ip2()], [Law2_ScGeom_MindlinPhys_Mindlin()]),",
        "#                millimpact_law_runner(),                     # right after the InteractionLoop",
        "#                NewtonIntegrator(gravity=(0, 0, -9.81), damping=0.0)]",
        "# NewtonIntegrator(damping=0.0): Yade's default local damping 0.2 removes more energy than the",
        "# contact law (with it a 15 mm ball at 3 m/s and en = 0.8 rebounds at e = 0.65 instead of 0.80).",
        f"# Tangential: Coulomb mu = {t.friction:g}, Mindlin stiffness k_t / k_n = {t.tangential_stiffness_ratio:.4f}, "
        "no tangential damping.",
        "# The per-interaction update loops over O.interactions in Python every step: with many",
        "# thousands of contacts give the runner a larger iterPeriod (a new contact then runs its",
        "# first steps on millimpact_ip2()'s median values).",
        "",
    ]
    text = "\n".join(head) + "\n" + JSON_NAMES + "MILLIMPACT_LAW = " + json.dumps(law_data(law), indent=1)
    text += "\n\n" + RUNTIME.read_text()
    path = folder / "contact_law_yade.py"
    path.write_text(text)
    return path


def write_liggghts(folder: Path, law: ExportedLaw) -> Path:
    """``contact_law_liggghts.in``: LIGGGHTS ``model hertz`` with the constant law; type 1 ball, 2 liner."""
    t = law.table
    young = 2.0 * (1.0 - t.poisson**2) * law.e_star_const
    e = law.e_in_const
    lines = [
        "# millimpact contact law for LIGGGHTS (gran model hertz, tangential history): atom type 1 = ball,",
        "# type 2 = liner (the wall mesh's type). LIGGGHTS' hertz damping is gamma_n = -2 (5/6)^0.5 beta (S_n m*)^0.5,",
        "# beta = ln e / (ln^2 e + pi^2)^0.5: the coefficientRestitution below is the input that gives the",
        "# table's e_n, not e_n itself (docs/dem.md). Young's modulus: Y* = Y / (2 (1 - nu^2)) for two equal types.",
        *source_lines(t, "#"),
        *_band_lines(law, "#"),
        "# Ball-ball pairs (1 1) get the same values: the table describes ball-liner impacts only.",
        "",
        "# steel's modulus is above LIGGGHTS' default limit for SI units (1e9 Pa)",
        "hard_particles yes",
        f"fix m1 all property/global youngsModulus peratomtype {young:.6g} {young:.6g}",
        f"fix m2 all property/global poissonsRatio peratomtype {t.poisson:g} {t.poisson:g}",
        f"fix m3 all property/global coefficientRestitution peratomtypepair 2 {e:.6f} {e:.6f} {e:.6f} {e:.6f}",
        f"fix m4 all property/global coefficientFriction peratomtypepair 2 {t.friction:g} {t.friction:g} "
        f"{t.friction:g} {t.friction:g}",
        "# limitForce on: no attractive normal force at the end of a contact (as Yade; the fit assumes it);",
        "# tangential_damping off: the table's contact has no tangential damping",
        "pair_style gran model hertz tangential history limitForce on tangential_damping off",
        "pair_coeff * *",
        "# the liner as a mesh wall of type 2, same model (its keywords after the geometry), e.g.:",
        "# fix liner all wall/gran model hertz tangential history mesh n_meshes 1 meshes cad1 "
        "limitForce on tangential_damping off",
        "",
    ]
    path = folder / "contact_law_liggghts.in"
    path.write_text("\n".join(lines))
    return path


def write_lammps(folder: Path, law: ExportedLaw) -> Path:
    """``contact_law_lammps.in``: LAMMPS ``pair_style granular``, ``hertz/material`` with
    ``damping coeff_restitution`` and ``limit_damping``; type 1 ball, type 2 liner."""
    t = law.table
    young = 2.0 * (1.0 - t.poisson**2) * law.e_star_const
    e = law.e_in_const
    coeff = (
        f"hertz/material {young:.6g} {e:.6f} {t.poisson:g} tangential mindlin NULL 0.0 {t.friction:g} "
        "damping coeff_restitution limit_damping"
    )
    lines = [
        "# millimpact contact law for LAMMPS (pair_style granular; needs the damping model coeff_restitution):",
        "# atom type 1 = ball, type 2 = liner. coeff_restitution: eta_n = -2 (5/6)^0.5 ln e / (pi^2 + ln^2 e)^0.5",
        "# ((3/2) k_nd m_eff)^0.5 with k_nd = (4/3) E_eff a: the restitution below is the input that gives the",
        "# table's e_n, not e_n itself (docs/dem.md). hertz/material mixes E_eff = E / (2 (1 - nu^2)) for equal types.",
        "# mindlin NULL: k_t = 8 G_eff a from E and nu; damping factor 0.0: no tangential damping (as the table).",
        *source_lines(t, "#"),
        *_band_lines(law, "#"),
        "",
        "pair_style granular",
        f"pair_coeff * * {coeff}",
        "# the liner as a granular wall with the same model, e.g. a plane z = 0:",
        f"# fix liner all wall/gran granular {coeff} zplane 0.0 NULL",
        "",
    ]
    path = folder / "contact_law_lammps.in"
    path.write_text("\n".join(lines))
    return path


def write_law_json(folder: Path, law: ExportedLaw, code: str) -> Path:
    """``contact_law.json``: every fitted number, per table point and constant."""
    t = law.table
    points = []
    for i, s in enumerate(t.speeds):
        for j, a in enumerate(t.angles):
            points.append(
                {
                    "impact_speed_m_s": float(s),
                    "impact_angle_deg": float(a),
                    "normal_velocity_in_m_s": float(t.normal_speed[i, j]),
                    "restitution_normal_table": float(t.e_n[i, j]),
                    "peak_normal_force_N_table": float(t.peak_force[i, j]),
                    "restitution_tangential_table": None if math.isnan(t.e_t[i, j]) else float(t.e_t[i, j]),
                    "damping_ratio_zeta": float(law.zeta[i, j]),
                    "restitution_input_e": float(law.e_in[i, j]),
                    "yade_betan": float(law.zeta[i, j] / math.sqrt(6.0)),
                    "contact_modulus_E_star_Pa": float(law.e_star[i, j]),
                    "hertz_coefficient_k_no_N_m1_5": float(4.0 / 3.0 * law.e_star[i, j] * math.sqrt(t.radius)),
                    "restitution_normal_law": float(law.e_n_law[i, j]),
                    "peak_normal_force_N_law": float(law.peak_force_law[i, j]),
                }
            )
    doc = {
        "millimpact_version": __version__,
        "code": code,
        "source_table": str(t.folder.resolve()),
        "scene": t.scene_name,
        "method": t.method,
        "units": "SI",
        "ball_radius_m": t.radius,
        "ball_mass_kg": t.ball_mass,
        "friction": t.friction,
        "tangential_stiffness_ratio": t.tangential_stiffness_ratio,
        "contact_modulus_of_the_materials_Pa": t.e_star_materials,
        "interpolation_checked": t.adaptive
        and {k: t.adaptive[k] for k in ("tolerance", "reached", "checks", "largest_checked_error")},
        "points": points,
        "constant": {
            "damping_ratio_zeta": law.zeta_const,
            "restitution_input_e": law.e_in_const,
            "restitution_normal": restitution_of_damping(law.zeta_const),
            "contact_modulus_E_star_Pa": law.e_star_const,
            "valid_normal_speeds_m_s": list(law.band) if law.band else None,
        },
    }
    path = folder / "contact_law.json"
    path.write_text(json.dumps(doc, indent=1) + "\n")
    return path


WRITERS = {"yade": write_yade, "liggghts": write_liggghts, "lammps": write_lammps}
