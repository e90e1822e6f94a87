"""Benchmark: how well a local tangent on the yielding coordinates would precondition a yielding
step (a direction not taken), measured on the plastic rig's own operators.

A yielding step's iteration today is the fixed point on the elastic operator A (Anderson-mixed):
its linear rate is that of a Krylov method on A^-1 B, B = A + dK_r the step's tangent, whose
spectrum the yielding points spread over (0, 1]. dK_r = G^T dK G lives on the p reduced
coordinates of the yielding cells (a third of the rig's 11,433). This script runs
``paper-rig-plastic`` (impact only, serial) and, at the chosen steps, takes A and the tangent
of the converged state (the zone's return map with its consistent tangent,
:meth:`~millimpact.fem.plastic_zone.PlasticZone.stiffness_correction`, projected), then counts
GMRES iterations (restart 200, to 1e-8) for B x = b with each preconditioner (Smith, Bjorstad &
Gropp, Domain Decomposition, 1996, ch. 1 and 5: additive and multiplicative Schwarz):

  elastic          A^-1                                         (today's operator)
  additive         A^-1 + R^T (B_pp^-1 - A_pp^-1) R
  mult el+loc      x = A^-1 r, then x += R^T B_pp^-1 R (r - B x)
  mult loc+el      x = R^T B_pp^-1 R r, then x += A^-1 (r - B x)
  coarse           x = A^-1 r, then x += Z (Z^T B Z)^-1 Z^T (r - B x), Z the step's own LOW_MODES
                   softest eigenvectors of A^-1 B, or the previous chosen step's RECYCLED (a space
                   recycled from step to step needs B Z only, no solve)

(R: restriction to the yielding coordinates p), the last with the local tangent of the previous
chosen step held (its own p: what a tangent kept over steps would give), the smallest eigenvalue
of A^-1 B and how many of its lowest LOW_MODES lie below 0.3 (a handful would be a coarse space
worth deflating; the rig has a continuum: 18 below 0.3 at step 20, 34 at step 40, the 80th at
0.45 and 0.36), and CHOLMOD's factorization and solve times of A and of the local tangent B_pp (PETSc,
one process).
Writes benchmarks/out/plastic_local_tangent/{plastic_local_tangent.csv,.md}.

    .venv/bin/python benchmarks/plastic_local_tangent.py --steps 30,50

The capture wraps the zone's commit for this process only (no option of the package does this):
the run's own iterations are those of the default path plus one tangent evaluation a chosen step.
"""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import millimpact  # noqa: F401  (before numpy: it chooses OpenBLAS's kernels, millimpact/__init__.py)
import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as sla

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "benchmarks"))

from _report import write_report  # noqa: E402


#: eigenvalues of A^-1 B computed from the bottom (shift-invert at 0): enough to tell a few
#: isolated soft modes from a continuum
LOW_MODES = 80
#: the previous chosen step's softest eigenvectors recycled as a coarse space
RECYCLED = 40


def capture(steps: set[int], folder: Path) -> dict[int, tuple[sp.csr_matrix, sp.csr_matrix, int]]:
    """Run the rig's impact and return {step: (A, dK_r, yielding points)} at the chosen steps."""
    from millimpact.cli import main
    from millimpact.fem import plastic_zone as pz
    from millimpact.integration import plastic_newmark as pn

    got, state = {}, {"u": None}
    evaluate, step = pz.PlasticZone.evaluate, pn.PlasticNewmarkScheme.step

    def full_evaluate(self, u_vec, tangent=True, candidates_only=False):
        if not candidates_only:           # the last full evaluation of a step is its converged iterate
            state["u"] = u_vec.copy() if state["u"] is None else (u_vec.copy(state["u"]) or state["u"])
        return evaluate(self, u_vec, tangent, candidates_only)

    def csr(M):
        ai, aj, av = M.getValuesCSR()
        return sp.csr_matrix((av, aj, ai), shape=M.getSize())

    def wrapped_step(self, dt, t_new, n, allow_reject):
        zone, commit = self.zone, self.zone.commit

        def take_then_commit():
            if n in steps:
                n_yield = zone.zone.evaluate(state["u"], tangent=True)
                if n_yield:
                    dK = zone.stiffness_correction()
                    got[n] = (csr(self._ops(dt).A), csr(dK), n_yield)
                    dK.destroy()
            commit()
        zone.commit = take_then_commit
        try:
            return step(self, dt, t_new, n, allow_reject)
        finally:
            zone.commit = commit

    pz.PlasticZone.evaluate, pn.PlasticNewmarkScheme.step = full_evaluate, wrapped_step
    try:
        main(["run", "paper-rig-plastic", "-q", "--force", "--set", "time.end=1e-4", "--out", str(folder)])
    finally:
        pz.PlasticZone.evaluate, pn.PlasticNewmarkScheme.step = evaluate, step
    return got


