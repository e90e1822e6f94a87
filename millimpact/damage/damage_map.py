"""The damage map's flow: impacts -> bins (:mod:`millimpact.damage.bins`) -> placed scenes
(:mod:`millimpact.damage.places`) -> table cases and repeated-impact sequences
(:mod:`millimpact.damage.responses`) -> sums per place and revolution
(:mod:`millimpact.damage.accumulate`) -> files (:mod:`millimpact.damage.report`). Rank 0 writes
and prints.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from .. import __version__
from ..commandkit.store import PieceStore, kept_note
from ..commandkit.timing import StageClock
from ..console import sayer
from ..dem.impacts import Impact, impact_column
from ..errors import InputError
from ..interrupts import raise_if_interrupted
from ..results.output_folder import OutputFolder, claim_output
from ..scene.schema import Scene
from ..scene.toml_io import scene_to_dict
from .accumulate import accumulate, dent_trend, dominant_bin, place_extent, place_totals, profile_rates
from .adaptive_bins import DEFAULT_BINS_FROM, check_bins_from, compute_map_rows
from .bins import choose_bins, describe, yield_onset_speed
from .edges import fit_contacts
from .places import liner_of, place_scene
from .responses import BinCase, CaseRunner, define_bin_cases, finite, run_repeat, table_runner

#: a bin at or below V_y whose table case reports more plastic work than this fraction of its
#: kinetic energy is flagged (the map counts no plastic work there: Thornton 1997)
SUBYIELD_PLASTIC_FLAG = 1e-6
#: a ball radius this far (relative) from the scene's is flagged (the response is the scene ball's)
RADIUS_MISMATCH = 0.05
#: what a map keeps in its folder as it goes (finished bins, finished sequences): reused by a rerun
KEPT = ("cases", "repeat")
#: what damage.json's wall_time_s holds
WALL_TIME_IS = (
    "this command's wall seconds on rank 0: reading the impact log (read_impacts), binning and placing "
    "the bins (plan), the bins' table cases (bins), the repeated-impact sequences (repeated_impacts), the "
    "outputs up to this file (report), the rest (other) and the whole (total); bins and sequences taken "
    "from DIR/cases and DIR/repeat cost nothing"
)


@dataclass
class MapSettings:
    """The map's choices (see ``millimpact damage --help``)."""

    revolutions: float
    lifters: int = 1
    slice_length_m: float | None = None
    max_bins: int = 30
    tolerance: float = 0.02
    angle_bins: int = 2
    arc_bins: int = 1
    cell_m: float = 0.01
    method: str = "improved"
    options: dict = field(default_factory=dict)
    petsc_options: dict = field(default_factory=dict)
    repeat_impacts: int = 6
    ranks_per_case: int = 1
    #: the bins' rows: "adaptive" (the table engine's grid where it saves cases) or "cases" (one per bin)
    bins_from: str = DEFAULT_BINS_FROM
    #: the log's rock impacts per place (:func:`millimpact.dem.impacts.kind_totals`), set beside the balls'
    rock_per_place: dict | None = None


@dataclass
class MapPlan:
    """The map's bins decided before anything is computed (:func:`plan_map`): the choice, each
    bin's placed scene and table case, the edge moves, and the warnings said so far."""

    choice: Any
    v_y: float
    bin_cases: list
    edges: dict
    warnings: list[str]


def check_repeat_method(method: str, repeat_impacts: int) -> None:
    """One line for a method the repeated-impact stage cannot run (it runs the FE methods of
    ``millimpact repeat``), before anything is computed."""
    from ..repeat.command import METHODS

    if repeat_impacts > 0 and method not in METHODS:
        raise InputError(
            f"--method {method}: the repeated-impact stage runs {', '.join(METHODS)} only; add "
            f"--repeat-impacts 0 for a map without it, or choose one of those methods"
        )


