"""AndersonMixing (the plastic step's accelerated fixed point, issue 31) on small exact problems.

- a linear contraction G(u) = M u + b: Anderson type II with full depth is GMRES on (I - M) u = b
  (Walker & Ni, SIAM J. Numer. Anal. 49, 2011, Thm 2.2), so it reaches the fixed point in at most
  n + 1 iterations in exact arithmetic, where the plain iteration contracts by rho(M) only;
- the carried image: mixing L G(u_i) with the same gamma gives L u_(k+1) exactly (the residual's
  product A u that the plastic step no longer forms, :mod:`millimpact.integration.plastic_newmark`).
"""
from __future__ import annotations

import numpy as np
from mpi4py import MPI
from petsc4py import PETSc

from millimpact.integration.plastic_newmark import AndersonMixing


def _vec(a):
    v = PETSc.Vec().createSeq(len(a), comm=PETSc.COMM_SELF)
    v.array[:] = a
    return v


def _problem(n=8, rho=0.9, seed=3):
    rng = np.random.default_rng(seed)
    Q, _ = np.linalg.qr(rng.standard_normal((n, n)))
    M = Q @ np.diag(np.linspace(0.1, rho, n)) @ Q.T          # symmetric, spectral radius rho
    return M, rng.standard_normal(n), rng.standard_normal((n, n))


def test_full_depth_reaches_the_fixed_point_in_n_plus_one_iterations():
    M, b, _ = _problem()
    exact = np.linalg.solve(np.eye(len(b)) - M, b)
    mixing = AndersonMixing(len(b) + 1, MPI.COMM_SELF)
    u, g = _vec(np.zeros(len(b))), _vec(np.zeros(len(b)))
    for _ in range(len(b) + 2):
        g.array[:] = M @ u.array + b
        mixing.next_iterate(u, g)
    # round-off of a Gram-matrix least squares with a 1e-12 ridge: 1e-6 relative is far below
    # the plain iteration's 0.9^10 = 0.35 after as many steps
    assert np.linalg.norm(u.array - exact) < 1e-6 * np.linalg.norm(exact)


def test_the_carried_image_is_the_image_of_the_mixed_iterate():
    M, b, L = _problem()
    mixing = AndersonMixing(4, MPI.COMM_SELF)
    u, g = _vec(np.ones(len(b))), _vec(np.zeros(len(b)))
    for k in range(7):
        g.array[:] = M @ u.array + b
        image = mixing.next_iterate(u, g, L @ g.array)
        # exact up to the rounding of a few products of size-8 vectors
        assert np.allclose(image, L @ u.array, rtol=1e-12, atol=1e-12 * np.abs(image).max()), k


def test_no_image_without_one_from_the_start():
    """A history begun without images cannot carry one (its earlier pairs have none): None."""
    M, b, L = _problem()
    mixing = AndersonMixing(4, MPI.COMM_SELF)
    u, g = _vec(np.ones(len(b))), _vec(np.zeros(len(b)))
    g.array[:] = M @ u.array + b
    assert mixing.next_iterate(u, g) is None
    g.array[:] = M @ u.array + b
    assert mixing.next_iterate(u, g, L @ g.array) is None