def cholmod_times(M: sp.csr_matrix) -> tuple[float, float]:
    """(factorization s, one solve s) of PETSc's CHOLMOD Cholesky of the SPD matrix M."""
    from petsc4py import PETSc

    P = PETSc.Mat().createAIJ(M.shape, csr=(M.indptr.astype(PETSc.IntType), M.indices.astype(PETSc.IntType), M.data),
                              comm=PETSc.COMM_SELF)
    P.setOption(PETSc.Mat.Option.SPD, True)
    ksp = PETSc.KSP().create(PETSc.COMM_SELF)
    ksp.setOperators(P)
    ksp.setType("preonly")
    ksp.getPC().setType("cholesky")
    ksp.getPC().setFactorSolverType("cholmod")
    t = time.perf_counter()
    ksp.setUp()
    t_factor = time.perf_counter() - t
    b = P.createVecLeft()
    b.setRandom()
    x = b.duplicate()
    ksp.solve(b, x)
    t = time.perf_counter()
    for _ in range(20):
        ksp.solve(b, x)
    t_solve = (time.perf_counter() - t) / 20
    for obj in (ksp, P, b, x):
        obj.destroy()
    return t_factor, t_solve


def preconditioners(A, B, p):
    """The four preconditioners of the module docstring as functions r -> x."""
    LA = sla.splu(A.tocsc())
    App, Bpp = A[p][:, p].tocsc(), B[p][:, p].tocsc()
    LApp, LBpp = sla.splu(App), sla.splu(Bpp)

    def additive(r):
        x = LA.solve(r)
        x[p] += LBpp.solve(r[p]) - LApp.solve(r[p])
        return x

    def elastic_then_local(r):
        x = LA.solve(r)
        x[p] += LBpp.solve((r - B @ x)[p])
        return x

    def local_then_elastic(r):
        x = np.zeros_like(r)
        x[p] = LBpp.solve(r[p])
        return x + LA.solve(r - B @ x)

    return LA, {"elastic": LA.solve, "additive": additive, "mult el+loc": elastic_then_local,
                "mult loc+el": local_then_elastic}


def held_local(A, LA, B, dK_held):
    """'mult loc+el' with the local tangent of an earlier step (its yielding coordinates); ``LA``
    the factorization of A (:func:`preconditioners`)."""
    p = np.flatnonzero(np.diff(dK_held.indptr))
    LB = sla.splu((A + dK_held)[p][:, p].tocsc())

    def local_then_elastic(r):
        x = np.zeros_like(r)
        x[p] = LB.solve(r[p])
        return x + LA.solve(r - B @ x)
    return local_then_elastic


def coarse_corrected(LA, B, Z):
    """A^-1, then the Galerkin coarse correction on span(Z): x += Z (Z^T B Z)^-1 Z^T (r - B x).
    It needs B Z, not A^-1 Z: a space recycled from step to step would cost no solve (Parks et al.,
    SIAM J. Sci. Comput. 28, 2006, recycle Krylov subspaces for a sequence of systems)."""
    BZ = B @ Z
    L = np.linalg.cholesky(Z.T @ BZ)

    def precondition(r):
        x = LA.solve(r)
        y = np.linalg.solve(L.T, np.linalg.solve(L, Z.T @ (r - B @ x)))
        return x + Z @ y
    return precondition


