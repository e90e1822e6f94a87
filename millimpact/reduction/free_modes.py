"""Free-vibration modes of a reduced model, K_r phi = omega^2 M_r phi up to f_max (u = T Phi eta,
:class:`ModalProjection`), which the reduced methods propagate in closed form between impacts.
"""

from __future__ import annotations

import logging
import math
import time
from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np
import scipy.sparse as sp
from mpi4py import MPI
from petsc4py import PETSc
from slepc4py import SLEPc

from ..errors import InputError, SolverError
from ..fem.model import FEModel
from ..integration.solvers import create_factored_solver, petsc_options
from .distributed import aij_from_local_csr, gather_aij_dense, gather_rows
from .eigen import FIRST_NEV, default_solver_options, sorted_eigenpairs
from .reduced_model import ReducedModel

log = logging.getLogger(__name__)


# --- free-vibration modes of a reduced model -----------------------------------------------------
@dataclass
class ModalProjection:
    """The lowest free-vibration modes of a reduced model (no contact): u = T Phi eta.

    Between impacts the two bodies vibrate freely and independently, so the motion is a sum of
    the modes of ``(K_r, mass)`` per body (the ball's include its rigid motions at 0 Hz), with
    ``mass`` the integrator's mass matrix (M_r, or M_r redistributed: massless contact
    coordinates then follow quasi-statically), so that the closed form continues the semi-discrete
    system the integrator advanced. Keeping the modes up to ``f_max`` and propagating them in
    closed form replaces thousands of time steps (see :mod:`millimpact.methods.reduced`).
    ``Phi`` is dense (n_r x m, mass-orthonormal), ``omega2`` the eigenvalues (rad^2/s^2,
    replicated), ``body`` 0/1 per mode (replicated); ``M`` and ``K`` the projections of the
    consistent M_r and of K_r (AIJ, m x m), for the observers' energies.
    The interface mirrors :class:`ReducedModel` where the observers need it.
    """

    red: ReducedModel
    Phi: PETSc.Mat
    omega2: np.ndarray
    body: np.ndarray
    M: PETSc.Mat
    K: PETSc.Mat
    ball_coords: np.ndarray
    f_max: float
    mass: PETSc.Mat  #: the mass matrix of the eigenproblem (reduced coordinates)
    M_scheme: PETSc.Mat  #: Phi^T mass Phi (= I, AIJ m x m): the integrator's mass, modally
    timings: dict[str, float] = field(default_factory=dict)

    @property
    def model(self) -> FEModel:
        return self.red.model

    @property
    def comm(self) -> MPI.Comm:
        return self.red.comm

    @property
    def n_global(self) -> int:
        return len(self.omega2)

    def create_vector(self) -> PETSc.Vec:
        x = self.Phi.createVecRight()
        x.set(0.0)
        return x

    def project(self, q: PETSc.Vec) -> PETSc.Vec:
        """eta = Phi^T mass q: modal coordinates of a reduced state (exact for q in range(Phi))."""
        Mq = self.mass.createVecLeft()
        self.mass.mult(q, Mq)
        eta = self.create_vector()
        self.Phi.multTranspose(Mq, eta)
        Mq.destroy()
        return eta

    def lift(self, eta: PETSc.Vec) -> PETSc.Vec:
        """q = Phi eta."""
        q = self.red.create_vector()
        self.Phi.mult(eta, q)
        return q

    def expand(self, eta: PETSc.Vec) -> PETSc.Vec:
        """u = T Phi eta (a model vector, m)."""
        q = self.lift(eta)
        u = self.red.expand(q)
        q.destroy()
        return u

    def restrict(self, f: PETSc.Vec) -> PETSc.Vec:
        """Phi^T T^T f."""
        r = self.red.restrict(f)
        out = self.create_vector()
        self.Phi.multTranspose(r, out)
        r.destroy()
        return out

    def project_rows(self, A: PETSc.Mat) -> PETSc.Mat:
        """A T Phi (AIJ, k x m)."""
        AT = self.red.project_rows(A)
        D = AT.matMult(self.Phi)
        rows = gather_rows(D, self.comm)
        r0, r1 = AT.getOwnershipRange()
        out = aij_from_local_csr(sp.csr_matrix(rows[r0:r1]), (AT.getSizes()[0], self.Phi.getSizes()[1]), self.comm)
        D.destroy()
        return out

    def rows_dense(self, A: PETSc.Mat) -> np.ndarray:
        """A T Phi as a replicated numpy array (k x m): gap rows for closed-form predictions."""
        AT = self.red.project_rows(A)
        D = AT.matMult(self.Phi)
        out = gather_rows(D, self.comm)
        D.destroy()
        return out


class BodyModes(NamedTuple):
    """One body's free-vibration modes: ``local`` its rows among this rank's reduced coordinates,
    ``lam`` the eigenvalues omega^2 (rad^2/s^2, ascending, replicated) and ``vecs`` the
    mass-orthonormal eigenvectors (distributed over the body's rows)."""

    local: np.ndarray
    lam: np.ndarray
    vecs: list[PETSc.Vec]


