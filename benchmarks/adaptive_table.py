"""Benchmark: an adaptive contact table against the fixed table it replaces, side by side in one run.

Runs, each under ``mpirun -n RANKS ... --ranks-per-case 1`` into its own folder (its own ``cases/``,
its own empty mesh cache, no reduction cache: neither table reuses the other's cases, meshes or
reductions), timed:

1. the fixed table ``millimpact table SCENE --velocity SPEEDS --angle ANGLES`` (by default
   ``paper-rig-plastic``, 10 speeds geomspace(0.5, 10) x 10 angles linspace(0, 60): 100 cases);
2. the adaptive table ``millimpact table SCENE --velocity 0.5,10 --angle 0,60 --tolerance 0.01
   --max-cases 30``.

Then the adaptive table's exported law (:func:`millimpact.dem.export.files.law_at`: the law the
Yade export writes and the adaptive checks measure) is evaluated at every point of the fixed table
and compared with its finite-element case: |e_n - law|, |e_t - law| (where the law has an e_t: not
on a cell with a normal-incidence corner) and |F_max / law - 1|.

Targets (the adaptive table's ``Done when``): at every one of the 100 points the law within 0.01
in e_n and e_t and 2 % in F_max, with at most 30 finite-element cases; the adaptive table's wall
time below 1/3 of the fixed table's. Writes benchmarks/out/adaptive_table/:
``adaptive_table_bench.{csv,md}`` (the two runs: cases, wall and CPU time, load average, the
law's largest errors, the points within tolerance), ``adaptive_table_points.{csv,md}`` (the
comparison at each point) and ``adaptive_table_errors.png`` (the points over the (speed, angle)
plane coloured by the law's error, the adaptive table's grid and check cases overlaid); the
tables themselves in ``fixed/`` and ``adaptive/``.

    .venv/bin/python benchmarks/adaptive_table.py            # the full benchmark (~25 min on 2 cores)
    .venv/bin/python benchmarks/adaptive_table.py --scene hertz-halfspace --speeds 1,2.4,6 --angles 0,30 \\
        --velocity 1,6 --angle-range 0,30 --max-cases 11 --set model.h_contact=5.8e-4 --set model.h_far=0.012
                                                              # a quick look (coarse half-space, ~1 min)
    .venv/bin/python benchmarks/adaptive_table.py --fixed-from OLD/adaptive_table_points.csv --out NEW
        # the adaptive table alone, against the fixed table's values and time of an earlier run
        # (computed once: a case equals the same case of any run to 1e-10; the time is not side by side)
"""

from __future__ import annotations

import argparse
import json
import math
import os
import shutil
import sys
from pathlib import Path

# isort: off
import millimpact  # noqa: F401  (before numpy: it chooses OpenBLAS's kernels, millimpact/__init__.py)
import numpy as np
# isort: on

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "benchmarks"))
sys.path.insert(0, str(ROOT))

from _report import timed_run_cpu, write_report  # noqa: E402

#: (quantity, key of the law, whether its error is relative) in the order they are reported
QUANTITIES = (("e_n", "e_n", False), ("e_t", "e_t", False), ("F_max", "f_max", True))


def run_table(folder: Path, scene: str, ranks: int, args: list[str]) -> dict:
    """``millimpact table SCENE ARGS --out folder`` under mpirun (groups of one rank), with its own
    empty mesh cache and no reduction cache; its wall and CPU time, peak memory and the load average."""
    cmd = [sys.executable, "-m", "millimpact.cli", "table", scene, *args, "--out", str(folder), "-q"]
    if ranks > 1:
        cmd += ["--ranks-per-case", "1"]
    saved = dict(os.environ)
    os.environ.update(
        MILLIMPACT_MESH_CACHE=str(folder.parent / f"mesh-cache-{folder.name}"),
        MILLIMPACT_REDUCTION_CACHE="off",
        PYTHONPATH=str(ROOT),
    )
    load_before = os.getloadavg()
    try:
        code, wall, peak_gb, cpu = timed_run_cpu(cmd, ranks, ROOT)
    finally:
        os.environ.clear()
        os.environ.update(saved)
    load_after = os.getloadavg()
    if code != 0:
        raise SystemExit(f"millimpact table exited {code}: {' '.join(cmd)}")
    print(f"  {folder.name}: {wall:.0f} s wall, {cpu:.0f} s CPU", flush=True)
    timing = {
        "wall_s": wall,
        "cpu_s": cpu,
        "peak_rss_per_rank_GB": peak_gb,
        "load_1min_before": load_before[0],
        "load_1_5_15min_after": " ".join(f"{x:.2f}" for x in load_after),
    }
    (folder.parent / f"{folder.name}_run.json").write_text(json.dumps(timing))  # for --report-only
    return timing


