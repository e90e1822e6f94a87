"""Reduced run methods: ``traditional``, ``modal-p2`` and ``improved`` (DESIGN.md section 4).

Each is a Galerkin projection ``u = T q`` of the full finite-element model of the same mesh
(:mod:`millimpact.reduction`), integrated by the same integrator with the same contact rows:
``LinearDynamics(T^T M T, T^T K T, B T, g0, [], contact coordinates)``.

``traditional``
    The traditional multivariable method: whole mesh P1, contact-zone dofs kept physical, each
    body's non-contact region reduced by Craig-Bampton (constraint modes + fixed-interface modes up
    to the cutoff).
``modal-p2``
    The same on the whole-mesh P2 model.
``improved``
    The paper's improved multivariable method: whole mesh P2, the contact zone described by
    first-order manifold covers (:mod:`millimpact.reduction.nmm_zone`; default null-space remedy: no
    gradient enrichment at the zone/region interface vertices), the region by Craig-Bampton.

Options (``options`` keys, also ``-modes 20`` etc. on the command line):
``modes`` (modes kept per body; wins over the cutoff), ``f_cut`` (Hz; default the plan's
``f_cut = 4 / t_c`` or ``scene.model.f_cut``), ``nmm_remedy`` (improved: interface | anchors),
``augment`` (none | boussinesq | translation, comma-separated: modal truncation augmentation
vectors of each body's region, :mod:`millimpact.reduction`; default none), ``free_phase`` (modal | step, below), ``modal_min_span`` (s: a modal phase is taken only if no
gap closes within this span, default the stepping chunk max(2 t_c, 20 dt_contact)), ``free_modes_factor`` (the free phase keeps the
free-vibration modes up to this many times the plan's f_cut, whose dt_free = 1 / (10 f_cut) is its
output grid; default 4), ``integrator`` (default newmark-mr),
``recovery`` (mode-acceleration | modal, below), ``t_end`` (s). The rest goes to the integrator.

The free phase. The contact lasts ~0.1 ms of the 40 ms run; with the zone kept physical the
reduced model is still thousands of coordinates, so stepping the free vibration would cost nearly
as much as the full model. With ``free_phase = "modal"`` (default) the integrator runs while the
bodies touch (from the start to ``gap / v + 1.5 t_c`` with the contact step only, then in chunks of 2 t_c while a contact is
active); once they are apart, the motion is the closed-form sum of the free-vibration modes of the
reduced system up to ``free_modes_factor`` times the plan's f_cut (with the integrator's mass
matrix), recorded at once (vectorised over the times) on the integrator's free-step grid. A gap predicted to come back below the plan's initial gap
(a second impact) hands the state back to the integrator. The energy above the modal cutoff at
the switch is dropped and reported (``results["free_phase"]["energy_dropped_J"]``; 2e-5
(traditional) and 3e-6 (improved) of the impact energy at the default scene).
``free_phase = "step"`` integrates all the way.

Observables: the time series are the full method's (:class:`millimpact.methods.full.Recorder`),
computed from rows precomputed once per projection (probe rows P T, the ball's centre-of-mass
row T^T c), energies as ``q . M_r q / 2`` and ``q . K_r q / 2``; u = T q is expanded only for
the XDMF fields. Probe displacements and gradients in the non-contact region (the gauges) are
recovered by mode acceleration (``recovery``: mode-acceleration, the default, or modal: u = T q
alone): ``P T q + C q''`` with the rows C of :meth:`ReducedModel.mode_acceleration_rows`.
"""
from __future__ import annotations

import dataclasses
import logging
import math
import time
from pathlib import Path
from types import SimpleNamespace
from typing import Any, Optional

import numpy as np
import scipy.sparse as sp
from mpi4py import MPI
from petsc4py import PETSc

from ..errors import InputError
from ..fem.contact import ContactSet, create_contact
from ..fem.model import FEModel, create_fe_model
from ..fem.probes import PointProbe
from ..geometry.mesh import create_mesh
from ..integration import integrators
from ..reduction.craig_bampton import (AUGMENTATION_PATTERNS, ModalProjection, ReducedModel, compute_free_modes,
                                       create_nodal_zone_basis, gather_aij_dense, local_rows_to_aij, partition_dofs,
                                       reduce_model)
