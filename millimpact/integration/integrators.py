"""Time integrators with unilateral contact by Lagrange multipliers (DESIGN.md section 4).

Independent of the geometry: an integrator sees a :class:`LinearDynamics` (assembled PETSc M, K,
contact rows B with gaps ``g = g0 + B u >= 0``) and advances ``M a + K u = f + B^T lambda`` with
``lambda >= 0, g >= 0, lambda g = 0``. Units are those of the system (SI in millimpact): u in m,
t in s, lambda in N.

Methods (:data:`METHODS`):

``newmark-mr`` (default)
    Average-acceleration Newmark (beta = 1/4, gamma = 1/2) on the *redistributed* mass matrix
    (:func:`redistribute_mass`: no mass on the contact dofs; Khenous, Laborde, Renard, Eur. J.
    Mech. A 27, 2008), contact imposed on ``u_{n+1}``. The massless contact dofs follow the body
    quasi-statically, so an impact does not excite the spurious contact-node oscillation, the
    status does not chatter and the energy is conserved up to the small O(dt) release/impact
    error (bar: DESIGN.md section 3; measured in tests/integration/test_bar.py).
``newmark``
    The same with the consistent mass: the known chattering baseline (status switches every few
    steps, energy errors an order larger).
``central-penalty``
    Explicit central differences (velocity Verlet form) with the lumped (HRZ) mass and a penalty
    force ``k_p max(-g, 0)`` per constraint row. Conditionally stable: the critical step
    ``2 / sqrt(lambda_max(M_L^-1 (K + k_p B^T B)))`` is computed (SLEPc) and each scheduled step is
    cut into sub-steps of at most ``safety * dt_crit`` unless ``-impact_limit_step 0`` (for
    stability sweeps: above dt_crit the run blows up, is stopped and reported as diverged).

Each implicit step: one predictor solve with lambda = 0 using the factorization of
``A = K + M/(beta dt^2)`` (cached per step size, never refactored inside a step), the exact small
LCP ``g = q + S lambda`` on the dense ``S = B A^-1 B^T`` (:func:`millimpact.integration.solvers.solve_lcp`,
replicated on every rank, rank 0's answer broadcast), then the final state from the PETSc
saddle-point solve on the found active set (``-impact_contact_solve fieldsplit``, default), a
monolithic LU of it (``lu``) or ``u = u_pred + W lambda`` (``schur``, cheapest: no further solve).
Steps where the predictor opens every gap skip the contact work.

Non-PETSc settings (``options`` keys or command-line ``-impact_<key>``): ``contact_solve``
(fieldsplit|schur|lu), ``penalty`` (k_p in N/m; default ``penalty_factor`` (1) times the largest
``sum_j B_ij^2 K_jj``, i.e. about the element stiffness behind a contact node: on the bar a
10x stiffer penalty made the tip chatter at a stable step), ``critical_step_safety`` (0.5: the
on/off penalty contact of the sphere impact diverges at 0.8-0.9 of the linear estimate at 3 m/s and
0.7-0.8 at 20 m/s, ``millimpact stability``; the bar is stable to 0.91 h/c as theory says),
``limit_step`` (true), ``divergence_factor`` (10: energy growth that counts as blow-up),
``gap_rtol`` (1e-9), ``lambda_check_rtol`` (1e-6: saddle-point multipliers vs the LCP's).
The step-size rule's safety margin is :attr:`TimeSchedule.margin`.
"""
from __future__ import annotations

import logging
import math
import sys
import time
from dataclasses import asdict, dataclass
from typing import Callable, Mapping, Optional

import numpy as np
from mpi4py import MPI
from petsc4py import PETSc

from . import solvers
from ..errors import InputError, MillimpactError, SolverError

log = logging.getLogger(__name__)

#: default fraction of the estimated critical step for central-penalty (see the module docstring)
CRITICAL_STEP_SAFETY = 0.5

#: Integrator names accepted by :func:`integrate`.
METHODS = ("newmark-mr", "newmark", "central-penalty")


# ------------------------------------------------------------------------------------ values
@dataclass
class LinearDynamics:
    """A linear structural system with unilateral contact constraints.

    ``M`` consistent mass (kg; DOLFINx layout, block size 1 or 3), ``K`` stiffness (N/m); clamped
    dofs carry 1 on K's diagonal and 0 on M's (DOLFINx assembly with bcs). ``B`` (n_c x n)
    small-displacement contact rows: ``gap = g0 + B u >= 0`` (m), ``lambda >= 0``,
    ``lambda * gap = 0``; the contact force on the structure is ``B^T lambda`` (N). ``g0``
    initial gaps (m, length n_c, replicated on every rank). ``fixed_dofs`` local owned indices
    with u = v = a = 0. ``contact_dofs`` local owned dofs that mass redistribution makes massless
    (the dofs B acts on, on the deformable side(s)). ``f_ext`` constant external force (N).
    """

    M: PETSc.Mat
    K: PETSc.Mat
    B: PETSc.Mat
    g0: np.ndarray
    fixed_dofs: np.ndarray
    contact_dofs: np.ndarray
    f_ext: Optional[PETSc.Vec] = None
    #: Coulomb friction (:mod:`millimpact.integration.friction`): ``T`` (2 n_c x n) tangential rows [t1; t2]
    #: (relative tangential displacement, m), ``friction`` the coefficient mu; None / 0: frictionless
    T: Optional[PETSc.Mat] = None
    friction: float = 0.0


