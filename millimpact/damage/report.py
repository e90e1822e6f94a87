"""The damage map's files (rank 0): ``damage.csv`` (one row per place), ``bins.csv`` (one row per
bin), ``profile.csv`` (rates along the profile), ``damage.json`` (the summary: the bin choice,
the places, the warnings, the model's limits, the wall time per stage) and ``damage_map.png`` (the liner's profile
coloured by plastic work per revolution beside the impact-energy spectrum).

Each file is written to a temporary name and renamed; ``damage.json`` comes last and says
``"complete": true``, so an interrupted map never leaves a summary that looks complete.
"""

from __future__ import annotations

import csv
import json
import math
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from .. import __version__
from ..commandkit.store import write_atomic
from ..dem.impacts import PLACES, Impact, impact_column

#: where the model stops (foundations.md section 12): said in every file that shows its numbers
LIMITS = (
    "small-strain J2 plasticity (equivalent plastic strain up to ~0.1); no wear: no material is "
    "removed; no fatigue cracking; impacts at one spot repeat the place's dominant bin only"
)

#: damage.csv's columns: (name, definition); units are in the names
PLACE_COLUMNS = [
    ("place", "lifter_face, lifter_top or plate"),
    ("impacts_per_rev", "impacts on the place per revolution (per lifter)"),
    ("impact_energy_J_per_rev", "the impacts' kinetic energy per revolution"),
    ("energy_absorbed_J_per_rev", "sum of (1 - e_n^2) m v_n^2/2 + (1 - e_t^2) m v_t^2/7 per revolution"),
    ("plastic_work_J_per_rev", "plastic work in the liner and ball per revolution"),
    (
        "impacts_left_out_per_rev",
        "impacts of refused or failed bins per revolution (not in the sums: when > 0 the sums are lower bounds)",
    ),
    (
        "impacts_edge_clamped_per_rev",
        "impacts of bins computed away from an edge so that their contact fits "
        "on the place (docs/damage.md, edge impacts)",
    ),
    ("largest_edge_shift_m", "the largest such move of a bin's representative, along the surface"),
    ("dominant_bin", "the bin with the largest plastic work (else absorbed energy) per revolution"),
    ("dominant_normal_speed_m_s", "its representative normal speed"),
    ("dominant_angle_deg", "its representative angle from the surface normal"),
    ("repeat_verdict", "the repeated-impact sequence's verdict at the dominant bin"),
    ("impacts_to_shakedown", "impacts at one spot until shakedown (NaN: none within the sequence)"),
    ("repeat_impacts", "impacts computed in the sequence"),
    ("dent_depth_first_m", "residual dent depth after the first impact"),
    ("dent_depth_last_m", "residual dent depth after the sequence's last impact"),
    ("dent_growth_per_impact_m", "dent depth added by the sequence's last impact (0 after shakedown)"),
    ("spot_impacts_per_rev", "impacts per revolution on one dent-sized spot of the place"),
    ("dent_growth_m_per_rev", "dent growth per revolution at a spot"),
    ("revolutions_to_shakedown", "revolutions until a spot shakes down"),
    ("max_eq_plastic_strain_first", "largest equivalent plastic strain after the first impact"),
    ("rock_impacts_per_rev", "rock impacts on the place per revolution (a SAG charge's log; not computed)"),
    ("rock_impact_energy_J_per_rev", "the rock impacts' kinetic energy per revolution"),
    ("max_eq_plastic_strain_last", "largest equivalent plastic strain after the last impact"),
    ("max_eq_plastic_strain_growth_per_impact", "its increase by the last impact"),
    ("revolutions_to_small_strain_limit", "revolutions until it reaches 0.1 at that increase (inf: never)"),
]

