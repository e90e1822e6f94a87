"""Manifold (NMM) enrichment of the contact zone: a prolongation into the P2 space.

The paper's "improved multivariable method" describes the contact zone of each body by first-order
numerical-manifold covers (docs/methods.md, "Methods")::

    u(x) = sum_i N_i(x) (a_i + b_i . (x - x_i) / h_i)          (one such field per component)

with ``N_i`` the P1 hat functions of the zone's vertices ``x_i`` (the partition of unity), ``a_i``
the vertex value and ``b_i`` the scaled gradient (``h_i`` the mean length of the zone edges at
vertex i: ``a`` and ``b`` share the unit metre and the reduced mass matrix stays well conditioned).
On each affine tetrahedron ``u`` is quadratic, so the enriched fields are exactly their P2 nodal
interpolant. The prolongation ``P`` maps the cover coordinates to P2 nodal values:

* vertex node j:                 u_j = a_j
* midpoint m of edge (i, j):     u_m = (a_i + a_j) / 2 + (b_i / h_i - b_j / h_j) . (x_j - x_i) / 4

Every P2 node of a zone cell, the interface nodes included, takes its value from ``P``, so the
field is one conforming P2 function on the whole mesh; the region's interior is reduced by
Craig-Bampton on top (:mod:`.craig_bampton`), the interface nodes' cover coordinates as boundary
coordinates.

Null space: fields with ``a = 0`` and ``b_i = c + W x_i`` (W antisymmetric) vanish at every node
(the rigid motions of the edge framework, 6 per scalar field and connected zone), so with every
vertex enriched ``P^T M P`` is singular. Remedies (``remedy=``): ``"interface"`` (default) drops
``b`` at the interface vertices (a piecewise linear trace, 3 boundary coordinates per interface
vertex instead of 12); ``"anchors"`` drops it at three far-apart, non-collinear interface vertices
per zone; ``"none"`` keeps every vertex enriched (singular, for tests of the null space).

Constrained dofs: where component c of a zone vertex is fixed (symmetry plane or clamp), ``a^c``
is dropped and so are the components of ``b^c`` along the edges whose midpoints are fixed in c;
rows of ``P`` at fixed dofs stay empty. Edge-vector components below ``DIRECTION_TOL`` of the edge
length are exact zeros, so that ``P`` does not depend on the mesh partition's round-off.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import basix
import numpy as np
from dolfinx.common import IndexMap
from dolfinx.cpp.la.petsc import create_vector as _create_ghosted_vector
from mpi4py import MPI
from petsc4py import PETSc

from ..errors import InputError
from ..fem.model import FEModel
from ..geometry import builders as G
from .distributed import ownership_offsets
from .partition import DofPartition, ZoneBasis, partition_dofs, tagged_cells

log = logging.getLogger(__name__)

REMEDIES = ("interface", "anchors", "none")
#: cover coordinates per vertex and their order: a^x, a^y, a^z, then b^c_k at 3 + 3 c + k
SLOTS = 12
#: a direction component counts as present when above this share of the edge length
DIRECTION_TOL = 1e-8


@dataclass
class NMMZone:
    """The manifold-enriched zone: the :class:`ZoneBasis` (``basis.G`` = P) and, per owned zone
    vertex, its local P2 node, coordinates (m), scale h (m) and the global coordinate index of each
    of its 12 slots (-1 where dropped)."""

    basis: ZoneBasis
    nodes: np.ndarray  #: (nv,) local node indices of the owned zone vertices
    x: np.ndarray  #: (nv, 3)
    h: np.ndarray  #: (nv,)
    index: np.ndarray  #: (nv, 12) global coordinate indices, -1 if dropped
    remedy: str

    def linear_field(self, c: np.ndarray, A: np.ndarray) -> np.ndarray:
        """Owned coordinate values (local array) representing u(x) = c + A x (exact for every
        linear field: a_i = c + A x_i, b_i^c = h_i A[c, :])."""
        q = np.zeros(self.basis.n_local)
        lo = self.basis.G.getOwnershipRangeColumn()[0]
        vals = np.zeros((len(self.nodes), SLOTS))
        vals[:, :3] = c[None, :] + self.x @ A.T
        vals[:, 3:] = self.h[:, None] * A.reshape(1, 9)
        kept = self.index >= 0
        q[self.index[kept] - lo] = vals[kept]
        return q


def _accumulate(imap: IndexMap, bs: int, values: np.ndarray, op: str = "add") -> np.ndarray:
    """Sum (``add``) node values over the ranks that hold the node, returned on owners and ghosts
    alike (reverse then forward ghost update). ``values``: (n_local_nodes_with_ghosts, bs)."""
    x = _create_ghosted_vector(imap, bs)
    with x.localForm() as loc:
        loc.array[:] = values.ravel()
    if op == "add":
        x.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
    x.ghostUpdate(addv=PETSc.InsertMode.INSERT, mode=PETSc.ScatterMode.FORWARD)
    with x.localForm() as loc:
        out = loc.array.reshape(-1, bs).copy()
    x.destroy()
    return out


def _cell_layout(V):
    """Local cell-dof columns of the P2 vertex nodes (4) and of the edge nodes with their two
    vertex columns (6 x 3: edge node, vertex a, vertex b)."""
    layout = V.dofmap.dof_layout
    vcol = [layout.entity_dofs(0, v)[0] for v in range(4)]
    edges = basix.topology(basix.CellType.tetrahedron)[1]
    ecol = [(layout.entity_dofs(1, e)[0], vcol[a], vcol[b]) for e, (a, b) in enumerate(edges)]
    return np.array(vcol), np.array(ecol)


@dataclass(frozen=True)
class _ZoneMesh:
    """The zone's P2 nodes as :func:`create_nmm_zone` reads them: the model's dof layout (``imap``,
    ``bs``, owned and local nodes), node coordinates ``X``, each zone edge as (midpoint, vertex i,
    vertex j), the zone cells' nodes ``cn`` and the fixed flags (node, component) of every local node."""

    imap: IndexMap
    bs: int
    n_own: int
    n_loc: int
    X: np.ndarray
    E: np.ndarray
    cn: np.ndarray
    vcol: np.ndarray
    ball_cells: np.ndarray
    cell_nodes: np.ndarray
    fixed: np.ndarray


