"""One run of a scene by a named method: computes, then writes the output contract.

Output contract (``--out DIR``): ``summary.json`` (scene, method, peak_contact_force_N,
contact_duration_s, max_approach_m, restitution, hertz, wall_time_s, model, plan),
``timeseries.csv`` (header of names with units), ``timeseries.h5``, ``scene.toml``, figures
``*.png`` and, for FE methods, XDMF fields.
"""
from __future__ import annotations

import logging
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Optional

import numpy as np

from .errors import InputError
from .hertz import HertzHistory, HertzImpact, hertz_history, scene_hertz
from .plan import Plan, make_plan
from .results import TimeSeries, contact_metrics, staged_output, write_hdf5, write_summary
from .scene import Scene, dump_scene, scene_to_dict

log = logging.getLogger(__name__)

#: methods by name; FE methods register themselves when their modules exist
METHODS: dict[str, str] = {
    "hertz": "quasi-static Hertz contact, 1 DOF (m x'' = -k x^1.5): the analytical reference and lightest model",
}


@dataclass
class RunOutput:
    """What a method computed: the time series, scalar results, model sizes, and optional writers
    of extra files (e.g. XDMF fields) called with the output folder on rank 0."""

    method: str
    series: TimeSeries
    results: dict[str, Any]
    model: dict[str, Any]
    extra_writers: list[Callable[[Path], None]] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)


def hertz_summary(h: HertzImpact) -> dict[str, float]:
    """The Hertz values of a scene, SI, for ``summary.json``."""
    return {
        "delta_max_m": h.delta_max, "F_max_N": h.force_max, "t_c_s": h.contact_time, "a_max_m": h.a_max,
        "p0_Pa": h.p0, "tau_max_Pa": h.tau_max, "tau_depth_m": h.tau_depth, "impact_energy_J": h.energy,
        "effective_modulus_Pa": h.e_star, "mass_kg": h.mass, "normal_speed_m_s": h.speed,
    }


def run_hertz(scene: Scene, plan: Plan) -> RunOutput:
    """The Hertz model of a scene as a time series: flight over the initial gap, then contact.

    The liner's contact-point displacement is its share of the approach,
    w = delta (1-nu2^2)/E2 * E*, and its normal stress is the Hertz pressure p = 3F/(2 pi a^2)
    (compressive, so negative).
    """
    h = plan.hertz
    hist = hertz_history(h, n=401)
    t_gap = plan.gap / h.speed
    blk = scene.block.material
    share = (1 - blk.poisson**2) / blk.youngs_modulus * h.e_star
    t_flight = np.linspace(0.0, t_gap, 5, endpoint=False)
    t_after = hist.contact_time + np.linspace(0.0, 0.25 * hist.contact_time, 21)[1:]
    zeros_f, zeros_a = np.zeros_like(t_flight), np.zeros_like(t_after)
    t = np.concatenate([t_flight, t_gap + hist.time, t_gap + t_after])
    force = np.concatenate([zeros_f, hist.force, zeros_a])
    approach = np.concatenate([zeros_f, hist.approach, zeros_a])
    vel = np.concatenate([np.full_like(t_flight, h.speed), hist.velocity, np.full_like(t_after, -hist.rebound_speed)])
    a = np.sqrt(h.radius * approach)
    with np.errstate(divide="ignore", invalid="ignore"):
        p = np.where(a > 0, 3 * force / (2 * np.pi * a * a), 0.0)
    acc_ball = -force / h.mass
    in_contact = np.concatenate([zeros_f, np.ones_like(hist.time), zeros_a]) > 0
    ts = TimeSeries({
        "time_s": t,
        "contact_force_N": force,
        "approach_m": approach,
        "contact_radius_m": a,
        "ball_velocity_m_s": vel,
        "contact_point_displacement_m": share * approach,
        "contact_point_velocity_m_s": np.where(in_contact, share * vel, 0.0),
        "contact_point_acceleration_m_s2": np.where(in_contact, share * acc_ball, 0.0),
        "contact_point_stress_Pa": -p,
        "ball_kinetic_energy_J": 0.5 * h.mass * vel**2,
        "strain_energy_J": 0.4 * h.k * approach**2.5,
    })
    ts.columns["total_energy_J"] = ts["ball_kinetic_energy_J"] + ts["strain_energy_J"]
    return RunOutput("hertz", ts, {"restitution": hist.rebound_speed / h.speed,
                                   "peak_contact_stress_Pa": float(p.max())},
                     {"dofs": 1, "description": METHODS["hertz"]},
                     notes=["Hertz: quasi-static, half-space target, no wave or vibration losses (restitution 1)."])


