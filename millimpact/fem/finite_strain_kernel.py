"""A compiled pass over a finite-strain zone: deformation gradient, log strain, return map, P1, force.

:class:`millimpact.fem.finite_zone.FiniteStrainZone` maps every zone point at every iteration of a
step (its correction carries the geometric nonlinearity wherever Grad u is not zero). In numpy that
was a batched ``eigh`` and a dozen batched 3 x 3 products per point plus an FFCx expression and an
FFCx assembly: ~145 ms per 40,000 points, most of a finite-strain impact's time. Here one C loop
does per point what :mod:`millimpact.fem.finite_strain` does (the same equations):

    F = I + Grad u,   D = C - I = Grad u + Grad u^T + Grad u^T Grad u = sum_a mu_a N_a (x) N_a,
    E = sum_a 1/2 ln(1 + mu_a) N_a (x) N_a,          radial return of E - E_p,n  (T, d E_p, d alpha)
    S~_ab = 2 theta_ab T~_ab,  P1 = F S,             f_a += w |det J| (P1 - C : sym Grad u) Grad N_a

with the eigenpairs of D by cyclic Jacobi rotations (Golub and Van Loan, Matrix Computations,
4th ed., section 8.5: quadratically convergent; the sweeps stop when the off-diagonal's square sum
is below 1e-32 of the diagonal's) and the radial return of :mod:`.return_map_kernel` (one C
function for both). Decomposing D = C - I rather than C keeps the small strains' digits
(1 + mu loses those of mu below 1e-16; ln(1 + mu) is ``log1p``), so the kernel is, if anything,
more accurate than numpy's ``eigh`` of C at strains near round-off; the two agree to 1e-9 of the
force's largest entry at the strains of an impact (tests/fem/test_finite_strain_kernel.py).

Per point the trial state (T, d E_p, d alpha, yielding) is kept, as the numpy path's
:class:`.plasticity.ReturnMapResult`; a point is counted nonlinear where it yields or its
largest |Grad u| component passes ``floor`` (:data:`.finite_zone.GEOMETRIC_FLOOR`). A point with
det F <= 0 (or a 1 + mu_a not positive) stops the pass with its index, for the caller's
:class:`millimpact.errors.SolverError`. Compiled with cffi as the small-strain pass
(:func:`.return_map_kernel.load_compiled`); without a C compiler the zone keeps numpy.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from ..errors import SolverError
from .plasticity import CONSISTENCY_MAX_ITERATIONS, CONSISTENCY_RTOL, PlasticityError, ReturnMapResult
from .return_map_kernel import KERNEL_HELPERS_C, CompiledPass, ZoneKernelData, load_compiled, pointer, rate_terms

_CDEF = """
int finite_zone_force(int n_pos, const int *pos, int n_nodes, int n_q, const double *ref_grad,
                      const double *weights, const int *dofs, const double *jinv, const double *det,
                      const double *u, const double *eps_p, const double *alpha,
                      double G, double K, int n_pts, const double *a, const double *s, const double *k,
                      double rate_c, double rate_dg0, double tol, int max_it, double floor, double *f,
                      double *stress_out, double *deps_out, double *dg_out, unsigned char *yield_out,
                      long *failed);
"""

_SOURCE = (
    KERNEL_HELPERS_C
    + r"""
/* Eigenpairs of a symmetric 3 x 3 A (destroyed) by cyclic Jacobi rotations: w the eigenvalues,
   the columns of V the eigenvectors (Golub and Van Loan 8.5.2, the rotation of Numerical Recipes'
   jacobi) */
