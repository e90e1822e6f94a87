"""The J2 return map against closed forms (uniaxial stress, pure shear), its consistent tangent by
finite differences and Newton's quadratic convergence, exactness for proportional loading, the
energy balance of a cycle, and the refusal of bad flow curves."""
from __future__ import annotations

import numpy as np
import pytest

from millimpact.fem.plasticity import (FlowCurve, J2Material, PlasticityError, from_mandel, return_map, to_mandel,
                                       von_mises)

E, NU, Y = 200e9, 0.3, 1e9
G = E / (2 * (1 + NU))


def material(H=0.0, points=None):
    return J2Material(E, NU, FlowCurve(Y, H, points))


def uniaxial(mat, strains, state=None):
    """Strain-driven uniaxial stress: eps_xx prescribed, sigma_yy = sigma_zz = 0 solved by Newton
    with the returned tangent (lateral strains equal by symmetry). Returns sigma_xx, alpha, the
    Newton residual histories and the final state."""
    ep, al = (np.zeros((1, 6)), np.zeros(1)) if state is None else state
    lat = 0.0
    out, histories = [], []
    for exx in strains:
        hist = []
        for _ in range(20):
            eps = np.array([[exx, lat, lat, 0, 0, 0.0]])
            r = return_map(mat, eps, ep, al)
            res = r.stress[0, 1]
            hist.append(abs(res))
            if abs(res) < 1e-9 * Y:
                break
            # d sigma_yy / d lat = C_t[1,1] + C_t[1,2]
            lat -= res / (r.tangent[0, 1, 1] + r.tangent[0, 1, 2])
        ep, al = r.plastic_strain, r.alpha
        out.append((r.stress[0, 0], r.alpha[0]))
        histories.append(hist)
    return np.array(out), histories, (ep, al)


@pytest.mark.parametrize("H", [0.0, 20e9])
def test_uniaxial_stress_closed_form(H):
    """Elastic to eps_y = Y/E, then sigma = Y + E_t (eps - eps_y) with E_t = E H / (E + H), and
    alpha = eps_p = (sigma - Y) / H (exact for radial return: each step's answer solves the
    discrete equations, which for a monotone uniaxial path are the closed form's)."""
    eps = np.linspace(0, 6 * Y / E, 61)[1:]
    res, _, _ = uniaxial(material(H), eps)
    e_y = Y / E
    Et = E * H / (E + H)
    expected = np.where(eps <= e_y, E * eps, Y + Et * (eps - e_y))
    assert np.allclose(res[:, 0], expected, rtol=1e-9)
    alpha_expected = np.where(eps <= e_y, 0.0, (expected - Y) / H if H else eps - expected / E)
    assert np.allclose(res[:, 1], alpha_expected, rtol=1e-8, atol=1e-15)


@pytest.mark.parametrize("H", [0.0, 20e9])
def test_pure_shear_closed_form(H):
    """eps_xy = gamma / 2: yield at tau = Y / sqrt(3); beyond, tau = (Y + H alpha) / sqrt(3) with
    gamma_p = sqrt(3) alpha and tau = G (gamma - gamma_p) (closed form of J2 in shear)."""
    mat = material(H)
    ep, al = np.zeros((1, 6)), np.zeros(1)
    for gamma in np.linspace(0, 5 * Y / (np.sqrt(3) * G), 41)[1:]:
        r = return_map(mat, to_mandel(np.array([[[0, gamma / 2, 0], [gamma / 2, 0, 0], [0, 0, 0]]])), ep, al)
        ep, al = r.plastic_strain, r.alpha
        tau = from_mandel(r.stress)[0, 0, 1]
        g_y = Y / (np.sqrt(3) * G)
        if gamma <= g_y:
            assert tau == pytest.approx(G * gamma, rel=1e-12)
        else:
            # tau = (Y + H a)/sqrt3 and tau = G (gamma - sqrt3 a)  =>  a = (G gamma - Y/sqrt3) / (H/sqrt3 + sqrt3 G)
            a = (G * gamma - Y / np.sqrt(3)) / (H / np.sqrt(3) + np.sqrt(3) * G)
            assert al[0] == pytest.approx(a, rel=1e-10)
            assert tau == pytest.approx((Y + H * a) / np.sqrt(3), rel=1e-10)
        assert von_mises(r.stress)[0] <= Y + H * al[0] + 1e-6 * Y


CURVE = ((0.0, 400e6), (0.05, 700e6), (0.2, 1000e6), (0.5, 1200e6))   # Hadfield-like: strong hardening


