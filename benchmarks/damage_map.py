"""Benchmark: the liner's damage map: ``millimpact damage liner-segment`` from a
2-revolution impact log with at most 30 bins; the target is under 20 minutes on 2 cores.

The log is a ``millimpact mill`` run's impacts.csv (``--impacts``) or, until that command is merged,
a synthetic 2-revolution spectrum (``--synthetic N``: N impacts a revolution, seeded): normal
speeds log-normal about 1.5 m/s (0.2-8 m/s, the 3-13 m/s of foundations.md section 10 for the fastest balls
less their tangential part), angles 0-70 deg, half of them on the plate, a third on the lifter
face, the rest on its top, arc positions over each place. The map runs under ``mpirun -n RANKS
--ranks-per-case 1`` (the table engine's groups); with ``--serial`` also at 1 rank into its own
folder, side by side (the parallel efficiency). Reported: wall time, bins computed, the bins'
own wall times (sum, first of a band against the others: the reduction's reuse), the CPU time of
the ranks (user + system, from wait4: on a shared machine the wall time is inflated, the CPU time
much less), the load average before and after, peak memory, the bins refused and those moved off
an edge (docs/damage.md, edge impacts). Writes benchmarks/out/damage_map/damage_map_bench.{csv,md}.
``--resume`` keeps --out, so a map interrupted there continues (its finished bins are then not
timed again: the wall and CPU times cover the rerun only).

    .venv/bin/python benchmarks/damage_map.py                                  # the benchmark
    .venv/bin/python benchmarks/damage_map.py --max-bins 10 --set model.h_far=0.04   # a quick look
    .venv/bin/python benchmarks/damage_map.py --impacts out/mill/impacts.csv   # from a mill run
    .venv/bin/millimpact mill liner-segment --revolutions 2 --balls 200 --out out/mill-segment   # that run
"""
from __future__ import annotations

import argparse
import json
import os
import shutil
import sys
from pathlib import Path

import millimpact  # noqa: F401  (before numpy: it chooses OpenBLAS's kernels, millimpact/__init__.py)
import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "benchmarks"))
sys.path.insert(0, str(ROOT))

from _report import timed_run_cpu, write_report  # noqa: E402


def synthetic_log(path: Path, per_rev: int, revolutions: float, seed: int = 34) -> None:
    """A synthetic impacts.csv of ``per_rev`` impacts a revolution over ``revolutions`` (module docstring)."""
    from millimpact.dem.impacts import Impact, write_impacts
    from millimpact.scene.builtin import builtin_scene

    s = builtin_scene("liner-segment")
    r, rho = s.ball.radius, s.ball.material.density
    m = 4.0 / 3.0 * np.pi * r**3 * rho
    rng = np.random.default_rng(seed)
    n = int(round(per_rev * revolutions))
    places = rng.choice(["plate", "lifter_face", "lifter_top"], size=n, p=[0.5, 0.33, 0.17])
    arcs = {"plate": (0.13, 0.25), "lifter_face": (0.05, 0.12), "lifter_top": (-0.045, 0.045)}
    period = 60.0 / 10.0     # s a revolution at ~10 rpm
    out = []
    for k, p in enumerate(places):
        vn = float(np.clip(np.exp(rng.normal(np.log(1.5), 0.7)), 0.2, 8.0))
        vt = float(vn * np.tan(np.radians(rng.uniform(0.0, 70.0))))
        out.append(Impact(float(k * revolutions * period / n), r, vn, vt, 0.5 * m * (vn**2 + vt**2), str(p),
                          float(rng.uniform(*arcs[p]))))
    write_impacts(path, out)


