"""One run of a scene by a named method: computes, then writes the output contract.

Output contract (``--out DIR``): ``summary.json`` (scene, method, peak_contact_force_N,
contact_duration_s, max_approach_m, restitution, hertz, wall_time_s, model, plan),
``timeseries.csv`` (header of names with units), ``timeseries.h5``, ``scene.toml``, figures
``*.png`` and, for FE methods, XDMF fields.
"""

from __future__ import annotations

import logging
import os
import time
from pathlib import Path
from typing import Any

from ..console import stage
from ..errors import InputError
from ..integration.solvers import reset_option_usage, unused_options
from ..results import plots
from ..results.output import RunOutput
from ..results.output_folder import OutputFolder, claim_output
from ..results.reference import write_reference
from ..results.timeseries import contact_metrics, write_hdf5, write_summary
from ..scene.plan import Plan, elastic_limit_note, make_plan
from ..scene.schema import Scene
from ..scene.toml_io import dump_scene, scene_to_dict
from ..theory.hertz import HertzImpact, hertz_history
from .memory import check_memory, memory_check_applies
from .registry import method_runner

log = logging.getLogger(__name__)


def hertz_summary(h: HertzImpact) -> dict[str, float]:
    """The Hertz values of a scene, SI, for ``summary.json``."""
    return {
        "delta_max_m": h.delta_max,
        "F_max_N": h.force_max,
        "t_c_s": h.contact_time,
        "a_max_m": h.a_max,
        "p0_Pa": h.p0,
        "tau_max_Pa": h.tau_max,
        "tau_depth_m": h.tau_depth,
        "impact_energy_J": h.energy,
        "effective_modulus_Pa": h.e_star,
        "mass_kg": h.mass,
        "normal_speed_m_s": h.speed,
    }


def compute(scene: Scene, method: str, options: dict | None = None, progress: bool = False) -> tuple[RunOutput, Plan]:
    """Run ``scene`` with ``method`` (a name of :mod:`millimpact.methods.registry`); returns the
    output and the plan it used."""
    runner = method_runner(method)
    plan = make_plan(scene)
    refuse_if_too_large(scene, plan, method, options)  # before meshing: one line, exit 2
    left = dict(options or {})  # the runner pops its own settings; the rest are solver options
    reset_option_usage()
    out = runner(scene, plan, left, progress)
    note = elastic_limit_note(plan)
    if note:
        out.notes.append(note)
    unused = unused_options(left)
    if unused:
        out.notes.append(
            "warning: options that nothing in this run used (misspelled, or for a solver "
            f"method {method} does not have): {', '.join('-' + k for k in unused)}"
        )
    return out, plan


def refuse_if_too_large(scene: Scene, plan: Plan, method: str, options: dict | None = None) -> None:
    """Raise :class:`InputError` on every rank when the run's estimated peak memory (per rank, times
    the ranks on this node) does not fit in the available memory (:mod:`.memory`); rank 0 decides."""
    from mpi4py import MPI

    if not memory_check_applies(method):  # before any collective: hertz runs on a table's rank groups
        return
    comm = MPI.COMM_WORLD  # as the FE methods' (methods/full.py)
    # ranks on this node: from mpirun's environment (no collective needed); without mpirun, one
    on_node = int(os.environ.get("OMPI_COMM_WORLD_LOCAL_SIZE", os.environ.get("MPI_LOCALNRANKS", comm.size)))
    message = None
    if comm.rank == 0:
        try:
            est = check_memory(scene, plan, method, options, ranks=comm.size, ranks_on_node=on_node)
            if est is not None:
                log.info(
                    "estimated peak memory %.3g GB a rank (P%d, ~%d DOFs)", est.per_rank / 1e9, est.degree, est.dofs
                )
        except InputError as exc:
            message = str(exc)
    message = comm.bcast(message, root=0)
    if message:
        raise InputError(message)


