"""Reduced run methods: ``traditional``, ``modal-p2`` and ``improved`` (foundations.md section 4).

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

Options (``options`` keys, also ``-modes 20`` etc. on the command line; :func:`read_reduced_options`):
``modes`` (modes kept per body; wins over the cutoff), ``f_cut`` (Hz; default the plan's
``f_cut = 4 / t_c`` or ``scene.model.f_cut``), ``nmm_remedy`` (improved: interface | anchors),
``augment`` (none | boussinesq | translation, comma-separated: modal truncation augmentation
vectors of each body's region, :mod:`millimpact.reduction`; default none), ``free_phase``
(auto | modal | step: :mod:`.free_phase`; default auto, the cheaper of the two),
``modal_min_span`` (s: a modal phase is taken only if no gap closes within this span, default the
stepping chunk max(2 t_c, 20 dt_contact)),
``free_modes_factor`` (the free phase keeps the free-vibration modes up to this many times the
plan's f_cut, whose dt_free = 1 / (10 f_cut) is its output grid; default 4), ``integrator``
(default newmark-mr), ``recovery`` (mode-acceleration | modal:
:mod:`millimpact.results.reduced_recorder`), ``t_end`` (s). The rest goes to the integrator.

The run (:func:`run_reduced`): the reduced plan (a smaller contact zone), mesh, the full model and
its contact rows, the reduction, the reduced contact dynamics; the time loop with its closed-form
free phase is :mod:`.free_phase`, the observables :class:`millimpact.results.reduced_recorder.ReducedRecorder`.
"""

from __future__ import annotations

import logging
import math
import time
from dataclasses import dataclass, replace
from pathlib import Path
from types import SimpleNamespace
from typing import Any, NamedTuple

import numpy as np
from mpi4py import MPI
from petsc4py import PETSc

from ..console import stage
from ..errors import InputError
from ..fem.contact import ContactSet, create_contact
from ..fem.model import FEModel, create_fe_model
from ..fem.plastic_zones import create_plastic_zone
from ..geometry.builders import BALL_ZONE, BLOCK_ZONE
from ..geometry.mesh import create_mesh, with_whole_bodies_in_zone
from ..integration import integrators
from ..integration.integrators import SeparationStop
from ..integration.solvers import normalize_options, petsc_options
from ..reduction.augmentation import AUGMENTATION_PATTERNS
from ..reduction.craig_bampton import reduce_model
from ..reduction.nmm_zone import create_nmm_zone
from ..reduction.partition import create_nodal_zone_basis, partition_dofs
from ..reduction.plastic_projection import ProjectedPlasticZone
from ..reduction.reduced_model import MASS_FACTORIZATION, ReducedModel
from ..results.dent import plastic_report
from ..results.fields import write_fields
from ..results.output import RunOutput
from ..results.recorder import impact_results
from ..results.reduced_recorder import ReducedRecorder
from ..scene.plan import PLASTIC_ZONE_CAP, PLASTIC_ZONE_MARGIN, Plan, make_plan, size_growth_distance, zone_radius_limit
from ..scene.schema import Scene
from .free_phase import FREE_MODES_FACTOR, FREE_PHASES, integrate_reduced
from .options import float_option, int_option, take

log = logging.getLogger(__name__)

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
#: ``impact_only`` runs end this many Hertz contact times after separation: restitution is read
#: two rows after the last contact row and every other table column is fixed at separation; the
#: margin lets a gap that closes again soon (chatter on a thin plate) be seen as the same impact
IMPACT_QUIET_CONTACTS = 0.1
#: ``impact_only`` runs record the energies every this many rows (and the first and last): the
#: table reads none of them; they stay for the energy-drift check of the results
ENERGY_EVERY_IMPACT_ONLY = 10


def impact_only_stop(plan) -> SeparationStop:
    """The stop of an impact-only run (a contact table's case, a repeated impact): IMPACT_QUIET_CONTACTS
    Hertz contact times after the bodies separate, counted in contact steps."""
    return SeparationStop(math.ceil(IMPACT_QUIET_CONTACTS * plan.hertz.contact_time / plan.dt_contact))


