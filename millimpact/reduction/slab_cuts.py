"""Where the substructured reduction (:mod:`.substructures`) cuts a body, and the interface's traces.

1. Slabs: the interior's dofs are cut along the body's longest extent at quantiles of the dof
   count, each cut moved out of the bands of +-``margin`` around the zone-coupled dofs and the
   gauges (to the nearer edge of the merged band; cuts that then coincide are dropped).
2. Slabs across: the bands make the zone's slab wide, and the mesh is finest there (1.2M-DOF
   liner panel, 16 slabs asked: 244k dofs against ~55k for the others; its factorization and
   basis were one rank's memory peak and half its time). A slab of more than
   :data:`ACROSS_RATIO` x the mean is cut again across, along its own longest other extent, by
   the same rule (the bands of the zone and the gauges along that axis).
3. Interface: a dof that couples to a dof of a later piece (label) is on Gamma; the pieces'
   other dofs are then uncoupled from each other. Gamma's dofs are grouped in faces, a face being
   (its piece, the first later piece it couples to); a face between two pieces of one slab lies
   across the second axis, any other across the first.
4. Traces: per face and displacement component, tensor Legendre polynomials of the two in-face
   coordinates (degree ``density`` x extent / shear wavelength at f_cut in each), orthonormal over
   the face's dofs.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp
from mpi4py import MPI
from numpy.polynomial import legendre
from petsc4py import PETSc

from .distributed import global_extent, orthonormal_columns, ownership_offsets, reduce_array

#: histogram bins for the quantile cuts
QUANTILE_BINS = 4096
#: a slab of more than this many times the mean dofs a slab is cut again across
ACROSS_RATIO = 2.0


@dataclass(frozen=True)
class SlabCut:
    """The pieces of a body's interior: ``labels`` (per owned dof, its piece), the first cuts'
    ``axis`` and positions ``cuts`` (m), ``parent`` (per piece, the slab between the first cuts
    it lies in) and ``across`` (slab -> (axis, positions) of its second cuts)."""

    labels: np.ndarray
    axis: int
    cuts: np.ndarray
    parent: np.ndarray
    across: dict = field(default_factory=dict)

    @property
    def pieces(self) -> int:
        return len(self.parent)

    def normal(self, a: int, b: int) -> int:
        """The axis across the face between pieces a and b."""
        return self.across[int(self.parent[a])][0] if self.parent[a] == self.parent[b] else self.axis

    def stats(self) -> dict:
        return {
            "axis": "xyz"[self.axis],
            "cuts_m": [float(c) for c in self.cuts],
            **(
                {
                    "across": {
                        str(s): {"axis": "xyz"[a], "cuts_m": [float(c) for c in cuts]}
                        for s, (a, cuts) in self.across.items()
                    }
                }
                if self.across
                else {}
            ),
        }


def quantile_cuts(x: np.ndarray, pieces: int, bands: list[tuple[float, float]], comm: MPI.Comm) -> np.ndarray:
    """Positions cutting the (distributed) values ``x`` into ``pieces`` of equal count, each moved
    out of the merged ``bands`` to the nearer edge; cuts that coincide or sit at the ends dropped."""
    (lo,), (hi,) = global_extent(x[:, None], comm)
    if not lo < hi:
        return np.zeros(0)
    counts = reduce_array(np.histogram(x, bins=QUANTILE_BINS, range=(lo, hi))[0].astype(float), MPI.SUM, comm)
    edges = np.linspace(lo, hi, QUANTILE_BINS + 1)
    cum = np.cumsum(counts) / max(counts.sum(), 1)
    cuts = [float(edges[1 + np.searchsorted(cum, k / pieces)]) for k in range(1, pieces)]
    merged: list[list[float]] = []
    for b in sorted(bands):
        if merged and b[0] <= merged[-1][1]:
            merged[-1][1] = max(merged[-1][1], b[1])
        else:
            merged.append(list(b))
    for band in merged:
        cuts = [c if not band[0] < c < band[1] else (band[0] if c - band[0] < band[1] - c else band[1]) for c in cuts]
    h = (hi - lo) * 1e-3
    return np.asarray(sorted(c for c in set(round(c, 12) for c in cuts) if lo + h < c < hi - h))


def _bands(x_zone: np.ndarray, points: np.ndarray, margin: float, comm: MPI.Comm) -> list[tuple[float, float]]:
    """+-``margin`` around the zone-coupled values ``x_zone`` (distributed) and each of ``points``."""
    (z_lo,), (z_hi,) = global_extent(x_zone[:, None], comm)
    return ([(z_lo - margin, z_hi + margin)] if z_lo <= z_hi else []) + [(p - margin, p + margin) for p in points]


def cut_slabs(
    coords: np.ndarray,
    zone_rows: np.ndarray,
    slabs: int,
    margin: float,
    comm: MPI.Comm,
    keep_away: np.ndarray | None = None,
    across_ratio: float = ACROSS_RATIO,
) -> SlabCut:
    """The pieces of a body's interior (module docstring, steps 1 and 2): ``coords`` the owned
    dofs' node coordinates, ``zone_rows`` the dofs coupled to the zone, ``keep_away`` (k x 3) the
    gauges; a slab over ``across_ratio`` x the mean count is cut again (0: never). Collective."""
    lo, hi = global_extent(coords, comm)
    axis = int(np.argmax(hi - lo))
    away = np.reshape(keep_away if keep_away is not None else np.zeros((0, 3)), (-1, 3))
    cuts = quantile_cuts(coords[:, axis], slabs, _bands(coords[zone_rows, axis], away[:, axis], margin, comm), comm)
    slab = np.searchsorted(cuts, coords[:, axis]).astype(np.int32)
    counts = reduce_array(np.bincount(slab, minlength=len(cuts) + 1).astype(float), MPI.SUM, comm)
    target = counts.sum() / max(slabs, 1)
    across: dict = {}
    labels = np.zeros(len(slab), dtype=np.int32)
    parent: list[int] = []
    in_zone = np.zeros(len(slab), dtype=bool)
    in_zone[zone_rows] = True
    for s in range(len(counts)):
        mine = slab == s
        pieces = max(2, int(round(counts[s] / target))) if across_ratio and counts[s] > across_ratio * target else 1
        sub = np.zeros(0)
        if pieces > 1:
            s_lo, s_hi = global_extent(coords[mine], comm)
            ext = (s_hi - s_lo).copy()
            ext[axis] = -1.0
            a2 = int(np.argmax(ext))
            near = away[(away[:, axis] > s_lo[axis] - margin) & (away[:, axis] < s_hi[axis] + margin)]
            sub = quantile_cuts(
                coords[mine, a2], pieces, _bands(coords[mine & in_zone, a2], near[:, a2], margin, comm), comm
            )
            if len(sub):
                across[s] = (a2, sub)
        labels[mine] = len(parent) + (np.searchsorted(sub, coords[mine, across[s][0]]) if len(sub) else 0)
        parent += [s] * (len(sub) + 1)
    return SlabCut(labels, axis, cuts, np.asarray(parent, dtype=np.int32), across)


def interface_next(K_ii: PETSc.Mat, labels: np.ndarray) -> np.ndarray:
    """Per owned row of K_ii, the first later piece it couples to (-1: none). The rows with one
    form Gamma; the other rows of different pieces are then uncoupled."""
    comm = K_ii.getComm()
    lab = K_ii.createVecRight()
    lab.array[:] = labels
    indptr, indices, _ = K_ii.getValuesCSR()
    need = np.unique(indices).astype(np.int32)
    seq = PETSc.Vec().createSeq(len(need), comm=PETSc.COMM_SELF)
    sc = PETSc.Scatter().create(lab, PETSc.IS().createGeneral(need, comm=comm), seq, None)
    sc.scatter(lab, seq, addv=PETSc.InsertMode.INSERT, mode=PETSc.ScatterMode.FORWARD)
    col_label = seq.array[np.searchsorted(need, indices)]
    rows = np.repeat(np.arange(len(labels)), np.diff(indptr))
    later = col_label > labels[rows]
    first = np.full(len(labels), np.inf)
    np.minimum.at(first, rows[later], col_label[later])
    for obj in (sc, seq, lab):
        obj.destroy()
    return np.where(np.isfinite(first), first, -1).astype(np.int32)


def interface_faces(labels: np.ndarray, nxt: np.ndarray, comm: MPI.Comm) -> tuple[np.ndarray, list[tuple[int, int]]]:
    """Gamma's rows (``nxt`` >= 0) grouped in faces: per Gamma row its face index, and the faces'
    (piece, next piece) in order, numbered alike on every rank."""
    on = nxt >= 0
    pairs = np.unique(np.column_stack([labels[on], nxt[on]]), axis=0) if on.any() else np.zeros((0, 2), int)
    faces = sorted({(int(p[0]), int(p[1])) for part in comm.allgather(pairs.tolist()) for p in part})
    key = {f: k for k, f in enumerate(faces)}
    return np.array([key[(int(a), int(b))] for a, b in zip(labels[on], nxt[on])], dtype=np.int32), faces


def polynomial_traces(
    coords: np.ndarray,
    comps: np.ndarray,
    face: np.ndarray,
    normals: list[int],
    wavelength: float,
    density: float,
    comm: MPI.Comm,
) -> list[sp.csr_matrix]:
    """Per face, the trace basis on this rank's Gamma rows (``face``: each row's face index,
    ``normals`` each face's normal axis; sparse: zero off the face's rows): tensor Legendre
    polynomials of the two in-face coordinates per displacement component, orthonormal over the
    face's rows (dependent combinations dropped). ``density`` 0: the identity."""
    blocks = []
    for c, normal in enumerate(normals):
        mine = face == c
        rows = np.nonzero(mine)[0]
        if density == 0:
            n_c = comm.allreduce(int(mine.sum()))
            off = int(ownership_offsets(comm, int(mine.sum()))[comm.rank])
            blocks.append(
                sp.csr_matrix((np.ones(len(rows)), (rows, off + np.arange(len(rows)))), shape=(len(face), n_c))
            )
            continue
        p = coords[mine][:, [a for a in range(3) if a != normal]]
        lo, hi = global_extent(p, comm)
        ext = np.maximum(hi - lo, 1e-300)
        deg = [max(1, int(math.ceil(density * e / wavelength))) for e in ext]
        s = 2.0 * (p - lo) / ext - 1.0
        Pa, Pb = legendre.legvander(s[:, 0], deg[0]), legendre.legvander(s[:, 1], deg[1])
        poly = (Pa[:, :, None] * Pb[:, None, :]).reshape(len(p), (deg[0] + 1) * (deg[1] + 1))
        B = np.zeros((len(rows), 3 * poly.shape[1]))
        for comp in range(3):
            sel = comps[mine] == comp
            B[sel, comp * poly.shape[1] : (comp + 1) * poly.shape[1]] = poly[sel]
        blocks.append(_place_rows(sp.csr_matrix(orthonormal_columns(B, comm)), rows, len(face)))
    return blocks


def _place_rows(A: sp.csr_matrix, rows: np.ndarray, n: int) -> sp.csr_matrix:
    """A's rows put at ``rows`` of an n-row sparse matrix (zeros elsewhere)."""
    coo = A.tocoo()
    return sp.csr_matrix((coo.data, (rows[coo.row], coo.col)), shape=(n, A.shape[1]))
