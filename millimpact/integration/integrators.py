"""Time integrators with unilateral contact by Lagrange multipliers (foundations.md section 4).

Independent of the geometry: an integrator sees a :class:`LinearDynamics` (assembled PETSc M, K,
contact rows B with gaps ``g = g0 + B u >= 0``) and advances ``M a + K u = f + B^T lambda`` with
``lambda >= 0, g >= 0, lambda g = 0``. Units are those of the system (SI in millimpact): u in m,
t in s, lambda in N.

Methods (:data:`METHODS`):

``newmark-mr`` (default)
    Average-acceleration Newmark (beta = 1/4, gamma = 1/2) on the *redistributed* mass matrix
    (:func:`redistribute_mass`: no mass on the contact dofs; Khenous, Laborde, Renard, Eur. J.
    Mech. A 27, 2008), contact imposed on ``u_{n+1}``. The massless contact dofs follow the body
    quasi-statically, so an impact does not excite the spurious contact-node oscillation, the
    status does not chatter and the energy is conserved up to the small O(dt) release/impact
    error (bar: foundations.md section 3; measured in tests/integration/test_bar.py).
``newmark``
    The same with the consistent mass: the known chattering baseline (status switches every few
    steps, energy errors an order larger).
``central-penalty``
    Explicit central differences (velocity Verlet form) with the lumped (HRZ) mass and a penalty
    force ``k_p max(-g, 0)`` per constraint row. Conditionally stable: the critical step
    ``2 / sqrt(lambda_max(M_L^-1 (K + k_p B^T B)))`` is computed (SLEPc) and each scheduled step is
    cut into sub-steps of at most ``safety * dt_crit`` unless ``-impact_limit_step 0`` (for
    stability sweeps: above dt_crit the run blows up, is stopped and reported as diverged).

Each implicit step: one predictor solve with lambda = 0 using the factorization of
``A = K + M/(beta dt^2)`` (cached per step size, never refactored inside a step), the exact small
LCP ``g = q + S lambda`` on the dense ``S = B A^-1 B^T`` (:func:`millimpact.integration.lcp.solve_lcp`,
replicated on every rank, rank 0's answer broadcast), then the final state from the PETSc
saddle-point solve on the found active set (``-impact_contact_solve fieldsplit``, default), a
monolithic LU of it (``lu``) or ``u = u_pred + W lambda`` (``schur``, cheapest: no further solve).
Steps where the predictor opens every gap skip the contact work.

Non-PETSc settings (``options`` keys or command-line ``-impact_<key>``): ``contact_solve``
(fieldsplit|schur|lu), ``penalty`` (k_p in N/m; default ``penalty_factor`` (1) times the largest
``sum_j B_ij^2 K_jj``, about the element stiffness behind a contact node), ``critical_step_safety``
(0.5 of the linear estimate; why: docs/development/module-notes.md), ``limit_step`` (true),
``divergence_factor`` (10: energy growth that counts as blow-up),
``gap_rtol`` (1e-9), ``lambda_check_rtol`` (1e-6: saddle-point multipliers vs the LCP's).
The step-size rule's safety margin is :attr:`TimeSchedule.margin`.
"""

from __future__ import annotations

import logging
import math
import sys
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any, NamedTuple

import numpy as np
from mpi4py import MPI
from petsc4py import PETSc

from ..errors import InputError
from ..interrupts import raise_if_interrupted
from .central_penalty import CRITICAL_STEP_SAFETY, CentralPenaltyScheme
from .dynamics import (
    IntegrationStats,
    LinearDynamics,
    SeparationStop,
    StepState,
    TimeSchedule,
    kinetic_energy,
    product_matrix,
    strain_energy,
)
from .mass import lumped_mass, lumped_mass_matrix, redistribute_mass
from .newmark import NewmarkScheme
from .plastic_newmark import PlasticNewmarkScheme
from .solvers import GARBAGE_EVERY

log = logging.getLogger(__name__)

#: what callers take from this module: the driver and the values it works on
__all__ = [
    "integrate",
    "METHODS",
    "LinearDynamics",
    "StepState",
    "IntegrationStats",
    "TimeSchedule",
    "kinetic_energy",
    "product_matrix",
    "strain_energy",
    "SeparationStop",
    "redistribute_mass",
    "lumped_mass",
    "lumped_mass_matrix",
    "CRITICAL_STEP_SAFETY",
]

#: Integrator names accepted by :func:`integrate`.
METHODS = ("newmark-mr", "newmark", "central-penalty")


