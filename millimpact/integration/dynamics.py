"""The dynamic system an integrator advances, the states it hands out, its statistics and its
time schedule; kinetic and strain energies.

``M a + K u = f + B^T lambda`` with unilateral contact rows ``g = g0 + B u >= 0`` (SI units: u in m,
t in s, lambda in N); see :mod:`millimpact.integration.integrators` for the schemes.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass
from typing import Protocol

import numpy as np
from petsc4py import PETSc

from ..errors import InputError


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
    f_ext: PETSc.Vec | None = None
    #: Coulomb friction (:mod:`millimpact.integration.friction`): ``T`` (2 n_c x n) tangential rows [t1; t2]
    #: (relative tangential displacement, m), ``friction`` the coefficient mu; None / 0: frictionless
    T: PETSc.Mat | None = None
    friction: float = 0.0
    #: a nonlinear (plastic) internal force of the contact zone, ``f_int = K u + f_c(u)``
    #: (:class:`NonlinearZone`, e.g. :class:`millimpact.fem.plastic_zone.PlasticZone`); None: linear
    plastic: NonlinearZone | None = None
    #: a dict that keeps the implicit schemes' factorized step operators (with their contact
    #: operators W) and the redistributed mass between integrate() calls on this system (impacts
    #: that share a model and a time step: the cases of a contact table); None: each call factorizes
    #: and frees its own
    operator_cache: dict | None = None
    #: the initial-acceleration mass solve's PETSc defaults (keys relative to ``-impact_mass_``);
    #: None: Jacobi-CG (:func:`millimpact.integration.solvers.mass_solver_defaults`)
    mass_solver: dict | None = None


class NonlinearZone(Protocol):
    """What an integrator needs of a nonlinear internal force ``f_int(u) = K u + f_c(u)``:
    ``evaluate(u)`` computes the trial state at u from the committed one and returns how many
    points are nonlinear (yielding) on this rank; then ``force_correction()`` gives f_c (N, a Vec
    like u) and ``stiffness_correction()`` dK = d f_c / du (a Mat); ``frozen_force()`` is f_c of the
    committed state where no point yields (a new Vec); ``step_plastic_work()`` the
    plastic work of the trial state over the step (J, global); ``commit()`` accepts the trial state.
    ``select_candidates(fraction)`` picks the cells near yielding at the last full evaluation, and
    ``evaluate(u, candidates_only=True)`` then return-maps those alone (f_c elsewhere the frozen
    one); such a state is confirmed by a full evaluation before it is committed. ``compiled``
    chooses the compiled pass for the evaluations without the tangent (``evaluate(u, False)``);
    ``version`` changes whenever the committed state does; ``time_step`` is the step (s) the
    integrator takes (a strain-rate law's dg / dt). A ``finite`` (finite-strain) zone is nonlinear
    wherever it is strained: no candidates, and its frozen force is f_c at the committed
    displacement (:mod:`millimpact.fem.finite_zone`)."""

    compiled: bool
    time_step: float | None

    @property
    def finite(self) -> bool: ...

    @property
    def version(self) -> int: ...

    def evaluate(self, u: PETSc.Vec, tangent: bool = True, candidates_only: bool = False) -> int: ...

    def select_candidates(self, stress_fraction: float) -> int: ...

    def force_correction(self) -> PETSc.Vec: ...

    def frozen_force(self) -> PETSc.Vec: ...

    def stiffness_correction(self) -> PETSc.Mat: ...

    def step_plastic_work(self) -> float: ...

    def commit(self) -> None: ...


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
    tau: np.ndarray | None = None  #: friction: tangential multipliers (N, 2 n_c: [t1; t2])
    friction_work: float = 0.0  #: friction: energy dissipated by slip so far (J, >= 0)
    plastic_work: float = 0.0  #: plasticity: plastic work so far (J, >= 0)


@dataclass
class IntegrationStats:
    """What a run cost and did. Times in s."""

    method: str
    contact_solve: str = ""
    n_steps: int = 0  #: accepted steps
    n_steps_contact: int = 0  #: of which with dt_contact
    n_steps_free: int = 0  #: of which with dt_free
    n_rejected: int = 0  #: dt_free steps redone with dt_contact (a gap closed)
    n_substeps: int = 0  #: explicit sub-steps
    n_switches: int = 0  #: contact status switches summed over constraints
    n_active_set_changes: int = 0  #: steps whose active set differs from the previous one
    max_active: int = 0
    n_solves: int = 0  #: effective-matrix solves (predictors)
    n_saddle_solves: int = 0
    n_w_columns: int = 0  #: right-hand sides of W = A^-1 B^T
    n_factorizations: int = 0  #: of the step operators, those released after the impact included
    n_step_operators_released: int = 0  #: step sizes' operators freed after separation (newmark.py)
    max_schur_iterations: int = 0  #: fieldsplit: inner iterations of the Schur block (1 expected)
    n_newton: int = 0  #: LCP active-set iterations, summed
    max_newton: int = 0
    n_lcp_fallback: int = 0  #: LCPs solved by the NNLS fallback
    friction: float = 0.0  #: Coulomb coefficient
    max_friction_passes: int = 0  #: friction: normal/tangential fixed-point passes, maximum
    n_friction_fallback: int = 0  #: friction: Tresca problems finished by projected gradient
    friction_work_J: float = 0.0  #: friction: energy dissipated by slip (>= 0), J
    max_sliding_nodes: int = 0
    plastic_work_J: float = 0.0  #: plasticity: plastic work (dissipated and stored by hardening), J
    n_plastic_steps: int = 0  #: steps whose converged state yields
    n_plastic_iterations: int = 0  #: iterations of the steps with a yielding iterate, summed
    max_plastic_iterations: int = 0
    #: converged iterates whose full return map found a yielding point outside the candidate cells
    n_plastic_candidate_misses: int = 0
    #: iterations' solves of one body's block skipped: its load had not changed (body_blocks.py)
    n_body_solves_skipped: int = 0
    n_tangent_factorizations: int = 0
    dt_contact: float = 0.0
    dt_free: float = 0.0
    dt_critical: float = float("nan")  #: central differences: critical step, s
    dt_explicit: float = float("nan")  #: central differences: largest sub-step used, s
    penalty: float = float("nan")  #: central differences: k_p, N/m
    diverged: bool = False
    diverged_at: float = float("nan")
    stopped_at: float = float("nan")  #: the ``stop`` callback ended the run here (s), before t_end
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
    dt_free: float | None = None
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


#: the largest matrix (stored values) given a symmetric twin for products (:func:`product_matrix`):
#: a reduced model's K_r and M_r (2.3 million each on paper-rig-plastic's sequence model) and small
#: full models; not the large full ones, whose twin would cost memory the liner panel does not have
PRODUCT_TWIN_MAX_NNZ = 5_000_000
#: |A - A^T|_F <= this times |A|_F: symmetric for the twin (products then agree to rounding)
PRODUCT_TWIN_SYMMETRY_RTOL = 1e-12


def product_matrix(A: PETSc.Mat) -> PETSc.Mat:
    """``A`` or its symmetric twin for products y = A x: a copy in PETSc's SBAIJ format (the upper
    triangle: half the reads of a product, which is memory bound) when A is AIJ, symmetric to
    PRODUCT_TWIN_SYMMETRY_RTOL and holds at most PRODUCT_TWIN_MAX_NNZ values. The twin is made at
    the first call and kept on A (a changed A gets a new one). Measured on paper-rig-plastic's
    10-impact sequence model (14,833 coordinates): K_r 5.0 -> 3.2 ms, M_r 5.3 -> 4.0 ms a
    product, the same products to rounding."""
    held = A.getAttr("millimpact_product_twin")
    if held is not None and held[0] == A.stateGet():
        return held[1] if held[1] is not None else A
    twin = None
    if A.getType() in ("seqaij", "mpiaij") and A.getInfo()["nz_used"] <= PRODUCT_TWIN_MAX_NNZ:
        norm = A.norm(PETSc.NormType.FROBENIUS)
        diff = A.transpose(PETSc.Mat())
        diff.axpy(-1.0, A, PETSc.Mat.Structure.DIFFERENT_NONZERO_PATTERN)
        asym = diff.norm(PETSc.NormType.FROBENIUS)
        diff.destroy()
        if asym <= PRODUCT_TWIN_SYMMETRY_RTOL * norm:
            A.setOption(PETSc.Mat.Option.SYMMETRIC, True)
            twin = A.convert("sbaij", PETSc.Mat())
    A.setAttr("millimpact_product_twin", (A.stateGet(), twin))
    return twin if twin is not None else A


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


class SeparationStop:
    """A ``stop`` callback of :func:`millimpact.integration.integrators.integrate`: True once the
    bodies have touched and then stayed apart (no active contact) for ``quiet_steps`` accepted steps.

    For runs that need the impact only (contact tables): the rebound velocity, impulses, peak
    force and contact duration are all fixed at separation (no force acts on the ball after it;
    restitution is read two rows after the last contact row,
    :func:`millimpact.results.recorder.impact_results`). ``quiet_steps`` >= 3; a gap that closes
    again within them (chatter) resets the count.
    """

    def __init__(self, quiet_steps: int):
        self.quiet_steps = max(3, int(quiet_steps))
        self.touched, self.apart = False, 0

    def __call__(self, state: StepState) -> bool:
        if state.n_active > 0:
            self.touched, self.apart = True, 0
            return False
        if self.touched:
            self.apart += 1
        return self.touched and self.apart >= self.quiet_steps
