"""The finite-element model: DOLFINx spaces, materials, mass and stiffness, supports, and point
probes (linear maps from the displacement vector to values and gradients at chosen points).

Both bodies live in one mesh as disjoint volumes (cell tags from :mod:`millimpact.geometry`), so
one vector Lagrange space holds them; the ball is free, the block is clamped on its support facets,
and symmetry planes carry u . n = 0.
"""
from __future__ import annotations

import logging
from dataclasses import dataclass, field
from typing import Optional

import numpy as np
import ufl
from dolfinx import fem
from dolfinx.fem import petsc as fem_petsc
from mpi4py import MPI

from . import forms
from ..geometry import builders as G
from ..geometry.mesh import MeshData, facet_indices, locate_cells
from ..scene.plan import Plan
from ..scene.schema import Scene

log = logging.getLogger(__name__)

BALL_CELLS = (G.BALL_ZONE, G.BALL_REGION)
BLOCK_CELLS = (G.BLOCK_ZONE, G.BLOCK_REGION)


@dataclass
class FEModel:
    """Assembled finite-element model of ball and block (SI units).

    ``M`` consistent mass (zero diagonal on clamped rows), ``K`` stiffness (unit diagonal on
    clamped rows); ``fixed_dofs`` local owned indices of clamped and symmetry dofs; ``ball_mask``
    local owned indices of the ball's dofs; ``sym_factor`` multiplies model totals (forces,
    energies, masses) to the full body (2 for half, 4 for quarter models).
    """

    scene: Scene
    plan: Plan
    meshdata: MeshData
    V: fem.FunctionSpace
    degree: int
    M: object
    K: object
    bcs: list
    fixed_dofs: np.ndarray
    ball_dofs: np.ndarray
    block_dofs: np.ndarray
    sym_factor: float
    mu: fem.Function
    lmbda: fem.Function
    rho: fem.Function
    n_dofs_global: int
    extra: dict = field(default_factory=dict)

    @property
    def comm(self) -> MPI.Comm:
        return self.V.mesh.comm

    def function(self, name: str = "u") -> fem.Function:
        f = fem.Function(self.V)
        f.name = name
        return f

    def ball_velocity(self, velocity) -> "PETSc.Vec":
        """The velocity field (m/s): the ball moving rigidly with ``velocity``, the block at rest,
        zero on clamped and symmetry dofs (no normal velocity on a symmetry plane)."""
        v = self.M.createVecRight()
        v.set(0.0)
        for comp in range(3):
            v.array[self.ball_dofs[self.ball_dofs % 3 == comp]] = velocity[comp]
        v.array[self.fixed_dofs] = 0.0
        return v


def _cellwise(V0: fem.FunctionSpace, md: MeshData, ball_value: float, block_value: float, name: str) -> fem.Function:
    f = fem.Function(V0)
    f.name = name
    f.x.array[:] = block_value
    ball = locate_cells(md, BALL_CELLS)
    f.x.array[ball] = ball_value  # DG0: one dof per cell, dof index = cell index
    f.x.scatter_forward()
    return f


def create_fe_model(scene: Scene, plan: Plan, md: MeshData, degree: Optional[int] = None) -> FEModel:
    """Spaces, materials, M and K (PETSc), supports and symmetry conditions for a meshed scene."""
    degree = degree or plan.degree
    mesh = md.mesh
    V = fem.VectorFunctionSpace(mesh, ("Lagrange", degree))
    V0 = fem.FunctionSpace(mesh, ("DG", 0))
    mb, mk = scene.ball.material, scene.target_material
    mu = _cellwise(V0, md, mb.shear_modulus, mk.shear_modulus, "mu")
    lmbda = _cellwise(V0, md, mb.lame_lambda, mk.lame_lambda, "lambda")
    # The meshed ball is a polyhedron, a little smaller than the sphere (volume error ~ (h/R)^2):
    # its density is scaled so that its mass is the sphere's, which the impact depends on
    # (Hertz: t_c ~ m^(2/5), F_max ~ m^(3/5)).
    sym_factor = float(2 ** len(plan.symmetry_planes))
    ball_indicator = _cellwise(V0, md, 1.0, 0.0, "ball")
    vol = mesh.comm.allreduce(fem.assemble_scalar(fem.form(ball_indicator * ufl.dx(domain=mesh))), op=MPI.SUM)
    ball_volume_exact = 4.0 / 3.0 * np.pi * scene.ball.radius**3
    density_scale = ball_volume_exact / (sym_factor * vol)
    rho = _cellwise(V0, md, mb.density * density_scale, mk.density, "rho")

    fdim = mesh.topology.dim - 1
    mesh.topology.create_connectivity(fdim, mesh.topology.dim)
    zero = fem.Function(V)
    bcs = []
    support = facet_indices(md, G.SUPPORT)
    bcs.append(fem.dirichletbc(zero, fem.locate_dofs_topological(V, fdim, support)))
    for plane, tag, comp in (("x", G.SYM_X, 0), ("z", G.SYM_Z, 2)):
        if plane in plan.symmetry_planes:
            facets = facet_indices(md, tag)
            Vc, _ = V.sub(comp).collapse()
            dofs = fem.locate_dofs_topological((V.sub(comp), Vc), fdim, facets)
            bcs.append(fem.dirichletbc(fem.Function(Vc), dofs, V.sub(comp)))

    u, v = ufl.TrialFunction(V), ufl.TestFunction(V)
    dx = ufl.Measure("dx", domain=mesh)
    a_k = fem.form(forms.elastic_stiffness(u, v, mu, lmbda, dx))
    a_m = fem.form(forms.mass(u, v, rho, dx))
    K = fem_petsc.assemble_matrix(a_k, bcs=bcs, diagonal=1.0)
    K.assemble()
    M = fem_petsc.assemble_matrix(a_m, bcs=bcs, diagonal=0.0)
    M.assemble()

    bs = V.dofmap.index_map_bs
    n_owned = V.dofmap.index_map.size_local * bs
    fixed = []
    for bc in bcs:
        idx, _ = bc.dof_indices()
        fixed.append(idx[idx < n_owned])
    fixed_dofs = np.unique(np.concatenate(fixed)).astype(np.int32)

    # on a blocked space locate_dofs_topological returns node (block) indices
    ball_nodes = fem.locate_dofs_topological(V, mesh.topology.dim, locate_cells(md, BALL_CELLS))
    ball_nodes = ball_nodes[ball_nodes < V.dofmap.index_map.size_local]
    ball_dofs = np.sort((ball_nodes[:, None] * bs + np.arange(bs)[None, :]).ravel()).astype(np.int32)
    all_owned = np.ones(n_owned, dtype=bool)
    all_owned[ball_dofs] = False
    block_dofs = np.nonzero(all_owned)[0].astype(np.int32)
    n_global = V.dofmap.index_map.size_global * bs
    log.info("FE model: P%d, %d dofs, symmetry factor %g", degree, n_global, sym_factor)
    return FEModel(scene, plan, md, V, degree, M, K, bcs, fixed_dofs, ball_dofs, block_dofs, sym_factor,
                   mu, lmbda, rho, n_global, extra={"ball_density_scale": density_scale,
                                                    "ball_volume_mesh_m3": sym_factor * vol})
