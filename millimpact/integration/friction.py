"""Coulomb friction of one implicit contact step: the small dense frictional contact problem.

Formulation (velocity-level Coulomb law, discretized per step, exact Lagrange multipliers, no
regularization). Each candidate slave node i has a normal multiplier lambda_i >= 0 (N) and a
tangential multiplier tau_i in R^2 (N, the tangential force on the ball in the face's basis
t1, t2). With the step's effective-matrix factorization, the end-of-step state is
``u = u_pred + W [lambda; tau]``, ``W = A^-1 C^T``, ``C = [B; T]``, so the gaps and the slip
increments over the step are affine in the multipliers::

    g  = q_n + S_nn lambda + S_nt tau        (m)
    ds = q_t + S_tn lambda + S_tt tau        (m; ds_i = T_i (u_{n+1} - u_n), q_t = T (u_pred - u_n))

with ``S = C A^-1 C^T`` (dense, replicated). The discrete law::

    normal:   g >= 0, lambda >= 0, lambda . g = 0;
    Coulomb:  |tau_i| <= mu lambda_i;  |tau_i| < mu lambda_i  =>  ds_i = 0 (stick);
              ds_i != 0  =>  tau_i = -mu lambda_i ds_i / |ds_i|  (slip opposes the ball's relative slip).

Solution: a fixed point on the slip bounds (normal/tangential alternation, as in Panagiotopoulos'
process): for the current tau solve the normal LCP exactly (:func:`millimpact.integration.solve_lcp`);
for the resulting bounds mu lambda solve the Tresca problem (fixed bounds) exactly by a semi-smooth
Newton method on the Alart-Curnier projection equation: a stick/slip active set (nodes inside their
friction disc stick, the others slide) with a consistent linearization of the slip direction, damped
by a line search; repeat until lambda and tau stop changing (relative 1e-8). For identical ball and
liner materials the normal-tangential coupling S_nt is small (Dundurs' beta = 0 for a half-space)
and the alternation converges in a few passes (measured: at most 7 on the liner scene). Should
Newton stall, the Tresca problem is finished by an accelerated projected gradient (FISTA with
restart) on ``min 1/2 tau.S_tt tau + c.tau, |tau_i| <= b_i``, which converges for any SPD S_tt.
mu = 0 gives tau = 0 and the frictionless solution. The alternation itself has no general
convergence proof (Coulomb friction is not a convex problem); a failure raises :class:`SolverError`.

Units: S in m/N, gaps and slips in m, multipliers in N.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import SolverError
from .lcp import solve_lcp

#: relative tolerance of the fixed point and the slip directions
FRICTION_RTOL = 1e-10
#: the alternation stops when two passes agree to this fraction of the largest normal force
PASS_RTOL = 1e2 * FRICTION_RTOL
#: outer (normal/tangential) passes allowed
MAX_OUTER = 100
#: semi-smooth Newton (stick/slip active set) iterations allowed before the projected-gradient fallback
MAX_ACTIVE_SET = 40


@dataclass
class FrictionResult:
    """Multipliers of one frictional contact step: ``lam`` (n_c, N), ``tau`` (2 n_c: [t1; t2], N),
    ``slip`` bool per node (True: sliding, False: sticking or open), passes and fallbacks."""

    lam: np.ndarray
    tau: np.ndarray
    slip: np.ndarray
    iterations: int
    n_fallback: int
    active: np.ndarray


def solve_tresca(
    S_tt: np.ndarray,
    c: np.ndarray,
    bound: np.ndarray,
    slip0: np.ndarray | None = None,
    free: np.ndarray | None = None,
    tau0: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray, bool]:
    """Tresca friction with fixed bounds: ``ds = c + S_tt tau``, ``|tau_i| <= bound_i``, stick
    (ds_i = 0) inside the disc, tau_i = -bound_i ds_i/|ds_i| on it. ``S_tt`` (2n x 2n, rows
    [t1 nodes; t2 nodes]), ``c`` (2n, m), ``bound`` (n, N). ``free`` (2n bool) marks the tangential
    components that can carry force (a component clamped on both sides, e.g. across a symmetry
    plane, has a zero row and carries none). ``tau0`` (2n, N): a starting guess (the previous pass of
    the normal/tangential alternation), projected onto the discs; zero if None. The problem has one
    solution (S_tt SPD), so the start changes the iterations, not the answer beyond the tolerance.
    Returns (tau, slip per node, converged by Newton).

    Semi-smooth Newton on ``F(tau) = tau - P(tau - r ds(tau)) = 0`` (P: projection of each node's
    force onto its disc; Alart-Curnier): the nodes inside their disc are the sticking set (rows
    ``r ds_i = 0``), those outside slide (rows ``tau_i = b_i z_i/|z_i|`` linearized in the slip
    direction), i.e. a stick/slip active set with a consistent update of the slip directions,
    damped by a backtracking line search on |F|. ``r`` per node is 1/trace of its S block.
    """
    n_all = bound.size
    free = np.ones(2 * n_all, dtype=bool) if free is None else np.asarray(free, dtype=bool)
    on_all = bound > 0.0
    if not (np.concatenate([on_all, on_all]) & free).any():
        return np.zeros(2 * n_all), np.zeros(n_all, dtype=bool), True
    # nodes without normal force carry no friction: the problem on the loaded nodes only, in
    # node-major order (tau_i = x[2i:2i+2]), taken from S_tt in one copy
    idx = np.flatnonzero(on_all)
    n = idx.size
    perm = np.ravel(np.column_stack([idx, n_all + idx]))
    S = S_tt[np.ix_(perm, perm)]
    cc = c[perm]
    bound = bound[idx]
    fixed = ~free[perm].reshape(n, 2)  # components held at zero
    d = np.diag(S).reshape(n, 2)
    tr = np.where(fixed, 0.0, d).sum(axis=1)
    r = np.where(tr > 0, 1.0 / np.where(tr > 0, tr, 1.0), 0.0)  # N/m
    scale = max(float(bound.max()), 1e-300)

    def residual(x: np.ndarray):
        ds = (cc + S @ x).reshape(n, 2)
        X = x.reshape(n, 2)
        z = X - r[:, None] * ds
        z[fixed] = 0.0
        nz = np.linalg.norm(z, axis=1)
        slide = nz > bound
        Pz = np.where(slide[:, None], z * (bound / np.where(nz > 0, nz, 1.0))[:, None], z)
        F = X - Pz
        F[fixed] = X[fixed]
        return F.ravel(), z, nz, slide

    x = np.zeros(2 * n)
    if tau0 is not None:
        X = np.where(fixed, 0.0, np.asarray(tau0, dtype=float)[perm].reshape(n, 2))
        nx = np.linalg.norm(X, axis=1)
        x = (X * np.where(nx > bound, bound / np.where(nx > 0, nx, 1.0), 1.0)[:, None]).ravel()
    F, z, nz, slide = residual(x)
    for _ in range(MAX_ACTIVE_SET):
        fn = float(np.max(np.abs(F)))
        if fn <= FRICTION_RTOL * scale:
            break
        J = _newton_matrix(S, r, z, nz, bound, slide, fixed)
        try:
            dx = np.linalg.solve(J, -F)
        except np.linalg.LinAlgError:
            break
        f0 = float(np.linalg.norm(F))
        alpha = 1.0
        for _ls in range(30):
            F1, z1, nz1, s1 = residual(x + alpha * dx)
            if np.linalg.norm(F1) <= (1.0 - 1e-4 * alpha) * f0:
                break
            alpha *= 0.5
        x = x + alpha * dx
        F, z, nz, slide = F1, z1, nz1, s1
    ok = float(np.max(np.abs(F))) <= FRICTION_RTOL * scale
    if not ok:  # finish with the (always convergent) accelerated projected gradient
        tau_nm = _tresca_fista(S, cc, bound, x, ~fixed.ravel())
        F, z, nz, slide = residual(tau_nm)
        x = tau_nm
    tau = np.zeros(2 * n_all)
    tau[perm] = x
    slip = np.zeros(n_all, dtype=bool)
    slip[idx] = slide
    return tau, slip, ok


def _newton_matrix(
    S: np.ndarray, r: np.ndarray, z: np.ndarray, nz: np.ndarray, bound: np.ndarray, slide: np.ndarray, fixed: np.ndarray
) -> np.ndarray:
    """The generalized Jacobian of ``F(x) = x - P(z(x))``, ``z = x - r ds(x)`` (node-major pairs):
    ``J = I - D_P dz/dx`` with ``dz_i/dx = E_i - r_i S_i`` (S_i: node i's two rows of S) and
    ``D_P,i`` the identity inside the disc (stick: J_i = r_i S_i) or, on it (slide),
    ``(b_i/|z_i|)(I - z^_i z^_i^T)``, z^ = z/|z|. Rows of components held at zero are unit rows."""
    n = bound.size
    DP = np.broadcast_to(np.eye(2), (n, 2, 2)).copy()
    if slide.any():
        zh = z[slide] / nz[slide, None]
        DP[slide] = (bound[slide] / nz[slide])[:, None, None] * (np.eye(2) - zh[:, :, None] * zh[:, None, :])
    # J = I - D_P (E - r S) = r D_P S + blockdiag(I - D_P): two arrays of (2n)^2, not five
    J = np.einsum("nab,nbk->nak", r[:, None, None] * DP, S.reshape(n, 2, 2 * n)).reshape(2 * n, 2 * n)
    J.reshape(n, 2, n, 2)[np.arange(n), :, np.arange(n), :] += np.eye(2) - DP  # the diagonal blocks
    rows = np.flatnonzero(fixed.ravel())
    J[rows, :] = 0.0
    J[rows, rows] = 1.0
    return J


def _tresca_fista(
    S: np.ndarray, c: np.ndarray, bound: np.ndarray, x0: np.ndarray, free: np.ndarray, max_iter: int = 20000
) -> np.ndarray:
    """min 1/2 x.S x + c.x over |x_i| <= bound_i (discs of node-major pairs x[2i:2i+2]), x = 0 off
    ``free``: FISTA with adaptive restart (O'Donoghue, Candes 2015), step 1/L, L = lambda_max(S)."""
    n = bound.size

    def project(x: np.ndarray) -> np.ndarray:
        v = np.where(free, x, 0.0).reshape(n, 2)
        r = np.linalg.norm(v, axis=1)
        f = np.where(r > bound, bound / np.where(r > 0, r, 1.0), 1.0)
        return (v * f[:, None]).ravel()

    L = float(np.linalg.eigvalsh(S)[-1])
    if L <= 0:
        return np.zeros_like(x0)
    x = project(x0)
    y, t = x.copy(), 1.0
    scale = max(float(bound.max()), 1e-300)
    for _ in range(max_iter):
        x_new = project(y - (S @ y + c) / L)
        if (x_new - x) @ (S @ x_new + c) > 0:  # restart when the objective goes up
            t, y = 1.0, x.copy()
            continue
        t_new = 0.5 * (1.0 + np.sqrt(1.0 + 4.0 * t * t))
        y = x_new + (t - 1.0) / t_new * (x_new - x)
        if np.max(np.abs(x_new - x)) <= FRICTION_RTOL * scale:
            return x_new
        x, t = x_new, t_new
    return x


def solve_friction(
    S: np.ndarray,
    q_n: np.ndarray,
    q_t: np.ndarray,
    mu: float,
    active0: np.ndarray | None = None,
    slip0: np.ndarray | None = None,
    gap_tol: float = 0.0,
    tau0: np.ndarray | None = None,
    rtol: float = PASS_RTOL,
) -> FrictionResult:
    """The frictional contact problem of one step (module docstring). ``S`` (3 n_c)^2 with rows
    [normal; t1; t2], ``q_n`` predicted gaps (m), ``q_t`` predicted slip increments (m, [t1; t2]),
    ``mu`` >= 0. Warm starts: ``active0`` (normal active set) and ``slip0`` (sliding nodes) of the
    previous step, ``tau0`` its tangential forces (the first pass's LCP and Tresca start from them:
    a Newton iteration of a yielding step solves a problem close to the last one; coarse liner
    panel 8714 -> 4416 Tresca solves, friction 5.1 -> 1.8 s; F_max, e and the plastic work moved
    by 2e-10, 5e-10, 7e-10: the fixed point's tolerance). ``rtol``: the alternation stops when a
    pass changes lambda and tau by at most rtol max(lambda) (PASS_RTOL; a plastic step's early
    iterations take a looser one: :mod:`.plastic_newmark`). Raises :class:`SolverError` if the
    fixed point does not converge."""
    n = q_n.size
    S_nn, S_nt = S[:n, :n], S[:n, n:]
    S_tn, S_tt = S[n:, :n], S[n:, n:]
    diag = np.diag(S_tt)
    free = diag > 1e-12 * max(float(np.max(np.abs(np.diag(S_nn)))), 1e-300)
    tau = np.zeros(2 * n) if tau0 is None or mu == 0.0 else np.asarray(tau0, dtype=float).copy()
    lam = np.zeros(n)
    active = active0
    slip = slip0
    n_fallback = 0
    for it in range(1, MAX_OUTER + 1):
        res = solve_lcp(S_nn, q_n + S_nt @ tau, active, gap_tol)
        lam_new = res.lam
        active = res.active
        if mu > 0.0:
            tau_new, slip, ok = solve_tresca(S_tt, q_t + S_tn @ lam_new, mu * lam_new, slip, free, tau)
            n_fallback += not ok
        else:
            tau_new, slip = np.zeros(2 * n), np.zeros(n, dtype=bool)
        scale = max(float(np.max(np.abs(lam_new), initial=0.0)), 1e-300)
        done = (
            np.max(np.abs(lam_new - lam), initial=0.0) <= rtol * scale
            and np.max(np.abs(tau_new - tau), initial=0.0) <= rtol * scale
        )
        lam, tau = lam_new, tau_new
        if done:
            return FrictionResult(lam, tau, slip, it, n_fallback, active)
    raise SolverError(
        f"Coulomb friction: the normal/tangential fixed point did not converge in {MAX_OUTER} "
        f"passes (mu = {mu:g}; a large mu with dissimilar materials couples them strongly)"
    )
