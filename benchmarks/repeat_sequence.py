"""Benchmark: a repeated-impact sequence against one impact-only run of the same scene.

Side by side, in one process tree each, on the same machine state: ``millimpact repeat SCENE
--impacts N`` against two impact-only runs of the scene: ``millimpact repeat SCENE --impacts 1``
(mesh, reduction, one impact to 0.1 t_c after separation, the sequence's first impact alone) and
``millimpact run SCENE --set time.end=T`` with T = ``--impact-end`` (0.3 ms: the impact-only run
of the plastic contact table, which writes a run's full outputs); and, for context, ``millimpact run SCENE``
(the scene's 40 ms with the closed-form free phase). The target: the 10-impact sequence on
paper-rig-plastic costs at most 3x one impact-only run. A mesh is made once first (the mesh cache
serves the timed runs). Writes benchmarks/out/repeat_sequence/repeat_sequence.{csv,md}.

    .venv/bin/python benchmarks/repeat_sequence.py                         # paper-rig-plastic, 10 impacts
    .venv/bin/python benchmarks/repeat_sequence.py --set model.h_contact=0.0006 --set model.h_far=0.01
"""
from __future__ import annotations

import argparse
import shutil
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "benchmarks"))
sys.path.insert(0, str(ROOT))

from _report import timed_run, write_report  # noqa: E402


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scene", default="paper-rig-plastic")
    ap.add_argument("--impacts", type=int, default=10)
    ap.add_argument("--set", action="append", default=[], metavar="FIELD=VALUE")
    ap.add_argument("--impact-end", type=float, default=3e-4,
                    help="time.end (s) of the impact-only `run` (default 3e-4, the plastic rig's impact-only run)")
    ap.add_argument("--out", default=str(ROOT / "benchmarks" / "out" / "repeat_sequence"))
    args = ap.parse_args()
    out = Path(args.out)
    work = out / "runs"
    shutil.rmtree(work, ignore_errors=True)
    sets = [x for s in args.set for x in ("--set", s)]
    cli = [sys.executable, "-m", "millimpact.cli"]
    # the mesh cache first: no timed run pays for gmsh
    timed_run(cli + ["repeat", args.scene, "--impacts", "1", *sets, "-q", "--out", str(work / "warm")], 1, ROOT)
    rows = []
    for name, cmd in [
        ("one impact-only run (repeat --impacts 1)", ["repeat", args.scene, "--impacts", "1", *sets, "-q",
                                                      "--out", str(work / "one")]),
        (f"sequence of {args.impacts} (repeat --impacts {args.impacts})",
         ["repeat", args.scene, "--impacts", str(args.impacts), *sets, "-q", "--out", str(work / "seq")]),
        (f"one impact-only run (run --set time.end={args.impact_end:g})",
         ["run", args.scene, "--method", "improved", *sets, "-q", "--set", f"time.end={args.impact_end!r}",
          "--out", str(work / "run-impact")]),
        ("run (the scene's time span)", ["run", args.scene, "--method", "improved", *sets, "-q",
                                         "--set", "outputs.xdmf=false", "--out", str(work / "run")]),
    ]:
        code, wall, peak = timed_run(cli + cmd, 1, ROOT)
        rows.append({"case": name, "exit": code, "wall_s": wall, "peak_gb": peak})
    for r in rows:
        r["ratio_to_repeat_1"] = r["wall_s"] / rows[0]["wall_s"]
        r["ratio_to_run_impact"] = r["wall_s"] / rows[2]["wall_s"]
    write_report(out, "repeat_sequence", rows, 1,
                 ["case", "wall (s)", "x repeat --impacts 1", "x run impact-only", "peak RSS (GB)", "exit"],
                 lambda r: [r["case"], f"{r['wall_s']:.1f}", f"{r['ratio_to_repeat_1']:.2f}",
                            f"{r['ratio_to_run_impact']:.2f}", f"{r['peak_gb']:.2f}", str(r["exit"])],
                 note=f"{args.scene} {' '.join(args.set)}; target: the 10-impact sequence <= 3x one impact-only run")
    return 0


if __name__ == "__main__":
    sys.exit(main())
