"""The time integrators on the 1D bar hitting a rigid wall (exact solution: foundations.md section 3).

Default case (millimpact/bar.py): steel-like bar, L = 0.1 m, 100 P1 elements, v0 = 1 m/s, contact step
dt = h / c (Courant 1), so the exact contact lasts 2L/c = 200 dt. Tolerances are stated in units
of dt / (2L/c) = 0.5 % where they come from the time resolution of contact start and end.
"""
from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys

import numpy as np
import pytest
import ufl
from dolfinx import fem, mesh
from dolfinx.fem import petsc as fem_petsc
from mpi4py import MPI
from petsc4py import PETSc

from millimpact.integration.bar import BarCase, run_bar, summarize
from millimpact.integration.integrators import TimeSchedule, kinetic_energy, redistribute_mass
from millimpact.integration.lcp import solve_lcp

CASE = BarCase()
#: one contact step relative to the exact contact duration (dt = h/c, duration = 2L/c)
DT_REL = (CASE.h / CASE.c) / CASE.duration

serial = pytest.mark.skipif(MPI.COMM_WORLD.size > 1, reason="serial reference runs")


@pytest.fixture(scope="module")
def runs() -> dict:
    """The three methods on the default case, run once."""
    return {m: (r := run_bar(CASE, m), summarize(CASE, r)) for m in ("newmark-mr", "newmark", "central-penalty")}


def test_newmark_mr_reproduces_exact_bar(runs):
    res, s = runs["newmark-mr"]
    # contact start and end are each resolved to one step and counted whole (bar.contact_duration):
    # |error| <= 2 dt, plus the discrete wave's dispersion (< 1 dt here): 3 dt = 1.5 %
    assert abs(s["duration_rel_error"]) <= 3 * DT_REL, s
    # mean force = impulse / duration: the duration's 3 dt plus the impulse's share of the rebound
    # error (below, 2 %): impulse = m (v0 - v_after) exactly (Newmark's momentum balance)
    assert abs(s["mean_force_rel_error"]) <= 3 * DT_REL + 0.02, s
    # plateau: with no mass on the tip the wall force is rho c v0 once the wave runs (exact 1D FE
    # travelling wave); 0.1 % allows the start/end steps the median may pick up
    assert abs(s["median_force_rel_error"]) <= 1e-3, s
    # rebound: the exact bar leaves unstressed at -v0; the discrete one keeps ~1-2 % of the
    # energy in vibration (Courant-1 dispersion), so its mean velocity is within ~2 %
    assert abs(s["rebound_velocity_rel_error"]) <= 0.02, s
    # energy conserving scheme: only the impact/release steps change the discrete energy
    assert s["energy_max_rel_error"] <= 0.01, s
    # one contact, no chatter: closed once, opened once
    assert s["status_switches"] == 2, s
    # linear momentum: the redistributed mass keeps the bar's total mass rho L (exact up to rounding)
    assert res.momentum[0] == pytest.approx(CASE.rho * CASE.L * CASE.v0, rel=1e-12)


def test_plain_newmark_chatters(runs):
    _, mr = runs["newmark-mr"]
    _, nm = runs["newmark"]
    # the known failure of Newmark with consistent mass and contact on u_{n+1} (foundations.md section
    # 4: "chatter ... pumps energy 10x or more"): the tip rattles open/closed every few steps ...
    assert nm["status_switches"] >= 10 * mr["status_switches"], (nm, mr)
    # ... only a fraction of the contact time carries force ...
    assert nm["time_in_contact_rel_error"] < -0.3, nm
    # ... and the discrete energy error is at least an order of magnitude larger (measured: ~9x the
    # initial energy against 0.2 %)
    assert nm["energy_max_rel_error"] >= 10 * max(mr["energy_max_rel_error"], 1e-3), (nm, mr)


def test_central_penalty_stable_step(runs):
    res, s = runs["central-penalty"]
    hc = CASE.h / CASE.c
    # lumped P1 bar: omega_max = 2 c / h, so dt_crit = h / c without contact; the penalty spring
    # k_p = EA/h on the tip's mass rho h / 2 lowers it, but not below h / (2 c)
    assert 0.5 * hc < res.stats.dt_critical <= hc * (1 + 1e-6)
    assert res.stats.dt_explicit <= 0.9 * res.stats.dt_critical * (1 + 1e-12)
    # the penalty compliance EA/k_p = h adds about 2 h / c to the duration (1 %), plus the 2-step
    # resolution of start and end: a few %
    assert abs(s["duration_rel_error"]) <= 0.03, s
    assert abs(s["mean_force_rel_error"]) <= 0.03, s
    # symplectic explicit scheme below its critical step: energy conserved up to O(dt^2) oscillation
    assert s["energy_max_rel_error"] <= 0.01, s
    assert not res.stats.diverged


