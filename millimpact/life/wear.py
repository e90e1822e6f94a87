"""Wear of the liner from a mill run: abrasion (Archard) and impact, per surface bin and place.

The mill run (``millimpact mill``) gives, per bin of surface position along a lifter's unit (the
profile from the lifter's trailing foot over its trailing face, top and leading face, then the plate
to the next lifter; all lifters together) and per revolution of its slice:

- Archard's integral A = int F_n ds of the particles sliding on the liner (``abrasion.csv``);
- the impacts (``impacts.csv``), each with the energy the liner takes from it,
  E_abs = (1 - e^2) (1/2) m v_n^2, e the run's restitution for the particle's kind (the energy
  the impact's normal motion loses; the tangential part is already in the sliding).

The volume removed per revolution of a bin is the sum of the two wear laws,

    V = (k_a A + k_i E_abs) / H,

Archard's law for abrasion (J. F. Archard, J. Appl. Phys. 24 (1953) 981) and the impact-energy
law of the shear-impact energy model (wear = k_s W_shear + k_i E_impact; Y. Xu, Z. Luo and
Y. Zhao, Powder Technol. 2018), both with dimensionless coefficients over the steel's hardness H
(Pa). Spread over the bin's area (width b times the slice's thickness L times the n lifters'
units), the depth removed per revolution is V / (b L n), and per 1000 h of operation at N rpm,
times 60 N 1000. The mass is V rho. The constants come from a calibration
(:mod:`~millimpact.life.calibration`).
"""

from __future__ import annotations

import csv
import json
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..dem.impacts import read_impacts
from ..dem.mill.abrasion import SURFACES as UNIT_SURFACES
from ..dem.mill.geometry import MillProfile
from ..errors import InputError

#: the surfaces of a lifter's unit, in the profile's order, and their places (abrasion.csv's)
SURFACES = tuple(name for name, _ in UNIT_SURFACES)
PLACE_OF = dict(UNIT_SURFACES)


@dataclass(frozen=True)
class WearLaw:
    """V = (k_a A + k_i E_abs) / H (the module docstring): dimensionless k_a, k_i; H in Pa."""

    abrasion: float
    impact: float
    hardness_Pa: float
    density_kg_m3: float


@dataclass(frozen=True)
class MillRecord:
    """What the wear needs of a mill run: per surface bin A and E_abs per revolution, and the run's
    slice, lifters, speed and bin width."""

    folder: Path
    surface: np.ndarray  # the bins' surfaces (str)
    position: np.ndarray  # the bins' surface positions (m, along the unit)
    archard: np.ndarray  # int F_n ds per revolution (N m)
    absorbed: np.ndarray  # impact energy absorbed per revolution (J)
    bin_m: float
    slice_m: float
    n_lifters: int
    rpm: float
    summary: dict
    surfaces: list[list[float]]  # [start, end] of each surface along the unit (m)


def _restitutions(summary: dict) -> dict[str, float]:
    c = summary["contact"]
    e_ball = c.get("restitution")
    if e_ball is None:
        lo, hi = c["restitution_normal_range"]
        e_ball = 0.5 * (lo + hi)
    rock = summary["charge"].get("rock", {})
    return {"ball": float(e_ball), "rock": float(rock.get("restitution", e_ball))}