def build_summary(scene: Scene, plan: Plan, out: RunOutput, wall: float) -> dict[str, Any]:
    """The ``summary.json`` content."""
    m = contact_metrics(out.series)
    h = plan.hertz
    summary = {
        "scene": scene.name,
        "method": out.method,
        "peak_contact_force_N": m["peak_contact_force_N"],
        "contact_duration_s": m["contact_duration_s"],
        "max_approach_m": m.get("max_approach_m"),
        "impulse_N_s": m["impulse_N_s"],
        "restitution": out.results.get("restitution"),
        **{k: v for k, v in out.results.items() if k != "restitution"},
        "hertz": hertz_summary(h),
        "relative_to_hertz": {
            "peak_contact_force": m["peak_contact_force_N"] / h.force_max - 1.0,
            "contact_duration": m["contact_duration_s"] / h.contact_time - 1.0,
            **({"max_approach": m["max_approach_m"] / h.delta_max - 1.0} if m.get("max_approach_m") else {}),
        },
        "wall_time_s": wall,
        "model": out.model,
        "plan": {name: value for name, value, _ in plan.table()},
        "notes": out.notes,
        "scene_resolved": scene_to_dict(scene),
    }
    return summary


def write_run(
    folder: Path,
    scene: Scene,
    plan: Plan,
    out: RunOutput,
    summary: dict,
    figures: bool = True,
    comm=None,
    reference: bool = False,
) -> list[str]:
    """Write the output contract into ``folder``: rank 0 writes the files, every rank joins the
    collective writers (XDMF). Returns the file names written."""
    rank = comm.rank if comm is not None else 0
    for writer in out.extra_writers:
        writer(folder)
    if rank != 0:
        return []
    out.series.write_csv(folder / "timeseries.csv")
    scene_toml = dump_scene(scene)
    (folder / "scene.toml").write_text(scene_toml)
    if scene.outputs.hdf5:
        write_hdf5(folder, out.series, summary, scene_toml)
    if figures and scene.outputs.figures:
        hist = hertz_history(plan.hertz)
        title = f"{scene.name}: {out.method}"
        plots.plot_force(out.series, folder / "contact_force.png", hist, title=f"{title}: contact force")
        plots.plot_contact_point(
            {out.method: out.series},
            folder / "contact_point.png",
            title=f"{title}: liner contact point (normal components)",
        )
        t_end = float(out.series.time[-1]) if len(out.series.time) else 0.0
        if t_end > 10.0 * plan.hertz.contact_time:  # a run with ringing: the first 2 ms as well
            plots.plot_contact_point(
                {out.method: out.series},
                folder / "contact_point_run.png",
                title=f"{title}: liner contact point, impact and ringing",
                window=(0.0, min(t_end, 2e-3)),
            )
        plots.plot_gauges(out.series, folder / "gauges.png", title=f"{title}: strain gauges")
        plots.plot_energy(out.series, folder / "energy.png", title=f"{title}: energy")
        if "plastic_dissipation_J" in out.series:
            plots.plot_force_approach(
                out.series, folder / "force_approach.png", title=f"{title}: force against approach"
            )
            if "residual_dent_profile" in out.results:
                plots.plot_dent(
                    out.results["residual_dent_profile"],
                    folder / "dent.png",
                    out.results["residual_dent_depth_m"],
                    out.results["residual_dent_radius_m"],
                    title=f"{title}: residual dent",
                )
        if "tangential_force_N" in out.series:
            plots.plot_friction(
                out.series,
                folder / "friction.png",
                scene.contact.friction,
                title=f"{title}: friction (mu = {scene.contact.friction:g})",
            )
    if reference:  # reference.h5/.csv/.json for millimpact compare (reference.py)
        write_reference(folder, scene, plan, out, summary, scene_toml)
    write_summary(folder, summary)  # last: its presence marks a complete run
    return sorted(p.name for p in folder.iterdir())


def run_scene(
    scene: Scene,
    method: str,
    out_dir: Path | OutputFolder | None,
    options: dict | None = None,
    progress: bool = False,
    comm=None,
    reference: bool = False,
) -> dict[str, Any]:
    """Compute and (if ``out_dir``: a folder, or one claimed with
    :func:`~millimpact.results.output_folder.claim_output`) write a run (with ``reference``: also
    the reference files); returns the summary. Only rank 0 writes."""
    if out_dir is None or isinstance(out_dir, OutputFolder):
        target = out_dir
    else:
        target = claim_output(out_dir, "run", comm=comm)  # checked before computing
    t0 = time.perf_counter()
    out, plan = compute(scene, method, options, progress)
    wall = time.perf_counter() - t0
    summary = build_summary(scene, plan, out, wall)
    if target is not None:
        with stage("writing results and figures"), target.staged() as folder:
            summary["files"] = write_run(folder, scene, plan, out, summary, comm=comm, reference=reference)
    return summary