class ModalMatrices(NamedTuple):
    """The modes ``Phi`` (dense, n_r x m) with their replicated eigenvalues ``omega2``
    (rad^2/s^2, >= 0) and ``body`` (0 ball, 1 block) per mode."""

    Phi: PETSc.Mat
    omega2: np.ndarray
    body: np.ndarray


def _shift_invert_round(
    Kb: PETSc.Mat,
    Mb: PETSc.Mat,
    ksp: PETSc.KSP,
    prefix: str,
    sigma: float,
    nev: int,
    start: list[PETSc.Vec],
    opts: dict[str, str],
) -> tuple[np.ndarray, list[PETSc.Vec]]:
    """One Krylov-Schur solve of ``Kb x = lambda Mb x`` for the ``nev`` eigenvalues nearest the
    shift ``sigma`` (rad^2/s^2) by shift-and-invert with the factored ``ksp`` of
    ``Kb - sigma Mb``, started from ``start`` (a previous round's vectors, or none). Returns the
    ascending eigenvalues and the vectors of the lowest ``nev`` (all when ``nev`` nearly fills the
    body, n_b - 1 or more). Raises :class:`SolverError` if fewer than ``nev`` converge."""
    comm = Kb.getComm().tompi4py()
    n_b = Kb.getSize()[0]
    eps = SLEPc.EPS().create(comm)
    eps.setOptionsPrefix(prefix)
    eps.setOperators(Kb, Mb)
    eps.setProblemType(SLEPc.EPS.ProblemType.GHEP)
    eps.setType(SLEPc.EPS.Type.KRYLOVSCHUR)
    eps.setTarget(sigma)
    eps.setWhichEigenpairs(SLEPc.EPS.Which.TARGET_MAGNITUDE)
    st = eps.getST()
    st.setType(SLEPc.ST.Type.SINVERT)
    st.setShift(sigma)
    st.setKSP(ksp)
    eps.setDimensions(nev, PETSc.DECIDE)
    if start:
        eps.setInitialSpace(start)
    with petsc_options({}, {k: v for k, v in opts.items() if k.startswith("eps_")}, prefix=prefix):
        eps.setFromOptions()
    eps.solve()
    nconv = eps.getConverged()
    if nconv < nev:
        raise SolverError(f"free-vibration modes ({prefix}): {nconv} of {nev} converged")
    # vectors for the lowest nev only (the next round's start, or those kept)
    lam, vecs = sorted_eigenpairs(eps, Kb, None if nev >= n_b - 1 else nev)
    st.destroy()  # the Python handle alone keeps it, and with it the factorization (see
    # integration.solvers.destroy_petsc_tree)
    return lam, vecs


def _body_modes(
    red: ReducedModel,
    mass: PETSc.Mat,
    body: int,
    local: np.ndarray,
    sigma: float,
    lam_max: float,
    opts: dict[str, str],
) -> BodyModes:
    """The modes of body ``body`` (0 ball, 1 block; rows ``local`` of this rank) with
    omega^2 <= ``lam_max`` (rad^2/s^2): rounds of :func:`_shift_invert_round` from
    :data:`FIRST_NEV` eigenpairs, doubling their number (each round started from the last one's
    vectors) until the highest found passes ``lam_max`` or the body has no more. Collective."""
    comm = red.comm
    q_lo = red.M.getOwnershipRange()[0]
    IS = PETSc.IS().createGeneral((q_lo + local).astype(np.int32), comm=comm)
    n_b = comm.allreduce(len(local))
    if n_b == 0:
        return BodyModes(local, np.zeros(0), [])
    Kb = red.K.createSubMatrix(IS, IS)
    Mb = mass.createSubMatrix(IS, IS)
    A = Kb.duplicate(copy=True)
    A.axpy(-sigma, Mb, PETSc.Mat.Structure.SUBSET_NONZERO_PATTERN)
    prefix = f"impact_reduction_free_{'ball' if body == 0 else 'block'}_"
    ksp = create_factored_solver(A, prefix, opts)
    nev = min(FIRST_NEV, n_b)
    prev: list[PETSc.Vec] = []
    while True:
        lam, vecs = _shift_invert_round(Kb, Mb, ksp, prefix, sigma, nev, prev, opts)
        if lam[nev - 1] > lam_max or nev >= n_b - 1:
            break
        prev = vecs[:nev]
        nev = min(2 * nev, n_b - 1)
    keep = int(np.searchsorted(lam, lam_max, side="right"))
    ksp.destroy()
    A.destroy()
    return BodyModes(local, lam[:keep], vecs[:keep])


