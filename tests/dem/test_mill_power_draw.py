"""A mill run's net power and charge shape against Morrell's and Austin's models.

The power from a made-up energy log with a known answer, the comparison figures against the theory
module's functions for the run's mill (and, for the ball fill and Austin's ore-free form, against
their formulas written out here), and a short Yade run of the small mill of mill_scenes.py."""
from __future__ import annotations

import dataclasses
import json
import math

import numpy as np
import pytest

from millimpact.dem.mill.command import _comparison_lines
from millimpact.dem.mill.run import run_mill
from millimpact.dem.mill.power import charge_shape_report, measured_power, power_report, volumetric_fill
from millimpact.dem.mill.setup import MillOptions, plan_mill
from millimpact.theory.mill_power import austin_power, charge_shape, critical_speed, morrell_net_power

from mill_scenes import needs_yade, small_mill_scene


def _energy_log(warmup_s, end_s, p_warm, p_run, samples=10, at_warmup=None):
    """energy.csv's columns: drive work rising at p_warm W up to the warm-up's end, at p_run after;
    sampled evenly and once at ``at_warmup`` (default: the warm-up's end)."""
    at = warmup_s if at_warmup is None else at_warmup
    t = np.array(sorted({end_s * k / samples for k in range(samples + 1)} | {at}))
    w = np.where(t <= warmup_s, p_warm * t, p_warm * warmup_s + p_run * (t - warmup_s))
    zeros = np.zeros_like(t)
    return {"time_s": t, "drive_work_J": w, "kinetic_J": zeros}


def test_net_power_is_the_drive_work_after_the_warm_up_over_its_time():
    """30 W during a 1.3 s warm-up, 20 W for the 2 s after: 20 W, 20 / 0.12 W/m in a 0.12 m slice,
    20 x 4 / 0.12 W for a 4 m mill (exact up to rounding: 1e-12)."""
    log = _energy_log(1.3, 3.3, 30.0, 20.0)
    p = measured_power(log, 1.3, 0.12, mill_length=4.0)
    assert p["net_W"] == pytest.approx(20.0, rel=1e-12)
    assert p["net_per_metre_W_m"] == pytest.approx(20.0 / 0.12, rel=1e-12)
    assert p["net_mill_W"] == pytest.approx(20.0 * 4.0 / 0.12, rel=1e-12)
    assert p["window_s"] == pytest.approx([1.3, 3.3]) and p["drive_work_J"] == pytest.approx(40.0)
    # without a mill length: per metre only
    assert measured_power(log, 1.3, 0.12)["net_mill_W"] is None
    # the warm-up's sample written a little late (Yade samples at its next step): still the run's power
    late = _energy_log(1.3, 3.3, 30.0, 20.0, at_warmup=1.3 + 1e-4)
    assert measured_power(late, 1.3, 0.12, tolerance_s=2e-4)["net_W"] == pytest.approx(20.0, rel=1e-12)
    # a window of one sample: no power
    assert measured_power(log, 3.3, 0.12)["net_W"] is None


