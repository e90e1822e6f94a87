"""Distributed helpers of the reduction: local CSR rows to AIJ, small dense matrices gathered on
every rank, dense column blocks, ownership offsets and even splits of a count over ranks, rows
delivered to their owners, element-wise reductions, bases of a Gram matrix's range (dependent
directions dropped), and rank 0's dense work on the cores of the ranks that wait for it.
"""

from __future__ import annotations

import ctypes
import logging
import os
import time
from contextlib import contextmanager

import numpy as np
import scipy.sparse as sp
from dolfinx import fem
from mpi4py import MPI
from petsc4py import PETSc

from ..errors import SolverError

log = logging.getLogger(__name__)

#: relative eigenvalue of a Gram matrix below which a direction counts as dependent (dropped)
DEPENDENT_TOL = 1e-12


def local_rows_to_aij(P: sp.csr_matrix, V: fem.FunctionSpace) -> PETSc.Mat:
    """A linear map given on each rank by local rows over its local dofs (owned and ghost, the
    layout of ``Function.x.array``; e.g. :class:`millimpact.fem.model.PointProbe`'s maps, summed over
    ranks) as one AIJ matrix with global columns (rows on rank 0). Collective."""
    comm = V.mesh.comm
    bs = V.dofmap.index_map_bs
    imap = V.dofmap.index_map
    n_rows = P.shape[0]
    glob = imap.local_to_global(np.arange(imap.size_local + imap.num_ghosts, dtype=np.int32)).astype(np.int64)
    C = P.tocoo()
    cols = glob[C.col // bs] * bs + C.col % bs
    rows = (n_rows if comm.rank == 0 else 0, n_rows)
    A = PETSc.Mat().createAIJ((rows, (imap.size_local * bs, imap.size_global * bs)), comm=comm)
    A.setPreallocationNNZ((64, 64))
    A.setOption(PETSc.Mat.Option.NEW_NONZERO_ALLOCATION_ERR, False)
    for r, c, v in zip(C.row, cols, C.data):
        A.setValue(int(r), int(c), float(v), addv=PETSc.InsertMode.ADD_VALUES)
    A.assemble()
    return A


#: how often (s) a rank waiting for rank 0's dense work checks whether it is done
IDLE_POLL_S = 0.002


def _openblas():
    """OpenBLAS (numpy's BLAS on Debian, packages.txt), or None where numpy uses another BLAS."""
    try:
        lib = ctypes.CDLL("libopenblas.so.0")
        lib.openblas_get_num_threads()
        return lib
    except (OSError, AttributeError):
        return None


@contextmanager
def root_on_idle_cores(comm: MPI.Comm):
    """Rank 0's dense work inside the block (``if comm.rank == 0: ...``) runs with the BLAS threads
    of every rank on its node, while the others wait asleep at the block's end (a non-blocking
    barrier polled every IDLE_POLL_S) instead of in the blocking broadcast that follows, where
    Open MPI's polling would hold their cores. Collective. ``numpy.linalg.eigh`` of 4,368 columns
    (the liner panel's dense Rayleigh-Ritz): 21.5 s on one thread, 12.2 s on two."""
    if comm.size == 1:
        yield
        return
    mine = _affinity()
    where = comm.allgather((MPI.Get_processor_name(), mine))
    if comm.rank != 0:
        yield
        req = comm.Ibarrier()
        while not req.Test():
            time.sleep(IDLE_POLL_S)
        return
    blas = _openblas()
    n0 = blas.openblas_get_num_threads() if blas is not None else 1
    # mpirun binds each rank to its core(s): rank 0 takes its node's ranks' cores for the block
    # (the BLAS threads it starts keep that mask; they sleep outside BLAS calls)
    cores = set().union(*(c for host, c in where if host == where[0][0] and c is not None))
    if blas is not None and mine is not None and cores:
        os.sched_setaffinity(0, cores)
        blas.openblas_set_num_threads(n0 * sum(host == where[0][0] for host, _ in where))
    try:
        yield
    finally:
        if blas is not None and mine is not None and cores:
            blas.openblas_set_num_threads(n0)
            os.sched_setaffinity(0, mine)
        comm.Ibarrier().Wait()


def computed_on_root(comm: MPI.Comm, compute, shared=None):
    """``compute()`` on rank 0 alone, on the waiting ranks' cores (:func:`root_on_idle_cores`), then
    broadcast: rank 0 returns the result, the others ``shared(result)`` (default the result).
    Collective."""
    result = None
    with root_on_idle_cores(comm):
        if comm.rank == 0:
            result = compute()
    sent = comm.bcast(result if shared is None or comm.rank != 0 else shared(result), root=0)
    return result if comm.rank == 0 else sent


def _affinity() -> set[int] | None:
    """The cores this process may run on, or None where the system does not say."""
    try:
        return set(os.sched_getaffinity(0))
    except (AttributeError, OSError):
        return None


def check_converged(ksp: PETSc.KSP, what: str) -> None:
    reason = ksp.getConvergedReason()
    if reason < 0:
        raise SolverError(f"{what}: KSP diverged with reason {reason} (prefix {ksp.getOptionsPrefix()})")


def deliver_rows(blocks, starts: np.ndarray, n_cols: int, put, comm: MPI.Comm) -> None:
    """Collective: hand rows of a distributed dense result to the ranks that own them, a bounded
    piece at a time. ``blocks`` yields this rank's (global rows, values (k x n_cols)) pieces (each
    computed only when its turn comes); ``starts`` the ownership starts of every rank and the total
    (length size + 1); ``put(local_rows, values)`` stores a piece on its owner. Rows and values
    travel as raw buffers (Alltoallv, no pickling) one piece per round, so a rank holds one piece
    and what it receives in that round, not every slab's rows at once (the 1.2M-DOF panel's
    expansion of Phi took one rank from 6.9 to 9.75 GB with pickled all-at-once messages)."""
    size, rank = comm.size, comm.rank
    pieces = iter(blocks)
    while True:
        piece = next(pieces, None)
        if not comm.allreduce(piece is not None, op=MPI.LOR):
            return
        rows, vals = piece if piece is not None else (np.zeros(0, np.int64), np.zeros((0, n_cols)))
        dest = np.searchsorted(starts, rows, side="right") - 1
        order = np.argsort(dest, kind="stable")
        rows = np.ascontiguousarray(rows[order], dtype=np.int64)
        vals = np.ascontiguousarray(vals[order], dtype=float)
        counts = np.bincount(dest, minlength=size).astype(np.int64)
        recv = np.asarray(comm.alltoall(counts.tolist()), dtype=np.int64)
        got_rows = np.empty(int(recv.sum()), dtype=np.int64)
        comm.Alltoallv([rows, counts], [got_rows, recv])
        got = np.empty((len(got_rows), n_cols))
        comm.Alltoallv([vals, counts * n_cols], [got, recv * n_cols])
        del rows, vals
        put(got_rows - starts[rank], got)


def detached(P: PETSc.Mat) -> PETSc.Mat:
    """A copy of the product ``P`` (of ``matMult`` and kin), which is then destroyed: PETSc keeps
    a product's operands referenced for a later recomputation, so destroying them freed nothing
    while the product lived (the interior rows K_ia, M_ia of the 1.2M-DOF panel, ~1 GB a rank,
    stayed through the whole run behind K_iz G and M_iz G)."""
    out = P.copy()
    P.destroy()
    return out


def gather_rows(A: PETSc.Mat, comm: MPI.Comm) -> np.ndarray:
    """All rows of a (small) dense matrix on every rank, as a numpy array."""
    loc = np.array(A.getDenseArray(), copy=True)
    parts = comm.allgather(loc)
    return np.vstack(parts) if parts else loc


def aij_from_local_csr(S: sp.csr_matrix, sizes, comm: MPI.Comm) -> PETSc.Mat:
    """An MPIAIJ matrix from the CSR of this rank's rows (global column indices)."""
    S = S.tocsr()
    S.sum_duplicates()
    S.sort_indices()
    A = PETSc.Mat().createAIJ(sizes, csr=(S.indptr.astype(np.int32), S.indices.astype(np.int32), S.data), comm=comm)
    A.assemble()
    return A


def ownership_offsets(comm: MPI.Comm, n_local: int) -> np.ndarray:
    counts = np.array(comm.allgather(int(n_local)), dtype=np.int64)
    return np.concatenate([[0], np.cumsum(counts)])


def split_evenly(n: int, size: int, rank: int) -> int:
    """PETSc's default split of n items: the local share of rank ``rank``."""
    return n // size + (1 if rank < n % size else 0)


def dense_columns(A: PETSc.Mat, cols: np.ndarray, comm: MPI.Comm) -> PETSc.Mat:
    """The columns ``cols`` (global, sorted) of the AIJ matrix A as a dense matrix (same rows)."""
    m_loc, m = A.getLocalSize()[0], A.getSize()[0]
    Dm = PETSc.Mat().createDense(((m_loc, m), (PETSc.DECIDE, len(cols))), comm=comm)
    Dm.setUp()
    arr = Dm.getDenseArray()
    arr[:] = 0.0
    indptr, indices, data = A.getValuesCSR()
    if len(indices):
        pos = np.searchsorted(cols, indices)
        rows = np.repeat(np.arange(m_loc), np.diff(indptr))
        np.add.at(arr, (rows, pos), data)
    Dm.assemble()
    return Dm


def gather_aij_dense(A: PETSc.Mat, comm: MPI.Comm) -> np.ndarray:
    """All rows of a small AIJ matrix on every rank, as a dense numpy array."""
    r0, r1 = A.getOwnershipRange()
    indptr, indices, data = A.getValuesCSR()
    loc = sp.csr_matrix((data, indices, indptr), shape=(r1 - r0, A.getSize()[1])).toarray()
    return np.vstack(comm.allgather(loc))


def local_columns_csr(A: PETSc.Mat, cols: np.ndarray) -> sp.csr_matrix:
    """This rank's rows of the columns ``cols`` (global, sorted) of the AIJ matrix A, as scipy CSR
    (column j = cols[j]): :func:`dense_columns` without the dense copy."""
    m_loc = A.getLocalSize()[0]
    indptr, indices, data = A.getValuesCSR()
    keep = np.isin(indices, cols)
    rows = np.repeat(np.arange(m_loc), np.diff(indptr))[keep]
    return sp.csr_matrix((data[keep], (rows, np.searchsorted(cols, indices[keep]))), shape=(m_loc, len(cols)))


def dense_from_rows(loc: np.ndarray, comm: MPI.Comm) -> PETSc.Mat:
    """A dense matrix (rows distributed as given, all columns) holding this rank's rows ``loc``."""
    A = PETSc.Mat().createDense(((loc.shape[0], PETSc.DETERMINE), (PETSc.DECIDE, loc.shape[1])), comm=comm)
    A.setUp()
    A.getDenseArray()[:] = loc
    A.assemble()
    return A


def reduce_array(a: np.ndarray, op: MPI.Op, comm: MPI.Comm) -> np.ndarray:
    """Element-wise Allreduce of a float array (mpi4py's pickling allreduce is not element-wise
    for MIN / MAX / LOR)."""
    a = np.ascontiguousarray(a, dtype=float)
    out = np.empty_like(a)
    comm.Allreduce(a, out, op=op)
    return out


def global_extent(x: np.ndarray, comm: MPI.Comm) -> tuple[np.ndarray, np.ndarray]:
    """The lowest and highest coordinates over every rank's rows ``x`` (k x d; a rank may have none)."""
    d = x.shape[1]
    return (
        reduce_array(x.min(axis=0) if len(x) else np.full(d, np.inf), MPI.MIN, comm),
        reduce_array(x.max(axis=0) if len(x) else np.full(d, -np.inf), MPI.MAX, comm),
    )


def positions_in(sorted_values: np.ndarray, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(pos, found): where each of ``x`` sits in the sorted array, and whether it is there."""
    pos = np.searchsorted(sorted_values, x)
    found = (pos < len(sorted_values)) & (sorted_values[np.minimum(pos, len(sorted_values) - 1)] == x)
    return pos, found


def gram_basis(G: np.ndarray, tol: float, scaled: bool = True) -> np.ndarray:
    """Coefficients W (k x r) with W^T G W = I spanning the range of a Gram matrix G (k x k): the
    eigenvectors of G (``scaled``: of G with its columns scaled to unit norm first) whose eigenvalue
    is above ``tol`` x the largest; the rest count as dependent directions and are dropped."""
    G = 0.5 * (G + G.T)
    d = 1.0 / np.sqrt(np.maximum(np.diag(G), 1e-300)) if scaled else np.ones(len(G))
    lam, U = np.linalg.eigh(d[:, None] * G * d[None, :])
    keep = lam > tol * max(lam.max(initial=0.0), 1e-300)
    return d[:, None] * (U[:, keep] / np.sqrt(lam[keep]))


def orthonormal_columns(B: np.ndarray, comm: MPI.Comm) -> np.ndarray:
    """Columns spanning range(B) (rows distributed), orthonormal in the (distributed) Gram B^T B;
    dependent directions dropped."""
    return B @ gram_basis(reduce_array(B.T @ B, MPI.SUM, comm), DEPENDENT_TOL, scaled=False)