@pytest.mark.parametrize("H, points", [(0.0, None), (20e9, None), (0.0, CURVE)])
def test_consistent_tangent_by_finite_differences(H, points):
    """C_t = d sigma / d eps at plastic points: central differences (h = 1e-7 of the strain) agree
    to ~1e-6 (the O(h^2) truncation and round-off of a 1e-3 strain)."""
    rng = np.random.default_rng(1)
    mat = material(H, points)
    n = 20
    ep = rng.normal(scale=1e-3, size=(n, 6)) @ np.diag([1, 1, 1, 1, 1, 1.0])
    ep -= (ep[:, :3].sum(1, keepdims=True) / 3) * np.array([1, 1, 1, 0, 0, 0.0])   # plastic strain is deviatoric
    al = np.abs(rng.normal(scale=0.02, size=n))
    eps = ep + rng.normal(scale=8e-3, size=(n, 6))
    r0 = return_map(mat, eps, ep, al)
    assert r0.yielding.sum() >= n - 2
    h = 1e-7 * np.abs(eps).max()
    fd = np.empty((n, 6, 6))
    for j in range(6):
        d = np.zeros(6)
        d[j] = h
        fd[:, :, j] = (return_map(mat, eps + d, ep, al).stress - return_map(mat, eps - d, ep, al).stress) / (2 * h)
    y = r0.yielding
    err = np.abs(fd[y] - r0.tangent[y]).max() / np.abs(r0.tangent[y]).max()
    assert err < 2e-6
    assert np.allclose(r0.tangent, np.swapaxes(r0.tangent, 1, 2), rtol=0, atol=1e-6 * E)   # symmetric


def test_newton_converges_quadratically():
    """The uniaxial Newton on the lateral strain with the consistent tangent: each residual at most
    ~ C e_k^2 (quadratic), converged to 1e-9 Y within 5 iterations from the elastic guess."""
    mat = material(points=CURVE)
    _, hist, _ = uniaxial(mat, [0.05])
    # on one segment of the flow curve the axisymmetric residual is affine in the lateral strain, so
    # Newton may land on it exactly: a residual of 0.0 (this machine: [8.1 Y, 0.0]) is converged and
    # counts (it was dropped before, leaving no ratio to test). A linear rate (a wrong tangent, ~0.5
    # an iteration) would need ~35 iterations from 8 Y to 1e-9 Y, against the 6 allowed
    h = hist[0]
    assert len(h) <= 6 and h[-1] < 1e-9 * Y
    ratios = [h[k + 1] / h[k] ** 2 for k in range(len(h) - 1) if h[k] > 1e-3 * Y]
    assert ratios and max(ratios) < 1e-7      # e_{k+1} <= 1e-7 e_k^2 (Pa): quadratic, not linear


def test_proportional_loading_one_step_equals_many():
    """Radial return is exact for radial (proportional) loading with linear hardening: one big step
    gives the state of 100 small ones."""
    mat = material(20e9)
    direction = np.array([1.0, -0.3, -0.2, 0.4, 0.1, -0.2])
    one = return_map(mat, 6e-3 * direction[None], np.zeros((1, 6)), np.zeros(1))
    ep, al = np.zeros((1, 6)), np.zeros(1)
    for s in np.linspace(0, 6e-3, 101)[1:]:
        r = return_map(mat, s * direction[None], ep, al)
        ep, al = r.plastic_strain, r.alpha
    assert np.allclose(r.stress, one.stress, rtol=1e-10) and al[0] == pytest.approx(one.alpha[0], rel=1e-10)


def test_linear_table_equals_linear_hardening():
    lin = material(20e9)
    tab = material(points=((0.0, Y), (1.0, Y + 20e9)))
    eps = np.random.default_rng(3).normal(scale=1e-2, size=(50, 6))
    a, b = return_map(lin, eps, np.zeros((50, 6)), np.zeros(50)), return_map(tab, eps, np.zeros((50, 6)), np.zeros(50))
    assert np.allclose(a.stress, b.stress, rtol=1e-11) and np.allclose(a.tangent, b.tangent, rtol=1e-10, atol=1e-3)


def test_elastic_points_untouched():
    mat = material()
    eps = np.full((3, 6), 1e-5)
    r = return_map(mat, eps, np.zeros((3, 6)), np.zeros(3))
    assert not r.yielding.any() and np.all(r.dissipation_increment == 0)
    assert np.allclose(r.tangent, mat.elastic_matrix()[None])
    assert np.allclose(r.stress, eps @ mat.elastic_matrix())