from ..reduction.nmm_zone import create_nmm_zone
from ..results.fields import write_fields
from ..results.output import RunOutput
from ..results.recorder import Recorder, impact_results
from ..scene.plan import Plan, make_plan
from ..scene.schema import Scene
from .options import float_option, int_option

log = logging.getLogger(__name__)

#: the closed-form free phase keeps the free-vibration modes up to this many f_cut: its outputs
#: are sampled every dt_free = 1 / (10 f_cut) (plan.py), whose Nyquist frequency is 5 f_cut
FREE_MODES_FACTOR = 4.0

#: contact-zone radius of the reduced methods in units of a_max, unless the scene sets
#: model.zone_radius: the zone only has to hold the contact candidates with a few elements to
#: spare (the constraint modes make the reduction statically exact at any zone size; the modes
#: carry the dynamics). The full method's 4 a_max (plan.py) would make the NMM zone 1.5k vertices,
#: 15.6k coordinates at the default scene, and the time loop as dear as the full P1 model's.
REDUCED_ZONE_FACTOR = 2.5
#: contact candidates of the reduced methods within this many a_max of the contact axis: the
#: Hertz patch is a_max (the finite block's patch is a little smaller); at least 2 h_contact
#: inside the zone (mass redistribution must not reach the interface coordinates)
REDUCED_CANDIDATE_FACTOR = 1.75

#: the first integrator segment of the modal free phase lasts gap / v + this many t_c (Hertz):
#: the contact lasts ~t_c (0.99 t_c at the default scene, a few % more on thin blocks), so the
#: bodies are apart at its end and the switch to the modes needs no second segment (each segment
#: costs a factorization and the contact operator W)
FIRST_SPAN_CONTACTS = 1.5

#: method name -> (Lagrange degree, contact-zone basis: nodal unknowns or NMM covers); the
#: one-line descriptions are in :mod:`millimpact.methods.registry`
REDUCED_METHODS = {
    "traditional": (1, "nodal"),
    "modal-p2": (2, "nodal"),
    "improved": (2, "nmm"),
}


# --- observables ---------------------------------------------------------------------------------
def _reduced_probe(probe: PointProbe, red: ReducedModel) -> PointProbe:
    """The probe's rows P T, restricted on each rank to its owned reduced columns (so that
    ``values(q_owned)`` sums the ranks' parts exactly as :class:`PointProbe` does)."""
    q0, q1 = red.M.getOwnershipRange()
    mats = []
    for P in (probe.P_val, probe.P_grad):
        PT = red.project_rows(local_rows_to_aij(P, red.model.V))
        r0, r1 = PT.getOwnershipRange()
        indptr, indices, data = PT.getValuesCSR()
        local = sp.csr_matrix((data, indices, indptr), shape=(r1 - r0, red.n_global))
        full = sp.vstack(red.comm.allgather(local)).tocsc()
        mats.append(full[:, q0:q1].tocsr())
    return PointProbe(probe.comm, probe.n_points, mats[0], mats[1], probe.found)


