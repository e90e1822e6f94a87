"""Benchmark: the struck body's region of ``liner-panel`` (improved, P2) at the plan's sizes or
coarser: its size, the fill, time and memory of its factorization, and what one solve and a
multi-right-hand-side solve cost a column (the numbers behind the million-DOF run).

    .venv/bin/python benchmarks/region_factor.py                         # the plan's 1.2M P2 DOFs (~23 GB peak)
    .venv/bin/python benchmarks/region_factor.py --set model.h_far=0.025 # 157k DOFs
    .venv/bin/python benchmarks/region_factor.py --solver mumps -x_mat_mumps_icntl_35 2 -x_mat_mumps_cntl_7 1e-8

Prints one line per stage with the elapsed time and the process's resident and peak memory.
Serial (the factorization is the reduction's: CHOLMOD, or ``--solver mumps``); PETSc options with
the prefix ``x_`` reach the factorization.
"""
from __future__ import annotations

import argparse
import resource
import sys
import time

import millimpact  # noqa: F401  (before numpy: it chooses OpenBLAS's kernels, millimpact/__init__.py)
import numpy as np


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--set", action="append", default=[], metavar="KEY=VALUE", help="a scene field (numbers)")
    ap.add_argument("--solver", default="cholmod", help="factorization package (cholmod, mumps)")
    a, petsc_args = ap.parse_known_args()
    import petsc4py
    petsc4py.init([sys.argv[0], *petsc_args])
    from mpi4py import MPI
    from petsc4py import PETSc

    from millimpact.fem.model import create_fe_model
    from millimpact.geometry.mesh import create_mesh
    from millimpact.integration.solvers import create_factored_solver
    from millimpact.methods.reduced import reduced_plan
    from millimpact.reduction.eigen import default_solver_options
    from millimpact.reduction.nmm_zone import create_nmm_zone
    from millimpact.reduction.partition import partition_dofs
    from millimpact.scene.builtin import builtin_scene
    from millimpact.scene.plan import make_plan

    t0 = time.perf_counter()

    def say(*what) -> None:
        with open("/proc/self/status") as f:
            rss = next(int(line.split()[1]) for line in f if line.startswith("VmRSS")) / 1e6
        peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1e6
        print(f"[{time.perf_counter() - t0:7.1f} s, RSS {rss:5.2f} GB, peak {peak:5.2f} GB]", *what, flush=True)

    scene = builtin_scene("liner-panel")
    for kv in a.set:
        key, value = kv.split("=")
        scene = scene.with_value(key, float(value))
    scene, plan, _, _ = reduced_plan(scene, make_plan(scene))
    say(f"plan: h_far {plan.h_far * 1e3:.3g} mm, h_contact {plan.h_contact * 1e3:.3g} mm, "
        f"zone {plan.zone_radius * 1e3:.3g} mm")
    model = create_fe_model(create_mesh(scene, plan, MPI.COMM_WORLD), plan, 2)
    say(f"mesh and P2 model: {model.K.getSize()[0]:,} DOFs")
    part = partition_dofs(model)
    zone = create_nmm_zone(model, part).basis
    K, M = model.K, model.M
    r0 = K.getOwnershipRange()[0]
    idx = part.interior["block"]
    I = PETSc.IS().createGeneral((r0 + idx).astype(np.int32))
    K_ii = K.createSubMatrix(I, I)
    C = K.createSubMatrix(I, PETSc.IS().createStride(part.n_owned, r0, 1)).matMult(zone.G)
    n_b = len(np.unique(C.getValuesCSR()[1]))
    say(f"region K_ii: {K_ii.getSize()[0]:,} dofs, {int(K_ii.getInfo()['nz_used']):,} nonzeros, "
        f"{n_b} interface coordinates")
    opts = default_solver_options(1)
    opts["pc_factor_mat_solver_type"] = a.solver
    t = time.perf_counter()
    ksp = create_factored_solver(K_ii, "x_", opts)
    F = ksp.getPC().getFactorMatrix()
    if a.solver == "mumps":
        fill = f"{F.getMumpsInfog(29):,} entries ({F.getMumpsInfog(35):,} after compression), {F.getMumpsInfog(22)} MB"
    else:
        info = F.getInfo()
        fill = f"{int(info['nz_used']):,} nonzeros, {info['memory'] / 1e9:.2f} GB"
    say(f"factorization ({a.solver}): {time.perf_counter() - t:.1f} s, {fill}")
    x, b = K_ii.createVecs()
    b.setRandom()
    for _ in range(3):
        t = time.perf_counter()
        ksp.solve(b, x)
        say(f"one solve: {time.perf_counter() - t:.3f} s")
    for cols in (16, 64):
        B = PETSc.Mat().createDense((K_ii.getSizes()[0], (PETSc.DECIDE, cols)))
        B.setUp()
        B.getDenseArray()[:] = np.random.default_rng(0).standard_normal(B.getDenseArray().shape)
        B.assemble()
        X = B.duplicate()
        t = time.perf_counter()
        F.matSolve(B, X)
        dt = time.perf_counter() - t
        say(f"multi-right-hand-side solve, {cols} columns: {dt:.2f} s, {dt / cols:.3f} s a column")
        B.destroy()
        X.destroy()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
