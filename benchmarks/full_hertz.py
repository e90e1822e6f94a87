"""Benchmark: the full FE impact of the default ball on the half-space-like block against Hertz.

Runs ``hertz-halfspace`` with ``--method full`` at several contact mesh sizes (h_contact = a_max / n)
and degrees, side by side in one run, and writes ``benchmarks/out/full_hertz.csv`` plus a Markdown
table: F_max, t_c, max approach, restitution and energy drift against Hertz, with DOFs and wall time.

    .venv/bin/python benchmarks/full_hertz.py                 # default set (several minutes)
    .venv/bin/python benchmarks/full_hertz.py --quick         # coarse only
    mpirun -n 2 .venv/bin/python benchmarks/full_hertz.py     # the same under MPI
"""
from __future__ import annotations

import argparse
import json
import time

from mpi4py import MPI

from _report import write_report
from millimpact.methods.run import run_scene
from millimpact.scene.builtin import builtin_scene

A_MAX = 1.159e-3  # m, Hertz contact radius of the default impact (foundations.md section 3)


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--quick", action="store_true", help="only the coarsest case")
    p.add_argument("--cases", default="4:1,8:1,4:2", help="comma list of n:degree with h_contact = a_max/n")
    p.add_argument("--h-far", type=float, default=3.75e-3, help="far element size, m")
    p.add_argument("--out", default="benchmarks/out")
    args = p.parse_args()
    comm = MPI.COMM_WORLD
    cases = [tuple(int(x) for x in c.split(":")) for c in args.cases.split(",")]
    if args.quick:
        cases = cases[:1]
    rows = []
    for n, degree in cases:
        scene = (builtin_scene("hertz-halfspace").with_value("model.h_contact", A_MAX / n)
                 .with_value("model.h_far", args.h_far).with_value("time.end", 1.2e-4))
        t0 = time.perf_counter()
        s = run_scene(scene, "full", None, options={"degree": degree}, comm=comm)
        wall = time.perf_counter() - t0
        h = s["hertz"]
        rows.append({
            "h_contact": f"a_max/{n}", "degree": degree, "dofs": s["model"]["dofs"], "ranks": comm.size,
            "F_max_err_pct": 100 * (s["peak_contact_force_N"] / h["F_max_N"] - 1),
            "t_c_err_pct": 100 * (s["contact_duration_s"] / h["t_c_s"] - 1),
            "delta_max_err_pct": 100 * (s["max_approach_m"] / h["delta_max_m"] - 1),
            "restitution": s["restitution"], "energy_drift_pct": 100 * s["energy_drift_over_impact_rel"],
            "wall_s": wall, "integrate_s": s["timings_s"]["integrate"],
        })
        if comm.rank == 0:
            print(json.dumps(rows[-1]), flush=True)
    if comm.rank == 0:
        write_report(args.out, "full_hertz", rows, comm.size,
                     ["h_c", "P", "dofs", "F_max err %", "t_c err %", "delta err %", "e", "energy drift %", "wall s"],
                     lambda r: [r["h_contact"], str(r["degree"]), str(r["dofs"]), f"{r['F_max_err_pct']:+.2f}",
                                f"{r['t_c_err_pct']:+.2f}", f"{r['delta_max_err_pct']:+.2f}", f"{r['restitution']:.4f}",
                                f"{r['energy_drift_pct']:.3f}", f"{r['wall_s']:.1f}"])

if __name__ == "__main__":
    main()
