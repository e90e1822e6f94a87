"""Repeated impacts at one spot: the physics gates on a coarse rig.

The scene: paper-rig-plastic with an elastic ball (its 1.9 GPa yield is not reached: the block's
0.95 GPa yield caps the pressure), the block clamped at its BACK face (no cantilever bending: the
rig's base-clamped block swings within the pulse, so its force-approach path carries the block's
vibration and not the contact's), coarse (h_contact 0.6 mm ~ a_max / 1.9, h_far 10 mm), 3 m/s
(V/V_y ~ 60 on the block). Perfectly plastic (H = 0) and linear hardening (the liner steel's
H = 2.5 GPa). Each impact ~15-30 s: marked slow.
"""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from millimpact.repeat.sequence import ImpactSpec, run_sequence
from millimpact.scene.builtin import resolve_scene

pytestmark = pytest.mark.slow

#: the improved method's default zone for this scene (4.542 mm; `millimpact run` notes it), set
#: so that full meshes the very same mesh
ZONE = 0.004542404586583575


def _scene(hardening: float):
    # set together (Scene.with_values): an elastic ball, its steel's hardening going with its yield
    # stress (a hardening modulus alone is refused, scene.schema)
    return resolve_scene("paper-rig-plastic").with_values([
        ("model.h_contact", 6e-4), ("model.h_far", 0.01), ("model.zone_radius", ZONE),
        ("ball.material.yield_stress", None), ("ball.material.hardening_modulus", 0.0),
        ("block.support", "back"), ("block.material.hardening_modulus", hardening)])


@pytest.fixture(scope="module")
def perfectly_plastic(tmp_path_factory):
    """5 impacts at 3 m/s on the perfectly plastic block, run as 2 then continued to 5 from the
    stored state (the rerun path of an interrupted sequence)."""
    store = tmp_path_factory.mktemp("pp") / "impacts"
    first: list = []
    run_sequence(_scene(0.0), [ImpactSpec(3.0)] * 2, store_dir=store, records=first)
    rest: list = []
    outcomes = run_sequence(_scene(0.0), [ImpactSpec(3.0)] * 5, store_dir=store, records=rest)
    return outcomes, first + rest, len(rest)


@pytest.fixture(scope="module")
def hardening():
    recs: list = []
    return run_sequence(_scene(2.5e9), [ImpactSpec(3.0)] * 5, records=recs), recs


@pytest.fixture(scope="module")
def improved3():
    return run_sequence(_scene(0.0), [ImpactSpec(3.0)] * 3, method="improved")


def test_reloading_is_elastic_up_to_the_previous_peak(perfectly_plastic):
    """Impact 2 loads along impact 1's unloading curve up to impact 1's peak force (Johnson,
    Contact Mechanics, 1985, 9.2: the residual state is elastic up to the load that made it), and
    does no plastic work before that force."""
    _, recs, _ = perfectly_plastic
    a, b = recs[0].series, recs[1].series
    f1, x1 = a["contact_force_N"], a["approach_m"]
    i = int(np.argmax(f1))
    F1 = f1[i]
    on = f1[i:] > 0
    un_x, un_f = x1[i:][on][::-1], f1[i:][on][::-1]
    f2, x2 = b["contact_force_N"], b["approach_m"]
    rising = (np.arange(len(f2)) <= int(np.argmax(f2))) & (f2 > 0) & (f2 < F1)
    band = rising & (f2 > 0.3 * F1)
    dev = f2[band] / np.interp(x2[band], un_x, un_f) - 1.0
    # 2 %: the tolerance, on the median over 0.3-1 F_1; single rows may differ more:
    # impact 1 unloads dynamically from a vibrating block and ball, impact 2 loads from rest
    # (measured 0.3-3.1 %); below 0.3 F_1 the relative error of a small force is not the test
    assert np.median(np.abs(dev)) < 0.02, dev
    assert np.max(np.abs(dev)) < 0.05, dev
    # no new plastic strain before F_1: the plastic work there is round-off of the return map
    # against the impact's (measured 5e-5 of it)
    w = b["plastic_dissipation_J"]
    assert w[rising].max() < 1e-3 * w[-1]
    assert w[-1] > 0.1 * recs[0].outcome.plastic_dissipation_J      # beyond F_1 it yields again


