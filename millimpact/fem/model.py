"""The finite-element model: DOLFINx spaces, materials, mass and stiffness, supports, and point
probes (linear maps from the displacement vector to values and gradients at chosen points).

Both bodies live in one mesh as disjoint volumes (cell tags from :mod:`millimpact.geometry`), so
one vector Lagrange space holds them; the ball is free, the block is clamped on its support facets,
and symmetry planes carry u . n = 0. Takes the mesh and the plan (materials, ball radius,
symmetry planes, degree); the model keeps what it was built from, not the scene.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np
import ufl
from dolfinx import fem
from dolfinx.fem import petsc as fem_petsc
from mpi4py import MPI

from ..geometry import builders as G
from ..geometry.mesh import MeshData, facet_indices, locate_cells
from ..scene.plan import Plan
from ..scene.schema import Material, Vec3
from . import forms

if TYPE_CHECKING:
    from petsc4py import PETSc

log = logging.getLogger(__name__)

BALL_CELLS = (G.BALL_ZONE, G.BALL_REGION)
BLOCK_CELLS = (G.BLOCK_ZONE, G.BLOCK_REGION)


@dataclass
class FEModel:
    """Assembled finite-element model of ball and block (SI units).

    ``M`` consistent mass (zero diagonal on clamped rows), ``K`` stiffness (unit diagonal on
    clamped rows); ``fixed_dofs`` local owned indices of clamped and symmetry dofs; ``ball_dofs``
    and ``block_dofs`` local owned indices of each body's dofs; ``sym_factor`` multiplies model totals (forces,
    energies, masses) to the full body (2 for half, 4 for quarter models), whose cut planes are
    ``symmetry_planes``; ``ball_material`` and ``target_material`` are the two bodies' materials
    (cellwise in ``mu``, ``lmbda``, ``rho``; the ball's density scaled, see ``extra``);
    ``impact_point`` p (m) and ``contact_normal`` n (outward from the struck body) the place the
    mesh was built around (the ball touches the face at p); ``ball_cells`` and ``block_cells``
    the local cells (with ghosts) of each body, ``contact_facets`` the local facets of the ball's
    contact surface (where :mod:`millimpact.fem.contact` looks for slave nodes).
    """

    meshdata: MeshData
    V: fem.FunctionSpace
    degree: int
    M: PETSc.Mat
    K: PETSc.Mat
    bcs: list
    fixed_dofs: np.ndarray
    ball_dofs: np.ndarray
    block_dofs: np.ndarray
    ball_cells: np.ndarray
    block_cells: np.ndarray
    contact_facets: np.ndarray
    sym_factor: float
    symmetry_planes: tuple[str, ...]
    ball_material: Material
    target_material: Material
    impact_point: Vec3
    contact_normal: Vec3
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

    def ball_velocity(self, velocity) -> PETSc.Vec:
        """The velocity field (m/s): the ball moving rigidly with ``velocity``, the block at rest,
        zero on clamped and symmetry dofs (no normal velocity on a symmetry plane)."""
        v = self.M.createVecRight()
        v.set(0.0)
        for comp in range(3):
            v.array[self.ball_dofs[self.ball_dofs % 3 == comp]] = velocity[comp]
        v.array[self.fixed_dofs] = 0.0
        return v


def _cellwise(
    V0: fem.FunctionSpace, ball: np.ndarray, ball_value: float, block_value: float, name: str
) -> fem.Function:
    f = fem.Function(V0)
    f.name = name
    f.x.array[:] = block_value
    f.x.array[ball] = ball_value  # DG0: one dof per cell, dof index = cell index
    f.x.scatter_forward()
    return f


def create_fe_model(md: MeshData, plan: Plan, degree: int | None = None) -> FEModel:
    """Spaces, materials, M and K (PETSc), supports and symmetry conditions for a meshed scene and
    its plan (the Lagrange degree ``degree``, default the plan's)."""
    degree = degree or plan.degree
    mesh = md.mesh
    V = fem.VectorFunctionSpace(mesh, ("Lagrange", degree))
    # the mesh's tags are read here, once: the rest of fem works on the model
    ball_cells, block_cells = locate_cells(md, BALL_CELLS), locate_cells(md, BLOCK_CELLS)
    support = facet_indices(md, G.SUPPORT)
    sym_facets = {
        plane: facet_indices(md, tag)
        for plane, tag in (("x", G.SYM_X), ("z", G.SYM_Z))
        if plane in plan.symmetry_planes
    }
    contact_facets = facet_indices(md, G.BALL_CONTACT)

    sym_factor = float(2 ** len(plan.symmetry_planes))
    mu, lmbda, rho, extra = _assign_materials(V, ball_cells, plan, sym_factor)
    bcs = _clamp_and_symmetry(V, support, sym_facets)
    backing = (md.facet_tags, plan.backing_stiffness) if plan.backing_stiffness > 0 else None
    K, M = _assemble(V, mu, lmbda, rho, bcs, backing)
    fixed_dofs, ball_dofs, block_dofs = _dof_sets(V, bcs, ball_cells)
    n_global = V.dofmap.index_map.size_global * V.dofmap.index_map_bs
    log.info("FE model: P%d, %d dofs, symmetry factor %g", degree, n_global, sym_factor)
    return FEModel(
        md,
        V,
        degree,
        M,
        K,
        bcs,
        fixed_dofs,
        ball_dofs,
        block_dofs,
        ball_cells,
        block_cells,
        contact_facets,
        sym_factor,
        tuple(plan.symmetry_planes),
        plan.ball.material,
        plan.target,
        plan.impact_point,
        plan.contact_normal,
        mu,
        lmbda,
        rho,
        n_global,
        extra=extra,
    )


def _assign_materials(
    V: fem.FunctionSpace, ball_cells: np.ndarray, plan: Plan, sym_factor: float
) -> tuple[fem.Function, fem.Function, fem.Function, dict]:
    """Cellwise (DG0) shear modulus, Lame lambda and density of the two bodies; the ball's density
    scaled to the sphere's mass (``extra``: the scale and the meshed ball's volume)."""
    mesh = V.mesh
    V0 = fem.FunctionSpace(mesh, ("DG", 0))
    mb, mk = plan.ball.material, plan.target
    mu = _cellwise(V0, ball_cells, mb.shear_modulus, mk.shear_modulus, "mu")
    lmbda = _cellwise(V0, ball_cells, mb.lame_lambda, mk.lame_lambda, "lambda")
    # The meshed ball is a polyhedron, a little smaller than the sphere (volume error ~ (h/R)^2):
    # its density is scaled so that its mass is the sphere's, which the impact depends on
    # (Hertz: t_c ~ m^(2/5), F_max ~ m^(3/5)).
    ball_indicator = _cellwise(V0, ball_cells, 1.0, 0.0, "ball")
    vol = mesh.comm.allreduce(fem.assemble_scalar(fem.form(ball_indicator * ufl.dx(domain=mesh))), op=MPI.SUM)
    ball_volume_exact = 4.0 / 3.0 * np.pi * plan.ball.radius**3
    density_scale = ball_volume_exact / (sym_factor * vol)
    if plan.ball.body_mass is not None:  # the tip of a heavier body carries its mass (scene.schema.Ball)
        density_scale *= plan.ball.body_mass / plan.ball.sphere_mass
    rho = _cellwise(V0, ball_cells, mb.density * density_scale, mk.density, "rho")
    return mu, lmbda, rho, {"ball_density_scale": density_scale, "ball_volume_mesh_m3": sym_factor * vol}


def _clamp_and_symmetry(V: fem.FunctionSpace, support: np.ndarray, sym_facets: dict[str, np.ndarray]) -> list:
    """Dirichlet conditions: u = 0 on the ``support`` facets, u . n = 0 on each symmetry plane's
    facets (x: u_x = 0, z: u_z = 0)."""
    mesh = V.mesh
    fdim = mesh.topology.dim - 1
    mesh.topology.create_connectivity(fdim, mesh.topology.dim)
    zero = fem.Function(V)
    bcs = [fem.dirichletbc(zero, fem.locate_dofs_topological(V, fdim, support))]
    for plane, comp in (("x", 0), ("z", 2)):
        if plane in sym_facets:
            Vc, _ = V.sub(comp).collapse()
            dofs = fem.locate_dofs_topological((V.sub(comp), Vc), fdim, sym_facets[plane])
            bcs.append(fem.dirichletbc(fem.Function(Vc), dofs, V.sub(comp)))
    return bcs


def _assemble(
    V: fem.FunctionSpace,
    mu: fem.Function,
    lmbda: fem.Function,
    rho: fem.Function,
    bcs: list,
    backing: tuple | None = None,
):
    """Stiffness K (unit diagonal on constrained rows) and consistent mass M (zero diagonal there).
    ``backing`` = (facet tags, k_n Pa/m): K also holds the Winkler layer int_BACKING k_n (u.n)(v.n) ds
    (:func:`forms.winkler_foundation`), linear, so the region's modes stay those of a linear model."""
    u, v = ufl.TrialFunction(V), ufl.TestFunction(V)
    dx = ufl.Measure("dx", domain=V.mesh)
    a = forms.elastic_stiffness(u, v, mu, lmbda, dx)
    if backing is not None:
        tags, k_n = backing
        ds = ufl.Measure("ds", domain=V.mesh, subdomain_data=tags)
        a = a + forms.winkler_foundation(u, v, fem.Constant(V.mesh, float(k_n)), ufl.FacetNormal(V.mesh), ds(G.BACKING))
    a_k = fem.form(a)
    a_m = fem.form(forms.mass(u, v, rho, dx))
    K = fem_petsc.assemble_matrix(a_k, bcs=bcs, diagonal=1.0)
    K.assemble()
    M = fem_petsc.assemble_matrix(a_m, bcs=bcs, diagonal=0.0)
    M.assemble()
    return K, M


def _dof_sets(V: fem.FunctionSpace, bcs: list, ball_cells: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Local owned dof indices (int32): constrained (clamped or symmetry), the ball's, the block's."""
    bs = V.dofmap.index_map_bs
    n_owned = V.dofmap.index_map.size_local * bs
    fixed = []
    for bc in bcs:
        idx, _ = bc.dof_indices()
        fixed.append(idx[idx < n_owned])
    fixed_dofs = np.unique(np.concatenate(fixed)).astype(np.int32)
    # on a blocked space locate_dofs_topological returns node (block) indices
    ball_nodes = fem.locate_dofs_topological(V, V.mesh.topology.dim, ball_cells)
    ball_nodes = ball_nodes[ball_nodes < V.dofmap.index_map.size_local]
    ball_dofs = np.sort((ball_nodes[:, None] * bs + np.arange(bs)[None, :]).ravel()).astype(np.int32)
    all_owned = np.ones(n_owned, dtype=bool)
    all_owned[ball_dofs] = False
    block_dofs = np.nonzero(all_owned)[0].astype(np.int32)
    return fixed_dofs, ball_dofs, block_dofs