class ReducedRecorder(Recorder):
    """The full method's :class:`Recorder` on a reduced model: same rows, from reduced maps.

    Replaces the recorder's full-space maps by their images under the current projection (a
    :class:`ReducedModel` ``u = T q`` or a :class:`ModalProjection` ``u = T Phi eta``, switched
    with :meth:`set_projection`): the ball's centre-of-mass row ``c`` by ``T^T c``, the probes
    by ``P T``, the ball mask by the ball's coordinates, the energies' M and K by the projected
    ones (no fixed coordinates: T is zero on clamped dofs). ``time_offset`` (s) is added to the
    states' times (restarted integrations). XDMF states are expanded to model vectors at once.
    """

    def __init__(self, red: ReducedModel, contact: ContactSet, field_times: tuple[float, ...],
                 recovery: str = "mode-acceleration"):
        super().__init__(red.model, contact, field_times)
        self._c_full = self.c_y
        self._probe_full = self.probe
        # mode-acceleration rows of the probes (ReducedModel.mode_acceleration_rows): displacement
        # values and gradients get C q'' added; replicated dense (rows x reduced coordinates)
        self._ma = None
        if recovery == "mode-acceleration":
            P_val = self._probe_full.P_val
            C = red.mode_acceleration_rows(local_rows_to_aij(sp.vstack([P_val, self._probe_full.P_grad]).tocsr(),
                                                             red.model.V))
            self._ma = (C[:P_val.shape[0]], C[P_val.shape[0]:])
        self.time_offset = 0.0
        self.proj = None
        self._maps: dict[int, tuple] = {}
        self._ct_full = getattr(self, "c_t", None)     # friction: the ball's tangential row
        self._ct_maps: dict[int, object] = {}
        self.set_projection(red)

    def set_projection(self, proj) -> None:
        """Observe states of ``proj`` (a ReducedModel or a ModalProjection) from now on."""
        self.proj = proj
        key = id(proj)
        if key not in self._maps:
            mask = proj.create_vector()
            mask.array[proj.ball_coords] = 1.0
            view = SimpleNamespace(M=proj.M, K=proj.K, fixed_dofs=np.zeros(0, dtype=np.int32),
                                   scene=proj.model.scene, sym_factor=proj.model.sym_factor)
            self._maps[key] = (proj.restrict(self._c_full), mask, proj.create_vector(), proj.create_vector(),
                               _reduced_probe(self._probe_full, proj), view)
            self._maps[("ma", key)] = self._ma_probe(proj)
        self.c_y, self.ball_mask, self.tmp, self.tmp2, self.probe, self.model = self._maps[key]
        self.ma_probe = self._maps[("ma", key)]
        if self._ct_full is not None:
            if key not in self._ct_maps:
                self._ct_maps[key] = proj.restrict(self._ct_full)
            self.c_t = self._ct_maps[key]

    def _local(self, vec) -> np.ndarray:
        return vec.array_r

    def _ma_probe(self, proj) -> Optional[PointProbe]:
        """The mode-acceleration rows for states of ``proj`` as a probe acting on accelerations
        (owned columns of proj's coordinates): C for the reduced model, C Phi for a modal one."""
        if self._ma is None:
            return None
        comm = proj.comm
        mats = []
        for C in self._ma:
            if isinstance(proj, ModalProjection):
                r0, r1 = proj.red.M.getOwnershipRange()
                C = comm.allreduce(C[:, r0:r1] @ proj.Phi.getDenseArray(), op=MPI.SUM)
                # quasi-static only below the lowest fixed-interface mode not kept: a free mode
                # above it drives the truncated modes near or past resonance
                nxt = [b.next_frequency_hz for b in proj.red.bodies if b.n_interior and np.isfinite(b.next_frequency_hz)]
                if nxt:
                    C = C * (np.sqrt(proj.omega2) < 2 * math.pi * min(nxt))[None, :]
            lo, hi = proj.M.getOwnershipRange()
            mats.append(sp.csr_matrix(C[:, lo:hi]))
        return PointProbe(comm, self._probe_full.n_points, mats[0], mats[1], self._probe_full.found)

    def _displacement_probe(self, st) -> tuple[np.ndarray, np.ndarray]:
        vals, grads = super()._displacement_probe(st)
        if self.ma_probe is not None:
            a = st.a.array_r
            vals = vals + self.ma_probe.values(a)
            grads = grads + self.ma_probe.gradients(a)
        return vals, grads

    def _dense_maps(self, modal: ModalProjection) -> SimpleNamespace:
        """Replicated dense maps of a modal projection (m modal coordinates, a few dozen): the
        ball's rows c and c_t, the probe rows (values, gradients), the scheme's mass, K_r and the
        ball mask, all m-column; built once per projection."""
        key = ("dense", id(modal))
        if key not in self._maps:
            comm = modal.comm

            def vec(v) -> np.ndarray:
                return np.concatenate(comm.allgather(v.array_r.copy()))

            c_y, mask, _, _, probe, _ = self._maps[id(modal)]
            ma = self._maps[("ma", id(modal))]
            cols = lambda P: sp.hstack(comm.allgather(P)).toarray()    # noqa: E731 (local columns)
            self._maps[key] = SimpleNamespace(
                c=vec(c_y), ct=vec(self._ct_maps[id(modal)]) if self._ct_full is not None else None,
                mask=vec(mask), Pv=cols(probe.P_val), Pg=cols(probe.P_grad), n_points=probe.n_points,
                Cv=cols(ma.P_val) if ma is not None else None, Cg=cols(ma.P_grad) if ma is not None else None,
                M=gather_aij_dense(modal.M_scheme, comm), K=gather_aij_dense(modal.K, comm))
        return self._maps[key]

    def record_free(self, modal: ModalProjection, times: np.ndarray, eta: np.ndarray, etad: np.ndarray,
                    etadd: np.ndarray) -> None:
        """Rows of a closed-form free phase at ``times`` from the replicated modal states (m x n_t),
        all at once: the rows :meth:`__call__` would give for each (no contact force, zero
        multipliers; the same formulas on m-column maps), plus the XDMF fields at their times."""
        self.set_projection(modal)
        d = self._dense_maps(modal)
        n_t = len(times)
        approach = -(d.c @ eta) - self.gap0
        vball = -(d.c @ etad)
        np_ = d.n_points
        u_v, u_g = d.Pv @ eta, d.Pg @ eta
        if d.Cv is not None:            # mode-acceleration recovery
            u_v, u_g = u_v + d.Cv @ etadd, u_g + d.Cg @ etadd
        vals = [np.moveaxis(x.reshape(np_, 3, n_t), -1, 0) for x in (u_v, d.Pv @ etad, d.Pv @ etadd)]
        grads = np.moveaxis(u_g.reshape(np_, 3, 3, n_t), -1, 0)               # (n_t, points, 3, 3)
        ke = 0.5 * np.einsum("it,it->t", etad, d.M @ etad)
        vb = d.mask[:, None] * etad
        ke_ball = 0.5 * np.einsum("it,it->t", vb, d.M @ vb)
        se = 0.5 * np.einsum("it,it->t", eta, d.K @ eta)
        zero = np.zeros(n_t)
        cols = [times, zero, approach, zero, vball, *self.probe_columns(*vals, grads), self.sym * ke_ball, self.sym * ke, self.sym * se, self.sym * (ke + se)]
        if self.friction:
            # no friction while apart: the cumulative work stays at its value (see __call__)
            self._fw_base += self._fw_last
            self._fw_last = 0.0
            cols += [zero, d.ct @ etad, np.full(n_t, self.sym * self._fw_base)]
        self.rows.extend(np.column_stack(cols).tolist())
        lo, hi = modal.Phi.getOwnershipRangeColumn()
        while self._next_field < len(self.field_times):
            k = int(np.searchsorted(times, self.field_times[self._next_field] - 1e-15))
            if k >= n_t:
                break
            x = modal.create_vector()
            x.array[:] = eta[lo:hi, k]
            u = modal.expand(x)
            self.fields.append((float(times[k]), u.array_r.copy()))
            u.destroy()
            x.destroy()
            self._next_field += 1

    def __call__(self, st) -> None:
        if self.time_offset:
            st = dataclasses.replace(st, t=st.t + self.time_offset)
        n = len(self.fields)
        super().__call__(st)
        for i in range(n, len(self.fields)):
            t, arr = self.fields[i]
            x = self.proj.create_vector()
            x.array[:] = arr
            u = self.proj.expand(x)
            self.fields[i] = (t, u.array_r.copy())
            u.destroy()
            x.destroy()


