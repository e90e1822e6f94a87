"""``full``: the unreduced finite-element reference.

Both bodies elastic (P1 or P2), the block clamped, the ball free with its arrival velocity a small
gap before contact; node-to-surface Lagrange-multiplier contact (:mod:`millimpact.fem.contact`),
time integration by :mod:`millimpact.integration` (default Newmark with mass redistribution),
linear solves by PETSc (:mod:`millimpact.integration.solvers`); rows by
:class:`millimpact.results.recorder.Recorder`.
"""

from __future__ import annotations

import logging
import time
from typing import Any

from mpi4py import MPI

from ..console import stage
from ..errors import InputError
from ..fem.contact import create_contact
from ..fem.model import create_fe_model
from ..fem.plastic_zones import create_plastic_zone
from ..geometry.builders import BALL_REGION, BALL_ZONE, BLOCK_REGION, BLOCK_ZONE
from ..geometry.mesh import create_mesh
from ..integration import integrators
from ..results.dent import plastic_report
from ..results.fields import write_fields
from ..results.output import RunOutput
from ..results.recorder import Recorder, impact_results
from ..scene.plan import P1_EXPECTED_ERROR, P2_REMEDY, Plan
from ..scene.schema import Scene
from .options import take

log = logging.getLogger(__name__)


def plastic_cells(plan: Plan) -> list[tuple[int, Any]]:
    """(cell tag, material) of the plastic cells: each body's contact zone, and its region too where
    the plan makes the body plastic whole (``plan.plastic_whole``: its plastic region does not fit
    the zone; the full method meshes every cell, so nothing is truncated)."""
    cells = [(BALL_ZONE, plan.ball.material), (BLOCK_ZONE, plan.target)]
    if "ball" in plan.plastic_whole:
        cells.append((BALL_REGION, plan.ball.material))
    if "struck" in plan.plastic_whole:
        cells.append((BLOCK_REGION, plan.target))
    return cells


def run_fe(scene: Scene, plan: Plan, options: dict[str, Any], progress: bool, method: str = "full") -> RunOutput:
    """The full FE model of a scene, integrated over the scene's time span.

    ``options["candidate_radius"]`` (m, default the contact module's 2.5 a_max): contact candidates
    within this distance of the contact axis; a reduced run's (``candidate_radius_m`` of its model
    info) makes this run the very model that run reduces (same massless contact nodes).

    The method's own settings are popped from ``options`` (:func:`millimpact.methods.run.compute`
    reports what is left and unused): a caller that reuses a dict passes a copy."""
    comm = MPI.COMM_WORLD
    t0 = time.perf_counter()
    degree = int(take(options, "degree") or plan.degree)
    integrator = take(options, "integrator") or "newmark-mr"
    t_end = float(take(options, "t_end") or scene.time.end)
    radius = take(options, "candidate_radius")
    try:
        radius = float(radius) if radius not in (None, "") else None
    except (TypeError, ValueError):
        raise InputError(f"option candidate_radius = {radius!r}: must be a length in m") from None
    if radius is not None and not radius > 0:
        raise InputError(f"option candidate_radius = {radius!r}: must be > 0 m")
    with stage("meshing (gmsh, or the mesh cache)"):
        md = create_mesh(scene, plan, comm)
    t_mesh = time.perf_counter() - t0
    with stage(f"assembling the P{degree} model and the contact rows"):
        model = create_fe_model(md, plan, degree)
        contact = create_contact(model, plan, radius=radius)
    t_assemble = time.perf_counter() - t0 - t_mesh
    plastic = create_plastic_zone(model, plastic_cells(plan), plan.strain)
    system = integrators.LinearDynamics(
        M=model.M,
        K=model.K,
        B=contact.B,
        g0=contact.g0,
        fixed_dofs=model.fixed_dofs,
        contact_dofs=contact.contact_dofs,
        T=contact.T,
        friction=plan.friction,
        plastic=plastic,
    )
    u0 = model.M.createVecRight()
    u0.set(0.0)
    v0 = model.ball_velocity(plan.velocity)
    rec = Recorder(model, contact, plan.probes, scene.outputs.field_times if scene.outputs.xdmf else (), plastic)
    schedule = integrators.TimeSchedule(t_end, plan.dt_contact, plan.dt_free)
    with stage(f"time loop to {t_end * 1e3:.3g} ms ({integrator})"):
        stats = integrators.integrate(
            system, u0, v0, schedule, method=integrator, observer=rec, options=options, progress=progress
        )
    ts = rec.series()
    wall = time.perf_counter() - t0

    results = impact_results(ts, plan.normal_speed, plan.probes.gauge_names, stats, integrator)
    results["timings_s"] = {"mesh": t_mesh, "assemble": t_assemble, "integrate": wall - t_mesh - t_assemble}
    info = md.info
    model_info = {
        "method": method,
        "degree": degree,
        "dofs": model.n_dofs_global,
        "contact_candidates": contact.n,
        "symmetry": plan.symmetry,
        "symmetry_factor": model.sym_factor,
        "ball_mass_model_kg": model.sym_factor * rec.ball_mass_model,
        "ball_mass_exact_kg": plan.ball.mass,
        "ball_density_scale": model.extra["ball_density_scale"],
        "mesh": info.__dict__ if hasattr(info, "__dict__") else str(info),
        "mpi_ranks": comm.size,
    }
    notes = [f"full FE, P{degree}, {model.n_dofs_global} dofs, {plan.symmetry} model, integrator {integrator}"]
    if degree == 1:
        notes.append(P1_ERROR_NOTE)
    writers = []
    if plastic is not None:
        keys, more, writer = plastic_report(model, plastic, plan, stats)
        results.update(keys)
        notes += more
        writers.append(writer)
    fields = rec.fields
    if fields:
        writers.append(lambda folder: write_fields(model, fields, folder / "fields.xdmf", rec.plastic_fields))
    return RunOutput(method, ts, results, model_info, extra_writers=writers, notes=notes)


#: what a P1 run should expect, from the measured convergence (docs/validation.md; benchmarks/
#: full_hertz.py and reduced_vs_full.py): P1 is too stiff by a few percent whatever h_contact, the
#: error sits in the far mesh; P2 of the same mesh is within ~1 % of Hertz
P1_ERROR_NOTE = (
    f"expected accuracy: P1 is too stiff, {P1_EXPECTED_ERROR} on the half-space (+2.8 % against P2 "
    f"on the rig), and refining h_contact hardly helps; {P2_REMEDY} (docs: validation)"
)


def run(scene: Scene, plan: Plan, options: dict[str, Any], progress: bool) -> RunOutput:
    """``--method full`` (the registry's entry point)."""
    return run_fe(scene, plan, dict(options), progress)
