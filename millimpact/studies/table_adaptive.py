"""The adaptive contact table (``millimpact table SCENE --tolerance TOL``): the engine of
:mod:`.adaptive` choosing the cases, the table engine (:mod:`.table`) computing them.

Each batch the engine asks for (the starting grid, a batch of checks, a new grid line) is one
:meth:`~millimpact.studies.table.TableRun.compute`: the cases are defined by
:func:`~millimpact.studies.table.define_cases` (their bands on the fixed ladder, so a case is the
same computation, the same key and the same result as in a fixed table), taken from ``cases/``
when a run computed them before, else spread over the MPI groups of ranks; a group keeps its band's
reduction from one batch to the next. The engine runs eager: the starting grid comes with its
cells' centres in one batch, and a batch of checks holds every open cell's check when the budget
pays for them all, else max(2, groups), so that every group has one. One batch is one barrier,
and the cases of a band in one batch share a reduction (docs: studies, the benchmark). Every rank
runs the engine on the same broadcast values, so every rank takes the same decisions.

Files, beside the table's (:func:`millimpact.studies.table_report.write_table`, whose rows carry a
``role`` column, grid or check): ``checks.csv``, one row per check with the case's values, the
law's and their errors (units in its ``#`` header); ``contact_table.json``'s ``adaptive`` block
(tolerance, budget, reached, the largest checked errors, the grid); ``adaptive_points.png``, the
chosen points over the (speed, angle) plane, checks coloured by their error.
"""

from __future__ import annotations

import csv
import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from ..errors import MillimpactError
from ..results.output_folder import OutputFolder
from .adaptive import QUANTITIES, AdaptiveResult, Law, Point, Values, adaptive_table, bilinear_weights
from .table import check_table_method, define_cases, keep_budget_gb, open_table, table_scene
from .table_report import percent

#: the table's columns of the law's quantities (e_n, e_t, F_max)
ROW_KEYS = {"e_n": "restitution_normal", "e_t": "restitution_tangential", "f_max": "peak_normal_force_N"}


def _check_columns() -> list[tuple[str, str, str]]:
    """(name, unit, definition) of checks.csv's columns."""
    out = [
        ("impact_speed_m_s", "m/s", "impact speed |v| of the check (the geometric mean of its cell's speeds)"),
        ("impact_angle_deg", "deg", "angle from the face normal (the mean of its cell's angles)"),
        ("cell_speeds_m_s", "m/s", "the checked cell's speeds, low and high"),
        ("cell_angles_deg", "deg", "the checked cell's angles, low and high"),
        ("passed", "", "1: within the tolerance (F_max: 2 x tolerance); 0: missed, the cell was split"),
        ("became_grid", "", "1: a later split made the point a grid case (the law's error there is then 0)"),
    ]
    for name, unit, what in (
        ("restitution_normal", "-", "e_n"),
        ("restitution_tangential", "-", "e_t"),
        ("peak_normal_force_N", "N", "F_max"),
    ):
        error = "|F_max / law - 1|" if what == "F_max" else f"|{what} - law|"
        rel = "_rel" if what == "F_max" else ""
        out += [
            (name, unit, f"{what} of the case"),
            (f"{name}_law", unit, f"{what} of the exported law when checked (empty: the law has none)"),
            (f"error_{name}{rel}", "-", f"{error} when checked (empty: not compared)"),
            (f"error_{name}_final{rel}", "-", "the same against the table's final law (its grid after every split)"),
        ]
    return out


#: (name, unit, definition) of checks.csv's columns
CHECK_COLUMNS = _check_columns()


