"""Reduction: Craig-Bampton projection of a finite-element model, u = T q (DESIGN.md section 4).

Stage ``reduction`` of a run (DESIGN.md section 1). Every reduced method is a Galerkin projection
of a full model (:class:`millimpact.fem.model.FEModel`): the time loop, the contact rows and the
outputs run on ``M_r = T^T M T``, ``K_r = T^T K T`` and ``B_r = B T``.

The owned dofs of the model fall into three sets:

* ``fixed``: clamped and symmetry dofs (``FEModel.fixed_dofs``). ``T`` has zero rows there, so
  every reduced state keeps them at zero; they carry no reduced coordinate.
* ``zone``: the dofs of the cells tagged ``BALL_ZONE`` / ``BLOCK_ZONE`` (including the nodes on the
  zone/region interface). They are described by a :class:`ZoneBasis` ``u_z = G q_z``: the identity
  (``traditional``, ``modal-p2``: nodal dofs kept physical) or the manifold prolongation of
  :mod:`millimpact.reduction.nmm_zone` (``improved``).
* ``interior``: the rest (the non-contact region of each body), reduced per body by Craig-Bampton:

      u_i = Psi q_b + Phi eta,   Psi = -K_ii^-1 K_iz G  (static constraint modes),
      K_ii phi_k = omega_k^2 M_ii phi_k                 (fixed-interface modes, SLEPc).

  ``Psi`` has non-zero columns only for the zone coordinates ``q_b`` that touch the interface
  (``K_iz G`` couples interior dofs to interface nodes only). One Cholesky factorization of
  ``K_ii`` per body serves the multi-right-hand-side solve for ``Psi`` and the shift-and-invert
  spectral transformation of the eigensolver (shift 0).

Modes are kept up to a cutoff frequency (``f_cut``, default the plan's 4 / t_c: below ~1/t_c a
mode's dynamic error is large, DESIGN.md section 4) or a fixed count per body. Because ``Psi`` is
the static response of the interior to the interface, the constraint modes reproduce every
zero-energy motion of the interface exactly: the free ball keeps its rigid motion.

Optional modal truncation augmentation (``augment``, off by default): per body and zone-motion
pattern one more interior vector, the static response of the interior to the inertia load of that
motion, orthogonalised against the kept modes (Dickens et al. 1997). It restores the quasi-static
response of the truncated modes to the contact pulse: F_max at a 1 / t_c cutoff 3.0 % -> 0.05 %
from full P1 (tests/methods/test_reduced_validation.py). Measured effect on the gauge peaks at 4 / t_c
(issue 5; gauges 7.5-15 mm from the contact): on the default mesh traditional 9.0 / 7.3 / 0.5 %
-> 2.8 / 3.2 / 1.8 % (A / B / C) and improved 4.5 / 2.4 / 1.4 % -> 1.1 / 2.4 / 0.9 %, but on the
coarse test mesh traditional 2.0 / 1.5 / 2.6 % -> 5.6 / 5.4 / 12 %: the gauge stresses carry
content far above any affordable cutoff, so they are not a smooth function of the basis, and the
augmentation is not the default.

Output recovery by mode acceleration (:meth:`ReducedModel.mode_acceleration_rows`, the default of
the reduced methods' recorder): outputs in a body's interior (the gauges) add ``C q''`` to
``A T q``, the truncated modes' quasi-static response to the interior's inertia (residual
flexibility ``K_ii^-1 - Phi Omega^-2 Phi^T`` applied to ``(M_ii Psi + M_ib) q_b''``). The dynamics
do not change; the stresses next to the zone converge much faster with the cutoff: gauge A of the
block's 15.4 kHz free mode -14 % -> +0.3 %, and the band-limited gauge peaks of an impact 4.5 % ->
0.5 % (test mesh, 4/t_c; tests/methods/test_reduced_validation.py). Cost: one solve per output row with
the factorization of ``K_ii`` (kept until :meth:`ReducedModel.release_recovery`).

The reduced matrices have a sparse zone block ``G^T K_zz G`` plus dense blocks on the interface
coordinates and the modes (in closed form, no dense ``n x n`` matrix is ever formed)::

    K_r = [ G^T K_zz G + C^T Psi      0          ]     C = K_iz G,  D = M_iz G
          [ 0                         Phi^T K Phi ]
    M_r = [ G^T M_zz G + D^T Psi + Psi^T D + Psi^T M_ii Psi    D^T Phi + Psi^T M_ii Phi ]
          [ sym.                                               Phi^T M_ii Phi            ]

Reduced coordinates are numbered rank by rank: first the zone coordinates a rank owns, then its
share of the modes (all ball modes before all block modes in the global mode order).

Also here: :func:`compute_free_modes`, the lowest free-vibration modes of a reduced model
(:class:`ModalProjection`, u = T Phi eta), which the reduced methods propagate in closed form
between impacts (:mod:`millimpact.methods.reduced`).

PETSc and SLEPc objects live here and in :mod:`millimpact.reduction.nmm_zone` only (STYLE.md). Options
prefixes: ``impact_reduction_<body>_`` for the factorization of ``K_ii`` (``ksp_``, ``pc_``)
and its eigensolver (``eps_``, ``st_``); ``impact_reduction_free_<body>_`` for the free-vibration
modes; ``impact_reduction_mass_`` for the solve with ``M_r`` that projects initial states.
Defaults come from :func:`default_solver_options`, the ``solver_options`` arguments merge over
them and the command line wins.
"""
from __future__ import annotations

import logging
import math
import time
from dataclasses import dataclass, field
from typing import Any, Optional, Sequence

import numpy as np
import scipy.sparse as sp
from dolfinx import fem
from dolfinx.cpp.la.petsc import create_vector as _create_ghosted_vector
from mpi4py import MPI
from petsc4py import PETSc
from slepc4py import SLEPc

