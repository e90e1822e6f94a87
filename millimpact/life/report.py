"""What ``millimpact life`` writes: the rates, the profile through time, the relining, the figures.

- ``wear.csv``: per bin of surface position of the first mill run (the liner the user gave): the
  surface, place, position (m), depth rates by abrasion and impact and their sum (mm per 1000 h),
  the mass rate of the slice's liner (kg per 1000 h);
- ``profiles.csv``: the profile at each step (hours; lifter height above the plate, top width,
  both face angles, plate thickness, mm and degrees) and the mill on it (net power kW/m, toe and
  shoulder in degrees, the balls' impacts and their energy per revolution);
- ``summary.json``: the rates per surface for every cycle (mean and largest mm per 1000 h, shares
  of abrasion and impact, kg per 1000 h per metre of mill length), the metal flow beside them, the
  hours to relining per criterion at the calibration's constants and at their spread, the place
  that fails first, the calibration; the command's wall time per stage (``wall_time_s``: reading
  the mill runs, the wear and profile update, the mill re-runs, the outputs, the rest and the
  whole, s; ``wall_time_s_per_cycle``: each cycle's update and each re-run);
- ``wear.png`` (rates along the unit, the new profile drawn), ``profiles.png`` (the profiles over
  time, like a liner scan), ``height_angle.png`` (lifter height and face angles against hours).

Metal flow (``--damage DIR``): the damage map's dent growth per revolution at a spot of each place
(``damage.csv``), times the revolutions in 1000 h, in mm: steel moved, not removed, reported beside
the wear and never added to it.
"""

from __future__ import annotations

import csv
import math
from pathlib import Path

from ..errors import InputError
from .calibration import through_life
from .loop import hours_to_reline, rescaled, run_life
from .wear import PLACE_OF, SURFACES, depth_rates


def metal_flow(damage: str | None, rpm: float) -> dict | None:
    """Per place: the dent growth at a spot in mm per 1000 h, from a damage map's damage.csv."""
    if damage is None:
        return None
    path = Path(damage) / "damage.csv"
    if not path.is_file():
        raise InputError(f"--damage {damage}: not a damage map folder (no damage.csv); run millimpact damage first")
    with open(path) as fh:
        rows = list(csv.DictReader(line for line in fh if not line.startswith("#")))
    per_1000h = rpm * 60.0 * 1000.0
    out: dict = {}
    for r in rows:
        g = float(r.get("dent_growth_m_per_rev", "nan") or "nan")
        out[r["place"]] = {
            "dent_growth_mm_per_1000h": 1e3 * g * per_1000h if math.isfinite(g) else None,
            "repeat_verdict": r.get("repeat_verdict"),
        }
    out["is"] = "steel moved (dent growth at a spot), not removed: beside the wear, never added to it"
    return out


def life_summary(args, scene, lp, rec, cal, runner, say, clock=None):
    """Run the life (:func:`~millimpact.life.loop.run_life`, its stages timed on ``clock``) and
    gather summary.json: (the summary, the calibration, finished here for ``--calibrate-life``)."""
    reline = (args.reline_height, args.reline_plate)
    h1 = cal.calibrated_on.get("h1_mm")
    if h1 is not None:
        say(
            f"  life: steps at the first mill run's decay constants until the lifters are {h1:g} mm high "
            "(their hours scaled to the figure's after)"
        )
    steps, rates, why = run_life(
        lp,
        rec,
        cal.law,
        args.hours,
        args.cycles,
        reline,
        runner,
        scene.ball.radius,
        say,
        clock,
        getattr(args, "max_step_depth", None),
        stop_height=None if h1 is None else 1e-3 * h1,
    )
    if h1 is not None:
        cal, factor = through_life(cal, steps[-1].hours, args.hours)
        steps, rates = rescaled(steps, rates, factor)
        say(f"  life: the lifters reach {h1:g} mm at {args.hours:g} h with the constants x {factor:.3f}")
    first = rates[0]
    spread = {
        f"{label}": hours_to_reline(lp, first, reline, f)
        for label, f in (("constants", 1.0), ("constants_high", 1.0 + cal.spread), ("constants_low", 1.0 - cal.spread))
    }
    base = spread["constants"]
    relining = {
        "criterion": {"lifter_height_h": "lifter height", "plate_thickness_h": "plate thickness"}[base["first"]],
        "hours": base[base["first"]],
        "from": "the new liner's rates, extrapolated at constant rate",
        "at_spread": {k: v[v["first"]] for k, v in spread.items()},
        "limits_mm": {"lifter_height": reline[0], "plate_thickness": reline[1]},
    }
    if why is not None:
        relining["reached_in_cycles"] = {"criterion": why, "hours": steps[-1].hours}
    return {
        "scene": scene.name,
        "mill": str(rec.folder),
        "hours": args.hours,
        "cycles": args.cycles,
        "max_step_depth": getattr(args, "max_step_depth", None),
        "steps": len(steps) - 1,
        "calibration": {"law": vars(cal.law), "calibrated_on": cal.calibrated_on, "spread": cal.spread},
        "rates": rates,
        "rates_are": "per surface and mill run (cycle): mm per 1000 h (mean, largest), shares, kg per 1000 h per metre",
        "metal_flow": metal_flow(args.damage, rec.rpm),
        "relining": relining,
        "profiles": [
            {"hours": s.hours, **s.profile.record(), **s.mill, "largest_step_depth_mm": s.largest_step_depth_mm}
            for s in steps
        ],
        "units": "mm, degrees, hours, kg, kW/m",
    }, cal


