"""A compiled pass over a zone's cells: strains, radial return and the force correction.

A yielding step's iterations on the elastic operator (:mod:`millimpact.integration.plastic_newmark`,
``plastic_linearisation elastic``) need, per iteration, only the force correction of the candidate
cells and how many of their points yield (:meth:`PlasticZone.evaluate` with ``candidates_only``).
In numpy that was three passes over the points: the strains (an FFCx expression), the vectorised
return map (:func:`millimpact.fem.plasticity.return_map`) and the assembly of the stress correction
(an FFCx form): 3.6 ms of an iteration's ~14 ms on the plastic rig (3,342 candidate cells of
4,767), most of it numpy's temporaries. Here one C loop does all three per point:

    grad u = sum_a u_a (x) grad N_a,   grad N_a = J^-T grad_X N_a     (affine cells: J per cell)
    eps    = sym grad u (Mandel),      radial return from (eps_p,n, alpha_n)   (plasticity.py)
    f_a   += w_q |det J| (sigma - C (eps - eps_p,n)) : grad N_a,  sigma - C (eps - eps_p,n) = -C d eps_p

the same equations as the numpy path, in the same order of operations where it matters (the
tabulated flow curve's Newton stops per point at the same tolerance): the force agrees with the
numpy path's assembly to rounding (tests/fem/test_return_map_kernel.py: 1e-12 relative).

Only the yielding points add to f: where a point stays elastic, sigma - C eps is the frozen
plastic strain's -C eps_p,n, whose force f_frozen is kept per plastic state, so
f_c(u) = f_frozen + (this pass). A step's full evaluations without the tangent (the first that
yields, the confirmation of the converged iterate, and the one that finds nothing yielding: 304
of the rig's 985 evaluations, 4.2 ms each in numpy) take the same loop over every zone cell and
also keep each point's trial state (stress, d eps_p, d alpha, yielding), which
:meth:`PlasticZone.commit` accepts as it accepts numpy's.

The C source is compiled once per machine with cffi (the C compiler FFCx's JIT already needs) into
``$XDG_CACHE_HOME/millimpact`` (``~/.cache/millimpact``), keyed by the source's hash; the library is
written under a temporary name and renamed into place, so processes that compile side by side (the
ranks of a run, a study's workers) never load a half-written file. :func:`load_kernel` returns
None when no compiler is found; the zone then keeps the numpy path.
"""

from __future__ import annotations

import hashlib
import importlib.machinery
import importlib.util
import logging
import os
import tempfile
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from .plasticity import CONSISTENCY_MAX_ITERATIONS, CONSISTENCY_RTOL, PlasticityError, ReturnMapResult

log = logging.getLogger(__name__)

_CDEF = """
int zone_force(int n_pos, const int *pos, int n_nodes, int n_q, const double *ref_grad,
               const double *weights, const int *dofs, const double *jinv, const double *det,
               const double *u, const double *eps_p, const double *alpha,
               double G, double K, int n_pts, const double *a, const double *s, const double *k,
               double rate_c, double rate_dg0, double tol, int max_it, double *f,
               double *stress_out, double *deps_out, double *dg_out, unsigned char *yield_out);
"""