BIN_COLUMNS = [
    "bin",
    "place",
    "arc_low_m",
    "arc_high_m",
    "arc_used_m",
    "normal_speed_low_m_s",
    "normal_speed_high_m_s",
    "angle_low_deg",
    "angle_high_deg",
    "impacts",
    "normal_speed_m_s",
    "tangential_speed_m_s",
    "speed_m_s",
    "angle_deg",
    "below_yield",
    "restitution_normal",
    "restitution_tangential",
    "table_plastic_dissipation_J",
    "residual_dent_depth_m",
    "peak_normal_force_N",
    "impacts_per_rev",
    "energy_absorbed_J_per_rev",
    "plastic_work_J_per_rev",
    "contact_margin_m",
    "edge_shift_m",
    "case_key",
    "response",
    "status",
    "note",
]


def _csv(path: Path, header: Sequence[str], rows: Sequence[Sequence[Any]], comments: Sequence[str] = ()) -> None:
    def write(tmp: Path) -> None:
        with open(tmp, "w", newline="") as fh:
            for c in comments:
                fh.write(f"# {c}\n")
            w = csv.writer(fh)
            w.writerow(header)
            for r in rows:
                w.writerow([f"{x:.10g}" if isinstance(x, float) else x for x in r])

    write_atomic(path, write)


def write_outputs(
    out: Path,
    summary: dict,
    places: dict[str, dict],
    bin_rows: list[dict],
    profile: dict,
    impacts: Sequence[Impact],
    liner,
    revolutions: float,
    lifters: int,
    times: Callable[[], dict] | None = None,
) -> None:
    """Write the map's files into ``out`` (module docstring); ``damage.json`` last, with the
    entries ``times()`` gives just before it (the command's wall time per stage)."""
    out = Path(out)
    head = [
        f"millimpact {__version__} damage map of scene '{summary['scene']}' from {summary['impacts_file']}",
        f"per revolution: {summary['impacts']} impacts over {revolutions:g} revolutions and {lifters} lifter(s)",
        f"model limits: {LIMITS}",
    ]
    _csv(
        out / "damage.csv",
        [c for c, _ in PLACE_COLUMNS],
        [[p] + [places[p].get(c, math.nan) for c, _ in PLACE_COLUMNS[1:]] for p in PLACES if p in places],
        head + [f"{c}: {d}" for c, d in PLACE_COLUMNS],
    )
    _csv(out / "bins.csv", BIN_COLUMNS, [[r.get(c, "") for c in BIN_COLUMNS] for r in bin_rows], head)
    prof_rows = [
        [p, s, wp, wa]
        for p, d in profile.items()
        for s, wp, wa in zip(d["arc_m"], d["plastic_work_J_per_rev_m"], d["energy_absorbed_J_per_rev_m"])
    ]
    _csv(
        out / "profile.csv",
        ["place", "arc_m", "plastic_work_J_per_rev_m", "energy_absorbed_J_per_rev_m"],
        prof_rows,
        head + ["arc_m: cell centre, from the lifter's centre line, positive towards its leading face"],
    )
    write_atomic(
        out / "damage_map.png", lambda tmp: plot_map(tmp, profile, impacts, liner, revolutions, lifters, places)
    )
    timing = times() if times is not None else {}
    full = {**summary, "places": places, "bins": bin_rows, "model_limits": LIMITS, **timing, "complete": True}
    write_atomic(out / "damage.json", lambda tmp: tmp.write_text(json.dumps(full, indent=1, default=_jsonable)))


def _jsonable(x: Any) -> Any:
    if isinstance(x, (np.floating, np.integer)):
        return x.item()
    return str(x)