@pytest.mark.parametrize("case", ["perfectly_plastic", "hardening"])
def test_repeated_impacts_shake_down_monotonically(case, request):
    """Over 5 impacts e rises, and the dent increments and the plastic work per impact fall, each
    monotonically (foundations.md section 10: the unloading curve stores only e_1^2 of the impact energy, so
    the same impact yields again beyond it, less each time; Seifried et al. 2005 measured e rising)."""
    outcomes = request.getfixturevalue(case)[0]
    e = np.array([o.restitution_normal for o in outcomes])
    w = np.array([o.plastic_dissipation_J for o in outcomes])
    d = np.array([o.residual_dent_depth_m for o in outcomes])
    inc = np.diff(np.concatenate([[0.0], d]))
    assert np.all(np.diff(e) > 0), e
    assert np.all(np.diff(w) < 0), w
    assert np.all(inc > 0) and np.all(np.diff(inc) < 0), inc
    assert 0.6 < e[0] < e[-1] < 1.0


@pytest.mark.parametrize("case", ["perfectly_plastic", "hardening"])
def test_energy_balance_in_every_impact(case, request):
    """kinetic + elastic + plastic work constant within 0.5 % of the impact energy in every impact
    (the issue's tolerance; the energy-stable Newmark keeps it to ~3e-4 on this mesh)."""
    recs = request.getfixturevalue(case)[1]
    assert len(recs) == 5
    for r in recs:
        assert r.details["energy_drift_over_impact_rel"] < 5e-3, (r.outcome.impact, r.details)
        assert r.details["contact_ended"]


def test_a_continued_sequence_equals_an_uninterrupted_one(perfectly_plastic, improved3):
    """The stored state restarts a sequence exactly: impacts 1-3 of the run stopped after 2 and
    continued equal an uninterrupted run's (same code path and state: round-off, 1e-8)."""
    outcomes, _, computed_later = perfectly_plastic
    assert computed_later == 3
    for a, b in zip(outcomes[:3], improved3):
        for f in dataclasses.fields(a):
            x, y = getattr(a, f.name), getattr(b, f.name)
            if isinstance(x, float) and np.isnan(x):
                assert np.isnan(y)
            else:
                assert x == pytest.approx(y, rel=1e-8, abs=1e-15), f.name


def test_improved_carries_the_state_as_full_does(improved3):
    """The state the improved method carries (in the NMM zone) equals full P2's on the same mesh
    after 3 impacts: dent within 2 %, e within 0.01 (the issue's tolerances; the single impact's
    improved-full difference on this mesh: e 0.004, dent 2 %, from the reduction's modal cutoff)."""
    full = run_sequence(_scene(0.0), [ImpactSpec(3.0)] * 3, method="full")
    for a, b in zip(improved3, full):
        assert abs(a.restitution_normal - b.restitution_normal) < 0.01, (a, b)
    assert improved3[-1].residual_dent_depth_m == pytest.approx(full[-1].residual_dent_depth_m, rel=0.02)


def test_the_surface_flow_stress_follows_the_hardening_law(perfectly_plastic, hardening):
    """The block's flow stress at the impact point after each impact: the perfectly plastic block's
    is its yield stress (0.95 GPa) whatever its strain; the linearly hardening block's (H 2.5 GPa)
    rises above it from the first impact (the point under the contact yields), never falls
    (alpha only grows), stays below Y + H times the impact's largest plastic strain (the point's
    alpha is at most the largest), and rises less as the block shakes down (impact 5's rise below
    impact 2's)."""
    y, h = 0.95e9, 2.5e9
    pp, _, _ = perfectly_plastic
    assert all(o.surface_flow_stress_Pa == pytest.approx(y, rel=1e-12) for o in pp)
    lin, _ = hardening
    s = np.array([o.surface_flow_stress_Pa for o in lin])
    assert s[0] > y * (1 + 1e-3)
    assert np.all(np.diff(s) >= 0)
    assert np.all(s <= y + h * np.array([o.max_equivalent_plastic_strain for o in lin]) * (1 + 1e-12))
    assert s[4] - s[3] < s[1] - s[0]