KERNEL_HELPERS_C = r"""
#include <math.h>

/* sigma_y(alpha) and its slope on the flow table (a_i, s_i, k_i): segment i = the last a_i <= alpha
   (the first below a_0 = 0), continued with the last slope (plasticity.FlowCurve). */
static int segment(int n, const double *a, double alpha)
{
    int i = 0;
    while (i + 1 < n && a[i + 1] <= alpha) i++;
    return i;
}

/* The radial return of J2 plasticity (plasticity.return_map) from the elastic trial strain e
   (Mandel, eps - eps_p,n) and the committed alpha: fills the trial stress sig = C e (6); returns 1
   where the point yields, with the plastic strain increment d (6) and *dg_out (the increment of
   alpha), 0 where it stays elastic (d = 0, dg = 0), -1 where the consistency equation did not
   converge. The flow table and tolerances as zone_force's. */
static int radial_return(const double e[6], double al, double G, double K, int n_pts, const double *a,
                         const double *s, const double *k, double rate_c, double rate_dg0, double tol,
                         int max_it, double sig[6], double d[6], double *dg_out)
{
    const double s15 = sqrt(1.5);
    const double tr = e[0] + e[1] + e[2], third = tr / 3.0;
    double dev[6] = {e[0] - third, e[1] - third, e[2] - third, e[3], e[4], e[5]};
    double nrm = 0.0;
    for (int i = 0; i < 6; i++) nrm += dev[i] * dev[i];
    nrm = sqrt(nrm);
    const double q_tr = s15 * 2.0 * G * nrm;
    int i0 = segment(n_pts, a, al);
    sig[0] = 2.0 * G * dev[0] + K * tr; sig[1] = 2.0 * G * dev[1] + K * tr; sig[2] = 2.0 * G * dev[2] + K * tr;
    sig[3] = 2.0 * G * dev[3]; sig[4] = 2.0 * G * dev[4]; sig[5] = 2.0 * G * dev[5];
    for (int i = 0; i < 6; i++) d[i] = 0.0;
    *dg_out = 0.0;
    if (!(q_tr - (s[i0] + k[i0] * (al - a[i0])) > tol)) return 0;
    /* the consistency equation q_tr - 3 G dg - sigma_y(alpha + dg) = 0 (plasticity._consistency) */
    double dg = (q_tr - (s[i0] + k[i0] * (al - a[i0]))) / (3.0 * G + k[i0]);
    if (n_pts > 1) {
        int ok = 0;
        for (int it = 0; it < max_it; it++) {
            int i1 = segment(n_pts, a, al + dg);
            double r = q_tr - 3.0 * G * dg - (s[i1] + k[i1] * (al + dg - a[i1]));
            if (fabs(r) <= tol) { ok = 1; break; }
            dg = dg + r / (3.0 * G + k[i1]);
            if (dg < 0.0) dg = 0.0;
        }
        if (!ok) {
            int i1 = segment(n_pts, a, al + dg);
            if (fabs(q_tr - 3.0 * G * dg - (s[i1] + k[i1] * (al + dg - a[i1]))) > tol) return -1;
        }
    }
    if (rate_c > 0.0 && dg > rate_dg0) {
        /* the rate-dependent root lies in [rate_dg0, dg]: Newton kept inside the bracket */
        double lo = rate_dg0, up = dg, x = dg, r = 0.0;
        int ok = 0;
        for (int it = 0; it < 4 * max_it; it++) {
            int i1 = segment(n_pts, a, al + x);
            const double rf = 1.0 + rate_c * log(x / rate_dg0);
            const double sy = s[i1] + k[i1] * (al + x - a[i1]);
            r = q_tr - 3.0 * G * x - sy * rf;
            if (fabs(r) <= tol) { ok = 1; break; }
            if (r > 0.0) lo = x; else up = x;
            const double nx = x + r / (3.0 * G + k[i1] * rf + sy * rate_c / x);
            x = (nx > lo && nx < up) ? nx : 0.5 * (lo + up);
        }
        if (!ok) return -1;
        dg = x;
    }
    /* d eps_p = sqrt(3/2) dg dev / |dev| */
    const double scale = s15 * dg / nrm;
    for (int i = 0; i < 6; i++) d[i] = dev[i] * scale;
    *dg_out = dg;
    return 1;
}

/* the element's nodal displacements ue (n_nodes x 3) from u (3 per block dof cd) */
static void gather_cell(int n_nodes, const int *cd, const double *u, double ue[][3])
{
    for (int n = 0; n < n_nodes; n++)
        for (int i = 0; i < 3; i++) ue[n][i] = u[3L * cd[n] + i];
}

/* grad u at a point: (sum_a u_a (x) grad_X N_a) J^-1, the element's nodal displacements ue, the
   reference gradients rq (n_nodes, 3) at the point and the cell's J^-1 (Ji, row-major) */
static void point_grad(int n_nodes, double ue[][3], const double *rq, const double *Ji, double g[3][3])
{
    double gr[3][3] = {{0}};
    for (int n = 0; n < n_nodes; n++)
        for (int i = 0; i < 3; i++)
            for (int m = 0; m < 3; m++) gr[i][m] += ue[n][i] * rq[3 * n + m];
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++)
            g[i][j] = gr[i][0] * Ji[j] + gr[i][1] * Ji[3 + j] + gr[i][2] * Ji[6 + j];
}

/* f_a,i += w |det J| S_ij dN_a/dx_j = wd (S J^-T)_ik dN_a/dX_k for a stress (correction) S, any
   3 x 3 (row i the force's component); cd the cell's block dofs */
static void add_point_force(int n_nodes, const int *cd, const double *rq, const double *Ji, double wd,
                            const double S[3][3], double *f)
{
    double T[3][3];
    for (int i = 0; i < 3; i++)
        for (int m = 0; m < 3; m++)
            T[i][m] = wd * (S[i][0] * Ji[3 * m] + S[i][1] * Ji[3 * m + 1] + S[i][2] * Ji[3 * m + 2]);
    for (int n = 0; n < n_nodes; n++) {
        double *fn = f + 3L * cd[n];
        const double *rn = rq + 3 * n;
        for (int i = 0; i < 3; i++) fn[i] += T[i][0] * rn[0] + T[i][1] * rn[1] + T[i][2] * rn[2];
    }
}

"""