#: method name -> (Lagrange degree, contact-zone basis: nodal unknowns or NMM covers); the
#: one-line descriptions are in :mod:`millimpact.methods.registry`
REDUCED_METHODS = {
    "traditional": (1, "nodal"),
    "modal-p2": (2, "nodal"),
    "improved": (2, "nmm"),
}


class ReducedOptions(NamedTuple):
    """The options of a reduced run (module docstring), read by :func:`read_reduced_options`."""

    degree: int  #: Lagrange degree of the method
    kind: str  #: contact-zone basis: "nodal" or "nmm"
    integrator: str
    t_end: float  #: s
    n_modes: int | None  #: modes per body (wins over f_cut)
    f_cut: float  #: the reduction's cutoff, Hz
    remedy: str  #: NMM null-space remedy
    recovery: str  #: mode-acceleration | modal
    augment: tuple[str, ...]  #: modal truncation augmentation patterns
    free_phase: str  #: auto | modal | step
    free_factor: float  #: free modes up to this many times the plan's f_cut
    min_span: float | None  #: s
    candidate_radius: float | None = None  #: m; None: the reduced plan's (REDUCED_CANDIDATE_FACTOR a_max)


def read_reduced_options(method: str, scene: Scene, plan: Plan, options: dict[str, Any]) -> ReducedOptions:
    """Take a reduced run's own keys out of ``options`` (the rest goes to the integrator); a bad
    value is an :class:`InputError` naming the option."""
    degree, kind = REDUCED_METHODS[method]
    asked = take(options, "degree")
    if asked not in (None, "", degree, str(degree)):
        raise InputError(f"--degree {asked}: method {method} uses P{degree} (P1: --method full or traditional)")
    integrator = take(options, "integrator") or "newmark-mr"
    t_end = float_option(options, "t_end", scene.time.end)
    n_modes = int_option(options, "modes", scene.model.modes)
    f_cut = float_option(options, "f_cut", plan.f_cut)
    remedy = str(take(options, "nmm_remedy") or "interface")
    recovery = str(take(options, "recovery") or "mode-acceleration")
    if recovery not in ("mode-acceleration", "modal"):
        raise InputError(f"option recovery = {recovery!r}: choose mode-acceleration or modal")
    augment = tuple(a for a in str(take(options, "augment") or "none").split(",") if a and a != "none")
    if any(a not in AUGMENTATION_PATTERNS for a in augment):
        raise InputError(f"option augment = {','.join(augment)}: choose from none, {', '.join(AUGMENTATION_PATTERNS)}")
    free_phase = str(take(options, "free_phase") or "auto")
    if free_phase not in FREE_PHASES:
        raise InputError(f"option free_phase = {free_phase!r}: choose {', '.join(FREE_PHASES)}")
    free_factor = float_option(options, "free_modes_factor", FREE_MODES_FACTOR)
    min_span = float_option(options, "modal_min_span", None)
    cand = float_option(options, "candidate_radius", None)
    if cand is not None and not (math.isfinite(cand) and cand > 0):
        raise InputError(f"option candidate_radius = {cand!r}: must be a length > 0 m")
    return ReducedOptions(
        degree,
        kind,
        integrator,
        t_end,
        n_modes,
        f_cut,
        remedy,
        recovery,
        augment,
        free_phase,
        free_factor,
        min_span,
        cand,
    )


