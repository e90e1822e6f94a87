"""Finite-strain runs: the same answers as small strain where small strain holds, MPI equals
serial, at 1000 V_y a whole plastic ball with the energy balanced (full FE), and at 300 V_y the
whole plastic ball kept unreduced by a reduced method, as the full method gives it.

The small-strain comparison is conftest's coarse plastic half-space (V/V_y ~ 17, largest plastic
strain 0.03). The 1000 V_y run is the perfectly plastic 15 mm ball (Y = 1 GPa) on the 10x stiffer
block of docs/plasticity.md's study, on its coarsest mesh (h = a_c / 2, 15k DOFs) and through the
contact only (it ends at 46 us of the 60 simulated).
"""
from __future__ import annotations

import json

import pytest

from conftest import PLASTIC_HALFSPACE, run_cli
from millimpact.scene.builtin import builtin_scene
from millimpact.theory.hertz import effective_modulus
from millimpact.theory.thornton import yield_onset_velocity

KEYS = ("restitution", "peak_contact_force_N", "plastic_dissipation_J", "residual_dent_depth_m")


def _run(out, *args, np_=1) -> dict:
    r = run_cli("run", *args, "--out", str(out), np=np_)
    assert r.returncode == 0, r.stderr[-3000:]
    return json.loads((out / "summary.json").read_text())


@pytest.fixture(scope="module")
def finite_halfspace(tmp_path_factory):
    return _run(tmp_path_factory.mktemp("finite") / "run", *PLASTIC_HALFSPACE, "--set", "model.strain=finite")


def test_finite_strain_agrees_with_small_strain_where_small_strain_holds(finite_halfspace, plastic_halfspace_run):
    """The two kinematics differ by terms of the order of the strain: the largest plastic strain
    here is 0.03, and the small-strain model takes the quadratic strain of the 0.02 rad rotations
    at the contact's edge, theta^2 / 2 = 2e-4, for a stress: 4 % of the yield strain Y/E. So the
    bounds: e 0.01, F_max 1.5 %, plastic work and dent 4 % (measured: +0.005, +0.7 %, -2.2 %, -1.4 %)."""
    small = json.loads((plastic_halfspace_run / "summary.json").read_text())
    finite = finite_halfspace
    assert small["strain"] == "small" and finite["strain"] == "finite"
    assert abs(finite["restitution"] - small["restitution"]) < 0.01
    assert finite["peak_contact_force_N"] == pytest.approx(small["peak_contact_force_N"], rel=0.015)
    assert finite["plastic_dissipation_J"] == pytest.approx(small["plastic_dissipation_J"], rel=0.04)
    assert finite["residual_dent_depth_m"] == pytest.approx(small["residual_dent_depth_m"], rel=0.04)
    # energy with the plastic work: the small-strain run's bound (tests/methods/test_plastic.py)
    assert finite["energy_drift_max_rel"] < 5e-3


def test_finite_strain_under_mpi_equals_serial(finite_halfspace, tmp_path):
    """2 ranks against 1: the same equations, summed in another order (1e-6 relative: the
    plastic Newton's tolerance 1e-8 of the step's force, amplified over the contact's steps)."""
    par = _run(tmp_path / "np2", *PLASTIC_HALFSPACE, "--set", "model.strain=finite", np_=2)
    for key in KEYS:
        assert par[key] == pytest.approx(finite_halfspace[key], rel=1e-6), key


def test_a_thousand_yield_speeds_make_the_whole_ball_plastic_with_the_energy_balanced(tmp_path):
    """At 1000 V_y Johnson's cavity radius (14.3 mm) is about the ball's radius: the plan takes
    finite strain and the whole ball plastic, the plastic region reaches past the 6.6 mm contact
    zone (which truncated it before), and kinetic plus elastic energy plus the plastic work stay the
    impact energy within 0.5 % (the validation's bound for the regime)."""
    base = builtin_scene("hertz-halfspace")
    g = 10 * base.block.material.shear_modulus
    vy = yield_onset_velocity(1e9, effective_modulus(base.ball.material, base.with_value(
        "block.material.shear_modulus", g).block.material), base.ball.material.density)
    s = _run(tmp_path / "v1000", "hertz-halfspace", "--method", "full", "-q",
             "--set", f"impact.velocity=[0.0,{-1000 * vy!r},0.0]", "--set", f"block.material.shear_modulus={g!r}",
             "--set", "ball.material.yield_stress=1e9", "--set", "model.h_contact=0.0028",
             "--set", "model.fine_radius=0.006615", "--set", "time.end=6e-5")
    assert s["strain"] == "finite" and s["plastic_whole"] == ["ball"]
    assert s["plastic_zone_radius_m"]["ball"] > 1.5 * s["plastic_zone_radius_m"]["contact_zone"]
    assert s["zone_boundary_elastic"]
    assert s["energy_drift_max_rel"] < 5e-3
    assert s["plastic_dissipation_share"] > 0.7  # most of the impact energy (Thornton's model: 0.96)


def test_a_reduced_method_keeps_a_whole_plastic_ball_unreduced_and_agrees_with_full(tmp_path):
    """At 300 V_y (the same ball and block) Johnson's cavity radius (6.4 mm) passes the reduced
    zone's 6.6 mm x 0.85: a reduced method keeps the whole ball in its finite-element zone (no
    interior, no modes), the block reduced, and the plastic region reaches past the zone radius
    into what would have been the ball's reduced region. On the same mesh (coarse: h_contact
    1.5 mm, 15,894 P1 DOFs) the full method makes the ball's every cell plastic: the two agree as
    the block's modal truncation allows (measured: e 0.0008, F_max 0.36 %, plastic work 0.14 %;
    bounds 4x those), and kinetic plus elastic energy plus the plastic work stay the impact energy
    within 0.5 % (the regime's bound, as at 1000 V_y). The default method, improved (P2 and the
    manifold covers), takes the same plan: tests/reduction/test_reduction.py checks its covers
    of a whole body."""
    base = builtin_scene("hertz-halfspace")
    g = 10 * base.block.material.shear_modulus
    vy = yield_onset_velocity(1e9, effective_modulus(base.ball.material, base.with_value(
        "block.material.shear_modulus", g).block.material), base.ball.material.density)
    args = ("hertz-halfspace", "-q", "--set", f"impact.velocity=[0.0,{-300 * vy!r},0.0]",
            "--set", f"block.material.shear_modulus={g!r}", "--set", "ball.material.yield_stress=1e9",
            "--set", "model.h_contact=0.0015", "--set", "time.end=6e-5")
    red = _run(tmp_path / "traditional", *args, "--method", "traditional")
    full = _run(tmp_path / "full", *args, "--method", "full")
    assert red["strain"] == "finite" and red["plastic_whole"] == full["plastic_whole"] == ["ball"]
    assert red["model"]["dofs"] == full["model"]["dofs"]  # the same mesh
    bodies = red["model"]["reduction"]["bodies"]
    assert bodies["ball"]["interior_dofs"] == 0 and bodies["ball"]["modes"] == 0
    assert bodies["block"]["interior_dofs"] > 0 and bodies["block"]["modes"] > 0
    assert red["plastic_zone_radius_m"]["ball"] > red["plastic_zone_radius_m"]["contact_zone"]
    assert abs(red["restitution"] - full["restitution"]) < 0.003
    assert red["peak_contact_force_N"] == pytest.approx(full["peak_contact_force_N"], rel=0.015)
    assert red["plastic_dissipation_J"] == pytest.approx(full["plastic_dissipation_J"], rel=0.006)
    assert red["energy_drift_max_rel"] < 5e-3