_SOURCE = (
    KERNEL_HELPERS_C
    + r"""
/* One zone's candidate cells (positions pos in the zone's cell list): returns the number of
   yielding points, or -1 - (the point) where the consistency equation did not converge.
   ref_grad (n_q, n_nodes, 3) the reference gradients, weights (n_q), dofs (cells, n_nodes) block
   indices into u and f (3 per node), jinv (cells, 3, 3) J^-1, det (cells) |det J|, eps_p
   (cells * n_q, 6) and alpha (cells * n_q) the committed state; the flow table has n_pts rows
   (a linear curve: one row, a = 0, s = yield stress, k = hardening modulus); rate_c > 0: Johnson-
   Cook's C, the flow stress times 1 + C ln(dg / rate_dg0) where dg > rate_dg0 = rate0 dt
   (plasticity._consistency_with_rate); tol (Pa) both the
   yield test's margin and the consistency equation's (plasticity.CONSISTENCY_RTOL). f is added to.
   With stress_out (not NULL) the trial state is kept per point (ip * n_q + q): the stress (6),
   the plastic strain increment (6), dg (the increment of alpha) and whether it yields. */
int zone_force(int n_pos, const int *pos, int n_nodes, int n_q, const double *ref_grad,
               const double *weights, const int *dofs, const double *jinv, const double *det,
               const double *u, const double *eps_p, const double *alpha,
               double G, double K, int n_pts, const double *a, const double *s, const double *k,
               double rate_c, double rate_dg0, double tol, int max_it, double *f,
               double *stress_out, double *deps_out, double *dg_out, unsigned char *yield_out)
{
    const double s2 = sqrt(2.0);
    int n_yield = 0;
    double ue[64][3];
    for (int ip = 0; ip < n_pos; ip++) {
        const int c = pos[ip];
        const int *cd = dofs + (long)c * n_nodes;
        const double *Ji = jinv + 9L * c;
        gather_cell(n_nodes, cd, u, ue);
        for (int q = 0; q < n_q; q++) {
            const long p = (long)c * n_q + q;
            const double *rq = ref_grad + (long)q * n_nodes * 3;
            double g[3][3];
            point_grad(n_nodes, ue, rq, Ji, g);
            const double *ep = eps_p + 6 * p;
            double e[6] = {g[0][0] - ep[0], g[1][1] - ep[1], g[2][2] - ep[2],
                           s2 * 0.5 * (g[1][2] + g[2][1]) - ep[3], s2 * 0.5 * (g[0][2] + g[2][0]) - ep[4],
                           s2 * 0.5 * (g[0][1] + g[1][0]) - ep[5]};
            const long o = (long)ip * n_q + q;
            double sig[6], d[6], dg;
            const int r = radial_return(e, alpha[p], G, K, n_pts, a, s, k, rate_c, rate_dg0, tol, max_it, sig, d, &dg);
            if (r < 0) return -1 - (int)p;
            if (stress_out) {
                for (int i = 0; i < 6; i++) { stress_out[6 * o + i] = sig[i] - 2.0 * G * d[i]; deps_out[6 * o + i] = d[i]; }
                dg_out[o] = dg;
                yield_out[o] = (unsigned char)r;
            }
            if (r == 0) continue;
            n_yield++;
            const double trd = d[0] + d[1] + d[2], thd = trd / 3.0;
            double sc[6] = {-(2.0 * G * (d[0] - thd) + K * trd), -(2.0 * G * (d[1] - thd) + K * trd),
                            -(2.0 * G * (d[2] - thd) + K * trd), -2.0 * G * d[3], -2.0 * G * d[4],
                            -2.0 * G * d[5]};
            /* sigma from the Mandel vector */
            const double S[3][3] = {{sc[0], sc[5] / s2, sc[4] / s2},
                                    {sc[5] / s2, sc[1], sc[3] / s2},
                                    {sc[4] / s2, sc[3] / s2, sc[2]}};
            add_point_force(n_nodes, cd, rq, Ji, weights[q] * det[c], S, f);
        }
    }
    return n_yield;
}
"""
)

