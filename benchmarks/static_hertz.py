"""Benchmark: the static Hertz contact (ball pressed on the hertz-halfspace block) against Hertz.

The ball's top cap is pushed ``--cap`` towards the block and the contact solved exactly
(millimpact.methods.static); contact radius, approach and block indentation are compared with Hertz at
the measured force, for several contact mesh sizes and degrees side by side in one run. Writes
``benchmarks/out/static_hertz.csv`` and ``.md``.

    .venv/bin/python benchmarks/static_hertz.py               # a/4 P1, a/8 P1, a/4 P2 (minutes)
    .venv/bin/python benchmarks/static_hertz.py --cases 4:1   # one case
"""
from __future__ import annotations

import argparse
import json
import time

from mpi4py import MPI

from _report import write_report
from millimpact.geometry.mesh import create_mesh
from millimpact.scene.plan import make_plan
from millimpact.scene.builtin import builtin_scene
from millimpact.methods.static import static_hertz


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--cases", default="4:1,8:1,4:2", help="comma list of n:degree with h_contact = a_max/n")
    p.add_argument("--cap", type=float, default=1.0e-4, help="cap displacement towards the block, m")
    p.add_argument("--out", default="benchmarks/out")
    args = p.parse_args()
    comm = MPI.COMM_WORLD
    base = builtin_scene("hertz-halfspace")
    a_max = make_plan(base).hertz.a_max
    rows = []
    for case in args.cases.split(","):
        n, degree = (int(x) for x in case.split(":"))
        scene = base.with_value("model.h_contact", a_max / n)
        plan = make_plan(scene)
        t0 = time.perf_counter()
        md = create_mesh(scene, plan, comm)
        r = static_hertz(scene, plan, md, args.cap, degree=degree)
        wall = time.perf_counter() - t0
        h = r.hertz(scene)
        rows.append({"h_contact": f"a_max/{n}", "degree": degree, "dofs": r.n_dofs, "ranks": comm.size,
                     "force_N": r.force, "active_nodes": r.n_active,
                     **{f"{k}_err_pct": 100 * (getattr(r, k) / h[k] - 1) for k in h},
                     "wall_s": wall})
        if comm.rank == 0:
            print(json.dumps(rows[-1]), flush=True)
    if comm.rank == 0:
        write_report(args.out, "static_hertz", rows, comm.size,
                     ["h_c", "P", "dofs", "F kN", "a err %", "approach err %", "block indentation err %", "wall s"],
                     lambda r: [r["h_contact"], str(r["degree"]), str(r["dofs"]), f"{r['force_N'] / 1e3:.2f}",
                                f"{r['contact_radius_err_pct']:+.2f}", f"{r['approach_err_pct']:+.2f}",
                                f"{r['block_indentation_err_pct']:+.2f}", f"{r['wall_s']:.1f}"],
                     note=f"; cap {args.cap:g} m")

if __name__ == "__main__":
    main()
