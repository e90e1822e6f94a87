"""The dense contact operator of a step size: W = A^-1 C^T (multi-right-hand-side solves with the step's
factorization, in chunks of ``W_CHUNK`` columns) and S = C W, replicated on every rank, both computed
for the columns a step needs (the candidates that touch: :func:`solve_on_touching`); gather/scatter
of the small contact vectors, and the rows of C = [B; T] stacked.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np
from petsc4py import PETSc
from scipy.linalg.blas import daxpy

from ..errors import SolverError
from .solvers import solve_checked

log = logging.getLogger(__name__)

#: Columns of B^T per multi-right-hand-side solve when forming W (bounds the dense RHS memory).
W_CHUNK = 64


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
    """``W = A^-1 C^T`` (n x n_c, distributed MPIDENSE with A's row layout and C's row layout as
    column layout) and ``S = C W`` (n_c x n_c numpy, replicated on every rank), computed column by
    column when asked (:meth:`ensure`). A step needs the columns of the candidates that touch
    (:func:`solve_on_touching`): on the plastic liner panel a third of the 1,074 candidate rows or
    fewer, where forming all of W was half of the time loop (49 of 102 s at 1 rank; a yielding step
    takes a new tangent and its W). ``S`` (the property) completes every column; ``S_known``
    holds the computed columns and, S being symmetric, their rows; its other entries are NaN.
    Units: W and S in m/N."""

    W: PETSc.Mat
    S_known: np.ndarray
    known: np.ndarray  #: bool per column: computed
    ksp: PETSc.KSP
    C: PETSc.Mat
    Ct_csr: tuple  #: (rows, cols, values) of the local rows of C^T
    chunk: int = W_CHUNK
    n_rhs: int = 0  #: columns computed so far (right-hand sides solved)
    #: (key of the columns, S[:, cols], S[cols, cols]) of the last :meth:`columns`, dropped when
    #: :meth:`ensure` computes a column (its symmetrization rewrites known rows)
    _block: tuple | None = None

    @property
    def S(self) -> np.ndarray:
        """The whole S = C A^-1 C^T (computes the columns not yet known)."""
        self.ensure(np.arange(self.known.size))
        return self.S_known

    def ensure(self, cols: np.ndarray) -> int:
        """Compute the columns ``cols`` of W and S not yet known (collective: every rank passes the
        same ``cols``); returns how many it computed."""
        cols = np.asarray(cols, dtype=np.int64)
        new = np.unique(cols[~self.known[cols]])
        if new.size == 0:
            return 0
        for j0 in range(0, new.size, self.chunk):
            self._solve_columns(new[j0 : j0 + self.chunk])
        self.W.assemble()
        # S[:, new] = C W[:, new], gathered on every rank
        Wn = PETSc.Mat().createDense((self.W.getSizes()[0], (PETSc.DECIDE, new.size)), comm=self.W.getComm())
        Wn.setUp()
        Wn.getDenseArray()[:] = self.W.getDenseArray(readonly=True)[:, new]
        Wn.assemble()
        Sm = self.C.matMult(Wn)
        loc = np.array(Sm.getDenseArray(), dtype=float)
        comm = self.C.getComm().tompi4py()
        part = np.vstack(comm.allgather(loc)) if comm.size > 1 else loc
        Sm.destroy()
        Wn.destroy()
        # S is symmetric (A is): the new columns are also rows; where both halves were computed
        # (the new columns against the known ones) their mean removes the rounding asymmetry
        S, old = self.S_known, np.flatnonzero(self.known)
        S[:, new] = part
        both = 0.5 * (part[old, :] + S[np.ix_(new, old)].T)
        S[np.ix_(old, new)] = both
        S[np.ix_(new, old)] = both.T
        S[np.ix_(new, new)] = 0.5 * (part[new, :] + part[new, :].T)
        self.known[new] = True
        self.n_rhs += new.size
        self._block = None
        return new.size

    def columns(self, cols: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(S[:, cols], S[cols, cols]) of computed columns ``cols``, copies kept while the same
        columns are asked for and no column is computed. A yielding step solves its contact
        problem on the same touching columns in every iteration: on the plastic liner segment the
        two fancy-indexed copies were ~3.7 ms of an iteration's ~21 ms contact solve. Read only."""
        key = np.asarray(cols, dtype=np.int64).tobytes()
        if self._block is None or self._block[0] != key:
            S_cols = self.S_known[:, cols]
            self._block = (key, S_cols, S_cols[cols, :])
        return self._block[1], self._block[2]

    def _solve_columns(self, cols: np.ndarray) -> None:
        """W[:, cols] = A^-1 C^T[:, cols]: one multi-right-hand-side solve with a factorization,
        else one Krylov solve per column."""
        rows, aj, av = self.Ct_csr
        pos = np.full(self.known.size, -1, dtype=np.int64)
        pos[cols] = np.arange(cols.size)
        sel = pos[aj] >= 0
        Wa = self.W.getDenseArray()
        n_loc, n = self.W.getSizes()[0]
        pc = self.ksp.getPC()
        if pc.getType() in ("lu", "cholesky"):
            R = PETSc.Mat().createDense(((n_loc, n), (PETSc.DECIDE, cols.size)), comm=self.W.getComm())
            R.setUp()
            Ra = R.getDenseArray()
            Ra[:] = 0.0
            Ra[rows[sel], pos[aj[sel]]] = av[sel]
            R.assemble()
            X = R.duplicate()
            try:
                pc.getFactorMatrix().matSolve(R, X)
            except PETSc.Error as e:
                raise SolverError(f"W = A^-1 C^T: MatMatSolve failed (PETSc error {e.ierr})") from e
            Wa[:, cols] = X.getDenseArray()
            R.destroy()
            X.destroy()
            return
        b = self.ksp.getOperators()[0].createVecLeft()
        x = b.duplicate()
        for j in cols:
            b.set(0.0)
            s = aj == j
            b.array[rows[s]] = av[s]
            solve_checked(self.ksp, b, x, "W = A^-1 C^T column solve", 0, 0.0)
            Wa[:, j] = x.array_r
        b.destroy()
        x.destroy()

    def destroy(self) -> None:
        self.W.destroy()