@dataclass
class StepState:
    """The state after a step, handed to the observer (and once at t = 0).

    ``u`` (m), ``v`` (m/s), ``a`` (m/s^2) are the integrator's own Vecs: read them, copy what you
    keep, never modify them. ``lam`` contact multipliers (N) and ``gap`` (m), replicated numpy
    arrays of length n_c. ``mass`` is the mass matrix the integrator uses (redistributed for
    ``newmark-mr``, diagonal lumped for ``central-penalty``): kinetic energies consistent with
    the scheme are ``kinetic_energy(state.mass, state.v)``. ``penalty_energy`` (J) is the
    penalty springs' energy (0 for the Lagrange-multiplier methods). With mass redistribution,
    v and a on the massless dofs are backward differences of u (they carry no momentum).
    """

    t: float
    dt: float
    u: PETSc.Vec
    v: PETSc.Vec
    a: PETSc.Vec
    lam: np.ndarray
    gap: np.ndarray
    n_active: int
    n_newton: int
    step: int
    mass: PETSc.Mat
    penalty_energy: float = 0.0
    tau: Optional[np.ndarray] = None     #: friction: tangential multipliers (N, 2 n_c: [t1; t2])
    friction_work: float = 0.0           #: friction: energy dissipated by slip so far (J, >= 0)


@dataclass
class IntegrationStats:
    """What a run cost and did. Times in s."""

    method: str
    contact_solve: str = ""
    n_steps: int = 0                 #: accepted steps
    n_steps_contact: int = 0         #: of which with dt_contact
    n_steps_free: int = 0            #: of which with dt_free
    n_rejected: int = 0              #: dt_free steps redone with dt_contact (a gap closed)
    n_substeps: int = 0              #: explicit sub-steps
    n_switches: int = 0              #: contact status switches summed over constraints
    n_active_set_changes: int = 0    #: steps whose active set differs from the previous one
    max_active: int = 0
    n_solves: int = 0                #: effective-matrix solves (predictors)
    n_saddle_solves: int = 0
    n_w_columns: int = 0             #: right-hand sides of W = A^-1 B^T
    n_factorizations: int = 0
    max_schur_iterations: int = 0    #: fieldsplit: inner iterations of the Schur block (1 expected)
    n_newton: int = 0                #: LCP active-set iterations, summed
    max_newton: int = 0
    n_lcp_fallback: int = 0          #: LCPs solved by the NNLS fallback
    friction: float = 0.0            #: Coulomb coefficient
    max_friction_passes: int = 0     #: friction: normal/tangential fixed-point passes, maximum
    n_friction_fallback: int = 0     #: friction: Tresca problems finished by projected gradient
    friction_work_J: float = 0.0     #: friction: energy dissipated by slip (>= 0), J
    max_sliding_nodes: int = 0
    dt_contact: float = 0.0
    dt_free: float = 0.0
    dt_critical: float = float("nan")   #: central differences: critical step, s
    dt_explicit: float = float("nan")   #: central differences: largest sub-step used, s
    penalty: float = float("nan")       #: central differences: k_p, N/m
    diverged: bool = False
    diverged_at: float = float("nan")
    t_end: float = 0.0
    wall_time: float = 0.0

    def _asdict(self) -> dict:
        return asdict(self)


@dataclass(frozen=True)
class TimeSchedule:
    """Adaptive steps between two sizes: ``dt_contact`` near and in contact, ``dt_free`` otherwise.

    The step is ``dt_free`` while no contact is active and no constraint can close within the
    next ``dt_free`` step, estimated from the current gaps g and rates B v:
    ``g_i + margin * dt_free * min(rate_i, 0) > 0`` for all i. A ``dt_free`` step in which a gap
    closes anyway is redone with ``dt_contact``. All steps lie on the grid ``k * dt_grid`` with
    ``dt_grid = t_end / ceil(t_end / dt_contact)`` (<= dt_contact) and
    ``dt_free = m * dt_grid`` (m >= 1 integer, the largest with m dt_grid <= dt_free), so there
    are exactly two step sizes (two factorizations) and the run lands exactly on ``t_end``.
    """

    t_end: float
    dt_contact: float
    dt_free: Optional[float] = None
    margin: float = 2.0

    def __post_init__(self) -> None:
        for name in ("t_end", "dt_contact"):
            if not (getattr(self, name) > 0 and math.isfinite(getattr(self, name))):
                raise InputError(f"TimeSchedule.{name} = {getattr(self, name)!r}: must be > 0")
        if self.dt_free is not None and not self.dt_free > 0:
            raise InputError(f"TimeSchedule.dt_free = {self.dt_free!r}: must be > 0")

    @property
    def n_grid(self) -> int:
        """Number of dt_grid steps to t_end."""
        return max(1, math.ceil(self.t_end / self.dt_contact * (1 - 1e-12)))

    @property
    def dt_grid(self) -> float:
        """The contact step actually used (s): t_end / n_grid <= dt_contact."""
        return self.t_end / self.n_grid

    @property
    def free_ratio(self) -> int:
        """dt_free / dt_grid (integer >= 1)."""
        if self.dt_free is None:
            return 1
        return max(1, int(math.floor(self.dt_free / self.dt_grid * (1 + 1e-12))))

    def free_step_allowed(self, gap: np.ndarray, rate: np.ndarray, n_active: int) -> bool:
        """Whether the next step may be dt_free, from gaps (m) and their rates (m/s)."""
        if self.free_ratio == 1 or n_active > 0:
            return False
        if gap.size == 0:
            return True
        dt_free = self.free_ratio * self.dt_grid
        return bool(np.all(gap + self.margin * dt_free * np.minimum(rate, 0.0) > 0.0))


# ------------------------------------------------------------------------- energies and masses
def kinetic_energy(M: PETSc.Mat, v: PETSc.Vec) -> float:
    """Kinetic energy ``v . M v / 2`` (J) with the mass matrix M (kg) and velocity v (m/s)."""
    Mv = M.createVecLeft()
    M.mult(v, Mv)
    e = 0.5 * Mv.dot(v)
    Mv.destroy()
    return float(e)


