"""PETSc/SLEPc solver set-ups of the time integrators (foundations.md section 1, "solvers").

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

Beside it: the dense contact operator ``W = A^-1 B^T`` and ``S = B W`` (one multi-right-hand-side
solve per step size, :mod:`.contact_operator`), the saddle-point solver (:mod:`.saddle_point`) and
the exact small LCP of a contact step (:mod:`.lcp`).
"""

from __future__ import annotations

import logging
import math
from collections.abc import Iterator, Mapping
from contextlib import contextmanager
from typing import TypeVar

import numpy as np
from mpi4py import MPI
from petsc4py import PETSc

from ..errors import SolverError

log = logging.getLogger(__name__)

#: Prefix of all PETSc options of the integrators.
PREFIX = "impact_"
#: Split names of the saddle-point system (so the u block's prefix is ``impact_fieldsplit_u_``).
SPLIT_U, SPLIT_LAM = "u", "lam"

_KSP_REASONS = {
    getattr(PETSc.KSP.ConvergedReason, k): k
    for k in dir(PETSc.KSP.ConvergedReason)
    if not k.startswith("_") and isinstance(getattr(PETSc.KSP.ConvergedReason, k), int)
}


# ------------------------------------------------------------------------------------- options
#: MUMPS ICNTL(14), extra workspace in % over the analysis' estimate, of the effective-matrix
#: factorizations under MPI (memory: the factors' workspace doubles at most; here tens of MB)
MUMPS_WORKSPACE_PERCENT = "100"


def effective_solver_defaults(comm: MPI.Comm) -> dict[str, str]:
    """Defaults of the effective-matrix solve, keys relative to ``-impact_fieldsplit_u_``.

    A direct factorization reused for every step of a given size (NOTES: factor 17 s / solve
    0.2 s at 143k DOFs; iterative solvers were 5-10x slower than a reused factorization).
    """
    if comm.size == 1:
        return {"ksp_type": "preonly", "pc_type": "cholesky", "pc_factor_mat_solver_type": "cholmod"}
    # MUMPS under MPI with 100 % extra workspace over its analysis' estimate (ICNTL(14), default
    # 20-35 %): the estimate fell short intermittently under mpirun -n 2 (INFOG(1) -9, INFO(2) 9297:
    # 1 in 20 runs of the MPI tests, benchmarks/mpi_stress.sh, "even with the refactorization
    # retry", which until 2026-11-26 never refactorized: see refactorize)
    return {
        "ksp_type": "preonly",
        "pc_type": "cholesky",
        "pc_factor_mat_solver_type": "mumps",
        "mat_mumps_icntl_14": MUMPS_WORKSPACE_PERCENT,
    }


def saddle_solver_defaults(comm: MPI.Comm) -> dict[str, str]:
    """Defaults of the contact saddle-point solve, keys relative to ``-impact_``.

    Includes the ``fieldsplit_u_`` (effective matrix) and ``fieldsplit_lam_`` (Schur) blocks.
    """
    d = {
        "ksp_type": "preonly",
        "pc_type": "fieldsplit",
        "pc_fieldsplit_type": "schur",
        "pc_fieldsplit_schur_fact_type": "full",
        "pc_fieldsplit_schur_precondition": "user",
        "fieldsplit_lam_ksp_type": "preonly",
        "fieldsplit_lam_pc_type": "lu",
        "fieldsplit_lam_pc_factor_mat_solver_type": "mumps",
        "fieldsplit_lam_mat_mumps_icntl_14": MUMPS_WORKSPACE_PERCENT,
        # used only with -impact_pc_type lu (monolithic): MUMPS pivots on the zero block
        "pc_factor_mat_solver_type": "mumps",
    }
    d.update({f"fieldsplit_{SPLIT_U}_{k}": v for k, v in effective_solver_defaults(comm).items()})
    return d


