"""Finite-strain J2 in logarithmic strain space (millimpact/fem/finite_strain.py, finite_zone.py).

Point level, against exact results:
- a uniaxial stretch F = diag(l, 1, 1) of Hencky's material: P1_11 = (lambda + 2 mu) ln(l) / l;
- hyperelasticity: P1 = d psi / dF (central differences of the stored energy);
- objectivity: R F gives R P1 and the same plastic state; a rigid rotation gives no stress;
- the small-strain limit: P1 -> C : sym(Grad u) to second order in |Grad u|;
- isochoric compression to a true strain of -1 of a perfectly plastic material: the Kirchhoff
  (= Cauchy, J = 1) stress's von Mises value stays Y, no volume is lost plastically;
- the numerical tangent dP1/dF against central differences of P1 at yielding points.
Zone level (a cube, P1 and P2): the assembled force K u + f_c(u) is the derivative of the
elastic energy 1/2 u.K u + strain_energy_correction(u); dK is the derivative of f_c; an affine
displacement gives every quadrature point the point-level stress.
"""
from __future__ import annotations

import numpy as np
import pytest
from dolfinx import fem

from millimpact.fem.finite_strain import (
    finite_strain_update,
    log_strain,
    small_strain_stress,
    stored_energy,
)
from millimpact.fem.finite_zone import FiniteStrainZone
from millimpact.fem.plastic_zone import PlasticZone, ZoneMaterial
from millimpact.fem.plasticity import FlowCurve, J2Material, from_mandel, von_mises

from test_plastic_zone import _setup, _stiffness

E, NU, Y = 200e9, 0.3, 1e9
PLASTIC = J2Material(E, NU, FlowCurve(Y, 20e9))
PERFECT = J2Material(E, NU, FlowCurve(Y, 0.0))
ELASTIC = J2Material(E, NU, FlowCurve(1e30, 0.0))
LAME = ELASTIC.bulk_modulus - 2.0 * ELASTIC.shear_modulus / 3.0
RNG = np.random.default_rng(0)


def _update(material, F, n=None, **kw):
    n = len(F)
    return finite_strain_update(material, F, np.zeros((n, 6)), np.zeros(n), **kw)


def _rotation(theta, axis):
    a = np.asarray(axis, float) / np.linalg.norm(axis)
    K = np.array([[0, -a[2], a[1]], [a[2], 0, -a[0]], [-a[1], a[0], 0]])
    return np.eye(3) + np.sin(theta) * K + (1 - np.cos(theta)) * K @ K


@pytest.mark.parametrize("stretch", [0.6, 1.0 + 1e-9, 1.3, 2.0])
def test_uniaxial_stretch_is_hencky(stretch):
    """Exact to round-off (2e-16 relative): ln is evaluated as numpy's, nothing else is approximated."""
    P = _update(ELASTIC, np.diag([stretch, 1.0, 1.0])[None]).first_pk[0]
    exact = (LAME + 2 * ELASTIC.shear_modulus) * np.log(stretch) / stretch
    assert P[0, 0] == pytest.approx(exact, rel=1e-9, abs=1e-3)
    assert P[1, 1] == pytest.approx(LAME * np.log(stretch), rel=1e-9, abs=1e-3)


def test_first_piola_kirchhoff_is_the_energy_derivative():
    """Central differences at h = 1e-6 have error h^2 psi''' ~ 1e-12 E: 1e-8 relative is loose."""
    F = np.eye(3) + 0.08 * RNG.standard_normal((6, 3, 3))
    P = _update(ELASTIC, F).first_pk
    dpsi = np.zeros_like(P)
    zeros = np.zeros((len(F), 6))
    for k in range(3):
        for m in range(3):
            Fp, Fm = F.copy(), F.copy()
            Fp[:, k, m] += 1e-6
            Fm[:, k, m] -= 1e-6
            dpsi[:, k, m] = (stored_energy(ELASTIC, log_strain(Fp)[0], zeros)
                             - stored_energy(ELASTIC, log_strain(Fm)[0], zeros)) / 2e-6
    assert np.abs(dpsi - P).max() < 1e-8 * np.abs(P).max()


def test_equal_eigenvalues_take_the_limit():
    """A stretch with two equal principal values and one 1e-12 apart: S stays continuous (the
    divided difference's series, 1e-10 relative to a stretch 1e-3 away)."""
    base = np.diag([1.1, 1.1, 0.9])
    near = np.diag([1.1, 1.1 * (1 + 1e-12), 0.9])
    away = np.diag([1.1, 1.1 * (1 + 1e-3), 0.9])
    P0, P1, P2 = (_update(ELASTIC, F[None]).first_pk[0] for F in (base, near, away))
    assert np.all(np.isfinite(P0))
    assert np.abs(P1 - P0).max() < 1e-9 * np.abs(P0).max()
    assert np.abs(P2 - P0).max() > 1e-4 * np.abs(P0).max()  # the check can see a change


