"""The sliding at the liner: ``abrasion.csv``, the friction work and Archard's integral per place.

A liner wears by impact and by abrasion: particles sliding over it under load. The Yade script
follows every particle-liner contact (a ball's or a rock's) at each impact check, every
``check_every`` steps: its plastic slip vector u_p = u_total - u_elastic (Yade's Mindlin law
keeps both: the elastic part is cut back to the Coulomb limit while the contact slides, so u_p
grows by exactly the slip) changes by ds between two checks; the contact then did friction work

    dW = mu F_n ds      (the Coulomb force tan(phi) F_n while sliding, F_n at the check)

and adds F_n ds to the integral of Archard's law, V = k / H int F_n ds (J. F. Archard, J. Appl.
Phys. 24 (1953) 981-988). A contact that sticks adds nothing (its tangential spring stores and
returns its work). After the warm-up these sums are binned by the particle's kind and the surface
position of the contact point: its distance along the liner's profile from its lifter unit's start
(the lifter's trailing foot; :meth:`~millimpact.dem.mill.geometry.MillProfile.unit_starts`), in
bins :data:`~millimpact.dem.mill.setup.ABRASION_BIN` wide, every lifter's unit together, and
divided by the revolutions logged. Each bin's surface (``trailing_face``, ``top``,
``leading_face``, ``plate``), place and arc position (as in impacts.csv) come with it. The whole
run's friction work at the liner (from t = 0) goes to energy.csv beside Yade's total friction, so
the energy balance separates friction at the liner from friction in the bed.

``abrasion.csv`` columns: kind, place, surface, surface_position_m (the bin's centre), arc_position_m,
bin_m, friction_work_J_per_revolution, normal_force_slip_N_m_per_revolution (int F_n ds),
slip_m_per_revolution (int ds summed over contacts). Per revolution of the slice, whose thickness
summary.json gives.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..impacts import KINDS, PLACES
from .setup import MillSetup

#: abrasion.csv's columns
ABRASION_COLUMNS = (
    "kind",
    "place",
    "surface",
    "surface_position_m",
    "arc_position_m",
    "bin_m",
    "friction_work_J_per_revolution",
    "normal_force_slip_N_m_per_revolution",
    "slip_m_per_revolution",
)
#: a lifter unit's surfaces in the order of the profile (the part number modulo 4) and their places
SURFACES = (
    ("trailing_face", "lifter_face"),
    ("top", "lifter_top"),
    ("leading_face", "lifter_face"),
    ("plate", "plate"),
)


def abrasion_rows(raw: dict[str, np.ndarray], setup: MillSetup) -> list[dict]:
    """The rows of abrasion.csv from the script's abrasion_raw.csv: per kind, surface and bin of
    surface position (every lifter's unit summed), per revolution."""
    w = setup.abrasion_bin_m
    rev = setup.revolutions
    acc: dict[tuple[int, int, int], np.ndarray] = {}
    for j in range(raw["kind"].size if "kind" in raw else 0):
        key = (int(raw["kind"][j]), int(raw["unit_part"][j]), int(raw["surface_bin"][j]))
        row = np.array([raw["friction_work_J"][j], raw["normal_force_slip_N_m"][j], raw["slip_m"][j]])
        acc[key] = acc.get(key, 0.0) + row
    rows = []
    for (kind, part, k), (f, fs, ds) in sorted(acc.items()):
        s = (k + 0.5) * w
        x, y = setup.profile.point_at(s)
        rows.append(
            {
                "kind": KINDS[kind],
                "place": SURFACES[part][1],
                "surface": SURFACES[part][0],
                "surface_position_m": s,
                "arc_position_m": setup.profile.arc_position(x, y),
                "bin_m": w,
                "friction_work_J_per_revolution": f / rev,
                "normal_force_slip_N_m_per_revolution": fs / rev,
                "slip_m_per_revolution": ds / rev,
            }
        )
    return rows


def write_abrasion(path: Path, rows: list[dict]) -> None:
    """abrasion.csv (the caller stages the folder)."""
    with open(path, "w") as fh:
        fh.write(",".join(ABRASION_COLUMNS) + "\n")
        for r in rows:
            fh.write(
                ",".join(r[c] if c in ("kind", "place", "surface") else repr(float(r[c])) for c in ABRASION_COLUMNS)
                + "\n"
            )


def abrasion_summary(rows: list[dict]) -> dict:
    """summary.json's "abrasion": per kind and place, friction work (J) and int F_n ds (N m) per
    revolution, and their totals."""
    out: dict = {"units": "J and N m per revolution of the slice"}
    for kind in KINDS:
        per = {}
        for place in PLACES:
            sel = [r for r in rows if r["kind"] == kind and r["place"] == place]
            per[place] = {
                "friction_work_J_per_revolution": sum(r["friction_work_J_per_revolution"] for r in sel),
                "normal_force_slip_N_m_per_revolution": sum(r["normal_force_slip_N_m_per_revolution"] for r in sel),
            }
        out[kind] = per
    out["friction_work_J_per_revolution"] = sum(r["friction_work_J_per_revolution"] for r in rows)
    return out
