"""The dense Rayleigh-Ritz of a body's interior in the span of a Ritz basis V (the slab-wise
reduction's step 3, :mod:`.substructures`): the Craig-Bampton statics, modes and residual
flexibility from K_V = V^T K_ii V, M_V = V^T M_ii V and V^T [C | D], with V's dependent columns
dropped. Only the modes under the cutoff are computed; everything else comes from a Cholesky
factor of K in an M-orthonormal basis (:func:`rayleigh_ritz`)."""

from __future__ import annotations

import math

import numpy as np
import scipy.linalg as sla

from .distributed import DEPENDENT_TOL, gram_basis


def rayleigh_ritz(KV: np.ndarray, MV: np.ndarray, CV: np.ndarray, n_b: int, f_cut: float) -> dict:
    """The Craig-Bampton of the interior in span(V), in an M_V-orthonormal basis W (dependent
    directions dropped): psi (K_V psi = -V^T C), the Ritz modes phi under f_cut and their
    frequencies (with the next one), and R A_b's coefficients (the residual flexibility from the
    Ritz modes above the cutoff applied to V^T A_b = M_V psi + V^T D).

    With K_W = W^T K_V W (positive definite: the interior is held) factored by Cholesky,
    K_V^+ X = W K_W^-1 W^T X; the statics psi = -K_V^+ V^T C and R A_b = K_V^+ (I - M_V phi
    phi^T) A_b (mode acceleration's residual flexibility; Craig and Kurdila, Fundamentals of
    Structural Dynamics, 2nd ed., 2006) need only the Cholesky factor and the modes under the
    cutoff, so only those eigenpairs of K_W are computed (LAPACK's MRRR on a window of the
    spectrum, :func:`lowest_eigenpairs`). The liner panel's final Ritz (4,368 columns, 157 modes;
    its K_V, M_V, C_V saved and solved again, one process, 2 threads): 54-61 s with every
    eigenpair, 37-42 s so; psi within 4e-12, R A_b 2.5e-11, the frequencies 1.4e-11."""
    # columns scaled to unit M_V-norm first: the statics are ~1/omega^2 smaller than the M-normalized
    # modes, and an unscaled Gram matrix would drop them as "dependent" (1e-20 against 1)
    W = gram_basis(MV, DEPENDENT_TOL)
    KW = W.T @ (KV @ W)
    KW += KW.T
    KW *= 0.5
    lam_cut = (2 * math.pi * f_cut) ** 2
    lam, Y = lowest_eigenpairs(KW, lam_cut)
    chol = sla.cho_factor(KW, lower=True, overwrite_a=True, check_finite=False)  # KW's storage
    solve = _ritz_solver(W, chol)
    m = int(np.searchsorted(lam, lam_cut, side="right"))
    phi = W @ Y[:, :m]
    psi = -solve(CV[:, :n_b])
    Ab = MV @ psi + CV[:, n_b:]
    # the modes under the cutoff taken out of the load before the solve, not from its result: their
    # 1/lambda-amplified part would cancel there (liner panel: 1.1e-8 against 2.5e-11 of R A_b,
    # relative to the full eigendecomposition)
    flex = solve(Ab - MV @ (phi @ (phi.T @ Ab)))
    return {
        "psi": psi,
        "phi": phi,
        "flex": flex,
        "m": m,
        "rank": int(W.shape[1]),
        "freq": np.sqrt(np.maximum(lam, 0.0)) / (2 * math.pi),
        "solve": solve,
    }


def _ritz_solver(W: np.ndarray, chol: tuple):
    """X -> K_V^+ X = W K_W^-1 W^T X with K_W's Cholesky factor ``chol`` (scipy's cho_factor)."""
    return lambda X: W @ sla.cho_solve(chol, W.T @ X)


#: the first eigenvalue window of :func:`lowest_eigenpairs`, over the cutoff: (1.2 f_cut)^2
WINDOW = 1.44


def lowest_eigenpairs(A: np.ndarray, lam_cut: float) -> tuple[np.ndarray, np.ndarray]:
    """The eigenpairs of the symmetric ``A`` up to ``lam_cut`` and at least the next one (all when
    there are fewer), ascending: LAPACK's dsyevr on the window (-inf, WINDOW lam_cut], widened 4x
    while no eigenvalue falls above lam_cut in it (each widening one more tridiagonalization)."""
    n = len(A)
    hi = WINDOW * lam_cut
    while True:
        lam, Y = sla.eigh(A, subset_by_value=(-np.inf, hi), driver="evr")
        if len(lam) == n or (len(lam) and lam[-1] > lam_cut):
            return lam, Y
        if not np.isfinite(hi) or hi <= 0:
            return sla.eigh(A, driver="evr")
        hi *= 4.0
