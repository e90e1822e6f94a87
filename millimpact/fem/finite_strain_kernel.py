"""A compiled pass over a finite-strain zone: deformation gradient, log strain, return map, P1, force.

:class:`millimpact.fem.finite_zone.FiniteStrainZone` maps every zone point at every iteration of a
step (its correction carries the geometric nonlinearity wherever Grad u is not zero). In numpy that
was a batched ``eigh`` and a dozen batched 3 x 3 products per point plus an FFCx expression and an
FFCx assembly: ~145 ms per 40,000 points, most of a finite-strain impact's time. Here one C loop
does per point what :mod:`millimpact.fem.finite_strain` does (the same equations):

    F = I + Grad u,   D = C - I = Grad u + Grad u^T + Grad u^T Grad u = sum_a mu_a N_a (x) N_a,
    E = sum_a 1/2 ln(1 + mu_a) N_a (x) N_a,          radial return of E - E_p,n  (T, d E_p, d alpha)
    S~_ab = 2 theta_ab T~_ab,  P1 = F S,             f_a += w |det J| (P1 - C : sym Grad u) Grad N_a

where |D| (its largest absolute row sum) is at most GL_NORM (0.5: strains below ~25 %), the log
and its derivative as Gauss-Legendre sums of their integral forms (Higham, Functions of Matrices,
2008, sections 11.3-11.4: the m-point rule is the [m/m] Pade approximant of the log),

    ln(I + D) = int_0^1 D (I + t D)^-1 dt,   S = int_0^1 (I + t D)^-1 T (I + t D)^-1 dt,

on the fewest nodes that reach 1e-17 at that |D| (C's ``gl_nodes``: 2-4 at elastic strains, 12 at
0.5), and beyond it the eigenpairs of D by cyclic Jacobi rotations (Golub and Van Loan, Matrix
Computations, 4th ed., section 8.5: quadratically convergent; the sweeps stop when the
off-diagonal's square sum is below 1e-32 of the diagonal's), with the radial return of
:mod:`.return_map_kernel` (one C function for both). Taking D = C - I apart rather than C keeps
the small strains' digits (1 + mu loses those of mu below 1e-16; ln(1 + mu) is ``log1p``; the
sums are D times resolvents near I), so the kernel is, if anything, more accurate than numpy's
``eigh`` of C at strains near round-off; the two agree to 1e-9 of the force's largest entry at
the strains of an impact (tests/fem/test_finite_strain_kernel.py). The Gauss-Legendre sums took a
pass on the plastic rig's 19,068 points (a third of them past |D| = 1e-2) from 9.7 to 6.0 ms
against the series in D and the Jacobi rotations they replace, the force equal to 3e-15.

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
from .finite_strain import INVERTED
from .plasticity import CONSISTENCY_MAX_ITERATIONS, CONSISTENCY_RTOL, PlasticityError, ReturnMapResult
from .return_map_kernel import KERNEL_HELPERS_C, CompiledPass, cell_arguments, load_compiled, pointer, rate_terms

_CDEF = """
int finite_zone_force(int n_pos, const int *pos, int n_nodes, int n_q, const double *ref_grad,
                      const double *weights, const int *dofs, const double *jinv, const double *det,
                      const double *u, const double *eps_p, const double *alpha,
                      double G, double K, int n_pts, const double *a, const double *s, const double *k,
                      double rate_c, double rate_dg0, double tol, int max_it, double floor, double *f,
                      double *stress_out, double *deps_out, double *dg_out, unsigned char *yield_out,
                      long *failed);
int finite_zone_energy(int n_pos, const int *pos, int n_nodes, int n_q, const double *ref_grad,
                       const double *weights, const int *dofs, const double *jinv, const double *det,
                       const double *u, const double *eps_p, double G, double K, double *energy, long *failed);
