"""Nonlinear isotropic hardening laws as the flow curves the return map takes.

The return map (:mod:`millimpact.fem.plasticity`) solves the consistency condition exactly on a
piecewise-linear flow curve sigma_y(alpha). A smooth law is tabulated on it:

- Voce (E. Voce, J. Inst. Metals 74 (1948) 537): sigma_y = Y + Q (1 - exp(-b alpha)), saturating at
  Y + Q; the law of Hadfield steel's work hardening and of most metals at large strain;
- Swift (H. W. Swift, J. Mech. Phys. Solids 1 (1952) 1): sigma_y = K (eps0 + alpha)^n, growing
  without bound; its yield stress is K eps0^n.

Points: alpha_k = ALPHA_MAX (k / (N - 1))^2, k = 0..N-1 (dense where the curves bend most, near 0),
N = :data:`POINTS`. The error of linear interpolation on a segment of width h is at most
|sigma''| h^2 / 8; with these points it stays below 0.1 % of the flow stress up to ALPHA_MAX for
Voce with b <= 50 and Swift with eps0 >= 1e-3 (``tests/fem/test_hardening.py`` measures it: 0.05 %
at most). Beyond ALPHA_MAX the last segment continues (the flow curve's rule): Voce has saturated
there for b >= 2 (exp(-6) = 0.25 % of Q); a Swift law is overestimated a little (0.3 % at 3.5).
"""

from __future__ import annotations

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
