"""The bins' responses from the adaptive table engine (``millimpact damage --bins-from adaptive``):
where a placed scene's bins are more than the engine's starting grid, they are read from a grid of
cases that the engine (:mod:`millimpact.studies.adaptive`) chooses by the law's own interpolation
error, instead of one case per bin.

Groups. The bins of one placed scene (one place and arc bin after any move off an edge: one mesh
per speed band) form a group. The engine covers the group's bins above the yield-onset speed V_y:
Thornton's e is 1 below V_y and drops above it (Thornton 1997), a kink bilinear interpolation
cannot follow (the bins put V_y on an edge for the same reason), so a sub-yield bin is a case of
its own; so is a bin at normal incidence (v_t = 0) among oblique ones (the law has no e_t on a
cell with a normal-incidence corner).

Coordinates: (ln v_n, angle), the grid point (v_n, a) computed as the case of speed v_n / cos(a)
at angle a. The bins' edges and the table's mesh bands are normal speeds, and at one v_n the
normal response changes with the angle only through friction (a frictionless oblique impact is
the normal impact of its normal speed), so the law's error along the angle is friction's alone.

When (per group, ``START`` = 3): with more covered bins than the engine's starting grid (3 x 3 =
9 cases, 3 when the bins share one angle), the engine runs over the bins' range of normal speed
and angle with the tolerance ``--restitution-tolerance`` (e_n and e_t absolute, F_max 2 x that,
relative) and a budget of the covered bins' count. After its starting grid, its own prediction
(:func:`projected_cases`) says how many cases it would need at least; above the budget it stops
there. Reached within the budget, each covered bin's row is interpolated; otherwise (projected
or spent budget, a grid case failed or does not fit its place) the bins are one case each, as
with ``--bins-from cases``, and the engine's cases, spent, are reported.

Rows (bilinear weights :func:`millimpact.studies.adaptive.bilinear_weights`): e_n, e_t and F_max
from the law the engine checks (:func:`map_law`: e_n and e_t bilinear, F_max bilinear in ln F_max,
exact for a power law F ~ v_n^k, where F_max itself would need lines 0.42 apart in ln v_n for
4 % at k = 1.2: k^2 h^2 / 8 <= 0.8 x 0.04),
so the reported error is these rows'; the energies (plastic, friction, to the liner) as fractions
of the case's kinetic energy (the fraction :mod:`millimpact.damage.accumulate` uses) and the
impulses and spin per unit normal speed, each times the bin's; the other quantities positive at
the four corners (dent depth, approach, contact time, peak tangential force) bilinear in ln q
(power laws of the speed: Hertz, Thornton); the rest bilinear.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

from ..commandkit.store import PieceStore
from ..errors import InputError, MillimpactError, SceneError
from ..scene.toml_io import dump_scene
from ..studies.table import TableCase, define_cases

if TYPE_CHECKING:
    from ..studies.adaptive import AdaptiveResult, Point, Values
    from .responses import BinCase, CaseRunner
# numpy comes with the engine (studies.adaptive) and the responses: imported where the map
# computes, so that the command line (its --bins-from choices) imports neither

#: where the bins' rows come from: the engine where it saves cases, else one case per bin; or one
#: case per bin always
BINS_FROM = ("adaptive", "cases")
#: the default (docs/damage.md, "Bins from the adaptive engine")
DEFAULT_BINS_FROM = "cases"
#: the engine's starting grid: START normal speeds x START angles
START = 3
#: a check passes within this fraction of the tolerance: the cases' scatter alone (0.0025 in e_n
#: at most on the plastic rig's table, a quarter of 0.01). The contact table's wider margin
#: (millimpact.studies.adaptive.CHECK_MARGIN, 0.65) also covers a wide cell's worst point lying
#: off its centre (2.24-10 m/s x 0-30 deg); a place's bins span a few tens of per cent in v_n, where
#: the error of linear interpolation of a smooth response peaks at the cell's centre
BINS_CHECK_MARGIN = 0.8
#: a group's angles spread less than this (deg, 1.7e-8 rad) are one grid line
ONE_ANGLE_DEG = 1e-6
#: the row's columns the engine's law gives (its checked quantities)
LAW_COLUMNS = {"restitution_normal": "e_n", "restitution_tangential": "e_t", "peak_normal_force_N": "f_max"}
#: energies, interpolated as fractions of the case's kinetic energy
ENERGY_COLUMNS = ("plastic_dissipation_J", "friction_dissipation_J", "energy_to_liner_J")
#: impulses and spin, interpolated per unit normal speed
MOMENTUM_COLUMNS = ("normal_impulse_N_s", "tangential_impulse_N_s", "rebound_spin_rad_s")
#: columns that are the case's definition or bookkeeping, not a response
NOT_RESPONSES = (
    "case",
    "key",
    "impact_speed_m_s",
    "impact_angle_deg",
    "ball_radius_m",
    "normal_velocity_in_m_s",
    "tangential_velocity_in_m_s",
    "wall_time_s",
    "band",
    "hertz_peak_force_N",
    "reduction_reused",
    "reduction_from_cache",
)


class EngineStopped(MillimpactError):
    """The engine stopped before its law met the tolerance (a grid case that cannot be computed,
    did not finish or does not fit its place; a starting grid that projects more cases than the
    bins): the group's bins are one case each."""