static void sym_eig3(double A[3][3], double w[3], double V[3][3])
{
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++) V[i][j] = (i == j);
    for (int sweep = 0; sweep < 50; sweep++) {
        const double off = A[0][1] * A[0][1] + A[0][2] * A[0][2] + A[1][2] * A[1][2];
        const double dia = A[0][0] * A[0][0] + A[1][1] * A[1][1] + A[2][2] * A[2][2];
        if (off == 0.0 || off <= 1e-32 * dia) break;
        for (int p = 0; p < 2; p++)
            for (int q = p + 1; q < 3; q++) {
                const double apq = A[p][q];
                if (apq == 0.0) continue;
                const double theta = (A[q][q] - A[p][p]) / (2.0 * apq);
                const double t = (theta >= 0.0 ? 1.0 : -1.0) / (fabs(theta) + sqrt(theta * theta + 1.0));
                const double c = 1.0 / sqrt(t * t + 1.0), sn = t * c;
                for (int r = 0; r < 3; r++) {
                    const double arp = A[r][p], arq = A[r][q];
                    A[r][p] = c * arp - sn * arq;
                    A[r][q] = sn * arp + c * arq;
                }
                for (int r = 0; r < 3; r++) {
                    const double apr = A[p][r], aqr = A[q][r];
                    A[p][r] = c * apr - sn * aqr;
                    A[q][r] = sn * apr + c * aqr;
                }
                for (int r = 0; r < 3; r++) {
                    const double vrp = V[r][p], vrq = V[r][q];
                    V[r][p] = c * vrp - sn * vrq;
                    V[r][q] = sn * vrp + c * vrq;
                }
            }
    }
    for (int i = 0; i < 3; i++) w[i] = A[i][i];
}

/* theta_ab = (ln l_a - ln l_b) / (2 (l_a - l_b)), l = 1 + mu, the limit 1 / (2 l_b) where the
   relative difference x is below 1e-5 (the series of ln(1 + x) / x, finite_strain.py) */
static double theta(double ma, double mb)
{
    const double lb = 1.0 + mb, x = (ma - mb) / lb;
    const double ratio = fabs(x) < 1e-5 ? 1.0 - x / 2.0 + x * x / 3.0 : log1p(x) / x;
    return 0.5 * ratio / lb;
}

/* The finite-strain pass over the zone's cells at positions pos (as zone_force's arguments; floor
   the |Grad u| above which a point counts as nonlinear). The trial state per point (ip * n_q + q)
   is written when stress_out is not NULL: T (6, Mandel), d E_p (6), d alpha, whether it yields.
   Returns the number of nonlinear points; -1 with failed[0] = 1 (consistency) or 2 (det F <= 0)
   and failed[1] the point. f is added to. */
