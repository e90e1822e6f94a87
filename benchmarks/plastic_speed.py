"""Benchmark: a plastic impact against its elastic twin, and the plastic step's two linearisations
side by side in one run on this machine.

Runs, one after the other, each impact only (``--set time.end=...``):
  1. the elastic scene (``paper-rig``; with ``--liner``: ``liner-segment`` with both bodies
     ``paper-steel``),
  2. the plastic scene (``paper-rig-plastic``; ``liner-segment``) with the default linearisation
     (``-impact_plastic_linearisation elastic``: the elastic operator, Anderson-accelerated),
  3. the same with ``-impact_plastic_linearisation tangent`` (today's factorized tangent; the runs
     are ``--linearisations``, default ``elastic,tangent``),
and prints the time loop (summary ``timings_s.integrate``) and the whole run (``wall_time_s``) of
each over the elastic one's, and the plastic answers' relative differences between 2 and 3
(F_max, restitution, plastic work, dent; the bound 1e-6), each against the last. The targets: the time
loop at most 2.5x the elastic one's and the run at most 2x on the rig; the liner's time loop at most 3x.
Writes benchmarks/out/plastic_speed/{plastic_speed.csv,.md}.

    .venv/bin/python benchmarks/plastic_speed.py                 # the rig, 0.3 ms
    .venv/bin/python benchmarks/plastic_speed.py --liner         # liner-segment, the scene's time
"""
from __future__ import annotations

import argparse
import json
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "benchmarks"))

from _report import write_report  # noqa: E402

KEYS = ("peak_contact_force_N", "restitution", "plastic_dissipation_J", "residual_dent_depth_m")


def run(scene: str, folder: Path, *args: str) -> dict:
    cmd = [sys.executable, "-m", "millimpact.cli", "run", scene, "-q", "--force", "--out", str(folder), *args]
    t0 = time.perf_counter()
    subprocess.run(cmd, check=True, cwd=ROOT)
    s = json.loads((folder / "summary.json").read_text())
    s["process_wall_s"] = time.perf_counter() - t0
    return s


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--liner", action="store_true", help="liner-segment instead of the rig")
    ap.add_argument("--end", type=float, default=None, help="time.end, s (rig default 3e-4; liner: the scene's)")
    ap.add_argument("--linearisations", default="elastic,tangent",
                    help="the plastic runs' -impact_plastic_linearisation values, comma-separated (the last "
                         "is the reference of the differences)")
    ap.add_argument("--petsc", default="", help="more options for the plastic runs, e.g. '-impact_plastic_anderson_depth 10'")
    ap.add_argument("--out", default=str(ROOT / "benchmarks" / "out" / "plastic_speed"))
    a = ap.parse_args()
    out = Path(a.out)
    end = a.end if a.end is not None else (None if a.liner else 3e-4)
    sets = ["--set", f"time.end={end!r}"] if end is not None else []
    if a.liner:
        elastic = ("liner-segment", ["--set", "ball.material=paper-steel", "--set", "liner.material=paper-steel"])
        plastic = "liner-segment"
    else:
        elastic, plastic = ("paper-rig", []), "paper-rig-plastic"
    runs = [("elastic", run(elastic[0], out / "elastic", *elastic[1], *sets))]
    for lin in a.linearisations.split(","):
        runs.append((f"plastic ({lin})", run(plastic, out / f"plastic-{lin}", *sets,
                                             "-impact_plastic_linearisation", lin, *a.petsc.split())))
    ref = runs[0][1]
    rows = []
    for name, s in runs:
        i = s["integration"]
        rows.append({"run": name, "scene": s["scene"], "time_loop_s": s["timings_s"]["integrate"],
                     "wall_s": s["wall_time_s"], "loop_ratio": s["timings_s"]["integrate"] / ref["timings_s"]["integrate"],
                     "wall_ratio": s["wall_time_s"] / ref["wall_time_s"],
                     **{k: s.get(k, 0.0) for k in KEYS},
                     "yielding_steps": i.get("n_plastic_steps", 0), "iterations": i.get("n_plastic_iterations", 0),
                     "max_iterations": i.get("max_plastic_iterations", 0),
                     "tangents": i.get("n_tangent_factorizations", 0)})
    for r in rows:
        for k in KEYS:
            b = rows[-1][k]
            r[f"{k}_rel_diff"] = abs(r[k] - b) / abs(b) if b and r is not rows[0] else ""

    def cells(r: dict) -> list[str]:
        return [r["run"], f"{r['time_loop_s']:.1f} ({r['loop_ratio']:.2f}x)", f"{r['wall_s']:.1f} ({r['wall_ratio']:.2f}x)",
                f"{r['peak_contact_force_N'] / 1e3:.5g}", f"{r['restitution']:.5f}", f"{r['plastic_dissipation_J']:.5g}",
                f"{r['residual_dent_depth_m'] * 1e6:.5g}",
                f"{r['yielding_steps']} / {r['iterations']} / {r['max_iterations']} / {r['tangents']}"]

    write_report(out, "plastic_speed", rows, 1,
                 ["run", "time loop s (/ elastic)", "wall s (/ elastic)", "F_max kN", "e", "plastic work J", "dent um",
                  "yielding steps / iterations / max / tangents"],
                 cells, note=f"; {'liner-segment' if a.liner else 'paper-rig'} impact, time.end {end}; one after the other")
    for r in rows[1:-1]:
        print(f"{r['run']} against {rows[-1]['run']}, relative differences: " +
              ", ".join(f"{k} {r[k + '_rel_diff']:.1e}" for k in KEYS))
    return 0


if __name__ == "__main__":
    sys.exit(main())