def strain_energy(K: PETSc.Mat, u: PETSc.Vec, fixed_dofs: np.ndarray) -> float:
    """Strain energy ``u . K u / 2`` (J) with K (N/m) assembled with DOLFINx bcs.

    K's clamped rows are identity rows: u is zeroed there first so they add nothing.
    """
    w = u.copy()
    w.array[np.asarray(fixed_dofs, dtype=np.int64)] = 0.0
    Kw = K.createVecLeft()
    K.mult(w, Kw)
    e = 0.5 * Kw.dot(w)
    Kw.destroy()
    w.destroy()
    return float(e)


def redistribute_mass(M: PETSc.Mat, contact_dofs: np.ndarray, block_size: Optional[int] = None) -> PETSc.Mat:
    """Mass matrix without mass on the contact dofs, total mass per component preserved.

    The idea of Khenous, Laborde and Renard (Eur. J. Mech. A/Solids 27, 2008): a contact node
    without mass follows the body quasi-statically, so imposing the contact on it cannot hit a
    mass and leave it rattling, which is what makes Newmark with contact chatter and pump energy.

    Construction: the rows and columns of the contact dofs C are removed (zeroed) and each
    contact dof c gives ``share_c = r_c + sum_{j not in C} M_cj`` (r_c its row sum, its lumped
    mass) to the diagonal of its same-component neighbours j not in C in M's sparsity graph
    (component = global index % block size), in proportion to ``|M_cj|``. The shares add up to
    exactly what the removal takes from ``e_k^T M e_k`` (2 sum_C r_c - sum_{C x C} M), so the
    total mass of every component, hence the linear momentum of a rigid translation, is
    preserved. The result is symmetric and positive definite on the dofs that keep mass.
    Neighbours may be owned by another rank: the shares are added into a Vec with ADD_VALUES.

    Designed for P1 contact zones (all ``M_cj >= 0``). For P2, vertex row sums are negative and
    a share can be negative; a non-positive resulting diagonal raises :class:`MillimpactError`.

    Returns a new matrix; M is unchanged.
    """
    comm = M.getComm().tompi4py()
    bs = int(block_size or M.getBlockSize() or 1)
    rstart = M.getOwnershipRange()[0]
    cglob = np.asarray(contact_dofs, dtype=np.int64) + rstart
    all_c = np.unique(np.concatenate(comm.allgather(cglob))) if comm.size > 1 else np.unique(cglob)
    add = M.createVecLeft()
    add.set(0.0)
    pending = []     # (dof, share, its contact neighbours): every neighbour is a contact dof too
    for c in cglob:
        cols, vals = M.getRow(int(c))
        same = (cols % bs) == (c % bs)
        cols, vals = cols[same], vals[same]
        in_c = np.isin(cols, all_c)
        share = float(vals.sum() + vals[~in_c].sum())
        nb, w = cols[~in_c], np.abs(vals[~in_c])
        if w.sum() <= 0.0:
            pending.append((int(c), share))
            continue
        add.setValues(nb.astype(PETSc.IntType), share * w / w.sum(), addv=PETSc.InsertMode.ADD_VALUES)
    if comm.allreduce(len(pending)):
        # a node at the edge of a small contact zone: the next ring of non-contact dofs takes its
        # mass, weighted by the two-step couplings (|M| |M|)_ck (rows of any rank: collective)
        M2 = _abs_square(M)
        for c, share in pending:
            cols, vals = M2.getRow(c)
            keep = ((cols % bs) == (c % bs)) & ~np.isin(cols, all_c) & (vals > 0.0)
            nb, w = cols[keep], vals[keep]
            if w.sum() <= 0.0:
                raise MillimpactError(f"mass redistribution: contact dof {c} has no non-contact dof with mass "
                                      "within two rings to take its mass")
            add.setValues(nb.astype(PETSc.IntType), share * w / w.sum(), addv=PETSc.InsertMode.ADD_VALUES)
        M2.destroy()
    add.assemble()
    Mr = M.copy()
    Mr.zeroRowsColumns(cglob.astype(PETSc.IntType), diag=0.0)
    Mr.setDiagonal(add, addv=PETSc.InsertMode.ADD_VALUES)
    d = Mr.getDiagonal()
    bad = (add.array != 0.0) & (d.array <= 0.0)
    if comm.allreduce(int(np.count_nonzero(bad))):
        raise MillimpactError("mass redistribution produced a non-positive diagonal (negative row sums: "
                              "use P1 elements in the contact zone)")
    add.destroy()
    d.destroy()
    return Mr


def _abs_square(M: PETSc.Mat) -> PETSc.Mat:
    """|M| |M| (entrywise absolute values, then the matrix product), distributed like M."""
    ai, aj, av = M.getValuesCSR()
    A = PETSc.Mat().createAIJ(M.getSizes(), csr=(ai, aj, np.abs(av)), comm=M.getComm())
    A.assemble()
    A2 = A.matMult(A)
    A.destroy()
    return A2


def lumped_mass(M: PETSc.Mat, block_size: Optional[int] = None) -> PETSc.Vec:
    """Diagonal (HRZ) lumped masses (kg): M's diagonal scaled per component so each component's
    total ``e_k^T M e_k`` is kept (Hinton, Rock, Zienkiewicz 1976). Equal to row-sum lumping for
    P1 simplices; positive also for P2 (where row sums are not). Clamped rows (zero diagonal) stay 0.
    """
    bs = int(block_size or M.getBlockSize() or 1)
    ones = M.createVecRight()
    ones.set(1.0)
    rows = M.createVecLeft()
    M.mult(ones, rows)
    d = M.getDiagonal()
    r0 = d.getOwnershipRange()[0]
    comp = (np.arange(d.getLocalSize()) + r0) % bs
    comm = M.getComm().tompi4py()
    for k in range(bs):
        sel = comp == k
        tot = comm.allreduce(float(rows.array[sel].sum()))
        dsum = comm.allreduce(float(d.array[sel].sum()))
        if dsum > 0:
            d.array[sel] *= tot / dsum
    ones.destroy()
    rows.destroy()
    return d