_loaded: dict[str, object] = {}


def cache_dir() -> Path:
    """Where the compiled kernels live: ``$XDG_CACHE_HOME/millimpact`` (default ``~/.cache``)."""
    return Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache") / "millimpact"


def _compile(folder: Path, name: str, cdef: str, source: str) -> Path:
    """Compile the module in a private temporary folder and rename it into ``folder`` (atomic:
    a process that finds the library finds it whole)."""
    import cffi

    folder.mkdir(parents=True, exist_ok=True)
    ffi = cffi.FFI()
    ffi.cdef(cdef)
    ffi.set_source(name, source, extra_compile_args=["-O3", "-std=c99"])
    with tempfile.TemporaryDirectory(dir=folder, prefix=".build-") as tmp:
        built = Path(ffi.compile(tmpdir=tmp, verbose=False))
        target = folder / built.name
        os.replace(built, target)
    return target


def load_compiled(stem: str, cdef: str, source: str):
    """The cffi module of C ``source`` (declarations ``cdef``; its ``lib`` and ``ffi``), compiled on
    first use into :func:`cache_dir` under ``stem`` and the source's hash; None (and one log line)
    when it cannot be built here, e.g. without a C compiler."""
    name = f"_millimpact_{stem}_" + hashlib.sha256((cdef + source).encode()).hexdigest()[:12]
    if name in _loaded:
        return _loaded[name] or None
    folder = cache_dir()
    path = folder / (name + importlib.machinery.EXTENSION_SUFFIXES[0])
    try:
        if not path.exists():
            path = _compile(folder, name, cdef, source)
        spec = importlib.util.spec_from_file_location(name, path)
        if spec is None or spec.loader is None:
            raise ImportError(f"no module spec for {path}")
        module = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(module)
        _loaded[name] = module
    except Exception as exc:  # no compiler, no cffi, an unwritable cache: the numpy path stays
        log.warning("plastic zone: the compiled %s could not be built (%s); using numpy", stem, exc)
        _loaded[name] = False
        return None
    return module


def load_kernel():
    """The compiled small-strain pass (its ``lib.zone_force`` and ``ffi``): :func:`load_compiled`."""
    return load_compiled("zone_force", _CDEF, _SOURCE)


def cell_arguments(ffi, data: ZoneKernelData, pos: np.ndarray) -> tuple:
    """The kernels' first nine arguments: the cells at positions ``pos`` (int32, contiguous) and
    the zone's cell data (n_pos, pos, n_nodes, n_q, ref_grad, weights, dofs, jinv, det)."""
    return (
        len(pos),
        pointer(ffi, pos, "int *"),
        data.n_nodes,
        data.n_q,
        pointer(ffi, data.ref_grad),
        pointer(ffi, data.weights),
        pointer(ffi, data.dofs, "int *"),
        pointer(ffi, data.jinv),
        pointer(ffi, data.det),
    )