def reduced_plan(scene: Scene, plan: Plan) -> tuple[Scene, Plan, float, list[str]]:
    """The scene and plan of a reduced run: the contact zone shrunk to ``REDUCED_ZONE_FACTOR``
    a_max (unless the scene sets ``model.zone_radius``); the candidate radius (m); notes saying
    so. A ``full`` run with ``--set model.zone_radius=<the same>`` meshes the same mesh."""
    a = plan.hertz.a_max
    notes = []
    if scene.model.zone_radius is None:
        # the candidates plus 3 contact elements (coarse meshes: h_contact > a_max / 4) and plus
        # one element of the size the mesh has at the zone's boundary (slow impacts: a_max is small
        # against h_far and the size grows fast beyond fine_radius: the interface cells would reach
        # the candidates; the rig at 0.1 m/s needs 5 a_max); with plastic materials the plastic
        # region with its margin (plan.py PLASTIC_ZONE_MARGIN)
        plastic = PLASTIC_ZONE_MARGIN * plan.plastic_radius
        # a user's fine radius (model.fine_radius) lies inside the zone, as the plan requires
        zone = max(
            REDUCED_ZONE_FACTOR * a,
            plastic,
            REDUCED_CANDIDATE_FACTOR * a + 3.0 * plan.h_contact,
            scene.model.fine_radius or 0.0,
        )
        for _ in range(30):  # a fixed point: the boundary size grows with the zone, but slower
            zone = max(zone, REDUCED_CANDIDATE_FACTOR * a + boundary_element_size(plan, zone, scene.model.fine_radius))
        if zone == plastic:  # as the plan: no more than the bodies allow
            zone = min(zone, PLASTIC_ZONE_CAP * zone_radius_limit(scene))
        scene = scene.with_value("model.zone_radius", zone)
        c_p = plan.plastic_radius
        # the plan's whole plastic bodies were chosen on its own zone; the reduced zone set here is
        # not the user's, so the choice (and its reason) stays
        whole = plan.plastic_whole
        why = tuple((k, v) for k, v in plan.reasons if k.startswith("plastic_whole_"))
        plan = make_plan(scene)
        if whole:
            plan = replace(plan, plastic_whole=whole, reasons=plan.reasons + why)
        notes.append(
            f"contact zone radius {zone * 1e3:.4g} mm = {zone / a:.3g} a_max (reduced methods' default"
            + (
                f", {zone / c_p:.3g} x the predicted plastic radius {c_p * 1e3:.3g} mm"
                if c_p > 0 and zone >= 0.9 * plastic
                else ""
            )
            + f"; full on the same mesh: --set model.zone_radius={zone!r})"
        )
    radius = min(REDUCED_CANDIDATE_FACTOR * a, min(plan.zone_radius, plan.ball_zone) - 2.0 * plan.h_contact)
    if radius < 1.2 * a:
        raise InputError(
            f"model.zone_radius = {plan.zone_radius:g} m: too small for the contact candidates "
            f"(needs at least {1.2 * a + 2.0 * plan.h_contact:g} m = 1.2 a_max + 2 h_contact)"
        )
    notes.append(
        f"contact candidates within {radius * 1e3:.4g} mm ({radius / a:.3g} a_max) of the contact axis "
        f"(full with the same candidates: -candidate_radius {radius!r}); "
        f"f_cut {plan.f_cut / 1e3:.4g} kHz ({plan.f_cut * plan.hertz.contact_time:.3g} / t_c), "
        f"dt_contact {plan.dt_contact * 1e6:.4g} us (t_c / {plan.hertz.contact_time / plan.dt_contact:.3g}), "
        f"dt_free {plan.dt_free * 1e6:.4g} us"
    )
    return scene, plan, radius, notes


def boundary_element_size(plan: Plan, zone: float, fine_radius: float | None = None) -> float:
    """The element size (m) the mesh has at distance ``zone`` from the contact point when the zone
    radius is ``zone``: h_contact within the fine radius (``fine_radius``, the scene's
    ``model.fine_radius``; None: the plan's default 1.5 a_max), then the linear growth to h_far over
    :func:`millimpact.scene.plan.size_growth_distance` (:mod:`millimpact.geometry.builders`)."""
    fine = min(fine_radius if fine_radius is not None else 1.5 * plan.hertz.a_max, zone)
    grow = (
        (plan.h_far - plan.h_contact)
        * max(0.0, zone - fine)
        / size_growth_distance(plan.h_contact, plan.h_far, zone, plan.h_ball > 0)
    )
    return min(plan.h_far, plan.h_contact + grow)


