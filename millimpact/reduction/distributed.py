"""Distributed PETSc helpers of the reduction: local CSR rows to AIJ, small dense matrices gathered on
every rank, dense column blocks, ownership offsets and even splits of a count over ranks.
"""
from __future__ import annotations

import ctypes

import logging

import numpy as np
import scipy.sparse as sp
from dolfinx import fem
from mpi4py import MPI
from petsc4py import PETSc

from ..errors import SolverError

log = logging.getLogger(__name__)



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


def check_converged(ksp: PETSc.KSP, what: str) -> None:
    reason = ksp.getConvergedReason()
    if reason < 0:
        raise SolverError(f"{what}: KSP diverged with reason {reason} (prefix {ksp.getOptionsPrefix()})")


def return_freed_memory() -> None:
    """Hand the memory the process has freed back to the system (glibc's ``malloc_trim(0)``: it
    releases the free pages inside the heap too, not only at its top); no-op elsewhere."""
    try:
        ctypes.CDLL("libc.so.6").malloc_trim(0)
    except (OSError, AttributeError):
        pass


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
    A = PETSc.Mat().createAIJ(sizes, csr=(S.indptr.astype(np.int32), S.indices.astype(np.int32), S.data),
                              comm=comm)
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