def contact_operator(ksp_u: PETSc.KSP, C: PETSc.Mat, chunk: int = W_CHUNK) -> ContactOperator:
    """The contact operator of the factorization in ``ksp_u`` with no column computed yet.
    Memory: W is allocated whole, n x n_c doubles (150k x 300 -> 360 MB) per step size."""
    (m_loc, n_c), (n_loc, n) = C.getSizes()
    W = PETSc.Mat().createDense(((n_loc, n), (m_loc, n_c)), comm=C.getComm())
    W.setUp()
    W.assemble()
    Ct = C.transpose(PETSc.Mat())
    ai, aj, av = Ct.getValuesCSR()  # local rows of C^T, global column indices
    csr = (np.repeat(np.arange(n_loc), np.diff(ai)), np.asarray(aj, dtype=np.int64), np.array(av))
    Ct.destroy()
    return ContactOperator(W, np.full((n_c, n_c), np.nan), np.zeros(n_c, dtype=bool), ksp_u, C, csr, chunk)


def compute_contact_operator(ksp_u: PETSc.KSP, C: PETSc.Mat, chunk: int = W_CHUNK) -> ContactOperator:
    """W = A^-1 C^T and S = C W for every candidate row (:class:`ContactOperator`, all columns)."""
    op = contact_operator(ksp_u, C, chunk)
    op.ensure(np.arange(op.known.size))
    return op


def node_columns(nodes: np.ndarray, n_c: int, frictional: bool) -> np.ndarray:
    """The columns of C = [B; T] (T: t1 rows, then t2 rows) of the candidate ``nodes``:
    [normal; t1; t2] of each, in that block order (the layout of :mod:`.friction`)."""
    nodes = np.asarray(nodes, dtype=np.int64)
    return np.concatenate([nodes, n_c + nodes, 2 * n_c + nodes]) if frictional else nodes


def solve_on_touching(
    op: ContactOperator, q: np.ndarray, start: np.ndarray, gap_tol: float, frictional: bool, solve, comm
) -> tuple[object, np.ndarray, np.ndarray]:
    """The contact problem of a step solved on the candidates that touch, computing only their
    columns of W (:meth:`ContactOperator.ensure`). ``q`` the predicted gaps of all n_c candidates
    (m), ``start`` (bool, n_c) the nodes to begin with (the previous active set and the predicted
    penetrations), ``solve(nodes, cols, S_sub)`` the problem restricted to ``nodes`` (``cols`` their
    columns, :func:`node_columns`; ``S_sub = S[cols, cols]``), returning (result, x_sub), the same
    on every rank. A node left out carries no force, so the restricted solution is the whole one
    when every node left out stays open: g_i = q_i + S[i, cols] x_sub >= -gap_tol (the LCP's own
    test); the nodes that fail it join and the problem is solved again. Returns (the last
    result, the nodes, x over all columns: zero off ``cols``)."""
    n_c = q.size
    nodes = np.flatnonzero(start)
    while True:
        cols = node_columns(nodes, n_c, frictional)
        op.ensure(cols)
        S_cols, S_sub = op.columns(cols)
        res, x_sub = solve(nodes, cols, S_sub)
        gap = q + S_cols[:n_c] @ x_sub
        left_out = np.ones(n_c, dtype=bool)
        left_out[nodes] = False
        join = np.flatnonzero(left_out & (gap < -gap_tol))
        if comm.size > 1:
            join = comm.bcast(join, root=0)
        if join.size == 0:
            break
        nodes = np.union1d(nodes, join)
    x = np.zeros(op.known.size)
    x[cols] = x_sub
    return res, nodes, x


def apply_contact_update(op: ContactOperator, x: np.ndarray, u_pred: PETSc.Vec, u_new: PETSc.Vec) -> None:
    """``u_new = u_pred + W x`` for a replicated multiplier vector ``x`` (N: [lambda] or
    [lambda; tau], W's columns): the Lagrange-multiplier state update of a step. Only the columns
    where x is non-zero are read (the active contacts: tens of the hundreds of candidates; the full
    product was 3.8 ms of a 21 ms reduced step on the rig), each rank on its own rows, so no
    communication: the same sum as ``W.mult`` to rounding. The columns are added one by one, in
    place: W is column-major, and gathering the active ones into a copy first (``Wa[:, nz] @ x``)
    took twice as long (6.2 against 3.1 ms for 90 of 230 columns of 11,433 rows). BLAS daxpy adds
    each in place, without numpy's temporary x_j W_j: 0.55 against 1.67 ms for those 90 columns."""
    out = u_new.array
    out[:] = u_pred.array_r
    nz = np.flatnonzero(x)
    if nz.size:
        Wa = op.W.getDenseArray(readonly=True)
        for j in nz:
            res = daxpy(Wa[:, j], out, a=float(x[j]))
            if res is not out:  # in place only on a contiguous float64 array (a PETSc Vec's is)
                out[:] = res
