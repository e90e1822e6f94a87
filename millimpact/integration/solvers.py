"""PETSc/SLEPc solver set-ups of the time integrators (DESIGN.md section 1, "solvers").

Everything here sees assembled PETSc objects only. Every KSP has a non-empty options prefix; its
defaults come from a function that returns a fresh dict, the caller's options are merged over
them, and options already in the PETSc database (the command line) win over both:

``impact_fieldsplit_u_``
    the effective matrix ``A = K + M / (beta dt^2)`` of an implicit step: ``preonly`` + Cholesky,
    CHOLMOD in serial (1.5-3x faster than MUMPS, but serial only), MUMPS under MPI.
    :func:`effective_solver_defaults`.
``impact_``
    the saddle-point system of the contact step on the active set ``A``,
    ``[[A, B_A^T], [B_A, 0]] [u; -lambda_A] = [r; -g0_A]``: PCFIELDSPLIT, Schur, full
    factorization; the ``u`` block is the factorized ``A`` above (same prefix, same factorization:
    never refactored inside a step); the Schur block ``-S_AA = -B_A A^-1 B_A^T`` is preconditioned
    by that matrix formed explicitly from ``W = A^-1 B^T`` (prefix ``impact_fieldsplit_lam_``,
    LU), so its inner solve is exact in one application. ``-impact_pc_type lu`` switches to a
    monolithic MUMPS LU of the whole saddle matrix (refactored at every change of the active set:
    a check, not for 3D production). :func:`saddle_solver_defaults`.
``impact_mass_``
    a mass-matrix solve (initial acceleration): CG + Jacobi. :func:`mass_solver_defaults`.
``impact_eps_``
    SLEPc for the largest eigenvalue of ``M_lumped^-1 (K + k_p B^T B)`` (explicit critical step).

The same ``options`` mapping (keys relative to ``-impact_``, e.g. ``{"fieldsplit_u_pc_type":
"lu"}``) configures all of them. Converged reasons are always checked; a failure raises
:class:`millimpact.errors.SolverError` naming the reason, the step and the time.

Also here: the dense contact operator ``W = A^-1 B^T`` and ``S = B W`` (one multi-right-hand-side
solve per step size, :func:`compute_contact_operator`) and the exact small LCP of a contact step
(:func:`solve_lcp`).
"""
from __future__ import annotations

import logging
import math
from contextlib import contextmanager
from dataclasses import dataclass
from typing import Iterator, Mapping, Optional

import numpy as np
from mpi4py import MPI
from petsc4py import PETSc

from ..errors import SolverError

log = logging.getLogger(__name__)

#: Prefix of all PETSc options of the integrators.
PREFIX = "impact_"
#: Split names of the saddle-point system (so the u block's prefix is ``impact_fieldsplit_u_``).
SPLIT_U, SPLIT_LAM = "u", "lam"
#: Columns of B^T per multi-right-hand-side solve when forming W (bounds the dense RHS memory).
W_CHUNK = 64

_KSP_REASONS = {getattr(PETSc.KSP.ConvergedReason, k): k for k in dir(PETSc.KSP.ConvergedReason)
                if not k.startswith("_") and isinstance(getattr(PETSc.KSP.ConvergedReason, k), int)}


# ------------------------------------------------------------------------------------- options
def effective_solver_defaults(comm: MPI.Comm) -> dict[str, str]:
    """Defaults of the effective-matrix solve, keys relative to ``-impact_fieldsplit_u_``.

    A direct factorization reused for every step of a given size (NOTES: factor 17 s / solve
    0.2 s at 143k DOFs; iterative solvers were 5-10x slower than a reused factorization).
    """
    return {"ksp_type": "preonly", "pc_type": "cholesky",
            "pc_factor_mat_solver_type": "cholmod" if comm.size == 1 else "mumps"}


def saddle_solver_defaults(comm: MPI.Comm) -> dict[str, str]:
    """Defaults of the contact saddle-point solve, keys relative to ``-impact_``.

    Includes the ``fieldsplit_u_`` (effective matrix) and ``fieldsplit_lam_`` (Schur) blocks.
    """
    d = {"ksp_type": "preonly", "pc_type": "fieldsplit", "pc_fieldsplit_type": "schur",
         "pc_fieldsplit_schur_fact_type": "full", "pc_fieldsplit_schur_precondition": "user",
         "fieldsplit_lam_ksp_type": "preonly", "fieldsplit_lam_pc_type": "lu",
         "fieldsplit_lam_pc_factor_mat_solver_type": "mumps",
         # used only with -impact_pc_type lu (monolithic): MUMPS pivots on the zero block
         "pc_factor_mat_solver_type": "mumps"}
    d.update({f"fieldsplit_{SPLIT_U}_{k}": v for k, v in effective_solver_defaults(comm).items()})
    return d


