"""Thornton's analytical model of the normal impact of an elastic-perfectly-plastic sphere.

C. Thornton, "Coefficient of restitution for collinear collisions of elastic-perfectly plastic
spheres", J. Appl. Mech. 64 (1997) 383-386. The Hertz pressure is capped at the limiting contact
pressure p_y (taken, as in DESIGN.md section 7, as the first-yield pressure 1.6 Y of a von Mises
material with nu = 0.3, Johnson, Contact Mechanics, 1985, section 6.2). Plastic deformation starts
at the yield-onset speed

    V_y = 1.56 (p_y^5 / (E*^4 rho))^(1/2)                      (Thornton 1997, eq. 13)

(the speed at which the Hertz impact's peak pressure reaches p_y: 1.56 = 3.194 / sqrt(4 pi / 3)),
and above it (r = V_y / V < 1) the coefficient of restitution is

    e = (6 sqrt(3) / 5)^(1/2) (1 - r^2 / 6)^(1/2) [ r / (r + 2 (6/5 - r^2/5)^(1/2)) ]^(1/4)
                                                              (Thornton 1997, eq. 26)

e = 1 for V <= V_y, and e ~ V^(-1/4) at high speed. Thornton's flat-topped pressure over-dissipates:
finite-element restitutions of steel spheres lie markedly higher (tens of percent at V/V_y ~ 10-50;
Wu, Li & Thornton, Int. J. Impact Eng. 32 (2005) 593-604), so the curve is a lower bound to read
finite-element results against, not their target.
"""
from __future__ import annotations

import math

import numpy as np

#: first-yield pressure of a Hertz contact in units of the yield stress (von Mises, nu = 0.3)
FIRST_YIELD_PRESSURE_FACTOR = 1.60


def yield_onset_velocity(yield_stress: float, e_star: float, density: float,
                         pressure_factor: float = FIRST_YIELD_PRESSURE_FACTOR) -> float:
    """V_y (m/s) of a sphere of ``density`` (kg/m^3) on a flat, contact modulus ``e_star`` (Pa):
    the Hertz peak pressure reaches p_y = pressure_factor * yield_stress (Pa)."""
    p_y = pressure_factor * yield_stress
    return 1.56 * math.sqrt(p_y**5 / (e_star**4 * density))


def restitution_thornton(speed, v_y: float):
    """Thornton's e(V) for impact speed(s) ``speed`` (m/s) above the yield-onset speed ``v_y``
    (1 at or below it). Accepts a number or an array."""
    v = np.asarray(speed, dtype=float)
    r = np.minimum(v_y / np.maximum(v, 1e-300), 1.0)
    e = (math.sqrt(6.0 * math.sqrt(3.0) / 5.0) * np.sqrt(1.0 - r**2 / 6.0)
         * (r / (r + 2.0 * np.sqrt(6.0 / 5.0 - r**2 / 5.0))) ** 0.25)
    e = np.where(v <= v_y, 1.0, e)
    return float(e) if e.ndim == 0 else e