def lumped_mass_matrix(m: PETSc.Vec) -> PETSc.Mat:
    """A diagonal AIJ matrix from lumped masses (so :func:`kinetic_energy` works on it)."""
    n_loc, n = m.getLocalSize(), m.getSize()
    D = PETSc.Mat().createAIJ(((n_loc, n), (n_loc, n)), nnz=(1, 0), comm=m.getComm())
    D.setUp()
    D.setDiagonal(m)
    D.assemble()
    return D


# ------------------------------------------------------------------------------- internals
class _Contact:
    """Gaps and rates replicated on every rank; B^T lambda."""

    def __init__(self, system: LinearDynamics, comm: MPI.Comm):
        B = system.B
        self.comm = comm
        self.n_c = B.getSize()[0]
        self.g0 = np.asarray(system.g0, dtype=float).reshape(-1)
        if self.g0.size != self.n_c:
            raise InputError(f"g0 has {self.g0.size} entries but B has {self.n_c} rows")
        n_fixed = comm.allreduce(len(system.fixed_dofs))
        T = system.T
        if n_fixed:
            # clamped dofs cannot move: remove their columns so neither the gaps nor the forces
            # involve them (the saddle-point rows would otherwise move them)
            mask = B.createVecRight()
            mask.set(1.0)
            mask.array[np.asarray(system.fixed_dofs, dtype=np.int64)] = 0.0
            B = B.copy()
            B.diagonalScale(R=mask)
            if T is not None:
                T = T.copy()
                T.diagonalScale(R=mask)
            mask.destroy()
        self.B = B
        self._c = B.createVecLeft()
        self._f = B.createVecRight()
        # friction: C = [B; T] (3 n_c rows), the rows whose multipliers the step solves for
        self.T = T
        self.C = solvers.stack_rows([B, T]) if T is not None else B
        if T is not None:
            self._t = T.createVecLeft()
            self._cc = self.C.createVecLeft()

    def gap(self, u: PETSc.Vec) -> np.ndarray:
        """g0 + B u (m), replicated."""
        self.B.mult(u, self._c)
        return self.g0 + solvers.gather(self._c)

    def rate(self, v: PETSc.Vec) -> np.ndarray:
        """B v (m/s), replicated."""
        self.B.mult(v, self._c)
        return solvers.gather(self._c)

    def slip(self, du: PETSc.Vec) -> np.ndarray:
        """T du (m), replicated: relative tangential displacements [t1; t2]."""
        self.T.mult(du, self._t)
        return solvers.gather(self._t)

    def add_force(self, lam: np.ndarray, f: PETSc.Vec, scale: float = 1.0) -> None:
        """f += scale * B^T lam."""
        solvers.scatter_into(self._c, lam)
        self.B.multTranspose(self._c, self._f)
        f.axpy(scale, self._f)


def _bcast(comm: MPI.Comm, obj):
    return comm.bcast(obj, root=0) if comm.size > 1 else obj


@dataclass
class _StepOps:
    """Cached linear algebra of one step size."""

    dt: float
    A: PETSc.Mat
    ksp_u: PETSc.KSP
    saddle: Optional[solvers.SaddlePointSolver]
    contact: Optional[solvers.ContactOperator] = None


