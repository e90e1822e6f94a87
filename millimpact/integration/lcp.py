"""The exact small LCP of a contact step: g = q + S lambda >= 0, lambda >= 0, lambda . g = 0 (S dense, symmetric
positive definite on the candidates), by a primal-dual active set with an NNLS fallback.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np

from ..errors import SolverError

log = logging.getLogger(__name__)


# ------------------------------------------------------------------------------------ the LCP
@dataclass
class LCPResult:
    """Solution of the contact LCP: multipliers (N), active set, semi-smooth Newton iterations."""

    lam: np.ndarray
    active: np.ndarray
    iterations: int
    method: str


def solve_lcp(
    S: np.ndarray, q: np.ndarray, active0: np.ndarray | None = None, gap_tol: float = 0.0, max_iter: int = 50
) -> LCPResult:
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
        raise SolverError(
            "contact Schur complement S_AA is not positive definite: dependent constraint "
            "rows in B (e.g. two rows on the same node and direction)"
        ) from e