from ..geometry import builders as G
from ..errors import InputError, SolverError
from ..fem.model import FEModel
from ..integration.solvers import create_factored_solver, petsc_options, solve_or_factorize

log = logging.getLogger(__name__)

#: the two bodies: name, (zone tag, region tag)
BODIES: tuple[tuple[str, tuple[int, int]], ...] = (
    ("ball", (G.BALL_ZONE, G.BALL_REGION)),
    ("block", (G.BLOCK_ZONE, G.BLOCK_REGION)),
)
ZONE_TAGS = (G.BALL_ZONE, G.BLOCK_ZONE)
REGION_TAGS = (G.BALL_REGION, G.BLOCK_REGION)

#: first number of modes asked from the eigensolver when only a cutoff is given (doubled until the
#: cutoff is passed; the previous vectors seed the next round). The default scene keeps 3 ball and
#: 7 block modes: 8 asked first cost 1 s less CPU than 16 (the Krylov space is ~2 nev vectors, each
#: a solve with the interior's factorization)
FIRST_NEV = 8
#: a dense eigensolver (LAPACK) takes over when this share of all interior modes is requested
DENSE_EIGEN_SHARE = 0.5
#: relative residual accepted for the constraint modes K_ii Psi = -C (a direct solve gives ~1e-12)
CONSTRAINT_RESIDUAL_TOL = 1e-8


def default_solver_options(comm_size: int) -> dict[str, str]:
    """Fresh default PETSc/SLEPc options, relative to ``impact_reduction_<body>_``.

    A Cholesky factorization (the same factorization serves the constraint modes' multi-right-
    hand-side solve and the shift-and-invert eigensolver, NOTES-dolfinx-0.5.md): CHOLMOD in serial,
    MUMPS in parallel (``-impact_reduction_block_pc_factor_mat_solver_type mumps`` in serial: 17 %
    more CPU on the paper-rig improved reduction, 7.0 s against 5.9 s, two runs each); Krylov-Schur
    for the lowest modes (target 0, target-magnitude ordering).
    """
    return {
        "ksp_type": "preonly",
        "pc_type": "cholesky",
        "pc_factor_mat_solver_type": "cholmod" if comm_size == 1 else "mumps",
        "eps_type": "krylovschur",
        "eps_tol": "1e-10",
    }


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
    zone_body: np.ndarray          #: per zone dof: 0 ball, 1 block
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


