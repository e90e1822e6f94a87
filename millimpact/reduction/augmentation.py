"""Modal truncation augmentation (Dickens, Nakagawa & Wittbrodt 1997): per body and zone-motion pattern one
more interior vector, the static response of the interior to the inertia of that motion, orthogonalised against
the kept modes; off by default (see :mod:`millimpact.reduction.craig_bampton` for the measured effect).
"""

from __future__ import annotations

import logging
import math
from collections.abc import Sequence

import numpy as np
from petsc4py import PETSc

from ..fem.model import FEModel
from .distributed import check_converged
from .eigen import frequencies_hz, small_ghep
from .partition import DofPartition

log = logging.getLogger(__name__)


# --- modal truncation augmentation ---------------------------------------------------------------
#: representative zone motions of an impact for the augmentation (see interface_motion_pattern)
AUGMENTATION_PATTERNS = ("boussinesq", "translation")


def interface_motion_pattern(model: FEModel, part: DofPartition, body: str, kind: str) -> PETSc.Vec:
    """A representative motion of one body's contact zone during an impact, as a model vector
    (zero outside the body's zone; the scale is irrelevant). The ball: its rigid translation along
    the contact normal (it decelerates as a whole). The block: ``kind = "boussinesq"``, the
    half-space's static displacement under a normal point load at the impact point (Boussinesq;
    Johnson, Contact Mechanics (1985), section 3.2), or ``"translation"``, a translation along the normal."""
    V = model.V
    bs = V.dofmap.index_map_bs
    inward = -np.asarray(model.contact_normal, dtype=float)  # into the block
    u = model.K.createVecRight()
    u.set(0.0)
    zone = part.zone[part.zone_body == (0 if body == "ball" else 1)]
    if len(zone) == 0:
        return u
    node, comp = zone // bs, zone % bs
    if body == "ball" or kind == "translation":
        u.array[zone] = inward[comp]
        return u
    X = V.tabulate_dof_coordinates()[node, :3] - np.asarray(model.impact_point, dtype=float)
    nu = model.target_material.poisson
    z = np.maximum(X @ inward, 0.0)  # depth below the struck face
    lateral = X - np.outer(X @ inward, inward)
    rho = np.linalg.norm(lateral, axis=1)
    R = np.maximum(np.hypot(rho, z), 1e-12)
    u_z = (2.0 * (1.0 - nu) + z**2 / R**2) / R
    u_r = (rho * z / R**2 - (1.0 - 2.0 * nu) * rho / (R + z)) / R
    e_r = lateral / np.maximum(rho, 1e-300)[:, None]
    field_ = u_z[:, None] * inward[None, :] + u_r[:, None] * e_r
    u.array[zone] = field_[np.arange(len(zone)), comp]
    return u


def compute_augmentation_load(
    K: PETSc.Mat,
    M: PETSc.Mat,
    I: PETSc.IS,
    all_cols: PETSc.IS,
    K_ii: PETSc.Mat,
    M_ii: PETSc.Mat,
    ksp: PETSc.KSP,
    u_w: PETSc.Vec,
) -> PETSc.Vec:
    """The interior's static response to the inertia of a zone motion ``u_w`` (model vector, m):
    with the interior following statically, u_i = -K_ii^-1 K_iz u_w, the shape's inertia load on
    the interior is f_i = M_ii u_i + M_iz u_w, and its static response x = K_ii^-1 f_i (two
    solves with the factored ``ksp``; call it before the eigensolver, which takes the KSP over)."""
    K_iz = K.createSubMatrix(I, all_cols)
    M_iz = M.createSubMatrix(I, all_cols)
    rhs = K_ii.createVecLeft()
    K_iz.mult(u_w, rhs)
    u_i = K_ii.createVecRight()
    ksp.solve(rhs, u_i)
    check_converged(ksp, "augmentation: static extension of the zone motion")
    u_i.scale(-1.0)
    f = K_ii.createVecLeft()
    M_ii.mult(u_i, f)
    M_iz.multAdd(u_w, f, f)
    x = K_ii.createVecRight()
    ksp.solve(f, x)
    check_converged(ksp, "augmentation: static response to the inertia load")
    for obj in (K_iz, M_iz, rhs, u_i, f):
        obj.destroy()
    return x


def compute_augmentation_vectors(
    K_ii: PETSc.Mat, M_ii: PETSc.Mat, xs: Sequence[PETSc.Vec], vecs: Sequence[PETSc.Vec], rtol: float = 1e-8
) -> tuple[np.ndarray, list[PETSc.Vec]]:
    """Modal truncation augmentation (Dickens, Nakagawa & Wittbrodt, Comput. Struct. 62 (1997)):
    the static responses ``xs`` made M_ii-orthonormal to the kept fixed-interface modes ``vecs``
    and to each other (classical Gram-Schmidt, twice), then diagonalised by Rayleigh-Ritz on
    (K_ii, M_ii), so that they stay K_ii-orthogonal to the modes. A response whose part outside
    the kept space is below ``rtol`` of its M_ii-norm is dropped (e.g. every mode kept).
    Returns (Ritz frequencies in Hz, ascending; the vectors). Collective."""
    basis = list(vecs)
    Mbasis = []
    for v in basis:
        w = M_ii.createVecLeft()
        M_ii.mult(v, w)
        Mbasis.append(w)
    out: list[PETSc.Vec] = []
    for x in xs:
        Mx = M_ii.createVecLeft()
        M_ii.mult(x, Mx)
        ref = x.dot(Mx)
        Mx.destroy()
        y = x.copy()
        for _ in range(2):
            for v, w in zip(basis, Mbasis):
                y.axpy(-y.dot(w), v)
        My = M_ii.createVecLeft()
        M_ii.mult(y, My)
        norm2 = y.dot(My)
        if not norm2 > rtol**2 * ref:
            y.destroy()
            My.destroy()
            continue
        y.scale(1.0 / math.sqrt(norm2))
        My.scale(1.0 / math.sqrt(norm2))
        basis.append(y)
        Mbasis.append(My)
        out.append(y)
    k = len(out)
    if k == 0:
        for w in Mbasis:
            w.destroy()
        return np.zeros(0), []
    Mout = Mbasis[len(vecs) :]
    A = np.zeros((k, k))
    B = np.zeros((k, k))
    Ky = K_ii.createVecLeft()
    for j, y in enumerate(out):
        K_ii.mult(y, Ky)
        for i, z in enumerate(out):
            A[i, j] = z.dot(Ky)
            B[i, j] = z.dot(Mout[j])
    Ky.destroy()
    # the k x k Rayleigh-Ritz problem, replicated (the same numbers on every rank)
    lam, Q = small_ghep(0.5 * (A + A.T), 0.5 * (B + B.T))
    result = []
    for j in range(k):
        v = out[0].duplicate()
        v.set(0.0)
        for i in range(k):
            v.axpy(Q[i, j], out[i])
        result.append(v)
    for w in Mbasis:
        w.destroy()
    for y in out:
        y.destroy()
    return frequencies_hz(lam), result