def run_adaptive_table(
    scene_name: str | None,
    speed_range: tuple[float, float],
    angle_range: tuple[float, float],
    radius: float | None,
    method: str,
    options: dict,
    out: Path | OutputFolder,
    tolerance: float,
    max_cases: int,
    sets: Sequence[str] = (),
    ranks_per_case: int = 1,
    quiet: bool = False,
    start: tuple[int, int] = (3, 3),
) -> tuple[list[dict], dict[str, Any] | None]:
    """Choose and compute the table's cases (module docstring), starting from ``start`` = (speeds,
    angles; the command's default is table_command's START_SPEEDS, START_ANGLES), and write the
    table (rank 0) into ``out``. Returns the rows and the summary (:func:`adaptive_summary`; rank
    0, [] and None elsewhere)."""
    from .table_report import write_table

    check_table_method(method, ranks_per_case)
    base = table_scene(scene_name, sets)
    r = radius if radius is not None else base.ball.radius
    # the starting grid's cases defined before the folder is made: a scene that cannot mesh them
    # is one line and no folder
    define_cases(base, [speed_range[0], speed_range[1]], sorted(set(angle_range)), [r], method, options)
    run = open_table(base, method, options, out, ranks_per_case, quiet)
    # the batches come back to bands: each group keeps the reductions it builds while memory allows
    run.keep_gb = keep_budget_gb(run.world)
    angles = f"{angle_range[0]:g}-{angle_range[1]:g}" if angle_range[1] > angle_range[0] else f"{angle_range[0]:g}"
    run.say(
        f"table {base.name}, adaptive: {speed_range[0]:g}-{speed_range[1]:g} m/s x {angles} deg, tolerance "
        f"{tolerance:g} (F_max {percent(2 * tolerance)}), at most {max_cases} cases, method {method}, "
        f"{run.n_groups} group(s) of {ranks_per_case} rank(s)"
    )

    def compute(points: list[Point]) -> dict[Point, Values]:
        cases = define_cases(base, [], [], [r], method, options, pairs=points)
        done = run.compute(cases)
        values: dict[Point, Values] | str | None = None
        if run.world.rank == 0:
            failed = [c for c in cases if not str(done.get(c.index, {}).get("status", "")).startswith("ok")]
            values = (
                f"the case v = {failed[0].speed:g} m/s, angle {failed[0].angle:g} deg "
                f"{done.get(failed[0].index, {}).get('status', 'did not finish')}: the law cannot be built"
                if failed
                else {(c.speed, c.angle): {q: _value(done[c.index], q) for q, _ in QUANTITIES} for c in cases}
            )
        values = run.world.bcast(values, root=0)
        if isinstance(values, str):
            raise MillimpactError(values)
        assert values is not None
        return values

    ball = base.with_value("ball.radius", r).ball if r != base.ball.radius else base.ball
    result = adaptive_table(
        compute,
        speed_range,
        angle_range,
        tolerance,
        max_cases,
        start,
        max(2, run.n_groups),
        run.say,
        export_law(ball.mass, r),
        eager=True,
    )
    grid = [(v, a) for v in result.speeds for a in result.angles]
    checks = [c.point for c in result.checks if c.point not in set(grid)]
    # a spare case (a centre computed ahead whose cell a later split divided): computed, in no law
    points = grid + checks + [p for p in result.spare if p not in set(grid) | set(checks)]
    cases = define_cases(base, [], [], [r], method, options, pairs=points)
    done = run.compute(cases)  # every case is in cases/ now: nothing is computed
    if run.world.rank != 0:
        return [], None
    in_grid, in_checks = set(grid), set(checks)
    rows = []
    for c in cases:
        row = dict(done[c.index], case=c.index, band=c.band)
        p = (c.speed, c.angle)
        row["role"] = "grid" if p in in_grid else "check" if p in in_checks else "spare"
        rows.append(row)
    summary = adaptive_summary(result, tolerance, max_cases, len(cases))
    with run.target.staged(keep=["cases"], collective=False) as stage:
        write_table(stage, base, cases, rows, method, options, adaptive=summary)
        write_checks(stage / "checks.csv", result, tolerance, in_grid)
        plot_points(stage / "adaptive_points.png", base.name, result, tolerance)
    return rows, summary


def export_law(mass: float, radius: float) -> Law:
    """The law the DEM export writes and its Yade runtime evaluates
    (:mod:`millimpact.theory.hertz_dashpot`, :func:`millimpact.dem.export.files.fit_law`): each
    grid case's Hertz-dashpot parameters (zeta from its e_n, E* from its F_max at its normal
    speed), zeta and E* bilinear in (ln speed, angle) over the grid (held at the nearest edge
    outside), and at (v, a) the law's own e_n = e(zeta) and F_max = phi(zeta) k_no^(2/5)
    (m v_n^2)^(3/5), k_no = (4/3) E* R^(1/2), v_n = v cos(a). e_t, which the export leaves to the
    DEM code's Mindlin-Coulomb tangential law, is the table's e_t bilinear in (ln speed, angle).
    ``mass`` (kg), ``radius`` (m): the ball's."""
    from ..theory.hertz_dashpot import peak_force_factor, point_law, restitution_of_damping

    fitted: dict[tuple[Point, float, float], tuple[float, float]] = {}

    def params(p: Point, values: Values) -> tuple[float, float]:
        key = (p, values["e_n"], values["f_max"])
        if key not in fitted:
            vn = p[0] * math.cos(math.radians(p[1]))
            pl = point_law(min(values["e_n"], 1.0), values["f_max"], vn, mass, radius)
            fitted[key] = (pl.zeta, pl.e_star)
        return fitted[key]

    def law(speeds: Sequence[float], angles: Sequence[float], grid: dict[Point, Values], v: float, a: float) -> Values:
        w = [(p, wk) for p, wk in bilinear_weights(speeds, angles, v, a) if wk != 0.0]
        zeta = sum(wk * params(p, grid[p])[0] for p, wk in w)
        e_star = sum(wk * params(p, grid[p])[1] for p, wk in w)
        vn = v * math.cos(math.radians(a))
        k_no = 4.0 / 3.0 * e_star * math.sqrt(radius)
        return {
            "e_n": float(restitution_of_damping(zeta)),
            "e_t": sum(wk * grid[p]["e_t"] for p, wk in w),
            "f_max": float(peak_force_factor(zeta)) * k_no**0.4 * (mass * vn * vn) ** 0.6,
        }

    return law