def mass_solver_defaults() -> dict[str, str]:
    """Defaults of a mass-matrix solve (keys relative to ``-impact_mass_``): CG + Jacobi.

    The consistent mass matrix is well conditioned (condition number O(1) on quasi-uniform meshes).
    """
    return {"ksp_type": "cg", "pc_type": "jacobi", "ksp_rtol": "1e-12", "ksp_atol": "0", "ksp_max_it": "2000"}


def option_key(key: object) -> str:
    """An option's key relative to ``-impact_`` (a leading ``-`` or ``impact_`` is accepted)."""
    k = str(key).lstrip("-")
    return k[len(PREFIX) :] if k.startswith(PREFIX) else k


def normalize_options(options: Mapping[str, object] | None) -> dict[str, str]:
    """Keys relative to ``-impact_`` (:func:`option_key`); values as strings."""
    out: dict[str, str] = {}
    for k, v in (options or {}).items():
        k = option_key(k)
        if isinstance(v, bool):
            v = "true" if v else "false"
        out[k] = "" if v is None else str(v)
    return out


# ------------------------------------------------------------------------------ PETSc garbage
#: the time loop releases the PETSc garbage of its communicator every this many steps
GARBAGE_EVERY = 500


def release_petsc_garbage(comm=None) -> None:
    """Destroy the PETSc objects on ``comm`` whose Python handles are gone (collective on
    ``comm``; None: PETSC_COMM_WORLD, then PETSC_COMM_SELF).

    petsc4py 3.18 does not destroy an object when its handle is collected (a destroy can be
    collective, and collection order differs between ranks): it parks it on the garbage of the
    communicator the object was made on until ``PETSc.garbage_cleanup`` of that communicator,
    even in serial. Objects of a DOLFINx model live on the mesh's communicator (a duplicate of
    the one it was built on): pass ``mesh.comm``. Measured: a Vec of 1M doubles created and
    dropped 3 times kept 24 MB until the cleanup; a contact table's case kept 17.5 MB (coarse
    hertz-halfspace) until its mesh communicator was cleaned. A process that runs impact after
    impact (a contact table's cases) calls this between them, where all ranks of ``comm`` are at
    the same point; the time loop calls it every :data:`GARBAGE_EVERY` steps."""
    import gc

    gc.collect()
    PETSc.garbage_cleanup(comm)


def destroy_petsc_tree(root) -> int:
    """Destroy every PETSc / SLEPc object reachable from ``root`` through millimpact's own objects
    (dataclasses and classes of this package), lists, tuples, sets and dicts; returns how many.

    For a set of objects that nothing will use again (a contact table's dropped band: mesh,
    model, reduction, factorizations, contact operators). Dropping their Python handles is not
    enough with petsc4py 3.18 here: measured, each reduction of paper-rig built and dropped in a
    loop kept 0.87 GB (0.12 GB of it the model's M and K); ``garbage_cleanup`` of the caller's
    communicator found nothing, as the objects are parked on the mesh's (see
    :func:`release_petsc_garbage`); an explicit ``destroy()`` frees them. Collective on the
    objects' communicators."""
    seen: set[int] = set()
    count = 0
    stack = [root]
    while stack:
        obj = stack.pop()
        if obj is None or id(obj) in seen or isinstance(obj, (str, bytes, int, float, bool, np.ndarray)):
            continue
        seen.add(id(obj))
        if isinstance(obj, PETSc.Object):
            if obj.handle:
                obj.destroy()
                count += 1
        elif isinstance(obj, dict):
            stack.extend(obj.values())
        elif isinstance(obj, (list, tuple, set, frozenset)):
            stack.extend(obj)
        elif type(obj).__module__.startswith("millimpact.") and hasattr(obj, "__dict__"):
            stack.extend(vars(obj).values())
    return count


# ------------------------------------------------------------------------------ option usage
#: full names (no dash) of inserted options that a PETSc object read, and the ``get_option``
#: names read from the caller's options, since the last :func:`reset_option_usage` (this process)
_USED_NAMES: set[str] = set()
_READ_KEYS: set[str] = set()
_OPTIONS_USED_FN: list = []