def write_life_outputs(stage: Path, summary: dict, rec, cal, plots: bool = True) -> None:
    """wear.csv, profiles.csv and the figures (module docstring)."""
    r = depth_rates(rec, cal.law)
    with open(stage / "wear.csv", "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(
            [
                "surface",
                "place",
                "surface_position_m",
                "abrasion_mm_per_1000h",
                "impact_mm_per_1000h",
                "total_mm_per_1000h",
                "mass_kg_per_1000h",
            ]
        )
        for k in range(rec.surface.size):
            a, i = r["abrasion_mm_per_1000h"][k], r["impact_mm_per_1000h"][k]
            place = PLACE_OF[str(rec.surface[k])]
            w.writerow(
                [
                    rec.surface[k],
                    place,
                    repr(float(rec.position[k])),
                    repr(float(a)),
                    repr(float(i)),
                    repr(float(a + i)),
                    repr(float(r["mass_kg_per_1000h"][k])),
                ]
            )
    rows = summary["profiles"]
    cols = list(rows[0])
    with open(stage / "profiles.csv", "w", newline="") as fh:
        dw = csv.DictWriter(fh, fieldnames=cols)
        dw.writeheader()
        dw.writerows(rows)
    if plots:
        _figures(stage, summary, rec, r)


def _figures(stage: Path, summary: dict, rec, rates) -> None:
    from ..results.plots import pyplot
    from .profile import LifterProfile

    plt = pyplot()
    fig, ax = plt.subplots(figsize=(7.0, 4.0))
    a, i = rates["abrasion_mm_per_1000h"], rates["impact_mm_per_1000h"]
    ax.bar(rec.position, a, width=rec.bin_m, color="C0", label="abrasion")
    ax.bar(rec.position, i, width=rec.bin_m, bottom=a, color="C3", label="impact")
    for (s0, s1), name in zip(rec.surfaces, SURFACES):
        ax.axvline(s1, color="k", lw=0.5)
        ax.text(0.5 * (s0 + s1), ax.get_ylim()[1] * 0.95, name.replace("_", " "), ha="center", va="top", fontsize=8)
    ax.set_xlabel("surface position along a lifter's unit from its trailing foot (m)")
    ax.set_ylabel("wear (mm per 1000 h)")
    ax.legend(fontsize=8, loc="center right")
    fig.tight_layout()
    fig.savefig(stage / "wear.png", dpi=120)
    plt.close(fig)

    profiles = summary["profiles"]
    fig, ax = plt.subplots(figsize=(6.0, 4.0))
    cmap = plt.get_cmap("viridis")
    hmax = max(p["hours"] for p in profiles) or 1.0
    for p in profiles:
        outline = LifterProfile.from_record(p).outline()
        ax.plot(
            [1e3 * q[0] for q in outline],
            [1e3 * q[1] for q in outline],
            color=cmap(p["hours"] / hmax),
            label=f"{p['hours']:.0f} h",
        )
    ax.set_aspect("equal")
    ax.set_xlabel("across the lifter (mm), leading face to the right")
    ax.set_ylabel("height above the plate (mm)")
    ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(stage / "profiles.png", dpi=120)
    plt.close(fig)

    fig, ax = plt.subplots(figsize=(6.0, 4.0))
    t = [p["hours"] for p in profiles]
    ax.plot(t, [p["lifter_height_mm"] for p in profiles], "k-o", label="lifter height (mm)")
    ax2 = ax.twinx()
    ax2.plot(t, [p["leading_face_angle_deg"] for p in profiles], "C3-s", label="leading face angle (deg)")
    ax2.plot(t, [p["trailing_face_angle_deg"] for p in profiles], "C0--^", label="trailing face angle (deg)")
    ax.set_xlabel("hours of operation")
    ax.set_ylabel("lifter height (mm)")
    ax2.set_ylabel("face angle (deg)")
    lines = ax.get_legend_handles_labels()
    lines2 = ax2.get_legend_handles_labels()
    ax.legend(lines[0] + lines2[0], lines[1] + lines2[1], fontsize=8, loc="center left")
    fig.tight_layout()
    fig.savefig(stage / "height_angle.png", dpi=120)
    plt.close(fig)
