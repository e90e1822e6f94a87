"""Block shift-and-invert Krylov eigensolver: the lowest ``count`` modes of K phi = lambda M phi (K, M
symmetric, M positive definite) with an existing factorization of K, applied to blocks of vectors.

Why a block method: a liner region's ~170 modes under the cutoff cost SLEPc's Krylov-Schur ~480
single shift-and-invert solves, each a pass of forward and backward substitution through the whole
Cholesky factor, which is bandwidth-bound. One multi-right-hand-side solve (MatMatSolve) reads the
factor once for all its columns: on the liner panel's region (147k dofs, CHOLMOD) a solve costs
83 ms alone and 15 ms a column in blocks of 64; at the plan's 1.12M region dofs 1.1 s and 0.16 s
(docs/scenes.md). The block method needs more columns in all (the Krylov space is built from
blocks, ~5 ``count``) but each is 5-7x cheaper, and the orthogonalization is BLAS-3.

The method (block Lanczos with full reorthogonalization, Golub and Underwood 1977; Saad,
*Numerical Methods for Large Eigenvalue Problems*, 2nd ed. 2011, sections 6.3 and 8.3): with the
operator S = K^-1 M, self-adjoint in the M inner product, and an M-orthonormal basis V_m of the
block Krylov space span{V_1, S V_1, S^2 V_1, ...},

    S V_m = V_m H_m + V_(m+1) R_m E_m^T,     H_m = V_m^T M S V_m  (symmetric, m x m)

(each new block orthogonalized against the last two blocks, the three-term recurrence, then once
more against the whole basis, classical Gram-Schmidt; then M-orthonormalized by a Cholesky
factorization of its Gram matrix: R_m). The Ritz pairs
(mu, V_m y) of H_m approximate the largest eigenvalues mu = 1 / lambda of S, i.e. the lowest modes,
and the residual needs no extra product: ||S x - mu x||_M = ||R_m y_last||, the bottom block of y.
A pair is converged when that residual over mu is below ``tol`` (SLEPc's relative criterion for
the transformed problem, so ``eps_tol`` means the same for both solvers).

Distributed: each rank holds its rows of the basis (PETSc's row layout of K); the Gram matrices
are summed over ranks (MPI Allreduce), so every rank forms the same H_m and the same Ritz vectors.
The products with M and the solves are PETSc's (MatMatMult, MatMatSolve: CHOLMOD serial, MUMPS
parallel).
"""

from __future__ import annotations

import logging
import time

import numpy as np
import scipy.linalg as sla
from mpi4py import MPI
from petsc4py import PETSc

log = logging.getLogger(__name__)

#: default block size: 32 columns gave the smaller time on the liner panel's region (147k dofs, a
#: prototype of this solver with two BLAS threads: 49 s against 60 s with 64, which needs a larger
#: basis, 1152 against 864 vectors)
BLOCK_SIZE = 32
#: the basis is given up (and the caller falls back to Krylov-Schur) beyond this many times the
#: wanted count, plus 20 blocks for small counts; the panel needed 5.1x (864 vectors for 170 modes)
MAX_DIM_FACTOR = 8


