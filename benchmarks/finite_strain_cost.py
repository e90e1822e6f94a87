"""Benchmark: a finite-strain impact against the small-strain one, side by side on this machine.

Runs ``paper-rig-plastic`` (``improved``, the impact: ``time.end`` 0.3 ms by default) with
``model.strain = small`` and ``finite`` in turn, ``--pairs`` times, and reports per run the time
loop (summary ``timings_s.integrate``), the process's wall and CPU time (each over the small-strain
run's of its pair), and the answers: F_max,
restitution, plastic work, dent depth. The targets: the finite-strain run costs at most 1.5x the
small-strain one; where small strain holds (this rig, V/V_y ~ 30 on the block) the two agree
within 0.005 in e and 1 % in F_max and dent. Writes benchmarks/out/finite_strain_cost/
{finite_strain_cost.csv,.md}.

    .venv/bin/python benchmarks/finite_strain_cost.py [--pairs 2] [--end 3e-4] [--scene paper-rig-plastic]
"""
from __future__ import annotations

import argparse
import json
import statistics
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "benchmarks"))

from _report import timed_run_cpu, write_report  # noqa: E402

KEYS = ("peak_contact_force_N", "restitution", "plastic_dissipation_J", "residual_dent_depth_m")


def run(scene: str, folder: Path, strain: str, end: float) -> dict:
    cmd = [sys.executable, "-m", "millimpact.cli", "run", scene, "-q", "--force", "--out", str(folder),
           "--set", f"model.strain={strain}", "--set", f"time.end={end!r}"]
    folder.mkdir(parents=True, exist_ok=True)
    code, wall, _, cpu = timed_run_cpu(cmd, 1, ROOT, folder.with_suffix(".log"))
    if code != 0:
        raise SystemExit(f"{' '.join(cmd)} failed (exit {code}): see {folder.with_suffix('.log')}")
    s = json.loads((folder / "summary.json").read_text())
    return {"strain": strain, "loop_s": s["timings_s"]["integrate"], "wall_s": wall, "cpu_s": cpu,
            **{k: s.get(k, 0.0) for k in KEYS}, "strain_used": s.get("strain", "")}


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--pairs", type=int, default=2)
    ap.add_argument("--end", type=float, default=3e-4, help="time.end, s")
    ap.add_argument("--scene", default="paper-rig-plastic")
    ap.add_argument("--out", default=str(ROOT / "benchmarks" / "out" / "finite_strain_cost"))
    a = ap.parse_args()
    out = Path(a.out)
    rows = []
    for k in range(a.pairs):
        for strain in ("small", "finite"):
            rows.append({"pair": k, **run(a.scene, out / f"{strain}-{k}", strain, a.end)})
            r = rows[-1]
            print(f"pair {k} {strain}: loop {r['loop_s']:.1f} s, wall {r['wall_s']:.1f} s, cpu {r['cpu_s']:.1f} s, "
                  f"e {r['restitution']:.5f}", flush=True)
    for r in rows:
        small = next(s for s in rows if s["pair"] == r["pair"] and s["strain"] == "small")
        r["loop_ratio"], r["cpu_ratio"] = r["loop_s"] / small["loop_s"], r["cpu_s"] / small["cpu_s"]
        r["wall_ratio"] = r["wall_s"] / small["wall_s"]
        for key in KEYS:
            r[f"{key}_rel_diff"] = (r[key] - small[key]) / abs(small[key]) if small[key] else 0.0
        r["restitution_diff"] = r["restitution"] - small["restitution"]

    def cells(r: dict) -> list[str]:
        return [str(r["pair"]), r["strain"], f"{r['loop_s']:.1f} ({r['loop_ratio']:.2f}x)",
                f"{r['wall_s']:.1f} ({r['wall_ratio']:.2f}x)", f"{r['cpu_s']:.1f} ({r['cpu_ratio']:.2f}x)", f"{r['peak_contact_force_N'] / 1e3:.5g}",
                f"{r['restitution']:.5f}", f"{r['plastic_dissipation_J']:.5g}", f"{r['residual_dent_depth_m'] * 1e6:.5g}"]

    finite = [r for r in rows if r["strain"] == "finite"]
    note = (f"; {a.scene}, improved, time.end {a.end:g} s, small and finite strain in turn; finite over small: "
            f"time loop {statistics.median(r['loop_ratio'] for r in finite):.2f}x, "
            f"whole run {statistics.median(r['wall_ratio'] for r in finite):.2f}x (medians), "
            f"e {finite[-1]['restitution_diff']:+.4f}, F_max {finite[-1]['peak_contact_force_N_rel_diff']:+.2%}, "
            f"dent {finite[-1]['residual_dent_depth_m_rel_diff']:+.2%}, "
            f"plastic work {finite[-1]['plastic_dissipation_J_rel_diff']:+.2%}")
    write_report(out, "finite_strain_cost", rows, 1,
                 ["pair", "strain", "time loop s (/ small)", "wall s (/ small)", "CPU s (/ small)", "F_max kN", "e", "plastic work J",
                  "dent um"], cells, note=note)
    return 0


if __name__ == "__main__":
    sys.exit(main())