@dataclass
class Group:
    """The bins of one placed scene: those the engine covers and those computed as their own case."""

    index: int
    place: str
    arc_used_m: float
    engine: list[BinCase]
    own: list[BinCase]

    @property
    def one_angle(self) -> bool:
        """Whether the covered bins share one angle (the engine's grid has one angle line)."""
        a = [bc.bin.angle_deg for bc in self.engine]
        return not a or max(a) - min(a) <= ONE_ANGLE_DEG

    @property
    def start_cases(self) -> int:
        """The cases of the engine's starting grid: START x START, START at one angle."""
        return START if self.one_angle else START * START


@dataclass
class GroupOutcome:
    """A group's rows (bin index -> row) from the engine, the bins left to their own cases, and
    the group's report for damage.json."""

    rows: dict[int, dict] = field(default_factory=dict)
    own: list[BinCase] = field(default_factory=list)
    report: dict[str, Any] = field(default_factory=dict)
    keys: set[str] = field(default_factory=set)  #: the engine's cases (their keys)


def check_bins_from(mode: str) -> None:
    """One line for a ``--bins-from`` outside :data:`BINS_FROM`."""
    if mode not in BINS_FROM:
        raise InputError(f"--bins-from {mode}: must be one of {', '.join(BINS_FROM)}")


def group_bins(bcs: Sequence[BinCase]) -> list[Group]:
    """The computable bins grouped by placed scene (module docstring), in the order of their bins."""
    by_scene: dict[str, list[BinCase]] = {}
    for bc in bcs:
        if bc.case is not None and bc.placed.scene is not None:
            by_scene.setdefault(dump_scene(bc.placed.scene), []).append(bc)
    groups = []
    for i, members in enumerate(by_scene.values()):
        above = [bc for bc in members if not bc.bin.below_yield]
        oblique = [bc for bc in above if bc.bin.tangential_speed_m_s > 0.0]
        engine = oblique or above  # all normal: the engine's one angle line at 0 deg
        covered = {bc.bin.index for bc in engine}
        own = [bc for bc in members if bc.bin.index not in covered]
        groups.append(Group(i, members[0].bin.place, members[0].placed.arc_used_m, engine, own))
    return groups


def grid_cases(scene, points: Sequence[Point], method: str, options: dict) -> dict[Point, TableCase]:
    """The table case of each grid point (v_n, angle) on the group's placed ``scene``: speed v_n /
    cos(angle) (the bins' cases' own definition, :func:`millimpact.studies.table.define_cases`)."""
    pairs = {(vn / math.cos(math.radians(a)), a): (vn, a) for vn, a in points}
    try:
        cases = define_cases(scene, [], [], [scene.ball.radius], method, options, pairs=list(pairs))
    except (SceneError, InputError) as exc:
        raise EngineStopped(f"a grid case cannot be defined: {exc}") from None
    return {pairs[(c.speed, c.angle)]: c for c in cases}


