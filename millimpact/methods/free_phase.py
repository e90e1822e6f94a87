"""The time loop of a reduced model: the integrator while the bodies touch, the closed-form free
vibration between impacts (foundations.md section 4).

The contact lasts ~0.1 ms of the 40 ms run; with the zone kept physical the reduced model is
still thousands of coordinates, so stepping the free vibration would cost nearly as much as the
full model. With ``free_phase = "modal"`` (default) the integrator runs while the bodies touch
(from the start with the contact step only until the bodies have been apart for 10 steps, at the
latest ``gap / v + 1.5 t_c``, then in chunks of 2 t_c while a contact is active); once they are apart, the motion is the closed-form sum of the
free-vibration modes of the reduced system up to ``free_modes_factor`` times the plan's f_cut
(with the integrator's mass matrix; :func:`millimpact.reduction.free_modes.compute_free_modes`),
recorded at once (vectorised over the times) on the integrator's free-step grid. A gap predicted
to come back below the plan's initial gap (a second impact) hands the state back to the
integrator. The energy above the modal cutoff at the switch is dropped and reported
(``results["free_phase"]["energy_dropped_J"]``; 2e-5 (traditional) and 3e-6 (improved) of the
impact energy at the default scene). ``free_phase = "step"`` integrates all the way.

``free_phase = "auto"`` (the default) takes the modal phase only where it is the cheaper one
(:func:`resolve_free_phase`): the free modes cost a factorization and a shift-and-invert Krylov
solve of the reduced system, about ``STEPS_PER_MODAL_COORDINATE`` free steps per modal coordinate
of the reduced model, so a free span of fewer free steps than that is stepped instead
(measured: the liner panel's 0.6 ms run, 21 free steps after the contact, spent 72 s on 169 free
modes; the plastic rig's impact to 0.3 ms, 77 free steps, took 32.2 s modal against 29.9 s stepped).

Takes the reduced model, its contact dynamics and initial state, the contact set, the plan's
time steps and a :class:`millimpact.results.reduced_recorder.ReducedRecorder`; gives the summed
integrator statistics and the phases' record (:func:`integrate_reduced`).
"""

from __future__ import annotations

import logging
import math
import time
from types import SimpleNamespace
from typing import Any

import numpy as np
from petsc4py import PETSc

from ..fem.contact import ContactSet
from ..integration import integrators
from ..integration.dynamics import SeparationStop
from ..integration.solvers import return_freed_memory
from ..reduction.free_modes import ModalProjection, compute_free_modes
from ..reduction.plastic_projection import ProjectedPlasticZone
from ..reduction.reduced_model import ReducedModel
from ..results.reduced_recorder import ReducedRecorder
from ..scene.plan import Plan

log = logging.getLogger(__name__)

#: the closed-form free phase keeps the free-vibration modes up to this many f_cut: its outputs
#: are sampled every dt_free = 1 / (10 f_cut) (plan.py), whose Nyquist frequency is 5 f_cut
FREE_MODES_FACTOR = 4.0

#: the first integrator segment of the modal free phase lasts at most gap / v + this many t_c (Hertz):
#: the contact lasts ~t_c (0.99 t_c at the default scene, a few % more on thin blocks), so the
#: bodies are apart at its end and the switch to the modes needs no second segment (each segment
#: costs a factorization and the contact operator W)
FIRST_SPAN_CONTACTS = 1.5

