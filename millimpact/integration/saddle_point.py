"""The saddle-point solve of a contact step on its active set, [[A, B_A^T], [B_A, 0]] [u; -lambda_A] = [r; -g0_A]:
PCFIELDSPLIT Schur with the exact Schur complement from W (prefix ``impact_``; see
:mod:`millimpact.integration.solvers`), or a monolithic MUMPS LU (``-impact_pc_type lu``).
"""

from __future__ import annotations

import logging
from collections.abc import Mapping

import numpy as np
from petsc4py import PETSc

from .contact_operator import gather, scatter_into
from .solvers import (
    PREFIX,
    SPLIT_LAM,
    SPLIT_U,
    check_ksp,
    create_effective_solver,
    mark_symmetric,
    petsc_options,
    saddle_solver_defaults,
    setup_checked,
    solve_checked,
)

log = logging.getLogger(__name__)


# ------------------------------------------------------------------------------ saddle point
def diagonal_aij(comm: PETSc.Comm, m_loc: int, m: int, values: np.ndarray) -> PETSc.Mat:
    D = PETSc.Mat().createAIJ(((m_loc, m), (m_loc, m)), nnz=(1, 0), comm=comm)
    D.setUp()
    r0, r1 = D.getOwnershipRange()
    for i in range(r0, r1):
        D.setValue(i, i, float(values[i]))
    D.assemble()
    return D