def damage(folder: Path, impacts: Path, revolutions: float, ranks: int, extra: list[str]
           ) -> tuple[dict, float, float, float]:
    cmd = [sys.executable, "-m", "millimpact.cli", "damage", "liner-segment", "--impacts", str(impacts),
           "--revolutions", f"{revolutions:g}", "--out", str(folder), *extra]
    code, wall, peak_gb, cpu = timed_run_cpu(cmd + (["--ranks-per-case", "1"] if ranks > 1 else []), ranks, ROOT)
    if code != 0:
        raise SystemExit(f"millimpact damage failed (exit {code})")
    return json.loads((folder / "damage.json").read_text()), wall, peak_gb, cpu


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--impacts", help="a mill run's impacts.csv (default: a synthetic log)")
    ap.add_argument("--revolutions", type=float, default=2.0, help="revolutions the log covers (default 2)")
    ap.add_argument("--synthetic", type=int, default=400, metavar="N", help="synthetic impacts a revolution")
    ap.add_argument("--max-bins", type=int, default=30)
    ap.add_argument("--repeat-impacts", type=int, default=6)
    ap.add_argument("--ranks", type=int, default=2)
    ap.add_argument("--serial", action="store_true", help="also at 1 rank, side by side")
    ap.add_argument("--set", action="append", default=[], help="FIELD=VALUE for the map's scene")
    ap.add_argument("--out", default=str(ROOT / "benchmarks" / "out" / "damage_map"))
    ap.add_argument("--resume", action="store_true",
                    help="keep --out: a map interrupted there continues (its finished bins are not re-timed)")
    a = ap.parse_args()
    out = Path(a.out)
    if not a.resume:
        shutil.rmtree(out, ignore_errors=True)
    out.mkdir(parents=True, exist_ok=True)
    impacts = Path(a.impacts) if a.impacts else out / "impacts.csv"
    if not a.impacts:
        synthetic_log(impacts, a.synthetic, a.revolutions)
    extra = ["--max-bins", str(a.max_bins), "--repeat-impacts", str(a.repeat_impacts), "-q",
             *[x for s in a.set for x in ("--set", s)]]
    results = []
    for ranks in sorted({a.ranks} | ({1} if a.serial else set()), reverse=True):
        load_before = os.getloadavg()[0]
        res, wall, peak_gb, cpu = damage(out / f"np{ranks}", impacts, a.revolutions, ranks, extra)
        rows = [json.loads(p.read_text()) for p in (out / f"np{ranks}" / "cases").glob("*.json")]
        first = [r["wall_time_s"] for r in rows if not r.get("reduction_reused")]
        reused = [r["wall_time_s"] for r in rows if r.get("reduction_reused")]
        results.append({"ranks": ranks, "wall_s": round(wall, 1), "cpu_s": round(cpu, 1),
                        "load_1min_before": round(load_before, 1), "load_1min_after": round(os.getloadavg()[0], 1),
                        "peak_rss_gb": round(peak_gb, 2),
                        "bins": len(res["bins"]), "bins_computed": len(rows),
                        "bins_refused": sum(b["status"] == "refused" for b in res["bins"]),
                        "bins_edge_clamped": sum(b.get("edge_shift_m", 0) > 0 for b in res["bins"]),
                        "impacts": res["impacts"],
                        "impacts_left_out_per_rev": round(sum(t["impacts_left_out_per_rev"]
                                                              for t in res["places"].values()), 4),
                        "restitution_spread": round(res["binning"]["widest_thornton_restitution_spread"], 4),
                        "cases_wall_sum_s": round(sum(first) + sum(reused), 1),
                        "first_of_band_mean_s": round(float(np.mean(first)), 1) if first else float("nan"),
                        "reused_mean_s": round(float(np.mean(reused)), 1) if reused else float("nan"),
                        "repeat_impacts": res["repeat_impacts"],
                        "repeats_run": sum(1 for r in res["repeats"].values() if r),
                        "under_20_min": wall < 1200.0})
    write_report(out, "damage_map_bench", results, a.ranks,
                 ["ranks", "wall (s)", "CPU (s)", "load (1 min) before/after", "peak RSS (GB)",
                  "bins (computed, refused, clamped)", "Thornton spread", "cases' wall sum (s)",
                  "first of band / reused (s)", "repeats", "< 20 min"],
                 lambda r: [str(r["ranks"]), f"{r['wall_s']:.0f}", f"{r['cpu_s']:.0f}",
                            f"{r['load_1min_before']:.1f} / {r['load_1min_after']:.1f}", f"{r['peak_rss_gb']:.2f}",
                            f"{r['bins']} ({r['bins_computed']}, {r['bins_refused']}, {r['bins_edge_clamped']})",
                            f"{r['restitution_spread']:.3g}",
                            f"{r['cases_wall_sum_s']:.0f}", f"{r['first_of_band_mean_s']} / {r['reused_mean_s']}",
                            f"{r['repeats_run']} x {r['repeat_impacts']}", "yes" if r["under_20_min"] else "no"],
                 note=f"; liner-segment, {a.revolutions:g} revolutions, {'synthetic' if not a.impacts else impacts}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
