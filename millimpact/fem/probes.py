"""Point probes: linear maps from a displacement vector to values and gradients at chosen points
(where the contact point and the gauges sit in a symmetric model is the plan's:
:class:`millimpact.scene.plan.ProbeSpec`).

Each probe is a pair of sparse matrices built once from the basis functions of the cells that hold
the points; applying them is a sparse product and an MPI sum, so the time loop records a probe for
the cost of a matrix-vector product. Stresses follow from the gradients by Hooke's law.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from dolfinx import fem
from dolfinx import geometry as dgeom
from mpi4py import MPI


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
    P_val: sp.csr_matrix  # (3 n_points) x n_local
    P_grad: sp.csr_matrix  # (9 n_points) x n_local
    found: np.ndarray  # bool per point (globally)

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


def scalar_element(V: fem.FunctionSpace):
    """The basix element of V's scalar component (for :func:`tabulate_at`; V.sub(0) builds a
    subspace, 0.4-0.6 ms a call: once per loop over points, not once per point)."""
    element = V.sub(0).element
    if not hasattr(element, "basix_element"):  # pragma: no cover
        raise RuntimeError("basix element not available")
    return element.basix_element


def tabulate_at(
    V: fem.FunctionSpace, cell: int, x: np.ndarray, element=None
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Scalar basis values (ndofs,) and physical gradients (ndofs, 3) of V's element at point x in
    ``cell`` (affine tetrahedron), and the cell's node (block) dof indices. ``element``: V's
    :func:`scalar_element`, when the caller tabulates many points."""
    mesh = V.mesh
    gnodes = mesh.geometry.dofmap.links(cell)
    xg = mesh.geometry.x[gnodes, :3]
    J = (xg[1:4] - xg[0]).T  # x = x0 + J X on the reference tetrahedron
    X = np.linalg.solve(J, x - xg[0])
    elem = scalar_element(V) if element is None else element
    tab = elem.tabulate(1, X.reshape(1, 3))  # (4, 1, ndofs, 1)
    N = tab[0, 0, :, 0]
    dNdX = tab[1:4, 0, :, 0]  # (3, ndofs)
    grad = np.linalg.solve(J.T, dNdX).T  # (ndofs, 3): J^-T dN/dX
    return N, grad, V.dofmap.cell_dofs(cell)


def create_probe(V: fem.FunctionSpace, points: np.ndarray, cells_allowed: np.ndarray) -> PointProbe:
    """A :class:`PointProbe` of V at ``points`` (n, 3), searched among ``cells_allowed``."""
    points = np.ascontiguousarray(points, dtype=np.float64).reshape(-1, 3)
    cells = locate_points(V, points, cells_allowed)
    bs = V.dofmap.index_map_bs
    n_local = (V.dofmap.index_map.size_local + V.dofmap.index_map.num_ghosts) * bs
    rv, cv, vv, rg, cg, vg = [], [], [], [], [], []
    element = scalar_element(V) if np.any(cells >= 0) else None
    for i, (x, c) in enumerate(zip(points, cells)):
        if c < 0:
            continue
        N, grad, nodes = tabulate_at(V, int(c), x, element)
        for comp in range(bs):
            dofs = nodes * bs + comp
            rv += [3 * i + comp] * len(dofs)
            cv += dofs.tolist()
            vv += N.tolist()
            for j in range(3):
                rg += [9 * i + 3 * comp + j] * len(dofs)
                cg += dofs.tolist()
                vg += grad[:, j].tolist()
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


def patch_indicator(
    V: fem.FunctionSpace, M, body_dofs: np.ndarray, point: np.ndarray, direction: np.ndarray, radius: float
):
    """The nodal indicator chi of a patch, directed: chi_(i,k) = d_k for the nodes i of a body
    (``body_dofs``) within ``radius`` of ``point``, 0 elsewhere; and the uniform field e_(i,k) = d_k
    (vectors of ``M``'s layout). The radius grows by sqrt(2) until at least four nodes are inside
    (a mesh coarser than the radius). Returns (chi, e, nodes inside, radius used); collective.
    See :func:`patch_momentum_row`."""
    comm = V.mesh.comm
    bs = V.dofmap.index_map_bs
    n_owned = V.dofmap.index_map.size_local
    X = V.tabulate_dof_coordinates()[:n_owned]
    nodes = np.unique(np.asarray(body_dofs) // bs)
    dist = np.linalg.norm(X[nodes] - np.asarray(point, dtype=float)[None, :], axis=1)
    r = float(radius)
    while True:
        inside = nodes[dist <= r]
        n_in = comm.allreduce(len(inside), op=MPI.SUM)
        if n_in >= 4 or r > 1e3 * radius:
            break
        r *= np.sqrt(2.0)
    d = np.asarray(direction, dtype=float)
    chi, e = M.createVecRight(), M.createVecRight()
    chi.set(0.0)
    e.set(0.0)
    for k in range(bs):
        chi.array[inside * bs + k] = d[k]
        e.array[np.arange(n_owned) * bs + k] = d[k]
    return chi, e, n_in, r


def patch_momentum_row(mass, chi, e):
    """The row c with ``c . v`` the velocity along d of the patch's centre of mass,

        c = M chi / (e . M chi),   c . v = chi^T M v / m_patch,

    chi and e from :func:`patch_indicator`, M the mass the time integrator uses: chi^T M v is the
    patch's momentum along d (chi interpolates the indicator of the patch: the nodes inside and
    a one-element fringe) and e . M chi its mass. So ``c . a`` is the resultant force on the
    patch over its mass, chi^T (f_contact - K u) / m_patch: it follows the contact force and the
    stresses around the patch, smooth in time, while the contact node's own velocity jumps at
    first contact (a massless node under mass redistribution takes the contact impulse alone)
    and its acceleration spikes at onset and release. For the contact point
    (:class:`millimpact.results.recorder.Recorder`) the patch is the half-ball of radius a_max
    under the impact point; ``benchmarks/contact_point_convergence.py`` measures its convergence
    under dt and h. Collective; the caller destroys c."""
    c = mass.createVecLeft()
    mass.mult(chi, c)
    m_patch = c.dot(e)
    c.scale(1.0 / m_patch)
    return c
