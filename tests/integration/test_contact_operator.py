"""The contact operator's columns on demand: a contact problem solved on the candidates that touch
equals the problem on every candidate (exact dense references on a small SPD system)."""
import numpy as np
from mpi4py import MPI
from petsc4py import PETSc

from millimpact.integration.contact_operator import contact_operator, node_columns, solve_on_touching
from millimpact.integration.friction import solve_friction
from millimpact.integration.lcp import solve_lcp
from millimpact.integration.solvers import create_effective_solver


def _system(n=60, n_c=10, frictional=False, seed=3):
    """A (1D stiffness + mass, SPD) and contact rows C = [B; T] on random dofs, dense and PETSc."""
    rng = np.random.default_rng(seed)
    A = np.diag(np.full(n, 2.2)) - np.diag(np.ones(n - 1), 1) - np.diag(np.ones(n - 1), -1)
    rows = 3 * n_c if frictional else n_c
    C = np.zeros((rows, n))
    dofs = rng.choice(n, size=rows, replace=False)
    C[np.arange(rows), dofs] = rng.uniform(0.5, 1.5, size=rows)
    Ap = PETSc.Mat().createAIJ(A.shape, comm=PETSc.COMM_SELF)
    Cp = PETSc.Mat().createAIJ(C.shape, comm=PETSc.COMM_SELF)
    for M, D in ((Ap, A), (Cp, C)):
        M.setUp()
        for i, j in zip(*np.nonzero(D)):
            M.setValue(int(i), int(j), float(D[i, j]))
        M.assemble()
    ksp = create_effective_solver(Ap, {})
    return A, C, ksp, Cp, rng


def test_columns_on_demand_equal_the_dense_operator():
    A, C, ksp, Cp, _ = _system()
    op = contact_operator(ksp, Cp)
    op.ensure(np.array([3, 7]))
    assert op.n_rhs == 2 and op.known.sum() == 2
    S = C @ np.linalg.solve(A, C.T)
    # the factorization's solves: round-off of a 60-dof system (cond ~ 1e2)
    assert np.allclose(op.S_known[:, [3, 7]], S[:, [3, 7]], rtol=1e-12, atol=1e-14)
    assert np.allclose(op.S, S, rtol=1e-12, atol=1e-14)        # the property completes S
    assert op.n_rhs == C.shape[0]
    assert np.allclose(op.W.getDenseArray(), np.linalg.solve(A, C.T), rtol=1e-12, atol=1e-14)


def test_lcp_on_the_touching_nodes_equals_the_whole_lcp():
    A, C, ksp, Cp, rng = _system()
    S = C @ np.linalg.solve(A, C.T)
    q = rng.uniform(-1.0, 1.0, size=C.shape[0])
    want = solve_lcp(S, q)
    assert want.active.sum() >= 2           # a problem with several contacts
    op = contact_operator(ksp, Cp)
    start = np.zeros(q.size, dtype=bool)
    start[np.flatnonzero(want.active)[0]] = True     # one of them: the others must join

    def solve(nodes, cols, S_sub):
        r = solve_lcp(S_sub, q[nodes])
        return r, r.lam
    res, nodes, lam = solve_on_touching(op, q, start, 0.0, False, solve, MPI.COMM_SELF)
    assert set(np.flatnonzero(want.active)) <= set(nodes)
    # the active-set LCP solves its active block exactly: round-off of S (entries ~ 1)
    assert np.allclose(lam, want.lam, rtol=1e-10, atol=1e-12)
    assert op.n_rhs == nodes.size < q.size          # columns only of the nodes it kept


def test_friction_on_the_touching_nodes_equals_the_whole_problem():
    n_c = 8
    A, C, ksp, Cp, rng = _system(n=80, n_c=n_c, frictional=True, seed=5)
    S = C @ np.linalg.solve(A, C.T)
    q_n = rng.uniform(-1.0, 1.5, size=n_c)
    q_t = rng.uniform(-0.5, 0.5, size=2 * n_c)
    want = solve_friction(S, q_n, q_t, 0.3)
    assert want.active.sum() >= 2 and 0 < want.active.sum() < n_c
    op = contact_operator(ksp, Cp)

    def solve(nodes, cols, S_sub):
        pairs = np.concatenate([nodes, n_c + nodes])
        r = solve_friction(S_sub, q_n[nodes], q_t[pairs], 0.3)
        return r, np.concatenate([r.lam, r.tau])
    start = q_n < 0.0
    res, nodes, x = solve_on_touching(op, q_n, start, 0.0, True, solve, MPI.COMM_SELF)
    # the fixed point's tolerance (friction.FRICTION_RTOL 1e-10, relative to max lambda)
    scale = np.max(want.lam)
    assert np.allclose(x[:n_c], want.lam, rtol=0, atol=1e-8 * scale)
    assert np.allclose(x[n_c:], want.tau, rtol=0, atol=1e-8 * scale)
    assert op.n_rhs == node_columns(nodes, n_c, True).size < 3 * n_c


def test_kept_columns_follow_the_operator_when_columns_are_added():
    """S[:, cols] and S[cols, cols] are kept between contact solves on the same columns; computing
    another column rewrites known rows (the symmetrized block), so the kept copies must follow."""
    A, C, ksp, Cp, _ = _system()
    S = C @ np.linalg.solve(A, C.T)
    op = contact_operator(ksp, Cp)
    cols = np.array([2, 5, 8])
    op.ensure(cols)
    S_cols, S_sub = op.columns(cols)
    assert op.columns(cols)[0] is S_cols                       # kept while nothing changed
    assert np.allclose(S_sub, S[np.ix_(cols, cols)], rtol=1e-12, atol=1e-14)
    op.ensure(np.array([4]))                                    # a new column: rows 2, 5, 8 rewritten
    wider = np.array([2, 4, 5, 8])
    S_cols2 = op.columns(cols)[0]
    assert S_cols2 is not S_cols
    # the factorization's round-off, as above; the NaN of unknown columns would fail allclose
    assert np.allclose(S_cols2, S[:, cols], rtol=1e-12, atol=1e-14)
    assert np.allclose(op.columns(wider)[1], S[np.ix_(wider, wider)], rtol=1e-12, atol=1e-14)
