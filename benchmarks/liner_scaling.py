"""Benchmark: strong scaling of the liner-segment impact (full FE, with friction) on 1 and 2 ranks.

Runs the built-in ``liner-segment`` scene (125 mm ball, 8 m/s, 30 deg off the lifter face's normal,
mu = 0.2) with ``--method full`` at a moderate size, once per rank count, side by side in one
invocation, each as ``mpirun -n N python benchmarks/liner_scaling.py --worker``. Reports the DOFs,
wall time per phase (mesh, assembly + contact rows, time integration), speedup, and each rank's peak
resident memory (``resource.getrusage(RUSAGE_SELF).ru_maxrss``; the baseline after importing
DOLFINx/PETSc is given beside it). The mesh is built once first (cached), so no run pays for gmsh.

    .venv/bin/python benchmarks/liner_scaling.py                   # h_far 10 mm, 1 and 2 ranks
    .venv/bin/python benchmarks/liner_scaling.py --h-far 0.015 --ranks 1,2

Writes ``benchmarks/out/liner_scaling.csv`` and ``.md``. Wall times on a shared machine are noisy:
compare the ratios of one invocation. A third run on 1 rank with MUMPS (the factorization the
parallel runs use; CHOLMOD, the serial default, is serial only) separates the solver from the scaling.
"""
from __future__ import annotations

import argparse
import csv
import json
import os
import platform
import resource
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def _scene(args):
    from millimpact.scene.builtin import builtin_scene

    s = builtin_scene("liner-segment")
    for k, v in (("model.h_far", args.h_far), ("time.end", args.t_end), ("outputs.xdmf", False)):
        s = s.with_value(k, v)
    if args.h_contact:
        s = s.with_value("model.h_contact", args.h_contact)
    return s


def worker(args) -> None:
    base_rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    from mpi4py import MPI

    import dolfinx  # noqa: F401  (the baseline includes the stack)
    from millimpact.geometry.mesh import create_mesh
    from millimpact.scene.plan import make_plan
    from millimpact.methods.run import compute

    comm = MPI.COMM_WORLD
    scene = _scene(args)
    if args.mesh_only:
        create_mesh(scene, make_plan(scene), comm)
        return
    base_rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    comm.barrier()
    t0 = time.perf_counter()
    options = {"fieldsplit_u_pc_factor_mat_solver_type": args.solver} if args.solver else {}
    out, plan = compute(scene, "full", options, False)
    comm.barrier()
    wall = time.perf_counter() - t0
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss  # kB on Linux
    peaks = comm.gather(peak / 1024.0, root=0)
    bases = comm.gather(base_rss / 1024.0, root=0)
    if comm.rank == 0:
        r = out.results
        st = r["integration"]
        ts = out.series
        print("RESULT " + json.dumps({
            "ranks": comm.size, "solver": args.solver or ("cholmod" if comm.size == 1 else "mumps"),
            "dofs": out.model["dofs"], "contact_candidates": out.model["contact_candidates"],
            "cells": out.model["mesh"]["n_cells"] and sum(out.model["mesh"]["n_cells"].values()),
            "steps": st["n_steps"], "wall_s": wall, "mesh_s": r["timings_s"]["mesh"],
            "assemble_s": r["timings_s"]["assemble"], "integrate_s": r["timings_s"]["integrate"],
            "peak_rss_MB_per_rank": peaks, "baseline_rss_MB_per_rank": bases,
            "F_max_N": float(ts["contact_force_N"].max()), "hertz_F_max_N": plan.hertz.force_max,
            "friction_passes_max": st["max_friction_passes"], "w_columns": st["n_w_columns"],
        }), flush=True)


def run(n: int, args, extra=()) -> dict:
    env = dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1",
               OMPI_MCA_rmaps_base_oversubscribe="1", MPLBACKEND="Agg")
    cmd = ["mpirun", "-n", str(n), sys.executable, __file__, "--worker", "--h-far", str(args.h_far),
           "--t-end", str(args.t_end), *extra]
    if args.h_contact:
        cmd += ["--h-contact", str(args.h_contact)]
    p = subprocess.run(cmd, capture_output=True, text=True, env=env, cwd=ROOT)
    if p.returncode != 0:
        raise SystemExit(f"mpirun -n {n} failed:\n{p.stderr[-3000:]}")
    lines = [ln for ln in p.stdout.splitlines() if ln.startswith("RESULT ")]
    return json.loads(lines[-1][7:]) if lines else {}


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--worker", action="store_true", help=argparse.SUPPRESS)
    p.add_argument("--mesh-only", action="store_true", help=argparse.SUPPRESS)
    p.add_argument("--h-far", type=float, default=0.010, help="far element size, m (default 10 mm)")
    p.add_argument("--h-contact", type=float, default=None, help="contact element size, m (default: the plan's a_max/4)")
    p.add_argument("--t-end", type=float, default=4.0e-4, help="simulated time, s (contact lasts ~0.31 ms)")
    p.add_argument("--ranks", default="1,2")
    p.add_argument("--solver", default=None, help=argparse.SUPPRESS)
    p.add_argument("--no-serial-mumps", action="store_true",
                   help="skip the extra 1-rank run with MUMPS (the parallel solver) instead of CHOLMOD")
    p.add_argument("--out", default="benchmarks/out")
    args = p.parse_args()
    if args.worker:
        worker(args)
        return
    run(1, args, ["--mesh-only"])
    rows = [run(int(n), args) for n in args.ranks.split(",")]
    if not args.no_serial_mumps:   # same solver as the parallel runs: separates solver from scaling
        rows.append(run(1, args, ["--solver", "mumps"]))
    t1 = rows[0]["wall_s"]
    for r in rows:
        r["speedup"] = t1 / r["wall_s"]
        r["speedup_integrate"] = rows[0]["integrate_s"] / r["integrate_s"]
        print(json.dumps(r), flush=True)
    out = ROOT / args.out
    out.mkdir(parents=True, exist_ok=True)
    keys = [k for k in rows[0] if not isinstance(rows[0][k], list)]
    with open(out / "liner_scaling.csv", "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(keys + ["peak_rss_MB_per_rank", "baseline_rss_MB_per_rank"])
        for r in rows:
            w.writerow([r[k] for k in keys] + [" ".join(f"{x:.0f}" for x in r["peak_rss_MB_per_rank"]),
                                              " ".join(f"{x:.0f}" for x in r["baseline_rss_MB_per_rank"])])
    lines = [f"machine: {platform.node()}, {os.cpu_count()} cores (shared); liner-segment, full FE P1, mu = 0.2, "
             f"h_far {args.h_far * 1e3:g} mm, t_end {args.t_end * 1e3:g} ms, {rows[0]['steps']} steps", "",
             "| ranks | factorization | DOFs | wall s | mesh s | assembly s | integration s | speedup (wall / integration) | "
             "peak RSS per rank MB (baseline) |", "|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        mem = ", ".join(f"{a:.0f} ({b:.0f})" for a, b in zip(r["peak_rss_MB_per_rank"], r["baseline_rss_MB_per_rank"]))
        lines.append(f"| {r['ranks']} | {r['solver']} | {r['dofs']} | {r['wall_s']:.1f} | {r['mesh_s']:.1f} | {r['assemble_s']:.1f} | "
                     f"{r['integrate_s']:.1f} | {r['speedup']:.2f} / {r['speedup_integrate']:.2f} | {mem} |")
    (out / "liner_scaling.md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    main()