def check_grid_fits(group: Group, cases: Sequence[TableCase], method: str, options: dict) -> None:
    """EngineStopped when a grid case's contact does not fit its place (:mod:`millimpact.damage.edges`):
    the grid's normal speeds lie within the bins', whose bands fit, so this is checked, not assumed."""
    from .edges import contact_margin, edge_room
    from .responses import BinCase

    seen: set[str] = set()
    ref = group.engine[0]
    for c in cases:
        if c.band_key in seen:
            continue
        seen.add(c.band_key)
        margin = contact_margin(BinCase(ref.bin, ref.placed, c), method, options)
        room, edge = edge_room(c.scene)
        if room < margin * (1 - 1e-9):
            raise EngineStopped(
                f"the grid case v_n {c.scene.normal_speed:.4g} m/s needs {margin * 1e3:.3g} mm from {edge}, "
                f"{room * 1e3:.3g} mm away"
            )


def run_cases(cases: Sequence[TableCase], folder: Path, runner: CaseRunner, say: Callable, comm) -> PieceStore:
    """Compute those of ``cases`` not in ``folder`` with ``runner`` (collective); the store."""
    store = PieceStore(folder)
    todo = [c for c in cases if store.load(c.key) is None]
    if todo:
        runner(todo, folder, say)
    if comm is not None:
        comm.barrier()
    return store


def law_values(row: dict) -> Values:
    """A row's e_n, e_t and F_max as the engine's values (NaN where the row has none)."""
    from .responses import finite

    return {q: finite(row.get(col)) for col, q in LAW_COLUMNS.items()}


def run_engine(
    group: Group,
    tolerance: float,
    method: str,
    options: dict,
    folder: Path,
    runner: CaseRunner,
    say: Callable,
    comm,
    rows: dict[Point, dict],
    batch: int = 2,
) -> AdaptiveResult:
    """The engine over the group's covered bins (module docstring): its result; every case's row
    goes into ``rows`` by its point (v_n, angle). EngineStopped when a grid case cannot be computed."""
    from ..studies.adaptive import adaptive_table

    scene = group.engine[0].placed.scene
    vn = [bc.bin.normal_speed_m_s for bc in group.engine]
    ang = [bc.bin.angle_deg for bc in group.engine]
    a_range = (min(ang), max(ang)) if not group.one_angle else (min(ang), min(ang))

    def compute(points: list[Point]) -> dict[Point, Values]:
        start = not rows  # the engine's first batch is its starting grid
        cases = grid_cases(scene, points, method, options)
        check_grid_fits(group, list(cases.values()), method, options)
        store = run_cases(list(cases.values()), folder, runner, say, comm)
        out = {}
        for p, c in cases.items():
            row = store.load(c.key)
            status = "did not finish" if row is None else str(row.get("status", ""))
            if row is None or not status.startswith("ok"):
                raise EngineStopped(f"the grid case v_n {p[0]:.4g} m/s at {p[1]:.3g} deg {status}")
            rows[p] = row
            out[p] = law_values(row)
        if start:  # does the engine's own prediction from its starting grid leave a saving?
            need = projected_cases(out, tolerance)
            if need > len(group.engine):
                raise EngineStopped(f"its starting grid projects {need} cases for the {len(group.engine)} bins")
        return out

    result = adaptive_table(
        compute,
        (min(vn), max(vn)),
        a_range,
        tolerance,
        len(group.engine),
        start=START,
        batch=batch,
        say=lambda s: say(f"  {s}"),
        law=map_law,
        margin=BINS_CHECK_MARGIN,
    )
    return result


