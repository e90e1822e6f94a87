"""Contact kinematics: node-to-surface, small-displacement gap to a plane, optional friction rows.

The ball's surface nodes near the contact point are the slave nodes; the struck face (the block's
plane y = 0, or a liner's lifter face: the plane through the impact point p with outward unit
normal n) is the master surface. Displacements stay small against the ball radius (the approach
is ~90 um for R = 15 mm), so the normal stays n and each slave node keeps its projection point
p_i = x_i - ((x_i - p) . n) n on the face:

    gap_i = (x_i - p) . n + n . (u(x_i) - u^block(p_i)) >= 0,   lambda_i >= 0,   lambda_i gap_i = 0,

a linear map gap = g0 + B u (for the block, n = e_y: gap_i = y_i + u_y(x_i) - u_y^block(p_i)).
Node-to-surface (not mortar) because the master is flat and smooth, so the gap of each slave node
is exact to first order; the multipliers are nodal forces (N), whose sum is the contact force.
Mortar would give smoother pressures; the nodal forces integrate to the same resultant.

With friction (the plan's coefficient ``plan.friction > 0``) two tangential rows per slave node give the
relative tangential displacement s_i = t_k . (u(x_i) - u^block(p_i)), k = 1, 2, for an orthonormal
tangent basis (t1, t2) of the face; their multipliers are the tangential nodal forces on the ball
(:mod:`millimpact.integration.friction`). The master points stay fixed (small sliding): valid while the
slip distance stays small against the contact radius.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, field

import numpy as np
from dolfinx import fem
from mpi4py import MPI
from petsc4py import PETSc

from ..scene.plan import Plan
from .model import FEModel
from .probes import locate_points, scalar_element, tabulate_at

log = logging.getLogger(__name__)

#: candidate slave nodes lie within this many a_max of the contact axis (Hertz patch radius a_max)
CANDIDATE_RADIUS_FACTOR = 2.5


@dataclass
class ContactSet:
    """Constraint rows gap = g0 + B u >= 0 for the candidate slave nodes (SI units).

    ``points`` (n_c, 3) slave-node coordinates (replicated), ``B`` PETSc (n_c x n), ``g0`` initial
    gaps (m), ``contact_dofs`` local owned dofs whose mass mass-redistribution removes
    all three components of the slave nodes and of the block-face nodes they touch, less clamped
    or symmetry dofs), ``radius`` the candidate
    radius around the axis p + s n (m), ``point`` the impact point p on the face (m).
    """

    points: np.ndarray
    B: PETSc.Mat
    g0: np.ndarray
    contact_dofs: np.ndarray
    radius: float
    point: np.ndarray  #: p, the impact point: the contact axis is p + s n
    normal: np.ndarray = field(default_factory=lambda: np.array([0.0, 1.0, 0.0]))  #: n, outward from the block
    tangents: np.ndarray | None = None  #: (2, 3) t1, t2 (friction only)
    T: PETSc.Mat | None = None  #: (2 n_c x n) tangential rows [t1 rows; t2 rows] (friction only)

    @property
    def n(self) -> int:
        return len(self.g0)


def tangent_basis(n: np.ndarray) -> np.ndarray:
    """An orthonormal tangent basis (t1, t2) of the plane with unit normal n, t2 = n x t1: t1 = e_x
    when n is normal to x (the block's face, a lifter face), else the projection of e_x or e_z."""
    n = np.asarray(n, dtype=float)
    e = np.array([1.0, 0.0, 0.0]) if abs(n[0]) < 0.9 else np.array([0.0, 0.0, 1.0])
    t1 = e - (e @ n) * n
    t1 /= np.linalg.norm(t1)
    return np.array([t1, np.cross(n, t1)])


def create_contact(
    model: FEModel, plan: Plan, radius: float | None = None, friction: bool | None = None, ball_offset=None
) -> ContactSet:
    """Build the contact constraint rows of a model (collective) at its impact point and contact
    normal; candidates within ``radius`` (m; default 2.5 a_max, inside the plan's zone) of the
    contact axis; with ``friction`` (default: the plan's coefficient > 0) also the tangential
    rows. ``ball_offset`` (m, a vector in the face's plane; repeated impacts at a shifted place,
    :mod:`millimpact.repeat`): the ball stands at its meshed place shifted by it, so each slave
    node's master point is the face point below the shifted node, p_i = x_i + d - ((x_i - p) . n) n
    (the ball's displacement is then measured from the shifted place)."""
    V = model.V
    comm = model.comm
    mesh = V.mesh
    bs = V.dofmap.index_map_bs
    imap = V.dofmap.index_map
    n_owned_nodes = imap.size_local
    p = np.array(model.impact_point, dtype=float)
    n = np.array(model.contact_normal, dtype=float)
    if friction is None:
        friction = plan.friction > 0.0
    radius = radius or min(CANDIDATE_RADIUS_FACTOR * plan.hertz.a_max, 0.95 * min(plan.zone_radius, plan.ball_zone))

    fdim = mesh.topology.dim - 1
    nodes = fem.locate_dofs_topological(V, fdim, model.contact_facets)
    nodes = nodes[nodes < n_owned_nodes]
    coords = V.tabulate_dof_coordinates()[nodes]
    d = coords - p
    r = np.linalg.norm(d - np.outer(d @ n, n), axis=1)  # distance from the contact axis p + s n
    keep = r < radius
    nodes, coords = nodes[keep], coords[keep]
    order = np.lexsort((coords[:, 2], coords[:, 0], coords[:, 1]))  # deterministic order
    nodes, coords = nodes[order], coords[order]

    # global numbering of rows: rank order
    counts = comm.allgather(len(nodes))
    offset = sum(counts[: comm.rank])
    n_c = sum(counts)
    points = np.concatenate(comm.allgather(coords)) if n_c else np.zeros((0, 3))
    g0 = (points - p) @ n
    if n_c == 0:
        raise RuntimeError("no contact candidate nodes on the ball: is the contact zone meshed?")
    if g0.min() < 0:
        raise RuntimeError(f"a ball node starts {-g0.min():g} m inside the block")

    n_global = imap.size_global * bs
    n_local = imap.size_local * bs

    def rows_matrix(rows: int) -> PETSc.Mat:
        A = PETSc.Mat().createAIJ(((PETSc.DECIDE, rows), (n_local, n_global)), comm=comm)
        A.setPreallocationNNZ((40, 40))
        A.setOption(PETSc.Mat.Option.NEW_NONZERO_ALLOCATION_ERR, False)
        return A

    dirs = [n] + (list(tangent_basis(n)) if friction else [])
    B = rows_matrix(n_c)
    T = rows_matrix(2 * n_c) if friction else None
    mats = [B] + ([T] if friction else [])
    # rows of direction k: B for k = 0 (row i), T for k = 1, 2 (row (k - 1) n_c + i)
    targets = [(B, 0)] + ([(T, 0), (T, n_c)] if friction else [])

    glob_nodes = imap.local_to_global(nodes.astype(np.int32))
    for (mat, roff), e in zip(targets, dirs):
        for i, gn in enumerate(glob_nodes):
            for comp in range(3):
                if e[comp] != 0.0:
                    mat.setValue(
                        roff + offset + i, int(gn) * bs + comp, float(e[comp]), addv=PETSc.InsertMode.ADD_VALUES
                    )

    # master side: the block's face point below each slave node, found on whichever rank owns it
    proj = points - np.outer(g0, n)  # on the face
    if ball_offset is not None:
        d_t = np.asarray(ball_offset, dtype=float)
        proj = proj + (d_t - (d_t @ n) * n)[None, :]
    face_points = proj - 1e-9 * plan.h_contact * n  # just inside the block
    cells = locate_points(V, face_points, model.block_cells)
    block_face_dofs = []
    element = scalar_element(V) if np.any(cells >= 0) else None
    for i, c in enumerate(cells):
        if c < 0:
            continue
        # the cell was found just inside; its trace is evaluated on the face
        N, _, cnodes = tabulate_at(V, int(c), proj[i], element)
        gcn = imap.local_to_global(cnodes.astype(np.int32))
        for w, gn in zip(N, gcn):
            if abs(w) > 1e-9:  # nodes off the face have weight 0 up to round-off
                for (mat, roff), e in zip(targets, dirs):
                    for comp in range(3):
                        if e[comp] != 0.0:
                            mat.setValue(
                                roff + i,
                                int(gn) * bs + comp,
                                -float(w) * float(e[comp]),
                                addv=PETSc.InsertMode.ADD_VALUES,
                            )
                block_face_dofs.append(int(gn))
    found = comm.allreduce((cells >= 0).astype(np.int32), op=MPI.SUM)
    if np.any(found == 0):
        raise RuntimeError(f"{int(np.sum(found == 0))} contact points have no block face below them")
    for mat in mats:
        mat.assemble()
    # the block-face dofs may be owned by another rank than the one that found them
    face_nodes = np.unique(np.concatenate(comm.allgather(np.asarray(block_face_dofs, dtype=np.int64))))
    lo = imap.local_range[0]
    face_local = face_nodes[(face_nodes >= lo) & (face_nodes < lo + n_owned_nodes)] - lo
    # all components of the slave nodes and of the block-face nodes they touch lose their mass
    contact_nodes = np.unique(np.concatenate([nodes.astype(np.int64), face_local]))
    contact_dofs = (contact_nodes[:, None] * bs + np.arange(bs)[None, :]).ravel().astype(np.int32)
    contact_dofs = np.setdiff1d(contact_dofs, model.fixed_dofs).astype(np.int32)
    log.info(
        "contact: %d slave nodes within %.3g mm of the axis%s",
        n_c,
        radius * 1e3,
        ", with friction rows" if friction else "",
    )
    return ContactSet(points, B, g0, contact_dofs, radius, p, n, tangent_basis(n) if friction else None, T)