def plan_map(
    scene: Scene, impacts: Sequence[Impact], settings: MapSettings, say: Callable = lambda *a: None
) -> MapPlan:
    """Bin ``impacts``, place each bin's scene, define its table case and fit its contact on its
    place (:mod:`millimpact.damage.edges`), saying each bin; InputError (one line) when no bin can
    be computed (a setting every bin hits, such as a time.end below the contact step)."""
    st = settings
    warnings: list[str] = []

    def warn(text: str) -> None:
        warnings.append(text)
        say(f"  warning: {text}")

    check_bins_from(st.bins_from)
    v_y = yield_onset_speed(scene)
    choice = choose_bins(impacts, v_y, st.max_bins, st.tolerance, st.angle_bins, st.arc_bins)
    say(
        f"damage map of {scene.name}: {len(impacts)} {_impacts(len(impacts))} over {st.revolutions:g} "
        f"revolution(s); {describe(choice)}"
    )
    for n in choice.notes:
        warn(n)
    off = int(
        np.count_nonzero(np.abs(impact_column(impacts, "ball_radius_m") / scene.ball.radius - 1) > RADIUS_MISMATCH)
    )
    if off:
        warn(
            f"{off} of {len(impacts)} impacts have a ball radius more than {RADIUS_MISMATCH:.0%} from the scene's "
            f"{scene.ball.radius:g} m: their response is the scene ball's, their energies their own"
        )
    placed, cache = {}, {}
    for b in choice.bins:
        raise_if_interrupted()
        k = (b.place, b.arc_m)
        if k not in cache:
            cache[k] = place_scene(scene, b.place, b.arc_m)
            if cache[k].note:
                warn(f"{b.place} at arc {b.arc_m:.4g} m extrapolated: {cache[k].note}")
            if cache[k].refused:
                warn(f"{b.place} at arc {b.arc_m:.4g} m refused: {cache[k].refused}")
        placed[b.index] = cache[k]
    bcs = define_bin_cases(choice.bins, placed, st.method, st.options)
    raise_if_interrupted()
    # edge impacts: each bin's contact must fit on its place, decided before anything is computed
    placed, bcs, edges = fit_contacts(scene, choice.bins, placed, bcs, st.method, st.options, warn)
    raise_if_interrupted()
    if bcs and all(bc.case is None for bc in bcs):
        reasons = {bc.refused for bc in bcs}
        raise InputError(
            f"no bin can be computed: {bcs[0].refused}"
            + (
                f" (all {len(bcs)} bins)"
                if len(reasons) == 1
                else f" (bin {bcs[0].bin.index}; the other {len(bcs) - 1} refused too)"
            )
        )
    for bc in bcs:
        say(
            f"  bin {bc.bin.index}: {bc.bin.place}, arc {bc.placed.arc_used_m * 1e3:.0f} mm, v_n "
            f"{bc.bin.normal_speed_range_m_s[0]:.3g}-{bc.bin.normal_speed_range_m_s[1]:.3g} m/s, angle "
            f"{bc.bin.angle_range_deg[0]:.0f}-{bc.bin.angle_range_deg[1]:.0f} deg: {len(bc.bin.impacts)} "
            f"{_impacts(len(bc.bin.impacts))}, "
            + (
                f"refused ({bc.refused})"
                if bc.case is None
                else f"v = {bc.case.speed:.4g} m/s at {bc.case.angle:.3g} deg{' (below V_y)' if bc.bin.below_yield else ''}"
            )
        )
    return MapPlan(choice, v_y, bcs, edges, warnings)


def _impacts(n: int) -> str:
    return "impact" if n == 1 else "impacts"


