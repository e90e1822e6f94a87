"""Thornton's analytical model of the normal impact of an elastic-perfectly-plastic sphere.

C. Thornton, "Coefficient of restitution for collinear collisions of elastic-perfectly plastic
spheres", J. Appl. Mech. 64 (1997) 383-386. The Hertz pressure is capped at the limiting contact
pressure p_y (taken, as in foundations.md section 7, as the first-yield pressure 1.6 Y of a von Mises
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


def yield_onset_velocity(
    yield_stress: float, e_star: float, density: float, pressure_factor: float = FIRST_YIELD_PRESSURE_FACTOR
) -> float:
    """V_y (m/s) of a sphere of ``density`` (kg/m^3) on a flat, contact modulus ``e_star`` (Pa):
    the Hertz peak pressure reaches p_y = pressure_factor * yield_stress (Pa)."""
    p_y = pressure_factor * yield_stress
    return 1.56 * math.sqrt(p_y**5 / (e_star**4 * density))


def restitution_thornton(speed, v_y: float):
    """Thornton's e(V) for impact speed(s) ``speed`` (m/s) above the yield-onset speed ``v_y``
    (1 at or below it). Accepts a number or an array."""
    v = np.asarray(speed, dtype=float)
    r = np.minimum(v_y / np.maximum(v, 1e-300), 1.0)
    e = (
        math.sqrt(6.0 * math.sqrt(3.0) / 5.0)
        * np.sqrt(1.0 - r**2 / 6.0)
        * (r / (r + 2.0 * np.sqrt(6.0 / 5.0 - r**2 / 5.0))) ** 0.25
    )
    e = np.where(v <= v_y, 1.0, e)
    return float(e) if e.ndim == 0 else e


def max_approach_thornton(radius: float, mass: float, speed: float, e_star: float, p_y: float) -> float:
    """The largest approach delta_max (m) of Thornton's loading law: Hertz up to the approach
    delta_y = R (pi p_y / (2 E*))^2 where the peak pressure reaches p_y, then the flat-topped
    pressure's linear law F = F_y + pi p_y R (delta - delta_y) (Thornton 1997, eqs. 8-11); the
    ball's kinetic energy m V^2 / 2 (``mass`` the impacting mass, kg) is its work to delta_max:

        m V^2 / 2 = (8/15) E* R^(1/2) delta_y^(5/2) + F_y s + pi p_y R s^2 / 2,   s = delta_max - delta_y.

    Below the yield onset it is Hertz's delta_max."""
    d_y = radius * (math.pi * p_y / (2.0 * e_star)) ** 2
    w_y = 8.0 / 15.0 * e_star * math.sqrt(radius) * d_y**2.5
    energy = 0.5 * mass * speed**2
    if energy <= w_y:
        return (15.0 * mass * speed**2 / (16.0 * e_star * math.sqrt(radius))) ** 0.4
    f_y = 4.0 / 3.0 * e_star * math.sqrt(radius) * d_y**1.5
    k = math.pi * p_y * radius
    s = (-f_y + math.sqrt(f_y**2 + 2.0 * k * (energy - w_y))) / k
    return d_y + s


def plastic_zone_radius(
    radius: float, mass: float, speed: float, e_star: float, yield_stress: float, nu: float = 0.3
) -> tuple[float, float]:
    """(a_p, c): the largest contact radius a_p = (R delta_max)^(1/2) of Thornton's law
    (:func:`max_approach_thornton`, p_y = 1.6 Y) and the radius c of the plastic zone under it
    from Johnson's expanding-cavity model of a spherical indenter (Johnson, Contact Mechanics,
    1985, section 6.3, eq. 6.40 with tan(beta) = a / R and E* for an elastic indenter):

        (c / a)^3 = [E* a / (Y R) + 4 (1 - 2 nu)] / (6 (1 - nu))

    both in m; c is measured from the first contact point (the core's centre). Below the
    yield onset there is no plastic zone: c = 0. The model is for the fully plastic regime
    (E* a / (Y R) >~ 3); near the onset (a subsurface plastic core) it over-estimates c, which
    errs on the safe side when c sizes the contact zone."""
    p_y = FIRST_YIELD_PRESSURE_FACTOR * yield_stress
    d = max_approach_thornton(radius, mass, speed, e_star, p_y)
    a = math.sqrt(radius * d)
    d_y = radius * (math.pi * p_y / (2.0 * e_star)) ** 2
    if d <= d_y * (1.0 + 1e-12):
        return a, 0.0
    ratio3 = (e_star * a / (yield_stress * radius) + 4.0 * (1.0 - 2.0 * nu)) / (6.0 * (1.0 - nu))
    return a, a * ratio3 ** (1.0 / 3.0)


#: mean contact pressure of a fully plastic spherical indentation in units of the yield stress
#: (Tabor's H ~ 3 Y; Johnson, Contact Mechanics, 1985, section 6.2 and Fig. 6.9: p_m ~ 2.8-3 Y)
FULLY_PLASTIC_PRESSURE_FACTOR = 3.0


def fully_plastic_contact_radius(radius: float, mass: float, speed: float, mean_pressure: float) -> float:
    """The largest contact radius a (m) of a fully plastic impact: the ball's kinetic energy
    m V^2 / 2 (``mass`` kg, ``speed`` m/s) is the work of a constant mean pressure p_m
    (``mean_pressure``, Pa; FULLY_PLASTIC_PRESSURE_FACTOR x Y) over the dent volume
    pi a^4 / (4 R) of a truncated sphere, a^2 = 2 R delta (Johnson, Contact Mechanics, 1985,
    section 11.4, after Tabor's dynamic hardness):

        m V^2 / 2 = p_m pi a^4 / (4 R),   a = (2 R m V^2 / (pi p_m))^(1/4).

    Thornton's law at high speed is the same balance with a^2 = R delta and p_m = p_y (1.6 Y), so
    the two radii coincide for p_m = 2 p_y; with p_m = 3 Y the fully plastic radius is
    (3.2 / 3)^(1/4) = 1.016 x Thornton's (1.6 Y) one at high speed. Elastic work and pile-up are neglected."""
    return (2.0 * radius * mass * speed**2 / (math.pi * mean_pressure)) ** 0.25