def compare(fixed, law, tolerance: float) -> list[dict]:
    """The law against each point of the fixed table ``fixed`` (a ContactTable): one row per point."""
    rows = []
    for i, v in enumerate(fixed.speeds):
        for j, a in enumerate(fixed.angles):
            at = law(float(v), float(a))
            fe = {"e_n": fixed.e_n[i, j], "e_t": fixed.e_t[i, j], "F_max": fixed.peak_force[i, j]}
            row = {"impact_speed_m_s": float(v), "impact_angle_deg": float(a)}
            within = True
            for name, key, rel in QUANTITIES:
                x, y = float(fe[name]), float(at[key])
                err = abs(x / y - 1.0) if rel else abs(x - y)
                row |= {f"{name}_fe": x, f"{name}_law": y, f"error_{name}{'_rel' if rel else ''}": err}
                # NaN: e_t of a normal impact, or of the law on a cell with a normal-incidence corner
                within &= not (math.isfinite(err) and err > (2.0 * tolerance if rel else tolerance))
            row["error_over_tolerance"] = point_error(row, tolerance)
            row["within"] = int(within)
            rows.append(row)
    return rows


def point_error(row: dict, tolerance: float) -> float:
    """A point's error in units of its tolerance: the largest of |e_n diff| / tol, |e_t diff| / tol
    and |F_max ratio - 1| / (2 tol) (an undefined e_t left out)."""
    parts = [row["error_e_n"] / tolerance, row["error_e_t"] / tolerance, row["error_F_max_rel"] / (2.0 * tolerance)]
    return max((p for p in parts if math.isfinite(p)), default=0.0)


def largest(rows: list[dict], key: str) -> float:
    return max((r[key] for r in rows if math.isfinite(r[key])), default=math.nan)