def create_nmm_zone(
    model: FEModel, partition: DofPartition | None = None, *, remedy: str = "interface", scale: bool = True
) -> NMMZone:
    """The manifold-enriched zone of a P2 model (see the module docstring). Collective."""
    if model.degree != 2:
        raise InputError(f"manifold enrichment needs the P2 model (got P{model.degree})")
    if remedy not in REMEDIES:
        raise InputError(f"NMM null-space remedy {remedy!r}: must be one of {', '.join(REMEDIES)}")
    part = partition or partition_dofs(model)
    comm = model.comm
    zm = _zone_mesh(model)
    is_vertex, is_ball, h, tangent_fixed = _vertex_data(zm, scale)
    # kept slots of the owned zone vertices
    own_v = np.nonzero(is_vertex[: zm.n_own])[0].astype(np.int32)
    keep = np.ones((len(own_v), SLOTS), dtype=bool)
    keep[:, :3] = ~zm.fixed[own_v]
    keep[:, 3:] = ~tangent_fixed[own_v].reshape(-1, 9)
    n_fixed_drop = int(np.count_nonzero(~keep))
    interface_v = part.region_node[own_v]
    gidx = zm.imap.local_to_global(own_v)
    if remedy == "interface":
        keep[interface_v, 3:] = False
        # a body wholly in the zone (the plan's whole plastic body) has no interface: its edge
        # framework's rigid null space goes by three anchors among all its vertices
        for ball in (True, False):
            body = is_ball[own_v] == ball
            if comm.allreduce(int(np.count_nonzero(body & interface_v))) == 0 and comm.allreduce(
                int(np.count_nonzero(body))
            ):
                anchors = _choose_anchors(comm, zm.imap, own_v[body], zm.X[own_v[body]], is_ball[own_v[body]], model)
                keep[np.isin(gidx, anchors), 3:] = False
    elif remedy == "anchors":
        anchors = _choose_anchors(
            comm, zm.imap, own_v[interface_v], zm.X[own_v[interface_v]], is_ball[own_v[interface_v]], model
        )
        keep[np.isin(gidx, anchors), 3:] = False
    n_drop = int(np.count_nonzero(~keep))
    n_q = int(np.count_nonzero(keep))
    q0 = int(ownership_offsets(comm, n_q)[comm.rank])
    index = np.full((len(own_v), SLOTS), -1, dtype=np.int64)
    index[keep] = q0 + np.arange(n_q)
    idx_all = np.full((zm.n_loc, SLOTS), -1.0)
    idx_all[own_v] = index
    idx_all = _accumulate(zm.imap, SLOTS, idx_all, op="forward").round().astype(np.int64)
    P = _prolongation(zm, idx_all, h, n_q, comm)
    body = np.repeat(np.where(is_ball[own_v], 0, 1), SLOTS).reshape(-1, SLOTS)[keep].astype(np.int8)
    totals = comm.allreduce(
        np.array(
            [len(own_v), n_q, n_fixed_drop, n_drop - n_fixed_drop, int(np.count_nonzero(interface_v))], dtype=np.int64
        ),
        op=MPI.SUM,
    )
    info = {
        "zone_vertices": int(totals[0]),
        "zone_coordinates": int(totals[1]),
        "dropped_constrained": int(totals[2]),
        "dropped_remedy": int(totals[3]),
        "interface_vertices": int(totals[4]),
        "remedy": remedy,
        "p2_zone_dofs": int(comm.allreduce(len(part.zone))),
    }
    if comm.rank == 0:
        log.info(
            "NMM zone: %d vertices, %d cover coordinates (P2 zone dofs %d), dropped %d constrained + %d (%s)",
            info["zone_vertices"],
            info["zone_coordinates"],
            info["p2_zone_dofs"],
            info["dropped_constrained"],
            info["dropped_remedy"],
            remedy,
        )
    basis = ZoneBasis(P, body, "nmm", info)
    return NMMZone(basis, own_v, zm.X[own_v].copy(), h[own_v].copy(), index, remedy)