def build_reduced_model(
    model: FEModel,
    kind: str,
    *,
    f_cut: float | None,
    n_modes: int | None,
    remedy: str = "interface",
    augment: tuple[str, ...] = (),
    keep_away=None,
) -> ReducedModel:
    """The reduced model of ``model`` for a zone description ``kind`` ("nodal" or "nmm"), its modes
    augmented by the zone-motion patterns ``augment`` (:func:`millimpact.reduction.reduce_model`);
    ``keep_away``: points (the gauges) a substructured body's cuts stay away from."""
    part = partition_dofs(model)
    if kind == "nmm":
        zone = create_nmm_zone(model, part, remedy=remedy).basis
    else:
        zone = create_nodal_zone_basis(model, part)
    return reduce_model(model, zone, f_cut=f_cut, n_modes=n_modes, partition=part, augment=augment, keep_away=keep_away)


def reduced_system(red: ReducedModel, contact: ContactSet, friction: float) -> integrators.LinearDynamics:
    """The contact dynamics of a reduced model: ``(M_r, K_r, B T, g0)``, with the Coulomb
    coefficient ``friction``; the contact coordinates (made massless by mass redistribution) are
    those whose basis vectors touch the contact dofs."""
    B_r = red.project_rows(contact.B)
    contact_coords = red.reduced_dofs(contact.contact_dofs)
    q0 = red.M.getOwnershipRange()[0]
    boundary = np.concatenate([b.qb for b in red.bodies]) if red.bodies else np.zeros(0, np.int64)
    n_shared = red.comm.allreduce(int(np.count_nonzero(np.isin(contact_coords + q0, boundary))))
    if n_shared and red.comm.rank == 0:
        # their mass rows carry the dense Craig-Bampton couplings: mass redistribution would
        # spread their mass over the interface and the modes
        log.warning(
            "%d contact coordinates lie on the zone/region interface: the contact candidates "
            "reach the zone boundary; enlarge model.zone_radius",
            n_shared,
        )
    return integrators.LinearDynamics(
        M=red.M,
        K=red.K,
        B=B_r,
        g0=contact.g0,
        fixed_dofs=np.zeros(0, dtype=np.int32),
        contact_dofs=contact_coords,
        T=red.project_rows(contact.T) if contact.T is not None else None,
        friction=friction,
        mass_solver=dict(MASS_FACTORIZATION),
    )


def initial_state(red: ReducedModel, velocity) -> tuple[PETSc.Vec, PETSc.Vec]:
    """(q0, qdot0): at rest except the ball's arrival ``velocity`` (m/s; projected exactly: a
    rigid motion lies in range(T))."""
    v0 = red.model.ball_velocity(velocity)
    qd0 = red.project_state(v0)
    v0.destroy()
    return red.create_vector(), qd0


def refuse_plastic(method: str, plan: Plan) -> None:
    """For a method without plasticity (hertz-modal: a rigid ball on the block's modes), a plastic
    material is one line naming the way out."""
    plastic = [
        name
        for name, mat in (("ball.material", plan.ball.material), ("the struck body's material", plan.target))
        if mat.plastic
    ]
    if plastic:
        raise InputError(
            f"--method {method}: {' and '.join(plastic)} yield (yield_stress / flow_curve); --method "
            f"{method} is elastic; use --method improved, traditional or full"
        )


@dataclass
class ReducedSetup:
    """What the impacts on one mesh share (a run, or the cases of a contact table): the reduced
    plan's scene and plan, the options, the mesh, the full model, its contact rows and the
    reduction (its offline cost, s, in ``timings``)."""

    method: str
    scene: Scene
    plan: Plan
    opt: ReducedOptions
    md: Any
    model: FEModel
    contact: ContactSet
    red: ReducedModel
    cand_radius: float
    notes: list[str]
    timings: dict[str, float]
    #: the contact dynamics shared by the impacts (``share_operators``): their step factorizations
    #: and contact operators W are kept between impacts of the same time step
    system: integrators.LinearDynamics | None = None


