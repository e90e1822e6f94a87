"""PlasticZone: J2 at the quadrature points of tagged cells, on DOLFINx P1 and P2 spaces.

- an affine displacement (uniform strain) gives every quadrature point the return map of that
  strain, and int B^T sigma dV equals K u + f_c (the decomposition the integrator relies on);
- the stiffness correction is the derivative of the force correction (central differences);
- an elastic state gives zero corrections; cells outside the zone are untouched.
"""
from __future__ import annotations

import numpy as np
import pytest
import ufl
from dolfinx import fem, mesh as dmesh
from dolfinx.fem import petsc as fem_petsc
from mpi4py import MPI

from millimpact.fem import return_map_kernel as rk
from millimpact.fem.plastic_zone import PlasticZone, ZoneMaterial, mandel_strain
from millimpact.fem.plasticity import FlowCurve, J2Material, return_map

E, NU, Y = 200e9, 0.3, 1e9
MAT = J2Material(E, NU, FlowCurve(Y, 20e9))


def _setup(p):
    m = dmesh.create_unit_cube(MPI.COMM_WORLD, 2, 2, 2)
    n = m.topology.index_map(3).size_local + m.topology.index_map(3).num_ghosts
    mid = dmesh.compute_midpoints(m, 3, np.arange(n, dtype=np.int32))
    values = np.where(mid[:, 0] < 0.5, 3, 4).astype(np.int32)     # the zone (3): half the cube
    tags = dmesh.meshtags(m, 3, np.arange(n, dtype=np.int32), values)
    V = fem.VectorFunctionSpace(m, ("Lagrange", p))
    return m, tags, V


def _stiffness(V):
    mu, lmbda = E / (2 * (1 + NU)), E * NU / ((1 + NU) * (1 - 2 * NU))
    u, v = ufl.TrialFunction(V), ufl.TestFunction(V)
    eps = lambda w: ufl.sym(ufl.grad(w))  # noqa: E731
    K = fem_petsc.assemble_matrix(fem.form(ufl.inner(2 * mu * eps(u) + lmbda * ufl.tr(eps(u)) * ufl.Identity(3), eps(v)) * ufl.dx))
    K.assemble()
    return K


@pytest.mark.parametrize("tangent", [True, False], ids=["numpy", "compiled"])
@pytest.mark.parametrize("p", [1, 2])
def test_uniform_strain_and_force_decomposition(p, tangent):
    """Without the tangent the compiled pass evaluates (return_map_kernel): both paths against the
    closed-form return map of the uniform strain and the directly assembled plastic stress."""
    m, tags, V = _setup(p)
    zone = PlasticZone(V, tags, [ZoneMaterial(3, MAT)])
    e = np.array([8e-3, -2e-3, -1e-3, 0.0, 0.0, 3e-3 * np.sqrt(2)])   # Mandel: eps_xy = 3e-3
    u = fem.Function(V)
    u.interpolate(lambda x: np.vstack([e[0] * x[0] + 3e-3 * x[1], e[1] * x[1] + 3e-3 * x[0], e[2] * x[2]]))
    n_y = m.comm.allreduce(zone.evaluate(u.vector, tangent=tangent))
    assert bool(zone._kernel) == (not tangent and rk.load_kernel() is not None)
    ref = return_map(MAT, e[None], np.zeros((1, 6)), np.zeros(1))
    assert ref.yielding[0] and n_y == m.comm.allreduce(len(zone.cells[0]) * zone.n_q)
    for res in zone.trial():
        assert np.allclose(res.stress, ref.stress, rtol=1e-9, atol=1e-6 * Y)
    # int_zone B^T sigma dV == (K_zone u + f_c): compare with the plastic stress assembled directly
    sig = zone.stress_correction.copy()
    slots = zone.quadrature_slots(0)
    sig.x.array.reshape(-1, 6)[slots] = ref.stress[0]
    v = ufl.TestFunction(V)
    dxz = ufl.Measure("dx", domain=m, subdomain_data=tags, metadata={"quadrature_degree": zone.q_degree})(3)
    direct = fem_petsc.assemble_vector(fem.form(ufl.inner(sig, mandel_strain(v)) * dxz))
    mu, lmbda = E / (2 * (1 + NU)), E * NU / ((1 + NU) * (1 - 2 * NU))
    du = ufl.TrialFunction(V)
    eps = lambda w: ufl.sym(ufl.grad(w))  # noqa: E731
    Kz = fem_petsc.assemble_matrix(fem.form(ufl.inner(2 * mu * eps(du) + lmbda * ufl.tr(eps(du)) * ufl.Identity(3), eps(v)) * dxz))
    Kz.assemble()
    split = Kz.createVecLeft()
    Kz.mult(u.vector, split)
    split.axpy(1.0, zone.force_correction())
    assert np.allclose(split.array, direct.array, rtol=1e-9, atol=1e-9 * np.abs(direct.array).max())


