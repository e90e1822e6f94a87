"""Small-strain J2 (von Mises) plasticity with isotropic hardening: the return map at a batch of
quadrature points, vectorised with numpy.

Notation: Mandel vectors of length 6, ``[xx, yy, zz, sqrt2 yz, sqrt2 xz, sqrt2 xy]``, for strain
and stress alike, so a double contraction is the plain dot product and the 6 x 6 tangent is
symmetric. The elastic law is sigma = C (eps - eps_p), C = 3 K P_vol + 2 G P_dev.

Yield function f = q - sigma_y(alpha), q = sqrt(3/2) |dev sigma| (the von Mises stress), alpha
the equivalent plastic strain (d alpha = sqrt(2/3) |d eps_p|), sigma_y the flow curve: linear
(``yield_stress + hardening_modulus * alpha``) or tabulated (piecewise linear through the given
(alpha, stress) points, continued with the last segment's slope).

Radial return (backward Euler; Simo & Hughes, Computational Inelasticity, 1998, Box 3.2 / 3.3.1;
de Souza Neto, Peric & Owen, Computational Methods for Plasticity, 2008, Box 7.3-7.4): the trial
stress sigma_tr = C (eps_{n+1} - eps_p,n); if f_tr = q_tr - sigma_y(alpha_n) > 0 the increment
dg solves q_tr - 3 G dg - sigma_y(alpha_n + dg) = 0 (one linear solve for linear hardening,
Newton per point for a tabulated curve), then n = sqrt(3/2) dev sigma_tr / q_tr (unit Mandel
vector), eps_p += sqrt(3/2) dg n, alpha += dg, sigma = sigma_tr - 2 G sqrt(3/2) dg n.

Strain rate (optional, ``J2Material.rate = (C, rate0)``): Johnson and Cook's factor (G. R. Johnson
and W. H. Cook, Proc. 7th Int. Symp. on Ballistics, The Hague, 1983, 541-547, eq. 1) multiplies
the flow stress, sigma_y(alpha) (1 + C ln(alpha_dot / rate0)) for alpha_dot > rate0 (1 below),
with alpha_dot = dg / dt over the step (backward Euler, the step ``dt`` the caller gives; none: the
rate-independent map). The consistency equation becomes q_tr - 3 G dg - sigma_y(alpha_n + dg)
R(dg) = 0, R = 1 + C ln(dg / (rate0 dt)); its root lies between rate0 dt and the rate-independent
dg (where the left side is <= 0), and a Newton iteration kept inside that bracket (bisection
where a step leaves it) finds it. In the tangent H becomes d (sigma_y R) / d dg = H R +
sigma_y C / dg.

Consistent tangent (de Souza Neto et al. eq. 7.120): at a yielding point

    C_t = C - 6 G^2 dg / q_tr P_dev + 6 G^2 (dg / q_tr - 1 / (3 G + H)) n (x) n,

with H = d sigma_y / d alpha at alpha_{n+1}; elastic points get C. Newton with this tangent
converges quadratically (tests/fem/test_plasticity.py checks it by finite differences).

Energy: the plastic work of the step ``sigma_{n+1} . (eps_p,{n+1} - eps_p,n)`` (J/m^3) is what the
time integrator books as plastic dissipation (it includes the cold work stored by hardening,
which the rebound cannot recover either); :meth:`FlowCurve.stored_energy` gives the hardening
part int_0^alpha (sigma_y - sigma_y0) d alpha.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

_S2 = math.sqrt(2.0)
#: the identity (second-order) in Mandel notation, and the volumetric / deviatoric projectors
IDENTITY = np.array([1.0, 1.0, 1.0, 0.0, 0.0, 0.0])
P_VOL = np.outer(IDENTITY, IDENTITY) / 3.0
P_DEV = np.eye(6) - P_VOL
#: Newton on the scalar consistency equation (tabulated curves): tolerance relative to the yield stress
CONSISTENCY_RTOL = 1e-12
CONSISTENCY_MAX_ITERATIONS = 50


class PlasticityError(RuntimeError):
    """The return map failed (the consistency equation did not converge at some points)."""


def to_mandel(t: np.ndarray) -> np.ndarray:
    """(n, 3, 3) symmetric tensors -> (n, 6) Mandel vectors."""
    t = np.asarray(t, dtype=float)
    return np.stack([t[:, 0, 0], t[:, 1, 1], t[:, 2, 2], _S2 * t[:, 1, 2], _S2 * t[:, 0, 2], _S2 * t[:, 0, 1]], axis=1)


def from_mandel(v: np.ndarray) -> np.ndarray:
    """(n, 6) Mandel vectors -> (n, 3, 3) symmetric tensors."""
    v = np.asarray(v, dtype=float)
    s = v[:, 3:] / _S2
    return np.stack(
        [
            np.stack([v[:, 0], s[:, 2], s[:, 1]], 1),
            np.stack([s[:, 2], v[:, 1], s[:, 0]], 1),
            np.stack([s[:, 1], s[:, 0], v[:, 2]], 1),
        ],
        axis=1,
    )


def deviator(v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(dev v, tr v) of (n, 6) Mandel vectors: dev v = v - (tr v / 3) I.

    numpy's elementwise operations on rows of 6 (broadcasting, axis sums) cost ~6 ns an entry,
    a product with P_DEV more: the trace is a BLAS product with I and the normal components are
    shifted as three long strided rows of the transpose (13,000 points: 0.3 against 0.55 ms)."""
    v = np.asarray(v, dtype=float)
    tr = v @ IDENTITY
    dev = v.copy()
    third = tr / 3.0
    for i in range(3):
        dev[..., i] -= third
    return dev, tr