# --- the run -------------------------------------------------------------------------------------
def reduced_plan(scene: Scene, plan: Plan) -> tuple[Scene, Plan, float, list[str]]:
    """The scene and plan of a reduced run: the contact zone shrunk to ``REDUCED_ZONE_FACTOR``
    a_max (unless the scene sets ``model.zone_radius``); the candidate radius (m); notes saying
    so. A ``full`` run with ``--set model.zone_radius=<the same>`` meshes the same mesh."""
    a = plan.hertz.a_max
    notes = []
    if scene.model.zone_radius is None:
        # the candidates plus 3 contact elements (coarse meshes: h_contact > a_max / 4)
        zone = max(REDUCED_ZONE_FACTOR * a, REDUCED_CANDIDATE_FACTOR * a + 3.0 * plan.h_contact)
        scene = scene.with_value("model.zone_radius", zone)
        plan = make_plan(scene)
        notes.append(f"contact zone radius {zone * 1e3:.4g} mm = {zone / a:.3g} a_max (reduced methods' "
                     f"default; full on the same mesh: --set model.zone_radius={zone!r})")
    radius = min(REDUCED_CANDIDATE_FACTOR * a, plan.zone_radius - 2.0 * plan.h_contact)
    if radius < 1.2 * a:
        raise InputError(f"model.zone_radius = {plan.zone_radius:g} m: too small for the contact candidates "
                         f"(needs at least {1.2 * a + 2.0 * plan.h_contact:g} m = 1.2 a_max + 2 h_contact)")
    notes.append(f"contact candidates within {radius * 1e3:.4g} mm ({radius / a:.3g} a_max) of the contact axis "
                 f"(full with the same candidates: -candidate_radius {radius!r}); "
                 f"f_cut {plan.f_cut / 1e3:.4g} kHz ({plan.f_cut * plan.hertz.contact_time:.3g} / t_c), "
                 f"dt_contact {plan.dt_contact * 1e6:.4g} us (t_c / {plan.hertz.contact_time / plan.dt_contact:.3g}), "
                 f"dt_free {plan.dt_free * 1e6:.4g} us")
    return scene, plan, radius, notes