int finite_zone_force(int n_pos, const int *pos, int n_nodes, int n_q, const double *ref_grad,
                      const double *weights, const int *dofs, const double *jinv, const double *det,
                      const double *u, const double *eps_p, const double *alpha,
                      double G, double K, int n_pts, const double *a, const double *s, const double *k,
                      double rate_c, double rate_dg0, double tol, int max_it, double floor, double *f,
                      double *stress_out, double *deps_out, double *dg_out, unsigned char *yield_out,
                      long *failed)
{
    const double s2 = sqrt(2.0);
    int n_active = 0;
    double ue[64][3];
    for (int ip = 0; ip < n_pos; ip++) {
        const int c = pos[ip];
        const int *cd = dofs + (long)c * n_nodes;
        const double *Ji = jinv + 9L * c;
        for (int n = 0; n < n_nodes; n++)
            for (int i = 0; i < 3; i++) ue[n][i] = u[3L * cd[n] + i];
        for (int q = 0; q < n_q; q++) {
            const long p = (long)c * n_q + q;
            const long o = (long)ip * n_q + q;
            const double *rq = ref_grad + (long)q * n_nodes * 3;
            double g[3][3], D[3][3], mu[3], N[3][3];
            point_grad(n_nodes, ue, rq, Ji, g);
            double gmax = 0.0;
            for (int i = 0; i < 3; i++)
                for (int j = 0; j < 3; j++) {
                    if (fabs(g[i][j]) > gmax) gmax = fabs(g[i][j]);
                    double gtg = 0.0;
                    for (int m = 0; m < 3; m++) gtg += g[m][i] * g[m][j];
                    D[i][j] = g[i][j] + g[j][i] + gtg;
                }
            /* det F = det(I + g) > 0: an element not turned inside out (C = F^T F cannot tell) */
            const double detF = (1.0 + g[0][0]) * ((1.0 + g[1][1]) * (1.0 + g[2][2]) - g[1][2] * g[2][1])
                              - g[0][1] * (g[1][0] * (1.0 + g[2][2]) - g[1][2] * g[2][0])
                              + g[0][2] * (g[1][0] * g[2][1] - (1.0 + g[1][1]) * g[2][0]);
            if (!(gmax < INFINITY) || !(detF > 0.0)) { failed[0] = 2; failed[1] = p; return -1; }
            sym_eig3(D, mu, N);
            double h[3];
            for (int a_ = 0; a_ < 3; a_++) {
                if (!(1.0 + mu[a_] > 0.0)) { failed[0] = 2; failed[1] = p; return -1; }
                h[a_] = 0.5 * log1p(mu[a_]);
            }
            double E[3][3];
            for (int i = 0; i < 3; i++)
                for (int j = 0; j < 3; j++) E[i][j] = N[i][0] * h[0] * N[j][0] + N[i][1] * h[1] * N[j][1] + N[i][2] * h[2] * N[j][2];
            const double *ep = eps_p + 6 * p;
            double e[6] = {E[0][0] - ep[0], E[1][1] - ep[1], E[2][2] - ep[2],
                           s2 * E[1][2] - ep[3], s2 * E[0][2] - ep[4], s2 * E[0][1] - ep[5]};
            double sig[6], d[6], dg;
            const int r = radial_return(e, alpha[p], G, K, n_pts, a, s, k, rate_c, rate_dg0, tol, max_it, sig, d, &dg);
            if (r < 0) { failed[0] = 1; failed[1] = p; return -1; }
            double t6[6];
            for (int i = 0; i < 6; i++) t6[i] = sig[i] - 2.0 * G * d[i];
            if (stress_out) {
                for (int i = 0; i < 6; i++) { stress_out[6 * o + i] = t6[i]; deps_out[6 * o + i] = d[i]; }
                dg_out[o] = dg;
                yield_out[o] = (unsigned char)r;
            }
            n_active += r == 1 || gmax > floor;
            const double T[3][3] = {{t6[0], t6[5] / s2, t6[4] / s2},
                                    {t6[5] / s2, t6[1], t6[3] / s2},
                                    {t6[4] / s2, t6[3] / s2, t6[2]}};
            /* S = N (2 theta o (N^T T N)) N^T */
            double TN[3][3], St[3][3], SN[3][3], S[3][3];
            for (int i = 0; i < 3; i++)
                for (int b = 0; b < 3; b++) TN[i][b] = T[i][0] * N[0][b] + T[i][1] * N[1][b] + T[i][2] * N[2][b];
            for (int a_ = 0; a_ < 3; a_++)
                for (int b = 0; b < 3; b++)
                    St[a_][b] = 2.0 * theta(mu[a_], mu[b]) * (N[0][a_] * TN[0][b] + N[1][a_] * TN[1][b] + N[2][a_] * TN[2][b]);
            for (int i = 0; i < 3; i++)
                for (int b = 0; b < 3; b++) SN[i][b] = N[i][0] * St[0][b] + N[i][1] * St[1][b] + N[i][2] * St[2][b];
            for (int i = 0; i < 3; i++)
                for (int j = 0; j < 3; j++) S[i][j] = SN[i][0] * N[j][0] + SN[i][1] * N[j][1] + SN[i][2] * N[j][2];
            /* P1 - C : sym(Grad u) */
            const double tr = g[0][0] + g[1][1] + g[2][2];
            double Pc[3][3];
            for (int i = 0; i < 3; i++)
                for (int j = 0; j < 3; j++) {
                    const double P = S[i][j] + g[i][0] * S[0][j] + g[i][1] * S[1][j] + g[i][2] * S[2][j];
                    const double lin = G * (g[i][j] + g[j][i]) + (i == j ? (K - 2.0 * G / 3.0) * tr : 0.0);
                    Pc[i][j] = P - lin;
                }
            add_point_force(n_nodes, cd, rq, Ji, weights[q] * det[c], Pc, f);
        }
    }
    return n_active;
}
"""
)


def load_finite_kernel():
    """The compiled finite-strain pass (``lib.finite_zone_force``), or None (no C compiler)."""
    return load_compiled("finite_zone_force", _CDEF, _SOURCE)


class FiniteStrainPass(CompiledPass):
    """The finite-strain kernel bound to a zone's bodies (cell data, J2 material, flow table per
    body), for :meth:`.finite_zone.FiniteStrainZone.evaluate` without the tangent."""

    @classmethod
    def build(cls, V, cells: Sequence[np.ndarray], materials: Sequence, q_degree: int) -> FiniteStrainPass | None:
        module = load_finite_kernel() if ZoneKernelData.supports(V) else None
        return None if module is None else cls(module, V, cells, materials, q_degree)

    def evaluate_finite(
        self,
        u: np.ndarray,
        plastic_strain: Sequence[np.ndarray],
        alpha: Sequence[np.ndarray],
        f: np.ndarray,
        floor: float,
        dt: float | None = None,
    ) -> tuple[int, list[ReturnMapResult | None]]:
        """Per body, map every zone point of the displacement ``u`` (local array) from the committed
        (``plastic_strain``, ``alpha``), add the force correction int Grad(v) : (P1 - C eps) dV to
        ``f`` (local array, ghosts included); returns (the nonlinear points, per body the trial
        state as a :class:`ReturnMapResult` without tangent)."""
        ffi, lib = self.module.ffi, self.module.lib
        n_active, trial = 0, []  # type: tuple[int, list[ReturnMapResult | None]]
        failed = np.zeros(2, dtype=np.int64)
        for kz, (data, material, table) in enumerate(zip(self.data, self.materials, self.tables)):
            n_cells = len(data.det)
            if not n_cells:
                trial.append(None)
                continue
            n_points = n_cells * data.n_q
            pos = np.arange(n_cells, dtype=np.int32)
            stress, deps = np.empty((n_points, 6)), np.empty((n_points, 6))
            dg, yielding = np.empty(n_points), np.empty(n_points, dtype=bool)
            eps_p = np.ascontiguousarray(plastic_strain[kz], dtype=float)
            al = np.ascontiguousarray(alpha[kz], dtype=float)
            a, s, k = table
            rate_c, rate_dg0 = rate_terms(material, dt)
            n = lib.finite_zone_force(
                n_cells,
                pointer(ffi, pos, "int *"),
                data.n_nodes,
                data.n_q,
                pointer(ffi, data.ref_grad),
                pointer(ffi, data.weights),
                pointer(ffi, data.dofs, "int *"),
                pointer(ffi, data.jinv),
                pointer(ffi, data.det),
                pointer(ffi, u),
                pointer(ffi, eps_p),
                pointer(ffi, al),
                material.shear_modulus,
                material.bulk_modulus,
                len(a),
                pointer(ffi, a),
                pointer(ffi, s),
                pointer(ffi, k),
                rate_c,
                rate_dg0,
                CONSISTENCY_RTOL * material.flow.yield_stress,
                CONSISTENCY_MAX_ITERATIONS,
                floor,
                pointer(ffi, f),
                pointer(ffi, stress),
                pointer(ffi, deps),
                pointer(ffi, dg),
                pointer(ffi, yielding, "unsigned char *"),
                pointer(ffi, failed, "long *"),
            )
            if n < 0 and failed[0] == 2:
                raise SolverError(
                    "finite strain: a deformation gradient with det F <= 0 or not finite (an element turned "
                    "inside out, or the step's iteration diverged): try a smaller time.dt_contact"
                )
            if n < 0:
                raise PlasticityError(
                    f"return map: the consistency equation did not converge at point {failed[1]} of zone {kz}"
                )
            n_active += n
            trial.append(
                ReturnMapResult(
                    stress, eps_p + deps, al + dg, None, yielding, np.einsum("pi,pi->p", stress, deps), deps
                )
            )
        return n_active, trial
