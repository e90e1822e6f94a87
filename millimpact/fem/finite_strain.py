"""Finite-strain J2 plasticity in logarithmic strain space, at a batch of quadrature points.

Kinematics (total Lagrangian: the reference configuration's coordinates X, ``Grad`` = d/dX):

    F = I + Grad u,   C = F^T F = sum_a lambda_a N_a (x) N_a,   E = 1/2 ln C = sum_a 1/2 ln(lambda_a) N_a (x) N_a,

E the Lagrangian logarithmic (Hencky) strain, (lambda_a, N_a) the eigenpairs of C.

Constitutive law: additive plasticity in the logarithmic strain space (C. Miehe, N. Apel and
M. Lambrecht, Comput. Methods Appl. Mech. Engrg. 191, 2002, 5383-5425, sections 2-3): E = E_e + E_p,
and the small-strain J2 law of :mod:`millimpact.fem.plasticity` with E in place of eps. Its stress
T = C (E - E_p) is work conjugate to E (T : dE is the power per reference volume), so the radial
return, the hardening, the strain-rate factor, the consistent moduli dT/dE and the plastic work
T : dE_p are the small-strain ones, unchanged. Where nothing yields the model is Hencky's
hyperelastic material; plastic flow keeps tr E_p = 0, so det F_p = 1 and the volume changes
elastically only (as in the multiplicative J2 model of J. C. Simo, Comput. Methods Appl. Mech.
Engrg. 99, 1992, 61-112, whose logarithmic stored energy it shares).

Stresses (Miehe et al. eq. 2.13): the second Piola-Kirchhoff stress S = T : P with P = 2 dE/dC.
In the eigenbasis of C the derivative of the isotropic tensor function 1/2 ln C is diagonal (the
Daleckii-Krein formula; Miehe and Lambrecht, Int. J. Numer. Meth. Engng. 52, 2001, 1885-1908):

    S~_ab = 2 theta_ab T~_ab,   theta_ab = (ln lambda_a - ln lambda_b) / (2 (lambda_a - lambda_b)),
    theta_aa = 1 / (2 lambda_a),

with X~ = N^T X N the components in that basis; equal eigenvalues take the limit (continuous, so any
orthonormal basis of a repeated eigenvalue gives the same S). The first Piola-Kirchhoff stress is
P1 = F S (its divergence balances the inertia in the reference configuration); the Kirchhoff stress
F S F^T reduces to T for coaxial E and T.

Tangent: A = dP1/dF (9 x 9, row i*3+j, column k*3+l) by forward differences of the whole update
(strain, return map, S, F S) in the nine components of F, step ``TANGENT_STEP``: the numerical
consistent tangent of C. Miehe (Comput. Methods Appl. Mech. Engrg. 134, 1996, 223-240). Its error,
of order ``TANGENT_STEP`` times d2P1/dF2 (~E) plus the return map's tolerance over the step, is
~1e-7 relative: below what a Newton iteration sees (tests/fem/test_finite_strain.py checks it
against central differences of the force).

Elastic energy per reference volume: psi = 1/2 (E - E_p) : C : (E - E_p) (Mandel vectors, J/m^3).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import SolverError
from .plasticity import J2Material, ReturnMapResult, from_mandel, return_map, to_mandel

#: the error of a point with det F <= 0
INVERTED = (
    "finite strain: a deformation gradient with det F <= 0 or not finite (an element turned inside out, "
    "or the step's iteration diverged): try a smaller time.dt_contact"
)
#: the forward-difference step of the numerical tangent (|F| ~ 1; the module docstring)
TANGENT_STEP = 1e-7
#: below this |lambda_a - lambda_b| / lambda_b the divided difference of ln takes its series
#: 1 - x/2 + x^2/3 (its error x^3/4 is below round-off)
_SERIES_BELOW = 1e-5


def log_strain(F: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(E (n, 6) Mandel, lambda (n, 3), N (n, 3, 3)) of deformation gradients F (n, 3, 3): the
    logarithmic strain E = 1/2 ln(F^T F) and the eigenpairs of C = F^T F (columns of N)."""
    F = np.asarray(F, dtype=float)
    C = np.swapaxes(F, 1, 2) @ F  # batched matmul: 4x faster than the equivalent einsum
    lam, N = np.linalg.eigh(C)
    # det F > 0: C = F^T F is positive for an element turned inside out too
    if not (np.all(lam > 0.0) and np.all(np.linalg.det(F) > 0.0)):
        raise SolverError(INVERTED)
    E = (N * (0.5 * np.log(lam))[:, None, :]) @ np.swapaxes(N, 1, 2)
    return to_mandel(E), lam, N


