"""Hertz model against foundations.md section 3 (Johnson, Contact Mechanics 3.4 and 11.4)."""
import math

import numpy as np
import pytest

from millimpact.scene.plan import scene_hertz
from millimpact.theory.hertz import (T_C_FACTOR, effective_modulus, hertz_history, hertz_impact, hertz_static,
                                     max_shear_on_axis)
from millimpact.scene.schema import Material
from millimpact.scene.builtin import builtin_scene


def test_default_scene_values():
    # foundations.md section 3: delta_max 89.6 um, F_max 13.85 kN, t_c 87.9 us, a_max 1.159 mm, p0 4.92 GPa;
    # tolerance 0.5 % (the issue's), the values there are given to 3-4 digits
    h = scene_hertz(builtin_scene("paper-rig"))
    assert h.e_star == pytest.approx(100e9, rel=1e-12)  # E = 2 G (1+nu) = 182 GPa, E* = E / (2 (1-nu^2))
    assert h.delta_max == pytest.approx(89.6e-6, rel=5e-3)
    assert h.force_max == pytest.approx(13.85e3, rel=5e-3)
    assert h.contact_time == pytest.approx(87.9e-6, rel=5e-3)
    assert h.a_max == pytest.approx(1.159e-3, rel=5e-3)
    assert h.p0 == pytest.approx(4.92e9, rel=5e-3)


def test_tc_constant_and_subsurface_shear():
    # Johnson eq. 11.24: t_c = 2.94 delta/v; eq. 3.45: tau_1 max 0.31 p0 at 0.48 a for nu = 0.3
    assert T_C_FACTOR == pytest.approx(2.9432, abs=1e-4)
    tau, depth = max_shear_on_axis(0.3)
    assert tau == pytest.approx(0.31, abs=0.005)
    assert depth == pytest.approx(0.48, abs=0.01)


def test_scaling_laws():
    # F_max ~ v^(6/5) R^2 and t_c ~ R v^(-1/5) (mass ~ R^3): exact power laws of the closed form
    m = Material()
    e = effective_modulus(m, m)

    def impact(r, v):
        return hertz_impact(r, 4 / 3 * math.pi * r**3 * m.density, v, e)

    base = impact(0.02, 3.0)
    for fv in (0.5, 2.0):
        h = impact(0.02, 3.0 * fv)
        assert h.force_max / base.force_max == pytest.approx(fv**1.2, rel=1e-10)
        assert h.contact_time / base.contact_time == pytest.approx(fv**-0.2, rel=1e-10)
    for fr in (0.75, 1.25):
        h = impact(0.02 * fr, 3.0)
        assert h.force_max / base.force_max == pytest.approx(fr**2, rel=1e-10)
        assert h.contact_time / base.contact_time == pytest.approx(fr, rel=1e-10)


def test_history_matches_closed_form():
    # the integrated m x'' = -k x^1.5 must reproduce the closed forms (ODE tolerance 1e-11)
    h = scene_hertz(builtin_scene("paper-rig"))
    hist = hertz_history(h, n=2001)
    assert hist.force.max() == pytest.approx(h.force_max, rel=1e-5)  # sampling of the peak
    assert hist.approach.max() == pytest.approx(h.delta_max, rel=1e-5)
    assert hist.contact_time == pytest.approx(h.contact_time, rel=1e-8)
    assert hist.rebound_speed == pytest.approx(h.speed, rel=1e-8)  # elastic: no loss
    energy = 0.5 * h.mass * hist.velocity**2 + 0.4 * h.k * hist.approach**2.5
    assert np.ptp(energy) / h.energy < 1e-8
    # impulse = 2 m v (elastic rebound)
    assert np.trapz(hist.force, hist.time) == pytest.approx(2 * h.mass * h.speed, rel=1e-5)


def test_static_hertz_consistency():
    # static contact under F_max gives back a_max and delta_max (same Hertz law)
    h = scene_hertz(builtin_scene("paper-rig"))
    s = hertz_static(h.force_max, h.radius, h.e_star)
    assert s.a == pytest.approx(h.a_max, rel=1e-10)
    assert s.delta == pytest.approx(h.delta_max, rel=1e-10)
    assert s.p0 == pytest.approx(h.p0, rel=1e-10)


@pytest.mark.parametrize("a_over_r", [0.0, 1.0])
def test_patch_mean_displacement_against_a_direct_average(a_over_r):
    """theory.hertz.patch_mean_displacement against a Monte Carlo average of the Boussinesq field
    (Johnson 3.2) of the Hertz pressure over the half-ball (400k samples: standard error ~0.1 %;
    2 % allowed, the fitted spread factor is within 0.5 %)."""
    from millimpact.theory.hertz import patch_mean_displacement

    rng = np.random.default_rng(7)
    n, nu, E = 400_000, 0.3, 1.0
    G = E / (2 * (1 + nu))
    # load points with density p(s) / P: s / a = sqrt(1 - (1 - u)^(2/3)) (Hertz pressure, radial cdf)
    s = a_over_r * np.sqrt(1 - (1 - rng.random(n)) ** (2 / 3))
    th = 2 * np.pi * rng.random(n)
    # uniform points in the half-ball of radius 1 below the surface
    r, ct, ph = rng.random(n) ** (1 / 3), rng.random(n), 2 * np.pi * rng.random(n)
    st = np.sqrt(1 - ct**2)
    x, y, z = r * st * np.cos(ph), r * st * np.sin(ph), r * ct
    rho = np.sqrt((x - s * np.cos(th)) ** 2 + (y - s * np.sin(th)) ** 2 + z**2)
    mc = float(np.mean((2 * (1 - nu) / rho + z**2 / rho**3) / (4 * np.pi * G)))
    assert patch_mean_displacement(1.0, a_over_r, 1.0, E, nu) == pytest.approx(mc, rel=0.02)