def mass_solver_defaults() -> dict[str, str]:
    """Defaults of a mass-matrix solve (keys relative to ``-impact_mass_``): CG + Jacobi.

    The consistent mass matrix is well conditioned (condition number O(1) on quasi-uniform meshes).
    """
    return {"ksp_type": "cg", "pc_type": "jacobi", "ksp_rtol": "1e-12", "ksp_atol": "0",
            "ksp_max_it": "2000"}


def _normalize(options: Optional[Mapping[str, object]]) -> dict[str, str]:
    """Keys relative to ``-impact_`` (a leading ``-`` or ``impact_`` is accepted); values as strings."""
    out: dict[str, str] = {}
    for k, v in (options or {}).items():
        k = str(k).lstrip("-")
        if k.startswith(PREFIX):
            k = k[len(PREFIX):]
        if isinstance(v, bool):
            v = "true" if v else "false"
        out[k] = "" if v is None else str(v)
    return out


@contextmanager
def petsc_options(defaults: Mapping[str, str], options: Optional[Mapping[str, object]] = None,
                  prefix: str = PREFIX) -> Iterator[None]:
    """Temporarily put ``{**defaults, **options}`` (keys relative to ``prefix``) into the PETSc
    options database, skipping keys already there (the command line wins); removed on exit.

    Wrap ``setFromOptions()`` and ``setUp()`` of the objects that read them.
    """
    opts = PETSc.Options()
    merged = {**defaults, **_normalize(options)}
    inserted = []
    for k, v in merged.items():
        name = prefix + k
        if not opts.hasName(name):
            opts.setValue(name, v)
            inserted.append(name)
    try:
        yield
    finally:
        for name in inserted:
            opts.delValue(name)


def get_option(name: str, options: Optional[Mapping[str, object]], default: object) -> object:
    """A non-PETSc setting ``-impact_<name>``: command line, else ``options``, else ``default``.

    The result has the type of ``default`` (bool, int, float or str).
    """
    opts = PETSc.Options()
    full = PREFIX + name
    user = _normalize(options)
    if opts.hasName(full):
        raw = opts.getString(full, "")
    elif name in user:
        raw = user[name]
    else:
        return default
    if isinstance(default, bool):
        return raw.strip().lower() in ("", "1", "true", "yes", "on")
    if isinstance(default, int):
        return int(float(raw))
    if isinstance(default, float):
        return float(raw)
    return raw


# ------------------------------------------------------------------------------ checked solves
def check_ksp(ksp: PETSc.KSP, what: str, step: int, t: float) -> None:
    """Raise :class:`SolverError` if the last solve of ``ksp`` did not converge."""
    reason = ksp.getConvergedReason()
    if reason < 0:
        name = _KSP_REASONS.get(reason, str(reason))
        extra = ""
        if reason == PETSc.KSP.ConvergedReason.DIVERGED_PCSETUP_FAILED:
            extra = _pc_failure(ksp.getPC())
        raise SolverError(f"{what} (prefix {ksp.getOptionsPrefix()}) did not converge: {name}{extra} "
                          f"at step {step}, t = {t:.9g} s")


def _pc_failure(pc: PETSc.PC) -> str:
    """What a failed PC set-up reports, for the error message: the PC's failure reason and, for a
    MUMPS factorization, its INFOG(1) / INFO(1) / INFO(2) error codes (MUMPS user guide, section 8;
    -9 / -8: workspace too small, -10: numerically singular)."""
    parts = []
    try:
        parts.append(f"PC failure {pc.getFailedReason()}")
    except Exception:  # pragma: no cover - older petsc4py
        pass
    try:
        if pc.getType() in ("lu", "cholesky") and pc.getFactorSolverType() == "mumps":
            F = pc.getFactorMatrix()
            parts.append(f"MUMPS INFOG(1) {F.getMumpsInfog(1)}, INFO(1) {F.getMumpsInfo(1)}, "
                         f"INFO(2) {F.getMumpsInfo(2)}")
    except Exception:  # no factor matrix yet
        pass
    return f" ({'; '.join(parts)})" if parts else ""


