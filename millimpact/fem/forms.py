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


def mass(u, v, rho, dx):
    """Bilinear form of the consistent mass M: int rho u . v dx."""
    return rho * ufl.inner(u, v) * dx


def lumped_area(v, ds):
    """Linear form of nodal boundary areas (int_ds v, a scalar test function)."""
    return v * ds
