"""Free-vibration modes of a reduced model, K_r phi = omega^2 M_r phi up to f_max (u = T Phi eta,
:class:`ModalProjection`), which the reduced methods propagate in closed form between impacts.
"""

from __future__ import annotations

import logging
import math
import time
from dataclasses import dataclass, field

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
    Options prefix ``impact_reduction_free_<body>_``. Collective."""
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
    per_body: list[tuple[np.ndarray, np.ndarray, list[PETSc.Vec]]] = []  # (local rows, lambda, modes)
    for b, local in ((0, np.nonzero(is_ball)[0]), (1, np.nonzero(~is_ball)[0])):
        IS = PETSc.IS().createGeneral((q_lo + local).astype(np.int32), comm=comm)
        n_b = comm.allreduce(len(local))
        if n_b == 0:
            per_body.append((local, np.zeros(0), []))
            continue
        Kb = red.K.createSubMatrix(IS, IS)
        Mb = mass.createSubMatrix(IS, IS)
        A = Kb.duplicate(copy=True)
        A.axpy(-sigma, Mb, PETSc.Mat.Structure.SUBSET_NONZERO_PATTERN)
        prefix = f"impact_reduction_free_{'ball' if b == 0 else 'block'}_"
        ksp = create_factored_solver(A, prefix, opts)
        nev = min(FIRST_NEV, n_b)
        prev: list[PETSc.Vec] = []
        while True:
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
            if prev:
                eps.setInitialSpace(prev)
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
            if lam[nev - 1] > lam_max or nev >= n_b - 1:
                break
            prev = vecs[:nev]
            nev = min(2 * nev, n_b - 1)
        keep = int(np.searchsorted(lam, lam_max, side="right"))
        per_body.append((local, lam[:keep], vecs[:keep]))
        ksp.destroy()
        A.destroy()
    m = sum(len(p[1]) for p in per_body)
    Phi = PETSc.Mat().createDense(((n_loc, red.n_global), (PETSc.DECIDE, m)), comm=comm)
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
    body = np.array(body_all, dtype=np.int8)
    c0, c1 = Phi.getOwnershipRangeColumn()
    mats = []
    for A in (red.M, red.K, mass):
        AP = A.matMult(Phi)
        G = gather_rows(Phi.transposeMatMult(AP), comm)
        AP.destroy()
        G = 0.5 * (G + G.T)
        mats.append(aij_from_local_csr(sp.csr_matrix(G[c0:c1]), ((c1 - c0, m), (c1 - c0, m)), comm))
    ortho = float(np.max(np.abs(gather_aij_dense(mats[2], comm) - np.eye(m)))) if m else 0.0
    if ortho > 1e-6:
        raise SolverError(f"free-vibration modes are not M-orthonormal (max |Phi^T M Phi - I| = {ortho:.3g})")
    ball = np.array([i - c0 for i in range(c0, c1) if body[i] == 0], dtype=np.int32)
    proj = ModalProjection(
        red, Phi, omega2, body, mats[0], mats[1], ball, f_max, mass, mats[2], {"free_modes": time.perf_counter() - t0}
    )
    if comm.rank == 0:
        f = np.sqrt(omega2) / (2 * math.pi)
        log.info(
            "free-vibration modes up to %.4g kHz: %d ball (%d rigid), %d block, %.2f s",
            f_max / 1e3,
            int(np.count_nonzero(body == 0)),
            int(np.count_nonzero((body == 0) & (f < 1.0))),
            int(np.count_nonzero(body == 1)),
            proj.timings["free_modes"],
        )
    return proj