def terminal_bar(desc: str, total: float, unit: str, file):
    """The progress bar on a terminal: simulated time ``total`` (in ``unit``) with 3 significant
    digits. A terminal that reports no width (a pseudo-terminal without a size) is taken as 80
    columns: with 0, tqdm 4.64 drops the bar format and prints the raw floats
    (``16.666783564905753/133.33426851924602``)."""
    import os

    from tqdm import tqdm

    try:
        columns = os.get_terminal_size(file.fileno()).columns
    except (AttributeError, OSError, ValueError):
        columns = 0
    return tqdm(
        total=total,
        unit=unit,
        desc=desc,
        file=file,
        ncols=columns or 80,
        bar_format="{l_bar}{bar}| {n:.3g}/{total:.3g} " + unit + " simulated [{elapsed}<{remaining}]",
    )


#: the schemes :func:`integrate` drives (a :class:`PlasticNewmarkScheme` is a :class:`NewmarkScheme`)
Scheme = CentralPenaltyScheme | NewmarkScheme


def _create_scheme(
    system: LinearDynamics, method: str, options: dict, stats: IntegrationStats, comm: MPI.Comm
) -> Scheme:
    """The scheme of ``method`` for ``system``: central differences with penalty (elastic only),
    plastic Newmark when ``system.plastic`` is set, else Newmark; ``newmark-mr`` redistributes
    the mass (:func:`redistribute_mass`)."""
    if method == "central-penalty":
        if system.plastic is not None:
            raise InputError("--integrator central-penalty has no plasticity: use newmark-mr (or elastic materials)")
        return CentralPenaltyScheme(system, options, stats, comm)
    if system.plastic is not None:
        return PlasticNewmarkScheme(system, method == "newmark-mr", options, stats, comm)
    return NewmarkScheme(system, method == "newmark-mr", options, stats, comm)


@dataclass(frozen=True)
class Observers:
    """The caller's ``observer`` (sees every accepted state) and ``stop`` (may end the run)."""

    observer: Callable[[StepState], None] | None
    stop: Callable[[StepState], bool] | None

    def notify(self, integ: Scheme, stats: IntegrationStats, t: float, dt: float, step: int) -> bool:
        """Hand the state after step ``step`` (time ``t`` in s, size ``dt`` in s) to the observer;
        True if ``stop`` says the run is over (never at step 0)."""
        if self.observer is None and self.stop is None:
            return False
        st = StepState(
            t=t,
            dt=dt,
            u=integ.u,
            v=integ.v,
            a=integ.a,
            lam=integ.lam,
            gap=integ.gap,
            n_active=int(np.count_nonzero(integ.lam > 0)),
            n_newton=integ.n_newton,
            step=step,
            mass=integ.mass,
            penalty_energy=integ.penalty_energy,
            tau=getattr(integ, "tau", None),
            friction_work=stats.friction_work_J,
            plastic_work=stats.plastic_work_J,
        )
        if self.observer is not None:
            self.observer(st)
        return self.stop is not None and step > 0 and bool(self.stop(st))


@dataclass
class ProgressReport:
    """Progress over simulated time on rank 0: a tqdm bar on a terminal, else (a log, CI, a pipe)
    a plain line on stderr every 10 % of ``t_end``; neither when ``bar`` and ``plain_from`` are
    None. Times shown in ms (``t_end`` >= 1 ms) or microseconds."""

    method: str
    t_end: float  #: s
    t_scale: float  #: shown units per s
    t_unit: str
    bar: Any = None  #: the tqdm bar (None: no bar)
    plain_from: float | None = None  #: plain lines: wall clock at the start (s, perf_counter)
    plain_next: float = 0.1  #: plain lines: the fraction of t_end of the next line

    @classmethod
    def start(cls, method: str, t_end: float, wanted: bool, rank: int) -> ProgressReport:
        """The report of a run to ``t_end`` (s): shown if ``wanted`` and on rank 0."""
        t_scale, t_unit = (1e3, "ms") if t_end >= 1e-3 else (1e6, "\u00b5s")
        report = cls(method, t_end, t_scale, t_unit)
        if wanted and rank == 0 and sys.stderr.isatty():
            report.bar = terminal_bar(method, t_end * t_scale, t_unit, sys.stderr)
        elif wanted and rank == 0:
            report.plain_from = time.perf_counter()
        return report

    def advance(self, t: float, dt: float) -> None:
        """Account for an accepted step of ``dt`` (s) ending at ``t`` (s)."""
        if self.bar is not None:
            self.bar.update(dt * self.t_scale)
        elif self.plain_from is not None and t >= self.plain_next * self.t_end * (1 - 1e-12):
            print(
                f"  {self.method}: {100 * t / self.t_end:3.0f} % ({t * self.t_scale:.3g} of "
                f"{self.t_end * self.t_scale:.3g} {self.t_unit} simulated, "
                f"{time.perf_counter() - self.plain_from:.1f} s)",
                file=sys.stderr,
                flush=True,
            )
            self.plain_next = math.floor(10 * t / self.t_end + 1e-9) / 10 + 0.1

    def close(self) -> None:
        """Close the bar (if any)."""
        if self.bar is not None:
            self.bar.close()


