"""Time integrators with unilateral contact by Lagrange multipliers (design.md section 4).

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
    error (bar: design.md section 3; measured in tests/integration/test_bar.py).
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

import numpy as np
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
    options = dict(options or {})
    comm = system.M.getComm().tompi4py()
    wall0 = time.perf_counter()
    stats = IntegrationStats(method=method, t_end=schedule.t_end)
    integ: CentralPenaltyScheme | NewmarkScheme  # PlasticNewmarkScheme is a NewmarkScheme
    if method == "central-penalty":
        if system.plastic is not None:
            raise InputError("--integrator central-penalty has no plasticity: use newmark-mr (or elastic materials)")
        integ = CentralPenaltyScheme(system, options, stats, comm)
    elif system.plastic is not None:
        integ = PlasticNewmarkScheme(system, method == "newmark-mr", options, stats, comm)
    else:
        integ = NewmarkScheme(system, method == "newmark-mr", options, stats, comm)
    integ.initialize(u0, v0)

    n_grid, m_free, dt_g = schedule.n_grid, schedule.free_ratio, schedule.dt_grid
    dt_free = m_free * dt_g
    stats.dt_contact, stats.dt_free = dt_g, dt_free
    if comm.rank == 0:
        log.info(
            "%s: t_end %.4g s, dt_contact %.4g s (asked %.4g), dt_free %.4g s",
            method,
            schedule.t_end,
            dt_g,
            schedule.dt_contact,
            dt_free,
        )

    def notify(t: float, dt: float, step: int) -> bool:
        """Hand the state to the observer; True if ``stop`` says the run is over."""
        if observer is None and stop is None:
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
        if observer is not None:
            observer(st)
        return stop is not None and step > 0 and bool(stop(st))

    notify(0.0, 0.0, 0)
    bar, plain = None, None
    t_scale, t_unit = (1e3, "ms") if schedule.t_end >= 1e-3 else (1e6, "\u00b5s")
    if progress and comm.rank == 0 and sys.stderr.isatty():
        bar = terminal_bar(method, schedule.t_end * t_scale, t_unit, sys.stderr)
    elif progress and comm.rank == 0:
        # not a terminal (a log, CI, a pipe): a plain line every 10 % of the simulated time
        plain = {"next": 0.1, "t0": time.perf_counter()}
    k, step, t = 0, 0, 0.0
    prev_active = integ.lam > 0
    force_contact = False
    try:
        while k < n_grid:
            raise_if_interrupted()  # a Ctrl-C / SIGTERM whose exception a library swallowed
            n_act = int(np.count_nonzero(prev_active)) + int(getattr(integ, "touched", False))
            use_free = (
                not force_contact
                and n_grid - k >= m_free
                and schedule.free_step_allowed(integ.gap, integ.rate(), n_act)
            )
            kk = k + (m_free if use_free else 1)
            dt = dt_free if use_free else dt_g
            t_new = schedule.t_end if kk == n_grid else kk * dt_g
            if not integ.step(dt, t_new, step + 1, allow_reject=use_free):
                stats.n_rejected += 1
                force_contact = True
                continue
            force_contact = False
            k, step, t = kk, step + 1, t_new
            stats.n_steps += 1
            if use_free:
                stats.n_steps_free += 1
            else:
                stats.n_steps_contact += 1
            active = integ.lam > 0
            changed = int(np.count_nonzero(active != prev_active))
            stats.n_switches += changed
            stats.n_active_set_changes += changed > 0
            stats.max_active = max(stats.max_active, int(np.count_nonzero(active)))
            prev_active = active
            if notify(t, dt, step):
                stats.stopped_at = t
                break
            if step % GARBAGE_EVERY == 0:
                # dropped per-step PETSc objects are parked until a collective cleanup (solvers.py)
                PETSc.garbage_cleanup(comm)
            if bar is not None:
                bar.update(dt * t_scale)
            elif plain is not None and t >= plain["next"] * schedule.t_end * (1 - 1e-12):
                print(
                    f"  {method}: {100 * t / schedule.t_end:3.0f} % ({t * t_scale:.3g} of {schedule.t_end * t_scale:.3g} "
                    f"{t_unit} simulated, {time.perf_counter() - plain['t0']:.1f} s)",
                    file=sys.stderr,
                    flush=True,
                )
                plain["next"] = math.floor(10 * t / schedule.t_end + 1e-9) / 10 + 0.1
            if isinstance(integ, CentralPenaltyScheme) and integ.diverged:  # the explicit scheme's test
                stats.diverged, stats.diverged_at = True, t
                if comm.rank == 0:
                    log.warning(
                        "%s diverged at t = %.6g s (step %d, dt %.4g s, critical %.4g s): energy %.3e J "
                        "vs initial %.3e J",
                        method,
                        t,
                        step,
                        dt,
                        stats.dt_critical,
                        integ.energy,
                        integ.energy_ref,
                    )
                break
    finally:
        if bar is not None:
            bar.close()
        if isinstance(integ, NewmarkScheme):
            totals = integ.operator_totals()
            stats.n_step_operators_released = integ.released_operators
            stats.n_factorizations = totals.n_factorizations
            stats.n_saddle_solves = totals.n_saddle_solves
            stats.max_schur_iterations = totals.max_schur_iterations
            if totals.monolithic:
                stats.contact_solve = "lu"
        stats.wall_time = time.perf_counter() - wall0
    if comm.rank == 0:
        log.info(
            "%s done: %d steps (%d contact, %d free, %d rejected), %d status switches, %d solves, "
            "%d factorizations, %.2f s",
            method,
            stats.n_steps,
            stats.n_steps_contact,
            stats.n_steps_free,
            stats.n_rejected,
            stats.n_switches,
            stats.n_solves,
            stats.n_factorizations,
            stats.wall_time,
        )
    integ.destroy()
    return stats
