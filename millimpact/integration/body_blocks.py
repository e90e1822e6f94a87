"""The step operator solved body by body, re-solving only the bodies whose load changed.

Two bodies that only contact couples (the ball and the liner, or the rig's block) give a step
operator ``A = K + M / (beta dt^2)`` that is block-diagonal over them: the contact enters through
the multipliers, not through A. So ``A x = b`` splits into one solve per body,

    A_i x_i = b_i    (i over the connected components of A's graph),

and a body whose right-hand side is, to the bit, the one of the last solve has the same solution.
In a yielding step's fixed-point iterations (:mod:`.plastic_newmark`, ``elastic`` linearisation)
the right-hand side is ``r - f_c(u_k)``: r is fixed within the step and a body whose points do not
yield at u_k keeps its frozen plastic force, so its part does not change. On the plastic rig the
ball yields in 58 of the block's 827 yielding evaluations: most iterations re-solve the block
alone, half the factor.

The bodies are found from A's sparsity pattern (``scipy.sparse.csgraph.connected_components``);
components smaller than :data:`SMALL_COMPONENT` of the dofs (clamped dofs with a unit row, for one)
are solved together as one more block. Each block is a Cholesky factorization of its own
(``create_effective_solver``, the options of the effective matrix), kept with the step size's
operators: the whole operator's factorization stays for the contact operator W and the elastic
steps, so this holds a second factor of A's size. One process only: a distributed A is left to
its own solver.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np
from petsc4py import PETSc

from . import solvers

#: components of fewer dofs than this fraction of A's are gathered into one block
SMALL_COMPONENT = 0.02


@dataclass
class _Block:
    """One body's rows: its dofs (A's local indices), factorized block and last solve."""

    dofs: np.ndarray
    ksp: PETSc.KSP
    A: PETSc.Mat
    b: PETSc.Vec
    x: PETSc.Vec
    last_b: np.ndarray | None = None
    last_x: np.ndarray | None = None


class BodyBlockSolver:
    """``A x = b`` body by body, solving again only the bodies whose part of b changed."""

    def __init__(self, blocks: list[_Block]):
        self.blocks = blocks

    @classmethod
    def build(cls, A: PETSc.Mat, options: Mapping | None = None) -> BodyBlockSolver | None:
        """The block solver of ``A`` (assembled, symmetric positive definite), or None when A is
        distributed over processes or connects all its dofs (nothing to split)."""
        if A.getComm().getSize() > 1:
            return None
        groups = body_components(A)
        if len(groups) < 2:
            return None
        blocks = []
        for dofs in groups:
            iset = PETSc.IS().createGeneral(dofs.astype(PETSc.IntType), comm=A.getComm())
            sub = A.createSubMatrix(iset, iset)
            iset.destroy()
            ksp = solvers.create_effective_solver(sub, options)
            b, x = sub.createVecs()
            blocks.append(_Block(dofs, ksp, sub, b, x))
        return cls(blocks)

    def solve(self, b: PETSc.Vec, x: PETSc.Vec, what: str, step: int, t: float, lag: float = 0.0) -> int:
        """x = A^-1 b: each block solved unless its part of b equals (bitwise) its last one, or
        lies within ``lag`` of it (2-norm): then b's part becomes the last one, so x solves the b
        it returns exactly (a lagged load, for a caller that tests its residual). Returns the
        blocks skipped."""
        rhs, out = b.array, x.array
        skipped = 0
        for blk in self.blocks:
            part = rhs[blk.dofs]
            if blk.last_b is not None and (
                np.array_equal(part, blk.last_b) or (lag > 0.0 and np.linalg.norm(part - blk.last_b) <= lag)
            ):
                rhs[blk.dofs] = blk.last_b
                out[blk.dofs] = blk.last_x
                skipped += 1
                continue
            blk.b.array[:] = part
            solvers.solve_checked(blk.ksp, blk.b, blk.x, what, step, t)
            blk.last_b, blk.last_x = part, blk.x.array_r.copy()
            out[blk.dofs] = blk.last_x
        return skipped

    def destroy(self) -> None:
        for blk in self.blocks:
            for obj in (blk.ksp, blk.A, blk.b, blk.x):
                obj.destroy()
        self.blocks = []


def body_components(A: PETSc.Mat) -> list[np.ndarray]:
    """A's dofs grouped by the connected components of its sparsity pattern (local indices,
    sorted), the components under :data:`SMALL_COMPONENT` of the dofs gathered into one group."""
    import scipy.sparse as sp
    from scipy.sparse.csgraph import connected_components

    ai, aj, _ = A.getValuesCSR()
    n = A.getSize()[0]
    graph = sp.csr_matrix((np.ones(len(aj), dtype=np.int8), aj, ai), shape=(n, n))
    count, labels = connected_components(graph, directed=False)
    sizes = np.bincount(labels, minlength=count)
    big = np.flatnonzero(sizes >= SMALL_COMPONENT * n)
    groups = [np.flatnonzero(labels == c) for c in big]
    rest = np.flatnonzero(~np.isin(labels, big))
    if rest.size:
        groups.append(rest)
    return groups