def run_damage_map(
    scene: Scene,
    impacts: Sequence[Impact],
    out: Path | OutputFolder,
    settings: MapSettings,
    impacts_file: str = "",
    case_runner: CaseRunner | None = None,
    run_sequence: Callable | None = None,
    classify: Callable | None = None,
    quiet: bool = False,
    comm=None,
    prepared: MapPlan | None = None,
    clock: StageClock | None = None,
) -> dict:
    """Compute the damage map of ``impacts`` on the liner ``scene`` into ``out``, a folder or one
    claimed with :func:`~millimpact.results.output_folder.claim_output` (docs/outputs.md); returns
    the summary. Finished bins and sequences are kept in ``out/cases`` and ``out/repeat`` as they
    finish (:data:`KEPT`); the reports are staged and published at the end (rank 0).
    ``case_runner`` (default: the table engine) and ``run_sequence`` / ``classify`` (default:
    :mod:`millimpact.repeat.sequence`) may be given; ``prepared``: the map's :func:`plan_map`
    (made here, before the folder is touched, when not given); ``clock``: the command's
    :class:`~millimpact.commandkit.timing.StageClock`, whose stages end in ``wall_time_s``."""
    rank = 0 if comm is None else comm.rank
    clock = StageClock() if clock is None else clock
    say = sayer(quiet, comm)
    st = settings
    if run_sequence is None:
        check_repeat_method(st.method, st.repeat_impacts)
    if prepared is None:
        with clock.stage("plan"):
            prepared = plan_map(scene, impacts, st, say)
    plan = prepared
    target = out if isinstance(out, OutputFolder) else claim_output(out, "damage", comm=comm)
    out = target.open(KEPT, note=lambda: kept_bins_note(target))
    if comm is not None:
        comm.barrier()  # the folder exists before any rank stores a bin
    warnings = list(plan.warnings)

    def warn(text: str) -> None:
        warnings.append(text)
        say(f"  warning: {text}")

    choice, bcs, edges = plan.choice, plan.bin_cases, plan.edges
    runner = case_runner or table_runner(st.method, st.options, st.ranks_per_case)
    groups = (comm.size if comm is not None else 1) // st.ranks_per_case
    with clock.stage("bins"):
        rows, bins_from = compute_map_rows(
            bcs, out / "cases", runner, say, comm, st.bins_from, choice.tolerance, st.method, st.options, max(2, groups)
        )
    per_bin, shares = accumulate(
        impacts, choice.bins, rows, scene.ball.material.density, scene.ball.mass, st.revolutions, st.lifters
    )
    places = place_totals(impacts, choice.bins, per_bin, st.revolutions, st.lifters)
    per_rev = 1.0 / (st.revolutions * st.lifters)
    for p, tot in places.items():
        moved = [b for b in choice.bins if b.place == p and edges.get(b.index, {}).get("edge_shift_m", 0.0) > 0]
        tot["impacts_edge_clamped_per_rev"] = sum(len(b.impacts) for b in moved) * per_rev
        tot["largest_edge_shift_m"] = max((edges[b.index]["edge_shift_m"] for b in moved), default=0.0)
        if st.rock_per_place is not None:
            rock = st.rock_per_place.get(p, {})
            tot["rock_impacts_per_rev"] = rock.get("impacts_per_rev", 0.0)
            tot["rock_impact_energy_J_per_rev"] = rock.get("impact_energy_J_per_rev", 0.0)
    for bc in bcs:
        r = rows.get(bc.bin.index)
        if r is not None and not str(r.get("status", "ok")).startswith("ok"):
            warn(f"bin {bc.bin.index} failed: {r.get('status')}")
        if r is not None and bc.bin.below_yield:
            t = 0.5 * scene.ball.mass * bc.case.speed**2
            if finite(r.get("plastic_dissipation_J")) > SUBYIELD_PLASTIC_FLAG * t:
                warn(
                    f"bin {bc.bin.index} lies below V_y = {plan.v_y:.3g} m/s but its case reports plastic work "
                    f"{r['plastic_dissipation_J']:.3g} J (counted as 0)"
                )
    slice_length = st.slice_length_m or liner_of(scene).length
    with clock.stage("repeated_impacts"):
        repeats = _repeat_responses(
            scene, choice, bcs, per_bin, places, st, out, slice_length, run_sequence, classify, comm, say, warn
        )
    profile = profile_rates(impacts, shares, st.cell_m, st.revolutions, st.lifters)
    bin_rows = [_bin_row(bc, rows.get(bc.bin.index, {}), per_bin.get(bc.bin.index, {}), edges) for bc in bcs]
    summary = {
        "millimpact_version": __version__,
        "scene": scene.name,
        "impacts_file": impacts_file,
        "impacts": len(impacts),
        "revolutions": st.revolutions,
        "lifters": st.lifters,
        "slice_length_m": slice_length,
        "method": st.method,
        "options": st.options,
        "repeat_impacts": st.repeat_impacts,
        "binning": choice.report(),
        "bins_from": bins_from,
        "warnings": warnings,
        "repeats": {p: r for p, r in repeats.items()},
        "base_scene": scene_to_dict(scene),
    }
    if rank == 0:
        from .report import write_outputs

        def timing() -> dict:  # damage.json's, taken just before it is written
            return {"wall_time_s": clock.record(), "wall_time_is": WALL_TIME_IS}

        with target.staged(keep=KEPT, collective=False) as stage, clock.stage("report"):
            write_outputs(
                stage, summary, places, bin_rows, profile, impacts, scene.liner, st.revolutions, st.lifters, timing
            )
    for p, t in places.items():
        growth = t["dent_growth_m_per_rev"]
        say(
            f"  {p}: {t['impacts_per_rev']:.4g} impacts/rev, absorbed {t['energy_absorbed_J_per_rev']:.4g} J/rev, "
            f"plastic work {t['plastic_work_J_per_rev']:.4g} J/rev; repeat: {t['repeat_verdict']}"
            + (f", dent growth {growth:.3g} m/rev at a spot" if math.isfinite(growth) else "")
        )
    return {**summary, "places": places, "bins": bin_rows, "wall_time_s": clock.record()}


