"""The compiled pass (millimpact.fem.return_map_kernel) against the numpy path.

From a committed plastic state, a second displacement is return-mapped on the candidate cells by
both paths: the same number of yielding points and the same force correction. The two compute
the same expressions in a different order (FFCx's strain and assembly kernels against one C loop),
so they agree to rounding: 1e-12 of the force's largest entry, where the force is the sum of ~10^2
terms of one sign pattern (the observed differences are ~1e-15). The mesh is sheared and stretched
(a general affine map), so J^-1 is not diagonal; P1 and P2; a linear and a tabulated flow curve
(the tabulated one, with breakpoints the
step crosses, takes the per-point Newton of the consistency equation).
"""
from __future__ import annotations

import numpy as np
import pytest
from dolfinx import fem, mesh as dmesh
from mpi4py import MPI

from millimpact.fem import return_map_kernel as rk
from millimpact.fem.plastic_zone import PlasticZone, ZoneMaterial
from millimpact.fem.plasticity import FlowCurve, J2Material

E, NU = 200e9, 0.3
LINEAR = J2Material(E, NU, FlowCurve(1e9, 20e9))
TABULATED = J2Material(E, NU, FlowCurve(380e6, 0.0, ((0.0, 380e6), (2e-4, 450e6), (6e-4, 560e6), (2e-3, 700e6))))

pytestmark = pytest.mark.skipif(rk.load_kernel() is None, reason="no C compiler for the kernel")


def _zone(p, material, kind=PlasticZone):
    """A ``kind`` zone (the lower 0.6 of a sheared 1 cm cube) of ``material``, and its space."""
    m = dmesh.create_unit_cube(MPI.COMM_WORLD, 3, 3, 3)
    A = np.array([[1.3, 0.2, 0.0], [0.1, 0.9, 0.3], [0.0, -0.2, 1.1]]) * 1e-2      # 1 cm, sheared
    m.geometry.x[:] = m.geometry.x @ A.T
    n = m.topology.index_map(3).size_local + m.topology.index_map(3).num_ghosts
    mid = dmesh.compute_midpoints(m, 3, np.arange(n, dtype=np.int32))
    tags = dmesh.meshtags(m, 3, np.arange(n, dtype=np.int32), np.where(mid[:, 2] < 0.6e-2, 3, 4).astype(np.int32))
    V = fem.VectorFunctionSpace(m, ("Lagrange", p))
    return kind(V, tags, [ZoneMaterial(3, material)]), V


def _indent(V, depth):
    """A displacement that strains the zone unevenly (a dent below a point of the top face)."""
    u = fem.Function(V)
    u.interpolate(lambda x: np.vstack([depth * 0.3 * np.sin(200 * x[1]), 0.1 * depth * x[0] * 100,
                                       -depth * np.exp(-((x[0] - 0.006) ** 2 + (x[1] - 0.005) ** 2) / 2e-5)
                                       * (x[2] / 0.01)]))
    return u


@pytest.mark.parametrize("p", [1, 2])
@pytest.mark.parametrize("material", [LINEAR, TABULATED], ids=["linear", "tabulated"])
def test_compiled_candidates_equal_numpy(p, material):
    zone, V = _zone(p, material)
    depth = 6e-5 if material is LINEAR else 3e-5
    u1, u2 = _indent(V, depth), _indent(V, 1.4 * depth)
    assert zone.comm.allreduce(zone.evaluate(u1.vector, tangent=False)) > 0
    zone.commit()                                   # a plastic state to start from
    assert zone.comm.allreduce(zone.evaluate(u2.vector, tangent=False)) > 0
    assert zone.comm.allreduce(zone.select_candidates(0.5)) > 0
    got = {}
    for compiled in (False, True):
        zone.compiled, zone._kernel = compiled, None
        n = zone.comm.allreduce(zone.evaluate(u2.vector, tangent=False, candidates_only=True))
        got[compiled] = (n, zone.force_correction().array.copy())
    assert zone._kernel, "the compiled path ran"
    assert got[True][0] == got[False][0] > 0
    scale = zone.comm.allreduce(np.abs(got[False][1]).max(), op=MPI.MAX)
    assert np.abs(got[True][1] - got[False][1]).max() <= 1e-12 * scale
    # and the force differs from the frozen one (the candidates do yield at u2)
    assert np.abs(got[True][1] - zone.frozen_force().array).max() > 1e-6 * scale


@pytest.mark.parametrize("p", [1, 2])
@pytest.mark.parametrize("material", [LINEAR, TABULATED], ids=["linear", "tabulated"])
def test_compiled_full_evaluation_equals_numpy(p, material):
    """Over every zone cell the kernel also keeps the trial state to commit: stress, plastic
    strain, alpha, the step's plastic work and the yielding points equal numpy's return map
    (1e-12 of each field's largest value: rounding), and so does the force correction."""
    zone, V = _zone(p, material)
    depth = 6e-5 if material is LINEAR else 3e-5
    zone.compiled = False
    zone.evaluate(_indent(V, depth).vector, tangent=False)
    zone.commit()
    u2 = _indent(V, 1.4 * depth)
    got = {}
    for compiled in (False, True):
        zone.compiled, zone._kernel = compiled, None
        n = zone.comm.allreduce(zone.evaluate(u2.vector, tangent=False))
        got[compiled] = (n, zone.trial()[0], zone.force_correction().array.copy(), zone.step_plastic_work())
    assert zone._kernel, "the compiled path ran"
    (n0, r0, f0, w0), (n1, r1, f1, w1) = got[False], got[True]
    assert n1 == n0 > 0
    assert np.array_equal(r1.yielding, r0.yielding)
    for name in ("stress", "plastic_strain", "alpha", "dissipation_increment", "plastic_increment"):
        a, b = getattr(r1, name), getattr(r0, name)
        assert np.abs(a - b).max() <= 1e-12 * np.abs(b).max(), name
    assert np.abs(f1 - f0).max() <= 1e-12 * np.abs(f0).max()
    assert w1 == pytest.approx(w0, rel=1e-12)
    zone.commit()                                    # the kernel's trial state commits
    assert zone.max_equivalent_plastic_strain() == pytest.approx(r0.alpha.max(), rel=1e-12)


def test_without_a_buildable_kernel_the_numpy_path_stays(tmp_path, monkeypatch, caplog):
    """A cache folder that cannot be made (here a file stands in its way; on a machine without a
    C compiler the build fails the same way): one warning, and the zone's evaluations keep numpy's
    path with the same answer."""
    blocker = tmp_path / "not-a-folder"
    blocker.write_text("")
    monkeypatch.setenv("XDG_CACHE_HOME", str(blocker))
    monkeypatch.setattr(rk, "_loaded", {})
    with caplog.at_level("WARNING", logger=rk.__name__):
        assert rk.load_kernel() is None
    assert any("using numpy" in r.getMessage() for r in caplog.records)
    zone, V = _zone(2, LINEAR)
    n = zone.evaluate(_indent(V, 6e-5).vector, tangent=False)
    assert zone._kernel is False and n > 0 and zone.trial()[0].yielding.any()
