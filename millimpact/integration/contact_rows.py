"""The contact rows as an integrator uses them: gaps and rates replicated on every rank, forces
B^T lambda, and the tangential rows of friction; rank 0's answers broadcast."""

from __future__ import annotations

import numpy as np
from mpi4py import MPI
from petsc4py import PETSc

from ..errors import InputError
from .contact_operator import gather, scatter_into, stack_rows
from .dynamics import LinearDynamics


class ContactRows:
    """Gaps and rates replicated on every rank; B^T lambda."""

    def __init__(self, system: LinearDynamics, comm: MPI.Comm):
        B = system.B
        self.comm = comm
        self.n_c = B.getSize()[0]
        self.g0 = np.asarray(system.g0, dtype=float).reshape(-1)
        if self.g0.size != self.n_c:
            raise InputError(f"g0 has {self.g0.size} entries but B has {self.n_c} rows")
        n_fixed = comm.allreduce(len(system.fixed_dofs))
        T = system.T
        if n_fixed:
            # clamped dofs cannot move: remove their columns so neither the gaps nor the forces
            # involve them (the saddle-point rows would otherwise move them)
            mask = B.createVecRight()
            mask.set(1.0)
            mask.array[np.asarray(system.fixed_dofs, dtype=np.int64)] = 0.0
            B = B.copy()
            B.diagonalScale(R=mask)
            if T is not None:
                T = T.copy()
                T.diagonalScale(R=mask)
            mask.destroy()
        self.B = B
        self._c = B.createVecLeft()
        self._f = B.createVecRight()
        # friction: C = [B; T] (3 n_c rows), the rows whose multipliers the step solves for
        self.T = T
        self.C = stack_rows([B, T]) if T is not None else B
        if T is not None:
            self._t = T.createVecLeft()
            self._cc = self.C.createVecLeft()

    def gap(self, u: PETSc.Vec) -> np.ndarray:
        """g0 + B u (m), replicated."""
        self.B.mult(u, self._c)
        return self.g0 + gather(self._c)

    def rate(self, v: PETSc.Vec) -> np.ndarray:
        """B v (m/s), replicated."""
        self.B.mult(v, self._c)
        return gather(self._c)

    def slip(self, du: PETSc.Vec) -> np.ndarray:
        """T du (m), replicated: relative tangential displacements [t1; t2]."""
        assert self.T is not None, "slip() needs the friction rows T"
        self.T.mult(du, self._t)
        return gather(self._t)

    def add_multiplier_force(self, x: np.ndarray, f: PETSc.Vec, scale: float = 1.0) -> None:
        """f += scale * C^T x for x = [lambda; tau] (friction, 3 n_c values), or B^T lambda."""
        if x.size == self.n_c:
            self.add_force(x, f, scale)
            return
        scatter_into(self._cc, x)
        self.C.multTranspose(self._cc, self._f)
        f.axpy(scale, self._f)

    def add_force(self, lam: np.ndarray, f: PETSc.Vec, scale: float = 1.0) -> None:
        """f += scale * B^T lam."""
        scatter_into(self._c, lam)
        self.B.multTranspose(self._c, self._f)
        f.axpy(scale, self._f)


def broadcast(comm: MPI.Comm, obj):
    return comm.bcast(obj, root=0) if comm.size > 1 else obj
