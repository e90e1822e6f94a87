"""Thornton's 1997 elastic-perfectly-plastic impact model against independent references."""
from __future__ import annotations

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
    # DESIGN.md section 7: E* 100 GPa, rho 7800: Y 1 GPa -> 0.18 m/s, Y 2 GPa -> 1.0 m/s
    assert yield_onset_velocity(1e9, E_star, rho) == pytest.approx(0.18, abs=0.005)
    assert yield_onset_velocity(2e9, E_star, rho) == pytest.approx(1.0, abs=0.03)


def test_restitution_values_and_limits():
    """e = 1 up to V_y and continuous there; DESIGN.md's 0.76 / 0.58 / 0.46 at 1 / 3 / 8 m/s for
    Y = 1 GPa (V_y 0.18 m/s); e ~ V^(-1/4) at high speed."""
    vy = yield_onset_velocity(1e9, 100e9, 7800.0)
    assert restitution_thornton(0.5 * vy, vy) == 1.0
    assert restitution_thornton(vy * (1 + 1e-9), vy) == pytest.approx(1.0, abs=1e-6)
    for v, e in ((1.0, 0.76), (3.0, 0.58), (8.0, 0.46)):
        assert restitution_thornton(v, vy) == pytest.approx(e, abs=0.01)
    hi = restitution_thornton([1e3 * vy, 1e4 * vy], vy)
    assert hi[1] / hi[0] == pytest.approx(10 ** -0.25, rel=1e-2)
