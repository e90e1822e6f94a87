"""Eigen solves of the reduction: the lowest fixed-interface modes K_ii phi = omega^2 M_ii phi (SLEPc, generalized
Hermitian, shift-and-invert at 0 with the interior's Cholesky factorization; a dense LAPACK solve when most
modes are asked), and the default solver options (prefix ``impact_reduction_<body>_``).

With a cutoff, a first small round of Krylov-Schur (FIRST_NEV modes) serves the bodies with few
modes; a body with more under the cutoff has them counted by the inertia of K_ii - lambda_cut M_ii
(Sylvester's law, :func:`count_below`) and found, with the next one, by the block Krylov solver of
:mod:`.block_krylov` (multi-right-hand-side solves: the liner panel's 164-170 modes; option
``block_krylov_size``, 0 for one more round of Krylov-Schur, the fallback). The substructured
reduction's slabs count first (``count_first``): most have no mode under the cutoff or more than
the first round's, and the count alone settles the first (liner panel: the first pass's slabs
146 -> 117 s on the busier rank, docs: plasticity).
"""

from __future__ import annotations

import logging
import math

import numpy as np
from petsc4py import PETSc
from slepc4py import SLEPc

from ..errors import SolverError
from ..integration.solvers import petsc_options
from .block_krylov import BLOCK_SIZE, block_krylov_modes

log = logging.getLogger(__name__)


#: first number of modes asked from the eigensolver when only a cutoff is given (then the inertia
#: count, or doubled until the cutoff is passed; the previous vectors seed the next round). The
#: default scene keeps 3 ball and 7 block modes: 8 asked first cost 1 s less CPU than 16 (the
#: Krylov space is ~2 nev vectors, each a solve with the interior's factorization)
FIRST_NEV = 8
#: when the first round falls short of the cutoff, the count of modes under it comes from an inertia
#: (:func:`count_below`) for bodies above this many interior dofs; smaller ones double nev
INERTIA_MIN_DOFS = 5000
#: a dense eigensolver (LAPACK) takes over when this share of all interior modes is requested
DENSE_EIGEN_SHARE = 0.5


