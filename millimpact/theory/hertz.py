"""Hertz contact of a sphere on a flat: the analytical reference and the lightest model.

References: K. L. Johnson, *Contact Mechanics* (1985), sections 3.4 (static contact, subsurface
stresses on the axis, eq. 3.45) and 11.4 (quasi-static impact). All quantities SI.

- 1/E* = (1-nu1^2)/E1 + (1-nu2^2)/E2, k = (4/3) E* sqrt(R)
- delta_max = (15 m v^2 / (16 E* sqrt(R)))^(2/5), F_max = k delta_max^(3/2), a_max = sqrt(R delta_max),
  p0 = 3 F / (2 pi a^2), t_c = 2.9432 delta_max / v
- the force history integrates m x'' = -k x^(3/2) (scipy), from first touch to separation.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import NamedTuple

import numpy as np
from scipy import integrate, optimize

#: t_c = T_C_FACTOR * delta_max / v: 2 * int_0^1 ds / sqrt(1 - s^(5/2)) (Johnson eq. 11.24).
T_C_FACTOR = 2.0 * integrate.quad(lambda s: 1.0 / math.sqrt(1.0 - s**2.5), 0.0, 1.0)[0]


def effective_modulus(m1, m2) -> float:
    """Contact modulus E* (Pa): 1/E* = (1-nu1^2)/E1 + (1-nu2^2)/E2, of two materials with
    ``youngs_modulus`` (Pa) and ``poisson`` attributes."""
    return 1.0 / ((1 - m1.poisson**2) / m1.youngs_modulus + (1 - m2.poisson**2) / m2.youngs_modulus)


class HertzStatic(NamedTuple):
    """Static Hertz contact under force F (N): contact radius a (m), approach delta (m), peak pressure p0 (Pa)."""

    force: float
    a: float
    delta: float
    p0: float


def hertz_static(force: float, radius: float, e_star: float) -> HertzStatic:
    """Sphere of radius R pressed on a half-space with force F (Johnson 3.4)."""
    a = (3.0 * force * radius / (4.0 * e_star)) ** (1.0 / 3.0)
    return HertzStatic(force, a, a * a / radius, 3.0 * force / (2.0 * math.pi * a * a))


def max_shear_on_axis(nu: float) -> tuple[float, float]:
    """Maximum of the principal shear stress tau_1 on the contact axis (Johnson eq. 3.45).

    Returns (tau_max / p0, depth / a); (0.31, 0.48) for nu = 0.3.
    """

    def minus_tau(zeta: float) -> float:
        sz = -1.0 / (1.0 + zeta**2)
        sr = -(1.0 + nu) * (1.0 - zeta * math.atan(1.0 / zeta)) + 0.5 / (1.0 + zeta**2)
        return -0.5 * abs(sr - sz)

    res = optimize.minimize_scalar(minus_tau, bounds=(1e-6, 3.0), method="bounded", options={"xatol": 1e-10})
    return -res.fun, res.x


class HertzImpact(NamedTuple):
    """Quasi-static Hertz impact of a sphere on a half-space (SI units)."""

    radius: float  #: ball radius R, m
    mass: float  #: (effective) impacting mass, kg
    speed: float  #: normal approach speed v, m/s
    e_star: float  #: contact modulus E*, Pa
    k: float  #: Hertz stiffness (4/3) E* sqrt(R), N/m^1.5
    delta_max: float  #: maximum approach, m
    force_max: float  #: peak contact force, N
    contact_time: float  #: contact duration t_c, s
    a_max: float  #: maximum contact radius, m
    p0: float  #: peak contact pressure, Pa
    tau_max: float  #: maximum subsurface principal shear (target side), Pa
    tau_depth: float  #: its depth below the surface, m
    energy: float  #: impact kinetic energy m v^2 / 2, J

    def table(self) -> list[tuple[str, float, str, float]]:
        """Rows (name, value in display unit, unit, SI value) for printing."""
        return [
            ("ball radius R", self.radius * 1e3, "mm", self.radius),
            ("impacting mass m", self.mass * 1e3, "g", self.mass),
            ("normal speed v", self.speed, "m/s", self.speed),
            ("contact modulus E*", self.e_star / 1e9, "GPa", self.e_star),
            ("max approach delta_max", self.delta_max * 1e6, "um", self.delta_max),
            ("peak force F_max", self.force_max / 1e3, "kN", self.force_max),
            ("contact time t_c", self.contact_time * 1e6, "us", self.contact_time),
            ("contact radius a_max", self.a_max * 1e3, "mm", self.a_max),
            ("peak pressure p0", self.p0 / 1e9, "GPa", self.p0),
            ("max shear tau_max", self.tau_max / 1e9, "GPa", self.tau_max),
            ("depth of tau_max", self.tau_depth * 1e3, "mm", self.tau_depth),
            ("impact energy", self.energy, "J", self.energy),
        ]


def hertz_impact(radius: float, mass: float, speed: float, e_star: float, nu_target: float = 0.3) -> HertzImpact:
    """Closed-form Hertz impact values (Johnson 11.4); the subsurface shear is the target's (nu_target)."""
    k = 4.0 / 3.0 * e_star * math.sqrt(radius)
    delta = (15.0 * mass * speed**2 / (16.0 * e_star * math.sqrt(radius))) ** 0.4
    f_max = k * delta**1.5
    a = math.sqrt(radius * delta)
    p0 = 3.0 * f_max / (2.0 * math.pi * a * a)
    tau_ratio, depth_ratio = max_shear_on_axis(nu_target)
    return HertzImpact(
        radius,
        mass,
        speed,
        e_star,
        k,
        delta,
        f_max,
        T_C_FACTOR * delta / speed,
        a,
        p0,
        tau_ratio * p0,
        depth_ratio * a,
        0.5 * mass * speed**2,
    )