def build_reduced_model(model: FEModel, kind: str, *, f_cut: Optional[float], n_modes: Optional[int],
                        remedy: str = "interface", augment: tuple[str, ...] = ()) -> ReducedModel:
    """The reduced model of ``model`` for a zone description ``kind`` ("nodal" or "nmm"), its modes
    augmented by the zone-motion patterns ``augment`` (:func:`millimpact.reduction.reduce_model`)."""
    part = partition_dofs(model)
    if kind == "nmm":
        zone = create_nmm_zone(model, part, remedy=remedy).basis
    else:
        zone = create_nodal_zone_basis(model, part)
    return reduce_model(model, zone, f_cut=f_cut, n_modes=n_modes, partition=part, augment=augment)


def reduced_system(red: ReducedModel, contact: ContactSet) -> integrators.LinearDynamics:
    """The contact dynamics of a reduced model: ``(M_r, K_r, B T, g0)``; the contact coordinates
    (made massless by mass redistribution) are those whose basis vectors touch the contact dofs."""
    B_r = red.project_rows(contact.B)
    contact_coords = red.reduced_dofs(contact.contact_dofs)
    q0 = red.M.getOwnershipRange()[0]
    boundary = np.concatenate([b.qb for b in red.bodies]) if red.bodies else np.zeros(0, np.int64)
    n_shared = red.comm.allreduce(int(np.count_nonzero(np.isin(contact_coords + q0, boundary))))
    if n_shared and red.comm.rank == 0:
        # their mass rows carry the dense Craig-Bampton couplings: mass redistribution would
        # spread their mass over the interface and the modes
        log.warning("%d contact coordinates lie on the zone/region interface: the contact candidates "
                    "reach the zone boundary; enlarge model.zone_radius", n_shared)
    return integrators.LinearDynamics(M=red.M, K=red.K, B=B_r, g0=contact.g0,
                                      fixed_dofs=np.zeros(0, dtype=np.int32), contact_dofs=contact_coords,
                                      T=red.project_rows(contact.T) if contact.T is not None else None,
                                      friction=red.model.scene.contact.friction)


def initial_state(red: ReducedModel, scene: Scene) -> tuple[PETSc.Vec, PETSc.Vec]:
    """(q0, qdot0): at rest except the ball's arrival velocity (projected exactly: a rigid motion
    lies in range(T))."""
    v0 = red.model.ball_velocity(scene.impact.velocity)
    qd0 = red.project_state(v0)
    v0.destroy()
    return red.create_vector(), qd0