def gmres_iterations(B, b, P) -> int:
    n, count = B.shape[0], [0]
    M = sla.LinearOperator((n, n), matvec=P)
    x, info = sla.gmres(B, b, M=M, tol=1e-8, restart=200, maxiter=5,
                        callback=lambda _: count.__setitem__(0, count[0] + 1), callback_type="pr_norm")
    if info != 0:
        return -1
    return count[0]


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--steps", default="30,50", help="steps of the rig's impact to take (comma-separated)")
    ap.add_argument("--out", default=str(ROOT / "benchmarks" / "out" / "plastic_local_tangent"))
    a = ap.parse_args(argv)
    out = Path(a.out)
    got = capture({int(s) for s in a.steps.split(",")}, out / "run")
    rows, held = [], None
    rng = np.random.default_rng(0)
    for n, (A, dK, n_yield) in sorted(got.items()):
        B = (A + dK).tocsr()
        p = np.flatnonzero(np.diff(dK.indptr))
        b = dK @ rng.normal(size=A.shape[0])          # a load on the yielding coordinates
        LA, pcs = preconditioners(A, B, p)
        # the low end of the spectrum of A^-1 B (B v = mu A v, both SPD), its minimum included: a few
        # isolated soft modes could be deflated (a coarse space recycled from step to step); a
        # continuum cannot
        mu, V = sla.eigsh(B.tocsc(), k=LOW_MODES, M=A.tocsc(), sigma=0.0, which="LM", tol=1e-8)
        order = np.argsort(mu)
        mu, V = mu[order], V[:, order]
        tfa, tsa = cholmod_times(A.tocsr())
        tfl, tsl = cholmod_times(B[p][:, p].tocsr())
        row = {"step": n, "yielding_points": n_yield, "coordinates": A.shape[0], "yielding_coordinates": len(p),
               "lambda_min_AinvB": float(mu[0]), "modes_below_0.3": int(np.sum(mu < 0.3)),
               f"mode_{LOW_MODES}_AinvB": float(mu[-1]), "cholmod_A_factor_s": tfa, "cholmod_A_solve_s": tsa,
               "cholmod_Bpp_factor_s": tfl, "cholmod_Bpp_solve_s": tsl}
        for name, P in pcs.items():
            row[f"gmres_{name.replace(' ', '_').replace('+', '_')}"] = gmres_iterations(B, b, P)
        row["gmres_held_from_step"] = held[0] if held else -1
        row["gmres_mult_loc_el_held"] = gmres_iterations(B, b, held_local(A, LA, B, held[1])) if held else -1
        # the softest modes deflated: the step's own (an eigensolve a step), the previous chosen step's
        row[f"gmres_coarse_own_{LOW_MODES}"] = gmres_iterations(B, b, coarse_corrected(LA, B, V))
        row[f"gmres_coarse_held_{RECYCLED}"] = (gmres_iterations(B, b, coarse_corrected(LA, B, held[2][:, :RECYCLED]))
                                                if held else -1)
        held = (n, dK, V)
        rows.append(row)
    if not rows:
        print("no chosen step yielded: choose steps in the contact (the rig yields from step ~10 to ~70)")
        return 1

    def cells(r):
        its = [str(r[k]) for k in r if k.startswith("gmres_") and "held" not in k and "coarse" not in k]
        its.append(f"{r['gmres_mult_loc_el_held']} (step {r['gmres_held_from_step']})" if r["gmres_held_from_step"] >= 0
                   else "")
        its.append(str(r[f"gmres_coarse_own_{LOW_MODES}"]))
        held_c = r[f"gmres_coarse_held_{RECYCLED}"]
        its.append(f"{held_c} (step {r['gmres_held_from_step']})" if held_c >= 0 else "")
        return [str(r["step"]), f"{r['yielding_coordinates']} / {r['coordinates']}", f"{r['lambda_min_AinvB']:.3f}",
                f"{r['modes_below_0.3']} / {r[f'mode_{LOW_MODES}_AinvB']:.3f}",
                *its, f"{r['cholmod_A_factor_s'] * 1e3:.0f} / {r['cholmod_A_solve_s'] * 1e3:.1f}",
                f"{r['cholmod_Bpp_factor_s'] * 1e3:.0f} / {r['cholmod_Bpp_solve_s'] * 1e3:.1f}"]
    write_report(out, "plastic_local_tangent", rows, 1,
                 ["step", "yielding coords / all", "min eig A^-1 B",
                  f"eigs < 0.3 / {LOW_MODES}th (of the lowest {LOW_MODES})", "GMRES: elastic", "additive", "mult el+loc",
                  "mult loc+el", "held", f"coarse: own {LOW_MODES} softest", f"coarse: held {RECYCLED} softest",
                  "A: factor / solve ms", "B_pp: factor / solve ms"],
                 cells, note="; paper-rig-plastic impact, GMRES to 1e-8 from zero")
    return 0


if __name__ == "__main__":
    sys.exit(main())
