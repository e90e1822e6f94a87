"""Thornton's 1997 elastic-perfectly-plastic impact model against independent references."""
from __future__ import annotations

import numpy as np
import pytest
from scipy import optimize

from millimpact.theory.hertz import hertz_impact
from millimpact.theory.thornton import restitution_thornton, yield_onset_velocity


def test_yield_onset_speed_is_where_the_hertz_pressure_reaches_p_y():
    """V_y from Thornton's closed form equals the speed at which the Hertz impact's peak pressure
    (our theory.hertz, Johnson 11.4) reaches 1.6 Y, to the 3 digits of his constant 1.56."""
    Y, E_star, rho, R = 1e9, 100e9, 7800.0, 0.015
    m = 4.0 / 3.0 * 3.141592653589793 * R**3 * rho
    v_hertz = optimize.brentq(lambda v: hertz_impact(R, m, v, E_star).p0 - 1.6 * Y, 1e-4, 100.0)
    assert yield_onset_velocity(Y, E_star, rho) == pytest.approx(v_hertz, rel=2e-3)
    # foundations.md section 7: E* 100 GPa, rho 7800: Y 1 GPa -> 0.18 m/s, Y 2 GPa -> 1.0 m/s
    assert yield_onset_velocity(1e9, E_star, rho) == pytest.approx(0.18, abs=0.005)
    assert yield_onset_velocity(2e9, E_star, rho) == pytest.approx(1.0, abs=0.03)


def test_restitution_values_and_limits():
    """e = 1 up to V_y and continuous there; foundations.md section 7's 0.76 / 0.58 / 0.46 at 1 / 3 / 8 m/s for
    Y = 1 GPa (V_y 0.18 m/s); e ~ V^(-1/4) at high speed."""
    vy = yield_onset_velocity(1e9, 100e9, 7800.0)
    assert restitution_thornton(0.5 * vy, vy) == 1.0
    assert restitution_thornton(vy * (1 + 1e-9), vy) == pytest.approx(1.0, abs=1e-6)
    for v, e in ((1.0, 0.76), (3.0, 0.58), (8.0, 0.46)):
        assert restitution_thornton(v, vy) == pytest.approx(e, abs=0.01)
    hi = restitution_thornton([1e3 * vy, 1e4 * vy], vy)
    assert hi[1] / hi[0] == pytest.approx(10 ** -0.25, rel=1e-2)


def test_thornton_max_approach_does_the_impact_energy_of_work():
    """delta_max of Thornton's loading law: Hertz's below the yield onset; above it the work of the
    law (Hertz to delta_y, then F_y + pi p_y R (delta - delta_y)), integrated numerically, equals
    the impact energy m V^2 / 2."""
    from millimpact.theory.hertz import hertz_impact
    from millimpact.theory.thornton import max_approach_thornton

    R, m, E = 0.015, 0.11, 115e9
    p_y = 1.6e9
    slow = hertz_impact(R, m, 0.05, E)
    assert slow.p0 < p_y
    assert max_approach_thornton(R, m, 0.05, E, p_y) == pytest.approx(slow.delta_max, rel=1e-12)
    v = 3.0
    d = max_approach_thornton(R, m, v, E, p_y)
    d_y = R * (np.pi * p_y / (2 * E)) ** 2
    x = np.linspace(0.0, d, 200001)
    f = np.where(x <= d_y, 4 / 3 * E * np.sqrt(R) * x**1.5,
                 4 / 3 * E * np.sqrt(R) * d_y**1.5 + np.pi * p_y * R * (x - d_y))
    assert np.trapz(f, x) == pytest.approx(0.5 * m * v**2, rel=1e-6)
    assert d > hertz_impact(R, m, v, E).delta_max       # the capped pressure lets the ball in deeper


def test_plastic_zone_radius_follows_the_cavity_model():
    """Johnson's cavity model (Contact Mechanics, eq. 6.40): (c/a)^3 = (E* a/(Y R) + 4(1-2nu)) / (6(1-nu));
    no plastic zone below the yield onset; the zone grows with speed and as the yield stress falls."""
    from millimpact.theory.thornton import max_approach_thornton, plastic_zone_radius

    R, m, E, Y = 0.015, 0.11, 115e9, 1e9
    assert plastic_zone_radius(R, m, 0.05, E, Y)[1] == 0.0
    a, c = plastic_zone_radius(R, m, 3.0, E, Y)
    assert a == pytest.approx(np.sqrt(R * max_approach_thornton(R, m, 3.0, E, 1.6 * Y)), rel=1e-12)
    assert (c / a) ** 3 == pytest.approx((E * a / (Y * R) + 4 * 0.4) / (6 * 0.7), rel=1e-12)
    assert c > a
    assert plastic_zone_radius(R, m, 10.0, E, Y)[1] > c > plastic_zone_radius(R, m, 3.0, E, 2 * Y)[1]


def test_fully_plastic_contact_radius_is_the_energy_balance_of_the_dent():
    """Johnson 11.4 / Tabor: m V^2 / 2 = p_m x dent volume. The exact volume of a spherical cap of
    depth delta (pi delta^2 (3R - delta) / 3, independent of the shallow-dent formula) with a^2 = 2 R
    delta, times p_m = 3 Y, equals the impact energy; and at high speed Thornton's contact radius
    (Hertz to the yield onset, then F = F_y + pi p_y R (delta - delta_y) over a^2 = R delta) tends
    to the fully plastic one with p_m = 2 p_y, the same balance written with its own geometry."""
    from millimpact.theory.thornton import (FULLY_PLASTIC_PRESSURE_FACTOR, fully_plastic_contact_radius,
                                            plastic_zone_radius)

    R, rho, Y, E = 0.015, 7800.0, 1e9, 182e9
    m = 4.0 / 3.0 * np.pi * R**3 * rho
    for v in (1.0, 10.0, 55.0):
        p_m = FULLY_PLASTIC_PRESSURE_FACTOR * Y
        a = fully_plastic_contact_radius(R, m, v, p_m)
        delta = a**2 / (2 * R)
        cap = np.pi * delta**2 * (3 * R - delta) / 3
        # the shallow-dent volume pi a^4 / (4 R) omits the cap's -delta^3 term: a relative
        # difference delta / (3 R), 3 % at 55 m/s (a = 0.38 R), hence this tolerance
        assert p_m * cap == pytest.approx(0.5 * m * v**2, rel=delta / (3 * R) * 1.01)
    # Thornton's radius tends to the fully plastic one with p_m = 2 p_y as delta_y / delta -> 0: the
    # Hertz part's offset leaves 1.2 % at 1 m/s (18 V_y), 0.12 % at 10 m/s and 0.02 % at 55 m/s
    # (1000 V_y), hence 1e-3 there; p_m = 3 Y instead of 3.2 Y makes a (3.2 / 3)^(1/4) = 1.6 % larger
    a_th = plastic_zone_radius(R, m, 55.0, E, Y)[0]
    assert a_th == pytest.approx(fully_plastic_contact_radius(R, m, 55.0, 2 * 1.6 * Y), rel=1e-3)
    assert fully_plastic_contact_radius(R, m, 55.0, 3 * Y) / a_th == pytest.approx((3.2 / 3) ** 0.25, rel=1e-3)