#: the free modes' offline cost in free steps per modal coordinate of the reduced model
#: (``free_phase = "auto"``). Measured at 0.3 ms, against stepping the same free span
#: (``-free_phase step``): the elastic rig (10 modal coordinates, 14 free modes) 1.95 s of modes
#: against 13 ms a free step, 15 steps a coordinate; the plastic rig (9, 13 modes) 2.6 s with its
#: residual state against 19 ms, 15; the liner panel (220, 169 modes) 72 s. Rounded down to 10,
#: which favours the modal phase where the two are close
STEPS_PER_MODAL_COORDINATE = 10.0
#: a finite-strain zone's free step, in elastic free steps: its correction is nonlinear wherever the
#: zone is strained, so every free step iterates (zone pass and body solves each time) where a
#: small-strain one solves once. Measured on the plastic rig at 0.3 ms (131 free steps): 55 ms a
#: free step against the small-strain 19 ms, so 2.9
FINITE_FREE_STEP_COST = 2.9
#: the modal phase's first segment ends this many contact steps after the bodies part (a gap that
#: closes again within them resets the count; one closing later hands the state back to the steps)
SEPARATED_STEPS = 10
#: the values of ``free_phase``
FREE_PHASES = ("auto", "modal", "step")


def first_span_end(plan: Plan) -> float:
    """The end of the modal phase's first integrator segment (s): gap / v + FIRST_SPAN_CONTACTS t_c."""
    return plan.gap / plan.hertz.speed + FIRST_SPAN_CONTACTS * plan.hertz.contact_time


def resolve_free_phase(free_phase: str, red: ReducedModel, plan: Plan, t_end: float) -> tuple[str, str]:
    """("modal" | "step", why) for the asked ``free_phase``. ``auto``: step when the free span after
    the first segment, (t_end - t_first) / dt_free free steps (t_first: :func:`first_span_end`), is at
    most ``STEPS_PER_MODAL_COORDINATE`` times the reduced model's modal coordinates (an estimate of the
    free modes below the cutoff: 10 against 14 on the rig, 220 against 169 on the liner panel).
    With finite strain (``plan.strain``) a free step counts as FINITE_FREE_STEP_COST elastic ones."""
    if free_phase != "auto":
        return free_phase, "asked"
    n_free = max(0.0, t_end - first_span_end(plan)) / plan.dt_free
    n_modal = max(1, red.n_global - red.n_zone)
    finite = getattr(plan, "strain", "small") == "finite"
    weight = FINITE_FREE_STEP_COST if finite else 1.0
    steps = f"{n_free:.0f} free steps" + (f" (finite strain: x {FINITE_FREE_STEP_COST:g})" if finite else "")
    if weight * n_free <= STEPS_PER_MODAL_COORDINATE * n_modal:
        return "step", f"{steps} <= {STEPS_PER_MODAL_COORDINATE:g} x {n_modal} modal coordinates"
    return "modal", f"{steps} > {STEPS_PER_MODAL_COORDINATE:g} x {n_modal} modal coordinates"