def test_objectivity_and_rigid_rotation():
    """Round-off bounds: eigh on C = F^T F loses ~1e-16 relative, times E / Y ~ 200 in the stress."""
    F = np.eye(3) + 0.02 * RNG.standard_normal((5, 3, 3))
    ref = _update(PLASTIC, F)
    assert ref.state.yielding.any()
    R = _rotation(1.1, [1.0, 2.0, -0.5])
    rot = _update(PLASTIC, np.einsum("ij,pjk->pik", R, F))
    assert np.abs(rot.first_pk - np.einsum("ij,pjk->pik", R, ref.first_pk)).max() < 1e-10 * np.abs(ref.first_pk).max()
    assert np.allclose(rot.state.alpha, ref.state.alpha, rtol=1e-10, atol=1e-14)
    rigid = _update(PLASTIC, R[None]).first_pk
    assert np.abs(rigid).max() < 1e-12 * E


def test_small_strain_limit():
    """P1 - C eps is second order in |Grad u|: at |G| ~ 1e-5 it is ~1e-5 of the stress."""
    G = 1e-5 * RNG.standard_normal((6, 3, 3))
    lin = small_strain_stress(ELASTIC, G)
    P = _update(ELASTIC, np.eye(3) + G).first_pk
    assert np.abs(P - lin).max() < 1e-4 * np.abs(lin).max()
    assert np.abs(P - lin).max() > 1e-8 * np.abs(lin).max()  # and not zero: the model is nonlinear


def test_isochoric_compression_keeps_the_true_stress_at_yield():
    """F = diag(l, l^-1/2, l^-1/2), l from 1 to e^-1 in steps from the last state: J = 1, so the
    Kirchhoff stress tau = F S F^T is the Cauchy stress; perfectly plastic: its von Mises value is
    Y to the return map's tolerance, its pressure zero (tr E = 0), no plastic volume change, and
    the log strains add: alpha + Y / (3 G) = |ln l| = 1 (the elastic part's equivalent strain)."""
    eps_p, alpha = np.zeros((1, 6)), np.zeros(1)
    G = PERFECT.shear_modulus
    for lam in np.exp(-np.linspace(0.01, 1.0, 40)):
        F = np.diag([lam, lam ** -0.5, lam ** -0.5])[None]
        upd = finite_strain_update(PERFECT, F, eps_p, alpha, dt=None)
        eps_p, alpha = upd.state.plastic_strain, upd.state.alpha
    S = np.linalg.solve(F[0], upd.first_pk[0])
    tau = F[0] @ S @ F[0].T
    assert np.linalg.det(F[0]) == pytest.approx(1.0, rel=1e-12)
    assert von_mises(np.array([[tau[0, 0], tau[1, 1], tau[2, 2], 0, 0, 0]]))[0] == pytest.approx(Y, rel=1e-9)
    assert np.trace(tau) == pytest.approx(0.0, abs=1e-6 * Y)
    assert alpha[0] + Y / (3 * G) == pytest.approx(1.0, rel=1e-9)
    assert np.abs(from_mandel(eps_p)[0].trace()) < 1e-12