def test_contact_solve_choices_agree():
    """fieldsplit (default), schur and monolithic lu give the same steps; no refactorization."""
    ref = run_bar(CASE, "newmark-mr", options={"contact_solve": "fieldsplit"})
    # one Cholesky per step size, none inside the steps: dt_contact, dt_free once the bar has left
    # the wall (the contact step's operators freed first), dt_contact again for the step onto t_end
    assert ref.stats.n_factorizations == 3
    assert ref.stats.n_saddle_solves > 150
    # the explicit Schur preconditioner is exact: one inner iteration even with a Krylov inner solver
    gm = run_bar(CASE, "newmark-mr", options={"fieldsplit_lam_ksp_type": "gmres", "fieldsplit_lam_ksp_rtol": 1e-12})
    assert gm.stats.max_schur_iterations == 1
    for opts in ({"contact_solve": "schur"}, {"contact_solve": "lu"}, {"pc_type": "lu"}):
        res = run_bar(CASE, "newmark-mr", options=opts)
        assert res.t.shape == ref.t.shape
        # three exact solves of the same linear systems: rounding only (measured ~2e-12)
        assert np.max(np.abs(res.force - ref.force)) <= 1e-8 * CASE.force, opts
        assert np.max(np.abs(res.energy - ref.energy)) <= 1e-8 * ref.energy[0], opts
    assert run_bar(CASE, "newmark-mr", options={"contact_solve": "schur"}).stats.n_saddle_solves == 0


def test_step_operators_are_freed_after_separation_unless_shared():
    """After the impact the contact step's operators are freed before the free step's are built
    (NewmarkScheme._release_step_operators: two factorizations never sit side by side, the liner
    panel's peak memory), at most MAX_RELEASES times a run; a shared cache (a contact table's
    cases) keeps them all. The steps are the same either way."""
    from millimpact.integration.newmark import MAX_RELEASES

    own = run_bar(CASE, "newmark-mr")
    cache: dict = {}
    shared = run_bar(CASE, "newmark-mr", operator_cache=cache)
    # the bar: contact steps, free steps after it leaves the wall, one contact step onto t_end
    assert own.stats.n_step_operators_released == 2 <= MAX_RELEASES
    assert own.stats.n_factorizations == 3
    assert shared.stats.n_step_operators_released == 0 and shared.stats.n_factorizations == 2
    assert len(next(v for k, v in cache.items() if isinstance(k, tuple))) == 2
    # the same matrices factorized again: the same steps to round-off
    assert np.array_equal(own.t, shared.t)
    assert np.max(np.abs(own.force - shared.force)) <= 1e-10 * CASE.force


def test_central_penalty_above_critical_step_blows_up(runs):
    dc = runs["central-penalty"][0].stats.dt_critical
    t_end = CASE.t_contact_start + 0.5 * CASE.duration
    # limit disabled, 1.5 x critical: the amplification factor of the highest mode is ~4.5 per step,
    # so round-off grows past the 10x energy criterion within tens of steps
    res = run_bar(CASE, "central-penalty", dt_contact=1.5 * dc, dt_free=1.5 * dc, t_end=t_end,
                  options={"limit_step": False})
    assert res.stats.diverged
    assert res.stats.diverged_at < t_end
    assert not np.isfinite(res.energy[-1]) or res.energy[-1] > 10 * res.energy[0]
    # the same schedule with the limit on is cut into stable sub-steps
    ok = run_bar(CASE, "central-penalty", dt_contact=1.5 * dc, dt_free=1.5 * dc, t_end=t_end)
    assert not ok.stats.diverged
    assert ok.stats.n_substeps >= 2 * ok.stats.n_steps