class _Newmark:
    """Average-acceleration Newmark with Lagrange-multiplier contact on u_{n+1}."""

    beta, gamma = 0.25, 0.5

    def __init__(self, system: LinearDynamics, redistribute: bool, options: Mapping, stats: IntegrationStats,
                 comm: MPI.Comm):
        self.sys, self.options, self.stats, self.comm = system, dict(options), stats, comm
        self.contact = _Contact(system, comm)
        self.fixed = np.asarray(system.fixed_dofs, dtype=np.int64)
        if redistribute:
            self.M = redistribute_mass(system.M, system.contact_dofs)
            self.massless = np.asarray(system.contact_dofs, dtype=np.int64)
        else:
            self.M = system.M
            self.massless = np.zeros(0, dtype=np.int64)
        cs = str(solvers.get_option("contact_solve", options, "fieldsplit")).lower()
        if cs not in ("fieldsplit", "schur", "lu"):
            raise InputError(f"-impact_contact_solve {cs!r}: choose fieldsplit, schur or lu")
        # friction: the step's multipliers come from the dense problem on S = C A^-1 C^T and the
        # state from u = u_pred + W [lambda; tau] (the "schur" update, exact with the factorization)
        self.mu = float(system.friction) if system.T is not None else 0.0
        self.frictional = system.T is not None
        stats.friction = self.mu
        if self.frictional:
            cs = "schur"
        self.tau = np.zeros(2 * self.contact.n_c) if self.frictional else None
        self.sliding = np.zeros(self.contact.n_c, dtype=bool)
        self.contact_solve = cs
        stats.contact_solve = cs
        self.petsc_options = dict(options)
        if cs == "lu":
            self.petsc_options = {"pc_type": "lu", **solvers._normalize(options)}
        self.gap_rtol = float(solvers.get_option("gap_rtol", options, 1e-9))
        self.check_rtol = float(solvers.get_option("lambda_check_rtol", options, 1e-6))
        self.ops: dict[float, _StepOps] = {}
        self.u = system.M.createVecRight()
        self.v, self.a = self.u.duplicate(), self.u.duplicate()
        self.u_new, self.u_pred = self.u.duplicate(), self.u.duplicate()
        self.r, self.tmp = self.u.duplicate(), self.u.duplicate()
        self.lam = np.zeros(self.contact.n_c)
        self.gap = self.contact.g0.copy()
        self.active = np.zeros(self.contact.n_c, dtype=bool)
        self.n_newton = 0
        self.penalty_energy = 0.0

    @property
    def mass(self) -> PETSc.Mat:
        return self.M

    def initialize(self, u0: PETSc.Vec, v0: PETSc.Vec) -> None:
        u0.copy(self.u)
        v0.copy(self.v)
        for x in (self.u, self.v):
            x.array[self.fixed] = 0.0
        self.gap = self.contact.gap(self.u)
        tol = self.gap_rtol * max(float(np.max(np.abs(self.gap), initial=0.0)), 1e-300)
        if np.any(self.gap < -tol):
            raise InputError(f"initial penetration: min gap {self.gap.min():.3e} m < 0")
        # M a0 = f - K u0 (gaps open: lambda0 = 0); massless and clamped dofs: a0 = 0
        rhs = self.u.duplicate()
        self.sys.K.mult(self.u, rhs)
        rhs.scale(-1.0)
        if self.sys.f_ext is not None:
            rhs.axpy(1.0, self.sys.f_ext)
        rhs.array[self.fixed] = 0.0
        rhs.array[self.massless] = 0.0
        self.a.set(0.0)
        if rhs.norm() > 0.0:
            solvers.solve_mass(self.M, rhs, self.a, np.union1d(self.fixed, self.massless), self.options)
        rhs.destroy()

    def _ops(self, dt: float) -> _StepOps:
        if dt in self.ops:
            return self.ops[dt]
        c0 = 1.0 / (self.beta * dt * dt)
        A = self.sys.K.copy()
        try:
            A.axpy(c0, self.M, PETSc.Mat.Structure.SUBSET_NONZERO_PATTERN)
        except PETSc.Error:
            A = self.sys.K.copy()
            A.axpy(c0, self.M, PETSc.Mat.Structure.DIFFERENT_NONZERO_PATTERN)
        t0 = time.perf_counter()
        if self.contact_solve == "schur" or self.contact.n_c == 0:
            ksp_u = solvers.create_effective_solver(A, self.petsc_options)
            saddle = None
        else:
            saddle = solvers.SaddlePointSolver(A, self.contact.B, self.petsc_options)
            ksp_u = saddle.ksp_u
        self.stats.n_factorizations += 1
        if self.comm.rank == 0:
            log.info("dt = %.4g s: effective matrix factorized in %.2f s (%s)", dt, time.perf_counter() - t0,
                     ksp_u.getPC().getFactorSolverType() if ksp_u.getPC().getType() in ("lu", "cholesky")
                     else ksp_u.getPC().getType())
        op = _StepOps(dt, A, ksp_u, saddle)
        self.ops[dt] = op
        return op

    def _contact_operator(self, op: _StepOps) -> solvers.ContactOperator:
        if op.contact is None:
            t0 = time.perf_counter()
            op.contact = solvers.compute_contact_operator(op.ksp_u, self.contact.C)
            self.stats.n_w_columns += op.contact.n_rhs
            if self.comm.rank == 0:
                log.info("dt = %.4g s: W = A^-1 B^T for %d contact rows in %.2f s", op.dt, op.contact.n_rhs,
                         time.perf_counter() - t0)
        return op.contact

    def step(self, dt: float, t_new: float, step: int, allow_reject: bool) -> bool:
        """Advance by dt; False (state unchanged) if ``allow_reject`` and a gap would close."""
        op = self._ops(dt)
        b, g = self.beta, self.gamma
        c0, c1, c2 = 1.0 / (b * dt * dt), 1.0 / (b * dt), 0.5 / b - 1.0
        # predictor right-hand side r = M (c0 u + c1 v + c2 a) + f
        self.tmp.array[:] = c0 * self.u.array_r + c1 * self.v.array_r + c2 * self.a.array_r
        self.M.mult(self.tmp, self.r)
        if self.sys.f_ext is not None:
            self.r.axpy(1.0, self.sys.f_ext)
        self.r.array[self.fixed] = 0.0
        solvers.solve_checked(op.ksp_u, self.r, self.u_pred, "effective-matrix solve", step, t_new)
        self.stats.n_solves += 1
        q = self.contact.gap(self.u_pred)
        scale = max(float(np.max(np.abs(q), initial=0.0)), float(np.max(np.abs(self.contact.g0), initial=0.0)))
        gap_tol = self.gap_rtol * max(scale, 1e-300)
        n_c = q.size
        if n_c == 0 or np.all(q >= -gap_tol):
            lam = np.zeros(n_c)
            self.u_pred.copy(self.u_new)
            self.n_newton = 0
            if self.frictional:
                self.tau, self.sliding = np.zeros(2 * n_c), np.zeros(n_c, dtype=bool)
        else:
            if allow_reject:
                return False
            C = self._contact_operator(op)
        if n_c and not np.all(q >= -gap_tol) and self.frictional:
            lam = self._friction_step(C, q, gap_tol, step)
        elif n_c and not np.all(q >= -gap_tol):
            res = _bcast(self.comm, solvers.solve_lcp(C.S, q, self.active, gap_tol))
            self.n_newton = res.iterations
            self.stats.n_lcp_fallback += res.method != "active-set"
            lam = res.lam
            if not res.active.any():
                self.u_pred.copy(self.u_new)
            elif self.contact_solve == "schur":
                lv = self.contact.B.createVecLeft()
                solvers.scatter_into(lv, lam)
                C.W.mult(lv, self.tmp)
                lv.destroy()
                self.u_new.waxpy(1.0, self.tmp, self.u_pred)
            else:
                op.saddle.set_active(res.active, C.S, step, t_new)
                lam_s = op.saddle.solve(self.r, self.contact.g0, self.u_new, step, t_new)
                self.stats.n_saddle_solves += 1
                err = float(np.max(np.abs(lam_s - lam)))
                if err > self.check_rtol * max(float(np.max(np.abs(lam))), 1e-300):
                    raise SolverError(f"contact saddle-point solve disagrees with the LCP: max |dlambda| = "
                                      f"{err:.3e} N (|lambda| = {np.max(np.abs(lam)):.3e} N) at step {step}, "
                                      f"t = {t_new:.9g} s")
                lam = lam_s
            self.stats.n_newton += self.n_newton
            self.stats.max_newton = max(self.stats.max_newton, self.n_newton)
        gap = self.contact.gap(self.u_new)
        lam_tol = 1e-8 * max(float(np.max(np.abs(lam), initial=0.0)), 1e-300)
        if n_c and (np.min(lam) < -lam_tol or np.min(gap) < -max(gap_tol, 1e-8 * scale)):
            raise SolverError(f"contact conditions violated after the step: min lambda {np.min(lam):.3e} N, "
                              f"min gap {np.min(gap):.3e} m at step {step}, t = {t_new:.9g} s")
        if self.frictional:
            self.tau = np.where(np.concatenate([lam, lam]) > lam_tol, self.tau, 0.0)
        lam = np.where(lam > lam_tol, lam, 0.0)
        # Newmark update on the local arrays
        u, v, a, un = self.u.array, self.v.array, self.a.array, self.u_new.array_r
        a_new = c0 * (un - u) - c1 * v - c2 * a
        v_new = v + dt * ((1.0 - g) * a + g * a_new)
        ml = self.massless
        if ml.size:
            # massless dofs carry no momentum: their velocity is the backward difference of u
            # (the Newmark recursion would ring there with period 2 dt after an impact)
            vm = (un[ml] - u[ml]) / dt
            a_new[ml] = (vm - v[ml]) / dt
            v_new[ml] = vm
        a_new[self.fixed] = 0.0
        v_new[self.fixed] = 0.0
        u[:] = un
        u[self.fixed] = 0.0
        v[:] = v_new
        a[:] = a_new
        if not (np.isfinite(lam).all() and self.comm.allreduce(bool(np.isfinite(u).all()), op=MPI.LAND)):
            raise SolverError(f"non-finite state at step {step}, t = {t_new:.9g} s")
        self.lam, self.gap, self.active = lam, gap, lam > 0
        return True

    def _friction_step(self, C: solvers.ContactOperator, q: np.ndarray, gap_tol: float, step: int) -> np.ndarray:
        """Coulomb friction (:mod:`millimpact.integration.friction`): lambda, tau from the dense problem on
        S = C A^-1 C^T, then u_new = u_pred + W [lambda; tau]. Returns lambda (N); sets self.tau."""
        from . import friction

        self.tmp.waxpy(-1.0, self.u, self.u_pred)
        q_t = self.contact.slip(self.tmp)           # slip increment of the predictor, m
        # dense and small: solved on rank 0 only (the ranks share cores), the answer broadcast
        res = (friction.solve_friction(C.S, q, q_t, self.mu, self.active, self.sliding, gap_tol)
               if self.comm.rank == 0 else None)
        res = _bcast(self.comm, res)
        n_c = q.size
        x = np.concatenate([res.lam, res.tau])
        solvers.scatter_into(self.contact._cc, x)
        C.W.mult(self.contact._cc, self.tmp)
        self.u_new.waxpy(1.0, self.tmp, self.u_pred)
        ds = q_t + C.S[n_c:, :] @ x                 # slip increments over the step, m
        self.stats.friction_work_J += max(0.0, -float(res.tau @ ds))
        self.stats.max_friction_passes = max(self.stats.max_friction_passes, res.iterations)
        self.stats.n_friction_fallback += res.n_fallback
        self.stats.max_sliding_nodes = max(self.stats.max_sliding_nodes, int(np.count_nonzero(res.slip)))
        self.n_newton = res.iterations
        self.stats.n_newton += res.iterations
        self.stats.max_newton = max(self.stats.max_newton, res.iterations)
        self.tau, self.sliding = res.tau, res.slip
        return res.lam

    def rate(self) -> np.ndarray:
        return self.contact.rate(self.v)

    def destroy(self) -> None:
        for op in self.ops.values():
            if op.saddle is not None:
                op.saddle.destroy()
            else:
                op.ksp_u.destroy()
            if op.contact is not None:
                op.contact.W.destroy()
            op.A.destroy()