def rate_terms(material, dt: float | None) -> tuple[float, float]:
    """The kernels' (rate_c, rate_dg0): Johnson-Cook's C and the reference increment rate0 dt, or
    (0, 0) for a material without a strain-rate factor (or no step)."""
    return (0.0, 0.0) if material.rate is None or dt is None else (material.rate[0], material.rate[1] * dt)


def pointer(ffi, arr: np.ndarray, kind: str = "double *"):
    """A C pointer to a contiguous numpy array's data (the array must outlive the call)."""
    return ffi.cast(kind, arr.ctypes.data)


class ZoneKernelData:
    """One zone's per-cell data for :func:`zone_force`: the element's reference gradients at the
    quadrature points, each cell's J^-1 and |det J| (affine geometry) and its dofs (block indices).
    ``cells`` the zone's local cells, ``V`` the vector P1/P2 space, ``points``/``weights`` the
    zone's quadrature rule (basix, the one its Quadrature spaces use)."""

    def __init__(self, V, cells: np.ndarray, points: np.ndarray, weights: np.ndarray):
        import basix

        mesh = V.mesh
        degree = V.ufl_element().degree()
        element = basix.create_element(
            basix.ElementFamily.P, basix.CellType.tetrahedron, degree, basix.LagrangeVariant.equispaced
        )
        tab = element.tabulate(1, points)  # (4, n_q, n_nodes, 1)
        self.ref_grad = np.ascontiguousarray(np.moveaxis(tab[1:4, :, :, 0], 0, -1))  # (n_q, n_nodes, 3)
        self.n_q, self.n_nodes = self.ref_grad.shape[0], self.ref_grad.shape[1]
        self.weights = np.ascontiguousarray(weights, dtype=float)
        n_dofs = V.dofmap.list.array.size // max(1, V.dofmap.list.num_nodes)
        self.dofs = np.ascontiguousarray(V.dofmap.list.array.reshape(-1, n_dofs)[cells], dtype=np.int32)
        gdofs = mesh.geometry.dofmap.array.reshape(-1, 4)[cells]
        x = mesh.geometry.x[gdofs]  # (cells, 4, 3)
        J = np.stack([x[:, 1] - x[:, 0], x[:, 2] - x[:, 0], x[:, 3] - x[:, 0]], axis=-1)  # dx_i / dX_j
        self.jinv = np.ascontiguousarray(np.linalg.inv(J)) if len(cells) else np.zeros((0, 3, 3))
        self.det = np.ascontiguousarray(np.abs(np.linalg.det(J))) if len(cells) else np.zeros(0)

    @staticmethod
    def supports(V) -> bool:
        """Whether the kernel handles this space: vector Lagrange P1/P2 on affine tetrahedra."""
        mesh = V.mesh
        return (
            mesh.topology.cell_type.name == "tetrahedron"
            and mesh.geometry.cmap.degree == 1
            and V.ufl_element().degree() in (1, 2)
            and V.dofmap.bs == 3
        )


def zone_force(
    module,
    data: ZoneKernelData,
    pos: np.ndarray,
    u: np.ndarray,
    plastic_strain: np.ndarray,
    alpha: np.ndarray,
    material,
    table,
    tol: float,
    max_iterations: int,
    f: np.ndarray,
    state: tuple | None = None,
    dt: float | None = None,
) -> int:
    """Add the cells' (``pos``, positions in the zone's cells) force correction beyond the frozen
    one, -int B^T C d eps_p dV, to ``f`` (the local array, ghosts included) for the displacement
    ``u`` (local array); returns the number of yielding points, or -1 - (a point's index) where
    the consistency equation failed. ``state``: arrays (stress (n, 6), d eps_p (n, 6), d alpha (n,),
    yielding (n,) bool) filled with the trial state of the cells' points, in ``pos`` order; ``dt``
    (s) the step, for a material with a strain-rate factor."""
    ffi, lib = module.ffi, module.lib
    pos = np.ascontiguousarray(pos, dtype=np.int32)
    plastic_strain = np.ascontiguousarray(plastic_strain, dtype=float)
    alpha = np.ascontiguousarray(alpha, dtype=float)
    a, s, k = table
    rate_c, rate_dg0 = rate_terms(material, dt)

    def ptr(arr, kind="double *"):
        return pointer(ffi, arr, kind)

    outputs = (
        (ffi.NULL,) * 4
        if state is None
        else (ptr(state[0]), ptr(state[1]), ptr(state[2]), ptr(state[3], "unsigned char *"))
    )

    return int(
        lib.zone_force(
            *cell_arguments(ffi, data, pos),
            ptr(u),
            ptr(plastic_strain),
            ptr(alpha),
            material.shear_modulus,
            material.bulk_modulus,
            len(a),
            ptr(a),
            ptr(s),
            ptr(k),
            rate_c,
            rate_dg0,
            tol,
            max_iterations,
            ptr(f),
            *outputs,
        )
    )