def build_reduced_setup(
    scene: Scene,
    plan: Plan,
    options: dict[str, Any],
    method: str,
    comm: MPI.Comm = MPI.COMM_WORLD,
    share_operators: bool = False,
) -> ReducedSetup:
    """The offline part of a reduced run: reduced plan, mesh, model, contact rows, reduction
    (``options``: the run's options; the reduced run's own keys are taken out of it).
    ``share_operators``: one contact dynamics for every impact on this setup, whose factorized
    step operators are reused by impacts with the same time step (a contact table's band)."""
    opt = read_reduced_options(method, scene, plan, options)
    scene, plan, cand_radius, plan_notes = reduced_plan(scene, plan)
    if opt.candidate_radius is not None:
        # a plastic contact wider than the Hertz estimate (a soft block) needs more candidates: the
        # run's saturation warning names this option
        room = min(plan.zone_radius, plan.ball_zone) - 2.0 * plan.h_contact
        if opt.candidate_radius > room:
            raise InputError(
                f"option candidate_radius = {opt.candidate_radius!r}: must be at most the contact zone's "
                f"radius less 2 h_contact, {room:.4g} m (or --set model.zone_radius larger)"
            )
        cand_radius = opt.candidate_radius
        plan_notes = plan_notes + [f"contact candidates within {cand_radius * 1e3:.4g} mm (-candidate_radius)"]
    t0 = time.perf_counter()
    with stage("meshing (gmsh, or the mesh cache)"):
        md = with_whole_bodies_in_zone(create_mesh(scene, plan, comm), plan.plastic_whole)
    t_mesh = time.perf_counter() - t0
    with stage(f"assembling the P{opt.degree} model and the contact rows"):
        model = create_fe_model(md, plan, opt.degree)
        contact = create_contact(model, plan, radius=cand_radius)
    t_assemble = time.perf_counter() - t0 - t_mesh
    with stage("reduction (SLEPc modes, Craig-Bampton)"), reduction_solver_options(options):
        red = build_reduced_model(
            model,
            opt.kind,
            f_cut=opt.f_cut,
            n_modes=opt.n_modes,
            remedy=opt.remedy,
            augment=opt.augment,
            keep_away=[g.point for g in plan.probes.gauges],
        )
    t_reduce = time.perf_counter() - t0 - t_mesh - t_assemble
    system = None
    if share_operators:
        system = reduced_system(red, contact, plan.friction)
        system.operator_cache = {}
    return ReducedSetup(
        method,
        scene,
        plan,
        opt,
        md,
        model,
        contact,
        red,
        cand_radius,
        plan_notes,
        {"mesh": t_mesh, "assemble": t_assemble, "reduction_offline": t_reduce},
        system,
    )


def run_reduced(scene: Scene, plan: Plan, options: dict[str, Any], progress: bool, method: str) -> RunOutput:
    """One reduced run of a scene (``method`` in :data:`REDUCED_METHODS`)."""
    options = dict(options)
    setup = build_reduced_setup(scene, plan, options, method)
    return run_reduced_case(setup, setup.scene, setup.plan, options, progress, release=True)


def run_reduced_case(
    setup: ReducedSetup,
    scene: Scene,
    plan: Plan,
    options: dict[str, Any],
    progress: bool,
    t_end: float | None = None,
    release: bool = False,
    impact_only: bool = False,
) -> RunOutput:
    """One impact on a built reduced model: ``scene``/``plan`` (the same mesh sizes, zone and
    gap as the setup's; their own velocity, time steps and probes) from rest but the ball's
    velocity to ``t_end`` (default the setup's). A fresh plastic zone per impact. ``release``
    frees the reduction's recovery data once the recorder has it (a single run).

    ``impact_only`` (contact tables): the run ends IMPACT_QUIET_CONTACTS t_c after the bodies
    separate (:class:`millimpact.integration.integrators.SeparationStop`), at ``t_end`` at the
    latest, and the energies are recorded every ENERGY_EVERY_IMPACT_ONLY rows (and on the first
    and last; :attr:`millimpact.results.recorder.Recorder.energy_every`)."""
    with reduction_solver_options(options):  # the mass projection, the free modes, the output rows
        return _run_reduced_case(setup, scene, plan, options, progress, t_end, release, impact_only)


