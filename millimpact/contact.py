"""Contact kinematics: node-to-surface, frictionless, small-displacement gap.

The ball's surface nodes near the contact point are the slave nodes; the block's struck face
(the plane y = 0) is the master surface. Displacements stay small against the ball radius (the
approach is ~90 um for R = 15 mm), so the normal is the face normal -y and each slave node keeps
its projection point on the face:

    gap_i = y_i + u_y(p_i) - u_y^block(x_i, 0, z_i) >= 0,   lambda_i >= 0,   lambda_i gap_i = 0,

a linear map gap = g0 + B u. Node-to-surface (not mortar) because the master is flat and smooth,
so the gap of each slave node is exact to first order; the multipliers are nodal forces (N), whose
sum is the contact force. Mortar would give smoother pressures; the nodal forces integrate to the
same resultant.
"""
from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np
from dolfinx import fem
from mpi4py import MPI
from petsc4py import PETSc

from . import geometry as G
from .model import BLOCK_CELLS, FEModel, _cells_of, _facets_of, locate_points, tabulate_at

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
    radius around the axis (m).
    """

    points: np.ndarray
    B: PETSc.Mat
    g0: np.ndarray
    contact_dofs: np.ndarray
    radius: float

    @property
    def n(self) -> int:
        return len(self.g0)


def create_contact(model: FEModel, radius: float | None = None) -> ContactSet:
    """Build the contact constraint rows of a model (collective)."""
    V = model.V
    comm = model.comm
    md = model.meshdata
    mesh = V.mesh
    plan = model.plan
    bs = V.dofmap.index_map_bs
    imap = V.dofmap.index_map
    n_owned_nodes = imap.size_local
    x_p, _, z_p = model.scene.impact_point
    radius = radius or min(CANDIDATE_RADIUS_FACTOR * plan.hertz.a_max, 0.95 * plan.zone_radius)

    fdim = mesh.topology.dim - 1
    nodes = fem.locate_dofs_topological(V, fdim, _facets_of(md, G.BALL_CONTACT))
    nodes = nodes[nodes < n_owned_nodes]
    coords = V.tabulate_dof_coordinates()[nodes]
    r = np.hypot(coords[:, 0] - x_p, coords[:, 2] - z_p)
    keep = r < radius
    nodes, coords = nodes[keep], coords[keep]
    order = np.lexsort((coords[:, 2], coords[:, 0], coords[:, 1]))  # deterministic order
    nodes, coords = nodes[order], coords[order]

    # global numbering of rows: rank order
    counts = comm.allgather(len(nodes))
    offset = sum(counts[:comm.rank])
    n_c = sum(counts)
    points = np.concatenate(comm.allgather(coords)) if n_c else np.zeros((0, 3))
    g0 = points[:, 1].copy()
    if n_c == 0:
        raise RuntimeError("no contact candidate nodes on the ball: is the contact zone meshed?")
    if g0.min() < 0:
        raise RuntimeError(f"a ball node starts {-g0.min():g} m inside the block")

    n_global = imap.size_global * bs
    n_local = imap.size_local * bs
    B = PETSc.Mat().createAIJ(((PETSc.DECIDE, n_c), (n_local, n_global)), comm=comm)
    B.setPreallocationNNZ((40, 40))
    B.setOption(PETSc.Mat.Option.NEW_NONZERO_ALLOCATION_ERR, False)
    glob_nodes = imap.local_to_global(nodes.astype(np.int32))
    for i, gn in enumerate(glob_nodes):
        B.setValue(offset + i, int(gn) * bs + 1, 1.0, addv=PETSc.InsertMode.ADD_VALUES)

    # master side: the block's face point below each slave node, found on whichever rank owns it
    face_points = points.copy()
    face_points[:, 1] = -1e-9 * plan.h_contact   # just inside the block, on its face
    cells = locate_points(V, face_points, _cells_of(md, BLOCK_CELLS))
    block_face_dofs = []
    for i, c in enumerate(cells):
        if c < 0:
            continue
        on_face = face_points[i].copy()
        on_face[1] = 0.0  # the cell was found just inside; its trace is evaluated on the face
        N, _, cnodes = tabulate_at(V, int(c), on_face)
        gcn = imap.local_to_global(cnodes.astype(np.int32))
        for w, gn in zip(N, gcn):
            if abs(w) > 1e-9:  # nodes off the face have weight 0 up to round-off
                B.setValue(i, int(gn) * bs + 1, -float(w), addv=PETSc.InsertMode.ADD_VALUES)
                block_face_dofs.append(int(gn))
    found = comm.allreduce((cells >= 0).astype(np.int32), op=MPI.SUM)
    if np.any(found == 0):
        raise RuntimeError(f"{int(np.sum(found == 0))} contact points have no block face below them")
    B.assemble()
    # the block-face dofs may be owned by another rank than the one that found them
    face_nodes = np.unique(np.concatenate(comm.allgather(np.asarray(block_face_dofs, dtype=np.int64))))
    lo = imap.local_range[0]
    face_local = face_nodes[(face_nodes >= lo) & (face_nodes < lo + n_owned_nodes)] - lo
    # all components of the slave nodes and of the block-face nodes they touch lose their mass
    contact_nodes = np.unique(np.concatenate([nodes.astype(np.int64), face_local]))
    contact_dofs = (contact_nodes[:, None] * bs + np.arange(bs)[None, :]).ravel().astype(np.int32)
    contact_dofs = np.setdiff1d(contact_dofs, model.fixed_dofs).astype(np.int32)
    log.info("contact: %d slave nodes within %.3g mm of the axis", n_c, radius * 1e3)
    return ContactSet(points, B, g0, contact_dofs, radius)