def read_mill_record(folder: Path | str, profile: MillProfile) -> MillRecord:
    """The mill run in ``folder`` on the liner ``profile`` as wear takes it (InputError, one line,
    when it is not one)."""
    folder = Path(folder)
    need = [folder / n for n in ("summary.json", "abrasion.csv", "impacts.csv")]
    missing = [p.name for p in need if not p.is_file()]
    if missing:
        raise InputError(
            f"--mill {folder}: not a mill run with abrasion (missing {', '.join(missing)}); "
            "run millimpact mill SCENE --out DIR first"
        )
    summary = json.loads(need[0].read_text())
    with open(need[1]) as fh:
        rows = list(csv.DictReader(fh))
    if rows and "surface_position_m" not in rows[0]:
        raise InputError(f"--mill {folder}: abrasion.csv has no surface positions (a run of an older millimpact)")
    w = float(rows[0]["bin_m"]) if rows else 0.01
    keys = {(r["surface"], int(round(float(r["surface_position_m"]) / w - 0.5))) for r in rows}
    impacts = read_impacts(need[2])
    e = _restitutions(summary)
    rev = float(summary["clock"]["revolutions"])
    imp_acc: dict[tuple[str, int], float] = {}
    surfaces = profile.unit_surfaces()
    bounds = [b for _, b in surfaces]
    for i in impacts:
        if i.surface_position_m is None or i.mass_kg is None:
            raise InputError(f"--mill {folder}: impacts.csv has no surface positions or masses (an older run)")
        k = int(i.surface_position_m // w)
        surf = _surface_of(i.surface_position_m, bounds)
        imp_acc[(surf, k)] = (
            imp_acc.get((surf, k), 0.0) + (1 - e[i.kind] ** 2) * 0.5 * i.mass_kg * i.normal_speed_m_s**2
        )
    keys |= set(imp_acc)
    # every bin of every surface, so that means and face lines count the bins nothing touched as 0
    for name, (a, b) in zip(SURFACES, surfaces):
        keys |= {(name, k) for k in range(int(a // w), int(math.ceil(b / w))) if a <= (k + 0.5) * w < b}
    order = sorted(keys, key=lambda sk: sk[1])
    arch = {(r["surface"], int(round(float(r["surface_position_m"]) / w - 0.5))): 0.0 for r in rows}
    for r in rows:
        key = (r["surface"], int(round(float(r["surface_position_m"]) / w - 0.5)))
        arch[key] += float(r["normal_force_slip_N_m_per_revolution"])
    mill = summary["mill"]
    return MillRecord(
        folder=folder,
        surface=np.array([s for s, _ in order]),
        position=np.array([(k + 0.5) * w for _, k in order]),
        archard=np.array([arch.get(sk, 0.0) for sk in order]),
        absorbed=np.array([imp_acc.get(sk, 0.0) / rev for sk in order]),
        bin_m=w,
        slice_m=float(mill["slice_thickness_m"]),
        n_lifters=int(mill["lifters"]),
        rpm=float(mill["speed_rpm"]),
        summary=summary,
        surfaces=surfaces,
    )


def _surface_of(s: float, ends: list[float]) -> str:
    for name, end in zip(SURFACES, ends):
        if s <= end:
            return name
    return SURFACES[-1]


def depth_rates(rec: MillRecord, law: WearLaw) -> dict[str, np.ndarray]:
    """Per bin: the depth removed per 1000 h (mm) by abrasion and by impact, and the mass (kg per
    1000 h) removed from the whole slice's liner (the module docstring)."""
    revs_per_1000h = rec.rpm * 60.0 * 1000.0
    area = rec.bin_m * rec.slice_m * rec.n_lifters
    v_a = law.abrasion * rec.archard / law.hardness_Pa
    v_i = law.impact * rec.absorbed / law.hardness_Pa
    return {
        "abrasion_mm_per_1000h": 1e3 * v_a / area * revs_per_1000h,
        "impact_mm_per_1000h": 1e3 * v_i / area * revs_per_1000h,
        "mass_kg_per_1000h": (v_a + v_i) * law.density_kg_m3 * revs_per_1000h,
    }


def place_rates(rec: MillRecord, rates: dict[str, np.ndarray]) -> dict[str, dict]:
    """Per surface: mean depth rate (mm per 1000 h) over its bins, largest, the shares of abrasion
    and impact, and the mass per 1000 h of the slice (kg) and per metre of mill length (kg/m)."""
    out = {}
    for surf in SURFACES:
        sel = rec.surface == surf
        a, i = rates["abrasion_mm_per_1000h"][sel], rates["impact_mm_per_1000h"][sel]
        tot = a + i
        both = float(a.sum() + i.sum())
        out[surf] = {
            "place": PLACE_OF[surf],
            "mean_mm_per_1000h": float(tot.mean()) if tot.size else 0.0,
            "largest_mm_per_1000h": float(tot.max()) if tot.size else 0.0,
            "abrasion_share": float(a.sum()) / both if both > 0 else math.nan,
            "impact_share": float(i.sum()) / both if both > 0 else math.nan,
            "mass_kg_per_1000h_per_metre": float(rates["mass_kg_per_1000h"][sel].sum()) / rec.slice_m,
        }
    return out


def surface_depths(rec: MillRecord, rates: dict[str, np.ndarray], hours: float) -> dict:
    """Per surface: (positions along it from its start (m), depth removed in ``hours`` (m)), for
    :func:`millimpact.life.profile.worn_profile`."""
    starts = [a for a, _ in rec.surfaces]
    depth = (rates["abrasion_mm_per_1000h"] + rates["impact_mm_per_1000h"]) * 1e-3 * hours / 1000.0
    out = {}
    for surf, s0 in zip(SURFACES, starts):
        sel = rec.surface == surf
        out[surf] = (rec.position[sel] - s0, depth[sel])
    return out