def reduction_solver_options(options: dict[str, Any]):
    """The run's options for the reduction's solvers (``-impact_reduction_*``: the K_ii
    factorizations, eigensolvers, inertia counts, free modes, mass projection) in PETSc's options
    database while they are set up (:func:`~millimpact.integration.solvers.petsc_options`:
    the reduction's objects read the database, not the run's options)."""
    return petsc_options({}, {k: v for k, v in normalize_options(options).items() if k.startswith("reduction_")})


def _run_reduced_case(
    setup: ReducedSetup,
    scene: Scene,
    plan: Plan,
    options: dict[str, Any],
    progress: bool,
    t_end: float | None,
    release: bool,
    impact_only: bool,
) -> RunOutput:
    comm = setup.model.V.mesh.comm
    opt, model, contact, red, method = setup.opt, setup.model, setup.contact, setup.red, setup.method
    t_end = opt.t_end if t_end is None else t_end
    t0 = time.perf_counter()
    system = setup.system if setup.system is not None else reduced_system(red, contact, plan.friction)
    zone = create_plastic_zone(model, [(BALL_ZONE, plan.ball.material), (BLOCK_ZONE, plan.target)], plan.strain)
    plastic = ProjectedPlasticZone(zone, red) if zone is not None else None
    system.plastic = plastic
    free_phase = opt.free_phase
    q0, qd0 = initial_state(red, plan.velocity)
    t_case = time.perf_counter() - t0

    t1 = time.perf_counter()
    rec = ReducedRecorder(
        red, contact, plan.probes, scene.outputs.field_times if scene.outputs.xdmf else (), opt.recovery, plastic
    )
    if release:
        red.release_recovery()
    stop = None
    if impact_only:
        rec.energy_every = ENERGY_EVERY_IMPACT_ONLY
        stop = impact_only_stop(plan)
    t_rows = time.perf_counter() - t1
    t1 = time.perf_counter()
    with stage(f"time loop to {t_end * 1e3:.3g} ms ({opt.integrator}, free phase {free_phase})"):
        run = integrate_reduced(
            red,
            system,
            q0,
            qd0,
            contact,
            plan,
            t_end,
            rec,
            integrator=opt.integrator,
            options=dict(options),
            progress=progress,
            free_phase=free_phase,
            # the free modes follow the output grid (dt_free = 1 / (10 plan.f_cut)),
            # not a -f_cut option, which sets the reduction's cutoff alone
            f_free=opt.free_factor * plan.f_cut,
            min_span=opt.min_span,
            stop=stop,
        )
    t_integrate = time.perf_counter() - t1
    ts = rec.series()
    results = impact_results(ts, plan.normal_speed, plan.probes.gauge_names, run["stats"], opt.integrator)
    results["timings_s"] = {
        **setup.timings,
        "reduction_offline": setup.timings["reduction_offline"] + t_case,
        "free_modes_offline": run["free_modes_time"],
        "output_rows": t_rows,
        "integrate": t_integrate,
        "reduction_detail": dict(red.timings),
    }
    results["free_phase"] = {k: v for k, v in run.items() if k not in ("stats",)}
    model_info = {
        "method": method,
        "degree": opt.degree,
        "dofs": model.n_dofs_global,
        "reduced_dofs": red.n_global,
        "reduction": red.report(),
        "contact_candidates": contact.n,
        "symmetry": plan.symmetry,
        "symmetry_factor": model.sym_factor,
        "ball_mass_model_kg": model.sym_factor * rec.ball_mass_model,
        "ball_mass_exact_kg": plan.ball.mass,
        "mesh": setup.md.info.to_json(),
        "mpi_ranks": comm.size,
        "zone_radius_m": plan.zone_radius,
        "candidate_radius_m": setup.cand_radius,
    }
    notes = reduced_notes(method, opt, model, red) + setup.notes + mode_notes(red)
    notes += candidate_notes(ts, setup.cand_radius, plan, results)
    writers = []
    if zone is not None:
        keys, more, writer = plastic_report(model, zone, plan, SimpleNamespace(**run["stats"]), reduced=red)
        results.update(keys)
        notes += more
        writers.append(writer)
    if rec.fields:
        fields = list(rec.fields)
        writers.append(lambda folder: write_fields(model, fields, Path(folder) / "fields.xdmf", rec.plastic_fields))
    if plastic is not None:
        plastic.destroy()
    return RunOutput(method, ts, results, model_info, extra_writers=writers, notes=notes)


