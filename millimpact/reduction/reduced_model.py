"""The reduced model u = T q: its matrices M_r, K_r, the transform T, the coordinate sets, the bodies'
reductions, initial-state projection and output recovery by mode acceleration (see
:mod:`millimpact.reduction.craig_bampton` for the equations).
"""

from __future__ import annotations

import hashlib
import logging
import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import scipy.sparse as sp
from mpi4py import MPI
from petsc4py import PETSc

from ..fem.model import FEModel
from ..integration.solvers import (
    create_factored_solver,
    effective_solver_defaults,
    mark_symmetric,
    solve_checked,
    solve_or_factorize,
)
from .distributed import aij_from_local_csr, dense_columns, gather_rows, positions_in
from .partition import DofPartition, ZoneBasis

log = logging.getLogger(__name__)

#: how a reduced mass matrix M_r is solved (PETSc options): a Cholesky factorization. The
#: Craig-Bampton couplings and the NMM zone make M_r a poor fit for Jacobi-CG: 0.24 s CPU to
#: factorize at the default scene's 10k improved coordinates against 2.0 s and ~3000 iterations
#: of CG to rounding; on paper-rig-plastic's repeated-impact model (14,833 coordinates) the
#: initial-acceleration solve took 11 s of CG against 0.04 s a solve with the factorization
MASS_FACTORIZATION = {"ksp_type": "preonly", "pc_type": "cholesky", "pc_factor_mat_solver_type": "mumps"}


# --- the reduced model ---------------------------------------------------------------------------
@dataclass
class BodyReduction:
    """Craig-Bampton data of one body's interior (PETSc objects distributed like the model).

    ``I``: IS of the interior dofs (global model indices); ``Psi`` dense (n_i x n_b) constraint
    modes for the reduced coordinates ``qb`` (global reduced indices, replicated); ``Phi`` dense
    (n_i x m) fixed-interface modes, M_ii-orthonormal, for the reduced coordinates ``modes``
    (global reduced indices, replicated); ``frequencies_hz`` the modes' natural frequencies.
    """

    name: str
    n_interior: int
    I: PETSc.IS
    Psi: PETSc.Mat | None
    qb: np.ndarray
    Phi: PETSc.Mat | None
    modes: np.ndarray
    frequencies_hz: np.ndarray
    f_cut: float | None
    next_frequency_hz: float  #: lowest fixed-interface frequency not kept (nan if unknown)
    timings: dict[str, float] = field(default_factory=dict)
    #: the last ``n_augmented`` columns of Phi are augmentation vectors (their Ritz frequencies)
    n_augmented: int = 0
    #: substructured with zone-interface patterns (:mod:`.substructures`): Psi is None and the last
    #: ``n_patterns`` columns of Phi are the patterns' static responses (their Ritz frequencies)
    n_patterns: int = 0
    #: kept for the mode-acceleration output rows (:meth:`ReducedModel.mode_acceleration_rows`)
    #: until :meth:`ReducedModel.release_recovery`: the factored K_ii and the mass coupling M_ib
    #: (sparse n_i x n_b) of A_b = M_ii Psi + M_ib, through which the zone's acceleration loads the
    #: interior (A_b is applied, never stored: a dense n_i x n_b matrix)
    ksp: PETSc.KSP | None = None
    M_ib: PETSc.Mat | None = None
    K_ii: PETSc.Mat | None = None
    #: factors K_ii when ``ksp`` is None (Psi and Phi came from the on-disk cache: reduction.cache)
    factor: Callable[[], PETSc.KSP] | None = None
    from_cache: bool = False
    #: the slab-wise reduction's statistics (:mod:`.substructures`), None for one factorization
    substructures: dict | None = None
    #: substructured bodies: R A_b (dense n_i x n_b), the residual flexibility's response to the
    #: interface inertia from the Ritz space, for the mode-acceleration rows without K_ii's factor
    residual_b: PETSc.Mat | None = None
    #: substructured with zone-interface patterns: the Ritz-space recovery of output rows
    #: (:func:`~.substructures.ritz_recovery`: kept rows, V there, H_C, H_D, H_M), None otherwise
    ritz_recovery: dict | None = None

    @property
    def n_modes(self) -> int:
        """Columns of Phi: fixed-interface modes and augmentation vectors."""
        return len(self.frequencies_hz)

    def report(self) -> dict[str, Any]:
        """JSON-able summary."""
        f = self.frequencies_hz[: len(self.frequencies_hz) - self.n_augmented - self.n_patterns]
        return {
            "interior_dofs": self.n_interior,
            "interface_coordinates": int(len(self.qb)),
            "modes": int(len(f)),
            "augmentation_vectors": self.n_augmented,
            "augmentation_frequencies_Hz": [float(x) for x in self.frequencies_hz[len(f) : len(f) + self.n_augmented]],
            "interface_pattern_vectors": self.n_patterns,
            "f_cut_Hz": self.f_cut,
            "lowest_frequency_Hz": float(f[0]) if len(f) else None,
            "highest_frequency_Hz": float(f[-1]) if len(f) else None,
            "next_frequency_Hz": self.next_frequency_hz,
            "from_cache": self.from_cache,
            **({"substructures": self.substructures} if self.substructures else {}),
            "timings_s": dict(self.timings),
        }


