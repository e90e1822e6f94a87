"""The Hertz-dashpot law that Yade, LIGGGHTS and LAMMPS share, and its parameters from a contact table.

The three codes' Hertz models with a restitution input e_in have one normal law (a ball of mass m
on a fixed liner; m_eff = m):

    F_n = max(0, k_no delta^(3/2) + zeta (m k_no)^(1/2) delta^(1/4) d(delta)/dt),   k_no = (4/3) E* R^(1/2)

with the damping ratio

    zeta = 5^(1/2) |ln e_in| / (ln^2 e_in + pi^2)^(1/2)                                     (1)

- Yade 2023.02a, ``Ip2_FrictMat_FrictMat_MindlinPhys(en=e_in)`` + ``Law2_ScGeom_MindlinPhys_Mindlin``
  (pkg/dem/HertzMindlin.cpp): alpha = -2 (5/6)^(1/2) ln e / (ln^2 e + pi^2)^(1/2) (2 E* R^(1/2))^(1/2),
  c_n = alpha m^(1/2) delta^(1/4); zeta = alpha / k_no^(1/2) = (1) (Debian's 2023.02a measures 1.05 x (1):
  en = 0.8 gives e = 0.7999 with NewtonIntegrator(damping=0), not 0.808). The normal force is set to zero
  when the damping would make it attractive. With ``betan`` instead of ``en`` (the mode the export
  uses, settable per interaction): c_n = 2 betan (m k_n)^(1/2), k_n = (3/2) k_no delta^(1/2), so
  zeta = 6^(1/2) betan; tangential c_s = 2 betas (m k_s)^(1/2), k_s = k_so delta^(1/2).
- LIGGGHTS ``model hertz`` (gran_model_hertz): k_n = (4/3) Y* (R* delta)^(1/2),
  gamma_n = -2 (5/6)^(1/2) beta (S_n m*)^(1/2), S_n = 2 Y* (R* delta)^(1/2), beta = ln e /
  (ln^2 e + pi^2)^(1/2): the same (1); ``limitForce on`` gives the same non-attractive force.
- LAMMPS ``pair_style granular``, ``hertz/material ... damping coeff_restitution``:
  eta_n = -2 (5/6)^(1/2) ln e / (pi^2 + ln^2 e)^(1/2) ((3/2) k_nd m_eff)^(1/2), k_nd = (4/3) E a,
  a = (R delta)^(1/2): the same (1); ``limit_damping`` gives the non-attractive force.

Relation (1) is the linear spring-dashpot's e(beta) carried over to the Hertz spring. For the Hertz
law the restitution it gives is independent of the impact speed but is not e_in (Thornton,
Cummins & Cleary, Powder Technol. 233 (2013) 30-46, who integrated the contact numerically; Yade
with e_in = 0.8 returns 0.65 with its default damping, docs/dem.md). Here the law is integrated
exactly in its dimensionless form (delta = delta_0 x, t = (delta_0 / v) s, delta_0 = (m v^2 /
k_no)^(2/5)):

    x'' = -max(0, x^(3/2) + zeta x^(1/4) x'),   x(0) = 0, x'(0) = 1                          (2)

which gives e(zeta) = -x' at separation and the peak force F_max = phi(zeta) k_no^(2/5) (m v^2)^(3/5)
(phi(0) = (5/4)^(3/5), Hertz). Inverting it: zeta from the table's e_n, then k_no (and E*) from its
F_max, then e_in from (1) - at each of the table's speeds.
"""

from __future__ import annotations

import math
from functools import lru_cache
from typing import NamedTuple

import numpy as np

#: phi(0): the undamped Hertz impact's peak force in units of k_no^(2/5) (m v^2)^(3/5)
HERTZ_PEAK = 1.25**0.6
#: largest damping ratio tabulated (e(ZETA_MAX) ~ 0.1: restitutions below are refused)
ZETA_MAX = 3.0


@lru_cache(maxsize=1)
def _response_table(n: int = 601, h: float = 2e-4) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """e(zeta) and phi(zeta) of (2) on a grid of zeta in [0, ZETA_MAX], by RK4 in step h of s
    (the undamped contact lasts s = 3.22; h = 2e-4: e and phi converge to ~1e-7, checked by halving)."""
    zeta = np.linspace(0.0, ZETA_MAX, n)
    x = np.zeros(n)
    v = np.ones(n)
    e = np.full(n, np.nan)
    peak = np.zeros(n)
    live = np.ones(n, dtype=bool)

    def force(x, v):
        xp = np.maximum(x, 0.0)
        return np.maximum(0.0, xp**1.5 + zeta * xp**0.25 * v)

    for _ in range(200000):
        k1x, k1v = v, -force(x, v)
        k2x, k2v = v + 0.5 * h * k1v, -force(x + 0.5 * h * k1x, v + 0.5 * h * k1v)
        k3x, k3v = v + 0.5 * h * k2v, -force(x + 0.5 * h * k2x, v + 0.5 * h * k2v)
        k4x, k4v = v + h * k3v, -force(x + h * k3x, v + h * k3v)
        x = np.where(live, x + h / 6 * (k1x + 2 * k2x + 2 * k3x + k4x), x)
        v = np.where(live, v + h / 6 * (k1v + 2 * k2v + 2 * k3v + k4v), v)
        f = force(x, v)
        peak = np.where(live, np.maximum(peak, f), peak)
        # separation: back at x = 0, or the force has dropped to zero on the way out (from then on
        # the ball flies free: the velocity no longer changes)
        done = live & (v < 0) & ((x <= 0) | (f <= 0))
        e[done] = -v[done]
        live &= ~done
        if not live.any():
            break
    return zeta, e, peak


