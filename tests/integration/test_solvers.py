"""Small PETSc solver utilities against dense references."""
import numpy as np
import pytest
from petsc4py import PETSc

from millimpact.integration.solvers import solve_mass
from millimpact.integration.lcp import solve_lcp


def _aij(A: np.ndarray) -> PETSc.Mat:
    M = PETSc.Mat().createAIJ(A.shape, comm=PETSc.COMM_SELF)
    M.setUp()
    for i, j in zip(*np.nonzero(A)):
        M.setValue(int(i), int(j), float(A[i, j]))
    M.assemble()
    return M


def test_mass_solve_falls_back_to_a_factorization():
    # a 1D P1 mass matrix with badly scaled rows (as in reduced models); CG limited to 1 iteration
    # cannot converge, the fallback factorization must give the dense solution
    n = 30
    A = np.diag(np.full(n, 4.0)) + np.diag(np.ones(n - 1), 1) + np.diag(np.ones(n - 1), -1)
    s = np.logspace(0, -4, n)
    A = s[:, None] * A * s[None, :]
    b = np.random.default_rng(0).normal(size=n)
    M = _aij(A)
    rhs = PETSc.Vec().createWithArray(b.copy(), comm=PETSc.COMM_SELF)
    x = rhs.duplicate()
    solve_mass(M, rhs, x, np.array([0], dtype=np.int32), {"mass_ksp_max_it": 1})
    want = np.zeros(n)
    want[1:] = np.linalg.solve(A[1:, 1:], b[1:])      # row 0 is a unit (clamped) row: x = 0
    assert np.allclose(x.array, want, rtol=1e-9, atol=0)


def test_mass_solve_with_a_system_default_and_a_kept_factorization():
    # the reduced systems' default (a Cholesky factorization, reduction/reduced_model.py
    # MASS_FACTORIZATION) on the badly scaled matrix above, kept in a cache dict: a second solve
    # with another right-hand side reuses it and both equal the dense solution (rounding: 1e-9)
    from millimpact.reduction.reduced_model import MASS_FACTORIZATION

    n = 30
    A = np.diag(np.full(n, 4.0)) + np.diag(np.ones(n - 1), 1) + np.diag(np.ones(n - 1), -1)
    s = np.logspace(0, -4, n)
    A = s[:, None] * A * s[None, :]
    M = _aij(A)
    cache: dict = {}
    rows = np.array([0], dtype=np.int32)
    handles = []
    for seed in (0, 1):
        b = np.random.default_rng(seed).normal(size=n)
        rhs = PETSc.Vec().createWithArray(b.copy(), comm=PETSc.COMM_SELF)
        x = rhs.duplicate()
        solve_mass(M, rhs, x, rows, None, MASS_FACTORIZATION, cache)
        want = np.zeros(n)
        want[1:] = np.linalg.solve(A[1:, 1:], b[1:])
        assert np.allclose(x.array, want, rtol=1e-9, atol=0)
        (ksp, _), = cache.values()
        assert ksp.getPC().getType() == "cholesky" and ksp.getIterationNumber() <= 1
        handles.append(ksp.handle)
    # the kept solver is not rebuilt: the same factorization solved both
    assert len(cache) == 1 and handles[0] == handles[1]


def test_lcp_matches_brute_force():
    # the contact LCP g = q + S lam >= 0, lam >= 0, lam.g = 0 for a random SPD S: against the
    # enumeration of all active sets (exact for small n)
    rng = np.random.default_rng(1)
    n = 7
    L = rng.normal(size=(n, n))
    S = L @ L.T + n * np.eye(n)
    q = rng.normal(size=n)
    res = solve_lcp(S, q)
    best = None
    for mask in range(1 << n):
        act = np.array([(mask >> i) & 1 for i in range(n)], dtype=bool)
        lam = np.zeros(n)
        if act.any():
            lam[act] = np.linalg.solve(S[np.ix_(act, act)], -q[act])
        g = q + S @ lam
        if lam.min() >= -1e-12 and g.min() >= -1e-12:
            best = lam
            break
    assert best is not None
    assert np.allclose(res.lam, best, atol=1e-12)


def test_failed_factorization_is_reported_at_set_up():
    """A factorization that fails (here a singular matrix, MUMPS Cholesky) raises at set-up with
    MUMPS's error code, not later as a diverged solve."""
    from petsc4py import PETSc

    from millimpact.errors import SolverError
    from millimpact.integration.solvers import setup_checked

    A = PETSc.Mat().createAIJ((3, 3), nnz=1, comm=PETSc.COMM_SELF)
    for i in range(3):
        A.setValue(i, i, 0.0 if i == 1 else 1.0)
    A.assemble()
    ksp = PETSc.KSP().create(PETSc.COMM_SELF)
    ksp.setOperators(A)
    ksp.setType("preonly")
    ksp.getPC().setType("cholesky")
    ksp.getPC().setFactorSolverType("mumps")
    with pytest.raises(SolverError, match=r"failed in set-up.*MUMPS INFOG\(1\) -10"):
        setup_checked(ksp, "test factorization")


def test_refactorize_factors_again_with_the_new_options():
    """The MUMPS workspace retry (INFOG(1) -8/-9 under MPI) refactorizes with a larger ICNTL(14):
    the factor must really be rebuilt with the new value and still solve. (Found 2026-11-26 when a
    29-minute plastic run of the panel failed on it: after PC.reset() alone KSP.setUp() did nothing,
    so the retry had never worked.)"""
    from millimpact.integration.solvers import create_factored_solver, refactorize

    n = 40
    A = np.diag(np.full(n, 2.0)) - np.diag(np.ones(n - 1), 1) - np.diag(np.ones(n - 1), -1)
    M = _aij(A)
    ksp = create_factored_solver(M, "test_refactor_", {"ksp_type": "preonly", "pc_type": "cholesky",
                                                       "pc_factor_mat_solver_type": "mumps",
                                                       "mat_mumps_icntl_14": "20"})
    assert ksp.getPC().getFactorMatrix().getMumpsIcntl(14) == 20
    assert refactorize(ksp, {"mat_mumps_icntl_14": 400})
    assert ksp.getPC().getFactorMatrix().getMumpsIcntl(14) == 400
    b = np.random.default_rng(2).normal(size=n)
    rhs = PETSc.Vec().createWithArray(b.copy(), comm=PETSc.COMM_SELF)
    x = rhs.duplicate()
    ksp.solve(rhs, x)
    assert np.allclose(x.array, np.linalg.solve(A, b), rtol=1e-10, atol=0)
    opts = PETSc.Options()
    for k in ("ksp_type", "pc_type", "pc_factor_mat_solver_type", "mat_mumps_icntl_14"):
        opts.delValue("test_refactor_" + k)