def solve_checked(ksp: PETSc.KSP, b: PETSc.Vec, x: PETSc.Vec, what: str, step: int, t: float) -> None:
    """``ksp.solve(b, x)`` and :func:`check_ksp`; PETSc errors become :class:`SolverError` too."""
    try:
        ksp.solve(b, x)
    except PETSc.Error as e:
        raise SolverError(f"{what} (prefix {ksp.getOptionsPrefix()}) failed: PETSc error {e.ierr} "
                          f"at step {step}, t = {t:.9g} s") from e
    check_ksp(ksp, what, step, t)


def _mark_symmetric(A: PETSc.Mat) -> None:
    A.setOption(PETSc.Mat.Option.SYMMETRIC, True)
    A.setOption(PETSc.Mat.Option.SPD, True)


def create_effective_solver(A: PETSc.Mat, options: Optional[Mapping[str, object]] = None) -> PETSc.KSP:
    """A factorized solver of the effective matrix ``A`` (prefix ``impact_fieldsplit_u_``).

    The factorization happens here, once; ``ksp.solve`` then only does triangular solves.
    """
    _mark_symmetric(A)
    ksp = PETSc.KSP().create(A.getComm())
    ksp.setOptionsPrefix(f"{PREFIX}fieldsplit_{SPLIT_U}_")
    ksp.setOperators(A)
    pre = f"fieldsplit_{SPLIT_U}_"
    user = {k[len(pre):]: v for k, v in _normalize(options).items() if k.startswith(pre)}
    with petsc_options(effective_solver_defaults(A.getComm().tompi4py()), user, PREFIX + pre):
        ksp.setFromOptions()
        setup_checked(ksp, "factorization of the effective matrix")
    return ksp


def setup_checked(ksp: PETSc.KSP, what: str, step: int = 0, t: float = 0.0) -> None:
    """``ksp.setUp()`` (the factorization, for a direct solver); a PETSc error or a failed
    factorization is a :class:`SolverError` naming the prefix, the step, the time and, for MUMPS,
    its error codes."""
    try:
        ksp.setUp()
    except PETSc.Error as e:
        raise SolverError(f"{what} (prefix {ksp.getOptionsPrefix()}) failed in set-up: PETSc error "
                          f"{e.ierr} at step {step}, t = {t:.9g} s") from e
    pc = ksp.getPC()
    # a failed factorization does not raise: the KSP's reason says so (petsc4py 3.18 has no
    # PC.getFailedReason; before this check such a failure surfaced at the first solve)
    failed = ksp.getConvergedReason() < 0
    if failed:
        raise SolverError(f"{what} (prefix {ksp.getOptionsPrefix()}) failed in set-up{_pc_failure(pc)} "
                          f"at step {step}, t = {t:.9g} s")


def create_factored_solver(A: PETSc.Mat, prefix: str, options: Optional[Mapping[str, object]] = None) -> PETSc.KSP:
    """A set-up (for a direct solver: factored) KSP of ``A`` with options prefix ``prefix``:
    ``options`` (keys relative to the prefix) are defaults, the command line wins."""
    ksp = PETSc.KSP().create(A.getComm())
    ksp.setOptionsPrefix(prefix)
    ksp.setOperators(A)
    with petsc_options({}, options, prefix=prefix):
        ksp.setFromOptions()
        setup_checked(ksp, f"factorization {prefix}")
    return ksp


def solve_or_factorize(ksp: PETSc.KSP, A: PETSc.Mat, b: PETSc.Vec, x: PETSc.Vec, what: str,
                       direct_prefix: str) -> PETSc.KSP:
    """Solve ``A x = b`` with the (iterative) ``ksp``; if it does not converge, destroy it and
    solve with a Cholesky factorization of A instead (prefix ``direct_prefix``; CHOLMOD serial,
    MUMPS parallel). Returns the KSP that solved, for reuse. For mass matrices, whose Jacobi-CG
    is cheap but can stall when reduced coordinates of very different scales meet."""
    try:
        solve_checked(ksp, b, x, what, 0, 0.0)
        return ksp
    except SolverError as exc:
        log.warning("%s: %s; factorizing instead", what, exc)
    ksp.destroy()
    direct = PETSc.KSP().create(A.getComm())
    direct.setOptionsPrefix(direct_prefix)
    direct.setOperators(A)
    with petsc_options(effective_solver_defaults(A.getComm().tompi4py()), None, direct_prefix):
        direct.setFromOptions()
        setup_checked(direct, f"{what} (factorization)")
    solve_checked(direct, b, x, f"{what} (direct)", 0, 0.0)
    return direct