class _Blocks:
    """Products of PETSc matrices with blocks of rows held as numpy arrays (n_loc x b)."""

    def __init__(self, K: PETSc.Mat, M: PETSc.Mat, factor: PETSc.Mat):
        self.K, self.M, self.F = K, M, factor
        self.comm = K.getComm()
        self.mpi = self.comm.tompi4py()
        self.n_loc, self.n = K.getLocalSize()[0], K.getSize()[0]

    def _dense(self, arr: np.ndarray) -> PETSc.Mat:
        return PETSc.Mat().createDense(
            ((self.n_loc, self.n), (PETSc.DECIDE, arr.shape[1])), array=np.asfortranarray(arr), comm=self.comm
        )

    def mult(self, A: PETSc.Mat, W: np.ndarray) -> np.ndarray:
        Wm = self._dense(W)
        P = A.matMult(Wm)
        out = np.array(P.getDenseArray(), order="F", copy=True)
        Wm.destroy()
        P.destroy()
        return out

    def solve(self, B: np.ndarray) -> np.ndarray:
        """K^-1 B with the factorization (one multi-right-hand-side solve)."""
        B = np.asfortranarray(B)
        X = np.zeros_like(B, order="F")
        Bm, Xm = self._dense(B), self._dense(X)  # views of B and X
        self.F.matSolve(Bm, Xm)
        Bm.destroy()
        Xm.destroy()
        return X

    def gram(self, X: np.ndarray, Y: np.ndarray) -> np.ndarray:
        """X^T Y summed over ranks."""
        loc = np.ascontiguousarray(X.T @ Y)
        out = np.empty_like(loc)
        self.mpi.Allreduce(loc, out, op=MPI.SUM)
        return out

    def m_orthonormalize(self, W: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
        """(Q, M Q, R) with W = Q R, Q^T M Q = I (Cholesky of the Gram matrix); None on breakdown.
        M Q = (M W) R^-1 comes with it: the next block's solve needs it."""
        MW = self.mult(self.M, W)
        G = self.gram(W, MW)
        G = 0.5 * (G + G.T)
        try:
            R = np.linalg.cholesky(G).T
        except np.linalg.LinAlgError:
            return None
        if np.min(np.abs(np.diag(R))) < 1e-10 * np.max(np.abs(np.diag(R))):
            return None

        def right_divide(X: np.ndarray) -> np.ndarray:  # X R^-1
            return np.asfortranarray(sla.solve_triangular(R, X.T, trans="T", lower=False).T)

        return right_divide(W), right_divide(MW), R


def block_krylov_modes(
    K: PETSc.Mat,
    M: PETSc.Mat,
    factor: PETSc.Mat,
    count: int,
    *,
    block: int = BLOCK_SIZE,
    tol: float = 1e-10,
    max_dim: int | None = None,
    seed: int = 20221122,
) -> tuple[np.ndarray, list[PETSc.Vec], dict] | None:
    """The lowest ``count`` eigenpairs of K phi = lambda M phi, ``factor`` a factorization of K
    (its MatMatSolve). Returns (lambda ascending, M-orthonormal eigenvectors as Vecs laid out like
    K's columns, statistics: basis size, seconds in the solves and in all), or None if the basis reached ``max_dim`` (default
    MAX_DIM_FACTOR count + 20 blocks) unconverged or broke down (the caller falls back). Collective."""
    ops = _Blocks(K, M, factor)
    n = ops.n
    block = max(1, min(block, n))
    count = min(count, n)
    if max_dim is None:
        max_dim = MAX_DIM_FACTOR * count + 20 * block
    max_dim = min(max_dim, n)
    rng = np.random.default_rng([seed, ops.mpi.rank])
    first = ops.m_orthonormalize(rng.standard_normal((ops.n_loc, block)))
    if first is None:
        return None
    V = np.empty((ops.n_loc, max_dim + block), order="F")
    H = np.zeros((max_dim + block, max_dim + block))
    V[:, :block], MV_last = first[0], first[1]
    m = block
    t_solve = 0.0
    t_start = time.perf_counter()
    while True:
        t0 = time.perf_counter()
        W = ops.solve(MV_last)  # S applied to the last block
        t_solve += time.perf_counter() - t0
        # the three-term recurrence (S is M-self-adjoint: W is M-orthogonal to all but the last two
        # blocks in exact arithmetic), then one full classical Gram-Schmidt pass against the whole
        # basis, which the blocks need (they lose orthogonality fast). Two full passes instead:
        # the same basis and modes, eigensolve 68.8 s against 57.1 s on the panel's 147k dofs
        for lo in (max(0, m - 2 * block), 0):
            h = ops.gram(V[:, lo:m], ops.mult(M, W))
            W -= V[:, lo:m] @ h
            H[lo:m, m - block : m] += h
        qr = ops.m_orthonormalize(W)
        if qr is None:
            log.info("block Krylov: breakdown at basis size %d", m)
            return None
        W, MV_last, R = qr
        H[m : m + block, m - block : m] = R
        if m >= count + block:
            T = H[:m, :m]
            mu, Y = sla.eigh(0.5 * (T + T.T), subset_by_index=[m - count, m - 1])
            mu, Y = mu[::-1].copy(), np.ascontiguousarray(Y[:, ::-1])
            res = np.linalg.norm(R @ Y[m - block : m, :], axis=0) / np.abs(mu)
            if np.all(mu > 0) and np.max(res) < tol:
                break
        if m + block > max_dim:
            log.info(
                "block Krylov: %d of %d pairs unconverged at basis size %d",
                int(np.sum(res >= tol)) if m >= count + block else count,
                count,
                m,
            )
            return None
        V[:, m : m + block] = W
        m += block
    X = V[:, :m] @ Y
    vecs = []
    for k in range(count):
        v = K.createVecRight()
        v.getArray()[:] = X[:, k]
        vecs.append(v)
    return 1.0 / mu, vecs, {"basis": m, "solve_s": t_solve, "total_s": time.perf_counter() - t_start}
