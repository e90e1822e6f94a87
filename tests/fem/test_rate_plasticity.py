"""The Johnson-Cook strain-rate factor of the return map (millimpact.fem.plasticity): the flow
stress of steady uniaxial flow at a given rate against the law's closed form, the consistent
tangent by finite differences, the compiled kernel against numpy, and the scene's checks."""
from __future__ import annotations

import math

import numpy as np
import pytest

from millimpact.fem.plasticity import FlowCurve, J2Material, rate_factor, return_map
from millimpact.scene.schema import Material, SceneError

E, NU, Y = 200e9, 0.3, 380e6
#: Johnson & Cook (1983)'s C for 1006 steel, with their reference rate 1/s
C, RATE0 = 0.022, 1.0


def _uniaxial_at_rate(mat, rate, strain_to, steps):
    """Uniaxial stress at a constant strain rate: eps_xx = rate t in ``steps`` steps of dt, the
    lateral stresses zeroed by Newton on the returned tangent. Returns (sigma_xx, alpha) per step."""
    dt = strain_to / rate / steps
    ep, al, lat = np.zeros((1, 6)), np.zeros(1), 0.0
    out = []
    for k in range(1, steps + 1):
        exx = rate * dt * k
        for _ in range(30):
            r = return_map(mat, np.array([[exx, lat, lat, 0, 0, 0.0]]), ep, al, True, dt)
            if abs(r.stress[0, 1]) < 1e-9 * Y:
                break
            lat -= r.stress[0, 1] / (r.tangent[0, 1, 1] + r.tangent[0, 1, 2])
        ep, al = r.plastic_strain, r.alpha
        out.append((r.stress[0, 0], r.alpha[0]))
    return np.array(out)


@pytest.mark.parametrize("points", [None, ((0.0, Y), (0.05, 500e6), (0.3, 700e6))], ids=["perfect", "tabulated"])
@pytest.mark.parametrize("rate", [1e-2, 1e3, 1e5])
def test_steady_flow_stress_is_the_law_at_that_rate(points, rate):
    """Once the flow is steady, alpha grows by rate dt / (1 + H R / E) per step (the hardening
    slope H still moves the elastic strain: 0.4 % on the tabulated curve, 0 when perfectly
    plastic), and each step's stress is sigma_y(alpha) (1 + C ln(alpha_dot / rate0)) at that
    alpha_dot, to the lateral Newton's tolerance (1e-9 of Y); below rate0 the factor is 1."""
    flow = FlowCurve(Y, 0.0, points)
    mat = J2Material(E, NU, flow, (C, RATE0))
    res = _uniaxial_at_rate(mat, rate, 0.2, 400)
    sig, alpha = res[:, 0], res[:, 1]
    dt = 0.2 / rate / 400
    steady = slice(200, None)
    d_alpha = np.diff(alpha)[199:]
    r = 1.0 + C * np.log(np.maximum(d_alpha / dt, RATE0) / RATE0)
    h = flow.slope(alpha[steady])
    assert np.allclose(d_alpha, rate * dt / (1.0 + h * r / E), rtol=1e-3)
    assert np.allclose(sig[steady], flow.flow_stress(alpha[steady]) * r, rtol=1e-8)
    assert np.all(r == 1.0) if rate < RATE0 else np.allclose(r, 1.0 + C * math.log(rate / RATE0), rtol=1e-3)


def test_a_faster_test_flows_higher_by_the_ln_of_the_ratio():
    """The same perfectly plastic steel at 1e2 and 1e4 1/s: the plateaus differ by C ln(100) Y."""
    mat = J2Material(E, NU, FlowCurve(Y), (C, RATE0))
    slow = _uniaxial_at_rate(mat, 1e2, 0.05, 200)[-1, 0]
    fast = _uniaxial_at_rate(mat, 1e4, 0.05, 200)[-1, 0]
    assert fast - slow == pytest.approx(C * math.log(100.0) * Y, rel=1e-6)