def plot(path: Path, rows: list[dict], adaptive_doc: dict, scene: str, tolerance: float) -> None:
    """The fixed table's points over the (speed, angle) plane coloured by the law's error there (in
    units of the tolerance), the adaptive table's grid lines, grid cases and checks overlaid."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.colors import Normalize
    from matplotlib.ticker import NullFormatter

    block = adaptive_doc["adaptive"]
    fig, ax = plt.subplots(figsize=(7.5, 5.2), constrained_layout=True)
    for v in block["speeds_m_s"]:
        ax.axvline(v, color="0.85", lw=0.8, zorder=0)
    for a in block["angles_deg"]:
        ax.axhline(a, color="0.85", lw=0.8, zorder=0)
    err = np.array([r["error_over_tolerance"] for r in rows])
    sc = ax.scatter(
        [r["impact_speed_m_s"] for r in rows],
        [r["impact_angle_deg"] for r in rows],
        c=err,
        cmap="viridis",
        norm=Normalize(vmin=0.0, vmax=max(err.max(), 1.0)),
        s=70,
        edgecolors=["r" if not r["within"] else "none" for r in rows],
        linewidths=1.5,
        zorder=2,
        label=f"the fixed table's {len(rows)} cases (red ring: outside the tolerance)",
    )
    fig.colorbar(sc, ax=ax, label="law's error / tolerance (F_max: / 2 tolerance)")
    for role, marker, what in (("grid", "s", "grid cases: the law's points"), ("check", "x", "check cases")):
        pts = [(r["impact_speed_m_s"], r["impact_angle_deg"]) for r in adaptive_doc["rows"] if r.get("role") == role]
        if pts:
            v, a = zip(*pts)
            face = {"markerfacecolor": "none"} if marker == "s" else {}
            ax.plot(
                v,
                a,
                marker,
                color="k",
                ms=9,
                mew=1.2,
                ls="none",
                zorder=3,
                label=f"adaptive {what} ({len(pts)})",
                **face,
            )
    ax.set_xscale("log")
    ticks = [x for x in (0.5, 1, 2, 3, 5, 10, 20) if min(block["speeds_m_s"]) <= x <= max(block["speeds_m_s"])]
    ax.set_xticks(ticks, [f"{x:g}" for x in ticks])
    ax.xaxis.set_minor_formatter(NullFormatter())
    ax.set_xlabel("impact speed [m/s]")
    ax.set_ylabel("angle from the face normal [deg]")
    within = sum(r["within"] for r in rows)
    ax.set_title(
        f"{scene}: the adaptive table's exported law (tolerance {tolerance:g})\nat the fixed table's points: "
        f"{within} of {len(rows)} within",
        fontsize=9,
    )
    ax.legend(fontsize=7, loc="upper left", bbox_to_anchor=(0, -0.12), ncol=2, frameon=False)
    fig.savefig(path, dpi=130)
    plt.close(fig)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--scene", default="paper-rig-plastic")
    ap.add_argument(
        "--speeds",
        default=",".join(f"{v:.4g}" for v in np.geomspace(0.5, 10.0, 10)),
        help="the fixed table's speeds, m/s",
    )
    ap.add_argument(
        "--angles",
        default=",".join(f"{a:g}" for a in np.linspace(0.0, 60.0, 10).round(2)),
        help="the fixed table's angles, deg",
    )
    ap.add_argument("--velocity", default="0.5,10", help="the adaptive table's speed range, m/s")
    ap.add_argument("--angle-range", default="0,60", help="the adaptive table's angle range, deg")
    ap.add_argument("--tolerance", type=float, default=0.01)
    ap.add_argument("--max-cases", type=int, default=30)
    ap.add_argument("--method", default="improved")
    ap.add_argument("--ranks", type=int, default=2)
    ap.add_argument("--set", action="append", default=[], help="FIELD=VALUE for both tables")
    ap.add_argument("--out", default=str(ROOT / "benchmarks" / "out" / "adaptive_table"))
    ap.add_argument("--report-only", action="store_true", help="no runs: the report of the tables in --out")
    ap.add_argument(
        "--fixed-from",
        metavar="CSV",
        help="the fixed table's finite-element values from an earlier report's adaptive_table_points.csv "
        "(its *_fe columns) and its time from the adaptive_table_bench.csv beside it, instead of "
        "computing it again (its cases equal the same cases of any run to 1e-10)",
    )
    a = ap.parse_args()
    out = Path(a.out)
    fixed = None
    if a.fixed_from:
        fixed, fixed_run = fixed_from_report(Path(a.fixed_from))
        out.mkdir(parents=True, exist_ok=True)
        adaptive_run = json.loads((out / "adaptive_run.json").read_text()) if a.report_only else run_adaptive(a, out)
    elif a.report_only:
        fixed_run, adaptive_run = (json.loads((out / f"{n}_run.json").read_text()) for n in ("fixed", "adaptive"))
    else:
        fixed_run, adaptive_run = run_both(a, out)
    report(a, out, fixed_run, adaptive_run, fixed)
    return 0


class FixedValues:
    """A fixed table's values as :func:`compare` reads them: speeds, angles, e_n, e_t, peak_force."""

    def __init__(self, rows: list[dict]):
        self.speeds = np.array(sorted({float(r["impact_speed_m_s"]) for r in rows}))
        self.angles = np.array(sorted({float(r["impact_angle_deg"]) for r in rows}))
        at = {(float(r["impact_speed_m_s"]), float(r["impact_angle_deg"])): r for r in rows}

        def grid(key: str) -> np.ndarray:
            return np.array([[float(at[(v, a)][key]) for a in self.angles] for v in self.speeds])

        self.e_n, self.e_t, self.peak_force = grid("e_n_fe"), grid("e_t_fe"), grid("F_max_fe")


def fixed_from_report(points_csv: Path) -> tuple[FixedValues, dict]:
    """The fixed table's values and its run's timing (marked as taken from that report)."""
    import csv

    with open(points_csv, newline="") as fh:
        fixed = FixedValues(list(csv.DictReader(fh)))
    with open(points_csv.parent / "adaptive_table_bench.csv", newline="") as fh:
        row = next(r for r in csv.DictReader(fh) if r["table"].startswith("fixed"))
    run = {
        "wall_s": float(row["wall_s"]),
        "cpu_s": float(row["cpu_s"]),
        "peak_rss_per_rank_GB": float(row["peak_rss_per_rank_GB"]),
        "load_1min_before": float(row["load_1min_before"]),
        "load_1_5_15min_after": row["load_1_5_15min_after"] + " (an earlier run)",
    }
    return fixed, run