@pytest.mark.parametrize("p", [1, 2])
def test_stiffness_correction_is_the_derivative(p):
    """(f_c(u + h) - f_c(u - h)) / 2 == dK h at a plastic state (central differences of a smooth
    return map: relative 1e-7 or better at h = 1e-6 of u)."""
    m, tags, V = _setup(p)
    zone = PlasticZone(V, tags, [ZoneMaterial(3, MAT)])
    u = fem.Function(V)
    u.interpolate(lambda x: np.vstack([0.01 * x[0] + 0.004 * x[1] ** 2, -0.003 * x[1] * x[0], 0.002 * x[2]]))
    zone.evaluate(u.vector)
    dK = zone.stiffness_correction()
    h = u.vector.copy()
    h.array[:] = np.random.default_rng(0).standard_normal(h.array.size) * 1e-8
    up, um = u.vector.copy(), u.vector.copy()
    up.axpy(1.0, h)
    um.axpy(-1.0, h)
    zone.evaluate(up)
    fp = zone.force_correction().array.copy()
    zone.evaluate(um)
    fm = zone.force_correction().array.copy()
    lin = dK.createVecLeft()
    dK.mult(h, lin)
    assert np.linalg.norm((fp - fm) / 2 - lin.array) < 1e-6 * np.linalg.norm(lin.array)


def test_elastic_state_has_no_correction():
    m, tags, V = _setup(1)
    zone = PlasticZone(V, tags, [ZoneMaterial(3, MAT)])
    u = fem.Function(V)
    u.interpolate(lambda x: np.vstack([1e-4 * x[0], 0 * x[1], 0 * x[2]]))
    assert zone.evaluate(u.vector) == 0
    assert zone.force_correction().norm() == 0.0
    zone.commit()
    assert zone.max_equivalent_plastic_strain() == 0.0


def test_commit_frees_the_old_states_frozen_force():
    """f_frozen is kept per plastic state; a commit that changes the state destroys the old one's
    Vec. Dropped without destroy(), it stayed parked on its index map's communicator for the life
    of the process: ~50 MB a plastic case of paper-rig-plastic (73 states of 70,641 dofs), 1,105 ->
    1,301 MB over 5 cases in one process, 1,057 -> 1,063 MB with it destroyed (docs: plasticity).
    Its value is that of the new state, assembled again."""
    m, tags, V = _setup(1)
    zone = PlasticZone(V, tags, [ZoneMaterial(3, MAT)])
    old = zone._frozen_force()
    assert old.norm() == 0.0                         # no plastic strain yet
    u = fem.Function(V)
    u.interpolate(lambda x: np.vstack([8e-3 * x[0], -2e-3 * x[1], -1e-3 * x[2]]))
    assert m.comm.allreduce(zone.evaluate(u.vector)) > 0
    version = zone.version
    zone.commit()
    assert zone.version == version + 1
    assert not old.handle                            # destroyed, not left to the garbage
    assert all(k[1] == zone.version for k in zone._cache)
    assert zone._frozen_force().norm() > 0.0
