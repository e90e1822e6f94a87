"""Nonlinear isotropic hardening laws as the flow curves the return map takes.

The return map (:mod:`millimpact.fem.plasticity`) solves the consistency condition exactly on a
piecewise-linear flow curve sigma_y(alpha). A smooth law is tabulated on it:

- Voce (E. Voce, J. Inst. Metals 74 (1948) 537): sigma_y = Y + Q (1 - exp(-b alpha)), saturating at
  Y + Q; the law of Hadfield steel's work hardening and of most metals at large strain;
- Swift (H. W. Swift, J. Mech. Phys. Solids 1 (1952) 1): sigma_y = K (eps0 + alpha)^n, growing
  without bound; its yield stress is K eps0^n.

A law is fixed by a tensile test (:func:`swift_from_tensile`, :func:`voce_from_tensile`): the 0.2 %
yield stress Y, the tensile strength S_u and the uniform elongation e_u (engineering strain at the
largest load) give the true stress at necking sigma_u = S_u (1 + e_u) at the plastic strain
alpha_u = ln(1 + e_u) - sigma_u / E, where Considere's condition d sigma / d eps = sigma holds
(A. Considere, Ann. Ponts Chaussees 9 (1885) 574; Dieter, Mechanical Metallurgy, 3rd ed. 1986,
8-3; d sigma / d alpha taken for d sigma / d eps, the elastic share of the strain increment being
sigma / E < 1 % of it). Three conditions, three constants:

- Swift: K eps0^n = Y, K (eps0 + alpha_u)^n = sigma_u, n = eps0 + alpha_u; so eps0 solves
  (eps0 + alpha_u) ln(1 + alpha_u / eps0) = ln(sigma_u / Y), which has a root when
  ln(sigma_u / Y) > alpha_u;
- Voce: Y + Q (1 - exp(-b alpha_u)) = sigma_u, Q b exp(-b alpha_u) = sigma_u; so x = b alpha_u
  solves (e^x - 1) / x = (sigma_u - Y) / (sigma_u alpha_u), which has a root when the right side
  exceeds 1, and Q = sigma_u e^x / b.

A steel that necks too early for its hardening (neither condition holds) cannot be described by
either law with its yield at Y; the functions say so (ValueError).

Points: alpha_k = ALPHA_MAX (k / (N - 1))^2, k = 0..N-1 (dense where the curves bend most, near 0),
N = :data:`POINTS`. The error of linear interpolation on a segment of width h is at most
|sigma''| h^2 / 8; with these points it stays below 0.1 % of the flow stress up to ALPHA_MAX for
Voce with b <= 50 and Swift with eps0 >= 1e-3 (``tests/fem/test_hardening.py`` measures it: 0.05 %
at most). Beyond ALPHA_MAX the last segment continues (the flow curve's rule): Voce has saturated
there for b >= 2 (exp(-6) = 0.25 % of Q); a Swift law is overestimated a little (0.3 % at 3.5).
"""

from __future__ import annotations

import math

import numpy as np

#: tabulation: the largest equivalent plastic strain and the number of points
ALPHA_MAX = 3.0
POINTS = 400


def strains() -> np.ndarray:
    """The tabulation's equivalent plastic strains (module docstring)."""
    return ALPHA_MAX * (np.arange(POINTS) / (POINTS - 1)) ** 2


def voce_stress(alpha: np.ndarray, yield_stress: float, q: float, b: float) -> np.ndarray:
    """sigma_y = Y + Q (1 - exp(-b alpha)), Pa."""
    return yield_stress + q * (1.0 - np.exp(-b * np.asarray(alpha)))


def swift_stress(alpha: np.ndarray, k: float, eps0: float, n: float) -> np.ndarray:
    """sigma_y = K (eps0 + alpha)^n, Pa."""
    return k * (eps0 + np.asarray(alpha)) ** n


def tabulated(material) -> tuple[tuple[float, float], ...] | None:
    """The material's flow curve as [alpha, sigma_y] pairs: its own table, or its Voce or Swift
    law tabulated; None when it has neither (linear hardening or elastic)."""
    if material.flow_curve is not None:
        return tuple((float(a), float(s)) for a, s in material.flow_curve)
    a = strains()
    if material.voce is not None:
        q, b = material.voce
        s = voce_stress(a, float(material.yield_stress), float(q), float(b))
    elif material.swift is not None:
        s = swift_stress(a, *(float(x) for x in material.swift))
    else:
        return None
    return tuple(zip(a.tolist(), s.tolist()))


def _necking(yield_stress: float, tensile_strength: float, uniform_elongation: float, youngs_modulus: float):
    """(sigma_u, alpha_u): the true stress and plastic strain at the largest load (module docstring)."""
    if not (0 < yield_stress <= tensile_strength and uniform_elongation > 0 and youngs_modulus > 0):
        raise ValueError("a tensile test needs 0 < Y <= S_u, e_u > 0 and E > 0")
    sigma_u = tensile_strength * (1.0 + uniform_elongation)
    alpha_u = math.log1p(uniform_elongation) - sigma_u / youngs_modulus
    if alpha_u <= 0:
        raise ValueError(
            f"uniform elongation {uniform_elongation:g} is elastic (sigma_u / E {sigma_u / youngs_modulus:.3g})"
        )
    return sigma_u, alpha_u


def swift_from_tensile(
    yield_stress: float, tensile_strength: float, uniform_elongation: float, youngs_modulus: float
) -> tuple[float, float, float]:
    """[K (Pa), eps0, n] of the Swift law through a tensile test's Y, S_u and e_u (module docstring)."""
    sigma_u, alpha_u = _necking(yield_stress, tensile_strength, uniform_elongation, youngs_modulus)
    target = math.log(sigma_u / yield_stress)
    if target <= alpha_u:
        raise ValueError(
            f"ln(sigma_u / Y) = {target:.4g} <= alpha_u = {alpha_u:.4g}: no Swift law necks at e_u with its yield at Y"
        )
    from scipy.optimize import brentq

    # g decreases from +inf (eps0 -> 0) towards alpha_u - target < 0 (eps0 -> inf)
    eps0 = brentq(lambda e0: (e0 + alpha_u) * math.log1p(alpha_u / e0) - target, 1e-12, 1e6, xtol=1e-16, rtol=1e-14)
    n = eps0 + alpha_u
    return sigma_u / n**n, eps0, n


def voce_from_tensile(
    yield_stress: float, tensile_strength: float, uniform_elongation: float, youngs_modulus: float
) -> tuple[float, float]:
    """[Q (Pa), b] of the Voce law with yield Y through a tensile test's S_u and e_u (module
    docstring)."""
    sigma_u, alpha_u = _necking(yield_stress, tensile_strength, uniform_elongation, youngs_modulus)
    r = (sigma_u - yield_stress) / (sigma_u * alpha_u)
    if r <= 1.0:
        raise ValueError(
            f"(sigma_u - Y) / (sigma_u alpha_u) = {r:.4g} <= 1: no Voce law necks at e_u with its yield at Y"
        )
    from scipy.optimize import brentq

    x = brentq(lambda x: math.expm1(x) / x - r, 1e-12, 700.0, xtol=1e-16, rtol=1e-14)
    b = x / alpha_u
    return sigma_u * math.exp(x) / b, b