def _petsc_options_used():
    """``PetscOptionsUsed`` from the PETSc library petsc4py is linked to (petsc4py 3.18 does not
    wrap it), or None where it cannot be found (then nothing is reported unused)."""
    if not _OPTIONS_USED_FN:
        fn = None
        try:
            import ctypes

            fn = ctypes.CDLL(PETSc.__file__).PetscOptionsUsed  # dlsym searches its dependencies
            fn.argtypes = [ctypes.c_void_p, ctypes.c_char_p, ctypes.POINTER(ctypes.c_int)]
            fn.restype = ctypes.c_int
        except (OSError, AttributeError):
            fn = None
        _OPTIONS_USED_FN.append(fn)
    return _OPTIONS_USED_FN[0]


def _option_used(name: str) -> bool:
    import ctypes

    fn = _petsc_options_used()
    used = ctypes.c_int(0)
    return fn is not None and fn(None, name.encode(), ctypes.byref(used)) == 0 and bool(used.value)


def note_option_read(key: str) -> None:
    """Record that a method read its setting ``key`` from the caller's options."""
    _READ_KEYS.add(option_key(key))


def reset_option_usage() -> None:
    """Forget which options were used (call before a run)."""
    _USED_NAMES.clear()
    _READ_KEYS.clear()


def unused_options(options: Mapping[str, object] | None) -> list[str] | None:
    """The keys of ``options`` (as given, without a leading dash) that no PETSc object, no
    :func:`get_option` and no method setting read since :func:`reset_option_usage`: misspelled,
    or for a solver the run did not have. None when PETSc's usage record is not reachable."""
    if _petsc_options_used() is None:
        return None
    return [
        str(key).lstrip("-")
        for key in options or {}
        if PREFIX + option_key(key) not in _USED_NAMES and option_key(key) not in _READ_KEYS
    ]


@contextmanager
def petsc_options(
    defaults: Mapping[str, str], options: Mapping[str, object] | None = None, prefix: str = PREFIX
) -> Iterator[None]:
    """Temporarily put ``{**defaults, **options}`` (keys relative to ``prefix``) into the PETSc
    options database, skipping keys already there (the command line wins); removed on exit.

    Wrap ``setFromOptions()`` and ``setUp()`` of the objects that read them.
    """
    opts = PETSc.Options()
    user = normalize_options(options)
    merged = {**defaults, **user}
    user_names = {prefix + k for k in user}
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
            if name in user_names and _option_used(name):
                _USED_NAMES.add(name)
            opts.delValue(name)


#: the types a non-PETSc setting takes (its default's)
OptionValue = TypeVar("OptionValue", bool, int, float, str)


def get_option(name: str, options: Mapping[str, object] | None, default: OptionValue) -> OptionValue:
    """A non-PETSc setting ``-impact_<name>``: command line, else ``options``, else ``default``.

    The result has the type of ``default`` (bool, int, float or str).
    """
    opts = PETSc.Options()
    full = PREFIX + name
    user = normalize_options(options)
    if opts.hasName(full):
        raw = opts.getString(full, "")
    elif name in user:
        raw = user[name]
        _READ_KEYS.add(name)
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
        raise SolverError(
            f"{what} (prefix {ksp.getOptionsPrefix()}) did not converge: {name}{extra} at step {step}, t = {t:.9g} s"
        )


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
            parts.append(
                f"MUMPS INFOG(1) {F.getMumpsInfog(1)}, INFO(1) {F.getMumpsInfo(1)}, INFO(2) {F.getMumpsInfo(2)}"
            )
    except Exception:  # no factor matrix yet
        pass
    return f" ({'; '.join(parts)})" if parts else ""