def projected_cases(grid: dict[Point, Values], tolerance: float) -> int:
    """The cases the engine would need from its starting ``grid`` on: each cell split (in halves)
    until the error the engine predicts from the grid's second differences
    (:func:`millimpact.studies.adaptive.predicted_errors`, ~ h^2) is within BINS_CHECK_MARGIN of the
    tolerance, along speed and along angle; the grid those splits make and one check per cell.
    F_max enters as ln F_max (the law's form: :func:`map_law`), an absolute error within 2 x the
    tolerance."""
    from ..studies.adaptive import AdaptiveResult, predicted_errors

    speeds, angles = sorted({p[0] for p in grid}), sorted({p[1] for p in grid})
    nan = math.nan
    plain = {p: {"e_n": x["e_n"], "e_t": x["e_t"], "f_max": nan} for p, x in grid.items()}
    # ln F_max / 2 in the e_t slot: an absolute quantity held to the tolerance, i.e. ln F_max to 2 x it
    log_f = {
        p: {"e_n": nan, "e_t": 0.5 * math.log(x["f_max"]) if x["f_max"] > 0 else nan, "f_max": nan}
        for p, x in grid.items()
    }
    pred = [predicted_errors(AdaptiveResult(speeds, angles, g), tolerance) for g in (plain, log_f)]

    def parts(e: float) -> int:
        return 1 if not e > BINS_CHECK_MARGIN else 2 ** math.ceil(math.log2(math.sqrt(e / BINS_CHECK_MARGIN)))

    cells_v, cells_a = range(len(speeds) - 1), range(max(len(angles) - 1, 1))
    n_v = 1 + sum(max(parts(max(p[(i, j)][0] for p in pred)) for j in cells_a) for i in cells_v)
    n_a = (
        1
        if len(angles) == 1
        else 1 + sum(max(parts(max(p[(i, j)][1] for p in pred)) for i in cells_v) for j in cells_a)
    )
    return n_v * n_a + (n_v - 1) * max(n_a - 1, 1)


def map_law(speeds: Sequence[float], angles: Sequence[float], grid: dict[Point, Values], v: float, a: float) -> Values:
    """The law the engine checks and the rows use at (v_n, a): e_n and e_t bilinear in (ln v_n,
    angle) over the grid (:func:`millimpact.studies.adaptive.interpolate`'s), F_max bilinear in
    ln F_max (module docstring), each held at the nearest edge outside the grid."""
    from ..studies.adaptive import bilinear_weights

    w = [(p, wk) for p, wk in bilinear_weights(speeds, angles, v, a) if wk != 0.0]
    out = {q: sum(wk * grid[p][q] for p, wk in w) for q in ("e_n", "e_t")}
    f = [grid[p]["f_max"] for p, _ in w]
    out["f_max"] = math.exp(sum(wk * math.log(x) for (_, wk), x in zip(w, f))) if all(x > 0 for x in f) else math.nan
    return out


def _scale(row: dict, column: str) -> float:
    """The case's scale of a column (module docstring): its kinetic energy for the energies, its
    normal speed for the impulses and spin (1 otherwise)."""
    from .responses import finite

    vn, vt = finite(row.get("normal_velocity_in_m_s")), finite(row.get("tangential_velocity_in_m_s"))
    vt = 0.0 if math.isnan(vt) else vt
    if column in ENERGY_COLUMNS:
        return vn * vn + vt * vt  # the mass is the scene ball's in every case: it cancels
    if column in MOMENTUM_COLUMNS:
        return vn
    return 1.0