@pytest.mark.parametrize("H, points", [(0.0, None), (20e9, None), (0.0, CURVE)])
def test_cycle_energy_balance(H, points):
    """Along a tension-compression-tension uniaxial cycle, the external work int sigma d eps (trapezoid
    rule) equals the elastic energy left plus the plastic work booked per step, to the trapezoid
    rule's O(d eps^2) error (relative 1e-4 at 3000 steps)."""
    mat = material(H, points)
    path = np.concatenate([np.linspace(0, 8e-3, 1000), np.linspace(8e-3, -6e-3, 1000)[1:], np.linspace(-6e-3, 2e-3, 1000)[1:]])
    ep, al, lat = np.zeros((1, 6)), np.zeros(1), 0.0
    sig, work_p = [0.0], 0.0
    for exx in path[1:]:
        for _ in range(20):
            r = return_map(mat, np.array([[exx, lat, lat, 0, 0, 0.0]]), ep, al)
            if abs(r.stress[0, 1]) < 1e-9 * Y:
                break
            lat -= r.stress[0, 1] / (r.tangent[0, 1, 1] + r.tangent[0, 1, 2])
        ep, al = r.plastic_strain, r.alpha
        work_p += r.dissipation_increment[0]
        sig.append(r.stress[0, 0])
    w_ext = np.trapz(sig, path)
    ee = r.stress[0] @ np.linalg.solve(mat.elastic_matrix(), r.stress[0]) / 2
    assert w_ext == pytest.approx(ee + work_p, rel=1e-4)
    assert work_p > 0 and (H == 0 and points is None or mat.flow.stored_energy(al)[0] > 0)


@pytest.mark.parametrize("kwargs, words", [
    (dict(yield_stress=0.0), "yield_stress"), (dict(yield_stress=-1e6), "yield_stress"),
    (dict(yield_stress=1e9, hardening_modulus=-1.0), "hardening_modulus"),
    (dict(yield_stress=1e9, points=((0.0, 4e8), (0.1, 3e8))), "must not decrease"),
    (dict(yield_stress=1e9, points=((0.0, 4e8), (0.0, 5e8))), "strictly increase"),
    (dict(yield_stress=1e9, points=((0.01, 4e8), (0.1, 5e8))), "start at plastic strain 0"),
    (dict(yield_stress=1e9, points=((0.0, -4e8), (0.1, 5e8))), "> 0"),
])
def test_bad_flow_curves_are_refused(kwargs, words):
    with pytest.raises(ValueError, match=words):
        FlowCurve(**kwargs)


def test_consistency_failure_is_reported(monkeypatch):
    import millimpact.fem.plasticity as P

    monkeypatch.setattr(P, "CONSISTENCY_MAX_ITERATIONS", 0)
    with pytest.raises(PlasticityError, match="did not converge at 1 point"):
        return_map(material(points=CURVE), np.array([[0.3, -0.15, -0.15, 0, 0, 0]]), np.zeros((1, 6)), np.zeros(1))


def test_elementwise_elastic_law_and_increment_match_the_matrices():
    """The return map's elementwise elastic law (K tr I + 2 G dev, for speed) against the 6 x 6
    Mandel products it replaces, C = 3 K P_vol + 2 G P_dev and P_dev, on random strains; and its
    plastic increment, the change of the plastic strain, zero where a point stays elastic. The
    tolerance is rounding: the two orders of summation differ by a few ulps of the largest term."""
    from millimpact.fem.plasticity import P_DEV, deviator

    rng = np.random.default_rng(3)
    mat = material(H=20e9)
    eps = rng.normal(size=(500, 6)) * 0.5 * Y / E
    ep = rng.normal(size=(500, 6)) * 0.2 * Y / E
    ep[:, :3] -= ep[:, :3].mean(axis=1, keepdims=True)      # plastic strain is deviatoric
    al = np.abs(rng.normal(size=500)) * 1e-3
    scale = np.abs(eps).max()
    assert np.allclose(mat.elastic_stress(eps), eps @ mat.elastic_matrix(), rtol=0, atol=1e-14 * E * scale)
    dev, tr = deviator(eps)
    assert np.allclose(dev, eps @ P_DEV, rtol=0, atol=1e-15 * scale)
    assert np.allclose(tr, eps[:, :3].sum(axis=1), rtol=0, atol=1e-15 * scale)
    r = return_map(mat, eps, ep, al, tangent=False)
    assert 0 < np.count_nonzero(r.yielding) < len(eps)      # both kinds of point are tested
    assert np.allclose(r.stress, (eps - r.plastic_strain) @ mat.elastic_matrix(), rtol=0, atol=1e-13 * Y)
    assert np.allclose(r.plastic_increment, r.plastic_strain - ep, rtol=0, atol=1e-15 * scale)
    assert np.all(r.plastic_increment[~r.yielding] == 0.0)
    assert np.allclose(von_mises(r.stress), np.sqrt(1.5) * np.linalg.norm(r.stress @ P_DEV, axis=1),
                       rtol=1e-14)