class StepChoice(NamedTuple):
    """The next step on the grid ``k * dt_grid``: its size ``dt`` (s, ``dt_free`` or
    ``dt_contact``), the grid index ``k_next`` and time ``t_new`` (s) it ends at."""

    free: bool
    k_next: int
    dt: float
    t_new: float


def _choose_step(
    schedule: TimeSchedule, integ: Scheme, k: int, prev_active: np.ndarray, force_contact: bool
) -> StepChoice:
    """The step from grid index ``k``: ``dt_free`` when no constraint was active (or touched, in
    an explicit step), a whole free step fits before ``t_end``, the previous free step was not
    rejected (``force_contact``) and :meth:`TimeSchedule.free_step_allowed` says no gap can close
    within it; else ``dt_contact``. The last step ends at ``t_end`` exactly."""
    n_grid, m_free, dt_g = schedule.n_grid, schedule.free_ratio, schedule.dt_grid
    n_act = int(np.count_nonzero(prev_active)) + int(getattr(integ, "touched", False))
    use_free = not force_contact and n_grid - k >= m_free and schedule.free_step_allowed(integ.gap, integ.rate(), n_act)
    kk = k + (m_free if use_free else 1)
    dt = m_free * dt_g if use_free else dt_g
    t_new = schedule.t_end if kk == n_grid else kk * dt_g
    return StepChoice(use_free, kk, dt, t_new)


def _count_accepted_step(stats: IntegrationStats, free: bool, prev_active: np.ndarray, active: np.ndarray) -> None:
    """Add an accepted step to ``stats``: free or contact, the constraints whose status switched
    (``active`` vs ``prev_active``, lambda > 0) and the largest active set."""
    stats.n_steps += 1
    if free:
        stats.n_steps_free += 1
    else:
        stats.n_steps_contact += 1
    changed = int(np.count_nonzero(active != prev_active))
    stats.n_switches += changed
    stats.n_active_set_changes += changed > 0
    stats.max_active = max(stats.max_active, int(np.count_nonzero(active)))


def _report_divergence(
    integ: CentralPenaltyScheme, stats: IntegrationStats, t: float, step: int, dt: float, rank: int
) -> None:
    """Mark the explicit run as blown up at ``t`` (s) in ``stats`` and warn with its energies."""
    stats.diverged, stats.diverged_at = True, t
    if rank == 0:
        log.warning(
            "%s diverged at t = %.6g s (step %d, dt %.4g s, critical %.4g s): energy %.3e J vs initial %.3e J",
            stats.method,
            t,
            step,
            dt,
            stats.dt_critical,
            integ.energy,
            integ.energy_ref,
        )


def _step_to_end(
    integ: Scheme,
    schedule: TimeSchedule,
    stats: IntegrationStats,
    observers: Observers,
    report: ProgressReport,
    comm: MPI.Comm,
) -> None:
    """Advance ``integ`` from t = 0 over the grid to ``schedule.t_end``, step by step: a rejected
    free step (a gap closed) is redone with ``dt_contact``; ends early when ``stop`` says so
    (``stats.stopped_at``) or the explicit scheme diverges (``stats.diverged``)."""
    k, step, t = 0, 0, 0.0
    prev_active = integ.lam > 0
    force_contact = False
    while k < schedule.n_grid:
        raise_if_interrupted()  # a Ctrl-C / SIGTERM whose exception a library swallowed
        choice = _choose_step(schedule, integ, k, prev_active, force_contact)
        if not integ.step(choice.dt, choice.t_new, step + 1, allow_reject=choice.free):
            stats.n_rejected += 1
            force_contact = True
            continue
        force_contact = False
        k, step, t = choice.k_next, step + 1, choice.t_new
        active = integ.lam > 0
        _count_accepted_step(stats, choice.free, prev_active, active)
        prev_active = active
        if observers.notify(integ, stats, t, choice.dt, step):
            stats.stopped_at = t
            break
        if step % GARBAGE_EVERY == 0:
            # dropped per-step PETSc objects are parked until a collective cleanup (solvers.py)
            PETSc.garbage_cleanup(comm)
        report.advance(t, choice.dt)
        if isinstance(integ, CentralPenaltyScheme) and integ.diverged:  # the explicit scheme's test
            _report_divergence(integ, stats, t, step, choice.dt, comm.rank)
            break


