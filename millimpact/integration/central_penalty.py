"""Explicit central differences (velocity Verlet form) with the lumped (HRZ) mass and a penalty
contact force ``k_p max(-g, 0)`` per row: the cheap, conditionally stable baseline; see
:mod:`millimpact.integration.integrators` for its critical step and options."""

from __future__ import annotations

import logging
import math
import time
from collections.abc import Mapping

import numpy as np
from mpi4py import MPI
from petsc4py import PETSc

from ..errors import InputError
from . import solvers
from .contact_rows import ContactRows
from .dynamics import IntegrationStats, LinearDynamics
from .mass import lumped_mass, lumped_mass_matrix

log = logging.getLogger(__name__)

#: default fraction of the estimated critical step for central-penalty (see the module docstring)
CRITICAL_STEP_SAFETY = 0.5


class CentralPenaltyScheme:
    """Explicit central differences (velocity Verlet), lumped mass, penalty contact."""

    def __init__(self, system: LinearDynamics, options: Mapping, stats: IntegrationStats, comm: MPI.Comm):
        self.sys, self.options, self.stats, self.comm = system, dict(options), stats, comm
        if system.T is not None:
            raise InputError(
                "central-penalty has no friction: use --integrator newmark-mr (or set contact.friction = 0)"
            )
        self.contact = ContactRows(system, comm)
        self.fixed = np.asarray(system.fixed_dofs, dtype=np.int64)
        self.m = lumped_mass(system.M)
        self.m.array[self.fixed] = 0.0
        self.mass = lumped_mass_matrix(self.m)
        self.inv_m = self.m.copy()
        pos = self.m.array > 0
        self.inv_m.array[pos] = 1.0 / self.m.array[pos]
        self.inv_m.array[~pos] = 0.0
        k_p = float(solvers.get_option("penalty", options, -1.0))
        if k_p <= 0:
            factor = float(solvers.get_option("penalty_factor", options, 1.0))
            k_p = factor * self._row_stiffness()
        self.k_p = k_p
        stats.penalty = k_p
        t0 = time.perf_counter()
        lam_max = solvers.estimate_max_eigenvalue(system.K, self.m, self.contact.B, k_p, options)
        self.dt_crit = 2.0 / math.sqrt(lam_max)
        self.safety = float(solvers.get_option("critical_step_safety", options, CRITICAL_STEP_SAFETY))
        self.limit = bool(solvers.get_option("limit_step", options, True))
        self.div_factor = float(solvers.get_option("divergence_factor", options, 10.0))
        stats.dt_critical = self.dt_crit
        if comm.rank == 0:
            log.info(
                "central-penalty: k_p = %.4g N/m, critical step %.4g s (%.2f s); step %s",
                k_p,
                self.dt_crit,
                time.perf_counter() - t0,
                f"limited to {self.safety:g} x critical" if self.limit else "NOT limited",
            )
        self.u = system.M.createVecRight()
        self.v, self.a = self.u.duplicate(), self.u.duplicate()
        self.Ku, self.f = self.u.duplicate(), self.u.duplicate()
        self._saved = [self.u.duplicate() for _ in range(4)]
        self.lam = np.zeros(self.contact.n_c)
        self.gap = self.contact.g0.copy()
        self.n_newton = 0
        self.penalty_energy = 0.0
        self.energy = 0.0
        self.energy_ref = 0.0
        self.diverged = False
        self.touched = False  #: a penalty force acted in some sub-step of the last step

    def _row_stiffness(self) -> float:
        """max_i sum_j B_ij^2 K_jj (N/m): the stiffness a unit constraint displacement meets."""
        B = self.contact.B
        ai, aj, av = B.getValuesCSR()
        B2 = PETSc.Mat().createAIJ(B.getSizes(), csr=(ai, aj, av * av), comm=B.getComm())
        kd = self.sys.K.getDiagonal()
        kd.array[self.fixed] = 0.0
        out = B2.createVecLeft()
        B2.mult(kd, out)
        val = out.max()[1] if out.getSize() else 0.0
        for o in (B2, kd, out):
            o.destroy()
        if not val > 0:
            raise InputError(
                "central-penalty: cannot derive a penalty stiffness (B acts on no free dof); give -impact_penalty"
            )
        return float(val)

    def _forces(self) -> None:
        """a = M_L^-1 (f - K u + B^T k_p max(-g, 0)); updates gap, lam, energies."""
        self.gap = self.contact.gap(self.u)
        pen = np.maximum(-self.gap, 0.0)
        self.lam = self.k_p * pen
        self.penalty_energy = 0.5 * self.k_p * float(np.dot(pen, pen))
        self.sys.K.mult(self.u, self.Ku)
        self.Ku.array[self.fixed] = 0.0
        self.f.array[:] = -self.Ku.array_r
        if self.sys.f_ext is not None:
            self.f.axpy(1.0, self.sys.f_ext)
        if self.lam.any():
            self.contact.add_force(self.lam, self.f)
        self.a.array[:] = self.inv_m.array_r * self.f.array_r

    def _energy(self) -> float:
        ek = 0.5 * float(np.dot(self.m.array_r, self.v.array_r**2))
        es = 0.5 * float(np.dot(self.Ku.array_r, self.u.array_r))
        return self.comm.allreduce(ek + es) + self.penalty_energy

    def initialize(self, u0: PETSc.Vec, v0: PETSc.Vec) -> None:
        u0.copy(self.u)
        v0.copy(self.v)
        for x in (self.u, self.v):
            x.array[self.fixed] = 0.0
        self._forces()
        if np.any(self.gap < 0):
            raise InputError(f"initial penetration: min gap {self.gap.min():.3e} m < 0")
        self.energy = self.energy_ref = self._energy()

    def step(self, dt: float, t_new: float, step: int, allow_reject: bool) -> bool:
        if allow_reject:
            for src, dst in zip((self.u, self.v, self.a, self.Ku), self._saved):
                src.copy(dst)
            saved = (self.lam, self.gap, self.penalty_energy)
        n_sub = max(1, math.ceil(dt / (self.safety * self.dt_crit) - 1e-12)) if self.limit else 1
        h = dt / n_sub
        self.stats.dt_explicit = h if math.isnan(self.stats.dt_explicit) else max(self.stats.dt_explicit, h)
        self.touched = False
        for _ in range(n_sub):
            self.u.array[:] += h * self.v.array_r + 0.5 * h * h * self.a.array_r
            a_old = self.a.array.copy()
            self._forces()
            self.v.array[:] += 0.5 * h * (a_old + self.a.array_r)
            self.stats.n_substeps += 1
            self.touched = self.touched or bool(np.any(self.lam > 0))
        if allow_reject and self.touched:
            for src, dst in zip(self._saved, (self.u, self.v, self.a, self.Ku)):
                src.copy(dst)
            self.lam, self.gap, self.penalty_energy = saved
            self.stats.n_substeps -= n_sub
            return False
        self.energy = self._energy()
        finite = self.comm.allreduce(bool(np.isfinite(self.u.array_r).all() and np.isfinite(self.energy)), op=MPI.LAND)
        if not finite or (self.energy_ref > 0 and self.energy > self.div_factor * self.energy_ref):
            self.diverged = True
        return True

    def rate(self) -> np.ndarray:
        return self.contact.rate(self.v)

    def destroy(self) -> None:
        for o in (self.mass, self.m, self.inv_m, *self._saved):
            o.destroy()