def _zone_mesh(model: FEModel) -> _ZoneMesh:
    """The zone's cells, edges and the fixed flags of every local node."""
    V = model.V
    mesh = V.mesh
    imap = V.dofmap.index_map
    bs = V.dofmap.index_map_bs
    n_own = imap.size_local
    n_loc = n_own + imap.num_ghosts
    X = V.tabulate_dof_coordinates()[:, :3]
    n_cells_own = mesh.topology.index_map(mesh.topology.dim).size_local
    cell_nodes = V.dofmap.list.array.reshape(-1, V.dofmap.dof_layout.num_dofs)
    vcol, ecol = _cell_layout(V)
    zone_cells = tagged_cells(model, (G.BALL_ZONE, G.BLOCK_ZONE))
    zone_cells = zone_cells[zone_cells < n_cells_own]
    ball_cells = tagged_cells(model, (G.BALL_ZONE,))
    ball_cells = ball_cells[ball_cells < n_cells_own]
    cn = cell_nodes[zone_cells]  # (nc, 10)
    E = np.stack([cn[:, ecol[:, 0]], cn[:, ecol[:, 1]], cn[:, ecol[:, 2]]], axis=-1).reshape(-1, 3)  # m, i, j
    # fixed flags on every local node
    fixed_owned = np.zeros(n_own * bs)
    fixed_owned[model.fixed_dofs] = 1.0
    fixed = (
        _accumulate(
            imap, bs, np.concatenate([fixed_owned, np.zeros((n_loc - n_own) * bs)]).reshape(-1, bs), op="forward"
        )
        > 0.5
    )
    return _ZoneMesh(imap, bs, n_own, n_loc, X, E, cn, vcol, ball_cells, cell_nodes, fixed)