def solve_mass(M: PETSc.Mat, b: PETSc.Vec, x: PETSc.Vec, unit_rows: np.ndarray,
               options: Optional[Mapping[str, object]] = None) -> None:
    """Solve ``M x = b`` with ``x = 0`` on ``unit_rows`` (local owned indices: clamped and
    massless dofs), prefix ``impact_mass_``. Used once, for the initial acceleration (m/s^2)."""
    rstart = M.getOwnershipRange()[0]
    Ms = M.copy()
    Ms.zeroRowsColumns(np.asarray(unit_rows, dtype=PETSc.IntType) + rstart, diag=1.0)
    rhs = b.copy()
    rhs.array[np.asarray(unit_rows, dtype=np.int64)] = 0.0
    ksp = PETSc.KSP().create(M.getComm())
    ksp.setOptionsPrefix(PREFIX + "mass_")
    ksp.setOperators(Ms)
    pre = "mass_"
    user = {k[len(pre):]: v for k, v in _normalize(options).items() if k.startswith(pre)}
    with petsc_options(mass_solver_defaults(), user, PREFIX + pre):
        ksp.setFromOptions()
        ksp.setUp()
    ksp = solve_or_factorize(ksp, Ms, rhs, x, "initial-acceleration mass solve", PREFIX + "mass_direct_")
    ksp.destroy()
    Ms.destroy()
    rhs.destroy()


# ----------------------------------------------------------------------- dense contact operator
def gather(vec: PETSc.Vec) -> np.ndarray:
    """A distributed Vec as a numpy array replicated on every rank (global order)."""
    comm = vec.getComm().tompi4py()
    loc = np.array(vec.getArray(readonly=True), dtype=float)
    if comm.size == 1:
        return loc
    return np.concatenate(comm.allgather(loc))


def scatter_into(vec: PETSc.Vec, values: np.ndarray) -> None:
    """Set the owned part of ``vec`` from a replicated global array."""
    r0, r1 = vec.getOwnershipRange()
    vec.array[:] = values[r0:r1]


def stack_rows(mats: list[PETSc.Mat]) -> PETSc.Mat:
    """The matrices (same column layout) stacked by rows, ``[A_0; A_1; ...]``, in global row order
    (row r of A_k becomes row sum(rows of A_0..A_k-1) + r, whichever rank owns it). Collective."""
    comm = mats[0].getComm()
    n_loc, n = mats[0].getSizes()[1]
    rows = [m.getSize()[0] for m in mats]
    C = PETSc.Mat().createAIJ(((PETSc.DECIDE, sum(rows)), (n_loc, n)), comm=comm)
    C.setPreallocationNNZ((60, 60))
    C.setOption(PETSc.Mat.Option.NEW_NONZERO_ALLOCATION_ERR, False)
    off = 0
    for m, nr in zip(mats, rows):
        r0, r1 = m.getOwnershipRange()
        for r in range(r0, r1):
            cols, vals = m.getRow(r)
            if len(cols):
                C.setValues([off + r], cols, vals, addv=PETSc.InsertMode.INSERT_VALUES)
        off += nr
    C.assemble()
    return C


@dataclass
class ContactOperator:
    """``W = A^-1 B^T`` (n x n_c, distributed MPIDENSE with A's row layout and B's row layout as
    column layout, so ``W.mult`` takes a multiplier Vec) and ``S = B W`` (n_c x n_c numpy,
    symmetrised, replicated on all ranks). Units: W in m/N, S in m/N."""

    W: PETSc.Mat
    S: np.ndarray
    n_rhs: int