def integrate_reduced(
    red: ReducedModel,
    system: integrators.LinearDynamics,
    q0: PETSc.Vec,
    qd0: PETSc.Vec,
    contact: ContactSet,
    plan: Plan,
    t_end: float,
    rec: ReducedRecorder,
    *,
    integrator: str = "newmark-mr",
    options: dict | None = None,
    progress: bool = False,
    free_phase: str = "auto",
    f_free: float,
    min_span: float | None = None,
    stop=None,
) -> dict[str, Any]:
    """Integrate a reduced model over [0, t_end], feeding ``rec``.

    ``free_phase = "step"``: the integrator all the way. ``"auto"`` (default): "modal" or "step",
    whichever costs less (:func:`resolve_free_phase`). ``"modal"``: the integrator
    while the bodies touch; once they have separated, the free vibration is the closed-form sum
    of the free-vibration modes up to ``f_free`` (Hz; :func:`compute_free_modes`), sampled on the
    integrator's free-step grid; if a gap is predicted to come back within the plan's initial gap
    (a second impact), the modal state at the grid point before is handed back to the integrator.
    The energy of the state above ``f_free`` at each switch is reported (it is dropped).
    ``stop`` (a :class:`millimpact.integration.integrators.SeparationStop`, say) ends the run at the
    step it returns True (``stats["stopped_at"]``; runs that need the impact only: tables).
    Returns a dict: ``stats`` (summed integrator statistics), ``segments`` [(kind, t0, t1)], the
    modal energy dropped (J), modal rows, free-mode count and their offline time (s).
    """
    options = dict(options or {})
    asked = free_phase
    free_phase, why = resolve_free_phase(free_phase, red, plan, t_end)
    t_c = plan.hertz.contact_time
    chunk = max(2.0 * t_c, 20.0 * plan.dt_contact)
    t_first = min(t_end, first_span_end(plan))
    q, qd = q0, qd0
    t = 0.0
    stats_sum: dict[str, Any] = {}
    segments: list[tuple[str, float, float]] = []
    out: dict[str, Any] = {
        "modal_rows": 0,
        "energy_dropped_J": 0.0,
        "free_modes": 0,
        "free_modes_time": 0.0,
        "free_modes_f_max_Hz": f_free,
        "mode": free_phase,
        "mode_asked": asked,
        "mode_reason": why,
    }
    modal: ModalProjection | None = None
    offset: SimpleNamespace | None = None  # plastic runs: the residual state q_s
    comm = red.comm
    while t < t_end * (1 - 1e-12):
        t_stop = t_end if free_phase == "step" else min(t_end, t_first if not segments else t + chunk)
        # the modal phase's first segment ends once the bodies have parted (SEPARATED_STEPS steps
        # without contact after touching), at the latest at t_first: the steps after separation
        # only step the free vibration the modes give (a finite-strain step iterates: the plastic
        # rig's 0.3 ms spent a fifth of its zone passes there)
        parted = SeparationStop(SEPARATED_STEPS) if free_phase == "modal" and stop is None and not segments else None
        # between modal phases the steps are short: one step size (one factorization and one
        # contact operator W instead of two; the modal phase takes the free vibration)
        q, qd, lam, st, mass = _run_steps(
            system,
            q,
            qd,
            t,
            t_stop,
            plan,
            rec,
            integrator,
            options,
            progress,
            single_size=free_phase == "modal",
            stop=stop if parted is None else parted,
        )
        _add_stats(stats_sum, st)
        if parted is not None and math.isfinite(st.stopped_at):  # parted: on to the free modes
            t_stop = t + st.stopped_at
            stats_sum["stopped_at"] = math.inf
        elif math.isfinite(st.stopped_at):  # the stop callback ended the run
            segments.append(("step", t, t + st.stopped_at))
            stats_sum["stopped_at"] = t + st.stopped_at
            t_end = t + st.stopped_at
            break
        segments.append(("step", t, t_stop))
        t = t_stop
        if t >= t_end * (1 - 1e-12) or np.any(lam > 0):
            continue
        if modal is None:
            t0 = time.perf_counter()
            # the stepping's factorizations are freed: their memory back before the free modes'
            # (coarse plastic liner panel: 1.30 -> 1.05 GB; the free modes then add 0.13 GB)
            return_freed_memory()
            modal = compute_free_modes(red, f_free, mass=mass)
            out["free_modes_time"] = time.perf_counter() - t0
            out["free_modes"] = modal.n_global
            gap_rows = modal.rows_dense(contact.B)
        if system.plastic is not None and (offset is None or offset.version != system.plastic.version):
            t0 = time.perf_counter()
            offset = residual_offset(red, system, contact)
            out["residual_state_time"] = out.get("residual_state_time", 0.0) + time.perf_counter() - t0
        q_free = q if offset is None else _minus(q, offset.q)
        g0 = contact.g0 if offset is None else contact.g0 + offset.gap_shift
        res = _free_vibration(
            modal, gap_rows, g0, q_free, qd, t, t_end, plan, rec, chunk if min_span is None else min_span, offset
        )
        if res is None:  # a gap closes soon: keep stepping
            continue
        t_new, q_new, qd_new, n_rows, dropped = res
        out["modal_rows"] += n_rows
        out["energy_dropped_J"] += dropped * red.model.sym_factor
        segments.append(("modal", t, t_new))
        t = t_new
        if q_new is not None:
            q, qd = (q_new, qd_new) if offset is None else (_plus(q_new, offset.q), qd_new)
            rec.set_projection(red)
    out["segments"] = segments
    stats_sum["t_end"] = t_end
    out["stats"] = stats_sum
    if comm.rank == 0 and modal is not None:
        log.info(
            "free phase: %d modal rows, %d modes up to %.4g kHz, %.3g J dropped at the switches",
            out["modal_rows"],
            out["free_modes"],
            f_free / 1e3,
            out["energy_dropped_J"],
        )
    return out


