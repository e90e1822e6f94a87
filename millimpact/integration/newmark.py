"""Average-acceleration Newmark (beta = 1/4, gamma = 1/2) with Lagrange-multiplier contact on
u_{n+1}, on the redistributed mass (``newmark-mr``) or the consistent one (``newmark``).

Each step: one predictor solve with lambda = 0 using the factorization of ``A = K + M/(beta dt^2)``
(cached per step size; after the impact, one step size's at a time), the exact small LCP
``g = q + S lambda`` on ``S = B A^-1 B^T`` (or the frictional problem on ``C = [B; T]``), then
the final state from the saddle-point solve on the active set or ``u = u_pred + W lambda``; see
:mod:`millimpact.integration.integrators`.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING, Literal

import numpy as np
from mpi4py import MPI
from petsc4py import PETSc

from ..errors import InputError, SolverError
from . import solvers
from .contact_operator import ContactOperator, apply_contact_update, contact_operator, node_columns, solve_on_touching
from .contact_rows import ContactRows, broadcast
from .dynamics import IntegrationStats, LinearDynamics, product_matrix
from .friction import PASS_RTOL
from .lcp import LCPResult, solve_lcp
from .mass import redistribute_mass
from .saddle_point import SaddlePointSolver

if TYPE_CHECKING:
    from .body_blocks import BodyBlockSolver

log = logging.getLogger(__name__)

#: how often a run may free its step operators after separation (NewmarkScheme._release_step_operators)
MAX_RELEASES = 2


@dataclass
class StepOperators:
    """Cached linear algebra of one step size."""

    dt: float
    A: PETSc.Mat
    ksp_u: PETSc.KSP
    saddle: SaddlePointSolver | None
    contact: ContactOperator | None = None
    #: A solved body by body (:class:`.body_blocks.BodyBlockSolver`), built by a plastic scheme;
    #: None until it is, False when A did not split (or is distributed)
    body_blocks: BodyBlockSolver | Literal[False] | None = None


class NewmarkScheme:
    """Average-acceleration Newmark with Lagrange-multiplier contact on u_{n+1}."""

    beta, gamma = 0.25, 0.5

    def __init__(
        self, system: LinearDynamics, redistribute: bool, options: Mapping, stats: IntegrationStats, comm: MPI.Comm
    ):
        self.sys, self.options, self.stats, self.comm = system, dict(options), stats, comm
        self.contact = ContactRows(system, comm)
        self.fixed = np.asarray(system.fixed_dofs, dtype=np.int64)
        if redistribute:
            # with a shared operator cache (the impacts of a contact table) the redistributed mass
            # is built once too: it depends on M and the contact dofs only (0.2-0.3 s a case on the rig)
            cache = system.operator_cache
            if cache is not None and "redistributed_mass" in cache:
                self.M = cache["redistributed_mass"]
            else:
                self.M = redistribute_mass(system.M, system.contact_dofs)
                if cache is not None:
                    cache["redistributed_mass"] = self.M
            self.massless = np.asarray(system.contact_dofs, dtype=np.int64)
        else:
            self.M = system.M
            self.massless = np.zeros(0, dtype=np.int64)
        cs = str(solvers.get_option("contact_solve", options, "fieldsplit")).lower()
        if cs not in ("fieldsplit", "schur", "lu"):
            raise InputError(f"-impact_contact_solve {cs!r}: choose fieldsplit, schur or lu")
        # friction: the step's multipliers come from the dense problem on S = C A^-1 C^T and the
        # state from u = u_pred + W [lambda; tau] (the "schur" update, exact with the factorization)
        self.mu = float(system.friction) if system.T is not None else 0.0
        self.frictional = system.T is not None
        stats.friction = self.mu
        if self.frictional:
            cs = "schur"
        self.tau = np.zeros(2 * self.contact.n_c) if self.frictional else None
        self.sliding = np.zeros(self.contact.n_c, dtype=bool)
        self.contact_solve = cs
        stats.contact_solve = cs
        self.petsc_options = dict(options)
        if cs == "lu":
            self.petsc_options = {"pc_type": "lu", **solvers.normalize_options(options)}
        self.gap_rtol = float(solvers.get_option("gap_rtol", options, 1e-9))
        self.check_rtol = float(solvers.get_option("lambda_check_rtol", options, 1e-6))
        # step operators per dt; shared between calls when the system keeps a cache (same mass
        # treatment and contact solve: they determine the operators)
        cache = system.operator_cache
        self._shared_ops = cache is not None
        self.ops: dict[float, StepOperators] = cache.setdefault((cs, redistribute), {}) if cache is not None else {}
        self.contact_seen = False  #: a contact was active at some accepted step
        self.n_releases = 0  #: times the step operators were released (<= MAX_RELEASES)
        self.released_operators = 0  #: step sizes' operators released after the impact
        self._released = _OperatorTotals()  #: what the released operators did
        self.u = system.M.createVecRight()
        self.v, self.a = self.u.duplicate(), self.u.duplicate()
        self.u_new, self.u_pred = self.u.duplicate(), self.u.duplicate()
        self.r, self.tmp = self.u.duplicate(), self.u.duplicate()
        self.lam = np.zeros(self.contact.n_c)
        self.gap = self.contact.g0.copy()
        self.active = np.zeros(self.contact.n_c, dtype=bool)
        self.n_newton = 0
        self.penalty_energy = 0.0
        #: the Coulomb alternation's stopping test (friction.solve_friction's rtol)
        self.friction_rtol = PASS_RTOL

    @property
    def mass(self) -> PETSc.Mat:
        return self.M

    def initialize(self, u0: PETSc.Vec, v0: PETSc.Vec) -> None:
        u0.copy(self.u)
        v0.copy(self.v)
        for x in (self.u, self.v):
            x.array[self.fixed] = 0.0
        self.gap = self.contact.gap(self.u)
        tol = self.gap_rtol * max(float(np.max(np.abs(self.gap), initial=0.0)), 1e-300)
        if np.any(self.gap < -tol):
            raise InputError(f"initial penetration: min gap {self.gap.min():.3e} m < 0")
        # M a0 = f - K u0 (gaps open: lambda0 = 0); massless and clamped dofs: a0 = 0
        rhs = self.u.duplicate()
        self.sys.K.mult(self.u, rhs)
        rhs.scale(-1.0)
        if self.sys.f_ext is not None:
            rhs.axpy(1.0, self.sys.f_ext)
        rhs.array[self.fixed] = 0.0
        rhs.array[self.massless] = 0.0
        self.a.set(0.0)
        if rhs.norm() > 0.0:
            solvers.solve_mass(
                self.M,
                rhs,
                self.a,
                np.union1d(self.fixed, self.massless),
                self.options,
                self.sys.mass_solver,
                self.sys.operator_cache,
            )
        rhs.destroy()

    def _ops(self, dt: float) -> StepOperators:
        if dt in self.ops:
            return self.ops[dt]
        for known in self.ops:  # the same step from another schedule's grid, to round-off
            if abs(known - dt) <= 1e-12 * dt:
                return self.ops[known]
        if (
            self.ops
            and not self._shared_ops
            and self.contact_seen
            and not self.active.any()
            and self.n_releases < MAX_RELEASES
        ):
            self._release_step_operators()
        c0 = 1.0 / (self.beta * dt * dt)
        A = self.sys.K.copy()
        try:
            A.axpy(c0, self.M, PETSc.Mat.Structure.SUBSET_NONZERO_PATTERN)
        except PETSc.Error:
            A = self.sys.K.copy()
            A.axpy(c0, self.M, PETSc.Mat.Structure.DIFFERENT_NONZERO_PATTERN)
        t0 = time.perf_counter()
        if self.contact_solve == "schur" or self.contact.n_c == 0:
            ksp_u = solvers.create_effective_solver(A, self.petsc_options)
            saddle = None
        else:
            saddle = SaddlePointSolver(A, self.contact.B, self.petsc_options)
            ksp_u = saddle.ksp_u
        self.stats.n_factorizations += 1
        if self.comm.rank == 0:
            log.info(
                "dt = %.4g s: effective matrix factorized in %.2f s (%s)",
                dt,
                time.perf_counter() - t0,
                ksp_u.getPC().getFactorSolverType()
                if ksp_u.getPC().getType() in ("lu", "cholesky")
                else ksp_u.getPC().getType(),
            )
        op = StepOperators(dt, A, ksp_u, saddle)
        self.ops[dt] = op
        return op

    def _release_step_operators(self) -> None:
        """Free the cached step operators (factorizations and contact operators W) before another
        step size's are built, once the bodies have separated after an impact: the free steps'
        operators then do not sit beside the contact step's (the plastic liner panel: +1.2 GB at
        the time loop's end, its machine peak). A step size needed again later (the contact step
        that lands on t_end, or between free steps while a gap closes) is factorized again; at
        most MAX_RELEASES times a run, after which both are kept, so a vibrating gap costs at
        most that many factorizations more (the count of factorizations includes them)."""
        self.n_releases += 1
        self.released_operators += len(self.ops)
        self._released = self._released.plus(self.ops.values())
        for op in self.ops.values():
            _destroy_step_operators(op)
        self.ops.clear()
        solvers.return_freed_memory()

    def operator_totals(self) -> _OperatorTotals:
        """Factorizations and saddle-point solves of this run's step operators, released ones included."""
        return self._released.plus(self.ops.values())

    def _contact_operator(self, op: StepOperators) -> ContactOperator:
        """The step size's contact operator (its columns are computed as steps need them)."""
        if op.contact is None:
            op.contact = contact_operator(op.ksp_u, self.contact.C)
        return op.contact

    def _start_active(self) -> np.ndarray:
        """The active set a contact problem starts from (its nodes first solved on and the LCP's
        warm start): the last accepted step's."""
        return self.active

    def _on_touching(self, C: ContactOperator, q: np.ndarray, gap_tol: float, solve):
        """:func:`solve_on_touching` from the last active set and the predicted penetrations,
        booking the columns of W it computed."""
        before = C.n_rhs
        out = solve_on_touching(C, q, self._start_active() | (q < -gap_tol), gap_tol, self.frictional, solve, self.comm)
        self.stats.n_w_columns += C.n_rhs - before
        return out

    def _lcp(self, C: ContactOperator, q: np.ndarray, gap_tol: float) -> LCPResult:
        """The frictionless contact LCP of the step over all candidates, solved on those that touch."""

        def solve(nodes, cols, S_sub):
            r = broadcast(self.comm, solve_lcp(S_sub, q[nodes], self._start_active()[nodes], gap_tol))
            return r, r.lam

        res, nodes, lam = self._on_touching(C, q, gap_tol, solve)
        return LCPResult(lam, lam > 0, res.iterations, res.method)

    def step(self, dt: float, t_new: float, step: int, allow_reject: bool) -> bool:
        """Advance by dt; False (state unchanged) if ``allow_reject`` and a gap would close."""
        op = self._ops(dt)
        self._predictor_rhs(dt)
        solvers.solve_checked(op.ksp_u, self.r, self.u_pred, "effective-matrix solve", step, t_new)
        self.stats.n_solves += 1
        q = self.contact.gap(self.u_pred)
        scale = max(float(np.max(np.abs(q), initial=0.0)), float(np.max(np.abs(self.contact.g0), initial=0.0)))
        gap_tol = self.gap_rtol * max(scale, 1e-300)
        n_c = q.size
        if n_c == 0 or np.all(q >= -gap_tol):
            lam = np.zeros(n_c)
            self.u_pred.copy(self.u_new)
            self.n_newton = 0
            if self.frictional:
                self.tau, self.sliding = np.zeros(2 * n_c), np.zeros(n_c, dtype=bool)
        else:
            if allow_reject:
                return False
            C = self._contact_operator(op)
        if n_c and not np.all(q >= -gap_tol) and self.frictional:
            lam = self._friction_step(C, q, gap_tol, step)
        elif n_c and not np.all(q >= -gap_tol):
            res = self._lcp(C, q, gap_tol)
            self.n_newton = res.iterations
            self.stats.n_lcp_fallback += res.method != "active-set"
            lam = res.lam
            if not res.active.any():
                self.u_pred.copy(self.u_new)
            elif self.contact_solve == "schur":
                apply_contact_update(C, lam, self.u_pred, self.u_new)
            else:
                assert op.saddle is not None, "a saddle-point contact solve has its solver"
                op.saddle.set_active(res.active, C.S_known, step, t_new)
                lam_s = op.saddle.solve(self.r, self.contact.g0, self.u_new, step, t_new)
                self.stats.n_saddle_solves += 1
                err = float(np.max(np.abs(lam_s - lam)))
                if err > self.check_rtol * max(float(np.max(np.abs(lam))), 1e-300):
                    raise SolverError(
                        f"contact saddle-point solve disagrees with the LCP: max |dlambda| = "
                        f"{err:.3e} N (|lambda| = {np.max(np.abs(lam)):.3e} N) at step {step}, "
                        f"t = {t_new:.9g} s"
                    )
                lam = lam_s
            self.stats.n_newton += self.n_newton
            self.stats.max_newton = max(self.stats.max_newton, self.n_newton)
        self._accept(lam, dt, step, t_new, gap_tol, scale)
        return True

    def _predictor_rhs(self, dt: float) -> None:
        """self.r = M (c0 u + c1 v + c2 a) + f_ext, zero on clamped rows (the effective right-hand side)."""
        b = self.beta
        c0, c1, c2 = 1.0 / (b * dt * dt), 1.0 / (b * dt), 0.5 / b - 1.0
        self.tmp.array[:] = c0 * self.u.array_r + c1 * self.v.array_r + c2 * self.a.array_r
        product_matrix(self.M).mult(self.tmp, self.r)
        if self.sys.f_ext is not None:
            self.r.axpy(1.0, self.sys.f_ext)
        self.r.array[self.fixed] = 0.0

    def _accept(self, lam: np.ndarray, dt: float, step: int, t_new: float, gap_tol: float, scale: float) -> None:
        """Check the contact conditions at ``self.u_new`` and advance u, v, a by the Newmark update."""
        b, g = self.beta, self.gamma
        c0, c1, c2 = 1.0 / (b * dt * dt), 1.0 / (b * dt), 0.5 / b - 1.0
        n_c = lam.size
        gap = self.contact.gap(self.u_new)
        lam_tol = 1e-8 * max(float(np.max(np.abs(lam), initial=0.0)), 1e-300)
        if n_c and (np.min(lam) < -lam_tol or np.min(gap) < -max(gap_tol, 1e-8 * scale)):
            raise SolverError(
                f"contact conditions violated after the step: min lambda {np.min(lam):.3e} N, "
                f"min gap {np.min(gap):.3e} m at step {step}, t = {t_new:.9g} s"
            )
        if self.tau is not None:  # frictional
            self.tau = np.where(np.concatenate([lam, lam]) > lam_tol, self.tau, 0.0)
        lam = np.where(lam > lam_tol, lam, 0.0)
        # Newmark update on the local arrays
        u, v, a, un = self.u.array, self.v.array, self.a.array, self.u_new.array_r
        a_new = c0 * (un - u) - c1 * v - c2 * a
        v_new = v + dt * ((1.0 - g) * a + g * a_new)
        ml = self.massless
        if ml.size:
            # massless dofs carry no momentum: their velocity is the backward difference of u
            # (the Newmark recursion would ring there with period 2 dt after an impact)
            vm = (un[ml] - u[ml]) / dt
            a_new[ml] = (vm - v[ml]) / dt
            v_new[ml] = vm
        a_new[self.fixed] = 0.0
        v_new[self.fixed] = 0.0
        u[:] = un
        u[self.fixed] = 0.0
        v[:] = v_new
        a[:] = a_new
        if not (np.isfinite(lam).all() and self.comm.allreduce(bool(np.isfinite(u).all()), op=MPI.LAND)):
            raise SolverError(f"non-finite state at step {step}, t = {t_new:.9g} s")
        self.lam, self.gap, self.active = lam, gap, lam > 0
        self.contact_seen = self.contact_seen or bool(self.active.any())

    def _friction_step(self, C: ContactOperator, q: np.ndarray, gap_tol: float, step: int) -> np.ndarray:
        """Coulomb friction (:mod:`millimpact.integration.friction`): lambda, tau from the dense problem on
        S = C A^-1 C^T, then u_new = u_pred + W [lambda; tau]. Returns lambda (N); sets self.tau."""
        from . import friction

        self.tmp.waxpy(-1.0, self.u, self.u_pred)
        q_t = self.contact.slip(self.tmp)  # slip increment of the predictor, m
        n_c = q.size
        tau0 = self.tau if self.tau is not None and self.tau.size == 2 * n_c else None

        def solve(nodes, cols, S_sub):
            # dense and small: solved on rank 0 only (the ranks share cores), the answer broadcast
            pairs = np.concatenate([nodes, n_c + nodes])
            r = (
                friction.solve_friction(
                    S_sub,
                    q[nodes],
                    q_t[pairs],
                    self.mu,
                    self._start_active()[nodes],
                    self.sliding[nodes],
                    gap_tol,
                    None if tau0 is None else tau0[pairs],
                    self.friction_rtol,
                )
                if self.comm.rank == 0
                else None
            )
            r = broadcast(self.comm, r)
            return r, np.concatenate([r.lam, r.tau])

        res, nodes, x = self._on_touching(C, q, gap_tol, solve)
        apply_contact_update(C, x, self.u_pred, self.u_new)
        cols = node_columns(nodes, n_c, True)
        ds = q_t + C.columns(cols)[0][n_c:] @ x[cols]  # slip increments over the step, m
        lam, tau, slip = x[:n_c], x[n_c:], np.zeros(n_c, dtype=bool)
        slip[nodes] = res.slip
        self.stats.friction_work_J += max(0.0, -float(tau @ ds))
        self.stats.max_friction_passes = max(self.stats.max_friction_passes, res.iterations)
        self.stats.n_friction_fallback += res.n_fallback
        self.stats.max_sliding_nodes = max(self.stats.max_sliding_nodes, int(np.count_nonzero(slip)))
        self.n_newton = res.iterations
        self.stats.n_newton += res.iterations
        self.stats.max_newton = max(self.stats.max_newton, res.iterations)
        self.tau, self.sliding = tau, slip
        return lam

    def rate(self) -> np.ndarray:
        return self.contact.rate(self.v)

    def destroy(self) -> None:
        if self._shared_ops:  # the system's cache keeps them for the next call
            return
        for op in self.ops.values():
            _destroy_step_operators(op)


@dataclass(frozen=True)
class _OperatorTotals:
    """What step operators did: factorizations, saddle-point solves, the largest Schur-block
    iteration count and whether a saddle point was solved monolithically (not fieldsplit)."""

    n_factorizations: int = 0
    n_saddle_solves: int = 0
    max_schur_iterations: int = 0
    monolithic: bool = False

    def plus(self, ops) -> _OperatorTotals:
        out = self
        for op in ops:
            sd = op.saddle
            out = _OperatorTotals(
                out.n_factorizations + (sd.n_factorizations if sd is not None else 1),
                out.n_saddle_solves + (sd.n_solves if sd is not None else 0),
                max(out.max_schur_iterations, sd.max_schur_iterations if sd is not None else 0),
                out.monolithic or (sd is not None and not sd.fieldsplit),
            )
        return out


def _destroy_step_operators(op: StepOperators) -> None:
    if op.saddle is not None:
        op.saddle.destroy()
    else:
        op.ksp_u.destroy()
    if op.contact is not None:
        op.contact.W.destroy()
    if op.body_blocks:
        op.body_blocks.destroy()
    op.A.destroy()
