"""The contact point's patch row (``fem.probes.patch_mean_row``) against exact means over a half-ball.

A unit cube's top face y = 0 is struck at its centre p; the patch is the half-ball
B = {|x - p| <= r, y <= 0}. Exact references: the mean of a constant field is the constant; the
mean of the linear field v_y = -y is the depth of B's centroid, 3 r / 8 (a solid hemisphere's
centroid); a field that is zero in B but not outside it has mean zero only if the row ignores the
rest of the body.
"""
import numpy as np
import pytest
import ufl
from dolfinx import fem, mesh
from dolfinx.fem import petsc as fem_petsc
from mpi4py import MPI

from millimpact.fem.probes import patch_indicator, patch_momentum_row


def _setup(n: int, degree: int = 2):
    msh = mesh.create_box(MPI.COMM_WORLD, [np.array([-0.5, -1.0, -0.5]), np.array([0.5, 0.0, 0.5])], [n, n, n],
                          mesh.CellType.tetrahedron)
    V = fem.VectorFunctionSpace(msh, ("CG", degree))
    u, v = ufl.TrialFunction(V), ufl.TestFunction(V)
    M = fem_petsc.assemble_matrix(fem.form(ufl.inner(u, v) * ufl.dx))
    M.assemble()
    tdim = msh.topology.dim
    n_cells = msh.topology.index_map(tdim).size_local + msh.topology.index_map(tdim).num_ghosts
    return V, M, np.arange(n_cells, dtype=np.int32)


def _field(V, M, expr):
    f = fem.Function(V)
    f.interpolate(expr)
    x = M.createVecRight()
    x.array[:] = f.x.array[: x.getLocalSize()]
    return x


def _row(V, M, r=0.3):
    all_dofs = np.arange(V.dofmap.index_map.size_local * V.dofmap.index_map_bs)
    chi, e, n_in, r_used = patch_indicator(V, M, all_dofs, np.zeros(3), np.array([0.0, -1.0, 0.0]), r)
    return patch_momentum_row(M, chi, e), chi, e, r_used


@pytest.mark.parametrize("n", [8, 12])
def test_patch_row_gives_the_mean_over_the_half_ball(n):
    V, M, _ = _setup(n)
    c, _, _, r = _row(V, M)
    assert r == 0.3
    const = _field(V, M, lambda x: np.vstack([0 * x[0] + 0.3, 0 * x[0] - 2.0, 0 * x[0] + 0.7]))
    assert c.dot(const) == pytest.approx(2.0, rel=1e-12)           # d = -y: the mean of -v_y = 2
    depth = _field(V, M, lambda x: np.vstack([0 * x[0], x[1], 0 * x[0]]))    # -v_y = -y, the depth
    # the centroid's depth 3 r / 8 (a solid hemisphere's): chi interpolates the indicator, so the
    # weight has a one-element fringe at the sphere; measured +1.0 % (n = 8, r = 2.4 h) and +0.8 %
    # (n = 12, P2); 3 % allowed
    assert c.dot(depth) == pytest.approx(3 * r / 8, rel=0.03)
    outside = _field(V, M, lambda x: np.vstack([0 * x[0], np.where(np.linalg.norm(x, axis=0) > 2 * r, 1.0, 0.0),
                                                 0 * x[0]]))
    assert abs(c.dot(outside)) < 1e-12                        # nothing of the body beyond the patch's fringe


def test_patch_row_converges_with_the_mesh():
    """On a finer mesh (r = 7.2 h, P1) the fringe is thinner: the centroid depth within 1 %
    (measured +0.43 %, and +1.6 % at r = 4.8 h): the weight converges to the half-ball's."""
    V, M, _ = _setup(24, degree=1)
    c, _, _, _ = _row(V, M)
    depth = _field(V, M, lambda x: np.vstack([0 * x[0], x[1], 0 * x[0]]))
    assert c.dot(depth) == pytest.approx(3 * 0.3 / 8, rel=0.01)


def test_patch_acceleration_is_the_resultant_force_over_the_mass():
    """With M a = f (the equation of motion), c . a = chi^T f / m_patch: the patch's acceleration
    is the force on it over its mass, whatever a single node does (round-off: 1e-10)."""
    from petsc4py import PETSc

    V, M, _ = _setup(6)
    c, chi, e, _ = _row(V, M)
    f = M.createVecLeft()
    f.setRandom()
    a = M.createVecRight()
    ksp = PETSc.KSP().create(M.comm)
    ksp.setOperators(M)
    ksp.setType("preonly")
    ksp.getPC().setType("lu")
    ksp.solve(f, a)
    m_patch = (M * chi).dot(e)
    assert c.dot(a) == pytest.approx(chi.dot(f) / m_patch, rel=1e-10)
    ksp.destroy()