def default_solver_options(comm_size: int) -> dict[str, str]:
    """Fresh default PETSc/SLEPc options, relative to ``impact_reduction_<body>_``.

    A Cholesky factorization (the same factorization serves the constraint modes' multi-right-
    hand-side solve and the shift-and-invert eigensolver): CHOLMOD in serial,
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


# --- eigenmodes ----------------------------------------------------------------------------------
def sorted_eigenpairs(
    eps, A: PETSc.Mat, count: int | None = None, keep_ksp: bool = False
) -> tuple[np.ndarray, list[PETSc.Vec]]:
    """The converged eigenvalues of a solved EPS (real parts, ascending) and the eigenvectors of
    the lowest ``count`` of them (all if None; Vecs laid out like A's columns); destroys the EPS.
    (Krylov-Schur converges more pairs than asked, and each eigenvector costs a B-normalization:
    979 of them took 3.4 s of a liner-panel reduction.) ``keep_ksp``: the caller's KSP of the
    spectral transformation keeps its factorization (destroying the EPS resets the ST's KSP, and
    the reduction's output rows factored K_ii again: 0.4 s on the coarse panel, 6.5 s at 157k dofs)."""
    nconv = eps.getConverged()
    lam = np.array([eps.getEigenvalue(i).real for i in range(nconv)])
    order = np.argsort(lam)
    vecs = []
    for i in order[:count]:
        v = A.createVecRight()
        eps.getEigenvector(int(i), v)
        vecs.append(v)
    if keep_ksp:
        spare = PETSc.KSP().create(A.getComm())
        eps.getST().setKSP(spare)  # the reset on destroy hits this one
        spare.destroy()
    eps.destroy()
    return lam[order], vecs


def count_below(
    K: PETSc.Mat, M: PETSc.Mat, lam: float, prefix: str, options: dict[str, str] | None = None
) -> int | None:
    """The number of eigenvalues of K phi = lambda M phi below ``lam``: Sylvester's law of inertia,
    the count of negative pivots of the LDL^T factorization of K - lam M (M positive definite;
    Parlett, The Symmetric Eigenvalue Problem, 1998, section 3.3; SLEPc's spectrum slicing uses the
    same count). One extra factorization (MUMPS, prefix ``<prefix>inertia_``) replaces the rounds
    of a growing eigensolve: on the coarse liner panel (26.6k interior dofs, 164 modes under
    f_cut) the doubling 8, 16, ..., 256 took 46 s. None if the factorization gives no inertia.
    """
    A = K.duplicate(copy=True)
    ksp = None
    try:
        A.axpy(-lam, M, PETSc.Mat.Structure.SUBSET_NONZERO_PATTERN)  # M's pattern is in K's (as free_modes)
        A.setOption(PETSc.Mat.Option.SPD, False)
        A.setOption(PETSc.Mat.Option.SYMMETRIC, True)
        ksp = PETSc.KSP().create(K.getComm())
        ksp.setOptionsPrefix(prefix + "inertia_")
        ksp.setOperators(A)
        defaults = {
            "ksp_type": "preonly",
            "pc_type": "cholesky",
            "pc_factor_mat_solver_type": "mumps",
            # MUMPS: no ScaLAPACK root node, whose factorization gives no inertia, and null
            # pivot detection, without which PETSc 3.18 refuses MatGetInertia (SLEPc manual,
            # spectrum slicing)
            "mat_mumps_icntl_13": "1",
            "mat_mumps_icntl_24": "1",
        }
        user = {k[len("inertia_") :]: v for k, v in (options or {}).items() if k.startswith("inertia_")}
        with petsc_options(defaults, user, prefix=prefix + "inertia_"):
            ksp.setFromOptions()
            ksp.setUp()
        neg, zero, _ = ksp.getPC().getFactorMatrix().getInertia()
        if zero:
            return None
        return int(neg)
    except PETSc.Error as exc:
        log.info("eigensolver %s: no inertia count (%s); growing the solve instead", prefix, exc)
        return None
    finally:
        if ksp is not None:
            ksp.destroy()
        A.destroy()


def compute_modes(
    K_ii: PETSc.Mat,
    M_ii: PETSc.Mat,
    ksp: PETSc.KSP,
    f_cut: float | None,
    n_modes: int | None,
    prefix: str,
    options: dict[str, str] | None = None,
    count_first: bool = False,
) -> tuple[np.ndarray, list[PETSc.Vec], float]:
    """Lowest modes of K_ii phi = omega^2 M_ii phi (GHEP): all up to ``f_cut`` (Hz), or the
    lowest ``n_modes``. Shift-and-invert at 0 with the already factored ``ksp`` (K_ii).

    Returns (frequencies in Hz ascending, M-orthonormal eigenvectors, the next frequency not kept
    or nan). A dense LAPACK solver takes over when most of the spectrum is requested.
    ``count_first`` (with a cutoff, above INERTIA_MIN_DOFS): the inertia count before any
    Krylov-Schur round, for bodies that mostly have none or many modes under the cutoff (the
    substructured reduction's slabs); no mode under it returns at once, the next frequency nan.
    """
    n = K_ii.getSize()[0]
    if n == 0 or n_modes == 0:
        return np.zeros(0), [], math.nan
    lam_cut = (2 * math.pi * f_cut) ** 2 if f_cut is not None else math.inf
    nev = min(n_modes, n) if n_modes is not None else min(FIRST_NEV, n)
    counted = False
    prev: list[PETSc.Vec] = []
    if count_first and n_modes is None and f_cut is not None and n > INERTIA_MIN_DOFS:
        below = count_below(K_ii, M_ii, lam_cut, prefix, options)
        counted = True
        if below == 0:
            return np.zeros(0), [], math.nan
        if below is not None and below < FIRST_NEV:
            nev = min(below + 1, n)  # one Krylov-Schur round (the liner panel's 6-mode slab: block
        elif below is not None:  # Krylov 16.5 s against 8.8 s for the round of 8)
            found = block_modes_under_cutoff(K_ii, M_ii, ksp, lam_cut, below, prefix, options)
            if found is not None:
                return found
            nev = min(max(below + 1 + max(2, below // 50), nev), n)
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
            # no purification (one more shift-and-invert solve per converged eigenvector, for a
            # singular M): M_ii is positive definite. Coarse panel, 164 modes: 2.8 s of ~13 s saved;
            # the vectors' relative residual 7e-12 -> 3e-10 (-eps_purify 1 restores it)
            eps.setPurify(False)
            if prev:
                eps.setInitialSpace(prev)
            with petsc_options({}, {k: v for k, v in (options or {}).items() if k.startswith("eps_")}, prefix=prefix):
                eps.setFromOptions()
        eps.solve()
        nconv = eps.getConverged()
        if nconv < min(nev, n):
            raise SolverError(
                f"eigensolver ({prefix}): {nconv} of {nev} modes converged, reason {eps.getConvergedReason()}"
            )
        # vectors for the lowest nev only: the next round's start, or those kept (when done, the
        # kept ones are among them: lam[nev - 1] > lam_cut, or exactly n_modes)
        lam, vecs = sorted_eigenpairs(eps, K_ii, None if dense or nconv >= n else nev, keep_ksp=not dense)
        if not dense:
            st.destroy()  # the Python handle alone keeps it, and with it the caller's factorization (see
            # integration.solvers.destroy_petsc_tree)
        done = n_modes is not None or dense or nconv >= n or lam[min(nev, len(lam)) - 1] > lam_cut
        if done:
            break
        for v in prev:
            v.destroy()
        prev = vecs[:nev]
        below = None if counted or n <= INERTIA_MIN_DOFS else count_below(K_ii, M_ii, lam_cut, prefix, options)
        counted = True
        if below is not None:
            found = block_modes_under_cutoff(K_ii, M_ii, ksp, lam_cut, below, prefix, options)
            if found is not None:
                for v in prev:
                    v.destroy()
                return found
            # every mode under the cutoff and the next one (its frequency is reported): one more round
            nev = min(max(below + 1 + max(2, below // 50), nev + 1), n)
            log.info("eigensolver %s: %d modes under f_cut (inertia), asking %d", prefix, below, nev)
        else:
            nev = min(2 * nev, n)
    if n_modes is not None:
        keep = min(n_modes, len(lam))
    else:
        keep = int(np.searchsorted(lam, lam_cut, side="right"))
    freq = frequencies_hz(lam)
    nxt = float(freq[keep]) if keep < len(freq) else math.nan
    for v in vecs[keep:]:
        v.destroy()
    return freq[:keep], vecs[:keep], nxt


def block_modes_under_cutoff(
    K_ii: PETSc.Mat,
    M_ii: PETSc.Mat,
    ksp: PETSc.KSP,
    lam_cut: float,
    below: int,
    prefix: str,
    options: dict[str, str] | None,
) -> tuple[np.ndarray, list[PETSc.Vec], float] | None:
    """The ``below`` modes under lam_cut (rad^2/s^2; the count from the inertia) and the next
    frequency by the block Krylov solver; None (the caller runs Krylov-Schur) when the option
    ``<prefix>block_krylov_size`` is 0, most of the spectrum is asked, or the block solver does not
    converge within its basis or finds another count."""
    options = options or {}
    with petsc_options({}, {k: v for k, v in options.items() if k in ("block_krylov_size", "eps_tol")}, prefix=prefix):
        db = PETSc.Options()
        block = db.getInt(prefix + "block_krylov_size", BLOCK_SIZE)
        tol = db.getReal(prefix + "eps_tol", 1e-10)
    n = K_ii.getSize()[0]
    if block <= 0 or below + 1 >= DENSE_EIGEN_SHARE * n:
        return None
    found = block_krylov_modes(K_ii, M_ii, ksp.getPC().getFactorMatrix(), below + 1, block=block, tol=tol)
    if found is None:
        log.info("eigensolver %s: block Krylov unconverged; Krylov-Schur instead", prefix)
        return None
    lam, vecs, stats = found
    found_below = int(np.searchsorted(lam, lam_cut, side="right"))
    if found_below != below:
        # a mode missed or one above the cut in the lowest below + 1: leave it to Krylov-Schur
        log.info(
            "eigensolver %s: block Krylov found %d modes under f_cut, the inertia %d; Krylov-Schur instead",
            prefix,
            found_below,
            below,
        )
        for v in vecs:
            v.destroy()
        return None
    log.info(
        "eigensolver %s: %d modes under f_cut (inertia) by block Krylov, basis %d in blocks of %d, "
        "%.3g s (solves %.3g s, the rest the products with M and the orthogonalization)",
        prefix,
        below,
        stats["basis"],
        block,
        stats["total_s"],
        stats["solve_s"],
    )
    freq = frequencies_hz(lam)
    vecs[below].destroy()
    return freq[:below], vecs[:below], float(freq[below])


def frequencies_hz(lam: np.ndarray) -> np.ndarray:
    """Natural frequencies (Hz) of the eigenvalues lam = omega^2 (round-off negatives as 0)."""
    return np.sqrt(np.maximum(lam, 0.0)) / (2 * math.pi)


def small_ghep(A: np.ndarray, B: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Eigenpairs of the small symmetric-definite problem A q = lam B q (ascending, B-orthonormal)."""
    L = np.linalg.cholesky(B)
    Linv = np.linalg.inv(L)
    lam, W = np.linalg.eigh(Linv @ A @ Linv.T)
    return lam, Linv.T @ W
