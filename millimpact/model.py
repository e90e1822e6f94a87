"""The finite-element model: DOLFINx spaces, materials, mass and stiffness, supports, and point
probes (linear maps from the displacement vector to values and gradients at chosen points).

Both bodies live in one mesh as disjoint volumes (cell tags from :mod:`millimpact.geometry`), so
one vector Lagrange space holds them; the ball is free, the block is clamped on its support facets,
and symmetry planes carry u . n = 0.
"""
from __future__ import annotations

import logging
from dataclasses import dataclass, field
from typing import Optional, Sequence

import numpy as np
import scipy.sparse as sp
import ufl
from dolfinx import fem
from dolfinx import geometry as dgeom
from dolfinx.fem import petsc as fem_petsc
from mpi4py import MPI

from . import forms
from . import geometry as G
from .mesh import MeshData
from .plan import Plan
from .scene import Scene

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


def _cells_of(md: MeshData, tags: Sequence[int]) -> np.ndarray:
    return np.sort(np.concatenate([md.cell_tags.find(t) for t in tags])).astype(np.int32)


def _facets_of(md: MeshData, tag: int) -> np.ndarray:
    return md.facet_tags.find(tag).astype(np.int32)


def _cellwise(V0: fem.FunctionSpace, md: MeshData, ball_value: float, block_value: float, name: str) -> fem.Function:
    f = fem.Function(V0)
    f.name = name
    f.x.array[:] = block_value
    ball = _cells_of(md, BALL_CELLS)
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
    support = _facets_of(md, G.SUPPORT)
    bcs.append(fem.dirichletbc(zero, fem.locate_dofs_topological(V, fdim, support)))
    for plane, tag, comp in (("x", G.SYM_X, 0), ("z", G.SYM_Z, 2)):
        if plane in plan.symmetry_planes:
            facets = _facets_of(md, tag)
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
    ball_nodes = fem.locate_dofs_topological(V, mesh.topology.dim, _cells_of(md, BALL_CELLS))
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


# --- point probes --------------------------------------------------------------------------------
@dataclass
class PointProbe:
    """Values and gradients of a vector field of ``V`` at fixed points, as sparse linear maps.

    ``values(u_local)`` returns (n_points, 3) and ``gradients(u_local)`` (n_points, 3, 3) with
    grad[i, j] = d u_i / d x_j; ``u_local`` is the local array with ghosts (``Function.x.array``).
    Each point is owned by one rank (the lowest that holds a cell containing it); the results are
    summed over ranks so every rank gets them.
    """

    comm: MPI.Comm
    n_points: int
    P_val: sp.csr_matrix     # (3 n_points) x n_local
    P_grad: sp.csr_matrix    # (9 n_points) x n_local
    found: np.ndarray        # bool per point (globally)

    def values(self, u_local: np.ndarray) -> np.ndarray:
        loc = self.P_val @ u_local
        return self.comm.allreduce(loc, op=MPI.SUM).reshape(self.n_points, 3)

    def gradients(self, u_local: np.ndarray) -> np.ndarray:
        loc = self.P_grad @ u_local
        return self.comm.allreduce(loc, op=MPI.SUM).reshape(self.n_points, 3, 3)


def locate_points(V: fem.FunctionSpace, points: np.ndarray, cells_allowed: np.ndarray) -> np.ndarray:
    """For each point, an owned local cell (from ``cells_allowed``) containing it, or -1; each point
    is given to the lowest rank that finds it."""
    mesh = V.mesh
    n_owned_cells = mesh.topology.index_map(mesh.topology.dim).size_local
    allowed = cells_allowed[cells_allowed < n_owned_cells]
    cell_of = np.full(len(points), -1, dtype=np.int32)
    if len(allowed):
        # bounding boxes give candidates; a barycentric test decides (compute_colliding_cells of
        # DOLFINx 0.5.2 misses points within ~1e-10 m of a face, where our probes sit)
        tree = dgeom.BoundingBoxTree(mesh, mesh.topology.dim, allowed)
        cand = dgeom.compute_collisions(tree, points)
        allowed_set = set(allowed.tolist())

        def best_of(i: int, cells) -> tuple[int, float]:
            best, best_lam = -1, -np.inf
            for c in cells:
                if c not in allowed_set:
                    continue
                lam = _barycentric(mesh, int(c), points[i])
                if lam.min() > best_lam:
                    best, best_lam = int(c), lam.min()
            return best, best_lam

        # a point on a plane of the mesh (a symmetry plane, the struck face) can lie a rounding
        # error outside its cell's bounding box: then the boxes of points nudged by 1e-10 of the
        # mesh size in each direction supply the candidates
        nudge = 1e-10 * float(np.ptp(mesh.geometry.x, axis=0).max() or 1.0)
        for i in range(len(points)):
            best, best_lam = best_of(i, cand.links(i))
            if best_lam <= -1e-8:
                shifted = points[i] + nudge * np.vstack([np.eye(3), -np.eye(3)])
                more = dgeom.compute_collisions(tree, shifted)
                best, best_lam = best_of(i, np.unique(np.concatenate([more.links(k) for k in range(6)])))
            if best >= 0 and best_lam > -1e-8:
                cell_of[i] = best
    comm = mesh.comm
    me = np.where(cell_of >= 0, comm.rank, comm.size).astype(np.int32)
    owner = np.empty_like(me)
    comm.Allreduce(me, owner, op=MPI.MIN)
    cell_of[owner != comm.rank] = -1
    return cell_of