def integrate_reduced(red: ReducedModel, system: integrators.LinearDynamics, q0: PETSc.Vec, qd0: PETSc.Vec,
                      contact: ContactSet, plan: Plan, t_end: float, rec: ReducedRecorder, *,
                      integrator: str = "newmark-mr", options: Optional[dict] = None, progress: bool = False,
                      free_phase: str = "modal", f_free: Optional[float] = None,
                      min_span: Optional[float] = None) -> dict[str, Any]:
    """Integrate a reduced model over [0, t_end], feeding ``rec``.

    ``free_phase = "step"``: the integrator all the way. ``"modal"`` (default): the integrator
    while the bodies touch; once they have separated, the free vibration is the closed-form sum
    of the free-vibration modes up to ``f_free`` (Hz; :func:`compute_free_modes`), sampled on the
    integrator's free-step grid; if a gap is predicted to come back within the plan's initial gap
    (a second impact), the modal state at the grid point before is handed back to the integrator.
    The energy of the state above ``f_free`` at each switch is reported (it is dropped).
    Returns a dict: ``stats`` (summed integrator statistics), ``segments`` [(kind, t0, t1)], the
    modal energy dropped (J), modal rows, free-mode count and their offline time (s).
    """
    options = dict(options or {})
    t_c = plan.hertz.contact_time
    chunk = max(2.0 * t_c, 20.0 * plan.dt_contact)
    t_first = min(t_end, plan.gap / plan.hertz.speed + FIRST_SPAN_CONTACTS * t_c)
    q, qd = q0, qd0
    t = 0.0
    stats_sum: dict[str, Any] = {}
    segments: list[tuple[str, float, float]] = []
    out: dict[str, Any] = {"modal_rows": 0, "energy_dropped_J": 0.0, "free_modes": 0, "free_modes_time": 0.0,
                           "free_modes_f_max_Hz": f_free, "mode": free_phase}
    modal: Optional[ModalProjection] = None
    comm = red.comm
    while t < t_end * (1 - 1e-12):
        t_stop = t_end if free_phase == "step" else min(t_end, t_first if not segments else t + chunk)
        # between modal phases the steps are short: one step size (one factorization and one
        # contact operator W instead of two; the modal phase takes the free vibration)
        q, qd, lam, st, mass = _run_steps(system, q, qd, t, t_stop, plan, rec, integrator, options, progress,
                                          single_size=free_phase == "modal")
        _add_stats(stats_sum, st)
        segments.append(("step", t, t_stop))
        t = t_stop
        if t >= t_end * (1 - 1e-12) or np.any(lam > 0):
            continue
        if modal is None:
            t0 = time.perf_counter()
            modal = compute_free_modes(red, f_free, mass=mass)
            out["free_modes_time"] = time.perf_counter() - t0
            out["free_modes"] = modal.n_global
            gap_rows = modal.rows_dense(contact.B)
        res = _free_vibration(modal, gap_rows, contact.g0, q, qd, t, t_end, plan, rec,
                              chunk if min_span is None else min_span)
        if res is None:          # a gap closes soon: keep stepping
            continue
        t_new, q_new, qd_new, n_rows, dropped = res
        out["modal_rows"] += n_rows
        out["energy_dropped_J"] += dropped * red.model.sym_factor
        segments.append(("modal", t, t_new))
        t = t_new
        if q_new is not None:
            q, qd = q_new, qd_new
            rec.set_projection(red)
    out["segments"] = segments
    stats_sum["t_end"] = t_end
    out["stats"] = stats_sum
    if comm.rank == 0 and modal is not None:
        log.info("free phase: %d modal rows, %d modes up to %.4g kHz, %.3g J dropped at the switches",
                 out["modal_rows"], out["free_modes"], f_free / 1e3, out["energy_dropped_J"])
    return out


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
        elif k.startswith("n_") or k == "wall_time":
            total[k] = total.get(k, 0) + v
        else:
            total.setdefault(k, v)
    total["n_segments"] = total.get("n_segments", 0) + 1