def create_nodal_zone_basis(model: FEModel, partition: Optional[DofPartition] = None) -> ZoneBasis:
    """The identity on the zone: every non-fixed zone dof is a reduced coordinate (traditional
    multivariable method, and ``modal-p2``)."""
    part = partition or partition_dofs(model)
    comm = model.comm
    n_q = len(part.zone)
    q0 = comm.exscan(n_q) or 0
    indptr = np.zeros(part.n_owned + 1, dtype=np.int32)
    indptr[part.zone + 1] = 1
    indptr = np.cumsum(indptr).astype(np.int32)
    cols = (q0 + np.arange(n_q)).astype(np.int32)
    Gm = PETSc.Mat().createAIJ(((part.n_owned, PETSc.DETERMINE), (n_q, PETSc.DETERMINE)),
                               csr=(indptr, cols, np.ones(n_q)), comm=comm)
    Gm.assemble()
    return ZoneBasis(Gm, part.zone_body.copy(), "nodal", {"zone_coordinates": comm.allreduce(n_q)})


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
    Psi: Optional[PETSc.Mat]
    qb: np.ndarray
    Phi: Optional[PETSc.Mat]
    modes: np.ndarray
    frequencies_hz: np.ndarray
    f_cut: Optional[float]
    next_frequency_hz: float       #: lowest fixed-interface frequency not kept (nan if unknown)
    timings: dict[str, float] = field(default_factory=dict)
    #: the last ``n_augmented`` columns of Phi are augmentation vectors (their Ritz frequencies)
    n_augmented: int = 0
    #: kept for the mode-acceleration output rows (:meth:`ReducedModel.mode_acceleration_rows`)
    #: until :meth:`ReducedModel.release_recovery`: the factored K_ii, M_ii, and the coupling
    #: A_b = M_ii Psi + M_ib (dense n_i x n_b) through which the zone's acceleration loads the interior
    ksp: Optional[PETSc.KSP] = None
    A_b: Optional[PETSc.Mat] = None
    K_ii: Optional[PETSc.Mat] = None

    @property
    def n_modes(self) -> int:
        """Columns of Phi: fixed-interface modes and augmentation vectors."""
        return len(self.frequencies_hz)

    def report(self) -> dict[str, Any]:
        """JSON-able summary."""
        f = self.frequencies_hz[:len(self.frequencies_hz) - self.n_augmented]
        return {"interior_dofs": self.n_interior, "interface_coordinates": int(len(self.qb)),
                "modes": int(len(f)), "augmentation_vectors": self.n_augmented,
                "augmentation_frequencies_Hz": [float(x) for x in self.frequencies_hz[len(f):]],
                "f_cut_Hz": self.f_cut,
                "lowest_frequency_Hz": float(f[0]) if len(f) else None,
                "highest_frequency_Hz": float(f[-1]) if len(f) else None,
                "next_frequency_Hz": self.next_frequency_hz, "timings_s": dict(self.timings)}


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
    _mass_ksp: Optional[PETSc.KSP] = None
    _scatters: dict = field(default_factory=dict)

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
    def _scatter(self, body: BodyReduction, which: str, q: PETSc.Vec) -> tuple[PETSc.Scatter, PETSc.Vec]:
        """Scatter from reduced vectors to the column layout of ``Psi`` / ``Phi`` of a body."""
        key = (body.name, which)
        if key not in self._scatters:
            mat = body.Psi if which == "psi" else body.Phi
            idx = body.qb if which == "psi" else body.modes
            x = mat.createVecRight()
            c0, c1 = x.getOwnershipRange()
            is_from = PETSc.IS().createGeneral(idx[c0:c1].astype(np.int32), comm=self.comm)
            self._scatters[key] = (PETSc.Scatter().create(q, is_from, x, None), x)
        return self._scatters[key]

    def expand(self, q: PETSc.Vec, u: Optional[PETSc.Vec] = None) -> PETSc.Vec:
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
                sc, x = self._scatter(b, which, q)
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

    def restrict(self, f: PETSc.Vec, r: Optional[PETSc.Vec] = None) -> PETSc.Vec:
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
                sc, x = self._scatter(b, which, r)
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
            # a Cholesky factorization of M_r: 0.24 s CPU at the default scene's 10k improved
            # coordinates, against 2.0 s and ~3000 iterations of Jacobi-CG to rounding (the
            # Craig-Bampton couplings and the NMM zone make M_r a poor fit for Jacobi); exact, so
            # a rigid motion stays exact (1e-12)
            self._mass_ksp = create_factored_solver(self.M, "impact_reduction_mass_",
                                     {"ksp_type": "preonly", "pc_type": "cholesky",
                                      "pc_factor_mat_solver_type": "mumps"})
        q = self.create_vector()
        # a user's iterative choice (-impact_reduction_mass_ksp_type cg) that stalls falls back
        # to a factorization
        self._mass_ksp = solve_or_factorize(self._mass_ksp, self.M, rhs, q,
                                            "projection of the initial state on the reduced basis",
                                            "impact_reduction_mass_direct_")
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
                extra.append((_gather_rows(dense, self.comm), idx))
        if not extra:
            return AG
        # add the dense parts: rebuild the local rows as CSR
        r0, r1 = AG.getOwnershipRange()
        indptr, indices, data = AG.getValuesCSR()
        n_rows, n_cols = r1 - r0, self.n_global
        S = sp.csr_matrix((data, indices, indptr), shape=(n_rows, n_cols))
        for dense, idx in extra:
            loc = dense[r0:r1]
            S = S + sp.csr_matrix((loc.ravel(), (np.repeat(np.arange(n_rows), len(idx)),
                                                 np.tile(idx, n_rows))), shape=(n_rows, n_cols))
        return _aij_from_local_csr(S.tocsr(), AG.getSizes(), self.comm)

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
        k = A.getSize()[0]
        C = np.zeros((k, self.n_global))
        r0, r1 = A.getOwnershipRange()
        for b in self.bodies:
            if b.n_interior == 0 or b.ksp is None or b.A_b is None or b.n_augmented:
                continue
            cols = PETSc.IS().createGeneral(b.I.getIndices(), comm=self.comm)
            rows = PETSc.IS().createStride(r1 - r0, r0, 1, comm=self.comm)
            AI = A.createSubMatrix(rows, cols)                       # k x n_i
            if AI.norm(PETSc.NormType.FROBENIUS) == 0.0:
                continue
            AIt = AI.transpose()                                   # n_i x k
            rhs = _dense_columns(AIt, np.arange(k), self.comm)
            Y = rhs.duplicate()
            # the eigensolver's reset dropped the factor (shift-and-invert shares this KSP): set up
            # again (a no-op when the factor is current)
            b.ksp.setOperators(b.K_ii)
            b.ksp.setUp()
            b.ksp.getPC().getFactorMatrix().matSolve(rhs, Y)      # K_ii^-1 A_i^T
            if b.Phi is not None:
                Z = _gather_rows(b.Phi.transposeMatMult(rhs), self.comm)          # m x k
                w2 = (2 * math.pi * np.asarray(b.frequencies_hz)) ** 2
                y = Y.getDenseArray()
                y -= b.Phi.getDenseArray() @ (Z / w2[:, None])
                Y.assemble()
            G = _gather_rows(b.A_b.transposeMatMult(Y), self.comm)                # n_b x k
            C[:, b.qb] -= G.T
            for m in (AI, AIt, rhs, Y):
                m.destroy()
        return C

    def release_recovery(self) -> None:
        """Free the per-body factorizations and couplings kept for :meth:`mode_acceleration_rows`."""
        for b in self.bodies:
            for m in (b.ksp, b.A_b):
                if m is not None:
                    m.destroy()
            b.ksp = b.A_b = b.K_ii = None

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
        return _aij_from_local_csr(S.tocsr(), self.Gr.getSizes(), self.comm)

    def report(self) -> dict[str, Any]:
        """JSON-able summary of the reduction."""
        return {"reduced_coordinates": self.n_global, "zone_coordinates": self.n_zone,
                "zone_description": self.zone.kind, **{f"zone_{k}": v for k, v in self.zone.info.items()},
                "modes": self.n_modes - sum(b.n_augmented for b in self.bodies),
                "augmentation_vectors": sum(b.n_augmented for b in self.bodies),
                "bodies": {b.name: b.report() for b in self.bodies},
                "timings_s": dict(self.timings)}