@dataclass
class ReducedModel:
    """A Galerkin projection u = T q of an :class:`FEModel` (see the module docstring).

    ``M``, ``K``: reduced mass and stiffness (PETSc AIJ, n_r x n_r, SI units: kg, N/m for the
    physical coordinates); ``Gr``: the zone part of T (AIJ, n x n_r); ``bodies``: the interior
    reductions; ``ball_coords``: owned local reduced indices that belong to the ball.
    """

    model: FEModel
    zone: ZoneBasis
    partition: DofPartition
    M: PETSc.Mat
    K: PETSc.Mat
    Gr: PETSc.Mat
    bodies: list[BodyReduction]
    ball_coords: np.ndarray
    n_zone: int
    timings: dict[str, float] = field(default_factory=dict)
    _mass_ksp: PETSc.KSP | None = None
    _static: dict = field(default_factory=dict)  #: (K_r + s M_r, its factored KSP) by (s, prefix)
    _scatters: dict = field(default_factory=dict)
    _recovery_rows: dict = field(default_factory=dict)  #: mode_acceleration_rows by the rows' CSR hash

    # sizes ------------------------------------------------------------------------------------
    @property
    def comm(self) -> MPI.Comm:
        return self.model.comm

    @property
    def n_global(self) -> int:
        """Number of reduced coordinates."""
        return self.M.getSize()[0]

    @property
    def n_modes(self) -> int:
        return sum(b.n_modes for b in self.bodies)

    def create_vector(self) -> PETSc.Vec:
        """A zero reduced vector."""
        q = self.M.createVecRight()
        q.set(0.0)
        return q

    # maps -------------------------------------------------------------------------------------
    def _scatter(
        self, body: BodyReduction, which: str, mat: PETSc.Mat, q: PETSc.Vec
    ) -> tuple[PETSc.Scatter, PETSc.Vec]:
        """Scatter from reduced vectors to the column layout of ``mat``, the ``Psi`` / ``Phi`` of a body."""
        key = (body.name, which)
        if key not in self._scatters:
            idx = body.qb if which == "psi" else body.modes
            x = mat.createVecRight()
            c0, c1 = x.getOwnershipRange()
            is_from = PETSc.IS().createGeneral(idx[c0:c1].astype(np.int32), comm=self.comm)
            self._scatters[key] = (PETSc.Scatter().create(q, is_from, x, None), x)
        return self._scatters[key]

    def expand(self, q: PETSc.Vec, u: PETSc.Vec | None = None) -> PETSc.Vec:
        """u = T q (a model vector, m)."""
        if u is None:
            u = self.model.K.createVecRight()
        self.Gr.mult(q, u)
        for b in self.bodies:
            if b.n_interior == 0:
                continue
            y = None
            for which, mat in (("psi", b.Psi), ("phi", b.Phi)):
                if mat is None:
                    continue
                sc, x = self._scatter(b, which, mat, q)
                sc.scatter(q, x, addv=PETSc.InsertMode.INSERT, mode=PETSc.ScatterMode.FORWARD)
                if y is None:
                    y = mat.createVecLeft()
                    mat.mult(x, y)
                else:
                    mat.multAdd(x, y, y)
            if y is not None:
                u.isaxpy(b.I, 1.0, y)
                y.destroy()
        return u

    def restrict(self, f: PETSc.Vec, r: PETSc.Vec | None = None) -> PETSc.Vec:
        """r = T^T f (a reduced vector; generalized forces in N for physical coordinates)."""
        if r is None:
            r = self.create_vector()
        self.Gr.multTranspose(f, r)
        for b in self.bodies:
            if b.n_interior == 0:
                continue
            fi = f.getSubVector(b.I)
            for which, mat in (("psi", b.Psi), ("phi", b.Phi)):
                if mat is None:
                    continue
                sc, x = self._scatter(b, which, mat, r)
                mat.multTranspose(fi, x)
                sc.scatter(x, r, addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
            f.restoreSubVector(b.I, fi)
        return r

    def project_state(self, u: PETSc.Vec) -> PETSc.Vec:
        """The reduced coordinates of the M-orthogonal projection of ``u`` on range(T):
        q = M_r^-1 T^T M u (exact, q with T q = u, whenever u lies in range(T), e.g. a rigid
        motion of the free ball)."""
        Mu = self.model.M.createVecLeft()
        self.model.M.mult(u, Mu)
        rhs = self.restrict(Mu)
        if self._mass_ksp is None:
            # exact, so a rigid motion stays exact (1e-12)
            self._mass_ksp = create_factored_solver(self.M, "impact_reduction_mass_", dict(MASS_FACTORIZATION))
        q = self.create_vector()
        # a user's iterative choice (-impact_reduction_mass_ksp_type cg) that stalls falls back
        # to a factorization
        self._mass_ksp = solve_or_factorize(
            self._mass_ksp,
            self.M,
            rhs,
            q,
            "projection of the initial state on the reduced basis",
            "impact_reduction_mass_direct_",
        )
        log.debug("mass projection: %d CG iterations", self._mass_ksp.getIterationNumber())
        return q

    def project_rows(self, A: PETSc.Mat) -> PETSc.Mat:
        """A T for a row operator A (k x n, AIJ: contact rows, probes) as an AIJ matrix k x n_r."""
        AG = A.matMult(self.Gr)
        extra = []
        for b in self.bodies:
            if b.n_interior == 0:
                continue
            cols = PETSc.IS().createGeneral(b.I.getIndices(), comm=self.comm)
            rows = PETSc.IS().createStride(A.getLocalSize()[0], A.getOwnershipRange()[0], 1, comm=self.comm)
            AI = A.createSubMatrix(rows, cols)
            if AI.norm(PETSc.NormType.FROBENIUS) == 0.0:
                continue
            for mat, idx in ((b.Psi, b.qb), (b.Phi, b.modes)):
                if mat is None:
                    continue
                dense = AI.matMult(mat)
                extra.append((gather_rows(dense, self.comm), idx))
        if not extra:
            return AG
        # add the dense parts: rebuild the local rows as CSR
        r0, r1 = AG.getOwnershipRange()
        indptr, indices, data = AG.getValuesCSR()
        n_rows, n_cols = r1 - r0, self.n_global
        S = sp.csr_matrix((data, indices, indptr), shape=(n_rows, n_cols))
        for dense, idx in extra:
            loc = dense[r0:r1]
            S = S + sp.csr_matrix(
                (loc.ravel(), (np.repeat(np.arange(n_rows), len(idx)), np.tile(idx, n_rows))), shape=(n_rows, n_cols)
            )
        return aij_from_local_csr(S.tocsr(), AG.getSizes(), self.comm)

    def mode_acceleration_rows(self, A: PETSc.Mat) -> np.ndarray:
        """Output rows by the mode-acceleration method: a replicated dense C (k x n_r) such that
        ``A u ~ (A T) q + C q''`` for a row operator A (k x n, AIJ: probes, gauges).

        In each body's interior (no external load) the exact motion obeys
        ``u_i = Psi u_b - K_ii^-1 (M_ii u_i'' + M_ib u_b'')``. With the reduced accelerations on the
        right and the modal equations of the reduced model, this is
        ``u_i = Psi q_b + Phi eta - R A_b q_b''``, ``R = K_ii^-1 - Phi Omega^-2 Phi^T`` the residual
        flexibility of the modes not kept and ``A_b = M_ii Psi + M_ib``: the truncated modes'
        quasi-static response to the interior's inertia. Stresses near the zone converge much
        faster with the cutoff this way (mode shapes' gauge stresses: 14 % -> 0.4 % at 4/t_c on
        the test mesh); the dynamics are unchanged. Zero rows where A does not reach an interior.
        Needs the factorizations kept by :func:`reduce_model` (:meth:`release_recovery` frees
        them); bodies with augmentation vectors are skipped (Phi holds non-eigenvectors there)."""
        return self._recovery(A)[1].copy()

    def displacement_recovery_rows(self, A: PETSc.Mat) -> np.ndarray | None:
        """The displacement part of the recovery, for bodies reduced with zone-interface patterns
        (:func:`~.substructures.ritz_recovery`): a replicated dense D (k x n_r) such that
        ``A u ~ (A T + D) q + C q''`` (C: :meth:`mode_acceleration_rows`); None when no such body
        is reached (Craig-Bampton's constraint modes already hold the interior's static response)."""
        D = self._recovery(A)[0]
        return None if D is None else D.copy()

    def _recovery(self, A: PETSc.Mat) -> tuple[np.ndarray | None, np.ndarray]:
        """(D, C) of :meth:`displacement_recovery_rows` and :meth:`mode_acceleration_rows`."""
        # the same rows again (the impacts of a contact table share the probes): D, C from the first
        # time, not a fresh factorization of K_ii and solve (0.5-1 s a case on the rig)
        indptr, indices, values = A.getValuesCSR()
        key = hashlib.sha1(
            b"".join(np.ascontiguousarray(x).tobytes() for x in (indptr, indices, values)) + repr(A.getSize()).encode()
        ).hexdigest()
        if self.comm.allreduce(key in self._recovery_rows, op=MPI.LAND):
            return self._recovery_rows[key]
        k = A.getSize()[0]
        C = np.zeros((k, self.n_global))
        D = None
        r0, r1 = A.getOwnershipRange()
        for b in self.bodies:
            if b.ritz_recovery is not None:
                rec = b.ritz_recovery
                cols = PETSc.IS().createGeneral(b.I.getIndices(), comm=self.comm)
                rows = PETSc.IS().createStride(r1 - r0, r0, 1, comm=self.comm)
                AI = A.createSubMatrix(rows, cols)
                ip, ix, vals = AI.getValuesCSR()
                pos, inside = positions_in(rec["rows"], ix)
                if self.comm.allreduce(int(np.count_nonzero(~inside)), op=MPI.SUM):
                    if self.comm.rank == 0:
                        log.warning("%s: output rows outside the kept Ritz rows: recovered as u = T q there", b.name)
                    AI.destroy()
                    continue
                if self.comm.allreduce(len(ix), op=MPI.SUM):
                    S = sp.csr_matrix((vals, pos, ip), shape=(r1 - r0, len(rec["rows"])))
                    AV = np.vstack(self.comm.allgather(np.asarray(S @ rec["V"])))  # k x n_cols
                    D = np.zeros((k, self.n_global)) if D is None else D
                    D[:, b.qb] += AV @ rec["H_C"]
                    D[:, b.modes] -= gather_rows(AI.matMult(b.Phi), self.comm)  # u_i replaced, not added
                    C[:, b.qb] += AV @ rec["H_D"]
                    C[:, b.modes] += AV @ rec["H_M"]
                AI.destroy()
                continue
            if b.residual_b is not None and not b.n_augmented:
                # substructured: C[:, qb] -= A_i R A_b with R A_b from the reduction's Ritz space
                cols = PETSc.IS().createGeneral(b.I.getIndices(), comm=self.comm)
                rows = PETSc.IS().createStride(r1 - r0, r0, 1, comm=self.comm)
                AI = A.createSubMatrix(rows, cols)
                if AI.norm(PETSc.NormType.FROBENIUS) > 0.0:
                    G = AI.matMult(b.residual_b)
                    C[:, b.qb] -= gather_rows(G, self.comm)
                    G.destroy()
                AI.destroy()
                continue
            if b.ksp is None and b.factor is not None and b.M_ib is not None and b.n_interior and not b.n_augmented:
                b.ksp = b.factor()  # Psi and Phi came from the cache: factor K_ii now, once
            if b.n_interior == 0 or b.ksp is None or b.M_ib is None or b.n_augmented:
                continue
            # M_ib is kept with the constraint modes only (craig_bampton._body_blocks)
            assert b.Psi is not None, f"{b.name}: the mass coupling M_ib without constraint modes Psi"
            cols = PETSc.IS().createGeneral(b.I.getIndices(), comm=self.comm)
            rows = PETSc.IS().createStride(r1 - r0, r0, 1, comm=self.comm)
            AI = A.createSubMatrix(rows, cols)  # k x n_i
            if AI.norm(PETSc.NormType.FROBENIUS) == 0.0:
                continue
            AIt = AI.transpose()  # n_i x k
            rhs = dense_columns(AIt, np.arange(k), self.comm)
            Y = rhs.duplicate()
            # the eigensolver's reset dropped the factor (shift-and-invert shares this KSP): set up
            # again (a no-op when the factor is current)
            b.ksp.setOperators(b.K_ii)
            b.ksp.setUp()
            b.ksp.getPC().getFactorMatrix().matSolve(rhs, Y)  # K_ii^-1 A_i^T
            if b.Phi is not None:
                Z = gather_rows(b.Phi.transposeMatMult(rhs), self.comm)  # m x k
                w2 = (2 * math.pi * np.asarray(b.frequencies_hz)) ** 2
                y = Y.getDenseArray()
                y -= b.Phi.getDenseArray() @ (Z / w2[:, None])
                Y.assemble()
            # G = A_b^T Y = Psi^T (M_ii Y) + M_ib^T Y                               (n_b x k)
            M_ii = self.model.M.createSubMatrix(b.I, b.I)
            MY = M_ii.matMult(Y)
            G = gather_rows(b.Psi.transposeMatMult(MY), self.comm) + gather_rows(b.M_ib.transposeMatMult(Y), self.comm)
            C[:, b.qb] -= G.T
            for m in (AI, AIt, rhs, Y, M_ii, MY):
                m.destroy()
        self._recovery_rows[key] = (D, C)
        return D, C

    def static_solve(self, rhs: PETSc.Vec, shift: float, prefix: str, what: str) -> PETSc.Vec:
        """q with ``(K_r + s M_r) q = rhs``, s = ``shift`` (1/s^2; the mass term holds the free
        ball's rigid motions), e.g. the residual state of a frozen plastic strain. Factorized once per shift and
        options ``prefix`` (Cholesky: CHOLMOD in serial, MUMPS under MPI) and kept with the model:
        a contact table's cases, a repeated-impact sequence's impacts and a run's dent share it
        (paper-rig's 11,433 coordinates: ~0.4 s a factorization with the matrix sum; 1.2 s on the
        sequence's 14,833). Freed with the model
        (:func:`~millimpact.integration.solvers.destroy_petsc_tree`); ``what`` names the solve in a
        failure."""
        key = (shift, prefix)
        if key not in self._static:
            A = self.K.copy()
            A.axpy(shift, self.M, structure=PETSc.Mat.Structure.DIFFERENT_NONZERO_PATTERN)
            mark_symmetric(A)
            self._static[key] = (A, create_factored_solver(A, prefix, effective_solver_defaults(self.comm)))
        q = self.create_vector()
        solve_checked(self._static[key][1], rhs, q, what, 0, 0.0)
        return q

    def release_recovery(self) -> None:
        """Free the per-body factorizations and couplings kept for :meth:`mode_acceleration_rows`."""
        for b in self.bodies:
            for m in (b.ksp, b.M_ib, b.residual_b):
                if m is not None:
                    m.destroy()
            b.ksp = b.M_ib = b.K_ii = b.factor = b.residual_b = b.ritz_recovery = None

    def reduced_dofs(self, dofs: np.ndarray) -> np.ndarray:
        """Owned local reduced indices whose basis vectors touch the given owned model dofs (the
        non-zero columns of those rows of T's zone part): the reduced image of e.g. the contact
        dofs for mass redistribution."""
        r0 = self.Gr.getOwnershipRange()[0]
        cols = []
        for d in np.asarray(dofs, dtype=np.int64):
            c, v = self.Gr.getRow(int(r0 + d))
            v = np.abs(np.asarray(v))
            # round-off entries (1e-19 against 1e-5, see enrichment.DIRECTION_TOL) must not count:
            # the massless set would then depend on the partition and the BLAS
            cols.append(np.asarray(c)[v > 1e-10 * v.max()] if len(v) else np.zeros(0, np.int32))
        mine = np.unique(np.concatenate(cols)) if cols else np.zeros(0, dtype=np.int64)
        allc = np.unique(np.concatenate(self.comm.allgather(mine.astype(np.int64))))
        q0, q1 = self.M.getOwnershipRange()
        return (allc[(allc >= q0) & (allc < q1)] - q0).astype(np.int32)

    def assemble_T(self) -> PETSc.Mat:
        """The whole T as an AIJ matrix (n x n_r, dense columns over the interiors). For tests and
        small models only: the Craig-Bampton columns are dense."""
        r0, r1 = self.Gr.getOwnershipRange()
        indptr, indices, data = self.Gr.getValuesCSR()
        n_rows = r1 - r0
        S = sp.csr_matrix((data, indices, indptr), shape=(n_rows, self.n_global)).tolil()
        for b in self.bodies:
            if b.n_interior == 0:
                continue
            rows = b.I.getIndices() - r0
            for mat, idx in ((b.Psi, b.qb), (b.Phi, b.modes)):
                if mat is None:
                    continue
                loc = mat.getDenseArray()
                for k, row in enumerate(rows):
                    S[row, idx] = loc[k]
        return aij_from_local_csr(S.tocsr(), self.Gr.getSizes(), self.comm)

    def report(self) -> dict[str, Any]:
        """JSON-able summary of the reduction."""
        return {
            "reduced_coordinates": self.n_global,
            "zone_coordinates": self.n_zone,
            "zone_description": self.zone.kind,
            **{f"zone_{k}": v for k, v in self.zone.info.items()},
            "modes": self.n_modes - sum(b.n_augmented + b.n_patterns for b in self.bodies),
            "augmentation_vectors": sum(b.n_augmented for b in self.bodies),
            "bodies": {b.name: b.report() for b in self.bodies},
            "timings_s": dict(self.timings),
        }