def residual_offset(red: ReducedModel, system: integrators.LinearDynamics, contact: ContactSet) -> SimpleNamespace:
    """The residual state of a plastic run's committed plastic strain (the static offset of its
    free vibration): ``q`` = q_s with K_r q_s = -f_frozen
    (:meth:`millimpact.reduction.plastic_projection.ProjectedPlasticZone.residual_state`), the
    contact gaps it shifts (``gap_shift`` = B_r q_s, replicated, m) and the plastic state's
    ``version`` it belongs to."""
    plastic = system.plastic
    assert isinstance(plastic, ProjectedPlasticZone), "a reduced plastic run's zone is the projected one"
    q_s = plastic.residual_state()
    shift = system.B.createVecLeft()
    system.B.mult(q_s, shift)
    gap_shift = np.concatenate(red.comm.allgather(shift.array_r.copy()))
    shift.destroy()
    return SimpleNamespace(q=q_s, gap_shift=gap_shift, version=plastic.version)


def _minus(a: PETSc.Vec, b: PETSc.Vec) -> PETSc.Vec:
    c = a.copy()
    c.axpy(-1.0, b)
    return c


def _plus(a: PETSc.Vec, b: PETSc.Vec) -> PETSc.Vec:
    c = a.copy()
    c.axpy(1.0, b)
    return c


def _add_stats(total: dict, stats) -> None:
    """Accumulate the integrator statistics of one segment: counts and wall time add up, maxima
    take the maximum, the rest keeps the first segment's value."""
    d = stats._asdict() if hasattr(stats, "_asdict") else dict(vars(stats))
    for k, v in d.items():
        if isinstance(v, bool):
            total[k] = bool(total.get(k, False) or v)
        elif not isinstance(v, (int, float)):
            total.setdefault(k, v)
        elif k.startswith("max_"):
            total[k] = max(total.get(k, v), v)
        elif k.startswith("n_") or k == "wall_time" or k.endswith("_J"):
            total[k] = total.get(k, 0) + v
        else:
            total.setdefault(k, v)
    total["n_segments"] = total.get("n_segments", 0) + 1


def _run_steps(
    system,
    q,
    qd,
    t0: float,
    t1: float,
    plan: Plan,
    rec: ReducedRecorder,
    integrator: str,
    options: dict,
    progress: bool,
    single_size: bool = False,
    stop=None,
):
    """The integrator from (q, qd) at t0 to t1 (steps dt_contact, and dt_free out of contact unless
    ``single_size``), or until ``stop``; returns the final (q, qd, lambda, stats, mass matrix of
    the scheme)."""
    schedule = integrators.TimeSchedule(t1 - t0, plan.dt_contact, None if single_size else plan.dt_free)
    rec.time_offset = t0
    last = {}

    def observe(st) -> None:
        last["st"] = st
        if st.step == 0 and t0 > 0:
            return  # the state at t0 is already recorded
        rec(st)

    stats = integrators.integrate(
        system,
        q,
        qd,
        schedule,
        method=integrator,
        observer=observe,
        options=dict(options),
        progress=progress,
        stop=stop,
    )
    st = last["st"]
    rec.time_offset = 0.0
    return st.u.copy(), st.v.copy(), np.array(st.lam, copy=True), stats, st.mass