def test_numerical_tangent_matches_central_differences():
    """Forward differences at 1e-7 against central ones at 1e-6 (the latter's error ~1e-12):
    1e-5 relative covers the forward step's h |P''| ~ 1e-7 E and the return map's tolerance."""
    F = np.eye(3) + 0.02 * RNG.standard_normal((6, 3, 3))
    upd = _update(PLASTIC, F, tangent=True)
    assert upd.state.yielding.all()
    A = np.zeros_like(upd.tangent)
    for kl in range(9):
        Fp, Fm = F.copy(), F.copy()
        Fp[:, kl // 3, kl % 3] += 1e-6
        Fm[:, kl // 3, kl % 3] -= 1e-6
        A[:, :, kl] = (_update(PLASTIC, Fp).first_pk - _update(PLASTIC, Fm).first_pk).reshape(-1, 9) / 2e-6
    assert np.abs(A - upd.tangent).max() < 1e-5 * np.abs(A).max()


# --- the zone -------------------------------------------------------------------------------------
def _field(V, scale):
    """A nonlinear displacement field (a Vec of its own: a Function's .vector wraps the Function's
    memory, freed with it)."""
    u = fem.Function(V)
    u.interpolate(lambda x: scale * np.vstack([0.5 * x[0] + 0.3 * x[1] ** 2, -0.4 * x[1] * x[0] + 0.2 * x[2],
                                               0.3 * x[2] ** 2 - 0.25 * x[0]]))
    return u.vector.copy()


@pytest.mark.parametrize("p", [1, 2])
def test_zone_force_is_the_energy_derivative(p):
    """Elastic, strains ~0.2 (rotations of the same size): (W(u + h d) - W(u - h d)) / 2h =
    (K u + f_c(u)) . d, W = 1/2 u.K u + the zone's energy correction, the zone being the whole
    cube's half; central differences at h = 1e-6 of u: 1e-7 relative."""
    m, tags, V = _setup(p)
    K = _stiffness(V)  # the whole cube's; the zone (tag 3) is half of it
    zone = FiniteStrainZone(V, tags, [ZoneMaterial(3, ELASTIC)])
    u = _field(V, 0.4)
    zone.evaluate(u, tangent=False)
    f = K.createVecLeft()
    K.mult(u, f)
    f.axpy(1.0, zone.force_correction())
    d = u.copy()
    d.array[:] = RNG.standard_normal(d.array.size)
    h = 1e-6 * u.norm() / d.norm()

    def W(w):
        Kw = K.createVecLeft()
        K.mult(w, Kw)
        return 0.5 * w.dot(Kw) + zone.strain_energy_correction(w)

    up, um = u.copy(), u.copy()
    up.axpy(h, d)
    um.axpy(-h, d)
    dW = (W(up) - W(um)) / (2 * h)
    assert dW == pytest.approx(f.dot(d), rel=1e-6)
    # the correction is not small here: the check sees the geometric terms
    assert zone.force_correction().norm() > 0.05 * f.norm()


@pytest.mark.parametrize("p", [1, 2])
def test_zone_stiffness_is_the_force_derivative(p):
    """Plastic points, central differences of f_c at 1e-8 of u against dK d: the forward-difference
    tangent's 1e-7 error plus the differences': 1e-5 relative."""
    m, tags, V = _setup(p)
    zone = FiniteStrainZone(V, tags, [ZoneMaterial(3, PLASTIC)])
    u = _field(V, 0.05)
    n = m.comm.allreduce(zone.evaluate(u, tangent=True))
    assert n > 0 and any(r is not None and r.yielding.any() for r in zone.trial())
    dK = zone.stiffness_correction()
    d = u.copy()
    d.array[:] = RNG.standard_normal(d.array.size) * 1e-8 * np.abs(u.array).max()
    up, um = u.copy(), u.copy()
    up.axpy(1.0, d)
    um.axpy(-1.0, d)
    zone.evaluate(up, tangent=False)
    fp = zone.force_correction().array.copy()
    zone.evaluate(um, tangent=False)
    fm = zone.force_correction().array.copy()
    lin = dK.createVecLeft()
    dK.mult(d, lin)
    assert np.linalg.norm((fp - fm) / 2 - lin.array) < 1e-5 * np.linalg.norm(lin.array)


def test_zone_commits_its_displacement_and_force():
    """The frozen force of a finite-strain zone is f_c at the committed displacement (the start of
    the next step), and an undeformed zone without plastic strain has none."""
    m, tags, V = _setup(1)
    zone = FiniteStrainZone(V, tags, [ZoneMaterial(3, PLASTIC)])
    assert zone.frozen_force().norm() == 0.0
    u = _field(V, 0.05)
    zone.evaluate(u, tangent=False)
    f = zone.force_correction().array.copy()
    v0 = zone.version
    zone.commit()
    assert zone.version == v0 + 1 and zone.max_equivalent_plastic_strain() > 0
    assert np.allclose(zone.frozen_force().array, f, rtol=0, atol=1e-12 * np.abs(f).max())


def test_unloaded_force_is_the_small_strain_frozen_force():
    """At u = 0 both kinematics give the load -int B^T C E_p dV of the same plastic strain, to
    round-off: the linear unloading's load (the residual state of a finite-strain run)."""
    m, tags, V = _setup(2)
    small = PlasticZone(V, tags, [ZoneMaterial(3, PLASTIC)])
    finite = FiniteStrainZone(V, tags, [ZoneMaterial(3, PLASTIC)])
    n = len(small.alpha[0])
    dev = RNG.standard_normal((n, 6)) * 0.05
    dev[:, :3] -= dev[:, :3].mean(axis=1, keepdims=True)  # a deviatoric plastic strain
    state = {"plastic_strain_0": dev, "alpha_0": np.abs(dev).sum(axis=1)}
    small.set_state(state)
    finite.set_state(state)
    ref = small.frozen_force().array
    assert np.abs(ref).max() > 0
    assert np.allclose(finite.unloaded_force().array, ref, rtol=0, atol=1e-12 * np.abs(ref).max())
    assert np.allclose(finite.frozen_force().array, ref, rtol=0, atol=1e-12 * np.abs(ref).max())