def _collect_operator_totals(integ: Scheme, stats: IntegrationStats) -> None:
    """Copy an implicit scheme's factorization, saddle-point and released-operator counts (and
    ``lu`` if it solved monolithically) into ``stats``."""
    if isinstance(integ, NewmarkScheme):
        totals = integ.operator_totals()
        stats.n_step_operators_released = integ.released_operators
        stats.n_factorizations = totals.n_factorizations
        stats.n_saddle_solves = totals.n_saddle_solves
        stats.max_schur_iterations = totals.max_schur_iterations
        if totals.monolithic:
            stats.contact_solve = "lu"


def _log_summary(stats: IntegrationStats, rank: int) -> None:
    """One log line on rank 0 with the steps, switches, solves and wall time of the run."""
    if rank == 0:
        log.info(
            "%s done: %d steps (%d contact, %d free, %d rejected), %d status switches, %d solves, "
            "%d factorizations, %.2f s",
            stats.method,
            stats.n_steps,
            stats.n_steps_contact,
            stats.n_steps_free,
            stats.n_rejected,
            stats.n_switches,
            stats.n_solves,
            stats.n_factorizations,
            stats.wall_time,
        )


def integrate(
    system: LinearDynamics,
    u0: PETSc.Vec,
    v0: PETSc.Vec,
    schedule: TimeSchedule,
    method: str = "newmark-mr",
    observer: Callable[[StepState], None] | None = None,
    options: Mapping[str, object] | None = None,
    progress: bool = False,
    stop: Callable[[StepState], bool] | None = None,
) -> IntegrationStats:
    """Integrate from t = 0 (displacement u0 in m, velocity v0 in m/s) to ``schedule.t_end``.

    ``method`` one of :data:`METHODS`; ``observer(state)`` is called (collectively, on every rank)
    once at t = 0 and after every accepted step; ``options`` keys relative to ``-impact_`` (PETSc
    solver options and the settings listed in the module docstring; the command line wins).
    ``progress`` shows a tqdm bar over simulated time on rank 0 if stderr is a terminal.
    ``stop(state)`` (optional, e.g. :class:`SeparationStop`), called after the observer on every
    accepted step, ends the run early when it returns True (``stats.stopped_at``; the state it
    saw is the last one). It must give the same answer on every rank (replicated inputs only).
    Raises :class:`SolverError` on a failed solve or violated contact conditions. An explicit run
    that blows up is stopped and returned with ``stats.diverged = True`` (and a warning).
    """
    method = method.lower()
    if method not in METHODS:
        raise InputError(f"integrator {method!r}: choose one of {', '.join(METHODS)}")
    comm = system.M.getComm().tompi4py()
    wall0 = time.perf_counter()
    stats = IntegrationStats(method=method, t_end=schedule.t_end)
    integ = _create_scheme(system, method, dict(options or {}), stats, comm)
    integ.initialize(u0, v0)
    stats.dt_contact, stats.dt_free = schedule.dt_grid, schedule.free_ratio * schedule.dt_grid
    if comm.rank == 0:
        log.info(
            "%s: t_end %.4g s, dt_contact %.4g s (asked %.4g), dt_free %.4g s",
            method,
            schedule.t_end,
            stats.dt_contact,
            schedule.dt_contact,
            stats.dt_free,
        )
    observers = Observers(observer, stop)
    observers.notify(integ, stats, 0.0, 0.0, 0)
    report = ProgressReport.start(method, schedule.t_end, progress, comm.rank)
    try:
        _step_to_end(integ, schedule, stats, observers, report, comm)
    finally:
        report.close()
        _collect_operator_totals(integ, stats)
        stats.wall_time = time.perf_counter() - wall0
    _log_summary(stats, comm.rank)
    integ.destroy()
    return stats