def _repeat_responses(
    scene,
    choice,
    bcs,
    per_bin,
    places,
    st: MapSettings,
    out: Path,
    slice_length: float,
    run_sequence,
    classify,
    comm,
    say,
    warn,
) -> dict:
    """The repeated-impact response of each place's dominant bin (place -> sequence or None); the
    place's dent growth and strain trend added to ``places``."""
    if run_sequence is None or classify is None:
        from ..repeat.sequence import run_sequence as real_sequence
        from ..repeat.verdict import classify as real_classify

        run_sequence, classify = run_sequence or real_sequence, classify or real_classify
    repeats = {}
    for p, tot in places.items():
        dom = dominant_bin(choice.bins, per_bin, p)
        bc = next((c for c in bcs if dom is not None and c.bin.index == dom), None)
        tot["dominant_bin"] = dom if dom is not None else -1
        tot["dominant_normal_speed_m_s"] = bc.case.speed * math.cos(math.radians(bc.case.angle)) if bc else math.nan
        tot["dominant_angle_deg"] = bc.case.angle if bc else math.nan
        rep = None
        if bc is not None and st.repeat_impacts > 0:
            rep = run_repeat(
                bc,
                st.repeat_impacts,
                st.method,
                st.options,
                st.petsc_options,
                out / "repeat",
                run_sequence,
                classify,
                comm,
                say,
            )
        repeats[p] = rep
        tot.update(dent_trend(rep, tot["impacts_per_rev"], place_extent(scene.liner, p), slice_length))
        if tot["max_eq_plastic_strain_last"] >= 0.1:
            warn(
                f"{p}: the largest equivalent plastic strain {tot['max_eq_plastic_strain_last']:.3g} passes the "
                "small-strain limit 0.1: the numbers there are beyond the model"
            )
    return repeats


def _bin_row(bc: BinCase, r: dict, pb: dict, edges: dict) -> dict:
    """A bin's row of bins.csv: its edges, representative, table case and sums per revolution."""
    b = bc.bin
    return {
        "bin": b.index,
        "place": b.place,
        "arc_low_m": b.arc_range_m[0],
        "arc_high_m": b.arc_range_m[1],
        "arc_used_m": bc.placed.arc_used_m,
        "normal_speed_low_m_s": b.normal_speed_range_m_s[0],
        "normal_speed_high_m_s": b.normal_speed_range_m_s[1],
        "angle_low_deg": b.angle_range_deg[0],
        "angle_high_deg": b.angle_range_deg[1],
        "impacts": len(b.impacts),
        "normal_speed_m_s": b.normal_speed_m_s,
        "tangential_speed_m_s": b.tangential_speed_m_s,
        "speed_m_s": b.speed_m_s,
        "angle_deg": b.angle_deg,
        "below_yield": b.below_yield,
        "restitution_normal": finite(r.get("restitution_normal")),
        "restitution_tangential": finite(r.get("restitution_tangential")),
        "table_plastic_dissipation_J": finite(r.get("plastic_dissipation_J")),
        "residual_dent_depth_m": finite(r.get("residual_dent_depth_m")),
        "peak_normal_force_N": finite(r.get("peak_normal_force_N")),
        "impacts_per_rev": pb.get("impacts_per_rev", math.nan),
        "energy_absorbed_J_per_rev": pb.get("energy_absorbed_J_per_rev", math.nan),
        "plastic_work_J_per_rev": pb.get("plastic_work_J_per_rev", math.nan),
        "contact_margin_m": edges.get(b.index, {}).get("contact_margin_m", math.nan),
        "edge_shift_m": edges.get(b.index, {}).get("edge_shift_m", math.nan),
        "case_key": bc.case.key if bc.case and not r.get("interpolated_from") else "",
        "response": ("interpolated" if r.get("interpolated_from") else "case") if r else "",
        "status": (r.get("status", "not computed") if bc.case else "refused"),
        "note": bc.refused or bc.placed.note,
    }


def kept_bins_note(target: OutputFolder) -> str:
    """What an interrupted map leaves: its finished bins and sequences, reused by a rerun."""
    return kept_note(
        [
            (PieceStore(target.path / "cases").count(), "bin", f"{target.shown}/cases/"),
            (PieceStore(target.path / "repeat").count(), "repeated-impact sequence", f"{target.shown}/repeat/"),
        ],
        "the map itself is not written",
    )