def _barycentric(mesh, cell: int, x: np.ndarray) -> np.ndarray:
    """Barycentric coordinates of x in an affine tetrahedron (all >= 0 inside)."""
    xg = mesh.geometry.x[mesh.geometry.dofmap.links(cell), :3]
    X = np.linalg.solve((xg[1:4] - xg[0]).T, x - xg[0])
    return np.array([1.0 - X.sum(), *X])


def tabulate_at(V: fem.FunctionSpace, cell: int, x: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Scalar basis values (ndofs,) and physical gradients (ndofs, 3) of V's element at point x in
    ``cell`` (affine tetrahedron), and the cell's node (block) dof indices."""
    mesh = V.mesh
    gnodes = mesh.geometry.dofmap.links(cell)
    xg = mesh.geometry.x[gnodes, :3]
    J = (xg[1:4] - xg[0]).T           # x = x0 + J X on the reference tetrahedron
    X = np.linalg.solve(J, x - xg[0])
    elem = V.sub(0).element.basix_element if hasattr(V.sub(0).element, "basix_element") else None
    if elem is None:  # pragma: no cover
        raise RuntimeError("basix element not available")
    tab = elem.tabulate(1, X.reshape(1, 3))  # (4, 1, ndofs, 1)
    N = tab[0, 0, :, 0]
    dNdX = tab[1:4, 0, :, 0]                  # (3, ndofs)
    grad = np.linalg.solve(J.T, dNdX).T       # (ndofs, 3): J^-T dN/dX
    return N, grad, V.dofmap.cell_dofs(cell)


def create_probe(V: fem.FunctionSpace, points: np.ndarray, cells_allowed: np.ndarray) -> PointProbe:
    """A :class:`PointProbe` of V at ``points`` (n, 3), searched among ``cells_allowed``."""
    points = np.ascontiguousarray(points, dtype=np.float64).reshape(-1, 3)
    cells = locate_points(V, points, cells_allowed)
    bs = V.dofmap.index_map_bs
    n_local = (V.dofmap.index_map.size_local + V.dofmap.index_map.num_ghosts) * bs
    rv, cv, vv, rg, cg, vg = [], [], [], [], [], []
    for i, (x, c) in enumerate(zip(points, cells)):
        if c < 0:
            continue
        N, grad, nodes = tabulate_at(V, int(c), x)
        for comp in range(bs):
            dofs = nodes * bs + comp
            rv += [3 * i + comp] * len(dofs); cv += dofs.tolist(); vv += N.tolist()
            for j in range(3):
                rg += [9 * i + 3 * comp + j] * len(dofs); cg += dofs.tolist(); vg += grad[:, j].tolist()
    P_val = sp.csr_matrix((vv, (rv, cv)), shape=(3 * len(points), n_local))
    P_grad = sp.csr_matrix((vg, (rg, cg)), shape=(9 * len(points), n_local))
    found = V.mesh.comm.allreduce((cells >= 0).astype(np.int32), op=MPI.SUM) > 0
    return PointProbe(V.mesh.comm, len(points), P_val, P_grad, found)


def stress_from_gradient(grad: np.ndarray, mu: float, lmbda: float) -> np.ndarray:
    """Cauchy stress (…, 3, 3) in Pa from displacement gradients (…, 3, 3)."""
    eps = 0.5 * (grad + np.swapaxes(grad, -1, -2))
    tr = np.trace(eps, axis1=-2, axis2=-1)
    return 2.0 * mu * eps + lmbda * tr[..., None, None] * np.eye(3)


def von_mises(s: np.ndarray) -> np.ndarray:
    """Von Mises stress of stress tensors (…, 3, 3), Pa."""
    dev = s - np.trace(s, axis1=-2, axis2=-1)[..., None, None] * np.eye(3) / 3.0
    return np.sqrt(1.5 * np.sum(dev * dev, axis=(-2, -1)))
