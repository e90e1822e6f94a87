"""The rubber backing's Winkler layer in K (:func:`millimpact.fem.forms.winkler_foundation`,
assembled by :func:`millimpact.fem.model._assemble`): an exact quasi-static solution.

A plate of thickness t on the layer (normal stiffness k_n per area), rollers on its four sides
(u . n = 0), a uniform pressure p on its top: uniaxial strain, so the plate compresses uniformly
and the layer under it by p / k_n. Exact: u_y(y) = -p / k_n - p (y + t) / (lambda + 2 mu). The field
is linear, which P1 elements hold exactly: the FE answer differs only by the direct solver's
rounding (~1e-12 relative at this size; the test allows 1e-8).
"""
from __future__ import annotations

import numpy as np
import pytest
import ufl
from dolfinx import fem, mesh as dmesh
from dolfinx.fem import petsc as fem_petsc
from mpi4py import MPI
from petsc4py import PETSc

from millimpact.fem.model import _assemble
from millimpact.geometry.builders import BACKING

A, T = 0.2, 0.05              # plate side and thickness, m
MU, LMBDA = 80e9, 120e9       # Pa
K_N = 1.7e11                  # Pa/m: the liner-panel's 1.04 GPa sheet, 6 mm thick
P = 2.0e6                     # Pa


def test_plate_on_winkler_layer_settles_by_p_over_kn():
    comm = MPI.COMM_WORLD
    msh = dmesh.create_box(comm, [np.array([0.0, -T, 0.0]), np.array([A, 0.0, A])], [4, 3, 4],
                           dmesh.CellType.tetrahedron)
    fdim = 2
    bottom = dmesh.locate_entities_boundary(msh, fdim, lambda x: np.isclose(x[1], -T))
    top = dmesh.locate_entities_boundary(msh, fdim, lambda x: np.isclose(x[1], 0.0))
    order = np.argsort(np.concatenate([bottom, top]))
    facets = np.concatenate([bottom, top])[order].astype(np.int32)
    values = np.concatenate([np.full(len(bottom), BACKING), np.full(len(top), 1)])[order].astype(np.int32)
    tags = dmesh.meshtags(msh, fdim, facets, values)
    V = fem.VectorFunctionSpace(msh, ("Lagrange", 1))
    V0 = fem.FunctionSpace(msh, ("DG", 0))
    mu, lmbda, rho = fem.Function(V0), fem.Function(V0), fem.Function(V0)
    mu.x.array[:], lmbda.x.array[:], rho.x.array[:] = MU, LMBDA, 7800.0
    bcs = []
    for comp, value in ((0, 0.0), (0, A), (2, 0.0), (2, A)):     # rollers on the sides
        side = dmesh.locate_entities_boundary(msh, fdim, lambda x, c=comp, v=value: np.isclose(x[c], v))
        Vc, _ = V.sub(comp).collapse()
        dofs = fem.locate_dofs_topological((V.sub(comp), Vc), fdim, side)
        bcs.append(fem.dirichletbc(fem.Function(Vc), dofs, V.sub(comp)))
    K, _ = _assemble(V, mu, lmbda, rho, bcs, backing=(tags, K_N))
    v = ufl.TestFunction(V)
    ds = ufl.Measure("ds", domain=msh, subdomain_data=tags)
    load = fem.form(ufl.dot(fem.Constant(msh, PETSc.ScalarType((0.0, -P, 0.0))), v) * ds(1))
    b = fem_petsc.assemble_vector(load)
    b.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
    fem_petsc.set_bc(b, bcs)                    # the rollers are homogeneous: no lifting
    u = fem.Function(V)
    ksp = PETSc.KSP().create(comm)
    ksp.setOptionsPrefix("test_backing_")
    ksp.setOperators(K)
    ksp.setType("preonly")
    ksp.getPC().setType("lu")
    ksp.getPC().setFactorSolverType("mumps")
    ksp.solve(b, u.vector)
    u.x.scatter_forward()
    x = V.tabulate_dof_coordinates()
    n_owned = V.dofmap.index_map.size_local
    uy = u.x.array.reshape(-1, 3)[:n_owned, 1]
    exact = -P / K_N - P * (x[:n_owned, 1] + T) / (LMBDA + 2 * MU)
    assert np.max(np.abs(uy - exact)) == pytest.approx(0.0, abs=1e-8 * P / K_N)
    # and the layer's share, the settlement of the bottom: p / k_n
    bottom_dofs = np.isclose(x[:n_owned, 1], -T)
    assert np.allclose(uy[bottom_dofs], -P / K_N, rtol=1e-8)
