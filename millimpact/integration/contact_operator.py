"""The dense contact operator of a step size: W = A^-1 C^T (one multi-right-hand-side solve with the step's
factorization, in chunks of ``W_CHUNK`` columns) and S = C W, replicated on every rank; gather/scatter of the
small contact vectors, and the rows of C = [B; T] stacked.
"""
from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np
from petsc4py import PETSc

from ..errors import SolverError

log = logging.getLogger(__name__)

#: Columns of B^T per multi-right-hand-side solve when forming W (bounds the dense RHS memory).
W_CHUNK = 64


from .solvers import solve_checked


# ----------------------------------------------------------------------- dense contact operator
def gather(vec: PETSc.Vec) -> np.ndarray:
    """A distributed Vec as a numpy array replicated on every rank (global order)."""
    comm = vec.getComm().tompi4py()
    loc = np.array(vec.getArray(readonly=True), dtype=float)
    if comm.size == 1:
        return loc
    return np.concatenate(comm.allgather(loc))


def scatter_into(vec: PETSc.Vec, values: np.ndarray) -> None:
    """Set the owned part of ``vec`` from a replicated global array."""
    r0, r1 = vec.getOwnershipRange()
    vec.array[:] = values[r0:r1]


def stack_rows(mats: list[PETSc.Mat]) -> PETSc.Mat:
    """The matrices (same column layout) stacked by rows, ``[A_0; A_1; ...]``, in global row order
    (row r of A_k becomes row sum(rows of A_0..A_k-1) + r, whichever rank owns it). Collective."""
    comm = mats[0].getComm()
    n_loc, n = mats[0].getSizes()[1]
    rows = [m.getSize()[0] for m in mats]
    C = PETSc.Mat().createAIJ(((PETSc.DECIDE, sum(rows)), (n_loc, n)), comm=comm)
    C.setPreallocationNNZ((60, 60))
    C.setOption(PETSc.Mat.Option.NEW_NONZERO_ALLOCATION_ERR, False)
    off = 0
    for m, nr in zip(mats, rows):
        r0, r1 = m.getOwnershipRange()
        for r in range(r0, r1):
            cols, vals = m.getRow(r)
            if len(cols):
                C.setValues([off + r], cols, vals, addv=PETSc.InsertMode.INSERT_VALUES)
        off += nr
    C.assemble()
    return C


@dataclass
class ContactOperator:
    """``W = A^-1 B^T`` (n x n_c, distributed MPIDENSE with A's row layout and B's row layout as
    column layout, so ``W.mult`` takes a multiplier Vec) and ``S = B W`` (n_c x n_c numpy,
    symmetrised, replicated on all ranks). Units: W in m/N, S in m/N."""

    W: PETSc.Mat
    S: np.ndarray
    n_rhs: int


def apply_contact_update(op: ContactOperator, x: np.ndarray, u_pred: PETSc.Vec, u_new: PETSc.Vec) -> None:
    """``u_new = u_pred + W x`` for a replicated multiplier vector ``x`` (N: [lambda] or
    [lambda; tau], W's columns): the Lagrange-multiplier state update of a step. Only the columns
    where x is non-zero are read (the active contacts: tens of the hundreds of candidates; the full
    product was 3.8 ms of a 21 ms reduced step on the rig), each rank on its own rows, so no
    communication: the same sum as ``W.mult`` to rounding."""
    out = u_new.array
    out[:] = u_pred.array_r
    nz = np.flatnonzero(x)
    if nz.size:
        Wa = op.W.getDenseArray(readonly=True)
        out += Wa[:, nz] @ x[nz]


def compute_contact_operator(ksp_u: PETSc.KSP, B: PETSc.Mat, chunk: int = W_CHUNK) -> ContactOperator:
    """W = A^-1 B^T for all candidate rows with the factorization of ``ksp_u`` (multi-RHS solves of
    ``chunk`` columns), and the small dense S = B W replicated on every rank.

    Memory: W holds n x n_c doubles (150k x 300 -> 360 MB) per step size.
    """
    comm = B.getComm().tompi4py()
    (m_loc, n_c), (n_loc, n) = B.getSizes()
    pc = ksp_u.getPC()
    F = pc.getFactorMatrix() if pc.getType() in ("lu", "cholesky") else None
    W = PETSc.Mat().createDense(((n_loc, n), (m_loc, n_c)), comm=B.getComm())
    W.setUp()
    Wa = W.getDenseArray()          # local rows x all columns, a view
    Bt = B.transpose(PETSc.Mat())
    ai, aj, av = Bt.getValuesCSR()  # local rows of B^T, global column indices
    rows = np.repeat(np.arange(n_loc), np.diff(ai))
    for j0 in range(0, n_c, chunk):
        j1 = min(n_c, j0 + chunk)
        k = j1 - j0
        if F is not None:
            R = PETSc.Mat().createDense(((n_loc, n), (PETSc.DECIDE, k)), comm=B.getComm())
            R.setUp()
            Ra = R.getDenseArray()
            Ra[:] = 0.0
            sel = (aj >= j0) & (aj < j1)
            Ra[rows[sel], aj[sel] - j0] = av[sel]
            R.assemble()
            X = R.duplicate()
            try:
                F.matSolve(R, X)
            except PETSc.Error as e:
                raise SolverError(f"W = A^-1 B^T: MatMatSolve failed (PETSc error {e.ierr})") from e
            Wa[:, j0:j1] = X.getDenseArray()
            R.destroy()
            X.destroy()
        else:   # an iterative u-block solver: one solve per column
            b = ksp_u.getOperators()[0].createVecLeft()
            x = b.duplicate()
            for j in range(j0, j1):
                b.set(0.0)
                sel = aj == j
                b.array[rows[sel]] = av[sel]
                solve_checked(ksp_u, b, x, "W = A^-1 B^T column solve", 0, 0.0)
                Wa[:, j] = x.array_r
    W.assemble()
    Bt.destroy()
    Sm = B.matMult(W)
    Sloc = np.array(Sm.getDenseArray(), dtype=float)
    S = np.vstack(comm.allgather(Sloc)) if comm.size > 1 else Sloc
    Sm.destroy()
    S = 0.5 * (S + S.T)      # A is symmetric: remove the rounding asymmetry
    return ContactOperator(W=W, S=S, n_rhs=n_c)


