"""Benchmark: the liner panel's region reduced with one factorization against slabs (substructured
Craig-Bampton, ``millimpact.reduction.substructures``), side by side in one invocation.

One ``millimpact run liner-panel --method improved`` per variant, 1 rank, the reduction cache off:
wall time, offline reduction, peak resident memory, the struck body's modes under f_cut, and
F_max, t_c, e and the two gauges' peaks against the one-factorization row (the reference: the
slabs' Ritz frequencies are upper bounds and their constraint modes a Galerkin approximation
with polynomial interface traces).

    .venv/bin/python benchmarks/panel_substructures.py                       # coarse panel, ~31k P2 DOFs
    .venv/bin/python benchmarks/panel_substructures.py --h-far 0.025 --slabs 3,4   # 157k DOFs, ~7 min

Writes benchmarks/out/panel_substructures/panel_substructures.{csv,md}.
"""
from __future__ import annotations

import argparse
import json
import os
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "benchmarks"))

from _report import add_panel_arguments, panel_sets, timed_run, write_report  # noqa: E402


def run(slabs: int, out: Path, sets: list[str], extra: list[str]) -> dict:
    opts = ["-impact_reduction_block_substructures", str(slabs), *extra] if slabs > 1 else []
    cmd = [sys.executable, "-m", "millimpact.cli", "run", "liner-panel", "--method", "improved", *sets,
           "--force", "-q", "--out", str(out), *opts]
    code, wall, peak_gb = timed_run(cmd, 1, ROOT)
    if code != 0:
        raise SystemExit(f"{slabs} slab(s): millimpact run failed (exit {code})")
    s = json.loads((out / "summary.json").read_text())
    body = s["model"]["reduction"]["bodies"]["block"]
    sub = body.get("substructures") or {}
    g = s["peak_gauge_stress_Pa"]
    return {"slabs": slabs, "dofs": s["model"]["dofs"], "wall_s": wall,
            "reduction_s": s["timings_s"]["reduction_offline"], "peak_rss_GB": peak_gb,
            "modes": body["modes"], "interface_dofs": sub.get("interface_dofs", 0), "traces": sub.get("traces", 0),
            "slab_modes": sub.get("slab_modes", 0), "ritz_columns": sub.get("ritz_columns", 0),
            "constraint_residual": body.get("constraint_residual", float("nan")),
            "F_max_N": s["peak_contact_force_N"], "t_c_s": s["contact_duration_s"], "e": s["restitution"],
            **{f"gauge_{k}_Pa": v for k, v in g.items()}}


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--slabs", default="3,4", help="comma-separated slab counts beside the one factorization")
    add_panel_arguments(ap)
    ap.add_argument("--option", action="append", default=[],
                    help="a further option for the slab runs, e.g. --option=-impact_reduction_block_substructure_trace_density=0")
    ap.add_argument("--out", default=str(ROOT / "benchmarks" / "out" / "panel_substructures"))
    a = ap.parse_args()
    extra = [x for o in a.option for x in o.split("=", 1)]
    out = Path(a.out)
    os.environ["MILLIMPACT_REDUCTION_CACHE"] = "off"
    sets = panel_sets(a, ROOT, out / "mesh")
    rows = [run(n, out / f"slabs{n}", sets, extra) for n in [1] + [int(x) for x in a.slabs.split(",")]]
    ref = rows[0]
    gauges = [k for k in ref if k.startswith("gauge_")]
    for r in rows:
        for k in ("F_max_N", "t_c_s", "e", *gauges):
            r[f"{k}_rel"] = r[k] / ref[k] - 1.0
    load = os.getloadavg()
    write_report(out, "panel_substructures", rows, 1,
                 ["slabs", "DOFs", "wall s", "reduction s", "peak RSS GB", "modes < f_cut", "interface dofs -> traces",
                  "Ritz basis", "F_max, t_c, e vs 1 slab", "gauges vs 1 slab (" + ", ".join(g[6:-3] for g in gauges) + ")"],
                 lambda r: [str(r["slabs"]), f"{r['dofs']:,}", f"{r['wall_s']:.1f}", f"{r['reduction_s']:.1f}",
                            f"{r['peak_rss_GB']:.2f}", str(r["modes"]),
                            f"{r['interface_dofs']:,} -> {r['traces']:,}" if r["slabs"] > 1 else "-",
                            f"{r['ritz_columns']:,} ({r['slab_modes']} slab modes)" if r["slabs"] > 1 else "-",
                            ", ".join(f"{r[k + '_rel']:+.2%}" for k in ("F_max_N", "t_c_s", "e")),
                            ", ".join(f"{r[g + '_rel']:+.1%}" for g in gauges)],
                 note=f"; liner-panel, improved, {' '.join(sets + extra)}; load after {load[0]:.2f} / {load[1]:.2f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
