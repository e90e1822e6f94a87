"""The compiled finite-strain pass (millimpact/fem/finite_strain_kernel.py) against the numpy path.

A finite-strain zone on a sheared cube (J^-1 not diagonal) is evaluated by both paths, from a
fresh and then from a committed plastic state: the same nonlinear points, trial states, force
correction and energy correction. The paths compute the same equations in a different order
(Gauss-Legendre sums in C - I or Jacobi on it against LAPACK's eigh of C, one C loop against FFCx's
expression and assembly), so they agree to rounding amplified by the eigenvectors' conditioning
and numpy's lost digits of small strains (its eigenvalues of C = I + 2 eps): 1e-9 of the force's
largest entry (observed ~1e-13 at large strains), 1e-9 of the stresses'.
"""

from __future__ import annotations

import numpy as np
import pytest
from dolfinx import fem

from millimpact.errors import SolverError
from millimpact.fem import finite_strain_kernel as fk
from millimpact.fem.finite_zone import FiniteStrainZone

from test_return_map_kernel import LINEAR, TABULATED, _indent
from test_return_map_kernel import _zone as _cube_zone

pytestmark = pytest.mark.skipif(fk.load_finite_kernel() is None, reason="no C compiler for the kernel")


def _zone(p, material):
    return _cube_zone(p, material, FiniteStrainZone)


def _dent(V, depth):
    """The uneven dent of test_return_map_kernel (large strains and rotations at this depth), as
    a Vec of its own (a Function's .vector wraps the Function's memory, freed with it)."""
    return _indent(V, depth).vector.copy()


def _both(zone, u):
    """(nonlinear points, force, trial) by the compiled pass, then by numpy (the tangent path
    without its tangent: the same trial state)."""
    out = []
    for compiled in (True, False):
        zone._kernel = None if compiled else False
        n = zone.comm.allreduce(zone.evaluate(u, tangent=False))
        assert (zone._compiled_force is not None) == compiled
        out.append((n, zone.force_correction().array.copy(), zone.trial()))
    return out


def _agree(a, b):
    (n1, f1, t1), (n0, f0, t0) = a, b
    assert n1 == n0 and n1 > 0
    assert np.abs(f1 - f0).max() <= 1e-9 * np.abs(f0).max()
    for r1, r0 in zip(t1, t0):
        if r0 is None:
            assert r1 is None
            continue
        assert np.array_equal(r1.yielding, r0.yielding)
        for name in ("stress", "plastic_strain", "alpha"):
            x1, x0 = getattr(r1, name), getattr(r0, name)
            assert np.abs(x1 - x0).max() <= 1e-9 * max(np.abs(x0).max(), 1e-300), name


@pytest.mark.parametrize("p", [1, 2])
@pytest.mark.parametrize("material", [LINEAR, TABULATED], ids=["linear", "tabulated"])
@pytest.mark.parametrize("depth", [3e-3, 6e-4, 2e-5], ids=["eigenbasis", "gauss-legendre", "small"])
def test_compiled_pass_equals_numpy(p, material, depth):
    """depth 3e-3: |C - I| up to 0.85 (P1; 0.76 P2), past GL_NORM at a quarter of the points (the
    eigenbasis; the rest on 12 Gauss-Legendre nodes), det F down to 0.65; 6e-4: |C - I| up to 0.21,
    the Gauss-Legendre sums on 5-8 nodes; 2e-5: |C - I| below 7e-3, 2-4 nodes (the tabulated steel
    yields)."""
    zone, V = _zone(p, material)
    first = _both(zone, _dent(V, depth))
    _agree(*first)
    assert any(r.yielding.any() for r in first[0][2] if r is not None) == (depth > 1e-4 or material is TABULATED)
    zone._kernel = None
    zone.evaluate(_dent(V, depth), tangent=False)
    f_committed = zone.force_correction().array.copy()
    zone.commit()  # a plastic state and a displacement to start from
    # the committed force is the compiled pass's own
    assert np.abs(zone.frozen_force().array - f_committed).max() <= 1e-12 * np.abs(f_committed).max()
    _agree(*_both(zone, _dent(V, 1.3 * depth)))
    # the energy correction of the committed plastic strain at a displacement: both paths
    u = _dent(V, 1.3 * depth)
    zone._kernel = None
    w1 = zone.strain_energy_correction(u)
    zone._kernel = False
    w0 = zone.strain_energy_correction(u)
    assert w1 == pytest.approx(w0, rel=1e-9) and w0 != 0.0


@pytest.mark.parametrize("compiled", [True, False], ids=["compiled", "numpy"])
def test_an_inverted_element_stops_the_pass(compiled):
    """A displacement that turns every element inside out (F_11 = -1, det F = -1; C = F^T F = I
    cannot tell): both paths stop with the same SolverError."""
    zone, V = _zone(1, LINEAR)
    u = fem.Function(V)
    u.interpolate(lambda x: np.vstack([-2.0 * x[0], 0.0 * x[1], 0.0 * x[2]]))
    zone._kernel = None if compiled else False
    with pytest.raises(SolverError, match="det F <= 0"):
        zone.evaluate(u.vector.copy(), tangent=False)
    assert (zone._kernel is not False) == compiled