@pytest.mark.mpi
@serial
def test_mpi_matches_serial():
    if shutil.which("mpirun") is None:
        pytest.skip("mpirun not installed")
    env = dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1",
               OMPI_MCA_rmaps_base_oversubscribe="1")
    out = subprocess.run(["mpirun", "-n", "2", sys.executable, "-m", "millimpact.integration.bar", "--method", "newmark-mr"],
                         capture_output=True, text=True, env=env, timeout=300)
    assert out.returncode == 0, out.stderr[-3000:]
    par = json.loads(out.stdout.strip().splitlines()[-1])
    ser = run_bar(CASE, "newmark-mr")
    f_par = np.array(par["force"])
    assert f_par.shape == ser.force.shape
    np.testing.assert_allclose(par["t"], ser.t, rtol=0, atol=1e-15)
    # MUMPS (parallel) vs CHOLMOD (serial) factorizations: rounding differences only
    assert np.max(np.abs(f_par - ser.force)) <= 1e-6 * np.max(np.abs(ser.force))


@serial
def test_redistribute_mass_keeps_mass_per_component():
    """Vector P1 on a square (block size 2): contact dofs of the top edge lose their mass,
    each component's total mass e_k^T M e_k is unchanged, M_r stays symmetric positive."""
    msh = mesh.create_unit_square(MPI.COMM_WORLD, 6, 5)
    V = fem.VectorFunctionSpace(msh, ("Lagrange", 1))
    u, w = ufl.TrialFunction(V), ufl.TestFunction(V)
    M = fem_petsc.assemble_matrix(fem.form(3.0 * ufl.inner(u, w) * ufl.dx))
    M.assemble()
    assert M.getBlockSize() == 2
    nodes = fem.locate_dofs_geometrical(V, lambda x: np.isclose(x[1], 1.0))
    dofs = np.sort(np.concatenate([2 * nodes, 2 * nodes + 1])).astype(np.int32)
    Mr = redistribute_mass(M, dofs)
    for k in range(2):
        e = M.createVecRight()
        e.set(0.0)
        e.array[k::2] = 1.0
        assert 2 * kinetic_energy(Mr, e) == pytest.approx(2 * kinetic_energy(M, e), rel=1e-13)
        assert 2 * kinetic_energy(M, e) == pytest.approx(3.0, rel=1e-13)   # rho * area
    A = Mr.convert("dense", PETSc.Mat()).getDenseArray()
    assert np.abs(A[dofs]).max() == 0 and np.abs(A[:, dofs]).max() == 0
    np.testing.assert_allclose(A, A.T, atol=1e-15)
    keep = np.setdiff1d(np.arange(A.shape[0]), dofs)
    assert np.linalg.eigvalsh(A[np.ix_(keep, keep)]).min() > 0


def test_time_schedule_lands_on_t_end():
    s = TimeSchedule(1.0e-3, 3.0e-6, 2.0e-5)
    assert s.dt_grid <= 3.0e-6 and s.n_grid * s.dt_grid == pytest.approx(1.0e-3, rel=1e-14)
    assert s.free_ratio == 6          # floor(2e-5 / dt_grid)
    # open, slowly closing gap: free step; a gap that closes within margin * dt_free: contact step
    assert s.free_step_allowed(np.array([1e-3]), np.array([-1.0]), 0)
    assert not s.free_step_allowed(np.array([1e-5]), np.array([-1.0]), 0)
    assert not s.free_step_allowed(np.array([1e-3]), np.array([-1.0]), 1)
    res = run_bar(CASE, "newmark-mr")
    assert res.t[-1] == CASE.t_contact_start + 1.5 * CASE.duration
    assert len(np.unique(res.dt[1:])) == 2
    assert res.stats.n_steps_free > 0 and res.stats.n_steps_contact > 0


def test_lcp_complementarity():
    """Random SPD problems: exact complementarity, same answer as the NNLS fallback."""
    rng = np.random.default_rng(1)
    for n in (1, 5, 40):
        G = rng.normal(size=(n, n))
        S = G @ G.T + n * np.eye(n)
        q = rng.normal(size=n)
        r = solve_lcp(S, q)
        g = q + S @ r.lam
        assert r.lam.min() >= 0 and g.min() >= -1e-12
        assert np.abs(r.lam * g).max() <= 1e-12
        fb = solve_lcp(S, q, max_iter=0)       # forces the Lawson-Hanson path
        assert fb.method == "nnls"
        np.testing.assert_allclose(fb.lam, r.lam, atol=1e-10)


def test_failed_solve_raises_solver_error():
    """A solver that does not converge is reported with its reason, step and time."""
    from millimpact.errors import SolverError

    with pytest.raises(SolverError, match=r"DIVERGED_MAX_IT at step 1, t = "):
        run_bar(CASE, "newmark-mr", options={"fieldsplit_u_ksp_type": "cg", "fieldsplit_u_pc_type": "none",
                                             "fieldsplit_u_ksp_max_it": 2})