class _CentralPenalty:
    """Explicit central differences (velocity Verlet), lumped mass, penalty contact."""

    def __init__(self, system: LinearDynamics, options: Mapping, stats: IntegrationStats, comm: MPI.Comm):
        self.sys, self.options, self.stats, self.comm = system, dict(options), stats, comm
        if system.T is not None:
            raise InputError("central-penalty has no friction: use --integrator newmark-mr (or set contact.friction = 0)")
        self.contact = _Contact(system, comm)
        self.fixed = np.asarray(system.fixed_dofs, dtype=np.int64)
        self.m = lumped_mass(system.M)
        self.m.array[self.fixed] = 0.0
        self.mass = lumped_mass_matrix(self.m)
        self.inv_m = self.m.copy()
        pos = self.m.array > 0
        self.inv_m.array[pos] = 1.0 / self.m.array[pos]
        self.inv_m.array[~pos] = 0.0
        k_p = float(solvers.get_option("penalty", options, -1.0))
        if k_p <= 0:
            factor = float(solvers.get_option("penalty_factor", options, 1.0))
            k_p = factor * self._row_stiffness()
        self.k_p = k_p
        stats.penalty = k_p
        t0 = time.perf_counter()
        lam_max = solvers.estimate_max_eigenvalue(system.K, self.m, self.contact.B, k_p, options)
        self.dt_crit = 2.0 / math.sqrt(lam_max)
        self.safety = float(solvers.get_option("critical_step_safety", options, CRITICAL_STEP_SAFETY))
        self.limit = bool(solvers.get_option("limit_step", options, True))
        self.div_factor = float(solvers.get_option("divergence_factor", options, 10.0))
        stats.dt_critical = self.dt_crit
        if comm.rank == 0:
            log.info("central-penalty: k_p = %.4g N/m, critical step %.4g s (%.2f s); step %s", k_p, self.dt_crit,
                     time.perf_counter() - t0,
                     f"limited to {self.safety:g} x critical" if self.limit else "NOT limited")
        self.u = system.M.createVecRight()
        self.v, self.a = self.u.duplicate(), self.u.duplicate()
        self.Ku, self.f = self.u.duplicate(), self.u.duplicate()
        self._saved = [self.u.duplicate() for _ in range(4)]
        self.lam = np.zeros(self.contact.n_c)
        self.gap = self.contact.g0.copy()
        self.n_newton = 0
        self.penalty_energy = 0.0
        self.energy = 0.0
        self.energy_ref = 0.0
        self.diverged = False
        self.touched = False     #: a penalty force acted in some sub-step of the last step

    def _row_stiffness(self) -> float:
        """max_i sum_j B_ij^2 K_jj (N/m): the stiffness a unit constraint displacement meets."""
        B = self.contact.B
        ai, aj, av = B.getValuesCSR()
        B2 = PETSc.Mat().createAIJ(B.getSizes(), csr=(ai, aj, av * av), comm=B.getComm())
        kd = self.sys.K.getDiagonal()
        kd.array[self.fixed] = 0.0
        out = B2.createVecLeft()
        B2.mult(kd, out)
        val = out.max()[1] if out.getSize() else 0.0
        for o in (B2, kd, out):
            o.destroy()
        if not val > 0:
            raise InputError("central-penalty: cannot derive a penalty stiffness (B acts on no free dof); "
                             "give -impact_penalty")
        return float(val)

    def _forces(self) -> None:
        """a = M_L^-1 (f - K u + B^T k_p max(-g, 0)); updates gap, lam, energies."""
        self.gap = self.contact.gap(self.u)
        pen = np.maximum(-self.gap, 0.0)
        self.lam = self.k_p * pen
        self.penalty_energy = 0.5 * self.k_p * float(np.dot(pen, pen))
        self.sys.K.mult(self.u, self.Ku)
        self.Ku.array[self.fixed] = 0.0
        self.f.array[:] = -self.Ku.array_r
        if self.sys.f_ext is not None:
            self.f.axpy(1.0, self.sys.f_ext)
        if self.lam.any():
            self.contact.add_force(self.lam, self.f)
        self.a.array[:] = self.inv_m.array_r * self.f.array_r

    def _energy(self) -> float:
        ek = 0.5 * float(np.dot(self.m.array_r, self.v.array_r ** 2))
        es = 0.5 * float(np.dot(self.Ku.array_r, self.u.array_r))
        return self.comm.allreduce(ek + es) + self.penalty_energy

    def initialize(self, u0: PETSc.Vec, v0: PETSc.Vec) -> None:
        u0.copy(self.u)
        v0.copy(self.v)
        for x in (self.u, self.v):
            x.array[self.fixed] = 0.0
        self._forces()
        if np.any(self.gap < 0):
            raise InputError(f"initial penetration: min gap {self.gap.min():.3e} m < 0")
        self.energy = self.energy_ref = self._energy()

    def step(self, dt: float, t_new: float, step: int, allow_reject: bool) -> bool:
        if allow_reject:
            for src, dst in zip((self.u, self.v, self.a, self.Ku), self._saved):
                src.copy(dst)
            saved = (self.lam, self.gap, self.penalty_energy)
        n_sub = max(1, math.ceil(dt / (self.safety * self.dt_crit) - 1e-12)) if self.limit else 1
        h = dt / n_sub
        self.stats.dt_explicit = h if math.isnan(self.stats.dt_explicit) else max(self.stats.dt_explicit, h)
        self.touched = False
        for _ in range(n_sub):
            self.u.array[:] += h * self.v.array_r + 0.5 * h * h * self.a.array_r
            a_old = self.a.array.copy()
            self._forces()
            self.v.array[:] += 0.5 * h * (a_old + self.a.array_r)
            self.stats.n_substeps += 1
            self.touched = self.touched or bool(np.any(self.lam > 0))
        if allow_reject and self.touched:
            for src, dst in zip(self._saved, (self.u, self.v, self.a, self.Ku)):
                src.copy(dst)
            self.lam, self.gap, self.penalty_energy = saved
            self.stats.n_substeps -= n_sub
            return False
        self.energy = self._energy()
        finite = self.comm.allreduce(bool(np.isfinite(self.u.array_r).all() and np.isfinite(self.energy)),
                                     op=MPI.LAND)
        if not finite or (self.energy_ref > 0 and self.energy > self.div_factor * self.energy_ref):
            self.diverged = True
        return True

    def rate(self) -> np.ndarray:
        return self.contact.rate(self.v)

    def destroy(self) -> None:
        for o in (self.mass, self.m, self.inv_m, *self._saved):
            o.destroy()