class CompiledPass:
    """The kernel bound to a zone's bodies: per body its cell data (:class:`ZoneKernelData`), J2
    material and flow table, for :meth:`PlasticZone.evaluate` without the tangent."""

    def __init__(self, module, V, cells: Sequence[np.ndarray], materials: Sequence, q_degree: int):
        import basix

        points, weights = basix.make_quadrature(basix.CellType.tetrahedron, q_degree)
        self.module, self.materials = module, list(materials)
        self.data = [ZoneKernelData(V, c, points, weights) for c in cells]
        self.tables = [tuple(np.ascontiguousarray(x, dtype=float) for x in m.flow.segments()) for m in self.materials]

    @staticmethod
    def load_module():
        """The compiled module this pass calls (None where it cannot be built)."""
        return load_kernel()

    @classmethod
    def build(cls, V, cells: Sequence[np.ndarray], materials: Sequence, q_degree: int):
        """The pass for these zones, or None where the space is not one the kernel handles or the
        kernel cannot be built here."""
        module = cls.load_module() if ZoneKernelData.supports(V) else None
        return None if module is None else cls(module, V, cells, materials, q_degree)

    def evaluate(
        self,
        u: np.ndarray,
        positions: Sequence[np.ndarray],
        plastic_strain: Sequence[np.ndarray],
        alpha: Sequence[np.ndarray],
        f: np.ndarray,
        keep_state: bool,
        dt: float | None = None,
    ) -> tuple[int, list[ReturnMapResult | None]]:
        """Per body, return-map the points of the cells at ``positions`` (in its cell list) from the
        committed (``plastic_strain``, ``alpha``) and add their force correction beyond the frozen
        one to ``f``; returns (the yielding points, per body its :class:`ReturnMapResult` without
        tangent when ``keep_state``, else None)."""
        n_yield = 0
        trial: list[ReturnMapResult | None] = []
        for k, (pos, material) in enumerate(zip(positions, self.materials)):
            if not len(pos):
                trial.append(None)
                continue
            n_points = len(pos) * self.data[k].n_q
            state = (
                (np.empty((n_points, 6)), np.empty((n_points, 6)), np.empty(n_points), np.empty(n_points, dtype=bool))
                if keep_state
                else None
            )
            tol = CONSISTENCY_RTOL * material.flow.yield_stress
            n = zone_force(
                self.module,
                self.data[k],
                pos,
                u,
                plastic_strain[k],
                alpha[k],
                material,
                self.tables[k],
                tol,
                CONSISTENCY_MAX_ITERATIONS,
                f,
                state,
                dt,
            )
            if n < 0:
                raise PlasticityError(
                    f"return map: the consistency equation did not converge at point {-1 - n} of zone {k}"
                )
            n_yield += n
            if state is not None:
                stress, deps, dg, yielding = state
                trial.append(
                    ReturnMapResult(
                        stress,
                        plastic_strain[k] + deps,
                        alpha[k] + dg,
                        None,
                        yielding,
                        np.einsum("pi,pi->p", stress, deps),
                        deps,
                    )
                )
            else:
                trial.append(None)
        return n_yield, trial
