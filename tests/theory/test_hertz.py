"""Hertz model against DESIGN.md section 3 (Johnson, Contact Mechanics 3.4 and 11.4)."""
import math

import numpy as np
import pytest

from millimpact.scene.plan import scene_hertz
from millimpact.theory.hertz import (T_C_FACTOR, effective_modulus, hertz_history, hertz_impact, hertz_static,
                                     max_shear_on_axis)
from millimpact.scene.schema import Material
from millimpact.scene.builtin import builtin_scene


def test_default_scene_values():
    # DESIGN.md section 3: delta_max 89.6 um, F_max 13.85 kN, t_c 87.9 us, a_max 1.159 mm, p0 4.92 GPa;
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