def _run_steps(system, q, qd, t0: float, t1: float, plan: Plan, rec: ReducedRecorder, integrator: str,
               options: dict, progress: bool, single_size: bool = False):
    """The integrator from (q, qd) at t0 to t1 (steps dt_contact, and dt_free out of contact unless
    ``single_size``); returns the final (q, qd, lambda, stats, mass matrix of the scheme)."""
    schedule = integrators.TimeSchedule(t1 - t0, plan.dt_contact, None if single_size else plan.dt_free)
    rec.time_offset = t0
    last = {}

    def observe(st) -> None:
        last["st"] = st
        if st.step == 0 and t0 > 0:
            return          # the state at t0 is already recorded
        rec(st)

    stats = integrators.integrate(system, q, qd, schedule, method=integrator, observer=observe,
                                  options=dict(options), progress=progress)
    st = last["st"]
    rec.time_offset = 0.0
    return st.u.copy(), st.v.copy(), np.array(st.lam, copy=True), stats, st.mass


def _free_vibration(modal: ModalProjection, gap_rows: np.ndarray, g0: np.ndarray, q: PETSc.Vec, qd: PETSc.Vec,
                    t0: float, t_end: float, plan: Plan, rec: ReducedRecorder, min_span: float):
    """Closed-form free vibration from (q, qd) at t0, recorded on the free-step grid until t_end or
    until a gap is predicted below the plan's initial gap. None if that happens within
    ``min_span`` (stay with the integrator); else (t_stop, q, qd at t_stop or None at t_end, rows,
    energy dropped at the switch in J)."""
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

    def state(tau: np.ndarray):
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
        tau = times[k0:k0 + 2048] - t0
        eta, _, _ = state(tau)
        gaps = g0[:, None] + gap_rows @ eta
        bad = np.nonzero(gaps.min(axis=0) < g_thr)[0]
        if len(bad):
            k_stop = k0 + int(bad[0])
            break
    if k_stop is not None and times[k_stop] - t0 < min_span:
        return None
    last = len(times) if k_stop is None else k_stop        # rows 0 .. last-1
    for k0 in range(0, last, 2048):
        idx = np.arange(k0, min(last, k0 + 2048))
        rec.record_free(modal, times[idx], *state(times[idx] - t0))
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