def test_the_comparison_is_the_theory_modules_models_for_the_runs_mill():
    """--fill 0.2 in the small mill: J back within one ball of 0.2 (the run counted its balls with the
    same porosity), and Morrell's and Austin's figures equal the theory module's for that mill (D
    inside the liners, the speed fraction, J_B = J, no rock, no slurry); Austin's with no ore is
    K D^2.5 (1 - A J) 0.6 J rho_b phi (1 - 0.1 / 2^(9 - 10 phi)) per metre."""
    opts = MillOptions(revolutions=1.0, fill=0.2, speed_fraction=0.8)
    setup = plan_mill(small_mill_scene(), opts)
    j = volumetric_fill(setup)
    one_ball = 0.2 / setup.n_balls
    assert j == pytest.approx(0.2, abs=one_ball)
    v_ball = 4 / 3 * math.pi * setup.ball_radius**3
    assert j == pytest.approx(setup.n_balls * v_ball / (0.6 * setup.profile.open_area() * setup.thickness))

    log = _energy_log(setup.warmup_s, setup.warmup_s + setup.run_s, 5.0, 7.0)
    rep = power_report(setup, log)
    d, rho_b = 0.8, setup.ball_material[2]
    assert setup.profile.diameter == pytest.approx(d)
    morrell = morrell_net_power(d, 1.0, 0.8, j, 0.6 * rho_b).net
    austin = austin_power(d, 1.0, 0.8, j, j, 0.0, rho_b)
    assert austin == pytest.approx(10.6 * d**2.5 * (1 - 0.937 * j) * 0.6 * j * rho_b * 0.8 * (1 - 0.1 / 2.0), rel=1e-12)
    assert rep["morrell_net_per_metre_W_m"] == pytest.approx(morrell, rel=1e-12)
    assert rep["austin_per_metre_W_m"] == pytest.approx(austin, rel=1e-12)
    per_m = 7.0 / setup.thickness
    assert rep["measured"]["net_per_metre_W_m"] == pytest.approx(per_m, rel=1e-9)
    assert rep["morrell_relative_difference"] == pytest.approx(per_m / morrell - 1.0, rel=1e-9)
    assert rep["austin_relative_difference"] == pytest.approx(per_m / austin - 1.0, rel=1e-9)
    assert "per metre" in rep["scaled_to"] and "pinion" in rep["austin_is"]
    # the models' critical speed is the run's (the same D)
    assert 60 * critical_speed(d) == pytest.approx(setup.critical_rpm, rel=1e-3)

    shape = charge_shape(0.8, j)
    rep_s = charge_shape_report(setup, {"toe_deg": -40.0, "shoulder_deg": 130.0})
    assert rep_s["morrell_toe_deg"] == pytest.approx(shape.toe_deg)
    assert rep_s["morrell_shoulder_deg"] == pytest.approx(shape.shoulder_deg)
    assert rep_s["toe_difference_deg"] == pytest.approx(-40.0 - shape.toe_deg)
    assert rep_s["shoulder_difference_deg"] == pytest.approx(130.0 - shape.shoulder_deg)
    assert charge_shape_report(setup, {"toe_deg": None, "shoulder_deg": None})["toe_difference_deg"] is None


@needs_yade
def test_a_mill_run_reports_a_positive_net_power_and_keeps_its_energy_balance(tmp_path):
    """30 balls at 75 % of n_c, half a revolution's warm-up and one logged: the drive does work on
    the charge (net power > 0), the energy balance still closes within 5 % (as in
    test_mill_physics.py), the window starts at the warm-up's end (the sample the script adds
    there, within one torque sum's steps), and the two printed lines carry the figures."""
    opts = MillOptions(revolutions=1.0, balls=30, speed_fraction=0.75, stiffness_scale=0.001, warmup=0.5)
    scene = small_mill_scene()
    setup = dataclasses.replace(plan_mill(scene, opts), power_every=1)
    stage = tmp_path / "run"
    stage.mkdir()
    summary = run_mill(scene, opts, stage, plots=False, setup=setup, timeout=900)
    json.dumps(summary)  # summary.json takes it as it is
    m = summary["power"]["measured"]
    assert m["net_W"] > 0 and m["net_per_metre_W_m"] == pytest.approx(m["net_W"] / setup.thickness)
    assert abs(summary["energy_balance"]["relative_error"]) < 0.05, summary["energy_balance"]
    assert abs(m["window_s"][0] - setup.warmup_s) <= setup.dt * setup.power_every * 1.01
    assert m["window_s"][1] == pytest.approx(setup.warmup_s + setup.run_s, abs=2 * setup.dt)
    power_line, shape_line = _comparison_lines(summary)
    assert f"{m['net_per_metre_W_m'] / 1e3:.4g} kW/m" in power_line and "Morrell" in power_line
    assert "pinion" in power_line and shape_line.startswith("charge shape: toe")