def solve_checked(ksp: PETSc.KSP, b: PETSc.Vec, x: PETSc.Vec, what: str, step: int, t: float) -> None:
    """``ksp.solve(b, x)`` and :func:`check_ksp`; PETSc errors become :class:`SolverError` too."""
    try:
        ksp.solve(b, x)
    except PETSc.Error as e:
        raise SolverError(
            f"{what} (prefix {ksp.getOptionsPrefix()}) failed: PETSc error {e.ierr} at step {step}, t = {t:.9g} s"
        ) from e
    check_ksp(ksp, what, step, t)


def mark_symmetric(A: PETSc.Mat) -> None:
    A.setOption(PETSc.Mat.Option.SYMMETRIC, True)
    A.setOption(PETSc.Mat.Option.SPD, True)


def create_effective_solver(A: PETSc.Mat, options: Mapping[str, object] | None = None) -> PETSc.KSP:
    """A factorized solver of the effective matrix ``A`` (prefix ``impact_fieldsplit_u_``).

    The factorization happens here, once; ``ksp.solve`` then only does triangular solves.
    """
    mark_symmetric(A)
    ksp = PETSc.KSP().create(A.getComm())
    ksp.setOptionsPrefix(f"{PREFIX}fieldsplit_{SPLIT_U}_")
    ksp.setOperators(A)
    pre = f"fieldsplit_{SPLIT_U}_"
    user = {k[len(pre) :]: v for k, v in normalize_options(options).items() if k.startswith(pre)}
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
        raise SolverError(
            f"{what} (prefix {ksp.getOptionsPrefix()}) failed in set-up: PETSc error "
            f"{e.ierr} at step {step}, t = {t:.9g} s"
        ) from e
    pc = ksp.getPC()
    # a failed factorization does not raise: the KSP's reason says so (petsc4py 3.18 has no
    # PC.getFailedReason; before this check such a failure surfaced at the first solve)
    failed = ksp.getConvergedReason() < 0
    if failed:
        codes = _pc_failure(pc)
        if _retry_mumps_workspace(ksp, what):
            return
        raise SolverError(
            f"{what} (prefix {ksp.getOptionsPrefix()}) failed in set-up{codes} at step {step}, t = {t:.9g} s"
        )


#: MUMPS ICNTL(14) (percentage of extra workspace over the analysis' estimate) tried after a
#: factorization fails with INFOG(1) = -8 / -9 (workspace too small; MUMPS user guide, section 8):
#: seen intermittently under mpirun -n 2 at the default (PETSc passes MUMPS's own, 20-35 %)
MUMPS_WORKSPACE_RETRIES = (200, 400)


def _retry_mumps_workspace(ksp: PETSc.KSP, what: str) -> bool:
    """Refactorize a MUMPS factorization that ran out of workspace with a larger ICNTL(14); True
    (and a warning saying so) if one of :data:`MUMPS_WORKSPACE_RETRIES` succeeded. Collective:
    INFOG is the same on every rank."""
    pc = ksp.getPC()
    try:
        if pc.getType() not in ("lu", "cholesky") or pc.getFactorSolverType() != "mumps":
            return False
        if pc.getFactorMatrix().getMumpsInfog(1) not in (-8, -9):
            return False
    except Exception:  # no factor matrix: not a MUMPS workspace failure
        return False
    prefix = ksp.getOptionsPrefix() or ""
    for percent in MUMPS_WORKSPACE_RETRIES:
        if refactorize(ksp, {"mat_mumps_icntl_14": percent}):
            if MPI.COMM_WORLD.rank == 0:
                log.warning(
                    "%s: MUMPS ran out of workspace (INFOG(1) -8/-9); refactorized with -%smat_mumps_icntl_14 %d",
                    what,
                    prefix,
                    percent,
                )
            return True
    return False