def run_both(a: argparse.Namespace, out: Path) -> tuple[dict, dict]:
    """The fixed table, then the adaptive one, each in a fresh folder: their timings."""
    for name in ("fixed", "mesh-cache-fixed"):
        shutil.rmtree(out / name, ignore_errors=True)
    out.mkdir(parents=True, exist_ok=True)
    common = ["--method", a.method, *[x for s in a.set for x in ("--set", s)]]
    fixed_run = run_table(out / "fixed", a.scene, a.ranks, ["--velocity", a.speeds, "--angle", a.angles, *common])
    return fixed_run, run_adaptive(a, out)


def run_adaptive(a: argparse.Namespace, out: Path) -> dict:
    """The adaptive table in a fresh folder: its timing."""
    for name in ("adaptive", "mesh-cache-adaptive"):
        shutil.rmtree(out / name, ignore_errors=True)
    out.mkdir(parents=True, exist_ok=True)
    common = ["--method", a.method, *[x for s in a.set for x in ("--set", s)]]
    return run_table(
        out / "adaptive",
        a.scene,
        a.ranks,
        [
            "--velocity",
            a.velocity,
            "--angle",
            a.angle_range,
            "--tolerance",
            repr(a.tolerance),
            "--max-cases",
            str(a.max_cases),
            *common,
        ],
    )


