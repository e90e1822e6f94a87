"""Benchmark: strong scaling of the liner panel with ``improved``, at any rank counts.

Runs ``millimpact run liner-panel --method improved`` once per rank count (``mpirun -n N``; 1 rank
plain), side by side in one invocation, each into its own folder, and writes one row per rank
count: DOFs, reduced coordinates, wall time and its parts (offline reduction, time loop), speed-up
against the first rank count, the busiest rank's peak resident memory (``wait4``'s ru_maxrss:
the largest of mpirun's ranks) and F_max / t_c with their largest difference from the first row
(``mpirun -n N`` equals serial to 1e-9). The mesh is made once first (cached), so no row
pays for gmsh. The machine's load is printed with the table: wall times on a shared machine
measure the load.

    .venv/bin/python benchmarks/panel_scaling.py                          # coarse panel, 1 and 2 ranks
    .venv/bin/python benchmarks/panel_scaling.py --ranks 1,2,4,8,16,32,64 --h-far 0.0118   # a larger machine, the plan's size
    .venv/bin/python benchmarks/panel_scaling.py --h-far 0.025 --slabs 4    # 157k DOFs, the region in 4 slabs

``--h-far``/``--h-contact``/``--zone`` set the mesh (defaults: a coarse panel of ~31k P2 DOFs that
runs in about a minute here; the scene's own plan, ~1.2M P2 DOFs, is ``--h-far 0 --h-contact 0
--zone 0``); ``--end`` the simulated time (default 0.5 ms: the whole impact). Writes
benchmarks/out/panel_scaling/panel_scaling.{csv,md}.
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


def run(ranks: int, out: Path, sets: list[str], options: list[str]) -> dict:
    cmd = [sys.executable, "-m", "millimpact.cli", "run", "liner-panel", "--method", "improved", *sets,
           "--force", "-q", "--out", str(out), *options]
    code, wall, peak_gb = timed_run(cmd, ranks, ROOT)
    if code != 0:
        raise SystemExit(f"{ranks} rank(s): millimpact run failed (exit {code})")
    s = json.loads((out / "summary.json").read_text())
    t = s["timings_s"]
    return {"ranks": ranks, "dofs": s["model"]["dofs"], "reduced": s["model"]["reduced_dofs"], "wall_s": wall,
            "reduction_s": t["reduction_offline"], "integrate_s": t["integrate"],
            "peak_rss_busiest_rank_GB": peak_gb,
            "F_max_N": s["peak_contact_force_N"], "t_c_s": s["contact_duration_s"],
            "hertz_F_max_N": s["hertz"]["F_max_N"], "hertz_t_c_s": s["hertz"]["t_c_s"]}


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--ranks", default="1,2", help="comma-separated rank counts (default 1,2)")
    add_panel_arguments(ap)
    ap.add_argument("--slabs", type=int, default=0,
                    help="cut the struck body's region into this many slabs (-impact_reduction_block_substructures; "
                         "default 0: one factorization)")
    ap.add_argument("--out", default=str(ROOT / "benchmarks" / "out" / "panel_scaling"))
    a = ap.parse_args()
    ranks = [int(x) for x in a.ranks.split(",")]
    out = Path(a.out)
    sets = panel_sets(a, ROOT, out / "mesh")
    options = ["-impact_reduction_block_substructures", str(a.slabs)] if a.slabs > 1 else []
    rows = [run(n, out / f"np{n}", sets, options) for n in ranks]
    for r in rows:
        r["speedup"] = rows[0]["wall_s"] / r["wall_s"]
        r["F_max_rel_diff"] = abs(r["F_max_N"] / rows[0]["F_max_N"] - 1.0)
        r["t_c_rel_diff"] = abs(r["t_c_s"] / rows[0]["t_c_s"] - 1.0)
    load = os.getloadavg()
    write_report(out, "panel_scaling", rows, max(ranks),
                 ["ranks", "DOFs (reduced)", "wall s", "reduction s", "time loop s", "speed-up", "peak RSS, busiest rank GB",
                  "F_max kN (Hertz)", "t_c us (Hertz)", "vs first row: F_max, t_c"],
                 lambda r: [str(r["ranks"]), f"{r['dofs']:,} ({r['reduced']:,})", f"{r['wall_s']:.1f}",
                            f"{r['reduction_s']:.1f}", f"{r['integrate_s']:.1f}", f"{r['speedup']:.2f}",
                            f"{r['peak_rss_busiest_rank_GB']:.2f}",
                            f"{r['F_max_N'] / 1e3:.1f} ({r['hertz_F_max_N'] / 1e3:.1f})",
                            f"{r['t_c_s'] * 1e6:.1f} ({r['hertz_t_c_s'] * 1e6:.1f})",
                            f"{r['F_max_rel_diff']:.1e}, {r['t_c_rel_diff']:.1e}"],
                 note=f"; liner-panel, improved, {' '.join(sets + options)}; {os.cpu_count()} cores, load after "
                      f"{load[0]:.2f} / {load[1]:.2f} (1 / 5 min)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
