"""Zone-interface patterns: the interface reduction of a substructured body (foundations.md section 4).

With ``-impact_reduction_<body>_substructure_zone_degree d`` (d >= 1; :mod:`.substructures`) a
body's interior is no longer described by its n_b constraint modes Psi (one per zone coordinate on
the interface: 583 at the liner panel's 1.2M DOFs, where every dense n_i x n_b array is 5.2 GB)
but by its static responses X = -K_ii^-1 K_iz W to a few smooth interface motions W, with
coordinates of their own (characteristic constraint modes in spirit: Castanier, Tan and Pierre,
AIAA J. 39 (2001) 1182-1187; Krattiger et al., Mech. Syst. Signal Process. 114 (2019) 579-603).
This module builds W (:func:`zone_interface_patterns`), the couplings K_iz W and M_iz W that the
slabs take instead of C and D (:func:`zone_pattern_couplings`), and the interior rows the gauges
reach, where the slabs keep their Ritz basis for the output recovery (:func:`probe_interior_rows`;
the recovery itself: :func:`~.substructures.ritz_recovery`).
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from mpi4py import MPI
from petsc4py import PETSc

from ..fem.model import FEModel
from ..fem.probes import create_probe
from .distributed import (
    aij_from_local_csr,
    global_extent,
    local_columns_csr,
    orthonormal_columns,
    ownership_offsets,
    positions_in,
)
from .partition import BODIES, DofPartition


def zone_interface_patterns(coords: np.ndarray, comps: np.ndarray, degree: int, comm: MPI.Comm) -> np.ndarray:
    """Smooth displacement patterns of a body's zone interface: per displacement component the
    monomials of total degree <= ``degree`` in the interface nodes' coordinates (centred, scaled to
    the interface's extent), orthonormal over the owned interface dofs (``coords`` their nodes,
    ``comps`` their components; dependent combinations dropped: on a curved interface some
    polynomials coincide). Degree >= 1 holds the rigid motions (translations, and rotations
    omega x r, linear in r), so a free body keeps its rigid motion. Owned rows x patterns."""
    lo, hi = global_extent(coords, comm)
    s = (coords - 0.5 * (lo + hi)) / max(0.5 * float(np.max(hi - lo)), 1e-300)
    powers = [(a, b, c) for a in range(degree + 1) for b in range(degree + 1 - a) for c in range(degree + 1 - a - b)]
    mono = (
        np.column_stack([s[:, 0] ** a * s[:, 1] ** b * s[:, 2] ** c for a, b, c in powers])
        if len(s)
        else np.zeros((0, len(powers)))
    )
    B = np.zeros((len(coords), 3 * len(powers)))
    for comp in range(3):
        sel = comps == comp
        B[sel, comp * len(powers) : (comp + 1) * len(powers)] = mono[sel]
    return orthonormal_columns(B, comm)


def zone_pattern_couplings(
    model: FEModel, part: DofPartition, body: str, degree: int, K_ia: PETSc.Mat, M_ia: PETSc.Mat
) -> tuple[sp.csr_matrix, sp.csr_matrix]:
    """K_iz W and M_iz W (owned interior rows, CSR) for the body's zone-interface patterns W of
    ``degree`` (:func:`zone_interface_patterns`; K_ia, M_ia: the interior rows of
    K and M, all columns). W is sparse: non-zero on the body's interface dofs only."""
    comm = model.comm
    zone_dofs = part.zone[part.zone_body == [n for n, _ in BODIES].index(body)]
    iface = part.interface[np.isin(part.interface, zone_dofs)]
    xyz = model.V.tabulate_dof_coordinates()[iface // 3]
    W_loc = zone_interface_patterns(xyz, iface % 3, degree, comm)
    p = W_loc.shape[1]
    rows = sp.csr_matrix(
        (W_loc.ravel(), (np.repeat(iface, p), np.tile(np.arange(p), len(iface)))), shape=(part.n_owned, p)
    )
    W = aij_from_local_csr(rows, ((part.n_owned, PETSc.DETERMINE), (PETSc.DECIDE, p)), comm)
    out = []
    for A in (K_ia, M_ia):
        AW = A.matMult(W)
        out.append(local_columns_csr(AW, np.arange(p)))
        AW.destroy()
    W.destroy()
    return out[0], out[1]


def probe_interior_rows(model: FEModel, idx: np.ndarray, points: np.ndarray) -> np.ndarray:
    """The interior rows (global numbering of K_ii, whose owned rows are ``idx``) that the
    displacement and gradient rows of a probe at ``points`` (the gauges) reach: the dofs of the
    block cells holding them. Sorted, the same on every rank. Collective."""
    comm, V = model.comm, model.V
    probe = create_probe(V, np.reshape(np.asarray(points, dtype=float), (-1, 3)), model.block_cells)
    local = np.unique(np.concatenate([probe.P_val.indices, probe.P_grad.indices]).astype(np.int64))
    bs = V.dofmap.index_map_bs
    glob = V.dofmap.index_map.local_to_global((local // bs).astype(np.int32)).astype(np.int64) * bs + local % bs
    glob = np.unique(np.concatenate(comm.allgather(glob)))
    r0 = model.K.getOwnershipRange()[0]
    mine = glob[(glob >= r0) & (glob < r0 + model.K.getLocalSize()[0])] - r0
    pos, hit = positions_in(idx, mine)
    off = int(ownership_offsets(comm, len(idx))[comm.rank])
    return np.unique(np.concatenate(comm.allgather((off + pos[hit]).astype(np.int64))))