@pytest.mark.parametrize("points", [None, ((0.0, Y), (0.05, 500e6), (0.3, 700e6))], ids=["perfect", "tabulated"])
def test_rate_tangent_by_finite_differences(points):
    """C_t = d sigma / d eps with the rate factor (H -> H R + sigma_y C / dg): central differences
    (h = 1e-7 of the strain) agree to ~1e-6 (truncation and round-off of a 1e-3 strain)."""
    rng = np.random.default_rng(3)
    mat = J2Material(E, NU, FlowCurve(Y, 0.0, points), (C, RATE0))
    n, dt = 20, 1e-6
    ep = rng.normal(scale=1e-3, size=(n, 6))
    ep -= (ep[:, :3].sum(1, keepdims=True) / 3) * np.array([1, 1, 1, 0, 0, 0.0])
    al = np.abs(rng.normal(scale=0.02, size=n))
    eps = ep + rng.normal(scale=8e-3, size=(n, 6))
    r0 = return_map(mat, eps, ep, al, True, dt)
    assert r0.yielding.sum() >= n - 2
    assert np.all(rate_factor(mat, (r0.alpha - al)[r0.yielding], dt) > 1.1)   # the rate term is on
    h = 1e-7 * np.abs(eps).max()
    fd = np.empty((n, 6, 6))
    for j in range(6):
        d = np.zeros(6)
        d[j] = h
        fd[:, :, j] = (return_map(mat, eps + d, ep, al, False, dt).stress
                       - return_map(mat, eps - d, ep, al, False, dt).stress) / (2 * h)
    y = r0.yielding
    assert np.abs(fd[y] - r0.tangent[y]).max() / np.abs(r0.tangent[y]).max() < 2e-6


def test_without_a_step_the_map_is_rate_independent():
    """No dt (a static solve) or no rate law: the same answer as the rate-independent map."""
    rng = np.random.default_rng(4)
    eps = rng.normal(scale=8e-3, size=(10, 6))
    plain = return_map(J2Material(E, NU, FlowCurve(Y)), eps, np.zeros((10, 6)), np.zeros(10))
    rated = return_map(J2Material(E, NU, FlowCurve(Y), (C, RATE0)), eps, np.zeros((10, 6)), np.zeros(10))
    assert np.array_equal(plain.stress, rated.stress)


@pytest.mark.parametrize("p", [1, 2])
def test_compiled_rate_law_equals_numpy(p):
    """The compiled kernel's rate-dependent consistency equals numpy's to what their stopping
    rule allows: both stop at |r| <= 1e-12 Y, numpy when every point has, the kernel per point,
    so their dg may differ by 2e-12 Y / (3 G) (|dr / d dg| >= 3 G), 1e-11 of the largest dg here:
    1e-10 of each field's largest value."""
    from test_return_map_kernel import _indent, _zone

    from millimpact.fem import return_map_kernel as rk

    if rk.load_kernel() is None:
        pytest.skip("no C compiler for the kernel")
    mat = J2Material(E, NU, FlowCurve(Y, 0.0, ((0.0, Y), (2e-4, 450e6), (6e-4, 560e6), (2e-3, 700e6))), (C, RATE0))
    zone, V = _zone(p, mat)
    zone.time_step = 1e-7
    zone.compiled = False
    zone.evaluate(_indent(V, 3e-5).vector, tangent=False)
    zone.commit()
    u2 = _indent(V, 4.2e-5)
    got = {}
    for compiled in (False, True):
        zone.compiled, zone._kernel = compiled, None
        n = zone.comm.allreduce(zone.evaluate(u2.vector, tangent=False))
        got[compiled] = (n, zone.trial()[0], zone.force_correction().array.copy())
    assert zone._kernel, "the compiled path ran"
    (n0, r0, f0), (n1, r1, f1) = got[False], got[True]
    assert n1 == n0 > 0
    dg = (r0.alpha - zone.alpha[0])[r0.yielding]
    assert np.all(rate_factor(mat, dg, 1e-7) > 1.0)
    for name in ("stress", "alpha", "plastic_increment"):
        a, b = getattr(r1, name), getattr(r0, name)
        assert np.abs(a - b).max() <= 1e-10 * np.abs(b).max(), name
    assert np.abs(f1 - f0).max() <= 1e-10 * np.abs(f0).max()
    # and the rate raised the stress: without a step the same strain yields more
    zone.time_step, zone.compiled = None, False
    zone.evaluate(u2.vector, tangent=False)
    assert zone.trial()[0].alpha.sum() > r0.alpha.sum()


@pytest.mark.parametrize("value, words", [
    ((0.0, 1.0), "0 < C <= 0.5"), ((0.6, 1.0), "0 < C <= 0.5"), ((0.02, 0.0), "0 < rate0"),
])
def test_bad_rate_laws_are_refused(value, words):
    with pytest.raises(SceneError, match=words):
        Material(yield_stress=Y, johnson_cook_rate=value).validate("block.material")
    with pytest.raises(SceneError, match="needs a plastic material"):
        Material(johnson_cook_rate=(0.02, 1.0)).validate("block.material")
