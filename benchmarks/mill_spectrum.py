"""Speed of ``millimpact mill``: 2 revolutions of 200 balls in the liner-panel mill (11 m across, 77
lifters), one and two Yade threads, run one after the other in this one invocation.

The target: 2 revolutions of about 200 balls in under 5 minutes on 2 cores. Reported per
case: the wall time of the whole command, Yade's own wall and CPU time (run.json), the steps and
the time per step. On a loaded machine the wall time is inflated; Yade's CPU time is not.

    .venv/bin/python benchmarks/mill_spectrum.py [--balls 200] [--revolutions 2] [--threads 1 2]

The table is rewritten after each case, so an interrupted run keeps the cases it finished. On an
oversubscribed machine two Yade threads are far slower than one (OpenMP's threads wait for each
other at every step): measured 2026-11-27 at load 13, the first 5 % took 40 s with one thread and
370 s with two.
"""
from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _report import write_report  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scene", default="liner-panel")
    ap.add_argument("--balls", type=int, default=200)
    ap.add_argument("--revolutions", type=float, default=2.0)
    ap.add_argument("--warmup", type=float, default=0.0, help="revolutions before logging (default 0: the 2 "
                                                             "revolutions are all that is simulated)")
    ap.add_argument("--threads", type=int, nargs="+", default=[1, 2])
    ap.add_argument("--out", default=str(ROOT / "benchmarks" / "out" / "mill_spectrum"))
    a = ap.parse_args()
    rows = []
    for threads in a.threads:
        folder = Path(a.out) / f"run-j{threads}"
        cmd = [sys.executable, "-m", "millimpact.cli", "mill", a.scene, "--revolutions", str(a.revolutions),
               "--balls", str(a.balls), "--warmup", str(a.warmup), "--no-plots", "--force", "--out", str(folder)]
        env = {**os.environ, "MILLIMPACT_YADE_THREADS": str(threads)}
        t0 = time.perf_counter()
        subprocess.run(cmd, cwd=ROOT, env=env, check=True)
        wall = time.perf_counter() - t0
        s = json.loads((folder / "summary.json").read_text())
        y = s["yade"]
        rows.append({"threads": threads, "balls": s["charge"]["balls"], "revolutions": a.revolutions,
                     "warmup_revolutions": a.warmup, "steps": y["steps"], "dt_s": y["dt_s"], "wall_s": wall,
                     "yade_wall_s": y["wall_s"], "yade_cpu_s": y["cpu_s"],
                     "us_per_step_wall": 1e6 * y["wall_s"] / y["steps"],
                     "impacts_per_revolution": s["impacts_per_revolution"]["all"],
                     "energy_balance_error": s["energy_balance"]["relative_error"],
                     "load_1min": os.getloadavg()[0]})
        report(a.out, rows)


def report(out, rows) -> None:
    """mill_spectrum.csv / .md of the cases run so far."""
    write_report(out, "mill_spectrum", rows, 1,
                 ["Yade threads", "balls", "revolutions", "steps", "wall (s)", "Yade wall (s)", "Yade CPU (s)",
                  "us/step (wall)", "load (1 min)"],
                 lambda r: [str(r["threads"]), str(r["balls"]), f"{r['revolutions']:g}", str(r["steps"]),
                            f"{r['wall_s']:.0f}", f"{r['yade_wall_s']:.0f}", f"{r['yade_cpu_s']:.0f}",
                            f"{r['us_per_step_wall']:.0f}", f"{r['load_1min']:.1f}"],
                 note=f"; load average when written {os.getloadavg()[0]:.1f}")


if __name__ == "__main__":
    main()