def interpolated_row(result: AdaptiveResult, rows: dict[Point, dict], bc: BinCase) -> dict:
    """The bin's row from the engine's grid (module docstring); ``status`` "ok (interpolated)",
    ``interpolated_from`` the grid cases' keys and weights."""
    from ..studies.adaptive import bilinear_weights
    from .responses import finite

    b = bc.bin
    vn, vt, a = b.normal_speed_m_s, b.tangential_speed_m_s, b.angle_deg
    w = [(p, wk) for p, wk in bilinear_weights(result.speeds, result.angles, vn, a) if wk != 0.0]
    corners = [rows[p] for p, _ in w]
    law = map_law(result.speeds, result.angles, result.grid, vn, a)
    row: dict[str, Any] = {col: law[q] for col, q in LAW_COLUMNS.items()}
    mine = {"normal_velocity_in_m_s": vn, "tangential_velocity_in_m_s": vt}
    numeric = [
        k
        for k, x in corners[0].items()
        if k not in NOT_RESPONSES and k not in LAW_COLUMNS and isinstance(x, (int, float)) and not isinstance(x, bool)
    ]
    for col in numeric:
        vals = [finite(r.get(col)) / _scale(r, col) for r in corners]
        if col not in ENERGY_COLUMNS and col not in MOMENTUM_COLUMNS and all(x > 0 for x in vals):
            row[col] = math.exp(sum(wk * math.log(x) for (_, wk), x in zip(w, vals)))
        else:
            row[col] = sum(wk * x for (_, wk), x in zip(w, vals)) * _scale(mine, col)
    row.update(mine)
    row.update(
        {
            "case": b.index,
            "key": "",
            "impact_speed_m_s": b.speed_m_s,
            "impact_angle_deg": a,
            "ball_radius_m": corners[0].get("ball_radius_m"),
            "status": "ok (interpolated)",
            "interpolated_from": [[r.get("key", ""), wk] for r, (_, wk) in zip(corners, w)],
        }
    )
    return row


def _law_covers(row: dict, bc: BinCase) -> bool:
    """Whether the law gives what the accumulation reads of the bin's own case: e_n, and e_t for
    an oblique bin."""
    e_t_needed = bc.bin.tangential_speed_m_s > 0.0
    return math.isfinite(row["restitution_normal"]) and not (
        e_t_needed and not math.isfinite(row["restitution_tangential"])
    )


def largest_errors(result: AdaptiveResult) -> dict[str, float | None]:
    """The engine's largest checked errors against its final law (its
    :meth:`~millimpact.studies.adaptive.AdaptiveResult.largest_error`); None for a quantity no
    check compared (e_t on a normal-incidence grid)."""
    from ..studies.adaptive import QUANTITIES

    worst = result.largest_error()
    compared = {q for c in result.checks for q, _ in QUANTITIES if math.isfinite(result.law_errors(c)[q])}
    names = {"e_n": "restitution_normal", "e_t": "restitution_tangential", "f_max": "peak_normal_force_rel"}
    return {names[q]: (worst[q] if q in compared else None) for q, _ in QUANTITIES}


def engine_report(result: AdaptiveResult) -> dict[str, Any]:
    """The engine's part of a group's report: grid, checks, cases, whether it reached, its errors."""
    return {
        "cases": result.cases,
        "grid_cases": len(result.grid),
        "checks": len(result.checks),
        "checks_missed": sum(not c.passed for c in result.checks),
        "reached": result.reached,
        "stopped_by_budget": result.stopped_by_budget,
        "normal_speeds_m_s": result.speeds,
        "angles_deg": result.angles,
        "largest_checked_error": largest_errors(result),
    }


def compute_group(
    group: Group, tolerance: float, method: str, options: dict, folder: Path, runner, say, comm, batch: int
) -> GroupOutcome:
    """A group's rows from the engine where it saves cases, else its bins left to their own cases."""
    out = GroupOutcome(own=list(group.own))
    rep: dict[str, Any] = {
        "group": group.index,
        "place": group.place,
        "arc_used_m": group.arc_used_m,
        "bins": len(group.engine) + len(group.own),
        "bins_covered": len(group.engine),
        "budget": len(group.engine),
        "engine": False,
        "cases": 0,
        "note": "",
    }
    out.report = rep
    vn = [bc.bin.normal_speed_m_s for bc in group.engine]
    if len(group.engine) <= group.start_cases:
        rep["note"] = f"{len(group.engine)} bin(s) to cover, the engine's starting grid needs {group.start_cases}"
    elif max(vn) <= min(vn) * (1 + 1e-9):
        rep["note"] = "the bins share one normal speed: no speed range to interpolate over"
    if rep["note"]:
        out.own += group.engine
        return out
    rows: dict[Point, dict] = {}
    try:
        result = run_engine(group, tolerance, method, options, folder, runner, say, comm, rows, batch)
    except EngineStopped as exc:
        rep["note"] = f"one case per bin: {exc}"
        rep["cases"] = len(rows)
        out.keys = {r["key"] for r in rows.values()}
        out.own += group.engine
        return out
    out.keys = {r["key"] for r in rows.values()}
    rep.update(engine_report(result))
    if not result.reached:
        rep["note"] = f"one case per bin: the tolerance was not reached within {len(group.engine)} cases"
        out.own += group.engine
        return out
    rep["engine"] = True
    for bc in group.engine:
        row = interpolated_row(result, rows, bc)
        if _law_covers(row, bc):
            out.rows[bc.bin.index] = row
        else:
            out.own.append(bc)
    rep["bins_interpolated"] = len(out.rows)
    return out