#: the contact reached the candidates' edge when its radius came within this many contact
#: elements of the candidate radius (the discrete radius is the outermost node in contact)
CANDIDATE_EDGE_ELEMENTS = 1.0


def candidate_notes(ts, cand_radius: float, plan: Plan, results: dict) -> list[str]:
    """A warning when the contact's radius reached the candidates' edge, where the contact could
    not grow further (a plastic contact wider than the Hertz estimate): the run's contact is then
    too small and its restitution too high. Sets ``results["contact_candidates_saturated"]``."""
    radius = ts["contact_radius_m"]
    reached = float(max(radius)) if len(radius) else 0.0
    saturated = reached >= cand_radius - CANDIDATE_EDGE_ELEMENTS * plan.h_contact
    results["contact_candidates_saturated"] = bool(saturated)
    results["contact_radius_max_m"] = reached
    if not saturated:
        return []
    return [
        f"WARNING: the contact reached the candidates' edge ({reached * 1e3:.4g} mm of {cand_radius * 1e3:.4g} mm): "
        f"rerun with -candidate_radius {1.3 * cand_radius!r} (and --set model.zone_radius="
        f"{max(plan.zone_radius, 1.3 * cand_radius + 3.0 * plan.h_contact)!r} if the zone is too small)"
    ]


def reduced_notes(method: str, opt: ReducedOptions, model: FEModel, red: ReducedModel) -> list[str]:
    """The run's first note: the method, the full and reduced sizes, the cutoff."""
    return [
        f"{method}: P{opt.degree}, {model.n_dofs_global} dofs -> {red.n_global} reduced "
        f"({red.n_zone} zone, {red.n_modes} modal), f_cut {opt.f_cut / 1e3:.4g} kHz"
        + (f", {opt.n_modes} modes per body" if opt.n_modes is not None else "")
    ]


def mode_notes(red: ReducedModel) -> list[str]:
    """One note per body: its modes' count and frequency band, and its augmentation vectors."""
    notes = []
    for b in red.bodies:
        f = b.frequencies_hz
        f = f[: len(f) - b.n_augmented - b.n_patterns]
        notes.append(
            f"  {b.name}: {len(f)} modes"
            + (f", {f[0] / 1e3:.4g}-{f[-1] / 1e3:.4g} kHz" if len(f) else "")
            + (f" + {b.n_augmented} augmentation vectors" if b.n_augmented else "")
            + (
                f" + {b.n_patterns} zone-interface pattern vectors (gauges recovered in the slabs' Ritz space)"
                if b.n_patterns
                else ""
            )
            + (" (constraint and fixed-interface modes from the reduction cache)" if b.from_cache else "")
        )
    return notes


def run_traditional(scene: Scene, plan: Plan, options: dict[str, Any], progress: bool) -> RunOutput:
    """``--method traditional``: the paper's traditional multivariable method (P1, nodal zone)."""
    return run_reduced(scene, plan, dict(options), progress, "traditional")


def run_improved(scene: Scene, plan: Plan, options: dict[str, Any], progress: bool) -> RunOutput:
    """``--method improved``: the paper's improved multivariable method (P2, NMM zone)."""
    return run_reduced(scene, plan, dict(options), progress, "improved")


def run_modal_p2(scene: Scene, plan: Plan, options: dict[str, Any], progress: bool) -> RunOutput:
    """``--method modal-p2``: the traditional reduction of the whole-mesh P2 model."""
    return run_reduced(scene, plan, dict(options), progress, "modal-p2")