def compute_contact_operator(ksp_u: PETSc.KSP, B: PETSc.Mat, chunk: int = W_CHUNK) -> ContactOperator:
    """W = A^-1 B^T for all candidate rows with the factorization of ``ksp_u`` (multi-RHS solves of
    ``chunk`` columns), and the small dense S = B W replicated on every rank.

    Memory: W holds n x n_c doubles (150k x 300 -> 360 MB) per step size.
    """
    comm = B.getComm().tompi4py()
    (m_loc, n_c), (n_loc, n) = B.getSizes()
    pc = ksp_u.getPC()
    F = pc.getFactorMatrix() if pc.getType() in ("lu", "cholesky") else None
    W = PETSc.Mat().createDense(((n_loc, n), (m_loc, n_c)), comm=B.getComm())
    W.setUp()
    Wa = W.getDenseArray()          # local rows x all columns, a view
    Bt = B.transpose(PETSc.Mat())
    ai, aj, av = Bt.getValuesCSR()  # local rows of B^T, global column indices
    rows = np.repeat(np.arange(n_loc), np.diff(ai))
    for j0 in range(0, n_c, chunk):
        j1 = min(n_c, j0 + chunk)
        k = j1 - j0
        if F is not None:
            R = PETSc.Mat().createDense(((n_loc, n), (PETSc.DECIDE, k)), comm=B.getComm())
            R.setUp()
            Ra = R.getDenseArray()
            Ra[:] = 0.0
            sel = (aj >= j0) & (aj < j1)
            Ra[rows[sel], aj[sel] - j0] = av[sel]
            R.assemble()
            X = R.duplicate()
            try:
                F.matSolve(R, X)
            except PETSc.Error as e:
                raise SolverError(f"W = A^-1 B^T: MatMatSolve failed (PETSc error {e.ierr})") from e
            Wa[:, j0:j1] = X.getDenseArray()
            R.destroy()
            X.destroy()
        else:   # an iterative u-block solver: one solve per column
            b = ksp_u.getOperators()[0].createVecLeft()
            x = b.duplicate()
            for j in range(j0, j1):
                b.set(0.0)
                sel = aj == j
                b.array[rows[sel]] = av[sel]
                solve_checked(ksp_u, b, x, "W = A^-1 B^T column solve", 0, 0.0)
                Wa[:, j] = x.array_r
    W.assemble()
    Bt.destroy()
    Sm = B.matMult(W)
    Sloc = np.array(Sm.getDenseArray(), dtype=float)
    S = np.vstack(comm.allgather(Sloc)) if comm.size > 1 else Sloc
    Sm.destroy()
    S = 0.5 * (S + S.T)      # A is symmetric: remove the rounding asymmetry
    return ContactOperator(W=W, S=S, n_rhs=n_c)


# ------------------------------------------------------------------------------ saddle point
def _diag_aij(comm: PETSc.Comm, m_loc: int, m: int, values: np.ndarray) -> PETSc.Mat:
    D = PETSc.Mat().createAIJ(((m_loc, m), (m_loc, m)), nnz=(1, 0), comm=comm)
    D.setUp()
    r0, r1 = D.getOwnershipRange()
    for i in range(r0, r1):
        D.setValue(i, i, float(values[i]))
    D.assemble()
    return D


