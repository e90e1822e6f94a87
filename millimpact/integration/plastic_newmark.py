"""Newmark with mass redistribution and a plastic contact zone: Newton with the contact inside.

The equation of a step (average acceleration, u = u_{n+1}; :mod:`millimpact.integration.newmark`):

    A u + f_c(u) = r + C^T x,     A = K + M / (beta dt^2),   r = M (c0 u_n + c1 v_n + c2 a_n),

with f_c the zone's plastic force correction (N; ``f_int = K u + f_c``, :mod:`millimpact.fem.plastic_zone`)
and x the contact multipliers (normal, and tangential with friction). Converged when the residual
|A u + f_c(u) - r - C^T x| is below ``plastic_rtol`` (default 1e-8) of the step's force scale
max(|f_c(u)|, |C^T x|) (not |r|, which carries the ball's rigid-body inertia); a step with neither
converges at 1e-12 |r|. While no point yields f_c is the frozen plastic strain's and the step is
the elastic one. Each converged step books the plastic work of its return map
(``stats.plastic_work_J``) and commits the zone's state; after separation the plastic strain stays
frozen and the free vibration is linear about the residual state.

Linearisation (option ``plastic_linearisation``):

- ``elastic`` (the default): the fixed point u = G(u) of
  ``A u_{k+1} = r - f_c(u_k) + C^T x``, x from the LCP (or friction) on the elastic S = C A^-1 C^T,
  solved with the step size's elastic factorization and cached contact operator, accelerated by
  Anderson mixing of the last ``plastic_anderson_depth`` (10) iterates (:class:`AndersonMixing`;
  Walker and Ni, SIAM J. Numer. Anal. 49, 2011). Its fixed point is the Newton step's.
- ``tangent``: Newton with the consistent tangent dK_k (Simo and Hughes 1998, ch. 3),
  ``(A + dK_k) u_{k+1} = r - f_c(u_k) + dK_k u_k + C^T x`` with x on S_k = C (A + dK_k)^-1 C^T, the
  active set re-decided every iteration (a semi-smooth Newton on plasticity and contact); a tangent
  is reused while the residual contracts by ``plastic_tangent_reuse`` (0.5) an iteration.
- ``held``: the held tangent's iterates mixed as ``elastic``'s.

The three agree within 5e-9 on the coarse plastic half-space (F_max, e, plastic work, dent). On the
accelerated paths: ``plastic_candidate_fraction`` (0.5) return-maps only the cells near yield
between full checks; ``plastic_predictor`` (``extrapolated``) starts from the plastic force
extrapolated in time; ``plastic_friction_forcing`` (0.1) loosens the Coulomb alternation on
iterates far from the answer; ``plastic_return_map`` (``compiled``) evaluates the zone in one
compiled loop (:mod:`millimpact.fem.return_map_kernel`); ``plastic_body_blocks`` (1) solves body by
body once a step size has iterated a while (:mod:`.body_blocks`), and ``plastic_block_lag`` (0.05
on a finite-strain zone, else 0) keeps a body's last solve while its load moves by less than that
share of the residual. None changes the converged step beyond the residual tolerance.
What each saves, measured: docs/development/module-notes.md.

A step that does not converge in ``plastic_max_iterations`` (40 with ``tangent``, 80 otherwise)
raises :class:`SolverError` naming the step, the time and the residual.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
from mpi4py import MPI
from petsc4py import PETSc

from ..errors import InputError, SolverError
from . import solvers
from .body_blocks import BodyBlockSolver
from .contact_operator import ContactOperator, apply_contact_update, contact_operator
from .dynamics import IntegrationStats, LinearDynamics
from .friction import PASS_RTOL
from .newmark import NewmarkScheme

#: the residual of an exact linear solve relative to |r| (a step without contact or plastic
#: force has a zero force scale: it converges at this round-off floor)
ROUNDOFF_RTOL = 1e-12
#: the iterations of a step (``-impact_plastic_linearisation``): ``elastic`` the elastic step operator
#: and its cached contact operator, accelerated (:class:`AndersonMixing`); ``held`` a tangent A + dK
#: kept while the accelerated iteration contracts, ``tangent`` the same without acceleration
LINEARISATIONS = ("elastic", "held", "tangent")
#: a yielding step's Coulomb alternation stops at ``-impact_plastic_friction_forcing`` (default
#: 0.1) of the step's relative residual, never looser than FRICTION_LOOSEST, never tighter than
#: friction.PASS_RTOL; the iterate that passes the residual test was solved at PASS_RTOL
FRICTION_LOOSEST = 1e-3
#: a step's first iterate (``-impact_plastic_predictor``): the committed plastic force extrapolated
#: from the last step's increment, or the committed force itself
PREDICTORS = ("extrapolated", "frozen")
#: a step size's operator is split into its bodies' blocks (:mod:`.body_blocks`) once its yielding
#: steps have needed this many solves beyond their first (the plastic liner's third step size: 10)
BODY_BLOCKS_AFTER = 20
#: a step's iterates that contract their residual by less than this stop lagging body loads
LAG_CONTRACTION = 0.9
#: the zone's evaluations without tangent (``-impact_plastic_return_map``): one compiled pass for
#: strains, return map and force (:mod:`millimpact.fem.return_map_kernel`), or the numpy return map
#: between FFCx's strain and assembly kernels
RETURN_MAPS = ("compiled", "numpy")


class PlasticNewmarkScheme(NewmarkScheme):
    """Newmark (average acceleration, optional mass redistribution) with a :class:`NonlinearZone`."""

    def __init__(
        self, system: LinearDynamics, redistribute: bool, options: Mapping, stats: IntegrationStats, comm: MPI.Comm
    ):
        # the state update is u_pred + W x (each iteration's tangent has its own W): "schur"
        super().__init__(system, redistribute, {**dict(options), "contact_solve": "schur"}, stats, comm)
        self.contact_solve = stats.contact_solve = "schur"
        assert system.plastic is not None, "the plastic scheme integrates a system with a plastic zone"
        self.zone = system.plastic
        self.rtol = float(solvers.get_option("plastic_rtol", options, 1e-8))
        self.linearisation = str(solvers.get_option("plastic_linearisation", options, "elastic")).lower()
        if self.linearisation not in LINEARISATIONS:
            raise InputError(
                f"-impact_plastic_linearisation {self.linearisation!r}: choose {', '.join(LINEARISATIONS)}"
            )
        # the accelerated fixed point converges linearly: up to 26 iterations a step on the plastic
        # liner segment (15 on the rig), against 17 for the reused tangent
        default_cap = 40 if self.linearisation == "tangent" else 80
        self.max_iterations = int(solvers.get_option("plastic_max_iterations", options, default_cap))
        if not (self.rtol > 0 and self.max_iterations >= 1):
            raise InputError(
                f"-impact_plastic_rtol {self.rtol} / -impact_plastic_max_iterations "
                f"{self.max_iterations}: must be > 0 and >= 1"
            )
        self.reuse = float(solvers.get_option("plastic_tangent_reuse", options, 0.5))
        if not 0.0 <= self.reuse < 1.0:
            raise InputError(f"-impact_plastic_tangent_reuse {self.reuse}: must be in [0, 1) (0 = full Newton)")
        self.depth = int(solvers.get_option("plastic_anderson_depth", options, 10))
        if self.depth < 0:
            raise InputError(f"-impact_plastic_anderson_depth {self.depth}: must be >= 0 (0 = plain fixed point)")
        self._res, self._rhs, self._force = self.u.duplicate(), self.u.duplicate(), self.u.duplicate()
        # u_n is the strain the committed state was return-mapped at (the last converged step's
        # final full evaluation): the first step evaluates the zone at u_0 instead
        self._at_committed = False
        self.candidate_fraction = float(solvers.get_option("plastic_candidate_fraction", options, 0.5))
        if not 0.0 <= self.candidate_fraction < 1.0:
            raise InputError(
                f"-impact_plastic_candidate_fraction {self.candidate_fraction}: must be in [0, 1) "
                "(0 = every zone cell in every iteration)"
            )
        if getattr(self.zone, "finite", False):
            self.candidate_fraction = 0.0  # a finite-strain zone is nonlinear wherever it is strained
        # a factorized tangent kept for reuse: (dt, dK, A_t, ksp, W)
        self._held: tuple[float, PETSc.Mat, PETSc.Mat, PETSc.KSP, ContactOperator] | None = None
        self.forcing = float(solvers.get_option("plastic_friction_forcing", options, 0.1))
        if not 0.0 <= self.forcing <= 1.0:
            raise InputError(
                f"-impact_plastic_friction_forcing {self.forcing}: must be in [0, 1] "
                "(0 = the full Coulomb test in every iteration)"
            )
        self.predictor = str(solvers.get_option("plastic_predictor", options, "extrapolated")).lower()
        if self.predictor not in PREDICTORS:
            raise InputError(f"-impact_plastic_predictor {self.predictor!r}: choose {', '.join(PREDICTORS)}")
        # (dt, version, f_c,n) of the last step's start: the predictor's increment
        self._last_frozen: tuple[float, int, PETSc.Vec] | None = None
        kernel = str(solvers.get_option("plastic_return_map", options, "compiled")).lower()
        if kernel not in RETURN_MAPS:
            raise InputError(f"-impact_plastic_return_map {kernel!r}: choose {', '.join(RETURN_MAPS)}")
        self.zone.compiled = kernel == "compiled"
        # a yielding step's iterations re-solve only the bodies whose load changed (.body_blocks)
        blocks = str(solvers.get_option("plastic_body_blocks", options, "1")).lower()
        if blocks not in ("0", "1", "true", "false"):
            raise InputError(f"-impact_plastic_body_blocks {blocks!r}: choose 1 or 0")
        self.body_blocks = blocks in ("1", "true")
        # a body whose load moved by less than this share of the iterate's residual keeps its last
        # solve (.body_blocks, lagged): default on a finite-strain zone only, where every strained
        # point changes the load a little at every iteration
        self.block_lag = float(
            solvers.get_option("plastic_block_lag", options, 0.05 if getattr(self.zone, "finite", False) else 0.0)
        )
        if not 0.0 <= self.block_lag < 1.0:
            raise InputError(
                f"-impact_plastic_block_lag {self.block_lag}: must be in [0, 1) (0 = re-solve on any change)"
            )
        self._later_solves: dict[float, int] = {}  # per step size, solves beyond a step's first
        # the active set of the step's last iteration's contact
        self._iteration_active: np.ndarray | None = None

    def initialize(self, u0: PETSc.Vec, v0: PETSc.Vec) -> None:
        """Newmark's start with the zone's frozen plastic force: M a0 = -K u0 - f_c(u0). A start
        from a plastic state (a repeated impact from its residual state K u_res = -f_frozen, or a
        state handed back by the closed-form free phase) is otherwise accelerated by f_frozen;
        with no plastic strain f_c = 0 and the start is Newmark's. The force joins the start's
        load (f_ext) for that one mass solve."""
        self._forget_frozen()
        f = self.zone.frozen_force()
        if f.norm() == 0.0:
            f.destroy()
            super().initialize(u0, v0)
            return
        f.scale(-1.0)
        saved = self.sys.f_ext
        if saved is not None:
            f.axpy(1.0, saved)
        self.sys.f_ext = f
        try:
            super().initialize(u0, v0)
        finally:
            self.sys.f_ext = saved
            f.destroy()

    # --- one step -------------------------------------------------------------------------------
    def step(self, dt: float, t_new: float, step: int, allow_reject: bool) -> bool:
        self.zone.time_step = dt  # a strain-rate factor's dg / dt
        op = self._ops(dt)
        self.friction_rtol = PASS_RTOL  # the test of the last solve (the step's first: none)
        self._predictor_rhs(dt)
        r_norm = self.r.norm()
        u_k = self.u.copy()
        x = np.zeros(self.contact.n_c * (3 if self.frictional else 1))
        work0 = self.stats.friction_work_J
        work_step = 0.0
        yielding_seen = False
        fresh = self.reuse == 0.0  # a new tangent at the next yielding iteration
        res_prev = None
        lag = self.block_lag  # the lagged body loads' share of the residual, this step (_solve)
        elastic = self.linearisation == "elastic"
        mixing = AndersonMixing(self.depth, self.comm) if self.linearisation != "tangent" else None
        # A u_k carried by the iteration (elastic linearisation, a direct solve): A G(u_k) is the
        # solve's right-hand side plus C^T x, and the mixed iterate's is the same combination of
        # those, so the residual's product with A (a third of an iteration's cost on the rig) is
        # spent only on the iterate that passes the test (confirmed by the product itself)
        carry = elastic and self._direct_elastic(op)
        Au = None
        solved_frozen = False  # u_k is the exact elastic solve with the committed state's f_c
        # after the first full evaluation that yields, the iterations return-map the candidate
        # cells alone (near or at yield); a full evaluation confirms the converged iterate
        candidates = self.candidate_fraction > 0.0 and self.linearisation != "tangent"
        restricted = False
        extrapolated = False  # this iteration's solve took the predictor's force, not f_c(u_k)
        self._iteration_active = None  # the active set of the last iteration's contact problem
        for it in range(self.max_iterations + 1):
            restricted_now = False
            if it == 0 and self._at_committed:
                # the committed state was return-mapped at u_n itself (the last step's converged
                # iterate): from it no point yields there (its points sit on the yield surface to
                # the consistency tolerance, the yielding test is beyond it) and f_c(u_n) is the
                # frozen plastic strain's (cached). No return map before the first solve: after a
                # yielding step this was a repeat of the confirmation's (rig: 73 of 5.6 + 2 ms)
                n_yield, f_c = 0, self.zone.frozen_force()
                extrapolated = self._extrapolate(f_c, dt)
            else:
                n_yield = self._evaluate(u_k, restricted)
                restricted_now = restricted
                if restricted and n_yield == 0:
                    # the candidates stay elastic: whether any other point yields, a full one tells
                    n_yield, restricted_now = self._evaluate(u_k, False), False
                if n_yield == 0 and solved_frozen:
                    # no point yields at u_k, so f_c(u_k) is the committed state's frozen force, the
                    # one u_k was solved with exactly (a factorization): the residual is round-off,
                    # as an elastic step's (on the rig's repeated impacts, 70 of an impact's 90
                    # steps; the return map above is the test)
                    break
                if candidates and n_yield > 0 and not restricted_now:
                    self.zone.select_candidates(self.candidate_fraction)
                f_c = self.zone.force_correction()
                restricted = candidates and n_yield > 0
            yielding_seen |= n_yield > 0
            if it == 0 and carry:
                res = f_scale = tol = np.inf  # never tested (only later iterates converge)
            else:
                res, f_scale = self._residual(op, u_k, f_c, x, Au)
                tol = max(self.rtol * f_scale, ROUNDOFF_RTOL * r_norm)
            if self.friction_rtol > PASS_RTOL:
                tol = 0.0  # x met a looser Coulomb test: one more iteration, at the full one
            if it > 0 and res <= tol and Au is not None:
                res, f_scale = self._residual(op, u_k, f_c, x)  # the test on the true product
                tol = max(self.rtol * f_scale, ROUNDOFF_RTOL * r_norm)
            if it > 0 and res <= tol and restricted_now:
                # the confirmation: a full evaluation at u_k; the same number of yielding points
                # means no point outside the candidates yields, so f_c(u_k) is the one tested
                n_candidates = n_yield
                n_yield = self._evaluate(u_k, False)
                if n_yield == n_candidates:
                    break
                self.stats.n_plastic_candidate_misses += 1
                if mixing is not None:
                    mixing.forget()  # G changed with its candidates: the pairs were another map's
                f_c.destroy()
                self.zone.select_candidates(self.candidate_fraction)
                f_c = self.zone.force_correction()
                res, f_scale = self._residual(op, u_k, f_c, x)
                tol = max(self.rtol * f_scale, ROUNDOFF_RTOL * r_norm)
            if it > 0 and res <= tol:
                break
            # a reused tangent that contracts the residual too slowly is replaced
            fresh = fresh or (res_prev is not None and res > self.reuse * res_prev)
            if res_prev is not None and res > LAG_CONTRACTION * res_prev:
                lag = 0.0  # the iterates stall: no lagged load for the rest of the step
            res_prev = res
            if it == self.max_iterations:
                raise SolverError(
                    f"plastic Newton did not converge: residual {res:.3e} N (force scale {f_scale:.3e} N) "
                    f"after {it} iterations at step {step}, t = {t_new:.9g} s "
                    "(-impact_plastic_max_iterations, a smaller time.dt_contact)"
                )
            ksp, W, tangent = self._linearisation(op, u_k, f_c, 0 if elastic else n_yield, dt, fresh)
            if self.frictional:
                self.friction_rtol = self._coulomb_rtol(
                    res / f_scale if np.isfinite(res) else np.inf, n_yield == 0 and not extrapolated
                )
            solved_frozen = carry and n_yield == 0 and not extrapolated
            extrapolated = False
            if mixing is not None:
                mixing.bind(ksp)
            fresh = False
            self._solve(op, ksp, it > 0, step, t_new, lag * res if np.isfinite(res) else 0.0)
            self.stats.n_solves += 1
            q = self.contact.gap(self.u_pred)
            gap_tol = self.gap_rtol * max(
                float(np.max(np.abs(q), initial=0.0)), float(np.max(np.abs(self.contact.g0), initial=0.0)), 1e-300
            )
            if it == 0 and allow_reject and not np.all(q >= -gap_tol):
                self._release(tangent)
                return False
            x = self._contact(W, q, gap_tol, step)
            self._iteration_active = x[: q.size] > 0
            work_step = self.stats.friction_work_J - work0  # only the last iteration's slip counts
            self.stats.friction_work_J = work0
            # A G(u_k) = rhs + C^T x (free rows) when carried
            AG = self._solved_product(x) if carry else None
            if mixing is not None and n_yield > 0:
                Au = mixing.next_iterate(u_k, self.u_new, AG)  # u_k <- the accelerated G(u_k)
            else:
                self.u_new.copy(u_k)
                Au = AG
            self._release(tangent)
            f_c.destroy()
        self.stats.friction_work_J = work0 + work_step
        # a yielding step is one whose converged state yields; the iterations are booked for every
        # step with a yielding iterate (an extrapolated start can make an unloading step's first
        # iterate yield before it converges elastically)
        self.stats.n_plastic_steps += n_yield > 0
        if yielding_seen:
            self.stats.n_plastic_iterations += it
            self.stats.max_plastic_iterations = max(self.stats.max_plastic_iterations, it)
        self.stats.plastic_work_J += self.zone.step_plastic_work()
        self.zone.commit()
        self._at_committed = True
        u_k.copy(self.u_new)
        u_k.destroy()
        scale = max(float(np.max(np.abs(self.contact.g0), initial=0.0)), 1e-300)
        lam = x[: self.contact.n_c]
        self._accept(lam, dt, step, t_new, self.gap_rtol * scale, scale)
        return True

    # --- pieces ---------------------------------------------------------------------------------
    def _extrapolate(self, f_c: PETSc.Vec, dt: float) -> bool:
        """The predictor's force in place of the committed one, ``f_c`` (= f_c,n, owned here):
        f_c,n + (dt / dt_prev) (f_c,n - f_c,n-1) when the last step changed the plastic state (the
        zone's version moved) and the predictor is ``extrapolated``; returns whether ``f_c`` was
        changed. A step that did not yield keeps the kept force and only takes its dt."""
        if self.predictor != "extrapolated" or self.linearisation == "tangent":
            return False
        version, last = self.zone.version, self._last_frozen
        if last is not None and last[1] == version:
            self._last_frozen = (dt, version, last[2])  # f_c,n = f_c,n-1: no increment
            return False
        self._last_frozen = (dt, version, f_c.copy())
        if last is None:
            return False
        dt_prev, _, f_prev = last
        f_prev.aypx(-1.0, f_c)  # f_c,n - f_c,n-1
        f_c.axpy(dt / dt_prev, f_prev)
        f_prev.destroy()
        return True

    def _coulomb_rtol(self, res_rel: float, may_be_last: bool) -> float:
        """The Coulomb alternation's test for the next contact solve (friction.solve_friction's rtol):
        a fraction ``plastic_friction_forcing`` of the step's relative residual ``res_rel``, between
        friction.PASS_RTOL and FRICTION_LOOSEST; the full PASS_RTOL when the solve ``may_be_last``
        (nothing yields at the iterate: the solve can end the step). An inexact inner solve of a
        fixed-point iteration keeps its rate when its error is a fraction of the outer residual
        (Dembo, Eisenstat & Steihaug, SIAM J. Numer. Anal. 19, 1982, for inexact Newton)."""
        if may_be_last or self.forcing == 0.0:
            return PASS_RTOL
        return min(FRICTION_LOOSEST, max(PASS_RTOL, self.forcing * res_rel))

    def _forget_frozen(self) -> None:
        if self._last_frozen is not None:
            self._last_frozen[2].destroy()
            self._last_frozen = None

    def _evaluate(self, u: PETSc.Vec, candidates_only: bool) -> int:
        """The zone's return map at u (all cells, or the candidates'): the yielding points (global)."""
        n = self.zone.evaluate(u, tangent=self.linearisation == "tangent", candidates_only=candidates_only)
        return self.comm.allreduce(n, op=MPI.SUM)

    def _residual(
        self, op, u: PETSc.Vec, f_c: PETSc.Vec, x: np.ndarray, Au: np.ndarray | None = None
    ) -> tuple[float, float]:
        """(|A u + f_c(u) - r - C^T x|, the force scale max(|f_c|, |C^T x|)) over the free dofs (N);
        ``Au`` (this rank's owned entries) stands for the product A u when the iteration carries it."""
        res, force = self._res, self._force
        force.set(0.0)
        if x.size:
            self.contact.add_multiplier_force(x, force, 1.0)
        force.array[self.fixed] = 0.0
        scale = max(f_c.norm(), force.norm(), 1e-300)
        if Au is None:
            op.A.mult(u, res)
        else:
            res.array[:] = Au
        res.axpy(1.0, f_c)
        res.axpy(-1.0, self.r)
        res.axpy(-1.0, force)
        res.array[self.fixed] = 0.0
        return res.norm(), scale

    def _solve(self, op, ksp: PETSc.KSP, later: bool, step: int, t: float, lag: float = 0.0) -> None:
        """u_pred = ksp^-1 self._rhs: by the bodies' blocks when the solve is the elastic
        operator's and they are built (:meth:`_body_blocks`), else by ``ksp``. ``lag`` (N): a body
        whose part of the right-hand side moved by at most this keeps its last solve, and that
        solve's right-hand side replaces its part of self._rhs, so u_pred solves self._rhs exactly
        and the iteration's product A u_pred stays known (the residual test sees the difference)."""
        what = "plastic effective-matrix solve"
        blocks = self._body_blocks(op, later) if ksp is op.ksp_u else None
        if blocks is None:
            solvers.solve_checked(ksp, self._rhs, self.u_pred, what, step, t)
        else:
            self.stats.n_body_solves_skipped += blocks.solve(self._rhs, self.u_pred, what, step, t, lag)

    def _body_blocks(self, op, later: bool):
        """The step size's operator solved body by body (:class:`.body_blocks.BodyBlockSolver`),
        for every solve of a plastic step once built. Built when this step size has needed
        BODY_BLOCKS_AFTER solves beyond its steps' first (``later``: a step size that iterates a
        few times does not pay for the blocks' factorizations); None before, when off
        (``-impact_plastic_body_blocks 0``), distributed, or A does not split. The two blocks'
        solves also take less than the whole operator's (rig, one process: 1.64 + 1.92 ms
        against 4.09 ms)."""
        if not self.body_blocks or op.body_blocks is False:
            return None
        if op.body_blocks is None:
            if not later:
                return None
            seen = self._later_solves.get(op.dt, 0) + 1
            self._later_solves[op.dt] = seen
            if seen < BODY_BLOCKS_AFTER:
                return None
            op.body_blocks = BodyBlockSolver.build(op.A, self.petsc_options) or False
        return op.body_blocks or None

    def _direct_elastic(self, op) -> bool:
        """Whether the elastic step operator is solved exactly (a factorization, no Krylov
        iterations): then A G(u) is known without a product (:meth:`_solved_product`)."""
        ksp = op.ksp_u
        return ksp.getType() == PETSc.KSP.Type.PREONLY and ksp.getPC().getType() in ("lu", "cholesky")

    def _solved_product(self, x: np.ndarray) -> np.ndarray:
        """A G(u_k) = rhs_k + C^T x on the free rows (zero on the clamped ones), this rank's owned
        entries: the last elastic solve's right-hand side (self._rhs) and contact force."""
        force = self._force
        force.set(0.0)
        if x.size:
            self.contact.add_multiplier_force(x, force, 1.0)
        out = self._rhs.array_r + force.array_r
        out[self.fixed] = 0.0
        return out

    def _linearisation(self, op, u_k: PETSc.Vec, f_c: PETSc.Vec, n_yield: int, dt: float, fresh: bool):
        """(ksp, W, owned objects) of iteration k and its right-hand side in self._rhs:
        the elastic factorization while no point yields, else a tangent A + dK: the held one (of
        this dt) unless ``fresh``, else dK_k of u_k factorized anew and held for reuse."""
        rhs = self._rhs
        rhs.waxpy(-1.0, f_c, self.r)
        if n_yield == 0:
            rhs.array[self.fixed] = 0.0
            return op.ksp_u, self._contact_operator(op), None
        held = self._held
        if held is not None and (fresh or held[0] != dt):
            self._release_held()
            held = None
        if held is None:
            if self.linearisation == "held":
                self.zone.evaluate(u_k, tangent=True)  # the same trial state, with C_t
            dK = self.zone.stiffness_correction()
            A_t, ksp, W = self._factorize_tangent(op, dK)
            held = self._held = (dt, dK, A_t, ksp, W)
        dK = held[1]
        dK.multAdd(u_k, rhs, rhs)
        rhs.array[self.fixed] = 0.0
        return held[3], held[4], None

    def destroy(self) -> None:
        self._forget_frozen()
        super().destroy()

    def _release_step_operators(self) -> None:
        """The elastic step operators (NewmarkScheme) and a held tangent with them."""
        self._release_held()
        super()._release_step_operators()

    def _release_held(self) -> None:
        if self._held is not None:
            _, dK, A_t, ksp, W = self._held
            dK.destroy()
            self._release((A_t, ksp, W))
            self._held = None
            # the factor's memory back to the system before the next tangent's: freed, it stayed
            # in the heap (coarse plastic liner panel: 1.30 GB at the time loop's end against
            # 1.0-1.03 GB after each release with the trim)
            solvers.return_freed_memory()

    def _factorize_tangent(self, op, dK: PETSc.Mat) -> tuple[PETSc.Mat, PETSc.KSP, ContactOperator]:
        """(A_t, ksp, W) of the tangent A + dK: factorized, with its contact operator."""
        A_t = op.A.copy()
        try:
            A_t.axpy(1.0, dK, PETSc.Mat.Structure.SUBSET_NONZERO_PATTERN)
        except PETSc.Error:  # a projected tangent whose pattern is not inside A's
            A_t.destroy()
            A_t = op.A.copy()
            A_t.axpy(1.0, dK, PETSc.Mat.Structure.DIFFERENT_NONZERO_PATTERN)
        ksp = solvers.create_effective_solver(A_t, self.petsc_options)
        W = contact_operator(ksp, self.contact.C)  # columns computed as the steps need them
        self.stats.n_tangent_factorizations += 1
        return A_t, ksp, W

    def _start_active(self) -> np.ndarray:
        """The active set of the step's last iteration starts this one's contact problem (the
        previous step's at its first): the solution is the same (S is positive definite), found in
        fewer active-set iterations (rig: 1 in 678 of 778 LCPs, against 75, and 0.41 ms a call
        against 0.66). With friction the tangential forces and sliding set already carry over from
        iteration to iteration."""
        return self.active if self._iteration_active is None else self._iteration_active

    def _contact(self, W: ContactOperator, q: np.ndarray, gap_tol: float, step: int) -> np.ndarray:
        """The multipliers of the linear step and u_new = u_pred + W x (x = lambda, or [lambda; tau])."""
        n_c = q.size
        if n_c == 0 or np.all(q >= -gap_tol):
            self.u_pred.copy(self.u_new)
            if self.frictional:
                self.tau, self.sliding = np.zeros(2 * n_c), np.zeros(n_c, dtype=bool)
                return np.zeros(3 * n_c)
            return np.zeros(n_c)
        if self.frictional:
            lam = self._friction_step(W, q, gap_tol, step)
            return np.concatenate([lam, self.tau])
        res = self._lcp(W, q, gap_tol)
        lam = res.lam
        self.n_newton = res.iterations
        apply_contact_update(W, lam, self.u_pred, self.u_new)
        return lam

    @staticmethod
    def _release(owned) -> None:
        if owned is not None:
            A_t, ksp, W = owned
            W.destroy()
            ksp.destroy()
            A_t.destroy()


class AndersonMixing:
    """Anderson acceleration of the fixed point u = G(u) (Walker & Ni, SIAM J. Numer. Anal. 49,
    2011, eq. 1.1 / "type II" with depth m): with the fixed-point residuals f_i = G(u_i) - u_i of
    the last m + 1 iterates, gamma = argmin |f_k - dF gamma| (dF's columns f_{i+1} - f_i) and

        u_{k+1} = G(u_k) - dG gamma,    dG's columns G(u_{i+1}) - G(u_i).

    Here G(u) is the step's linear problem on the elastic operator (or a held tangent A_t = A + dK,
    with dK u on the right) with f_c(u) on the right-hand side and the contact inside (the LCP on
    that operator's S): its fixed point is the step's exact answer, A u + f_c(u) = r + C^T x with
    complementarity on g0 + C u. A new operator makes a new G (:meth:`bind` forgets the pairs).
    Vectors are the ranks' owned parts; the m x m least squares is reduced over the ranks (the same
    gamma on every rank)."""

    def __init__(self, depth: int, comm: MPI.Comm):
        self.depth, self.comm = depth, comm
        self.operator: object = None  # the KSP of G's solve (bind)
        #: the last iterate's (f, G(u), companion image or None), None before the first
        self._prev: tuple[np.ndarray, np.ndarray, np.ndarray | None] | None = None
        # the pairs' columns in place, oldest overwritten (the least squares does not depend on
        # their order): no copies into a stacked array per iteration, and the Gram matrix dF^T dF
        # updated by one row (rig: 1.5 ms an iteration with the columns stacked anew)
        self._dF: np.ndarray | None = None
        self._dG: np.ndarray | None = None
        self._dB: np.ndarray | None = None
        self._gram = np.zeros((depth, depth))
        self._count = 0  # pairs kept (at most depth)
        self._slot = 0  # the next pair's column

    def bind(self, operator) -> None:
        """The operator of G's solve (a KSP): another one than the last makes another G, whose
        secant pairs are not the last's: they are forgotten."""
        if operator is not self.operator:
            self.operator = operator
            self.forget()

    def forget(self) -> None:
        """Drop the secant pairs (the map G changed)."""
        self._prev = None
        self._count = self._slot = 0

    def _keep(self, df: np.ndarray, dg: np.ndarray, db: np.ndarray | None) -> None:
        """Store a pair in the next column and its row of the Gram matrix (reduced over the ranks)."""
        dF, dG = self._dF, self._dG
        if dF is None or dG is None or dF.shape[0] != df.size:
            dF = self._dF = np.empty((df.size, self.depth), order="F")
            dG = self._dG = np.empty((df.size, self.depth), order="F")
            self._dB = None
        j = self._slot
        dF[:, j], dG[:, j] = df, dg
        if db is not None:
            if self._dB is None:
                self._dB = np.empty((db.size, self.depth), order="F")
            self._dB[:, j] = db
        self._count = min(self._count + 1, self.depth)
        self._slot = (j + 1) % self.depth
        k = self._count
        row = self.comm.allreduce(dF[:, :k].T @ df, op=MPI.SUM)
        self._gram[j, :k] = row
        self._gram[:k, j] = row

    def next_iterate(self, u: PETSc.Vec, g_vec: PETSc.Vec, companion: np.ndarray | None = None):
        """Given u = u_k and g_vec = G(u_k), overwrite u with u_{k+1}. ``companion``, a linear image
        L G(u_k) (here A G(u_k)), is mixed with the same gamma: returns L u_{k+1} (None without)."""
        g = np.array(g_vec.array_r)
        f = g - u.array_r
        if self._prev is not None:
            f_prev, g_prev, b_prev = self._prev
            if b_prev is None:
                companion = None  # the history has no images: stop carrying them
            if self.depth > 0:
                self._keep(
                    f - f_prev, g - g_prev, companion - b_prev if companion is not None and b_prev is not None else None
                )
        self._prev = (f, g, companion)
        out, image = g, companion
        k = self._count
        if k:
            assert self._dF is not None and self._dG is not None, "the kept pairs' columns"
            gram = self._gram[:k, :k]
            rhs = self.comm.allreduce(self._dF[:, :k].T @ f, op=MPI.SUM)
            # the normal equations with a relative ridge of 1e-12 (a column that repeats another
            # makes the Gram matrix singular; lstsq then gives the least-norm gamma)
            gram = gram + 1e-12 * np.trace(gram) * np.eye(k) / k
            gamma = np.linalg.lstsq(gram, rhs, rcond=None)[0]
            out = g - self._dG[:, :k] @ gamma
            if image is not None:
                assert self._dB is not None, "a carried image was kept with its pairs"
                image = image - self._dB[:, :k] @ gamma
        u.array[:] = out
        return image