def report(a: argparse.Namespace, out: Path, fixed_run: dict, adaptive_run: dict, fixed=None) -> None:
    """The comparison of the law with the fixed table (``fixed``: its values from an earlier report,
    else the table in ``out/fixed``), the reports and the figure."""
    from millimpact.dem.export.files import law_at
    from millimpact.dem.export.table_input import read_table

    fixed = read_table(out / "fixed") if fixed is None else fixed
    points = compare(fixed, law_at(read_table(out / "adaptive")), a.tolerance)
    doc = json.loads((out / "adaptive" / "contact_table.json").read_text())
    block = doc["adaptive"]
    checked = block["largest_checked_error"]
    runs = [
        {
            "table": f"fixed {len(fixed.speeds)} x {len(fixed.angles)}",
            "cases": len(fixed.speeds) * len(fixed.angles),
            "grid_cases": len(fixed.speeds) * len(fixed.angles),
            "checks": 0,
            **fixed_run,
        },
        {
            "table": f"adaptive, tolerance {a.tolerance:g}, at most {a.max_cases} cases",
            "cases": len(doc["rows"]),
            "grid_cases": block["grid_cases"],
            "checks": block["checks"],
            **adaptive_run,
            "tolerance_reached": block["reached"],
            "checked_e_n": checked["restitution_normal"],
            "checked_e_t": checked["restitution_tangential"],
            "checked_F_max_rel": checked["peak_normal_force_rel"],
        },
    ]
    compared_e_t = sum(math.isfinite(p["error_e_t"]) for p in points)
    summary = {
        "points": len(points),
        "points_within": sum(p["within"] for p in points),
        "largest_e_n": largest(points, "error_e_n"),
        "largest_e_t": largest(points, "error_e_t"),
        "e_t_compared": compared_e_t,
        "largest_F_max_rel": largest(points, "error_F_max_rel"),
        "wall_over_fixed": adaptive_run["wall_s"] / fixed_run["wall_s"],
        "cpu_over_fixed": adaptive_run["cpu_s"] / fixed_run["cpu_s"],
    }
    for r in runs:
        r |= {"wall_over_fixed": r["wall_s"] / fixed_run["wall_s"], "cpu_over_fixed": r["cpu_s"] / fixed_run["cpu_s"]}
    runs[1] |= {
        k: summary[k]
        for k in ("points", "points_within", "largest_e_n", "largest_e_t", "e_t_compared", "largest_F_max_rel")
    }
    runs[0] |= {k: None for k in runs[1] if k not in runs[0]}  # the CSV's columns are the first row's
    note = (
        f"; {os.cpu_count()} cores; scene {a.scene}, method {a.method}, each table under mpirun -n {a.ranks} "
        f"--ranks-per-case 1 in its own folder (no case, mesh or reduction reused between them)"
        + (f"; the fixed table's values and time from an earlier run ({a.fixed_from})" if a.fixed_from else "")
    )

    def num(x: float) -> str:
        return f"{x:.4f}" if math.isfinite(x) else "-"

    def dash(r, key, fmt):
        return "-" if r.get(key) is None else fmt(r[key])

    write_report(
        out,
        "adaptive_table_bench",
        runs,
        a.ranks,
        [
            "table",
            "FE cases (grid + checks)",
            "wall s",
            "CPU s",
            "wall / fixed",
            "CPU / fixed",
            "load 1 min before",
            "load 1/5/15 min after",
            "peak RSS of a rank GB",
            "largest error its checks measured (e_n, e_t, F_max)",
            "tolerance reached",
        ],
        lambda r: [
            r["table"],
            f"{r['cases']} ({r['grid_cases']} + {r['checks']})",
            f"{r['wall_s']:.0f}",
            f"{r['cpu_s']:.0f}",
            f"{r['wall_over_fixed']:.3f}",
            f"{r['cpu_over_fixed']:.3f}",
            f"{r['load_1min_before']:.2f}",
            r["load_1_5_15min_after"],
            f"{r['peak_rss_per_rank_GB']:.2f}",
            dash(
                r,
                "checked_e_n",
                lambda _: f"{r['checked_e_n']:.4f}, {r['checked_e_t']:.4f}, {100 * r['checked_F_max_rel']:.2f} %",
            ),
            dash(r, "tolerance_reached", lambda x: "yes" if x else "no (budget)"),
        ],
        note=note,
    )
    lines = [
        "",
        f"The adaptive table's exported law at the fixed table's {summary['points']} points against their "
        f"finite-element cases (targets: e_n and e_t within {a.tolerance:g}, F_max within "
        f"{200 * a.tolerance:g} %, at most {a.max_cases} cases, wall time below 1/3 of the fixed table's):",
        "",
        "| quantity | largest error | target | met |",
        "|---|---|---|---|",
        f"| e_n: largest abs(e_n - law) | {summary['largest_e_n']:.4f} | {a.tolerance:g} | "
        f"{'yes' if summary['largest_e_n'] <= a.tolerance else 'no'} |",
        f"| e_t: largest abs(e_t - law) ({compared_e_t} points where the law has an e_t) | "
        f"{summary['largest_e_t']:.4f} | {a.tolerance:g} | {'yes' if summary['largest_e_t'] <= a.tolerance else 'no'} |",
        f"| F_max: largest abs(F_max / law - 1) | {100 * summary['largest_F_max_rel']:.2f} % | {200 * a.tolerance:g} % | "
        f"{'yes' if summary['largest_F_max_rel'] <= 2 * a.tolerance else 'no'} |",
        f"| points within all three | {summary['points_within']} of {summary['points']} | all | "
        f"{'yes' if summary['points_within'] == summary['points'] else 'no'} |",
        f"| finite-element cases of the adaptive table | {runs[1]['cases']} | <= {a.max_cases} | "
        f"{'yes' if runs[1]['cases'] <= a.max_cases else 'no'} |",
        f"| wall time adaptive / fixed | {summary['wall_over_fixed']:.3f} | < 0.333 | "
        f"{'yes' if summary['wall_over_fixed'] < 1 / 3 else 'no'} |",
        f"| CPU time adaptive / fixed | {summary['cpu_over_fixed']:.3f} | - | - |",
        "",
        "Per point: adaptive_table_points.csv / .md; figure: adaptive_table_errors.png.",
    ]
    with open(out / "adaptive_table_bench.md", "a") as fh:
        fh.write("\n".join(lines) + "\n")
    print("\n".join(lines))

    write_report(
        out,
        "adaptive_table_points",
        points,
        a.ranks,
        [
            "speed m/s",
            "angle deg",
            "e_n FE",
            "e_n law",
            "abs diff",
            "e_t FE",
            "e_t law",
            "abs diff",
            "F_max FE N",
            "F_max law N",
            "abs(ratio - 1)",
            "error / tolerance",
            "within",
        ],
        lambda p: [
            f"{p['impact_speed_m_s']:.4g}",
            f"{p['impact_angle_deg']:g}",
            f"{p['e_n_fe']:.4f}",
            f"{p['e_n_law']:.4f}",
            f"{p['error_e_n']:.4f}",
            num(p["e_t_fe"]),
            num(p["e_t_law"]),
            num(p["error_e_t"]),
            f"{p['F_max_fe']:.5g}",
            f"{p['F_max_law']:.5g}",
            f"{100 * p['error_F_max_rel']:.2f} %",
            f"{p['error_over_tolerance']:.2f}",
            "yes" if p["within"] else "no",
        ],
        note=note,
    )
    plot(out / "adaptive_table_errors.png", points, doc, a.scene, a.tolerance)


if __name__ == "__main__":
    sys.exit(main())