class SaddlePointSolver:
    """The contact saddle-point solve on an active set, fixed size over all candidate rows.

    ``[[A, B_m^T], [B_m, D]] [u; mu] = [r; -g0_m]`` with ``B_m`` = B with the inactive rows zeroed,
    ``D`` = 1 on inactive rows and 0 on active ones, ``g0_m`` = g0 on active rows: inactive
    multipliers are exactly 0 and ``lambda_A = -mu_A``. A MatNest whose ``A`` block is the very
    matrix factorized by :attr:`ksp_u`: changing the active set changes only the other blocks, so
    the factorization is reused (one Cholesky per step size, checked by the tests).

    With the default PCFIELDSPLIT the u-block KSP *is* :attr:`ksp_u` (prefix
    ``impact_fieldsplit_u_``), also used for the predictor solves and for W. With another
    ``-impact_pc_type`` (e.g. ``lu``) the nest is converted to AIJ and factorized at every change
    of the active set, and :attr:`ksp_u` is a separate effective-matrix solver.
    """

    def __init__(self, A: PETSc.Mat, B: PETSc.Mat, options: Optional[Mapping[str, object]] = None):
        self.A, self.B = A, B
        self.options = dict(options or {})
        comm = A.getComm()
        self.comm = comm
        self.m_loc, self.n_c = B.getSizes()[0]
        _mark_symmetric(A)
        self.Bt = B.transpose(PETSc.Mat())
        self.Bm = B.copy()
        self.Btm = self.Bt.copy()
        self.mask = B.createVecLeft()
        self.mask.set(0.0)
        self.Bm.diagonalScale(L=self.mask)
        self.Btm.diagonalScale(R=self.mask)
        self.D = _diag_aij(comm, self.m_loc, self.n_c, np.ones(self.n_c))
        self.N = PETSc.Mat().createNest([[A, self.Btm], [self.Bm, self.D]], comm=comm)
        self.active = np.zeros(self.n_c, dtype=bool)
        self.Sp = _diag_aij(comm, self.m_loc, self.n_c, np.ones(self.n_c))
        self.n_factorizations = 0
        self.n_solves = 0
        self.max_schur_iterations = 0   #: inner (Schur block) iterations of a solve, maximum
        self._mono: Optional[PETSc.KSP] = None
        self._mono_mat: Optional[PETSc.Mat] = None

        defaults = saddle_solver_defaults(comm.tompi4py())
        self.ksp = PETSc.KSP().create(comm)
        self.ksp.setOptionsPrefix(PREFIX)
        self.ksp.setOperators(self.N)
        pc = self.ksp.getPC()
        with petsc_options(defaults, self.options):
            pc_type = PETSc.Options().getString(PREFIX + "pc_type", "fieldsplit")
            self.fieldsplit = pc_type == "fieldsplit"
            if self.fieldsplit:
                isu, isl = self.N.getNestISs()[0]
                pc.setType("fieldsplit")
                pc.setFieldSplitIS((SPLIT_U, isu), (SPLIT_LAM, isl))
                pc.setFieldSplitSchurPreType(PETSc.PC.SchurPreType.USER, self.Sp)
                self.ksp.setFromOptions()
                setup_checked(self.ksp, "saddle-point solver")
                subs = pc.getFieldSplitSubKSP()
                self.ksp_u, self.ksp_s = subs[0], subs[1]
                setup_checked(self.ksp_u, "factorization of the effective matrix (fieldsplit u block)")
                self.n_factorizations += 1
                setup_checked(self.ksp_s, "Schur-complement preconditioner")
        if not self.fieldsplit:
            self.ksp_u = create_effective_solver(A, self.options)
            self.n_factorizations += 1
        self._ready = self.fieldsplit    # the initial nest (no active row) matches its Schur matrix
        self._rhs_u = A.createVecLeft()
        self._rhs_l = B.createVecLeft()
        self._x_u = A.createVecRight()
        self._x_l = B.createVecLeft()
        self._b = PETSc.Vec().createNest([self._rhs_u, self._rhs_l], comm=comm)
        self._x = PETSc.Vec().createNest([self._x_u, self._x_l], comm=comm)

    def set_active(self, active: np.ndarray, S: np.ndarray, step: int = 0, t: float = 0.0) -> None:
        """Impose the constraints ``active`` (bool, replicated) using the dense S = B A^-1 B^T."""
        active = np.asarray(active, dtype=bool)
        if self._ready and np.array_equal(active, self.active):
            return
        self._ready = True
        self.active = active.copy()
        m = active.astype(float)
        scatter_into(self.mask, m)
        self.B.copy(self.Bm, PETSc.Mat.Structure.SAME_NONZERO_PATTERN)
        self.Bm.diagonalScale(L=self.mask)
        self.Bt.copy(self.Btm, PETSc.Mat.Structure.SAME_NONZERO_PATTERN)
        self.Btm.diagonalScale(R=self.mask)
        dv = self.B.createVecLeft()
        scatter_into(dv, 1.0 - m)
        self.D.setDiagonal(dv)
        dv.destroy()
        if self.fieldsplit:
            # Schur complement of the masked system: -S on the active block, 1 on inactive rows
            ia = np.flatnonzero(active)
            Sp = PETSc.Mat().createAIJ(((self.m_loc, self.n_c), (self.m_loc, self.n_c)),
                                       nnz=(self.m_loc, self.n_c - self.m_loc), comm=self.comm)
            r0, r1 = Sp.getOwnershipRange()
            for i in range(r0, r1):
                if active[i]:
                    Sp.setValues([i], ia.astype(PETSc.IntType), -S[i, ia])
                else:
                    Sp.setValue(i, i, 1.0)
            Sp.assemble()
            self.Sp.destroy()
            self.Sp = Sp
            self.ksp.getPC().setFieldSplitSchurPreType(PETSc.PC.SchurPreType.USER, self.Sp)
            # New state of the nest only (never N.assemble(): it would bump A's state and force a
            # refactorization): PCFieldSplit re-reads the blocks and the Schur preconditioner.
            self.N.stateIncrease()
            self.ksp.setOperators(self.N)
        else:
            if self._mono is not None:
                self._mono.destroy()
                self._mono_mat.destroy()
            Nm = self.N.convert("aij", PETSc.Mat())
            ksp = PETSc.KSP().create(self.comm)
            ksp.setOptionsPrefix(PREFIX)
            ksp.setOperators(Nm)
            with petsc_options(saddle_solver_defaults(self.comm.tompi4py()), self.options):
                ksp.setFromOptions()
                setup_checked(ksp, "monolithic saddle-point factorization", step, t)
            self.n_factorizations += 1
            self._mono = ksp
            self._mono_mat = Nm

    def solve(self, r: PETSc.Vec, g0: np.ndarray, u: PETSc.Vec, step: int, t: float) -> np.ndarray:
        """Solve on the current active set: ``u`` (m) in place; returns lambda (N, replicated)."""
        r.copy(self._rhs_u)
        scatter_into(self._rhs_l, -np.where(self.active, g0, 0.0))
        if self.fieldsplit:
            solve_checked(self.ksp, self._b, self._x, "contact saddle-point solve", step, t)
            check_ksp(self.ksp_s, "Schur-complement solve", step, t)
            self.max_schur_iterations = max(self.max_schur_iterations, self.ksp_s.getIterationNumber())
            xu, xl = self._x_u, self._x_l
        else:
            bb = self._mono_mat.createVecLeft()
            xx = self._mono_mat.createVecRight()
            n_loc = self._rhs_u.getLocalSize()
            bb.array[:n_loc] = self._rhs_u.array_r
            bb.array[n_loc:] = self._rhs_l.array_r
            solve_checked(self._mono, bb, xx, "monolithic contact saddle-point solve", step, t)
            self._x_u.array[:] = xx.array_r[:n_loc]
            self._x_l.array[:] = xx.array_r[n_loc:]
            xu, xl = self._x_u, self._x_l
        self.n_solves += 1
        xu.copy(u)
        lam = -gather(xl)
        lam[~self.active] = 0.0
        return lam

    def destroy(self) -> None:
        """Free the PETSc objects (with the fieldsplit, the factorization in :attr:`ksp_u` goes with
        :attr:`ksp`)."""
        objs = [self._mono, self._mono_mat, self.ksp, self.N, self.Bm, self.Btm, self.Bt, self.D, self.Sp,
                self.mask, self._b, self._x]
        if not self.fieldsplit:
            objs.append(self.ksp_u)
        for o in objs:
            if o is not None:
                o.destroy()