def _free_vibration(
    modal: ModalProjection,
    gap_rows: np.ndarray,
    g0: np.ndarray,
    q: PETSc.Vec,
    qd: PETSc.Vec,
    t0: float,
    t_end: float,
    plan: Plan,
    rec: ReducedRecorder,
    min_span: float,
    offset: SimpleNamespace | None = None,
):
    """Closed-form free vibration from (q, qd) at t0, recorded on the free-step grid until t_end or
    until a gap is predicted below the plan's initial gap. None if that happens within
    ``min_span`` (stay with the integrator); else (t_stop, q, qd at t_stop or None at t_end, rows,
    energy dropped at the switch in J). With a plastic ``offset`` (:func:`residual_offset`), q is
    the motion about the residual state q_s (the gaps ``g0`` include its shift; the recorder adds
    it back) and the returned q is too."""
    comm = modal.comm
    eta_v, etad_v = modal.project(q), modal.project(qd)
    eta0 = np.concatenate(comm.allgather(eta_v.array_r.copy()))
    etad0 = np.concatenate(comm.allgather(etad_v.array_r.copy()))
    red = modal.red
    e_red = 0.5 * (qd.dot(_mult(modal.mass, qd)) + q.dot(_mult(red.K, q)))
    e_mod = 0.5 * (float(etad0 @ etad0) + float(np.sum(modal.omega2 * eta0 * eta0)))
    sched = integrators.TimeSchedule(t_end - t0, plan.dt_contact, plan.dt_free)
    dt_out = sched.free_ratio * sched.dt_grid
    n = max(1, int(math.floor((t_end - t0) / dt_out * (1 + 1e-12))))
    times = t0 + dt_out * np.arange(1, n + 1)
    if times[-1] < t_end * (1 - 1e-12):
        times = np.append(times, t_end)
    times[-1] = min(times[-1], t_end)
    omega = np.sqrt(modal.omega2)
    span = max(t_end - t0, 1e-300)
    rigid = omega * span < 1e-6
    w = np.where(rigid, 1.0, omega)
    g_thr = plan.gap

    def state(tau: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        c, s_ = np.cos(np.outer(omega, tau)), np.sin(np.outer(omega, tau))
        eta = eta0[:, None] * c + (etad0 / w)[:, None] * s_
        etad = -(eta0 * omega)[:, None] * s_ + etad0[:, None] * c
        if np.any(rigid):
            eta[rigid] = eta0[rigid, None] + etad0[rigid, None] * tau[None, :]
            etad[rigid] = etad0[rigid, None]
        return eta, etad, -modal.omega2[:, None] * eta

    # first grid time with a gap below the threshold (gaps in closed form, in chunks of times)
    k_stop = None
    for k0 in range(0, len(times), 2048):
        tau = times[k0 : k0 + 2048] - t0
        eta, _, _ = state(tau)
        gaps = g0[:, None] + gap_rows @ eta
        bad = np.nonzero(gaps.min(axis=0) < g_thr)[0]
        if len(bad):
            k_stop = k0 + int(bad[0])
            break
    if k_stop is not None and times[k_stop] - t0 < min_span:
        return None
    last = len(times) if k_stop is None else k_stop  # rows 0 .. last-1
    for k0 in range(0, last, 2048):
        idx = np.arange(k0, min(last, k0 + 2048))
        rec.record_free(modal, times[idx], *state(times[idx] - t0), offset=offset)
    lo, hi = eta_v.getOwnershipRange()
    u, v = modal.create_vector(), modal.create_vector()
    if k_stop is None:
        return t_end, None, None, last, e_red - e_mod
    # hand the state at the last recorded time back to the integrator
    tau = np.array([times[last - 1] - t0]) if last else np.array([0.0])
    eta, etad, _ = state(tau)
    u.array[:] = eta[lo:hi, 0]
    v.array[:] = etad[lo:hi, 0]
    t_stop = float(times[last - 1]) if last else t0
    return t_stop, modal.lift(u), modal.lift(v), last, e_red - e_mod


def _mult(A: PETSc.Mat, x: PETSc.Vec) -> PETSc.Vec:
    y = A.createVecLeft()
    A.mult(x, y)
    return y