class HertzHistory(NamedTuple):
    """Force-time history of a Hertz impact (time from first touch, s)."""

    time: np.ndarray  #: s
    force: np.ndarray  #: N
    approach: np.ndarray  #: m (>= 0 in contact)
    velocity: np.ndarray  #: approach rate, m/s (positive towards the target)
    acceleration: np.ndarray  #: of the ball towards the target, m/s^2
    contact_radius: np.ndarray  #: m
    contact_time: float  #: s, from the integration (not the closed form)
    rebound_speed: float  #: m/s


class FallingZeroEvent:
    """A :func:`scipy.integrate.solve_ivp` event that ends the integration (``terminal``) where
    ``fn(t, y)`` falls through 0 (``direction`` -1): scipy reads both attributes off the event."""

    terminal = True
    direction = -1

    def __init__(self, fn: Callable[[float, np.ndarray], float]) -> None:
        self.fn = fn

    def __call__(self, t: float, y: np.ndarray) -> float:
        return self.fn(t, y)


def hertz_history(h: HertzImpact, n: int = 401, rtol: float = 1e-11) -> HertzHistory:
    """Integrate m x'' = -k x^(3/2), x(0) = 0, x'(0) = v, until x returns to 0 (scipy RK45/DOP853).

    Returns ``n`` samples uniformly spaced over the contact.
    """
    c = h.k / h.mass

    def rhs(_t: float, y: np.ndarray) -> list[float]:
        return [y[1], -c * max(y[0], 0.0) ** 1.5]

    separated = FallingZeroEvent(lambda _t, y: y[0])  # the approach x = y[0] back to 0

    t_guess = 1.5 * h.contact_time
    sol = integrate.solve_ivp(
        rhs,
        (0.0, t_guess),
        [0.0, h.speed],
        method="DOP853",
        rtol=rtol,
        atol=1e-14 * h.speed,
        events=separated,
        dense_output=True,
        first_step=1e-4 * h.contact_time,
    )
    tc = float(sol.t_events[0][0]) if len(sol.t_events[0]) else float(sol.t[-1])
    t = np.linspace(0.0, tc, n)
    x, v = sol.sol(t)
    x = np.maximum(x, 0.0)
    f = h.k * x**1.5
    return HertzHistory(
        t,
        f,
        x,
        v,
        -f / h.mass,
        np.sqrt(h.radius * x),
        tc,
        float(-sol.y_events[0][0][1]) if len(sol.t_events[0]) else float("nan"),
    )


#: the mean over the half-ball of radius R of the Boussinesq displacement under a Hertz pressure of
#: contact radius a, over that of a point load of the same force: 1 - PATCH_HERTZ_SPREAD (a / R)^2
#: (a Monte Carlo fit for nu = 0.2-0.45, within 0.5 % for a <= R: 0.150-0.158 over that range)
PATCH_HERTZ_SPREAD = 0.155


def patch_mean_displacement(force, contact_radius, patch_radius: float, youngs: float, nu: float):
    """Quasi-static mean normal displacement (m) of the half-ball of radius R = ``patch_radius``
    under a Hertz pressure of total ``force`` (N) and contact radius a on an elastic half-space
    (E = ``youngs``, nu): the Boussinesq point-load field (Johnson 3.2),
    u_z = P (2 (1 - nu) / rho + z^2 / rho^3) / (4 pi G), averaged over the half-ball:

        <u_z> = kappa(nu) (1 - 0.155 (a / R)^2) P / (E R),
        kappa = 3 (1 + nu) (2 (1 - nu) + 1/3) / (4 pi)   (0.538 at nu = 0.3),

    the factor in a from spreading the load over the Hertz pressure (:data:`PATCH_HERTZ_SPREAD`).
    Its time derivatives, band-limited to 4 / t_c, are the quasi-static reference of the contact
    point's patch velocity and acceleration (:mod:`millimpact.results.band_limit`; docs:
    validation, "Contact-point kinematics"). Works on arrays."""
    kappa = 3.0 * (1.0 + nu) * (2.0 * (1.0 - nu) + 1.0 / 3.0) / (4.0 * math.pi)
    a = np.asarray(contact_radius, dtype=float) / patch_radius
    return kappa * (1.0 - PATCH_HERTZ_SPREAD * a * a) * np.asarray(force, dtype=float) / (youngs * patch_radius)