# ------------------------------------------------------------------------------------ the LCP
@dataclass
class LCPResult:
    """Solution of the contact LCP: multipliers (N), active set, semi-smooth Newton iterations."""

    lam: np.ndarray
    active: np.ndarray
    iterations: int
    method: str


def solve_lcp(S: np.ndarray, q: np.ndarray, active0: Optional[np.ndarray] = None, gap_tol: float = 0.0,
              max_iter: int = 50) -> LCPResult:
    """Exact solution of the contact LCP  ``g = q + S lam >= 0, lam >= 0, lam . g = 0``.

    ``S = B A^-1 B^T`` (symmetric positive definite for independent constraint rows), ``q`` the
    predicted gaps (m). Primal-dual active set = semi-smooth Newton on
    ``lam - max(0, lam - c g) = 0`` (Hintermueller, Ito, Kunisch 2002), warm-started from
    ``active0`` (the previous step's set: usually 1-2 iterations). It terminates finitely for
    M-matrices; for a general SPD S it can cycle, which is detected (a repeated active set or
    ``max_iter``), and the problem is then solved as the equivalent non-negative least-squares
    problem ``min ||L^T lam + L^-1 q||, lam >= 0`` with ``S = L L^T`` by Lawson-Hanson (finite
    termination). Deterministic: equal inputs give bit-equal outputs on every rank.
    """
    n = q.size
    active = np.zeros(n, dtype=bool) if active0 is None else np.asarray(active0, dtype=bool).copy()
    seen: set[bytes] = set()
    for it in range(1, max_iter + 1):
        lam = np.zeros(n)
        ia = np.flatnonzero(active)
        if ia.size:
            lam[ia] = _spd_solve(S[np.ix_(ia, ia)], -q[ia])
        g = q + S @ lam
        lam_tol = 1e-12 * float(np.max(np.abs(lam))) if n else 0.0
        new = (active & (lam > -lam_tol)) | (~active & (g < -gap_tol))
        if np.array_equal(new, active):
            lam[lam < 0] = 0.0
            return LCPResult(lam, lam > 0, it, "active-set")
        key = new.tobytes()
        if key in seen:
            break
        seen.add(key)
        active = new
    from scipy.linalg import cholesky, solve_triangular
    from scipy.optimize import nnls

    L = cholesky(S, lower=True)
    lam, _ = nnls(L.T, -solve_triangular(L, q, lower=True), maxiter=max(50, 10 * n))
    return LCPResult(lam, lam > 0, max_iter, "nnls")