def compute(scene: Scene, method: str, options: Optional[dict] = None, progress: bool = False) -> tuple[RunOutput, Plan]:
    """Run ``scene`` with ``method``; returns the output and the plan it used."""
    plan = make_plan(scene)
    if method == "hertz":
        return run_hertz(scene, plan), plan
    if method not in _FE_RUNNERS:
        load_fe_methods()
    runner = _FE_RUNNERS.get(method)
    if runner is None:
        raise InputError(f"--method = {method!r}: must be one of {', '.join(sorted(set(METHODS) | set(_FE_RUNNERS)))}")
    return runner(scene, plan, options or {}, progress), plan


_FE_RUNNERS: dict[str, Callable[..., RunOutput]] = {}


def load_fe_methods() -> bool:
    """Import the finite-element methods (they register themselves); False if unavailable."""
    try:
        from . import fe_methods  # noqa: F401
    except ImportError as exc:
        if "fe_methods" not in str(exc):
            raise
        return False
    return True


def _typed_option(options: dict, key: str, default, kind: type, what: str):
    """Pop a method option converted by ``kind`` (``default`` if absent or empty); a bad value is
    an :class:`InputError` naming the option."""
    value = options.pop(key, None)
    if value is None or value == "":
        return default
    try:
        return kind(value)
    except (TypeError, ValueError):
        raise InputError(f"option {key} = {value!r}: must be {what}") from None


def int_option(options: dict, key: str, default: Optional[int]) -> Optional[int]:
    return _typed_option(options, key, default, int, "an integer")


def float_option(options: dict, key: str, default: Optional[float]) -> Optional[float]:
    return _typed_option(options, key, default, float, "a number")


def register_method(name: str, description: str, runner: Callable[..., RunOutput]) -> None:
    """Make ``runner(scene, plan, options, progress) -> RunOutput`` available as ``--method name``."""
    METHODS[name] = description
    _FE_RUNNERS[name] = runner


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


def write_run(folder: Path, scene: Scene, plan: Plan, out: RunOutput, summary: dict, figures: bool = True,
              comm=None, reference: bool = False) -> list[str]:
    """Write the output contract into ``folder``: rank 0 writes the files, every rank joins the
    collective writers (XDMF). Returns the file names written."""
    from . import plots

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
        plots.plot_contact_point({out.method: out.series}, folder / "contact_point.png",
                                 title=f"{title}: liner contact point (normal components)")
        t_end = float(out.series.time[-1]) if len(out.series.time) else 0.0
        if t_end > 10.0 * plan.hertz.contact_time:   # a run with ringing: the first 2 ms as well
            plots.plot_contact_point({out.method: out.series}, folder / "contact_point_run.png",
                                     title=f"{title}: liner contact point, impact and ringing",
                                     window=(0.0, min(t_end, 2e-3)))
        plots.plot_gauges(out.series, folder / "gauges.png", title=f"{title}: strain gauges")
        plots.plot_energy(out.series, folder / "energy.png", title=f"{title}: energy")
        if "tangential_force_N" in out.series:
            plots.plot_friction(out.series, folder / "friction.png", scene.contact.friction,
                                title=f"{title}: friction (mu = {scene.contact.friction:g})")
    if reference:  # reference.h5/.csv/.json for millimpact compare (reference.py)
        from .reference import write_reference

        write_reference(folder, scene, plan, out, summary, scene_toml)
    write_summary(folder, summary)  # last: its presence marks a complete run
    return sorted(p.name for p in folder.iterdir())


def run_scene(scene: Scene, method: str, out_dir: Optional[Path], options: Optional[dict] = None,
              progress: bool = False, comm=None, reference: bool = False) -> dict[str, Any]:
    """Compute and (if ``out_dir``) write a run (with ``reference``: also the reference files);
    returns the summary. Only rank 0 writes."""
    t0 = time.perf_counter()
    out, plan = compute(scene, method, options, progress)
    wall = time.perf_counter() - t0
    summary = build_summary(scene, plan, out, wall)
    if out_dir is not None:
        with staged_output(Path(out_dir), comm) as stage:
            summary["files"] = write_run(stage, scene, plan, out, summary, comm=comm,
                                         reference=reference)
    return summary