def refactorize(ksp: PETSc.KSP, options: Mapping[str, object]) -> bool:
    """Factor ``ksp``'s operator again from scratch after setting ``options`` (keys relative to its
    prefix, left in PETSc's database); True if the new MUMPS factorization succeeded (INFOG(1) 0).
    The operators are set again: after ``PC.reset()`` alone ``KSP.setUp()`` returns at once (the
    KSP still counts as set up), so until 2026-11-26 the workspace retry never refactorized and
    always failed. Collective."""
    prefix = ksp.getOptionsPrefix() or ""
    db = PETSc.Options()
    for k, v in options.items():
        db[prefix + k] = v
    pc = ksp.getPC()
    A, P = ksp.getOperators()
    try:
        pc.reset()
        ksp.setOperators(A, P)
        ksp.setUp()
        return ksp.getConvergedReason() >= 0 and pc.getFactorMatrix().getMumpsInfog(1) == 0
    except PETSc.Error:
        return False


def return_freed_memory() -> None:
    """Hand the memory the process has freed back to the system (glibc's ``malloc_trim(0)``: it
    releases the free pages inside the heap too, not only at its top); no-op elsewhere. Freed
    factorizations otherwise stay in the heap: the plastic liner panel's time loop grew by
    ~2 MB of resident memory a tangent (coarse mesh)."""
    import ctypes

    try:
        ctypes.CDLL("libc.so.6").malloc_trim(0)
    except (OSError, AttributeError):
        pass


def create_factored_solver(A: PETSc.Mat, prefix: str, options: Mapping[str, object] | None = None) -> PETSc.KSP:
    """A set-up (for a direct solver: factored) KSP of ``A`` with options prefix ``prefix``:
    ``options`` (keys relative to the prefix) are defaults, the command line wins."""
    ksp = PETSc.KSP().create(A.getComm())
    ksp.setOptionsPrefix(prefix)
    ksp.setOperators(A)
    with petsc_options({}, options, prefix=prefix):
        ksp.setFromOptions()
        setup_checked(ksp, f"factorization {prefix}")
    return ksp


def solve_or_factorize(
    ksp: PETSc.KSP, A: PETSc.Mat, b: PETSc.Vec, x: PETSc.Vec, what: str, direct_prefix: str
) -> PETSc.KSP:
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


def solve_mass(
    M: PETSc.Mat,
    b: PETSc.Vec,
    x: PETSc.Vec,
    unit_rows: np.ndarray,
    options: Mapping[str, object] | None = None,
    defaults: Mapping[str, str] | None = None,
    cache: dict | None = None,
) -> None:
    """Solve ``M x = b`` with ``x = 0`` on ``unit_rows`` (local owned indices: clamped and
    massless dofs), prefix ``impact_mass_``, for the initial acceleration (m/s^2).

    ``defaults``: the solver's defaults (keys relative to ``-impact_mass_``; None:
    :func:`mass_solver_defaults`, Jacobi-CG). ``cache``: a dict (a system's ``operator_cache``)
    that keeps the solver that solved, with its matrix, for the next solve with the same M and
    unit rows (the impacts of a repeated-impact sequence each start from a residual state)."""
    rows = np.asarray(unit_rows, dtype=np.int64)
    key = ("initial_mass", M.handle, rows.tobytes())
    rhs = b.copy()
    rhs.array[rows] = 0.0
    if cache is not None and key in cache:
        ksp, _ = cache[key]
        solve_checked(ksp, rhs, x, "initial-acceleration mass solve", 0, 0.0)
        rhs.destroy()
        return
    rstart = M.getOwnershipRange()[0]
    Ms = M.copy()
    Ms.zeroRowsColumns(rows.astype(PETSc.IntType) + rstart, diag=1.0)
    ksp = PETSc.KSP().create(M.getComm())
    ksp.setOptionsPrefix(PREFIX + "mass_")
    ksp.setOperators(Ms)
    pre = "mass_"
    user = {k[len(pre) :]: v for k, v in normalize_options(options).items() if k.startswith(pre)}
    with petsc_options(dict(defaults) if defaults is not None else mass_solver_defaults(), user, PREFIX + pre):
        ksp.setFromOptions()
        ksp.setUp()
    ksp = solve_or_factorize(ksp, Ms, rhs, x, "initial-acceleration mass solve", PREFIX + "mass_direct_")
    rhs.destroy()
    if cache is not None:
        cache[key] = (ksp, Ms)
        return
    ksp.destroy()
    Ms.destroy()