def local_rows_to_aij(P: sp.csr_matrix, V: fem.FunctionSpace) -> PETSc.Mat:
    """A linear map given on each rank by local rows over its local dofs (owned and ghost, the
    layout of ``Function.x.array``; e.g. :class:`millimpact.fem.model.PointProbe`'s maps, summed over
    ranks) as one AIJ matrix with global columns (rows on rank 0). Collective."""
    comm = V.mesh.comm
    bs = V.dofmap.index_map_bs
    imap = V.dofmap.index_map
    n_rows = P.shape[0]
    glob = imap.local_to_global(np.arange(imap.size_local + imap.num_ghosts, dtype=np.int32)).astype(np.int64)
    C = P.tocoo()
    cols = glob[C.col // bs] * bs + C.col % bs
    rows = (n_rows if comm.rank == 0 else 0, n_rows)
    A = PETSc.Mat().createAIJ((rows, (imap.size_local * bs, imap.size_global * bs)), comm=comm)
    A.setPreallocationNNZ((64, 64))
    A.setOption(PETSc.Mat.Option.NEW_NONZERO_ALLOCATION_ERR, False)
    for r, c, v in zip(C.row, cols, C.data):
        A.setValue(int(r), int(c), float(v), addv=PETSc.InsertMode.ADD_VALUES)
    A.assemble()
    return A


def _check_ksp(ksp: PETSc.KSP, what: str) -> None:
    reason = ksp.getConvergedReason()
    if reason < 0:
        raise SolverError(f"{what}: KSP diverged with reason {reason} (prefix {ksp.getOptionsPrefix()})")


def _gather_rows(A: PETSc.Mat, comm: MPI.Comm) -> np.ndarray:
    """All rows of a (small) dense matrix on every rank, as a numpy array."""
    loc = np.array(A.getDenseArray(), copy=True)
    parts = comm.allgather(loc)
    return np.vstack(parts) if parts else loc


def _aij_from_local_csr(S: sp.csr_matrix, sizes, comm: MPI.Comm) -> PETSc.Mat:
    """An MPIAIJ matrix from the CSR of this rank's rows (global column indices)."""
    S = S.tocsr()
    S.sum_duplicates()
    S.sort_indices()
    A = PETSc.Mat().createAIJ(sizes, csr=(S.indptr.astype(np.int32), S.indices.astype(np.int32), S.data),
                              comm=comm)
    A.assemble()
    return A


def _ownership_offsets(comm: MPI.Comm, n_local: int) -> np.ndarray:
    counts = np.array(comm.allgather(int(n_local)), dtype=np.int64)
    return np.concatenate([[0], np.cumsum(counts)])


def _split(n: int, size: int, rank: int) -> int:
    """PETSc's default split of n items: the local share of rank ``rank``."""
    return n // size + (1 if rank < n % size else 0)


# --- eigenmodes ----------------------------------------------------------------------------------
def _sorted_eigenpairs(eps, A: PETSc.Mat) -> tuple[np.ndarray, list[PETSc.Vec]]:
    """The converged eigenvalues of a solved EPS (real parts, ascending) and their eigenvectors
    (Vecs laid out like A's columns); destroys the EPS."""
    nconv = eps.getConverged()
    lam = np.array([eps.getEigenvalue(i).real for i in range(nconv)])
    order = np.argsort(lam)
    vecs = []
    for i in order:
        v = A.createVecRight()
        eps.getEigenvector(int(i), v)
        vecs.append(v)
    eps.destroy()
    return lam[order], vecs


def compute_modes(K_ii: PETSc.Mat, M_ii: PETSc.Mat, ksp: PETSc.KSP, f_cut: Optional[float],
                  n_modes: Optional[int], prefix: str,
                  options: Optional[dict[str, str]] = None) -> tuple[np.ndarray, list[PETSc.Vec], float]:
    """Lowest modes of K_ii phi = omega^2 M_ii phi (GHEP): all up to ``f_cut`` (Hz), or the
    lowest ``n_modes``. Shift-and-invert at 0 with the already factored ``ksp`` (K_ii).

    Returns (frequencies in Hz ascending, M-orthonormal eigenvectors, the next frequency not kept
    or nan). A dense LAPACK solver takes over when most of the spectrum is requested.
    """
    n = K_ii.getSize()[0]
    if n == 0 or n_modes == 0:
        return np.zeros(0), [], math.nan
    lam_cut = (2 * math.pi * f_cut) ** 2 if f_cut is not None else math.inf
    nev = min(n_modes, n) if n_modes is not None else min(FIRST_NEV, n)
    prev: list[PETSc.Vec] = []
    while True:
        eps = SLEPc.EPS().create(K_ii.getComm())
        eps.setOptionsPrefix(prefix)
        eps.setOperators(K_ii, M_ii)
        eps.setProblemType(SLEPc.EPS.ProblemType.GHEP)
        dense = nev >= DENSE_EIGEN_SHARE * n
        if dense:
            eps.setType(SLEPc.EPS.Type.LAPACK)
            eps.setWhichEigenpairs(SLEPc.EPS.Which.SMALLEST_REAL)
            eps.setDimensions(n)
        else:
            eps.setType(SLEPc.EPS.Type.KRYLOVSCHUR)
            eps.setTarget(0.0)
            eps.setWhichEigenpairs(SLEPc.EPS.Which.TARGET_MAGNITUDE)
            st = eps.getST()
            st.setType(SLEPc.ST.Type.SINVERT)
            st.setShift(0.0)
            st.setKSP(ksp)
            eps.setDimensions(nev, PETSc.DECIDE)
            if prev:
                eps.setInitialSpace(prev)
            with petsc_options({}, {k: v for k, v in (options or {}).items() if k.startswith("eps_")},
                               prefix=prefix):
                eps.setFromOptions()
        eps.solve()
        nconv = eps.getConverged()
        if nconv < min(nev, n):
            raise SolverError(f"eigensolver ({prefix}): {nconv} of {nev} modes converged, "
                              f"reason {eps.getConvergedReason()}")
        lam, vecs = _sorted_eigenpairs(eps, K_ii)
        done = (n_modes is not None or dense or nconv >= n or lam[min(nev, len(lam)) - 1] > lam_cut)
        if done:
            break
        for v in prev:
            v.destroy()
        prev = vecs[:nev]
        nev = min(2 * nev, n)
    if n_modes is not None:
        keep = min(n_modes, len(lam))
    else:
        keep = int(np.searchsorted(lam, lam_cut, side="right"))
    freq = np.sqrt(np.maximum(lam, 0.0)) / (2 * math.pi)
    nxt = float(freq[keep]) if keep < len(freq) else math.nan
    for v in vecs[keep:]:
        v.destroy()
    return freq[:keep], vecs[:keep], nxt


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
    inward = -np.asarray(model.contact_normal, dtype=float)     # into the block
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
    z = np.maximum(X @ inward, 0.0)                   # depth below the struck face
    lateral = X - np.outer(X @ inward, inward)
    rho = np.linalg.norm(lateral, axis=1)
    R = np.maximum(np.hypot(rho, z), 1e-12)
    u_z = (2.0 * (1.0 - nu) + z**2 / R**2) / R
    u_r = (rho * z / R**2 - (1.0 - 2.0 * nu) * rho / (R + z)) / R
    e_r = lateral / np.maximum(rho, 1e-300)[:, None]
    field_ = u_z[:, None] * inward[None, :] + u_r[:, None] * e_r
    u.array[zone] = field_[np.arange(len(zone)), comp]
    return u


def compute_augmentation_load(K: PETSc.Mat, M: PETSc.Mat, I: PETSc.IS, all_cols: PETSc.IS, K_ii: PETSc.Mat,
                              M_ii: PETSc.Mat, ksp: PETSc.KSP, u_w: PETSc.Vec) -> PETSc.Vec:
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
    _check_ksp(ksp, "augmentation: static extension of the zone motion")
    u_i.scale(-1.0)
    f = K_ii.createVecLeft()
    M_ii.mult(u_i, f)
    M_iz.multAdd(u_w, f, f)
    x = K_ii.createVecRight()
    ksp.solve(f, x)
    _check_ksp(ksp, "augmentation: static response to the inertia load")
    for obj in (K_iz, M_iz, rhs, u_i, f):
        obj.destroy()
    return x


def compute_augmentation_vectors(K_ii: PETSc.Mat, M_ii: PETSc.Mat, xs: Sequence[PETSc.Vec],
                                 vecs: Sequence[PETSc.Vec], rtol: float = 1e-8
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
    Mout = Mbasis[len(vecs):]
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
    lam, Q = _small_ghep(0.5 * (A + A.T), 0.5 * (B + B.T))
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
    return np.sqrt(np.maximum(lam, 0.0)) / (2 * math.pi), result


def _small_ghep(A: np.ndarray, B: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Eigenpairs of the small symmetric-definite problem A q = lam B q (ascending, B-orthonormal)."""
    L = np.linalg.cholesky(B)
    Linv = np.linalg.inv(L)
    lam, W = np.linalg.eigh(Linv @ A @ Linv.T)
    return lam, Linv.T @ W


# --- Craig-Bampton -------------------------------------------------------------------------------
def reduce_model(model: FEModel, zone: Optional[ZoneBasis] = None, *, f_cut: Optional[float] = None,
                 n_modes: Optional[int] = None, partition: Optional[DofPartition] = None,
                 solver_options: Optional[dict[str, str]] = None,
                 augment: Sequence[str] = ()) -> ReducedModel:
    """Craig-Bampton reduction of ``model``: the zone described by ``zone`` (default: nodal, the
    identity), each body's interior by constraint modes and fixed-interface modes up to ``f_cut``
    (Hz) or ``n_modes`` per body (``n_modes`` wins if both are given; ``n_modes >=`` the interior
    size keeps every mode and reproduces the full model exactly). ``augment``: zone-motion
    patterns (:data:`AUGMENTATION_PATTERNS`) whose modal truncation augmentation vectors are
    appended to each body's modes (one per pattern and body, see
    :func:`compute_augmentation_vectors`). Collective."""
    if f_cut is None and n_modes is None:
        raise InputError("reduction: give a modal cutoff f_cut (Hz) or a mode count per body")
    if f_cut is not None and not (f_cut > 0):
        raise InputError(f"reduction: f_cut = {f_cut!r} Hz must be > 0")
    if n_modes is not None and n_modes < 0:
        raise InputError(f"reduction: modes = {n_modes!r} must be >= 0")
    bad = [a for a in augment if a not in AUGMENTATION_PATTERNS]
    if bad:
        raise InputError(f"reduction: augment = {','.join(bad)}: choose from {', '.join(AUGMENTATION_PATTERNS)} "
                         "or none")
    t_start = time.perf_counter()
    comm = model.comm
    opts = default_solver_options(comm.size)
    opts.update(solver_options or {})
    part = partition or partition_dofs(model)
    zone = zone or create_nodal_zone_basis(model, part)
    K, M = model.K, model.M
    n_loc = part.n_owned
    r0 = K.getOwnershipRange()[0]
    all_cols = PETSc.IS().createStride(n_loc, r0, 1, comm=comm)

    # reduced numbering: per rank [owned zone coordinates, owned modes]; modes known later, so the
    # zone coordinates are numbered first in "q" numbering and moved at the end
    q_off = _ownership_offsets(comm, zone.n_local)
    G_q = zone.G
    timings: dict[str, float] = {}

    body_data = []
    for name, _tags in BODIES:
        tb = time.perf_counter()
        idx = part.interior[name]
        I = PETSc.IS().createGeneral((r0 + idx).astype(np.int32), comm=comm)
        n_i = comm.allreduce(len(idx))
        data: dict[str, Any] = {"name": name, "I": I, "n_i": n_i, "timings": {}}
        if n_i == 0:
            body_data.append(data)
            continue
        K_ii = K.createSubMatrix(I, I)
        M_ii = M.createSubMatrix(I, I)
        C = K.createSubMatrix(I, all_cols).matMult(G_q)      # K_iz G   (n_i x n_q)
        D = M.createSubMatrix(I, all_cols).matMult(G_q)      # M_iz G
        # interface coordinates: the non-zero columns of C and D
        cols_loc = np.unique(np.concatenate([C.getValuesCSR()[1], D.getValuesCSR()[1]]))
        qb = np.unique(np.concatenate(comm.allgather(cols_loc.astype(np.int64))))
        n_b = len(qb)
        t0 = time.perf_counter()
        prefix = f"impact_reduction_{name}_"
        ksp = create_factored_solver(K_ii, prefix, opts)
        data["timings"]["factor"] = time.perf_counter() - t0
        Psi = None
        Cb = Db = None
        if n_b:
            t0 = time.perf_counter()
            # sparse interface columns (for the products) and a dense copy of C's (the right-hand
            # sides of the multi-RHS solve: MUMPS takes dense right-hand sides)
            q_lo_b, q_hi_b = G_q.getOwnershipRangeColumn()
            is_qb = PETSc.IS().createGeneral(qb[(qb >= q_lo_b) & (qb < q_hi_b)].astype(np.int32), comm=comm)
            rows_I = PETSc.IS().createStride(len(idx), C.getOwnershipRange()[0], 1, comm=comm)
            Cb = C.createSubMatrix(rows_I, is_qb)
            Db = D.createSubMatrix(rows_I, is_qb)
            rhs = _dense_columns(C, qb, comm)
            Psi = rhs.duplicate()
            F = ksp.getPC().getFactorMatrix()
            F.matSolve(rhs, Psi)
            Psi.scale(-1.0)
            # residual check: K_ii Psi + C = 0
            R = K_ii.matMult(Psi)
            R.axpy(1.0, rhs)
            res = R.norm(PETSc.NormType.FROBENIUS) / max(rhs.norm(PETSc.NormType.FROBENIUS), 1e-300)
            R.destroy()
            rhs.destroy()
            if not res < CONSTRAINT_RESIDUAL_TOL:
                raise SolverError(f"constraint modes of the {name}: relative residual {res:.3g} "
                                  f"(factorization {prefix})")
            data["timings"]["constraint_modes"] = time.perf_counter() - t0
            data["constraint_residual"] = res
        t0 = time.perf_counter()
        xs = []
        for kind in dict.fromkeys(augment):
            u_w = interface_motion_pattern(model, part, name, kind)
            xs.append(compute_augmentation_load(K, M, I, all_cols, K_ii, M_ii, ksp, u_w))
            u_w.destroy()
        t_aug = time.perf_counter() - t0
        t0 = time.perf_counter()
        freq, vecs, nxt = compute_modes(K_ii, M_ii, ksp, f_cut, n_modes, prefix, opts)
        data["timings"]["eigenmodes"] = time.perf_counter() - t0
        data["n_aug"] = 0
        if xs:
            t0 = time.perf_counter()
            f_aug, v_aug = compute_augmentation_vectors(K_ii, M_ii, xs, vecs)
            for x in xs:
                x.destroy()
            freq = np.concatenate([freq, f_aug])
            vecs = list(vecs) + v_aug
            data["n_aug"] = len(v_aug)
            data["timings"]["augmentation"] = t_aug + time.perf_counter() - t0
        Phi = None
        if len(vecs):
            Phi = PETSc.Mat().createDense(((len(idx), n_i), (PETSc.DECIDE, len(vecs))), comm=comm)
            Phi.setUp()
            arr = Phi.getDenseArray()
            for k, v in enumerate(vecs):
                arr[:, k] = v.getArray(readonly=True)
                v.destroy()
            Phi.assemble()
        data.update(K_ii=K_ii, M_ii=M_ii, C=C, D=D, Cb=Cb, Db=Db, qb_q=qb, Psi=Psi, Phi=Phi, freq=freq,
                    next=nxt, ksp=ksp)
        data["timings"]["total"] = time.perf_counter() - tb
        body_data.append(data)

    # mode numbering
    m_total = sum(len(d.get("freq", ())) for d in body_data)
    m_loc = _split(m_total, comm.size, comm.rank)
    m_off = _ownership_offsets(comm, m_loc)
    red_off = q_off + m_off          # first reduced index of each rank

    def q_to_red(gq: np.ndarray) -> np.ndarray:
        owner = np.searchsorted(q_off, gq, side="right") - 1
        return gq + m_off[owner]

    def mode_to_red(gm: np.ndarray) -> np.ndarray:
        owner = np.searchsorted(m_off, gm, side="right") - 1
        return gm + q_off[owner + 1]

    n_red_loc = zone.n_local + m_loc
    n_red = int(red_off[-1])
    red_lo = int(red_off[comm.rank])

    # T's zone part with reduced column numbering: G_r = G E
    q_lo = int(q_off[comm.rank])
    rows = np.arange(q_lo, q_lo + zone.n_local)
    E_csr = (np.arange(zone.n_local + 1, dtype=np.int32), q_to_red(rows).astype(np.int32), np.ones(zone.n_local))
    E = PETSc.Mat().createAIJ(((zone.n_local, PETSc.DETERMINE), (n_red_loc, n_red)), csr=E_csr, comm=comm)
    E.assemble()
    Gr = G_q.matMult(E)

    # zone blocks G^T K G, G^T M G (sparse)
    t0 = time.perf_counter()
    Kzz = K.PtAP(Gr)
    Mzz = M.PtAP(Gr)
    timings["zone_projection"] = time.perf_counter() - t0

    # dense blocks, per body
    t0 = time.perf_counter()
    blocks_K: list[tuple[np.ndarray, np.ndarray, np.ndarray]] = []   # (rows, cols, dense values)
    blocks_M: list[tuple[np.ndarray, np.ndarray, np.ndarray]] = []
    bodies: list[BodyReduction] = []
    mode_start = 0
    for d in body_data:
        name = d["name"]
        if d["n_i"] == 0:
            bodies.append(BodyReduction(name, 0, d["I"], None, np.zeros(0, np.int64), None, np.zeros(0, np.int64),
                                        np.zeros(0), f_cut, math.nan, d["timings"]))
            continue
        freq = d["freq"]
        modes = mode_to_red(np.arange(mode_start, mode_start + len(freq)))
        mode_start += len(freq)
        qb = q_to_red(d["qb_q"])
        Psi, Phi, Cb, Db, K_ii, M_ii = d["Psi"], d["Phi"], d["Cb"], d["Db"], d["K_ii"], d["M_ii"]
        A_b = None
        if Psi is not None:
            Kbb = _gather_rows(Cb.transposeMatMult(Psi), comm)
            Kbb = 0.5 * (Kbb + Kbb.T)
            MPsi = M_ii.matMult(Psi)
            A_b = MPsi.copy()
            A_b.axpy(1.0, _dense_columns(Db, np.arange(Db.getSize()[1]), comm))
            DtPsi = _gather_rows(Db.transposeMatMult(Psi), comm)
            Mbb = DtPsi + DtPsi.T + _gather_rows(Psi.transposeMatMult(MPsi), comm)
            Mbb = 0.5 * (Mbb + Mbb.T)
            blocks_K.append((qb, qb, Kbb))
            blocks_M.append((qb, qb, Mbb))
        if Phi is not None:
            MPhi = M_ii.matMult(Phi)
            KPhi = K_ii.matMult(Phi)
            Mmm = _gather_rows(Phi.transposeMatMult(MPhi), comm)
            Kmm = _gather_rows(Phi.transposeMatMult(KPhi), comm)
            blocks_M.append((modes, modes, 0.5 * (Mmm + Mmm.T)))
            blocks_K.append((modes, modes, 0.5 * (Kmm + Kmm.T)))
            if Psi is not None:
                Mbm = _gather_rows(Db.transposeMatMult(Phi), comm) + _gather_rows(Psi.transposeMatMult(MPhi), comm)
                blocks_M.append((qb, modes, Mbm))
                blocks_M.append((modes, qb, Mbm.T))
                # C^T Phi + Psi^T K_ii Phi = 0 in exact arithmetic (Craig-Bampton decoupling);
                # kept as computed so that K_r = T^T K T to rounding
                Kbm = _gather_rows(Cb.transposeMatMult(Phi), comm) + _gather_rows(Psi.transposeMatMult(KPhi), comm)
                blocks_K.append((qb, modes, Kbm))
                blocks_K.append((modes, qb, Kbm.T))
            MPhi.destroy()
            KPhi.destroy()
        for m in (d["C"], d["D"], Cb, Db):
            if m is not None:
                m.destroy()
        bodies.append(BodyReduction(name, d["n_i"], d["I"], Psi, qb, Phi, modes, freq, f_cut, d["next"],
                                    d["timings"], d["n_aug"], ksp=d["ksp"], A_b=A_b, K_ii=K_ii))
    timings["dense_blocks"] = time.perf_counter() - t0

    sizes = ((n_red_loc, n_red), (n_red_loc, n_red))
    K_r, M_r = _combine(Kzz, Mzz, blocks_K, blocks_M, red_lo, n_red_loc, n_red, sizes, comm)
    for m in (Kzz, Mzz, E):
        m.destroy()

    # ball coordinates: zone coordinates of the ball and the ball's modes
    ball = [np.nonzero(zone.body == 0)[0]]
    for b in bodies:
        if b.name == "ball" and b.n_modes:
            own = b.modes[(b.modes >= red_lo) & (b.modes < red_lo + n_red_loc)] - red_lo
            ball.append(own)
    ball_coords = np.unique(np.concatenate(ball)).astype(np.int32)
    # zone coordinates sit first in each rank's block, so their local index is unchanged
    timings["total"] = time.perf_counter() - t_start
    red = ReducedModel(model, zone, part, M_r, K_r, Gr, bodies, ball_coords, zone.n_global, timings)
    if comm.rank == 0:
        for b in bodies:
            f = b.frequencies_hz
            log.info("reduction %s: %d interior dofs -> %d modes (%s), %d interface coordinates",
                     b.name, b.n_interior, b.n_modes,
                     f"{f[0]:.4g}-{f[-1]:.4g} Hz" if len(f) else "none", len(b.qb))
        log.info("reduced model: %d coordinates (%d zone, %d modal) in %.2f s", red.n_global, red.n_zone,
                 red.n_modes, timings["total"])
    return red


def _dense_columns(A: PETSc.Mat, cols: np.ndarray, comm: MPI.Comm) -> PETSc.Mat:
    """The columns ``cols`` (global, sorted) of the AIJ matrix A as a dense matrix (same rows)."""
    m_loc, m = A.getLocalSize()[0], A.getSize()[0]
    Dm = PETSc.Mat().createDense(((m_loc, m), (PETSc.DECIDE, len(cols))), comm=comm)
    Dm.setUp()
    arr = Dm.getDenseArray()
    arr[:] = 0.0
    indptr, indices, data = A.getValuesCSR()
    if len(indices):
        pos = np.searchsorted(cols, indices)
        rows = np.repeat(np.arange(m_loc), np.diff(indptr))
        np.add.at(arr, (rows, pos), data)
    Dm.assemble()
    return Dm


def _combine(Sk: PETSc.Mat, Sm: PETSc.Mat, blocks_K: list, blocks_M: list, red_lo: int, n_loc: int, n: int,
             sizes, comm: MPI.Comm) -> tuple[PETSc.Mat, PETSc.Mat]:
    """K_r and M_r as AIJ matrices on one common non-zero pattern: the sparse zone blocks Sk, Sm
    plus dense blocks (rows, cols, values with global reduced indices). The common pattern lets
    the integrators form K + c M with MatAXPY(SAME/SUBSET_NONZERO_PATTERN), which in parallel
    fails on differing patterns."""
    rows_l, cols_l, vals_l = [], [], []
    for S, unit in ((Sk, 1.0), (Sm, 1.0j)):
        indptr, indices, data = S.getValuesCSR()
        rows_l.append(np.repeat(np.arange(n_loc), np.diff(indptr)))
        cols_l.append(np.asarray(indices, dtype=np.int64))
        vals_l.append(unit * np.asarray(data))
    for blocks, unit in ((blocks_K, 1.0), (blocks_M, 1.0j)):
        for rows, cols, vals in blocks:
            mine = (rows >= red_lo) & (rows < red_lo + n_loc)
            if not np.any(mine) or len(cols) == 0:
                continue
            r = rows[mine] - red_lo
            rows_l.append(np.repeat(r, len(cols)))
            cols_l.append(np.tile(np.asarray(cols, dtype=np.int64), len(r)))
            vals_l.append(unit * vals[mine].ravel())
    # complex data: real part K, imaginary part M, summed on one pattern (zeros are kept)
    A = sp.coo_matrix((np.concatenate(vals_l), (np.concatenate(rows_l), np.concatenate(cols_l))),
                      shape=(n_loc, n)).tocsr()
    A.sum_duplicates()
    A.sort_indices()
    out = []
    for part in (A.data.real.copy(), A.data.imag.copy()):
        B = PETSc.Mat().createAIJ(sizes, csr=(A.indptr.astype(np.int32), A.indices.astype(np.int32), part), comm=comm)
        B.assemble()
        out.append(B)
    return out[0], out[1]


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
    mass: PETSc.Mat                #: the mass matrix of the eigenproblem (reduced coordinates)
    M_scheme: PETSc.Mat            #: Phi^T mass Phi (= I, AIJ m x m): the integrator's mass, modally
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
        rows = _gather_rows(D, self.comm)
        r0, r1 = AT.getOwnershipRange()
        out = _aij_from_local_csr(sp.csr_matrix(rows[r0:r1]), (AT.getSizes()[0], self.Phi.getSizes()[1]), self.comm)
        D.destroy()
        return out

    def rows_dense(self, A: PETSc.Mat) -> np.ndarray:
        """A T Phi as a replicated numpy array (k x m): gap rows for closed-form predictions."""
        AT = self.red.project_rows(A)
        D = AT.matMult(self.Phi)
        out = _gather_rows(D, self.comm)
        D.destroy()
        return out


def compute_free_modes(red: ReducedModel, f_max: float, mass: Optional[PETSc.Mat] = None,
                       solver_options: Optional[dict[str, str]] = None, shift_hz: float = 100.0) -> ModalProjection:
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
    sigma = -(2 * math.pi * shift_hz) ** 2
    lam_max = (2 * math.pi * f_max) ** 2
    per_body = []
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
            lam, vecs = _sorted_eigenpairs(eps, Kb)
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
    omega2, body = [], []
    k = 0
    for b, (local, lam, vecs) in enumerate(per_body):
        for lam_k, v in zip(lam, vecs):
            arr[local, k] = v.getArray(readonly=True)
            omega2.append(lam_k)
            body.append(b)
            k += 1
    Phi.assemble()
    omega2 = np.maximum(np.array(omega2), 0.0)   # rigid modes: rounding may give -1e-6 rad^2/s^2
    body = np.array(body, dtype=np.int8)
    c0, c1 = Phi.getOwnershipRangeColumn()
    mats = []
    for A in (red.M, red.K, mass):
        AP = A.matMult(Phi)
        G = _gather_rows(Phi.transposeMatMult(AP), comm)
        AP.destroy()
        G = 0.5 * (G + G.T)
        mats.append(_aij_from_local_csr(sp.csr_matrix(G[c0:c1]), ((c1 - c0, m), (c1 - c0, m)), comm))
    ortho = float(np.max(np.abs(gather_aij_dense(mats[2], comm) - np.eye(m)))) if m else 0.0
    if ortho > 1e-6:
        raise SolverError(f"free-vibration modes are not M-orthonormal (max |Phi^T M Phi - I| = {ortho:.3g})")
    ball = np.array([i - c0 for i in range(c0, c1) if body[i] == 0], dtype=np.int32)
    proj = ModalProjection(red, Phi, omega2, body, mats[0], mats[1], ball, f_max, mass, mats[2],
                           {"free_modes": time.perf_counter() - t0})
    if comm.rank == 0:
        f = np.sqrt(omega2) / (2 * math.pi)
        log.info("free-vibration modes up to %.4g kHz: %d ball (%d rigid), %d block, %.2f s", f_max / 1e3,
                 int(np.count_nonzero(body == 0)), int(np.count_nonzero((body == 0) & (f < 1.0))),
                 int(np.count_nonzero(body == 1)), proj.timings["free_modes"])
    return proj


def gather_aij_dense(A: PETSc.Mat, comm: MPI.Comm) -> np.ndarray:
    """All rows of a small AIJ matrix on every rank, as a dense numpy array."""
    r0, r1 = A.getOwnershipRange()
    indptr, indices, data = A.getValuesCSR()
    loc = sp.csr_matrix((data, indices, indptr), shape=(r1 - r0, A.getSize()[1])).toarray()
    return np.vstack(comm.allgather(loc))