class SaddlePointSolver:
    """The contact saddle-point solve on an active set, fixed size over all candidate rows.

    ``[[A, B_m^T], [B_m, D]] [u; mu] = [r; -g0_m]`` with ``B_m`` = B with the inactive rows zeroed,
    ``D`` = 1 on inactive rows and 0 on active ones, ``g0_m`` = g0 on active rows: inactive
    multipliers are exactly 0 and ``lambda_A = -mu_A``. A MatNest whose ``A`` block is the very
    matrix factorized by :attr:`ksp_u`: changing the active set changes only the other blocks, so
    the factorization is reused (one Cholesky per step size, checked by the tests).

    With the default PCFIELDSPLIT the u-block KSP *is* :attr:`ksp_u` (prefix
    ``impact_fieldsplit_u_``), also used for the predictor solves and for W. With another
    ``-impact_pc_type`` (e.g. ``lu``) the nest is converted to AIJ and factorized at every change
    of the active set, and :attr:`ksp_u` is a separate effective-matrix solver.
    """

    def __init__(self, A: PETSc.Mat, B: PETSc.Mat, options: Mapping[str, object] | None = None):
        self.A, self.B = A, B
        self.options = dict(options or {})
        comm = A.getComm()
        self.comm = comm
        self.m_loc, self.n_c = B.getSizes()[0]
        mark_symmetric(A)
        self.Bt = B.transpose(PETSc.Mat())
        self.Bm = B.copy()
        self.Btm = self.Bt.copy()
        self.mask = B.createVecLeft()
        self.mask.set(0.0)
        self.Bm.diagonalScale(L=self.mask)
        self.Btm.diagonalScale(R=self.mask)
        self.D = diagonal_aij(comm, self.m_loc, self.n_c, np.ones(self.n_c))
        self.N = PETSc.Mat().createNest([[A, self.Btm], [self.Bm, self.D]], comm=comm)
        self.active = np.zeros(self.n_c, dtype=bool)
        self.Sp = diagonal_aij(comm, self.m_loc, self.n_c, np.ones(self.n_c))
        self.n_factorizations = 0
        self.n_solves = 0
        self.max_schur_iterations = 0  #: inner (Schur block) iterations of a solve, maximum
        self._mono: PETSc.KSP | None = None
        self._mono_mat: PETSc.Mat | None = None

        defaults = saddle_solver_defaults(comm.tompi4py())
        self.ksp = PETSc.KSP().create(comm)
        self.ksp.setOptionsPrefix(PREFIX)
        self.ksp.setOperators(self.N)
        pc = self.ksp.getPC()
        with petsc_options(defaults, self.options):
            pc_type = PETSc.Options().getString(PREFIX + "pc_type", "fieldsplit")
            self.fieldsplit = pc_type == "fieldsplit"
            if self.fieldsplit:
                isu, isl = self.N.getNestISs()[0]
                pc.setType("fieldsplit")
                pc.setFieldSplitIS((SPLIT_U, isu), (SPLIT_LAM, isl))
                pc.setFieldSplitSchurPreType(PETSc.PC.SchurPreType.USER, self.Sp)
                self.ksp.setFromOptions()
                setup_checked(self.ksp, "saddle-point solver")
                subs = pc.getFieldSplitSubKSP()
                self.ksp_u, self.ksp_s = subs[0], subs[1]
                setup_checked(self.ksp_u, "factorization of the effective matrix (fieldsplit u block)")
                self.n_factorizations += 1
                setup_checked(self.ksp_s, "Schur-complement preconditioner")
        if not self.fieldsplit:
            self.ksp_u = create_effective_solver(A, self.options)
            self.n_factorizations += 1
        self._ready = self.fieldsplit  # the initial nest (no active row) matches its Schur matrix
        self._rhs_u = A.createVecLeft()
        self._rhs_l = B.createVecLeft()
        self._x_u = A.createVecRight()
        self._x_l = B.createVecLeft()
        self._b = PETSc.Vec().createNest([self._rhs_u, self._rhs_l], comm=comm)
        self._x = PETSc.Vec().createNest([self._x_u, self._x_l], comm=comm)

    def set_active(self, active: np.ndarray, S: np.ndarray, step: int = 0, t: float = 0.0) -> None:
        """Impose the constraints ``active`` (bool, replicated) using the dense S = B A^-1 B^T."""
        active = np.asarray(active, dtype=bool)
        if self._ready and np.array_equal(active, self.active):
            return
        self._ready = True
        self.active = active.copy()
        m = active.astype(float)
        scatter_into(self.mask, m)
        self.B.copy(self.Bm, PETSc.Mat.Structure.SAME_NONZERO_PATTERN)
        self.Bm.diagonalScale(L=self.mask)
        self.Bt.copy(self.Btm, PETSc.Mat.Structure.SAME_NONZERO_PATTERN)
        self.Btm.diagonalScale(R=self.mask)
        dv = self.B.createVecLeft()
        scatter_into(dv, 1.0 - m)
        self.D.setDiagonal(dv)
        dv.destroy()
        if self.fieldsplit:
            # Schur complement of the masked system: -S on the active block, 1 on inactive rows
            ia = np.flatnonzero(active)
            Sp = PETSc.Mat().createAIJ(
                ((self.m_loc, self.n_c), (self.m_loc, self.n_c)),
                nnz=(self.m_loc, self.n_c - self.m_loc),
                comm=self.comm,
            )
            r0, r1 = Sp.getOwnershipRange()
            for i in range(r0, r1):
                if active[i]:
                    Sp.setValues([i], ia.astype(PETSc.IntType), -S[i, ia])
                else:
                    Sp.setValue(i, i, 1.0)
            Sp.assemble()
            self.Sp.destroy()
            self.Sp = Sp
            self.ksp.getPC().setFieldSplitSchurPreType(PETSc.PC.SchurPreType.USER, self.Sp)
            # New state of the nest only (never N.assemble(): it would bump A's state and force a
            # refactorization): PCFieldSplit re-reads the blocks and the Schur preconditioner.
            self.N.stateIncrease()
            self.ksp.setOperators(self.N)
        else:
            if self._mono is not None:
                self._mono.destroy()
            if self._mono_mat is not None:
                self._mono_mat.destroy()
            Nm = self.N.convert("aij", PETSc.Mat())
            ksp = PETSc.KSP().create(self.comm)
            ksp.setOptionsPrefix(PREFIX)
            ksp.setOperators(Nm)
            with petsc_options(saddle_solver_defaults(self.comm.tompi4py()), self.options):
                ksp.setFromOptions()
                setup_checked(ksp, "monolithic saddle-point factorization", step, t)
            self.n_factorizations += 1
            self._mono = ksp
            self._mono_mat = Nm

    def solve(self, r: PETSc.Vec, g0: np.ndarray, u: PETSc.Vec, step: int, t: float) -> np.ndarray:
        """Solve on the current active set: ``u`` (m) in place; returns lambda (N, replicated)."""
        r.copy(self._rhs_u)
        scatter_into(self._rhs_l, -np.where(self.active, g0, 0.0))
        if self.fieldsplit:
            solve_checked(self.ksp, self._b, self._x, "contact saddle-point solve", step, t)
            check_ksp(self.ksp_s, "Schur-complement solve", step, t)
            self.max_schur_iterations = max(self.max_schur_iterations, self.ksp_s.getIterationNumber())
            xu, xl = self._x_u, self._x_l
        else:
            assert self._mono is not None and self._mono_mat is not None, "set_active() factorized the system"
            bb = self._mono_mat.createVecLeft()
            xx = self._mono_mat.createVecRight()
            n_loc = self._rhs_u.getLocalSize()
            bb.array[:n_loc] = self._rhs_u.array_r
            bb.array[n_loc:] = self._rhs_l.array_r
            solve_checked(self._mono, bb, xx, "monolithic contact saddle-point solve", step, t)
            self._x_u.array[:] = xx.array_r[:n_loc]
            self._x_l.array[:] = xx.array_r[n_loc:]
            xu, xl = self._x_u, self._x_l
        self.n_solves += 1
        xu.copy(u)
        lam = -gather(xl)
        lam[~self.active] = 0.0
        return lam

    def destroy(self) -> None:
        """Free the PETSc objects (with the fieldsplit, the factorization in :attr:`ksp_u` goes with
        :attr:`ksp`)."""
        objs = [
            self._mono,
            self._mono_mat,
            self.ksp,
            self.N,
            self.Bm,
            self.Btm,
            self.Bt,
            self.D,
            self.Sp,
            self.mask,
            self._b,
            self._x,
        ]
        if not self.fieldsplit:
            objs.append(self.ksp_u)
        for o in objs:
            if o is not None:
                o.destroy()