# ------------------------------------------------------------------------------------ driver
def integrate(system: LinearDynamics, u0: PETSc.Vec, v0: PETSc.Vec, schedule: TimeSchedule,
              method: str = "newmark-mr", observer: Optional[Callable[[StepState], None]] = None,
              options: Optional[Mapping[str, object]] = None, progress: bool = False) -> IntegrationStats:
    """Integrate from t = 0 (displacement u0 in m, velocity v0 in m/s) to ``schedule.t_end``.

    ``method`` one of :data:`METHODS`; ``observer(state)`` is called (collectively, on every rank)
    once at t = 0 and after every accepted step; ``options`` keys relative to ``-impact_`` (PETSc
    solver options and the settings listed in the module docstring; the command line wins).
    ``progress`` shows a tqdm bar over simulated time on rank 0 if stderr is a terminal.
    Raises :class:`SolverError` on a failed solve or violated contact conditions. An explicit run
    that blows up is stopped and returned with ``stats.diverged = True`` (and a warning).
    """
    method = method.lower()
    if method not in METHODS:
        raise InputError(f"integrator {method!r}: choose one of {', '.join(METHODS)}")
    options = dict(options or {})
    comm = system.M.getComm().tompi4py()
    wall0 = time.perf_counter()
    stats = IntegrationStats(method=method, t_end=schedule.t_end)
    if method == "central-penalty":
        integ = _CentralPenalty(system, options, stats, comm)
    else:
        integ = _Newmark(system, method == "newmark-mr", options, stats, comm)
    integ.initialize(u0, v0)

    n_grid, m_free, dt_g = schedule.n_grid, schedule.free_ratio, schedule.dt_grid
    dt_free = m_free * dt_g
    stats.dt_contact, stats.dt_free = dt_g, dt_free
    if comm.rank == 0:
        log.info("%s: t_end %.4g s, dt_contact %.4g s (asked %.4g), dt_free %.4g s", method, schedule.t_end,
                 dt_g, schedule.dt_contact, dt_free)

    def notify(t: float, dt: float, step: int) -> None:
        if observer is not None:
            observer(StepState(t=t, dt=dt, u=integ.u, v=integ.v, a=integ.a, lam=integ.lam, gap=integ.gap,
                               n_active=int(np.count_nonzero(integ.lam > 0)), n_newton=integ.n_newton,
                               step=step, mass=integ.mass, penalty_energy=integ.penalty_energy,
                               tau=getattr(integ, "tau", None), friction_work=stats.friction_work_J))

    notify(0.0, 0.0, 0)
    bar = None
    if progress and comm.rank == 0 and sys.stderr.isatty():
        from tqdm import tqdm

        bar = tqdm(total=schedule.t_end * 1e6, unit="us", desc=method, file=sys.stderr,
                   bar_format="{l_bar}{bar}| {n:.1f}/{total:.1f} us [{elapsed}<{remaining}]")
    k, step, t = 0, 0, 0.0
    prev_active = integ.lam > 0
    force_contact = False
    try:
        while k < n_grid:
            n_act = int(np.count_nonzero(prev_active)) + int(getattr(integ, "touched", False))
            use_free = (not force_contact and n_grid - k >= m_free
                        and schedule.free_step_allowed(integ.gap, integ.rate(), n_act))
            kk = k + (m_free if use_free else 1)
            dt = dt_free if use_free else dt_g
            t_new = schedule.t_end if kk == n_grid else kk * dt_g
            if not integ.step(dt, t_new, step + 1, allow_reject=use_free):
                stats.n_rejected += 1
                force_contact = True
                continue
            force_contact = False
            k, step, t = kk, step + 1, t_new
            stats.n_steps += 1
            if use_free:
                stats.n_steps_free += 1
            else:
                stats.n_steps_contact += 1
            active = integ.lam > 0
            changed = int(np.count_nonzero(active != prev_active))
            stats.n_switches += changed
            stats.n_active_set_changes += changed > 0
            stats.max_active = max(stats.max_active, int(np.count_nonzero(active)))
            prev_active = active
            notify(t, dt, step)
            if bar is not None:
                bar.update(dt * 1e6)
            if getattr(integ, "diverged", False):
                stats.diverged, stats.diverged_at = True, t
                if comm.rank == 0:
                    log.warning("%s diverged at t = %.6g s (step %d, dt %.4g s, critical %.4g s): energy %.3e J "
                                "vs initial %.3e J", method, t, step, dt, stats.dt_critical, integ.energy,
                                integ.energy_ref)
                break
    finally:
        if bar is not None:
            bar.close()
        if isinstance(integ, _Newmark):
            stats.n_factorizations = sum(
                (op.saddle.n_factorizations if op.saddle is not None else 1) for op in integ.ops.values())
            stats.n_saddle_solves = sum(op.saddle.n_solves for op in integ.ops.values() if op.saddle is not None)
            stats.max_schur_iterations = max(
                [op.saddle.max_schur_iterations for op in integ.ops.values() if op.saddle is not None], default=0)
            if any(op.saddle is not None and not op.saddle.fieldsplit for op in integ.ops.values()):
                stats.contact_solve = "lu"
        stats.wall_time = time.perf_counter() - wall0
    if comm.rank == 0:
        log.info("%s done: %d steps (%d contact, %d free, %d rejected), %d status switches, %d solves, "
                 "%d factorizations, %.2f s", method, stats.n_steps, stats.n_steps_contact, stats.n_steps_free,
                 stats.n_rejected, stats.n_switches, stats.n_solves, stats.n_factorizations, stats.wall_time)
    integ.destroy()
    return stats