def run_reduced(scene: Scene, plan: Plan, options: dict[str, Any], progress: bool, method: str) -> RunOutput:
    """One reduced run of a scene (``method`` in :data:`REDUCED_METHODS`)."""
    comm = MPI.COMM_WORLD
    options = dict(options)
    degree, kind = REDUCED_METHODS[method]
    asked = options.pop("degree", None)
    if asked not in (None, "", degree, str(degree)):
        raise InputError(f"--degree {asked}: method {method} uses P{degree} (P1: --method full or traditional)")
    integrator = options.pop("integrator", None) or "newmark-mr"
    t_end = float_option(options, "t_end", scene.time.end)
    n_modes = int_option(options, "modes", scene.model.modes)
    f_cut = float_option(options, "f_cut", plan.f_cut)
    remedy = str(options.pop("nmm_remedy", None) or "interface")
    recovery = str(options.pop("recovery", None) or "mode-acceleration")
    if recovery not in ("mode-acceleration", "modal"):
        raise InputError(f"option recovery = {recovery!r}: choose mode-acceleration or modal")
    augment = str(options.pop("augment", None) or "none")
    augment = tuple(a for a in augment.split(",") if a and a != "none")
    if any(a not in AUGMENTATION_PATTERNS for a in augment):
        raise InputError(f"option augment = {','.join(augment)}: choose from none, {', '.join(AUGMENTATION_PATTERNS)}")
    free_phase = str(options.pop("free_phase", None) or "modal")
    if free_phase not in ("modal", "step"):
        raise InputError(f"option free_phase = {free_phase!r}: choose modal or step")
    free_factor = float_option(options, "free_modes_factor", FREE_MODES_FACTOR)
    min_span = float_option(options, "modal_min_span", None)

    scene, plan, cand_radius, plan_notes = reduced_plan(scene, plan)
    t0 = time.perf_counter()
    md = create_mesh(scene, plan, comm)
    t_mesh = time.perf_counter() - t0
    model = create_fe_model(scene, plan, md, degree)
    contact = create_contact(model, radius=cand_radius)
    t_assemble = time.perf_counter() - t0 - t_mesh
    red = build_reduced_model(model, kind, f_cut=f_cut, n_modes=n_modes, remedy=remedy, augment=augment)
    system = reduced_system(red, contact)
    q0, qd0 = initial_state(red, scene)
    t_reduce = time.perf_counter() - t0 - t_mesh - t_assemble

    t1 = time.perf_counter()
    rec = ReducedRecorder(red, contact, scene.outputs.field_times if scene.outputs.xdmf else (), recovery)
    red.release_recovery()
    t_rows = time.perf_counter() - t1
    t1 = time.perf_counter()
    run = integrate_reduced(red, system, q0, qd0, contact, plan, t_end, rec, integrator=integrator,
                            options=options, progress=progress, free_phase=free_phase,
                            # the free modes follow the output grid (dt_free = 1 / (10 plan.f_cut)),
                            # not a -f_cut option, which sets the reduction's cutoff alone
                            f_free=free_factor * plan.f_cut, min_span=min_span)
    t_integrate = time.perf_counter() - t1
    stats = run["stats"]
    ts = rec.series()
    results = impact_results(ts, scene, stats, integrator)
    results["timings_s"] = {"mesh": t_mesh, "assemble": t_assemble, "reduction_offline": t_reduce,
                            "free_modes_offline": run["free_modes_time"], "output_rows": t_rows,
                            "integrate": t_integrate,
                            "reduction_detail": dict(red.timings)}
    results["free_phase"] = {k: v for k, v in run.items() if k not in ("stats",)}
    rep = red.report()
    model_info = {
        "method": method, "degree": degree, "dofs": model.n_dofs_global, "reduced_dofs": red.n_global,
        "reduction": rep, "contact_candidates": contact.n, "symmetry": plan.symmetry,
        "symmetry_factor": model.sym_factor, "ball_mass_model_kg": model.sym_factor * rec.ball_mass_model,
        "ball_mass_exact_kg": scene.ball.mass, "mesh": md.info.to_json(), "mpi_ranks": comm.size,
        "zone_radius_m": plan.zone_radius, "candidate_radius_m": cand_radius,
    }
    notes = [f"{method}: P{degree}, {model.n_dofs_global} dofs -> {red.n_global} reduced "
             f"({red.n_zone} zone, {red.n_modes} modal), f_cut {f_cut / 1e3:.4g} kHz"
             + (f", {n_modes} modes per body" if n_modes is not None else "")]
    notes.extend(plan_notes)
    for b in red.bodies:
        f = b.frequencies_hz
        f = f[:len(f) - b.n_augmented]
        notes.append(f"  {b.name}: {len(f)} modes" + (f", {f[0] / 1e3:.4g}-{f[-1] / 1e3:.4g} kHz" if len(f) else "")
                     + (f" + {b.n_augmented} augmentation vectors" if b.n_augmented else ""))
    writers = []
    if rec.fields:
        fields = list(rec.fields)
        writers.append(lambda folder: write_fields(model, fields, Path(folder) / "fields.xdmf"))
    return RunOutput(method, ts, results, model_info, extra_writers=writers, notes=notes)


def run_traditional(scene: Scene, plan: Plan, options: dict[str, Any], progress: bool) -> RunOutput:
    """``--method traditional``: the paper's traditional multivariable method (P1, nodal zone)."""
    return run_reduced(scene, plan, dict(options), progress, "traditional")


def run_improved(scene: Scene, plan: Plan, options: dict[str, Any], progress: bool) -> RunOutput:
    """``--method improved``: the paper's improved multivariable method (P2, NMM zone)."""
    return run_reduced(scene, plan, dict(options), progress, "improved")


def run_modal_p2(scene: Scene, plan: Plan, options: dict[str, Any], progress: bool) -> RunOutput:
    """``--method modal-p2``: the traditional reduction of the whole-mesh P2 model."""
    return run_reduced(scene, plan, dict(options), progress, "modal-p2")
