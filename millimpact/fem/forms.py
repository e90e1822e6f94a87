"""UFL form factories: small-strain linear elasticity and inertia. Imports UFL and dolfinx.fem only."""

from __future__ import annotations

import ufl


def epsilon(u):
    """Small strain tensor sym(grad u)."""
    return ufl.sym(ufl.grad(u))


def sigma(u, mu, lmbda):
    """Cauchy stress of isotropic linear elasticity, Pa: 2 mu eps + lambda tr(eps) I."""
    eps = epsilon(u)
    return 2.0 * mu * eps + lmbda * ufl.tr(eps) * ufl.Identity(len(u))


def elastic_stiffness(u, v, mu, lmbda, dx):
    """Bilinear form of the stiffness K: int sigma(u) : eps(v) dx."""
    return ufl.inner(sigma(u, mu, lmbda), epsilon(v)) * dx


def winkler_foundation(u, v, k_n, n, ds):
    """Bilinear form of an elastic (Winkler) foundation of normal stiffness per area k_n (Pa/m) under
    the facets of ``ds`` with unit normal n: int k_n (u . n)(v . n) ds (E. Winkler 1867; a bed of
    independent normal springs, no shear: a rubber backing sheet between liner and shell)."""
    return k_n * ufl.dot(u, n) * ufl.dot(v, n) * ds


def mass(u, v, rho, dx):
    """Bilinear form of the consistent mass M: int rho u . v dx."""
    return rho * ufl.inner(u, v) * dx


def lumped_area(v, ds):
    """Linear form of nodal boundary areas (int_ds v, a scalar test function)."""
    return v * ds