def profile_points(liner, place: str, arc: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Points (arc position across, height above the plate, m) of the unrolled profile for arc
    positions ``arc`` on ``place``: the plate at height 0, a lifter face where its projection
    meets the arc position, the top at the lifter height."""
    hb, ht, h = 0.5 * liner.lifter_base_width, 0.5 * liner.lifter_top_width, liner.lifter_height
    a = np.asarray(arc, float)
    if place == "plate":
        return a, np.zeros_like(a)
    if place == "lifter_top":
        return a, np.full_like(a, h)
    if abs(hb - ht) < 1e-12:
        return np.sign(a) * hb, np.full_like(a, 0.5 * h)
    f = np.clip((hb - np.abs(a)) / (hb - ht), 0.0, 1.0)
    return a, f * h


def _spectrum_points(n: int, most: int = 4000) -> np.ndarray:
    """Indices of a sorted spectrum's points to draw: all of them up to ``most``, else ``most``
    log-spaced ones (the count at each drawn point is exact; a figure shows no more)."""
    if n <= most:
        return np.arange(n)
    return np.unique(np.geomspace(1, n, most).astype(np.int64)) - 1


def plot_map(
    path: Path, profile: dict, impacts: Sequence[Impact], liner, revolutions: float, lifters: int, places: dict
) -> None:
    """The liner's profile coloured by plastic work per revolution per metre of arc (left) and the
    impact-energy spectrum, cumulative impacts per revolution against energy (right)."""
    from ..results.plots import pyplot

    plt = pyplot()
    from matplotlib.collections import LineCollection
    from matplotlib.colors import LogNorm, Normalize

    fig, (ax, bx) = plt.subplots(1, 2, figsize=(12, 4.8))
    fig.subplots_adjust(left=0.07, right=0.98, bottom=0.13, top=0.93, wspace=0.3)
    hb, ht, h = 0.5 * liner.lifter_base_width, 0.5 * liner.lifter_top_width, liner.lifter_height
    span = max([abs(s) for d in profile.values() for s in d["arc_m"]] + [hb + 0.05])
    outline = np.array([[-span, 0], [-hb, 0], [-ht, h], [ht, h], [hb, 0], [span, 0]])
    ax.plot(outline[:, 0] * 1e3, outline[:, 1] * 1e3, color="0.75", lw=6, solid_capstyle="round", zorder=1)
    segs: list[np.ndarray] = []
    values: list[float] = []
    for p, d in profile.items():
        s = np.asarray(d["arc_m"])
        if s.size == 0:
            continue
        w = np.asarray(d["plastic_work_J_per_rev_m"])
        cell = float(np.diff(s).min()) if s.size > 1 else 0.01
        for si, wi in zip(s, w):
            xs, ys = profile_points(liner, p, np.array([si - 0.5 * cell, si + 0.5 * cell]))
            segs.append(np.column_stack([xs, ys]) * 1e3)
            values.append(float(wi))
    vals = np.asarray(values, float)
    if segs:
        pos = vals[vals > 0]
        norm = (
            LogNorm(pos.min(), pos.max())
            if pos.size and pos.max() > pos.min()
            else Normalize(0, max(vals.max(), 1e-30))
        )
        lc = LineCollection(segs, cmap="inferno_r", norm=norm, linewidths=6, zorder=2)
        lc.set_array(np.where(vals > 0, vals, norm.vmin if isinstance(norm, LogNorm) else 0.0))
        ax.add_collection(lc)
        fig.colorbar(lc, ax=ax, label="plastic work per revolution (J/(rev m) of arc)")
    ax.set_xlabel("arc position from the lifter's centre line (mm), + towards its leading face")
    ax.set_ylabel("height above the plate (mm)")
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_title("liner profile: damage rate (small strain; no wear, no cracking)", fontsize=9)
    per_rev = 1.0 / (revolutions * lifters)
    energy, place = impact_column(impacts, "impact_energy_J"), impact_column(impacts, "place")
    for p in PLACES:
        e = np.sort(energy[place == p])[::-1]
        if e.size:
            k = _spectrum_points(e.size)
            bx.step(np.maximum(e[k], 1e-12), (k + 1) * per_rev, where="post", label=p.replace("_", " "))
    e_all = np.sort(energy)[::-1]
    k = _spectrum_points(e_all.size)
    bx.step(np.maximum(e_all[k], 1e-12), (k + 1) * per_rev, where="post", color="k", lw=1.5, label="all")
    bx.set_xscale("log")
    bx.set_yscale("log")
    bx.set_xlabel("impact energy (J)")
    bx.set_ylabel("impacts per revolution with at least this energy (1/rev)")
    bx.set_title("impact-energy spectrum", fontsize=9)
    bx.legend(fontsize=8)
    fig.savefig(path, dpi=120, format="png")
    plt.close(fig)