def _assemble_modes(per_body: list[BodyModes], n_loc: int, n_global: int, comm: MPI.Comm) -> ModalMatrices:
    """The bodies' modes side by side in one dense ``Phi`` (n_r x m, the ball's first), each
    mode zero outside its body's rows; negative rounding of the rigid modes' omega^2 (about
    -1e-6 rad^2/s^2) clipped to 0."""
    m = sum(len(p.lam) for p in per_body)
    Phi = PETSc.Mat().createDense(((n_loc, n_global), (PETSc.DECIDE, m)), comm=comm)
    Phi.setUp()
    arr = Phi.getDenseArray()
    arr[:] = 0.0
    lam_all, body_all = [], []
    k = 0
    for b, (local, lam, vecs) in enumerate(per_body):
        for lam_k, v in zip(lam, vecs):
            arr[local, k] = v.getArray(readonly=True)
            lam_all.append(lam_k)
            body_all.append(b)
            k += 1
    Phi.assemble()
    omega2 = np.maximum(np.array(lam_all), 0.0)  # rigid modes: rounding may give -1e-6 rad^2/s^2
    return ModalMatrices(Phi, omega2, np.array(body_all, dtype=np.int8))


def _project_pairs(Phi: PETSc.Mat, mats: tuple[PETSc.Mat, ...], comm: MPI.Comm) -> list[PETSc.Mat]:
    """``Phi^T A Phi`` (AIJ m x m, symmetrized: (G + G^T) / 2) of each ``A`` in ``mats``."""
    m = Phi.getSize()[1]
    c0, c1 = Phi.getOwnershipRangeColumn()
    out = []
    for A in mats:
        AP = A.matMult(Phi)
        G = gather_rows(Phi.transposeMatMult(AP), comm)
        AP.destroy()
        G = 0.5 * (G + G.T)
        out.append(aij_from_local_csr(sp.csr_matrix(G[c0:c1]), ((c1 - c0, m), (c1 - c0, m)), comm))
    return out


def _log_modes(omega2: np.ndarray, body: np.ndarray, f_max: float, seconds: float) -> None:
    """One log line: the ball's (rigid: below 1 Hz) and the block's mode counts up to ``f_max`` (Hz)."""
    f = np.sqrt(omega2) / (2 * math.pi)
    log.info(
        "free-vibration modes up to %.4g kHz: %d ball (%d rigid), %d block, %.2f s",
        f_max / 1e3,
        int(np.count_nonzero(body == 0)),
        int(np.count_nonzero((body == 0) & (f < 1.0))),
        int(np.count_nonzero(body == 1)),
        seconds,
    )


def compute_free_modes(
    red: ReducedModel,
    f_max: float,
    mass: PETSc.Mat | None = None,
    solver_options: dict[str, str] | None = None,
    shift_hz: float = 100.0,
) -> ModalProjection:
    """The free-vibration modes of each body of ``red`` up to ``f_max`` (Hz) with the mass matrix
    ``mass`` (default M_r; semi-definite allowed: massless coordinates), as a
    :class:`ModalProjection`. Shift-and-invert at ``-(2 pi shift_hz)^2``: the free ball's rigid
    modes (0 Hz) make K_r singular, the negative shift keeps K_r - sigma M positive definite.
    Options prefix ``impact_reduction_free_<body>_``. Raises :class:`SolverError` if the modes are
    not mass-orthonormal to 1e-6. Collective."""
    mass = mass if mass is not None else red.M
    if not f_max > 0:
        raise InputError(f"free-vibration cutoff {f_max!r} Hz must be > 0")
    t0 = time.perf_counter()
    comm = red.comm
    opts = default_solver_options(comm.size)
    opts.update(solver_options or {})
    q_lo, q_hi = red.M.getOwnershipRange()
    n_loc = q_hi - q_lo
    is_ball = np.zeros(n_loc, dtype=bool)
    is_ball[red.ball_coords] = True
    sigma = -((2 * math.pi * shift_hz) ** 2)
    lam_max = (2 * math.pi * f_max) ** 2
    per_body = [
        _body_modes(red, mass, b, local, sigma, lam_max, opts)
        for b, local in ((0, np.nonzero(is_ball)[0]), (1, np.nonzero(~is_ball)[0]))
    ]
    Phi, omega2, body = _assemble_modes(per_body, n_loc, red.n_global, comm)
    m = len(omega2)
    M_m, K_m, mass_m = _project_pairs(Phi, (red.M, red.K, mass), comm)
    ortho = float(np.max(np.abs(gather_aij_dense(mass_m, comm) - np.eye(m)))) if m else 0.0
    if ortho > 1e-6:
        raise SolverError(f"free-vibration modes are not M-orthonormal (max |Phi^T M Phi - I| = {ortho:.3g})")
    c0, c1 = Phi.getOwnershipRangeColumn()
    ball = np.array([i - c0 for i in range(c0, c1) if body[i] == 0], dtype=np.int32)
    proj = ModalProjection(
        red, Phi, omega2, body, M_m, K_m, ball, f_max, mass, mass_m, {"free_modes": time.perf_counter() - t0}
    )
    if comm.rank == 0:
        _log_modes(omega2, body, f_max, proj.timings["free_modes"])
    return proj