# ----------------------------------------------------------------------------- eigenvalues
def estimate_max_eigenvalue(
    K: PETSc.Mat,
    m_lumped: PETSc.Vec,
    B: PETSc.Mat | None = None,
    k_p: float = 0.0,
    options: Mapping[str, object] | None = None,
) -> float:
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
    with petsc_options(
        {}, {k[4:]: v for k, v in normalize_options(options).items() if k.startswith("eps_")}, PREFIX + "eps_"
    ):
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


#: the PETSc option suffixes whose values name a type, with the names PETSc knows (petsc4py's
#: enumerations; the solver packages are those Debian's PETSc is built with)
_TYPE_OPTIONS = {
    "ksp_type": ("KSP", PETSc.KSP.Type),
    "pc_type": ("PC", PETSc.PC.Type),
    "pc_factor_mat_solver_type": ("factorization package", PETSc.Mat.SolverType),
}


def check_type_options(options: Mapping[str, object]) -> None:
    """Refuse a PETSc option that names an unknown KSP, PC or factorization package (one line naming
    the option, its value and the known names), or a block Krylov block size or a substructuring
    setting out of its range, before any work; PETSc itself would fail later with only an error number."""
    from ..errors import InputError

    for key, value in options.items():
        if str(key).endswith("block_krylov_size") and not str(value).strip().isdigit():
            raise InputError(
                f"-{key} {value}: the block Krylov eigensolver's block size must be an integer "
                ">= 0 (0: SLEPc's Krylov-Schur; default 32)"
            )
        if str(key).endswith("_substructures") and not str(value).strip().isdigit():
            raise InputError(
                f"-{key} {value}: the number of slabs must be an integer >= 0 "
                "(0 or 1: one factorization of the region; default 0)"
            )
        if str(key).endswith("_substructure_zone_degree") and not str(value).strip().isdigit():
            raise InputError(
                f"-{key} {value}: the zone-interface patterns' polynomial degree must be an integer "
                ">= 0 (0: every zone-interface coordinate its own constraint mode; default 0)"
            )
        for suffix, low, high, what in (
            ("substructure_f_factor", 1.0, math.inf, "slab modes up to this x f_cut; default 1.5"),
            (
                "substructure_trace_density",
                0.0,
                math.inf,
                "trace degrees per shear wavelength; 0: every interface dof; default 4",
            ),
            ("substructure_margin", 0.0, math.inf, "shear wavelengths at f_cut; default 0.5"),
            (
                "substructure_across",
                0.0,
                math.inf,
                "a slab over this x the mean slab is cut again across; 0: never; default 2",
            ),
            (
                "substructure_compress",
                0.0,
                1.0,
                "relative Gram eigenvalue of a dropped second-pass direction; 0: keep all; default 1e-12",
            ),
            ("substructure_eps_tol", 1e-15, 1.0, "the slabs' eigensolver tolerance, relative residual; default 1e-4"),
        ):
            if str(key).endswith(suffix):
                try:  # a value that is no number or numeric string (None, a list) is refused too
                    ok = isinstance(value, (int, float, str)) and low <= float(value) < high
                except ValueError:
                    ok = False
                if not ok:
                    rng = f">= {low:g}" if high == math.inf else f"in [{low:g}, {high:g})"
                    raise InputError(f"-{key} {value}: must be a number {rng} ({what})")
        for suffix, (what, enum) in _TYPE_OPTIONS.items():
            if key.endswith(suffix):
                known = sorted({str(getattr(enum, k)).lower() for k in dir(enum) if not k.startswith("_")})
                if str(value).lower() not in known:
                    raise InputError(f"-{key} {value}: unknown {what} type; PETSc knows: {', '.join(known)}")