@lru_cache(maxsize=1)
def _interpolants():
    """Monotone cubic (PCHIP) interpolants e(zeta), phi(zeta) and zeta(e) of the tabulated law:
    within ~1e-8 of the RK4 values between the grid's points (linear interpolation: ~1e-5)."""
    from scipy.interpolate import PchipInterpolator

    z, e, p = _response_table()
    return PchipInterpolator(z, e), PchipInterpolator(z, p), PchipInterpolator(e[::-1], z[::-1])


def _call(f, x):
    out = f(np.asarray(x, dtype=float))
    return out if np.ndim(x) else float(out)


def restitution_of_damping(zeta):
    """The restitution e of the Hertz-dashpot law (2) with damping ratio ``zeta`` (scalar or array)."""
    return _call(_interpolants()[0], zeta)


def peak_force_factor(zeta):
    """phi(zeta): F_max / (k_no^(2/5) (m v^2)^(3/5)) of the law (2)."""
    return _call(_interpolants()[1], zeta)


def damping_for_restitution(e: float) -> float:
    """The damping ratio zeta of (2) that gives restitution ``e`` (e(ZETA_MAX) <= e <= 1)."""
    _, ee, _ = _response_table()
    if not (ee[-1] <= e <= 1.0):
        raise ValueError(f"{e:g} is outside [{ee[-1]:.3f}, 1], the restitutions the Hertz-dashpot law gives")
    return max(0.0, float(_interpolants()[2](e)))


def damping_of_code_restitution(e_in: float) -> float:
    """zeta of relation (1): what the codes make of a restitution input ``e_in``."""
    if e_in >= 1.0:
        return 0.0
    le = math.log(e_in)
    return math.sqrt(5.0) * abs(le) / math.sqrt(le * le + math.pi**2)


def code_restitution_for_damping(zeta: float) -> float:
    """The restitution input e_in whose relation (1) gives ``zeta`` (0 <= zeta < 5^(1/2))."""
    b = zeta / math.sqrt(5.0)
    if b <= 0.0:
        return 1.0
    if b >= 1.0:
        raise ValueError(f"damping ratio {zeta:g}: no restitution input gives it (relation (1) < 5^(1/2))")
    return math.exp(-math.pi * b / math.sqrt(1.0 - b * b))


def code_restitution(e_in: float) -> float:
    """The restitution the codes' Hertz law actually gives for an input ``e_in`` (e.g. 0.8 -> 0.65)."""
    return restitution_of_damping(damping_of_code_restitution(e_in))


class PointLaw(NamedTuple):
    """The Hertz-dashpot parameters that reproduce one table row (SI units)."""

    zeta: float  #: damping ratio of (2)
    e_in: float  #: restitution input of relation (1) (Yade en, LIGGGHTS, LAMMPS e)
    betan: float  #: Yade's betan (zeta / 6^(1/2))
    k_no: float  #: Hertz coefficient, N/m^1.5 (F = k_no delta^1.5)
    e_star: float  #: contact modulus E* = k_no / ((4/3) R^(1/2)), Pa
    restitution: float  #: the law's e_n (= the table's)
    peak_force: float  #: the law's F_max, N (= the table's)


def point_law(e_n: float, peak_force: float, normal_speed: float, mass: float, radius: float) -> PointLaw:
    """The law (2) that gives restitution ``e_n`` and peak force ``peak_force`` (N) to a ball of
    ``mass`` (kg) and ``radius`` (m) at normal speed ``normal_speed`` (m/s): zeta from e_n, then
    k_no from F_max = phi(zeta) k_no^(2/5) (m v^2)^(3/5)."""
    zeta = damping_for_restitution(min(e_n, 1.0))
    phi = peak_force_factor(zeta)
    k_no = (peak_force / (phi * (mass * normal_speed**2) ** 0.6)) ** 2.5
    e_star = k_no / (4.0 / 3.0 * math.sqrt(radius))
    return PointLaw(
        zeta,
        code_restitution_for_damping(zeta),
        zeta / math.sqrt(6.0),
        k_no,
        e_star,
        restitution_of_damping(zeta),
        phi * k_no**0.4 * (mass * normal_speed**2) ** 0.6,
    )