def _value(row: dict, q: str) -> float:
    x = row.get(ROW_KEYS[q])
    return math.nan if x is None else float(x)


def adaptive_summary(result: AdaptiveResult, tolerance: float, max_cases: int, n_cases: int) -> dict[str, Any]:
    """The ``adaptive`` block of contact_table.json (and the header lines of the table's files)."""
    worst = result.largest_error()
    return {
        "tolerance": tolerance,
        "tolerance_peak_force_rel": 2.0 * tolerance,
        "max_cases": max_cases,
        "cases": n_cases,
        "grid_cases": len(result.grid),
        "checks": len(result.checks),
        "reached": result.reached,
        "stopped_by_budget": result.stopped_by_budget,
        "largest_checked_error": {
            "restitution_normal": worst["e_n"],
            "restitution_tangential": worst["e_t"],
            "peak_normal_force_rel": worst["f_max"],
        },
        "speeds_m_s": result.speeds,
        "angles_deg": result.angles,
        "law": "bilinear in (ln speed, angle) over the grid speeds x angles, held at the nearest edge outside",
    }


def write_checks(path: Path, result: AdaptiveResult, tolerance: float, grid: set[Point]) -> None:
    """checks.csv: one row per check (:data:`CHECK_COLUMNS`), in the order they were computed."""

    def num(x: float) -> str:
        return "" if not math.isfinite(x) else repr(float(x))

    with open(path, "w", newline="") as fh:
        fh.write(
            f"# millimpact adaptive contact table: the checks of the law (bilinear in ln speed and angle) "
            f"between its grid cases; tolerance {tolerance:g} in e_n and e_t, {2 * tolerance:g} relative in F_max\n"
        )
        fh.write("".join(f"# {n} [{u}]: {d}\n" for n, u, d in CHECK_COLUMNS))
        w = csv.writer(fh)
        w.writerow([n for n, _, _ in CHECK_COLUMNS])
        for c in result.checks:
            (v0, a0), (v1, a1) = c.cell
            final = result.law_errors(c)
            w.writerow(
                [
                    repr(c.point[0]),
                    repr(c.point[1]),
                    f"{v0!r} {v1!r}",
                    f"{a0!r} {a1!r}",
                    int(c.passed),
                    int(c.point in grid),
                    *(num(x) for q, _ in QUANTITIES for x in (c.values[q], c.law[q], c.errors[q], final[q])),
                ]
            )


def check_error(errors: Values, tolerance: float) -> float:
    """A check's error in units of its tolerance: the largest of |e_n error| / tol, |e_t error| /
    tol and |F_max error| / (2 tol) (NaN errors left out)."""
    parts = [errors[q] / (2.0 * tolerance if rel else tolerance) for q, rel in QUANTITIES]
    return max((p for p in parts if math.isfinite(p)), default=0.0)


def plot_points(path: Path, scene_name: str, result: AdaptiveResult, tolerance: float) -> None:
    """The chosen points over the (speed, angle) plane: the grid cases (squares) with the law's grid
    lines, the checks coloured by their error in units of the tolerance (circles; ringed: missed)."""
    from matplotlib.colors import LogNorm

    from ..results.plots import pyplot

    plt = pyplot()
    fig, ax = plt.subplots(figsize=(7, 4.8), constrained_layout=True)
    for v in result.speeds:
        ax.axvline(v, color="0.85", lw=0.8, zorder=0)
    for a in result.angles:
        ax.axhline(a, color="0.85", lw=0.8, zorder=0)
    gv, ga = zip(*result.grid) if result.grid else ((), ())
    ax.plot(gv, ga, "s", color="k", ms=6, label=f"grid cases ({len(result.grid)}): the law's points")
    if result.checks:
        err = [max(check_error(c.errors, tolerance), 1e-3) for c in result.checks]
        sc = ax.scatter(
            [c.point[0] for c in result.checks],
            [c.point[1] for c in result.checks],
            c=err,
            cmap="viridis",
            norm=LogNorm(vmin=min(min(err), 0.1), vmax=max(max(err), 1.0)),
            s=60,
            edgecolors=["r" if not c.passed else "none" for c in result.checks],
            linewidths=1.5,
            label=f"checks ({len(result.checks)}; red ring: missed, its cell split)",
            zorder=3,
        )
        fig.colorbar(sc, ax=ax, label="check's error / tolerance (F_max: / 2 tolerance)")
    ax.set_xscale("log")
    ax.set_xlabel("impact speed [m/s]")
    ax.set_ylabel("angle from the face normal [deg]")
    state = "reached" if result.reached else "not reached (budget)"
    ax.set_title(f"adaptive contact table {scene_name}: tolerance {tolerance:g}, {state}", fontsize=10)
    ax.legend(fontsize=7, loc="upper left", bbox_to_anchor=(0, -0.14), ncol=2, frameon=False)
    fig.savefig(path, dpi=130)
    plt.close(fig)