"""

#: |C - I| (the largest absolute row sum, a bound on its eigenvalues) up to which the pass sums the
#: log strain and its derivative on Gauss-Legendre nodes rather than in C's eigenbasis (cyclic
#: Jacobi): at |C - I| = 0.5 the rule needs 12 nodes for 1e-17
GL_NORM = 0.5
GL_MAX_NODES = 12


def _gauss_legendre_c() -> str:
    """The C tables GL_T[m][k], GL_W[m][k]: the m-point Gauss-Legendre nodes and weights on [0, 1]
    (numpy's ``leggauss``, weights summing to 1), m = 1 ... GL_MAX_NODES, row 0 unused."""
    rows_t, rows_w = ["{0}"], ["{0}"]
    for m in range(1, GL_MAX_NODES + 1):
        x, w = np.polynomial.legendre.leggauss(m)
        rows_t.append("{" + ", ".join(repr(float(v)) for v in 0.5 * (x + 1.0)) + "}")
        rows_w.append("{" + ", ".join(repr(float(v)) for v in 0.5 * w) + "}")
    n = GL_MAX_NODES + 1
    return (
        f"#define GL_NORM {GL_NORM!r}\n#define GL_MAX_NODES {GL_MAX_NODES}\n"
        f"#define LN_1E17 {17 * np.log(10.0)!r}\n"
        f"static const double GL_T[{n}][{GL_MAX_NODES}] = {{{', '.join(rows_t)}}};\n"
        f"static const double GL_W[{n}][{GL_MAX_NODES}] = {{{', '.join(rows_w)}}};\n"
    )


_SOURCE = (
    KERNEL_HELPERS_C
    + _gauss_legendre_c()
    + r"""
#include <string.h>
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
                const double t = fabs(theta) > 1e150 ? 0.5 / theta /* theta^2 would overflow */
                               : (theta >= 0.0 ? 1.0 : -1.0) / (fabs(theta) + sqrt(theta * theta + 1.0));
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
                A[p][q] = A[q][p] = 0.0; /* zero by the rotation's choice; its rounding would linger */
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

/* A point's kinematics: D = C - I, and either the Gauss-Legendre nodes m (> 0) with the resolvents
   R_i = (I + t_i D)^-1, or (m = 0) the eigenpairs (mu, N) of D */
typedef struct {
    double D[3][3], mu[3], N[3][3];
    double R[GL_MAX_NODES][3][3];
    int m;
} Kinematics;

/* C = A B for a product known to be symmetric (the upper triangle computed, mirrored) */
static void symmul3(const double A[3][3], const double B[3][3], double C[3][3])
{
    for (int i = 0; i < 3; i++)
        for (int j = i; j < 3; j++) C[i][j] = C[j][i] = A[i][0] * B[0][j] + A[i][1] * B[1][j] + A[i][2] * B[2][j];
}

/* R = (I + t D)^-1 of a symmetric D (its cofactors over its determinant: I + t D = (1 - t) I + t C
   is positive definite for t in [0, 1]) */
static void sym_resolvent(const double D[3][3], double t, double R[3][3])
{
    const double a00 = 1.0 + t * D[0][0], a11 = 1.0 + t * D[1][1], a22 = 1.0 + t * D[2][2];
    const double a01 = t * D[0][1], a02 = t * D[0][2], a12 = t * D[1][2];
    const double c00 = a11 * a22 - a12 * a12, c01 = a02 * a12 - a01 * a22, c02 = a01 * a12 - a02 * a11;
    const double inv = 1.0 / (a00 * c00 + a01 * c01 + a02 * c02);
    R[0][0] = c00 * inv;
    R[0][1] = R[1][0] = c01 * inv;
    R[0][2] = R[2][0] = c02 * inv;
    R[1][1] = (a00 * a22 - a02 * a02) * inv;
    R[1][2] = R[2][1] = (a01 * a02 - a00 * a12) * inv;
    R[2][2] = (a00 * a11 - a01 * a01) * inv;
}

/* The Gauss-Legendre nodes for ln(I + D) to 1e-17 at |D| = dn: the integrand's poles t = -1 / mu
   lie outside the Bernstein ellipse of [0, 1] with rho = s + sqrt(s^2 - 1), s = 2 / dn - 1, and the
   m-point rule's error falls as rho^(-2m) (Trefethen, Approximation Theory and Approximation
   Practice, 2013, theorem 19.3); at least 1 node, at most GL_MAX_NODES (dn = GL_NORM) */
static int gl_nodes(double dn)
{
    if (!(dn > 1e-150)) return 1;
    const double s = 2.0 / dn - 1.0;
    const int m = (int)ceil(LN_1E17 / (2.0 * log(s + sqrt(s * s - 1.0))));
    return m < 1 ? 1 : (m > GL_MAX_NODES ? GL_MAX_NODES : m);
}

/* The log strain of grad u g at a point: D = C - I = g + g^T + g^T g and E = 1/2 ln(I + D), as
   the m-point Gauss-Legendre sum of ln(I + D) = int_0^1 D (I + t D)^-1 dt (Higham, Functions of
   Matrices, 2008, section 11.4: the [m/m] Pade approximant of the log) where |D| <= GL_NORM, else
   sum_a 1/2 ln(1 + mu_a) N_a (x) N_a; *gmax the largest |g_ij|. Returns -1 where det F <= 0 (an
   element turned inside out: C = F^T F cannot tell) or g is not finite. */
static int log_strain_point(const double g[3][3], Kinematics *kin, double E[3][3], double *gmax)
{
    /* local arrays (no aliasing through kin or the outputs: the loops stay in registers) */
    double D[3][3], gm = 0.0;
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++) {
            gm = fmax(gm, fabs(g[i][j]));
            D[i][j] = g[i][j] + g[j][i] + g[0][i] * g[0][j] + g[1][i] * g[1][j] + g[2][i] * g[2][j];
        }
    *gmax = gm;
    const double detF = (1.0 + g[0][0]) * ((1.0 + g[1][1]) * (1.0 + g[2][2]) - g[1][2] * g[2][1])
                      - g[0][1] * (g[1][0] * (1.0 + g[2][2]) - g[1][2] * g[2][0])
                      + g[0][2] * (g[1][0] * g[2][1] - (1.0 + g[1][1]) * g[2][0]);
    if (!(gm < INFINITY) || !(detF > 0.0)) return -1;
    memcpy(kin->D, D, sizeof D);
    double dn = 0.0;
    for (int i = 0; i < 3; i++) dn = fmax(dn, fabs(D[i][0]) + fabs(D[i][1]) + fabs(D[i][2]));
    if (dn <= GL_NORM) {
        const int m = gl_nodes(dn);
        const double *t = GL_T[m], *w = GL_W[m];
        double Rs[3][3] = {{0}};
        kin->m = m;
        for (int k = 0; k < m; k++) {
            double R[3][3];
            sym_resolvent(D, t[k], R);
            memcpy(kin->R[k], R, sizeof R);
            for (int i = 0; i < 3; i++)
                for (int j = 0; j < 3; j++) Rs[i][j] += w[k] * R[i][j];
        }
        symmul3(D, Rs, E); /* D commutes with every R_i: sum_i w_i D R_i = D sum_i w_i R_i */
        for (int i = 0; i < 3; i++)
            for (int j = 0; j < 3; j++) E[i][j] *= 0.5;
        return 0;
    }
    double A[3][3], h[3], mu[3], N[3][3];
    memcpy(A, D, sizeof D);
    kin->m = 0;
    sym_eig3(A, mu, N);
    for (int a_ = 0; a_ < 3; a_++) {
        if (!(1.0 + mu[a_] > 0.0)) return -1;
        h[a_] = 0.5 * log1p(mu[a_]);
    }
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++) E[i][j] = N[i][0] * h[0] * N[j][0] + N[i][1] * h[1] * N[j][1] + N[i][2] * h[2] * N[j][2];
    memcpy(kin->mu, mu, sizeof mu);
    memcpy(kin->N, N, sizeof N);
    return 0;
}

/* S = T : 2 dE/dC of the stress T conjugate to E = 1/2 ln C. Gauss-Legendre (kin->m > 0): the
   Frechet derivative of the log, int_0^1 (I + t D)^-1 T (I + t D)^-1 dt (Higham 2008, eq. 11.10),
   summed on the log's nodes. Eigenbasis: Daleckii-Krein, S = N (2 theta o (N^T T N)) N^T
   (finite_strain.second_piola_kirchhoff). */
static void second_pk_point(const Kinematics *kin, const double T[3][3], double S[3][3])
{
    if (kin->m > 0) {
        const double *w = GL_W[kin->m];
        double acc[3][3] = {{0}};
        for (int k = 0; k < kin->m; k++) {
            const double (*R)[3] = (const double (*)[3])kin->R[k];
            double TR[3][3], RTR[3][3];
            for (int i = 0; i < 3; i++)
                for (int j = 0; j < 3; j++) TR[i][j] = T[i][0] * R[0][j] + T[i][1] * R[1][j] + T[i][2] * R[2][j];
            symmul3(R, TR, RTR);
            for (int i = 0; i < 3; i++)
                for (int j = 0; j < 3; j++) acc[i][j] += w[k] * RTR[i][j];
        }
        memcpy(S, acc, sizeof acc);
        return;
    }
    const double *mu = kin->mu;
    const double (*N)[3] = (const double (*)[3])kin->N;
    double TN[3][3], St[3][3], SN[3][3], th[3][3]; /* th symmetric: three divided differences of ln */
    for (int a_ = 0; a_ < 3; a_++) {
        th[a_][a_] = 0.5 / (1.0 + mu[a_]);
        for (int b = a_ + 1; b < 3; b++) th[a_][b] = th[b][a_] = theta(mu[a_], mu[b]);
    }
    for (int i = 0; i < 3; i++)
        for (int b = 0; b < 3; b++) TN[i][b] = T[i][0] * N[0][b] + T[i][1] * N[1][b] + T[i][2] * N[2][b];
    for (int a_ = 0; a_ < 3; a_++)
        for (int b = 0; b < 3; b++)
            St[a_][b] = 2.0 * th[a_][b] * (N[0][a_] * TN[0][b] + N[1][a_] * TN[1][b] + N[2][a_] * TN[2][b]);
    for (int i = 0; i < 3; i++)
        for (int b = 0; b < 3; b++) SN[i][b] = N[i][0] * St[0][b] + N[i][1] * St[1][b] + N[i][2] * St[2][b];
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++) S[i][j] = SN[i][0] * N[j][0] + SN[i][1] * N[j][1] + SN[i][2] * N[j][2];
}

/* sig = C e (Mandel) of the isotropic moduli (shear G, bulk K) */
static void elastic_stress(const double e[6], double G, double K, double sig[6])
{
    const double tr = e[0] + e[1] + e[2];
    for (int i = 0; i < 6; i++) sig[i] = 2.0 * G * e[i];
    for (int i = 0; i < 3; i++) sig[i] += (K - 2.0 * G / 3.0) * tr;
}

/* int_zone (psi(E - E_p) - 1/2 eps : C : eps) dV over the cells at pos (finite_zone's energy
   correction; psi Hencky's 1/2 (E - E_p) : C : (E - E_p)); arguments as finite_zone_force's.
   Writes the sum to *energy; returns 0, or -1 with failed[1] the point where det F <= 0. */
int finite_zone_energy(int n_pos, const int *pos, int n_nodes, int n_q, const double *ref_grad,
                       const double *weights, const int *dofs, const double *jinv, const double *det,
                       const double *u, const double *eps_p, double G, double K, double *energy, long *failed)
{
    const double s2 = sqrt(2.0);
    double ue[64][3], sum = 0.0;
    for (int ip = 0; ip < n_pos; ip++) {
        const int c = pos[ip];
        const int *cd = dofs + (long)c * n_nodes;
        const double *Ji = jinv + 9L * c;
        gather_cell(n_nodes, cd, u, ue);
        for (int q = 0; q < n_q; q++) {
            const long p = (long)c * n_q + q;
            const double *rq = ref_grad + (long)q * n_nodes * 3;
            double g[3][3], E[3][3], gmax, sig[6];
            Kinematics kin;
            point_grad(n_nodes, ue, rq, Ji, g);
            if (log_strain_point(g, &kin, E, &gmax) < 0) { failed[0] = 2; failed[1] = p; return -1; }
            const double *ep = eps_p + 6 * p;
            const double e[6] = {E[0][0] - ep[0], E[1][1] - ep[1], E[2][2] - ep[2],
                                 s2 * E[1][2] - ep[3], s2 * E[0][2] - ep[4], s2 * E[0][1] - ep[5]};
            const double eps[6] = {g[0][0], g[1][1], g[2][2], s2 * 0.5 * (g[1][2] + g[2][1]),
                                   s2 * 0.5 * (g[0][2] + g[2][0]), s2 * 0.5 * (g[0][1] + g[1][0])};
            double psi = 0.0, lin = 0.0;
            elastic_stress(e, G, K, sig);
            for (int i = 0; i < 6; i++) psi += 0.5 * e[i] * sig[i];
            elastic_stress(eps, G, K, sig);
            for (int i = 0; i < 6; i++) lin += 0.5 * eps[i] * sig[i];
            sum += weights[q] * det[c] * (psi - lin);
        }
    }
    *energy = sum;
    return 0;
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
        gather_cell(n_nodes, cd, u, ue);
        for (int q = 0; q < n_q; q++) {
            const long p = (long)c * n_q + q;
            const long o = (long)ip * n_q + q;
            const double *rq = ref_grad + (long)q * n_nodes * 3;
            double g[3][3], E[3][3], gmax;
            Kinematics kin;
            point_grad(n_nodes, ue, rq, Ji, g);
            if (log_strain_point(g, &kin, E, &gmax) < 0) { failed[0] = 2; failed[1] = p; return -1; }
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
            double S[3][3];
            second_pk_point(&kin, T, S);
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

    @staticmethod
    def load_module():
        return load_finite_kernel()

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
                *cell_arguments(ffi, data, pos),
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
                raise SolverError(INVERTED)
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

    def energy(self, u: np.ndarray, plastic_strain: Sequence[np.ndarray]) -> float:
        """int_zone (psi(E - E_p) - 1/2 eps : C : eps) dV of the displacement ``u`` (local array)
        with the committed plastic strain, summed over this rank's zone cells (J)."""
        ffi, lib = self.module.ffi, self.module.lib
        total, failed = 0.0, np.zeros(2, dtype=np.int64)
        out = np.zeros(1)
        for data, material, eps_p in zip(self.data, self.materials, plastic_strain):
            n_cells = len(data.det)
            if not n_cells:
                continue
            pos = np.arange(n_cells, dtype=np.int32)
            eps_p = np.ascontiguousarray(eps_p, dtype=float)
            code = lib.finite_zone_energy(
                *cell_arguments(ffi, data, pos),
                pointer(ffi, u),
                pointer(ffi, eps_p),
                material.shear_modulus,
                material.bulk_modulus,
                pointer(ffi, out),
                pointer(ffi, failed, "long *"),
            )
            if code < 0:
                raise SolverError(INVERTED)
            total += float(out[0])
        return total