def log_divided_differences(lam: np.ndarray) -> np.ndarray:
    """theta_ab = (ln lambda_a - ln lambda_b) / (2 (lambda_a - lambda_b)) (n, 3, 3), the diagonal
    and the near-equal pairs by their limit 1 / (2 lambda): the eigenbasis components of dE/dC."""
    la, lb = lam[:, :, None], lam[:, None, :]
    x = (la - lb) / lb
    near = np.abs(x) < _SERIES_BELOW
    safe = np.where(near, 1.0, x)
    ratio = np.where(near, 1.0 - x / 2.0 + x * x / 3.0, np.log1p(safe) / safe)  # ln(1 + x) / x
    return 0.5 * ratio / lb


def second_piola_kirchhoff(T: np.ndarray, lam: np.ndarray, N: np.ndarray) -> np.ndarray:
    """S = T : 2 dE/dC (n, 3, 3) of the stresses T (n, 6 Mandel) conjugate to E = 1/2 ln C, C's
    eigenpairs (lam, N) given: S~_ab = 2 theta_ab T~_ab in the eigenbasis."""
    Nt = np.swapaxes(N, 1, 2)
    Tt = Nt @ from_mandel(T) @ N
    return N @ (2.0 * log_divided_differences(lam) * Tt) @ Nt


@dataclass(frozen=True)
class FiniteStrainUpdate:
    """The finite-strain state of a batch of points: the first Piola-Kirchhoff stress (n, 3, 3) Pa,
    the log-space return map (its ``stress`` is T, Mandel), the log strain E (n, 6) and, when asked,
    the tangent dP1/dF (n, 9, 9) Pa."""

    first_pk: np.ndarray
    state: ReturnMapResult
    log_strain: np.ndarray
    tangent: np.ndarray | None


def _first_pk(material, F, plastic_strain, alpha, dt):
    E, lam, N = log_strain(F)
    res = return_map(material, E, plastic_strain, alpha, tangent=False, dt=dt)
    return F @ second_piola_kirchhoff(res.stress, lam, N), res, E


def finite_strain_update(
    material: J2Material,
    F: np.ndarray,
    plastic_strain: np.ndarray,
    alpha: np.ndarray,
    tangent: bool = False,
    dt: float | None = None,
) -> FiniteStrainUpdate:
    """The return map in log strain space of deformation gradients F (n, 3, 3) from the committed
    state (E_p (n, 6), alpha (n,)): P1 = F S(T) and (``tangent``) dP1/dF by forward differences."""
    F = np.asarray(F, dtype=float)
    P1, res, E = _first_pk(material, F, plastic_strain, alpha, dt)
    A = None
    if tangent:
        n = len(F)
        Fh = np.repeat(F[None], 9, axis=0)  # (9, n, 3, 3): F perturbed in component kl
        for kl in range(9):
            Fh[kl, :, kl // 3, kl % 3] += TANGENT_STEP
        Ph, _, _ = _first_pk(
            material,
            Fh.reshape(9 * n, 3, 3),
            np.tile(plastic_strain, (9, 1)),
            np.tile(alpha, 9),
            dt,
        )
        dP = (Ph.reshape(9, n, 9) - P1.reshape(1, n, 9)) / TANGENT_STEP  # [kl, p, ij]
        A = np.transpose(dP, (1, 2, 0)).copy()  # [p, ij, kl]
    return FiniteStrainUpdate(P1, res, E, A)


def stored_energy(material: J2Material, E: np.ndarray, plastic_strain: np.ndarray) -> np.ndarray:
    """psi = 1/2 (E - E_p) : C : (E - E_p) (n,) J per reference m^3 (Hencky's stored energy)."""
    Ee = np.asarray(E, dtype=float) - np.asarray(plastic_strain, dtype=float)
    return 0.5 * np.einsum("pi,pi->p", Ee, material.elastic_stress(Ee))


def small_strain_stress(material: J2Material, grad_u: np.ndarray) -> np.ndarray:
    """C : sym(Grad u) (n, 3, 3) Pa: the linear stress the model's elastic K integrates."""
    eps = 0.5 * (grad_u + np.swapaxes(grad_u, 1, 2))
    return from_mandel(material.elastic_stress(to_mandel(eps)))


def small_strain_moduli(material: J2Material) -> np.ndarray:
    """The 9 x 9 matrix of Grad u -> C : sym(Grad u) (Pa): d(linear stress)/d(Grad u)."""
    lam = material.bulk_modulus - 2.0 * material.shear_modulus / 3.0
    mu = material.shear_modulus
    d = np.eye(3)
    A = lam * np.einsum("ij,kl->ijkl", d, d) + mu * (np.einsum("ik,jl->ijkl", d, d) + np.einsum("il,jk->ijkl", d, d))
    return A.reshape(9, 9)