def compute_map_rows(
    bcs: Sequence[BinCase],
    folder: Path,
    runner: CaseRunner,
    say: Callable,
    comm,
    mode: str,
    tolerance: float,
    method: str,
    options: dict,
    batch: int = 2,
) -> tuple[dict[int, dict], dict[str, Any]]:
    """Each computable bin's row (bin index -> row): from the engine per group where it saves cases
    (``mode`` "adaptive"), else from its own case (:func:`millimpact.damage.responses.compute_bin_rows`);
    and damage.json's ``bins_from`` report."""
    from .responses import compute_bin_rows

    check_bins_from(mode)
    if comm is None or comm.rank == 0:
        folder.mkdir(parents=True, exist_ok=True)
    if comm is not None:
        comm.barrier()
    groups = group_bins(bcs) if mode == "adaptive" else []
    rows: dict[int, dict] = {}
    engine_keys: set[str] = set()
    reports = []
    for g in groups:
        got = compute_group(g, tolerance, method, options, folder, runner, say, comm, batch)
        rows.update(got.rows)
        engine_keys |= got.keys
        reports.append(got.report)
        r = got.report
        say(
            f"  bins of {g.place} at arc {g.arc_used_m * 1e3:.0f} mm: {len(got.rows)} of {r['bins']} interpolated"
            + (f" from {r['cases']} engine cases" if r["engine"] else "")
            + (f" ({r['note']})" if r["note"] else "")
        )
    rest = [bc for bc in bcs if bc.bin.index not in rows]
    rows.update(compute_bin_rows(rest, folder, runner, say, comm))
    own = [bc.case.key for bc in rest if bc.case is not None]
    # a grid case at a bin's own point is one case
    cases = len(engine_keys | set(own))
    return rows, bins_from_report(mode, tolerance, reports, len(own), sum(bc.case is not None for bc in bcs), cases)


def bins_from_report(
    mode: str, tolerance: float, groups: list[dict], own: int, computable: int, cases: int
) -> dict[str, Any]:
    """damage.json's ``bins_from``: the mode, the tolerance, the bins computed as their own case
    (``own``) of the ``computable``, the ``cases`` the rows rest on (the engines' and the bins'
    own), and per group and over the map the largest checked errors."""
    used = [g for g in groups if g["engine"]]
    worst: dict[str, float | None] = {}
    for q in ("restitution_normal", "restitution_tangential", "peak_normal_force_rel"):
        vals = [g["largest_checked_error"][q] for g in used if g["largest_checked_error"][q] is not None]
        worst[q] = max(vals) if vals else None
    engine_cases = sum(g["cases"] for g in groups)
    return {
        "mode": mode,
        "tolerance": tolerance,
        "tolerance_peak_force_rel": 2.0 * tolerance,
        "bins_computable": computable,
        "bins_interpolated": sum(g.get("bins_interpolated", 0) for g in used),
        "bins_own_case": own,
        "engine_cases": engine_cases,
        "engine_cases_spent": sum(g["cases"] for g in groups if not g["engine"]),
        "cases": cases,
        "largest_checked_error": worst,
        "groups": groups,
    }
