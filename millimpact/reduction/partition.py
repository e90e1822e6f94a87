"""The dof sets of a reduction: fixed, contact zone and interior (per body), and the zone's basis.

The owned dofs of an :class:`millimpact.fem.model.FEModel` fall into ``fixed`` (clamped and symmetry), ``zone`` (the
cells tagged BALL_ZONE / BLOCK_ZONE, interface nodes included) and ``interior`` (the rest, per body). A
:class:`ZoneBasis` describes the zone, u_z = G q_z: the identity (nodal dofs kept, :func:`create_nodal_zone_basis`)
or the manifold covers of :mod:`millimpact.reduction.nmm_zone`.
"""

from __future__ import annotations

import logging
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
from dolfinx import fem
from dolfinx.cpp.la.petsc import create_vector as _create_ghosted_vector
from petsc4py import PETSc

from ..fem.model import FEModel
from ..geometry import builders as G
from .distributed import ownership_offsets

log = logging.getLogger(__name__)


#: the two bodies: name, (zone tag, region tag)
BODIES: tuple[tuple[str, tuple[int, int]], ...] = (
    ("ball", (G.BALL_ZONE, G.BALL_REGION)),
    ("block", (G.BLOCK_ZONE, G.BLOCK_REGION)),
)
ZONE_TAGS = (G.BALL_ZONE, G.BLOCK_ZONE)
REGION_TAGS = (G.BALL_REGION, G.BLOCK_REGION)


# --- dof sets ----------------------------------------------------------------------------------
def node_flags(V: fem.FunctionSpace, cells: np.ndarray) -> np.ndarray:
    """Boolean per local node of ``V`` (owned and ghost): does the node belong to one of ``cells``
    (local cell indices) on any rank? Collective; every rank agrees on shared nodes."""
    imap = V.dofmap.index_map
    x = _create_ghosted_vector(imap, 1)
    with x.localForm() as loc:
        loc.set(0.0)
        if len(cells):
            nodes = np.unique(V.dofmap.list.array.reshape(-1, V.dofmap.dof_layout.num_dofs)[cells])
            loc.array[nodes] = 1.0
    x.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
    x.ghostUpdate(addv=PETSc.InsertMode.INSERT, mode=PETSc.ScatterMode.FORWARD)
    with x.localForm() as loc:
        flags = loc.array > 0.5
    x.destroy()
    return flags


def tagged_cells(model: FEModel, tags: Sequence[int]) -> np.ndarray:
    """Local cells (owned and ghost) carrying one of ``tags``."""
    ct = model.meshdata.cell_tags
    return np.sort(ct.indices[np.isin(ct.values, list(tags))]).astype(np.int32)


@dataclass(frozen=True)
class DofPartition:
    """The owned dofs of a model split for the reduction (local owned indices, sorted, int32).

    ``zone``: non-fixed dofs of zone nodes; ``interface``: the zone dofs on nodes that also belong
    to region cells; ``interior[body]``: non-fixed dofs of the body outside the zone;
    ``ball_node``: per local node (with ghosts), does it belong to the ball.
    """

    n_owned: int
    zone: np.ndarray
    interface: np.ndarray
    interior: dict[str, np.ndarray]
    zone_body: np.ndarray  #: per zone dof: 0 ball, 1 block
    ball_node: np.ndarray
    zone_node: np.ndarray
    region_node: np.ndarray


def partition_dofs(model: FEModel) -> DofPartition:
    """Split the owned dofs of ``model`` into zone, interface and per-body interior (collective)."""
    V = model.V
    bs = V.dofmap.index_map_bs
    n_nodes_owned = V.dofmap.index_map.size_local
    n_owned = n_nodes_owned * bs
    zone_node = node_flags(V, tagged_cells(model, ZONE_TAGS))
    region_node = node_flags(V, tagged_cells(model, REGION_TAGS))
    ball_node = node_flags(V, tagged_cells(model, (G.BALL_ZONE, G.BALL_REGION)))
    free = np.ones(n_owned, dtype=bool)
    free[model.fixed_dofs] = False
    dof_node = np.arange(n_owned) // bs
    zone = np.nonzero(free & zone_node[dof_node])[0].astype(np.int32)
    interface = np.nonzero(free & zone_node[dof_node] & region_node[dof_node])[0].astype(np.int32)
    inner = free & ~zone_node[dof_node]
    interior = {
        "ball": np.nonzero(inner & ball_node[dof_node])[0].astype(np.int32),
        "block": np.nonzero(inner & ~ball_node[dof_node])[0].astype(np.int32),
    }
    zone_body = np.where(ball_node[dof_node[zone]], 0, 1).astype(np.int8)
    return DofPartition(n_owned, zone, interface, interior, zone_body, ball_node, zone_node, region_node)


# --- zone bases --------------------------------------------------------------------------------
@dataclass
class ZoneBasis:
    """The zone's description ``u_zone = G q_z``.

    ``G`` is a PETSc AIJ matrix (n x n_q) with non-zero rows only at non-fixed zone dofs; its
    column layout is the ownership of the zone coordinates. ``body`` gives, per owned zone
    coordinate, 0 (ball) or 1 (block). ``kind`` names the description ("nodal" or "nmm") and
    ``info`` holds numbers worth reporting.
    """

    G: PETSc.Mat
    body: np.ndarray
    kind: str
    info: dict = field(default_factory=dict)

    @property
    def n_local(self) -> int:
        """Owned zone coordinates."""
        return self.G.getLocalSize()[1]

    @property
    def n_global(self) -> int:
        """All zone coordinates."""
        return self.G.getSize()[1]


def create_nodal_zone_basis(model: FEModel, partition: DofPartition | None = None) -> ZoneBasis:
    """The identity on the zone: every non-fixed zone dof is a reduced coordinate (traditional
    multivariable method, and ``modal-p2``)."""
    part = partition or partition_dofs(model)
    comm = model.comm
    n_q = len(part.zone)
    q0 = int(ownership_offsets(comm, n_q)[comm.rank])
    indptr = np.zeros(part.n_owned + 1, dtype=np.int32)
    indptr[part.zone + 1] = 1
    indptr = np.cumsum(indptr).astype(np.int32)
    cols = (q0 + np.arange(n_q)).astype(np.int32)
    Gm = PETSc.Mat().createAIJ(
        ((part.n_owned, PETSc.DETERMINE), (n_q, PETSc.DETERMINE)), csr=(indptr, cols, np.ones(n_q)), comm=comm
    )
    Gm.assemble()
    return ZoneBasis(Gm, part.zone_body.copy(), "nodal", {"zone_coordinates": comm.allreduce(n_q)})
