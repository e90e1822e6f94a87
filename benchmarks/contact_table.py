"""Benchmark: a DEM contact table: its wall time, the cost per case after the first of
each band against a standalone run of the same case cut to the impact, and 1 against N ranks.

Runs ``millimpact table SCENE --velocity ... --angle ...`` at 1 rank and (with ``--ranks N``) under
``mpirun -n N --ranks-per-case 1``, each into its own folder (no reuse between them), and one
standalone ``millimpact run`` of the table's fastest normal case cut to the impact. The target
targets: the 100-case table (10 speeds 0.5-10 m/s x 10 angles 0-60 deg) on paper-rig with improved
in under 5 minutes on 2 cores; a case after the first of its band at most 1/10 of the standalone
run; parallel efficiency (cases per second per rank) >= 0.9; the peak resident memory of the busiest rank. Writes
benchmarks/out/contact_table/contact_table_bench.{csv,md}.

    .venv/bin/python benchmarks/contact_table.py                       # the 100 cases, 1 and 2 ranks
    .venv/bin/python benchmarks/contact_table.py --speeds 1,3 --angles 0,30 --ranks 2   # a quick look
    .venv/bin/python benchmarks/contact_table.py --ranks 64            # on a larger machine
"""
from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time
from pathlib import Path

import millimpact  # noqa: F401  (before numpy: it chooses OpenBLAS's kernels, millimpact/__init__.py)
import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "benchmarks"))
sys.path.insert(0, str(ROOT))

from _report import timed_run, write_report  # noqa: E402


def table(folder: Path, scene: str, speeds: str, angles: str, ranks: int, extra: list[str]) -> tuple[list[dict], float, float]:
    cmd = [sys.executable, "-m", "millimpact.cli", "table", scene, "--velocity", speeds, "--angle", angles,
           "--out", str(folder), "-q", *extra]
    _, wall, peak_gb = timed_run(cmd + (["--ranks-per-case", "1"] if ranks > 1 else []), ranks, ROOT)
    rows = json.loads((folder / "contact_table.json").read_text())["rows"]
    return rows, wall, peak_gb


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--scene", default="paper-rig")
    ap.add_argument("--speeds", default=",".join(f"{v:.4g}" for v in np.geomspace(0.5, 10.0, 10)))
    ap.add_argument("--angles", default=",".join(f"{a:g}" for a in np.linspace(0.0, 60.0, 10).round(2)))
    ap.add_argument("--ranks", type=int, default=2, help="also run under mpirun -n RANKS (1: serial only)")
    ap.add_argument("--set", action="append", default=[], help="FIELD=VALUE for every run")
    ap.add_argument("--out", default=str(ROOT / "benchmarks" / "out" / "contact_table"))
    a = ap.parse_args()
    out = Path(a.out)
    import shutil

    shutil.rmtree(out, ignore_errors=True)
    extra = [x for s in a.set for x in ("--set", s)]
    results = []
    for ranks in sorted({1, a.ranks}):
        rows, wall, peak_gb = table(out / f"np{ranks}", a.scene, a.speeds, a.angles, ranks, extra)
        ok = [r for r in rows if str(r["status"]).startswith("ok")]
        reused = [r["wall_time_s"] for r in rows if r.get("reduction_reused")]
        first = [r["wall_time_s"] for r in rows if not r.get("reduction_reused")]
        results.append({"ranks": ranks, "cases": len(rows), "ok": len(ok), "bands": len(first), "wall_s": wall,
                        "peak_rss_per_rank_GB": peak_gb,
                        "cases_per_s_per_rank": len(rows) / wall / ranks,
                        "mean_first_case_s": float(np.mean(first)) if first else float("nan"),
                        "mean_reused_case_s": float(np.mean(reused)) if reused else float("nan")})
    # the standalone run of the fastest normal case, cut to the impact
    from millimpact.scene.builtin import resolve_scene
    from millimpact.studies.table import case_t_end

    v = max(float(x) for x in a.speeds.split(","))
    sc = resolve_scene(a.scene).with_value("impact.velocity", [0.0, -v, 0.0])
    t0 = time.perf_counter()
    subprocess.run([sys.executable, "-m", "millimpact.cli", "run", a.scene, "-q", "--force", "--out", str(out / "standalone"),
                    "--set", f"impact.velocity=[0.0,{-v!r},0.0]", "--set", f"time.end={case_t_end(sc)!r}", *extra],
                   check=True, cwd=ROOT)
    standalone = time.perf_counter() - t0
    base = results[0]["cases_per_s_per_rank"]
    for r in results:
        r["parallel_efficiency"] = r["cases_per_s_per_rank"] / base
        r["standalone_run_s"] = standalone
        r["reused_over_standalone"] = r["mean_reused_case_s"] / standalone
    write_report(out, "contact_table_bench", results, a.ranks,
                 ["ranks", "cases (ok)", "bands", "wall s", "cases/s/rank", "efficiency", "first case s",
                  "reused case s", "standalone run s", "reused / standalone", "peak RSS of a rank GB"],
                 lambda r: [str(r["ranks"]), f"{r['cases']} ({r['ok']})", str(r["bands"]), f"{r['wall_s']:.0f}",
                            f"{r['cases_per_s_per_rank']:.4f}", f"{r['parallel_efficiency']:.2f}",
                            f"{r['mean_first_case_s']:.1f}", f"{r['mean_reused_case_s']:.1f}", f"{r['standalone_run_s']:.1f}",
                            f"{r['reused_over_standalone']:.2f}", f"{r['peak_rss_per_rank_GB']:.2f}"],
                 note=f"; scene {a.scene}, speeds {a.speeds} m/s, angles {a.angles} deg, {os.cpu_count()} cores")
    return 0


if __name__ == "__main__":
    sys.exit(main())
