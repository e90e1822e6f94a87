"""``hertz``: the quasi-static Hertz model of a scene as a time series (1 DOF, m x'' = -k x^1.5).

Flight over the initial gap at the normal speed, then the Hertz contact history
(:func:`millimpact.theory.hertz.hertz_history`), then the rebound. The target is a half-space of
the struck body's material: no waves, no vibration, so the restitution is 1.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ..results.output import RunOutput
from ..results.timeseries import TimeSeries
from ..scene.plan import Plan
from ..scene.schema import Scene
from ..theory.hertz import hertz_history


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
    # approach_m as every method defines it (results/recorder.py): the ball centre's travel towards
    # the face less the initial gap, negative in flight and after the rebound; the overlap
    # (Hertz's delta) is its positive part
    approach = np.concatenate(
        [h.speed * t_flight - plan.gap, hist.approach, -hist.rebound_speed * (t_after - hist.contact_time)]
    )
    overlap = np.maximum(approach, 0.0)
    vel = np.concatenate([np.full_like(t_flight, h.speed), hist.velocity, np.full_like(t_after, -hist.rebound_speed)])
    a = np.sqrt(h.radius * overlap)
    with np.errstate(divide="ignore", invalid="ignore"):
        p = np.where(a > 0, 3 * force / (2 * np.pi * a * a), 0.0)
    acc_ball = -force / h.mass
    in_contact = np.concatenate([zeros_f, np.ones_like(hist.time), zeros_a]) > 0
    ts = TimeSeries(
        {
            "time_s": t,
            "contact_force_N": force,
            "approach_m": approach,
            "contact_radius_m": a,
            "ball_velocity_m_s": vel,
            "contact_point_displacement_m": share * overlap,
            "contact_point_velocity_m_s": np.where(in_contact, share * vel, 0.0),
            "contact_point_acceleration_m_s2": np.where(in_contact, share * acc_ball, 0.0),
            "contact_point_stress_Pa": -p,
            "ball_kinetic_energy_J": 0.5 * h.mass * vel**2,
            "strain_energy_J": 0.4 * h.k * overlap**2.5,
        }
    )
    ts.columns["total_energy_J"] = ts["ball_kinetic_energy_J"] + ts["strain_energy_J"]
    return RunOutput(
        "hertz",
        ts,
        {"restitution": hist.rebound_speed / h.speed, "peak_contact_stress_Pa": float(p.max())},
        {"dofs": 1, "description": "quasi-static Hertz contact, 1 DOF"},
        notes=["Hertz: quasi-static, half-space target, no wave or vibration losses (restitution 1)."]
        + (
            ["Hertz is elastic: the materials' yield stress is not used (--method improved or full for plasticity)"]
            if plan.ball.material.plastic or plan.target.plastic
            else []
        ),
    )


def run(scene: Scene, plan: Plan, options: dict[str, Any], progress: bool) -> RunOutput:
    """``--method hertz`` (the registry's entry point); takes no options."""
    return run_hertz(scene, plan)