def _norm6(v: np.ndarray) -> np.ndarray:
    """|v| of (n, 6) rows (np.linalg.norm(v, axis=1) to rounding; its generic path took 0.7 ms
    for 13,000 points, this 0.17 ms)."""
    return np.sqrt(np.square(v) @ np.ones(v.shape[-1]))


def von_mises(stress: np.ndarray) -> np.ndarray:
    """q = sqrt(3/2) |dev sigma| of (n, 6) Mandel stresses, Pa."""
    return np.sqrt(1.5) * _norm6(deviator(stress)[0])


@dataclass(frozen=True)
class FlowCurve:
    """Flow stress against equivalent plastic strain: linear (``yield_stress``, ``hardening_modulus``)
    or tabulated (``points``: (alpha, stress) pairs, alpha from 0 strictly increasing, stress
    positive and non-decreasing; its first stress is the initial yield stress)."""

    yield_stress: float
    hardening_modulus: float = 0.0
    points: tuple[tuple[float, float], ...] | None = None

    def __post_init__(self) -> None:
        if self.points is not None:
            pts = np.asarray(self.points, dtype=float)
            if pts.ndim != 2 or pts.shape[1] != 2 or len(pts) < 2:
                raise ValueError("flow_curve: must be at least two [plastic strain, stress] pairs")
            if not np.all(np.isfinite(pts)):
                raise ValueError("flow_curve: every value must be a finite number")
            if pts[0, 0] != 0.0:
                raise ValueError(f"flow_curve: must start at plastic strain 0 (starts at {pts[0, 0]:g})")
            if np.any(np.diff(pts[:, 0]) <= 0):
                raise ValueError("flow_curve: plastic strains must strictly increase")
            if pts[0, 1] <= 0 or np.any(np.diff(pts[:, 1]) < 0):
                raise ValueError("flow_curve: stresses must be > 0 and must not decrease (no softening)")
            object.__setattr__(self, "yield_stress", float(pts[0, 1]))
        if not (math.isfinite(self.yield_stress) and self.yield_stress > 0):
            raise ValueError(f"yield_stress = {self.yield_stress!r}: must be > 0 Pa")
        if not (math.isfinite(self.hardening_modulus) and self.hardening_modulus >= 0):
            raise ValueError(f"hardening_modulus = {self.hardening_modulus!r}: must be >= 0 Pa")

    def _table(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        pts = np.asarray(self.points, dtype=float)
        slopes = np.diff(pts[:, 1]) / np.diff(pts[:, 0])
        return pts[:, 0], pts[:, 1], np.append(slopes, slopes[-1])

    def segments(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(a_i, s_i, k_i): the curve as segments sigma_y = s_i + k_i (alpha - a_i) from a_i on (the
        last one continued); a linear curve is one segment (0, yield stress, hardening modulus)."""
        if self.points is None:
            return np.zeros(1), np.array([self.yield_stress]), np.array([self.hardening_modulus])
        return self._table()

    def flow_stress(self, alpha: np.ndarray) -> np.ndarray:
        """sigma_y(alpha), Pa."""
        alpha = np.asarray(alpha, dtype=float)
        if self.points is None:
            return self.yield_stress + self.hardening_modulus * alpha
        a, s, k = self._table()
        i = np.clip(np.searchsorted(a, alpha, side="right") - 1, 0, len(a) - 1)
        return s[i] + k[i] * (alpha - a[i])

    def slope(self, alpha: np.ndarray) -> np.ndarray:
        """H = d sigma_y / d alpha at alpha (the segment's slope; right-continuous), Pa."""
        alpha = np.asarray(alpha, dtype=float)
        if self.points is None:
            return np.full_like(alpha, self.hardening_modulus)
        a, _, k = self._table()
        return k[np.clip(np.searchsorted(a, alpha, side="right") - 1, 0, len(a) - 1)]

    def stored_energy(self, alpha: np.ndarray) -> np.ndarray:
        """int_0^alpha (sigma_y(a) - sigma_y(0)) da, J/m^3: the cold work hardening stores."""
        alpha = np.asarray(alpha, dtype=float)
        if self.points is None:
            return 0.5 * self.hardening_modulus * alpha**2
        grid = np.linspace(0.0, 1.0, 65)[None, :] * alpha[..., None]
        return np.trapz(self.flow_stress(grid) - self.yield_stress, grid, axis=-1)


@dataclass(frozen=True)
class J2Material:
    """Isotropic elasticity (Young's modulus, Poisson's ratio) and a J2 flow curve."""

    youngs_modulus: float
    poisson: float
    flow: FlowCurve
    rate: tuple[float, float] | None = None  #: Johnson-Cook's (C, reference rate 1/s), the module docstring

    @property
    def shear_modulus(self) -> float:
        return self.youngs_modulus / (2.0 * (1.0 + self.poisson))

    @property
    def bulk_modulus(self) -> float:
        return self.youngs_modulus / (3.0 * (1.0 - 2.0 * self.poisson))

    def elastic_matrix(self) -> np.ndarray:
        """C = 3 K P_vol + 2 G P_dev (6 x 6, Mandel), Pa."""
        return 3.0 * self.bulk_modulus * P_VOL + 2.0 * self.shear_modulus * P_DEV

    def elastic_stress(self, strain: np.ndarray) -> np.ndarray:
        """C eps = K tr(eps) I + 2 G dev(eps) of (n, 6) Mandel strains (Pa), elementwise: the
        product ``strain @ elastic_matrix()`` to rounding, without a 6 x 6 product per point."""
        dev, tr = deviator(strain)
        dev *= 2.0 * self.shear_modulus
        vol = self.bulk_modulus * tr
        for i in range(3):
            dev[..., i] += vol
        return dev


class ReturnMapResult(NamedTuple):
    """The state at the end of a step, per point: stress (n, 6) Pa, plastic strain (n, 6), alpha
    (n,), consistent tangent (n, 6, 6) Pa or None, yielding mask (n,), plastic work of the step
    (n,) J/m^3, and the step's plastic strain increment (n, 6; zero where the point stays elastic)."""

    stress: np.ndarray
    plastic_strain: np.ndarray
    alpha: np.ndarray
    tangent: np.ndarray | None
    yielding: np.ndarray
    dissipation_increment: np.ndarray
    plastic_increment: np.ndarray


def _consistency(flow: FlowCurve, q_tr: np.ndarray, alpha: np.ndarray, G: float) -> np.ndarray:
    """dg solving q_tr - 3 G dg - sigma_y(alpha + dg) = 0 (dg > 0 where the trial state yields)."""
    if flow.points is None:
        return (q_tr - flow.flow_stress(alpha)) / (3.0 * G + flow.hardening_modulus)
    dg = (q_tr - flow.flow_stress(alpha)) / (3.0 * G + flow.slope(alpha))
    tol = CONSISTENCY_RTOL * flow.yield_stress
    for _ in range(CONSISTENCY_MAX_ITERATIONS):
        r = q_tr - 3.0 * G * dg - flow.flow_stress(alpha + dg)
        if np.all(np.abs(r) <= tol):
            return dg
        dg = np.maximum(dg + r / (3.0 * G + flow.slope(alpha + dg)), 0.0)
    bad = int(np.count_nonzero(np.abs(q_tr - 3.0 * G * dg - flow.flow_stress(alpha + dg)) > tol))
    if bad == 0:
        return dg
    raise PlasticityError(f"return map: the consistency equation did not converge at {bad} point(s)")


def _consistency_with_rate(
    flow: FlowCurve, q_tr: np.ndarray, alpha: np.ndarray, G: float, c: float, dg0: float
) -> np.ndarray:
    """dg solving q_tr - 3 G dg - sigma_y(alpha + dg) (1 + c ln(dg / dg0)) = 0 where the
    rate-independent root exceeds dg0 = rate0 dt (that root elsewhere): Newton kept inside the
    bracket [dg0, rate-independent root] (the module docstring)."""
    hi = _consistency(flow, q_tr, alpha, G)
    dg = hi.copy()
    act = np.flatnonzero(hi > dg0)
    if not act.size:
        return dg
    q, al, lo, up = q_tr[act], alpha[act], np.full(act.size, dg0), hi[act].copy()
    x = up.copy()
    tol = CONSISTENCY_RTOL * flow.yield_stress
    for _ in range(4 * CONSISTENCY_MAX_ITERATIONS):
        rf = 1.0 + c * np.log(x / dg0)
        sy = flow.flow_stress(al + x)
        r = q - 3.0 * G * x - sy * rf
        if np.all(np.abs(r) <= tol):
            dg[act] = x
            return dg
        pos = r > 0
        lo = np.where(pos, x, lo)
        up = np.where(pos, up, x)
        step = x + r / (3.0 * G + flow.slope(al + x) * rf + sy * c / x)
        inside = (step > lo) & (step < up)
        x = np.where(inside, step, 0.5 * (lo + up))
    raise PlasticityError(
        f"return map: the rate-dependent consistency equation did not converge at {int(np.count_nonzero(np.abs(r) > tol))} point(s)"
    )


def rate_factor(material: J2Material, dg: np.ndarray, dt: float | None) -> np.ndarray:
    """Johnson-Cook's 1 + C ln(dg / (rate0 dt)) (1 where the rate is below rate0 or no rate is set)."""
    dg = np.asarray(dg, dtype=float)
    if material.rate is None or dt is None:
        return np.ones_like(dg)
    c, rate0 = material.rate
    ratio = np.maximum(dg / (rate0 * dt), 1.0)
    return 1.0 + c * np.log(ratio)


def return_map(
    material: J2Material,
    strain: np.ndarray,
    plastic_strain: np.ndarray,
    alpha: np.ndarray,
    tangent: bool = True,
    dt: float | None = None,
) -> ReturnMapResult:
    """Radial return of total strains ``strain`` (n, 6) from the committed state (plastic strain
    (n, 6), alpha (n,)); see the module docstring for the equations. ``tangent=False`` leaves the
    consistent tangent out (``None``): an iteration on the elastic operator needs none. ``dt`` (s):
    the step, for a material with a strain-rate factor (ignored without one)."""
    G, flow = material.shear_modulus, material.flow
    rate = material.rate if dt is not None else None  # (C, rate0) of a rate-dependent step
    strain, plastic_strain, alpha = (np.asarray(x, dtype=float) for x in (strain, plastic_strain, alpha))
    # the trial stress C (eps - eps_p), elementwise: dev sigma_tr = 2 G dev(eps - eps_p), so
    # q_tr = sqrt(3/2) 2 G |dev(eps - eps_p)| and n = dev / |dev|
    dev, tr = deviator(strain - plastic_strain)
    stress = 2.0 * G * dev
    vol = material.bulk_modulus * tr
    for i in range(3):
        stress[:, i] += vol
    dev_norm = _norm6(dev)
    q_tr = np.sqrt(1.5) * 2.0 * G * dev_norm
    yielding = q_tr - flow.flow_stress(alpha) > CONSISTENCY_RTOL * flow.yield_stress
    eps_p, alpha_new = plastic_strain.copy(), alpha.copy()
    deps_p = np.zeros_like(eps_p)
    C_t = np.repeat(material.elastic_matrix()[None], len(strain), axis=0) if tangent else None
    work = np.zeros(len(strain))
    y = np.flatnonzero(yielding)  # integer rows: a boolean mask gathers 10x slower when few yield
    if y.size:
        if rate is not None and dt is not None:
            dg = _consistency_with_rate(flow, q_tr[y], alpha[y], G, rate[0], rate[1] * dt)
        else:
            dg = _consistency(flow, q_tr[y], alpha[y], G)
        d = dev[y]
        d.T[...] *= np.sqrt(1.5) * dg / dev_norm[y]  # sqrt(3/2) dg n, n = dev / |dev| (unit Mandel normal)
        deps_p[y] = d
        stress_y = stress[y] - 2.0 * G * d
        stress[y] = stress_y
        eps_p[y] = eps_p[y] + d
        alpha_new[y] += dg
        if C_t is not None:  # the tangent asked for
            n = dev[y] / dev_norm[y, None]
            C = material.elastic_matrix()
            H = flow.slope(alpha_new[y])
            if rate is not None:  # d (sigma_y R) / d dg (the module docstring)
                rf = rate_factor(material, dg, dt)
                H = H * rf + np.where(rf > 1.0, flow.flow_stress(alpha_new[y]) * rate[0] / dg, 0.0)
            a = 6.0 * G * G * dg / q_tr[y]
            b = 6.0 * G * G * (dg / q_tr[y] - 1.0 / (3.0 * G + H))
            C_t[y] = C[None] - a[:, None, None] * P_DEV[None] + b[:, None, None] * np.einsum("pi,pj->pij", n, n)
        work[y] = (stress_y * d) @ np.ones(6)
    return ReturnMapResult(stress, eps_p, alpha_new, C_t, yielding, work, deps_p)


def flow_curve_from_fields(
    yield_stress: float | None, hardening_modulus: float = 0.0, points: Sequence[Sequence[float]] | None = None
) -> FlowCurve | None:
    """The flow curve of a material's scene fields (None: elastic)."""
    if points is not None:
        return FlowCurve(float(points[0][1]), 0.0, tuple((float(a), float(s)) for a, s in points))
    if yield_stress is None:
        return None
    return FlowCurve(float(yield_stress), float(hardening_modulus or 0.0))