def _vertex_data(zm: _ZoneMesh, scale: bool) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Per local node: zone vertex, ball-zone vertex, the scale h (mean zone edge length, m; 1
    without ``scale``) and the tangential drop mask [node, c, k] (a midpoint fixed in c on an edge
    along axis k), summed over the ranks that hold the node."""
    E, X = zm.E, zm.X
    acc = np.zeros((zm.n_loc, 13))
    acc[np.unique(zm.cn[:, zm.vcol]), 0] = 1.0
    acc[np.unique(zm.cell_nodes[zm.ball_cells][:, zm.vcol]), 1] = 1.0
    d = X[E[:, 2]] - X[E[:, 1]]
    length = np.linalg.norm(d, axis=1)
    for end in (1, 2):
        np.add.at(acc[:, 2], E[:, end], length)
        np.add.at(acc[:, 3], E[:, end], 1.0)
    along = np.abs(d) > DIRECTION_TOL * length[:, None]  # (ne, 3) axes an edge spans
    for c in range(3):
        fm = zm.fixed[E[:, 0], c]  # midpoint fixed in component c
        for end in (1, 2):
            for k in range(3):
                sel = fm & along[:, k]
                np.add.at(acc[:, 4 + 3 * c + k], E[sel, end], 1.0)
    acc = _accumulate(zm.imap, 13, acc)
    h = np.where(acc[:, 3] > 0, acc[:, 2] / np.maximum(acc[:, 3], 1), 1.0) if scale else np.ones(zm.n_loc)
    return acc[:, 0] > 0.5, acc[:, 1] > 0.5, h, acc[:, 4:13].reshape(-1, 3, 3) > 0.5


def _prolongation(zm: _ZoneMesh, idx_all: np.ndarray, h: np.ndarray, n_q: int, comm: MPI.Comm) -> PETSc.Mat:
    """P's rows: vertex nodes and edge midpoints of the owned zone cells (off-process rows
    stashed); ``idx_all`` the global coordinate index of each local node's slots (-1: dropped)."""
    bs, X, fixed = zm.bs, zm.X, zm.fixed
    P = PETSc.Mat().createAIJ(((zm.n_own * bs, PETSc.DETERMINE), (n_q, PETSc.DETERMINE)), comm=comm)
    P.setPreallocationNNZ((8, 8))
    P.setOption(PETSc.Mat.Option.NEW_NONZERO_ALLOCATION_ERR, False)
    gnode = zm.imap.local_to_global(np.arange(zm.n_loc, dtype=np.int32))
    INSERT = PETSc.InsertMode.INSERT_VALUES
    for j in np.unique(zm.cn[:, zm.vcol]):
        for c in range(3):
            col = idx_all[j, c]
            if fixed[j, c] or col < 0:
                continue
            P.setValues([int(gnode[j]) * bs + c], [int(col)], [1.0], addv=INSERT)
    mids, first = np.unique(zm.E[:, 0], return_index=True)
    for m, (_, i, j) in zip(mids, zm.E[first]):
        dij = X[j] - X[i]
        # components below round-off are exact zeros (an edge in a symmetry plane or an
        # axis-aligned face): the P2 dof coordinates carry ~1e-20 m there, which differ with the
        # mesh partition, and would otherwise leave 1e-17 entries that make the gradient
        # coordinates "touch" the contact dofs (mass redistribution) on some partitions only
        dij = np.where(np.abs(dij) > DIRECTION_TOL * np.linalg.norm(dij), dij, 0.0)
        for c in range(3):
            if fixed[m, c]:
                continue
            cols = [idx_all[i, c], idx_all[j, c]]
            vals = [0.5, 0.5]
            for k in range(3):
                cols += [idx_all[i, 3 + 3 * c + k], idx_all[j, 3 + 3 * c + k]]
                vals += [0.25 * dij[k] / h[i], -0.25 * dij[k] / h[j]]
            row_cols, row_vals = np.array(cols), np.array(vals)
            ok = (row_cols >= 0) & (row_vals != 0.0)
            if np.any(ok):
                P.setValues([int(gnode[m]) * bs + c], row_cols[ok].astype(np.int32), row_vals[ok], addv=INSERT)
    P.assemble()
    return P


def _choose_anchors(
    comm: MPI.Comm, imap: IndexMap, nodes: np.ndarray, x: np.ndarray, ball: np.ndarray, model: FEModel
) -> np.ndarray:
    """Global node indices of three interface vertices per zone, far apart and not collinear:
    A the farthest from the zone's contact point, B the farthest from A, C the farthest from the
    line AB (ties broken by the global index, so every rank picks the same)."""
    g = imap.local_to_global(nodes.astype(np.int32)).astype(np.int64)
    all_g = np.concatenate(comm.allgather(g))
    all_x = np.concatenate(comm.allgather(x)).reshape(-1, 3)
    all_b = np.concatenate(comm.allgather(ball))
    info = model.meshdata.info
    picked = []
    for is_ball, centre in ((True, info.contact_point_ball), (False, info.contact_point_block)):
        sel = all_b == is_ball
        if np.count_nonzero(sel) < 3 or centre is None:
            continue
        gg, xx = all_g[sel], all_x[sel]
        order = np.argsort(gg)
        gg, xx = gg[order], xx[order]
        a = int(np.argmax(np.linalg.norm(xx - np.asarray(centre), axis=1)))
        b = int(np.argmax(np.linalg.norm(xx - xx[a], axis=1)))
        ab = (xx[b] - xx[a]) / np.linalg.norm(xx[b] - xx[a])
        rel = xx - xx[a]
        off = np.linalg.norm(rel - np.outer(rel @ ab, ab), axis=1)
        c = int(np.argmax(off))
        picked += [gg[a], gg[b], gg[c]]
    return np.array(picked, dtype=np.int64)
