"""A ``millimpact table`` folder read back for the DEM export: its grid of impacts and its scene.

The folder must hold ``contact_table.json`` as :func:`millimpact.studies.table_report.write_table`
writes it (the rows, the resolved base scene as TOML, the method) and ``contact_table.csv``. The
export uses the rows whose status is ok, on the grid impact speed x angle of one ball radius (the
table's first radius when it has several); each grid point must be present once. An adaptive
table's check rows (role check) are not on its grid: the export leaves them out and carries the
table's largest checked error (its ``adaptive`` block) into the files it writes.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import NamedTuple

import numpy as np

from ...errors import InputError

#: columns of contact_table.json's rows the export reads
NEEDED = (
    "impact_speed_m_s",
    "impact_angle_deg",
    "ball_radius_m",
    "normal_velocity_in_m_s",
    "tangential_velocity_in_m_s",
    "restitution_normal",
    "restitution_tangential",
    "peak_normal_force_N",
    "status",
)


class ContactTable(NamedTuple):
    """A contact table on its grid (SI units); arrays are indexed [speed, angle]."""

    folder: Path
    scene_name: str
    method: str
    version: str
    speeds: np.ndarray  #: impact speeds |v|, m/s (increasing)
    angles: np.ndarray  #: angles from the face normal, deg (increasing)
    radius: float  #: ball radius, m
    ball_density: float  #: kg/m^3
    ball_mass: float  #: kg
    target_density: float  #: kg/m^3
    youngs_modulus: float  #: the ball's E, Pa (the scene's; the law's E* comes from F_max)
    poisson: float  #: the ball's nu
    e_star_materials: float  #: the materials' contact modulus, Pa
    tangential_stiffness_ratio: float  #: Mindlin's k_t / k_n = 4 G* / E* of the materials
    friction: float  #: Coulomb mu of the scene
    normal_speed: np.ndarray  #: m/s
    e_n: np.ndarray
    e_t: np.ndarray  #: NaN at normal incidence
    peak_force: np.ndarray  #: N
    #: an adaptive table's summary (tolerance, reached, largest_checked_error, checks); None: a fixed grid
    adaptive: dict | None = None


def _not_a_table(folder: Path, why: str) -> InputError:
    return InputError(
        f"TABLE_DIR {folder}: not a contact table ({why}); make one with: millimpact table SCENE "
        f"--velocity V1,V2 --angle A1,A2 --out DIR"
    )


def read_table(folder: Path | str) -> ContactTable:
    """The table in ``folder`` (InputError, one line, if it is not one or its grid is incomplete)."""
    import tomllib

    from ...scene.toml_io import scene_from_dict
    from ...theory.hertz import effective_modulus

    folder = Path(folder)
    if not folder.is_dir():
        raise _not_a_table(folder, "a file, not a table's folder" if folder.exists() else "no such folder")
    path = folder / "contact_table.json"
    if not path.is_file() or not (folder / "contact_table.csv").is_file():
        raise _not_a_table(folder, "no contact_table.json and contact_table.csv")
    try:
        doc = json.loads(path.read_text())
        rows = doc["rows"]
        scene = scene_from_dict(tomllib.loads(doc["scene_resolved"]))
        method, version = str(doc.get("method", "?")), str(doc.get("millimpact_version", "?"))
    except (OSError, ValueError, KeyError, TypeError) as exc:
        raise _not_a_table(folder, f"contact_table.json unreadable: {type(exc).__name__}: {str(exc)[:120]}") from None
    except Exception as exc:  # a scene that no longer validates
        raise _not_a_table(folder, f"its scene does not load: {str(exc).splitlines()[0][:160]}") from None
    if (
        not isinstance(rows, list)
        or not rows
        or any(not isinstance(r, dict) or any(k not in r for k in NEEDED) for r in rows)
    ):
        raise _not_a_table(folder, f"contact_table.json rows lack the columns {', '.join(NEEDED)}")
    # an adaptive table's checks (and spare cases) lie between the grid's cases; the law is the grid's
    rows = [r for r in rows if r.get("role", "grid") == "grid"]
    adaptive = doc.get("adaptive") if isinstance(doc.get("adaptive"), dict) else None
    ok = [r for r in rows if str(r["status"]).startswith("ok")]
    if not ok:
        raise InputError(f"TABLE_DIR {folder}: no case of the table finished (status column); rerun millimpact table")
    radius = float(ok[0]["ball_radius_m"])
    ok = [r for r in ok if abs(float(r["ball_radius_m"]) - radius) <= 1e-12 * radius]
    speeds = np.array(sorted({float(r["impact_speed_m_s"]) for r in rows}))
    angles = np.array(sorted({float(r["impact_angle_deg"]) for r in rows}))
    grid = {(float(r["impact_speed_m_s"]), float(r["impact_angle_deg"])): r for r in ok}
    shape = (len(speeds), len(angles))
    vals = {k: np.full(shape, np.nan) for k in ("vn", "en", "et", "f")}
    for i, s in enumerate(speeds):
        for j, a in enumerate(angles):
            r = grid.get((s, a))
            if r is None:
                raise InputError(
                    f"TABLE_DIR {folder}: the case v = {s:g} m/s, angle {a:g} deg is missing or failed; "
                    "rerun millimpact table to complete its grid"
                )
            vals["vn"][i, j] = r["normal_velocity_in_m_s"]
            vals["en"][i, j] = r["restitution_normal"]
            et = r["restitution_tangential"]
            vals["et"][i, j] = math.nan if et is None else et
            vals["f"][i, j] = r["peak_normal_force_N"]
    if not (np.all(np.isfinite(vals["en"])) and np.all(vals["en"] > 0) and np.all(vals["f"] > 0)):
        raise InputError(f"TABLE_DIR {folder}: restitution_normal or peak_normal_force_N not positive in some rows")
    ball, target = scene.ball.material, scene.target_material
    e_star = effective_modulus(ball, target)
    # Mindlin: k_t = 8 G* a, k_n = 2 E* a (tangent), 1/G* = (2 - nu1)/G1 + (2 - nu2)/G2 (Johnson 1985, 7.2)
    g_star = 1.0 / ((2 - ball.poisson) / ball.shear_modulus + (2 - target.poisson) / target.shear_modulus)
    mass = ball.density * 4.0 / 3.0 * math.pi * radius**3
    return ContactTable(
        folder,
        scene.name,
        method,
        version,
        speeds,
        angles,
        radius,
        ball.density,
        mass,
        target.density,
        ball.youngs_modulus,
        ball.poisson,
        e_star,
        4.0 * g_star / e_star,
        scene.contact.friction,
        vals["vn"],
        vals["en"],
        vals["et"],
        vals["f"],
        adaptive,
    )
