"""Mass matrices for contact time stepping: redistribution (no mass on the contact dofs;
Khenous, Laborde, Renard, Eur. J. Mech. A 27, 2008) and row-sum (HRZ) lumping."""

from __future__ import annotations

import numpy as np
from petsc4py import PETSc

from ..errors import MillimpactError


def redistribute_mass(M: PETSc.Mat, contact_dofs: np.ndarray, block_size: int | None = None) -> PETSc.Mat:
    """Mass matrix without mass on the contact dofs, total mass per component preserved.

    The idea of Khenous, Laborde and Renard (Eur. J. Mech. A/Solids 27, 2008): a contact node
    without mass follows the body quasi-statically, so imposing the contact on it cannot hit a
    mass and leave it rattling, which is what makes Newmark with contact chatter and pump energy.

    Construction: the rows and columns of the contact dofs C are removed (zeroed) and each
    contact dof c gives ``share_c = r_c + sum_{j not in C} M_cj`` (r_c its row sum, its lumped
    mass) to the diagonal of its same-component neighbours j not in C in M's sparsity graph
    (component = global index % block size), in proportion to ``|M_cj|``. The shares add up to
    exactly what the removal takes from ``e_k^T M e_k`` (2 sum_C r_c - sum_{C x C} M), so the
    total mass of every component, hence the linear momentum of a rigid translation, is
    preserved. The result is symmetric and positive definite on the dofs that keep mass.
    Neighbours may be owned by another rank: the shares are added into a Vec with ADD_VALUES.

    Designed for P1 contact zones (all ``M_cj >= 0``). For P2, vertex row sums are negative and
    a share can be negative; a non-positive resulting diagonal raises :class:`MillimpactError`.

    Returns a new matrix; M is unchanged.
    """
    comm = M.getComm().tompi4py()
    bs = int(block_size or M.getBlockSize() or 1)
    rstart = M.getOwnershipRange()[0]
    cglob = np.asarray(contact_dofs, dtype=np.int64) + rstart
    all_c = np.unique(np.concatenate(comm.allgather(cglob))) if comm.size > 1 else np.unique(cglob)
    add = M.createVecLeft()
    add.set(0.0)
    pending = []  # (dof, share, its contact neighbours): every neighbour is a contact dof too
    for c in cglob:
        cols, vals = M.getRow(int(c))
        same = (cols % bs) == (c % bs)
        cols, vals = cols[same], vals[same]
        in_c = np.isin(cols, all_c)
        share = float(vals.sum() + vals[~in_c].sum())
        nb, w = cols[~in_c], np.abs(vals[~in_c])
        if w.sum() <= 0.0:
            pending.append((int(c), share))
            continue
        add.setValues(nb.astype(PETSc.IntType), share * w / w.sum(), addv=PETSc.InsertMode.ADD_VALUES)
    if comm.allreduce(len(pending)):
        # a node at the edge of a small contact zone: the next ring of non-contact dofs takes its
        # mass, weighted by the two-step couplings (|M| |M|)_ck (rows of any rank: collective)
        M2 = _abs_square(M)
        for c, share in pending:
            cols, vals = M2.getRow(c)
            keep = ((cols % bs) == (c % bs)) & ~np.isin(cols, all_c) & (vals > 0.0)
            nb, w = cols[keep], vals[keep]
            if w.sum() <= 0.0:
                raise MillimpactError(
                    f"mass redistribution: contact dof {c} has no non-contact dof with mass "
                    "within two rings to take its mass"
                )
            add.setValues(nb.astype(PETSc.IntType), share * w / w.sum(), addv=PETSc.InsertMode.ADD_VALUES)
        M2.destroy()
    add.assemble()
    Mr = M.copy()
    Mr.zeroRowsColumns(cglob.astype(PETSc.IntType), diag=0.0)
    Mr.setDiagonal(add, addv=PETSc.InsertMode.ADD_VALUES)
    d = Mr.getDiagonal()
    bad = (add.array != 0.0) & (d.array <= 0.0)
    if comm.allreduce(int(np.count_nonzero(bad))):
        raise MillimpactError(
            "mass redistribution produced a non-positive diagonal (negative row sums: "
            "use P1 elements in the contact zone)"
        )
    add.destroy()
    d.destroy()
    return Mr


def _abs_square(M: PETSc.Mat) -> PETSc.Mat:
    """|M| |M| (entrywise absolute values, then the matrix product), distributed like M."""
    ai, aj, av = M.getValuesCSR()
    A = PETSc.Mat().createAIJ(M.getSizes(), csr=(ai, aj, np.abs(av)), comm=M.getComm())
    A.assemble()
    A2 = A.matMult(A)
    A.destroy()
    return A2


def lumped_mass(M: PETSc.Mat, block_size: int | None = None) -> PETSc.Vec:
    """Diagonal (HRZ) lumped masses (kg): M's diagonal scaled per component so each component's
    total ``e_k^T M e_k`` is kept (Hinton, Rock, Zienkiewicz 1976). Equal to row-sum lumping for
    P1 simplices; positive also for P2 (where row sums are not). Clamped rows (zero diagonal) stay 0.
    """
    bs = int(block_size or M.getBlockSize() or 1)
    ones = M.createVecRight()
    ones.set(1.0)
    rows = M.createVecLeft()
    M.mult(ones, rows)
    d = M.getDiagonal()
    r0 = d.getOwnershipRange()[0]
    comp = (np.arange(d.getLocalSize()) + r0) % bs
    comm = M.getComm().tompi4py()
    for k in range(bs):
        sel = comp == k
        tot = comm.allreduce(float(rows.array[sel].sum()))
        dsum = comm.allreduce(float(d.array[sel].sum()))
        if dsum > 0:
            d.array[sel] *= tot / dsum
    ones.destroy()
    rows.destroy()
    return d


def lumped_mass_matrix(m: PETSc.Vec) -> PETSc.Mat:
    """A diagonal AIJ matrix from lumped masses (so :func:`kinetic_energy` works on it)."""
    n_loc, n = m.getLocalSize(), m.getSize()
    D = PETSc.Mat().createAIJ(((n_loc, n), (n_loc, n)), nnz=(1, 0), comm=m.getComm())
    D.setUp()
    D.setDiagonal(m)
    D.assemble()
    return D