def _spd_solve(S: np.ndarray, b: np.ndarray) -> np.ndarray:
    try:
        from scipy.linalg import cho_factor, cho_solve

        return cho_solve(cho_factor(S), b)
    except np.linalg.LinAlgError as e:
        raise SolverError("contact Schur complement S_AA is not positive definite: dependent constraint "
                          "rows in B (e.g. two rows on the same node and direction)") from e


# ----------------------------------------------------------------------------- eigenvalues
def estimate_max_eigenvalue(K: PETSc.Mat, m_lumped: PETSc.Vec, B: Optional[PETSc.Mat] = None,
                            k_p: float = 0.0, options: Optional[Mapping[str, object]] = None) -> float:
    """Largest eigenvalue (rad^2/s^2) of ``M_lumped^-1 (K + k_p B^T B)`` over the dofs with mass.

    Computed as the largest eigenvalue of the symmetric ``D^-1/2 (K + k_p B^T B) D^-1/2``
    (D = lumped masses, rows with zero mass dropped) by SLEPc Krylov-Schur (prefix
    ``impact_eps_``). The central-difference critical step is ``2 / sqrt(lambda_max)``.
    Falls back to the (safe, larger) Gershgorin bound if SLEPc does not converge.
    """
    from slepc4py import SLEPc

    Kp = K.copy()
    if B is not None and k_p > 0:
        BtB = B.transposeMatMult(B)
        Kp.axpy(k_p, BtB, PETSc.Mat.Structure.DIFFERENT_NONZERO_PATTERN)
        BtB.destroy()
    d = m_lumped.copy()
    arr = d.array
    pos = arr > 0
    arr[pos] = 1.0 / np.sqrt(arr[pos])
    arr[~pos] = 0.0
    Kp.diagonalScale(L=d, R=d)
    eps = SLEPc.EPS().create(K.getComm())
    eps.setOptionsPrefix(PREFIX + "eps_")
    eps.setOperators(Kp)
    eps.setProblemType(SLEPc.EPS.ProblemType.HEP)
    eps.setWhichEigenpairs(SLEPc.EPS.Which.LARGEST_MAGNITUDE)
    eps.setDimensions(1)
    eps.setTolerances(1e-8, 1000)
    with petsc_options({}, {k[4:]: v for k, v in _normalize(options).items() if k.startswith("eps_")},
                       PREFIX + "eps_"):
        eps.setFromOptions()
        eps.solve()
    lam = float("nan")
    if eps.getConverged() >= 1:
        lam = float(eps.getEigenvalue(0).real)
    if not math.isfinite(lam) or lam <= 0:
        # Gershgorin: max_i sum_j |A_ij| >= lambda_max
        absrow = Kp.createVecLeft()
        r0, r1 = Kp.getOwnershipRange()
        for i in range(r0, r1):
            _, vals = Kp.getRow(i)
            absrow.array[i - r0] = np.abs(vals).sum()
        lam = absrow.max()[1]
        if K.getComm().tompi4py().rank == 0:
            log.warning("SLEPc did not converge for the critical step; using the Gershgorin bound")
        absrow.destroy()
    eps.destroy()
    Kp.destroy()
    d.destroy()
    return lam
