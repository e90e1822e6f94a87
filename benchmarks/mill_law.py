"""The cost of ``millimpact mill --law DIR`` against the mill's own contact law, side by side.

    .venv/bin/python benchmarks/mill_law.py LAW_DIR [--balls 200] [--revolutions 0.15] [--every 1 3 10]

The tests' small mill (0.8 m across, 17 lifters; tests/dem/mill_scenes.py) with balls of the law's
radius, --balls balls at 75 % of n_c, --revolutions from rest (no warm-up), run one after the other
in this one invocation: without --law (Yade's Hertz-Mindlin with a constant en), then with --law
and its per-contact update every N steps for each N of --every. Reported per case: Yade's steps,
CPU time (run.json) and CPU per step, and the ratios to the case without the law. The time steps
differ a little (each from its own stiffest contact): compare the CPU per step.
"""
from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _report import write_report  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
SMALL_MILL = ["--set", "liner.width=0.3", "--set", "liner.thickness=0.04", "--set", "liner.lifter_height=0.05",
              "--set", "liner.lifter_top_width=0.03", "--set", "liner.lifter_spacing=0.15",
              "--set", "liner.mill_radius=0.4"]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("law", help="a folder written by millimpact export TABLE --to yade")
    ap.add_argument("--balls", type=int, default=200)
    ap.add_argument("--revolutions", type=float, default=0.15)
    ap.add_argument("--every", type=int, nargs="+", default=[1, 3, 10])
    ap.add_argument("--out", default=str(ROOT / "benchmarks" / "out" / "mill_law"))
    a = ap.parse_args()
    code = (Path(a.law) / "contact_law_yade.py").read_text()
    key = "MILLIMPACT_LAW = "
    radius = json.JSONDecoder().raw_decode(code, code.index(key) + len(key))[0]["ball_radius_m"]
    base = [sys.executable, "-m", "millimpact.cli", "mill", "liner-segment", "--set", f"ball.radius={radius}",
            *SMALL_MILL, "--balls", str(a.balls), "--revolutions", str(a.revolutions), "--warmup", "0",
            "--no-plots", "--force"]
    cases = [("no law (en 0.92)", ["--restitution", "0.92"])]
    cases += [(f"--law, update every {n}", ["--law", str(a.law), "--law-every", str(n)]) for n in a.every]
    rows = []
    for name, extra in cases:
        folder = Path(a.out) / f"run-{len(rows)}"
        subprocess.run([*base, *extra, "--out", str(folder)], cwd=ROOT, check=True)
        y = json.loads((folder / "summary.json").read_text())["yade"]
        rows.append({"case": name, "balls": y["balls"], "steps": y["steps"], "dt_s": y["dt_s"],
                     "yade_cpu_s": y["cpu_s"], "yade_wall_s": y["wall_s"],
                     "us_per_step_cpu": 1e6 * y["cpu_s"] / y["steps"], "load_1min": os.getloadavg()[0]})
        for r in rows:
            r["cpu_per_step_ratio"] = r["us_per_step_cpu"] / rows[0]["us_per_step_cpu"]
            r["cpu_ratio"] = r["yade_cpu_s"] / rows[0]["yade_cpu_s"]
        write_report(a.out, "mill_law", rows, 1,
                     ["case", "balls", "steps", "dt (us)", "Yade CPU (s)", "us/step (CPU)", "x per step", "x run",
                      "load (1 min)"],
                     lambda r: [r["case"], str(r["balls"]), str(r["steps"]), f"{1e6 * r['dt_s']:.2f}",
                                f"{r['yade_cpu_s']:.1f}", f"{r['us_per_step_cpu']:.0f}",
                                f"{r['cpu_per_step_ratio']:.2f}", f"{r['cpu_ratio']:.2f}", f"{r['load_1min']:.1f}"],
                     note=f"; load average when written {os.getloadavg()[0]:.1f}")


if __name__ == "__main__":
    main()
