"""Substructured (two-level) Craig-Bampton of a body's interior: the constraint modes Psi and the
fixed-interface modes Phi from a Ritz basis built slab by slab, without factorizing the whole interior
(one factorization fills like N^1.47; cut into S slabs, each factor is ~S^-1.47 of that and only one
slab's is held at a time).

Component mode synthesis (Hurty, AIAA J. 3 (1965) 678-685; Craig and Bampton, AIAA J. 6 (1968)
1313-1319), with the interface reduced (Krattiger et al., Mech. Syst. Signal Process. 114 (2019)
579-603):

1. The interior is cut into S slabs along its longest extent (:mod:`.slab_cuts`), the cuts at least
   ``margin`` shear wavelengths at f_cut from the zone-coupled dofs and the gauges. The dofs of a
   slab coupled to a later slab form the interface Gamma; the rest P_s are uncoupled:
   K_ii = [diag(K_ss)  K_PG; K_GP  K_GG].
2. A Ritz basis V, per slab with one factorization: fixed-interface modes of P_s up to
   ``f_factor`` x f_cut; static responses to the zone coordinates Z_s = -K_ss^-1 C_s and to their
   inertia K_ss^-1 (M_ss Z_s + M_sz); trace extensions X_s = -K_ss^-1 K_sG t_k, the traces t_k
   tensor Legendre polynomials per interface face and component (``trace_density`` 0: every Gamma
   dof its own trace, the exact interface).
3. Rayleigh-Ritz in span(V): K_V = V^T K_ii V, M_V = V^T M_ii V, C_V = V^T C; Psi = V psi with
   K_V psi = -C_V, Phi = V phi with K_V phi = lambda M_V phi, lambda <= (2 pi f_cut)^2.
4. One step of inverse iteration: each slab's static response (Gamma held) to the inertia
   M_ii [Phi, Psi] + [0, M_ib] joins V (M-orthonormalised, directions under ``compress`` dropped)
   and step 3 is repeated; it also puts K_ii^-1 A_b, which the mode-acceleration rows need, in V.

The Ritz frequencies are upper bounds of the exact ones (Rayleigh's principle). Zone-interface
patterns (``substructure_zone_degree`` d >= 1): the interior's vectors are the static responses
X = -K_ii^-1 K_iz W to p smooth interface motions W (monomials of degree <= d, :mod:`.interface_patterns`)
instead of the n_b constraint modes, coordinates of their own beside the modes
(:func:`pattern_vectors`; Castanier, Tan and Pierre, AIAA J. 39 (2001) 1182-1187); outputs are
recovered in the Ritz space (:func:`ritz_recovery`).

Options (prefix ``impact_reduction_<body>_``): ``substructures`` S (0 or 1: one factorization),
``substructure_f_factor`` (1.5), ``substructure_trace_density`` (4), ``substructure_margin`` (0.5),
``substructure_compress`` (1e-12), ``substructure_zone_degree`` (0), ``substructure_across`` (2; 0
keeps the slabs whole), ``substructure_eps_tol`` (:data:`SLAB_EPS_TOL`). Under MPI each rank takes
whole slabs (:func:`slab_owners`) and only the Ritz matrices (solved on rank 0) and the final rows
travel. Measured costs and accuracies: docs/development/reduction-notes.md.
"""

from __future__ import annotations

import logging
import math
import resource
import time
from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp
from mpi4py import MPI
from petsc4py import PETSc

from ..integration.solvers import check_type_options, create_factored_solver, petsc_options, return_freed_memory
from .distributed import (
    DEPENDENT_TOL,
    computed_on_root,
    deliver_rows,
    dense_from_rows,
    gram_basis,
    positions_in,
    reduce_array,
)
from .eigen import compute_modes
from .ritz import rayleigh_ritz
from .slab_cuts import ACROSS_RATIO, SlabCut, cut_slabs, interface_faces, interface_next, polynomial_traces

log = logging.getLogger(__name__)

#: interior dofs from which a body is cut into slabs without being asked: the liner panel's one
#: factorization ran at 344k P2 DOFs (docs/scenes.md) and was estimated at 109 GB a rank at 1.2M
#: (methods.memory), where 16 slabs ran in 17.1-18.7 GB on 2 ranks
AUTO_MIN_DOFS = 600_000
#: interior dofs a slab when cut without being asked (1.12M interior dofs -> 16 slabs, as run)
AUTO_SLAB_DOFS = 70_000
#: margin (shear wavelengths) and zone-interface pattern degree when cut without being asked: the
#: million-DOF run's (0.5 and exact constraint modes ran out of memory there: docs/scenes.md)
AUTO_MARGIN = 0.25
AUTO_ZONE_DEGREE = 3
#: the slabs' eigensolver tolerance (``substructure_eps_tol``, the relative residual of SLEPc and
#: :mod:`.block_krylov`): a slab's modes are Ritz vectors, which the second pass and the
#: Rayleigh-Ritz refine, so they need not be converged like a body's modes (``eps_tol`` 1e-10).
#: Liner panel, 17 slabs on 2 ranks: block Krylov bases of 416 -> 224-256 columns, the busier
#: rank's eigensolves 83.5 -> 59.8 s; frequencies within 3e-9, F_max and e 1e-9, the gauges 7e-7
SLAB_EPS_TOL = 1e-4
#: rows of a slab expanded and sent to their owners at a time (16k rows x ~300 columns: 40 MB)
EXPAND_ROWS = 16384


@dataclass(frozen=True)
class SubstructureSettings:
    """How a body's interior is substructured (see the module docstring)."""

    slabs: int
    f_factor: float = 1.5
    trace_density: float = 4.0
    margin: float = 0.5  #: shear wavelengths at f_cut between a cut and the zone or a gauge
    compress: float = 1e-12  #: second pass: relative Gram eigenvalue of a dropped direction (0: keep all)
    zone_degree: int = 0  #: zone-interface patterns' polynomial degree (0: exact constraint modes)
    across: float = ACROSS_RATIO  #: a slab over this x the mean is cut again across (0: never)
    eps_tol: float = SLAB_EPS_TOL  #: the slabs' eigensolver tolerance


def substructure_settings(
    prefix: str, options: dict[str, str] | None, n_interior: int = 0
) -> SubstructureSettings | None:
    """The body's settings from the command line (``-<prefix>substructures`` ...) or ``options``
    (their ranges checked by :func:`~millimpact.integration.solvers.check_type_options`, the CLI's
    check); None for one factorization (S < 2). Without ``substructures`` a body of
    ``n_interior`` >= :data:`AUTO_MIN_DOFS` interior dofs is cut by itself (:func:`auto_slabs`),
    with the margin and zone-interface patterns of the liner panel's million-DOF run
    (:data:`AUTO_MARGIN`, :data:`AUTO_ZONE_DEGREE`) unless given."""
    keys = (
        "substructures",
        "substructure_f_factor",
        "substructure_trace_density",
        "substructure_margin",
        "substructure_compress",
        "substructure_zone_degree",
        "substructure_across",
        "substructure_eps_tol",
    )
    with petsc_options({}, {k: v for k, v in (options or {}).items() if k in keys}, prefix=prefix):
        db = PETSc.Options()
        raw = {k: db.getString(prefix + k, "") for k in keys}
    check_type_options({prefix + k: v for k, v in raw.items() if v})
    default = SubstructureSettings(0)
    auto = not raw["substructures"] and auto_slabs(n_interior) >= 2
    settings = SubstructureSettings(
        auto_slabs(n_interior) if auto else int(raw["substructures"] or 0),
        float(raw["substructure_f_factor"] or default.f_factor),
        float(raw["substructure_trace_density"] or default.trace_density),
        float(raw["substructure_margin"] or (AUTO_MARGIN if auto else default.margin)),
        float(raw["substructure_compress"] or default.compress),
        int(raw["substructure_zone_degree"] or (AUTO_ZONE_DEGREE if auto else default.zone_degree)),
        float(raw["substructure_across"] or default.across),
        float(raw["substructure_eps_tol"] or default.eps_tol),
    )
    return settings if settings.slabs >= 2 else None


def auto_slabs(n_interior: int) -> int:
    """The slabs a body of ``n_interior`` interior dofs is cut into when no ``substructures`` is
    given: 0 (one factorization) below :data:`AUTO_MIN_DOFS`, else one per :data:`AUTO_SLAB_DOFS`."""
    return 0 if n_interior < AUTO_MIN_DOFS else int(math.ceil(n_interior / AUTO_SLAB_DOFS))


# --- the reduction ---------------------------------------------------------------------------------
def mass_orthonormal_columns(X: np.ndarray, M: PETSc.Mat, tol: float) -> np.ndarray:
    """An M-orthonormal basis of range(X) (M sequential): directions whose Gram eigenvalue, with the
    columns scaled to unit M-norm, is below ``tol`` times the largest are dropped."""
    if X.shape[1] == 0:
        return X
    return X @ gram_basis(X.T @ _mult_local(M, X, MPI.COMM_SELF), tol)


#: a slab's work (factor, modes, statics) grows like its dofs to this power: 1.2M-DOF panel, 16
#: slabs, 2 ranks: 19.6 s at 70k dofs (24 slab modes), 133 s at 244k (61; the zone's slab): 1.53
SLAB_WORK_EXPONENT = 1.5


def slab_owners(dofs: list[int], ranks: int) -> np.ndarray:
    """The rank that reduces each slab: the costliest first to the least loaded rank (Graham's LPT
    rule, within 4/3 of the best balance), a slab's cost dofs^SLAB_WORK_EXPONENT. Dealt in turn
    instead (slab s to rank s mod P), the 157k-DOF panel's 4 slabs of 34k, 20k, 48k and 36k dofs put
    82k against 57k dofs on 2 ranks; weighted by the dof count alone, the 1.2M-DOF panel's zone
    slab (244k dofs) and four small ones went to one rank, 171 s against 88 s."""
    cost = np.asarray(dofs, dtype=float) ** SLAB_WORK_EXPONENT
    load = np.zeros(ranks)
    owners = np.zeros(len(dofs), dtype=np.int64)
    for k in sorted(range(len(dofs)), key=lambda k: (-cost[k], k)):
        owners[k] = int(np.argmin(load))
        load[owners[k]] += cost[k]
    return owners


def _gather_slab_matrices(
    K_ii: PETSc.Mat, M_ii: PETSc.Mat, slab_rows: list[np.ndarray], gamma: np.ndarray
) -> list[tuple]:
    """Each of this rank's slabs' blocks K_ss, M_ss (sequential PETSc) and K_sG, M_sG (CSR) from the
    distributed K_ii, M_ii: one collective MatCreateSubMatrices per matrix for all of them (a rank
    with no slab takes an empty block)."""
    comm = PETSc.COMM_SELF
    rows = [PETSc.IS().createGeneral(r.astype(np.int32), comm=comm) for r in slab_rows]
    empty = not rows
    if empty:
        rows = [PETSc.IS().createGeneral(np.zeros(0, np.int32), comm=comm)]
    cols_g = [PETSc.IS().createGeneral(gamma.astype(np.int32), comm=comm) for _ in rows]
    K_ss, M_ss = K_ii.createSubMatrices(rows, rows), M_ii.createSubMatrices(rows, rows)
    K_sg, M_sg = K_ii.createSubMatrices(rows, cols_g), M_ii.createSubMatrices(rows, cols_g)
    out = [(K_ss[k], M_ss[k], _csr_rows(K_sg[k]), _csr_rows(M_sg[k])) for k in range(len(slab_rows))]
    for obj in [*K_sg, *M_sg, *rows, *cols_g] + ([*K_ss, *M_ss] if empty else []):
        obj.destroy()
    return out


def _dense_zeros(n_loc: int, k: int, comm: MPI.Comm) -> PETSc.Mat:
    A = PETSc.Mat().createDense(((n_loc, PETSc.DETERMINE), (PETSc.DECIDE, k)), comm=comm)
    A.setUp()
    A.getDenseArray()[:] = 0.0
    return A


def _mult_local(A: PETSc.Mat, X: np.ndarray, comm: MPI.Comm) -> np.ndarray:
    """The owned rows of A X for a distributed AIJ A and the owned rows of a dense X."""
    if X.shape[1] == 0:
        return np.zeros((A.getLocalSize()[0], 0))
    Xm = dense_from_rows(X, comm)
    Y = A.matMult(Xm)
    out = np.array(Y.getDenseArray(), copy=True)
    Xm.destroy()
    Y.destroy()
    return out


@dataclass
class _Slab:
    """One slab on the rank that owns it: its global interior rows, its matrices (sequential), the
    basis rows B (all its rows x its columns) and the global Ritz index of each column."""

    index: int
    rows: np.ndarray
    K_ss: PETSc.Mat
    M_ss: PETSc.Mat
    K_sg: sp.csr_matrix
    M_sg: sp.csr_matrix
    B: np.ndarray
    used: np.ndarray  #: which shared columns (zone statics, traces) reach the slab
    n_own: int  #: the slab's own columns (modes, second-order statics)
    first_blocks: tuple | None  #: (B^T K_ss B, B^T M_ss B) of the first pass until projected (:func:`_slab_blocks`)
    stats: dict
    #: the global Ritz index of each column of B (numbered by _first_projection)
    cols: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    projected: int = 0  #: columns of B already in K_V, M_V (see _project_slab)
    n_new: int = 0  #: columns the second pass added

    def release_matrices(self) -> None:
        """Free the slab's matrices (after the last projection: the Rayleigh-Ritz, the recovery
        and the expansion read only the basis rows B)."""
        if self.K_ss is not None:
            self.K_ss.destroy()
            self.M_ss.destroy()
        self.K_ss = self.M_ss = self.K_sg = self.M_sg = None

    def release(self) -> None:
        """Free the slab's matrices and basis rows (after the expansion: B is left empty)."""
        self.release_matrices()
        self.B = np.zeros((len(self.rows), 0))


def _release_slab_matrices(slabs: list[_Slab]) -> None:
    """Free every slab's matrices once the last projection has read them: the liner panel's
    reduction peaked as its expansion began, with the ~8 slabs' K_ss and M_ss of each rank still
    held beside Phi (1 GB a rank); the Rayleigh-Ritz and the expansion need the basis rows alone."""
    for sl in slabs:
        sl.release_matrices()
    return_freed_memory()


def _solve(ksp: PETSc.KSP, rhs: np.ndarray, chunk: int = 128) -> np.ndarray:
    """A^-1 rhs with a factored sequential KSP (multi-right-hand-side solves of ``chunk`` columns:
    the PETSc copies stay small)."""
    out = np.empty_like(rhs)
    F = ksp.getPC().getFactorMatrix()
    for j in range(0, rhs.shape[1], chunk):
        R = dense_from_rows(np.ascontiguousarray(rhs[:, j : j + chunk]), MPI.COMM_SELF)
        X = R.duplicate()
        F.matSolve(R, X)
        out[:, j : j + chunk] = X.getDenseArray()
        R.destroy()
        X.destroy()
    return out


def _peak_rss_gb() -> float:
    """This process's peak resident memory so far (GB; Linux reports kB)."""
    return round(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1e6, 3)


def _csr_rows(A: PETSc.Mat) -> sp.csr_matrix:
    """The owned rows of an AIJ matrix as scipy CSR (global column indices; a sequential one whole)."""
    indptr, indices, data = A.getValuesCSR()
    return sp.csr_matrix((data, indices, indptr), shape=(A.getLocalSize()[0], A.getSize()[1]))


def _global_rows(A: sp.csr_matrix, r0: int, n: int, comm: MPI.Comm) -> sp.csr_matrix:
    """Every rank's rows of a sparse matrix (owned rows from ``r0``) on every rank, n rows."""
    coo = A.tocoo()
    parts = comm.allgather((coo.row + r0, coo.col, coo.data))
    return sp.csr_matrix(
        (
            np.concatenate([p[2] for p in parts]),
            (np.concatenate([p[0] for p in parts]), np.concatenate([p[1] for p in parts])),
        ),
        shape=(n, A.shape[1]),
    )


def _serial_options(options: dict[str, str] | None, eps_tol: float) -> dict[str, str]:
    """A slab is factored by one rank: CHOLMOD unless another package was asked for; its modes are
    converged to ``eps_tol`` (``substructure_eps_tol``; a command-line ``eps_tol`` still wins)."""
    opts = dict(options or {})
    if opts.get("pc_factor_mat_solver_type", "mumps") == "mumps":
        opts["pc_factor_mat_solver_type"] = "cholmod"
    opts["eps_tol"] = repr(eps_tol)
    return opts


@dataclass(frozen=True)
class SlabReduction:
    """What :func:`substructured_modes` gives for a body's interior (module docstring)."""

    Psi: PETSc.Mat | None  #: constraint modes (dense, n_i x n_b); None with zone-interface patterns
    Phi: np.ndarray  #: owned rows of the modes (then the pattern vectors), column-major
    flex: PETSc.Mat | None  #: R A_b (dense, n_i x n_b); None with zone-interface patterns
    freq: np.ndarray  #: Phi's frequencies (Hz)
    n_patterns: int  #: pattern vectors at the end of Phi
    next: float  #: the lowest Ritz frequency not kept (nan if none)
    residual: float  #: ||K_ii Psi + C|| / ||C|| (0 without Psi)
    stats: dict  #: slabs, cuts, columns and the phases' times (s)
    recovery: dict | None  #: the Ritz-space output recovery (:func:`ritz_recovery`)
    grams: tuple | None  #: (Phi^T M_ii Phi, Phi^T K_ii Phi) from the Ritz space (patterns)


@dataclass(frozen=True)
class SlabLayout:
    """The interior cut into slabs, known alike on every rank: the cut, the interface Gamma (owned
    local rows ``gamma``; every rank's in ``gamma_glob``, global), its traces ``T`` (owned rows) and
    ``T_full`` (all rows), ``[C | D]`` with every rank's rows (``CD_full``), each slab's global rows
    off Gamma, the slabs that have rows and this rank's. Ritz columns: [zone statics (n_b) |
    traces (n_t) | the slabs' own]."""

    cut: SlabCut
    gamma: np.ndarray
    faces: list
    T: sp.csr_matrix
    T_full: sp.csr_matrix
    gamma_glob: np.ndarray
    CD_full: sp.csr_matrix
    slab_rows: list[np.ndarray]
    slab_ids: list[int]
    my_ids: list[int]
    r0: int
    n_i: int
    n_loc: int
    n_b: int

    @property
    def n_t(self) -> int:
        return self.T.shape[1]

    @property
    def t_idx(self) -> np.ndarray:
        """The traces' Ritz columns."""
        return self.n_b + np.arange(self.n_t)


@dataclass
class _RitzSystem:
    """The dense Ritz matrices K_V, M_V, C_V (rank 0's; None elsewhere), ``n_cols`` columns, and the
    last Rayleigh-Ritz's results; dropped (set to None) once the expansion no longer needs them."""

    KV: np.ndarray | None
    MV: np.ndarray | None
    CV: np.ndarray | None
    n_cols: int
    ritz: dict | None = None


def substructured_modes(
    K_ii: PETSc.Mat,
    M_ii: PETSc.Mat,
    C: sp.csr_matrix,
    D: sp.csr_matrix,
    coords: np.ndarray,
    comps: np.ndarray,
    f_cut: float,
    shear_speed: float,
    settings: SubstructureSettings,
    prefix: str,
    options: dict[str, str] | None = None,
    keep_away: np.ndarray | None = None,
    patterns: bool = False,
    zone_couplings: tuple[sp.csr_matrix, sp.csr_matrix] | None = None,
    recovery_rows: np.ndarray | None = None,
    release: bool = False,
) -> SlabReduction:
    """Psi, Phi, R A_b, frequencies (Hz), the next frequency, Psi's relative residual and statistics
    from the slab-wise Ritz basis (module docstring; :class:`SlabReduction`). ``C``, ``D``: owned rows
    of K_iz G and M_iz G on the interface coordinates (sparse: only the zone's slab has rows there);
    ``coords``, ``comps``: each owned interior dof's node coordinates and displacement component;
    ``shear_speed`` (m/s) sets the margin and the traces' degrees; ``keep_away`` (k x 3, m): points
    the cuts keep the margin from (the gauges). Collective.

    ``patterns``: the columns of C and D are the couplings of zone-interface patterns
    (:func:`~.interface_patterns.zone_interface_patterns`), not of the zone's coordinates: their
    static responses are then returned as extra columns of Phi (made M-orthogonal to the modes and
    Ritz-diagonalized, ``n_patterns`` of them) and Psi and R A_b are None. The output rows are then
    recovered from the Ritz space (:func:`ritz_recovery`): give ``zone_couplings`` (the owned rows of
    K_iz G and M_iz G on the zone's interface coordinates) and ``recovery_rows`` (global interior
    rows the output rows reach). ``release`` destroys K_ii and M_ii once the slabs hold their blocks.

    Two passes over the slabs (steps 1-3 and step 4 of the module docstring); each rank reduces its
    slabs alone (CHOLMOD), one slab's factor at a time, and only the Ritz matrices (summed on rank 0,
    which solves the Rayleigh-Ritz and broadcasts its results) and the final rows travel."""
    comm = K_ii.getComm().tompi4py()
    t_start = time.perf_counter()
    lay = _slab_layout(K_ii, C, D, coords, comps, f_cut, shear_speed, settings, keep_away, comm)
    serial_opts = _serial_options(options, settings.eps_tol)
    # pass 1: every rank gathers the rows of all its slabs in one collective call (a slab's matrices
    # are kept to the end anyway), then reduces them alone: no rank waits for another between slabs
    t_pass1 = time.perf_counter()
    gathered = _gather_slab_matrices(K_ii, M_ii, [lay.slab_rows[s] for s in lay.my_ids], lay.gamma_glob)
    KT_gg, MT_gg = _gamma_blocks(K_ii, M_ii, lay, release, comm)
    mine = [
        _first_pass_slab(s, mats, lay, settings, f_cut, prefix, serial_opts, comm.rank)
        for s, mats in zip(lay.my_ids, gathered)
    ]
    del gathered
    phase = {"pass1_s": time.perf_counter() - t_pass1}  # this rank's slabs (before any wait)
    t0 = time.perf_counter()
    system = _first_projection(mine, lay, KT_gg, MT_gg, comm)
    phase["project_s"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    system.ritz = _ritz_on_root(system.KV, system.MV, system.CV, lay.n_b, f_cut, comm)
    phase["ritz_s"] = time.perf_counter() - t0
    _second_pass(mine, lay, system, settings, f_cut, prefix, serial_opts, phase, comm)
    return_freed_memory()  # the second pass's factors and solves, before the expansion
    t0 = time.perf_counter()
    m, freq, ritz_rank = system.ritz["m"], system.ritz["freq"], system.ritz["rank"]
    Psi, Phi, flex, f_pat, recovery, grams = _expand(mine, lay, system, patterns, zone_couplings, recovery_rows, comm)
    phase["expand_s"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    residual = constraint_residual(K_ii, Psi, C, comm) if lay.n_b and Psi is not None else 0.0
    phase["residual_s"] = time.perf_counter() - t0
    stats = _slab_statistics(mine, lay, phase, system.n_cols, ritz_rank, patterns, len(f_pat), t_start, comm)
    if comm.rank == 0:
        log.info(
            "substructures %s: %d slabs along %s (cuts %s m; %d cut again across) on %d rank(s), %d "
            "interface dofs -> %d traces, %d slab modes, Ritz basis %d: %d modes under f_cut in %.3g s",
            prefix,
            len(lay.slab_ids),
            stats["axis"],
            ", ".join(f"{c:.4g}" for c in lay.cut.cuts),
            len(lay.cut.across),
            comm.size,
            stats["interface_dofs"],
            lay.n_t,
            stats["slab_modes"],
            system.n_cols,
            m,
            stats["total_s"],
        )
    return SlabReduction(
        Psi,
        Phi,
        flex,
        np.concatenate([freq[:m], f_pat]) if patterns else freq[:m],
        len(f_pat) if patterns else 0,
        float(freq[m]) if m < len(freq) else math.nan,
        residual,
        stats,
        recovery,
        grams,
    )


def _slab_layout(
    K_ii: PETSc.Mat,
    C: sp.csr_matrix,
    D: sp.csr_matrix,
    coords: np.ndarray,
    comps: np.ndarray,
    f_cut: float,
    shear_speed: float,
    settings: SubstructureSettings,
    keep_away: np.ndarray | None,
    comm: MPI.Comm,
) -> SlabLayout:
    """Step 1: the cuts, the interface Gamma and its traces, and which rank reduces which slab."""
    wavelength = shear_speed / f_cut
    zone_rows = np.nonzero(np.diff(C.indptr))[0]
    cut = cut_slabs(coords, zone_rows, settings.slabs, settings.margin * wavelength, comm, keep_away, settings.across)
    labels = cut.labels
    nxt = interface_next(K_ii, labels)
    on_gamma = nxt >= 0
    r0 = K_ii.getOwnershipRange()[0]
    n_i = K_ii.getSize()[0]
    gamma = np.nonzero(on_gamma)[0]
    face, faces = interface_faces(labels, nxt, comm)
    traces = polynomial_traces(
        coords[gamma],
        comps[gamma],
        face,
        [cut.normal(a, b) for a, b in faces],
        wavelength,
        settings.trace_density,
        comm,
    )
    T = sp.hstack(traces).tocsr() if traces else sp.csr_matrix((len(gamma), 0))
    n_t = T.shape[1]
    # what every slab's owner needs whole: Gamma's global rows and traces, the sparse couplings
    gamma_glob = np.concatenate(comm.allgather((r0 + gamma).astype(np.int64)))
    # sparse: a Gamma row has only its own cut's traces (dense, 1.6 GB a rank at 1.2M DOFs, 15 cuts)
    T_full = sp.vstack(comm.allgather(T)).tocsr() if n_t else sp.csr_matrix((len(gamma_glob), 0))
    CD_full = _global_rows(sp.hstack([C, D]).tocsr(), r0, n_i, comm)
    slab_rows = [
        np.concatenate(comm.allgather((r0 + np.nonzero((labels == s) & ~on_gamma)[0]).astype(np.int64)))
        for s in range(cut.pieces)
    ]
    slab_ids = [s for s in range(cut.pieces) if len(slab_rows[s])]
    owners = slab_owners([len(slab_rows[s]) for s in slab_ids], comm.size)
    my_ids = [s for s, o in zip(slab_ids, owners) if o == comm.rank]
    return SlabLayout(
        cut, gamma, faces, T, T_full, gamma_glob, CD_full, slab_rows, slab_ids, my_ids, r0, n_i, len(labels), C.shape[1]
    )


def _gamma_blocks(
    K_ii: PETSc.Mat, M_ii: PETSc.Mat, lay: SlabLayout, release: bool, comm: MPI.Comm
) -> tuple[np.ndarray, np.ndarray]:
    """Gamma's own block of the Ritz matrices, T^T A_GG T with the owned rows of A_GG (columns
    numbered as gamma_glob, the IS's order); then (``release``) K_ii and M_ii are destroyed."""
    is_gamma = PETSc.IS().createGeneral((lay.r0 + lay.gamma).astype(np.int32), comm=comm)
    Kgg, Mgg = K_ii.createSubMatrix(is_gamma, is_gamma), M_ii.createSubMatrix(is_gamma, is_gamma)
    KT_gg, MT_gg = (reduce_array((lay.T.T @ (_csr_rows(A) @ lay.T_full)).toarray(), MPI.SUM, comm) for A in (Kgg, Mgg))
    for obj in (Kgg, Mgg, is_gamma) + ((K_ii, M_ii) if release else ()):
        obj.destroy()
    return KT_gg, MT_gg


def _first_pass_slab(
    s: int,
    matrices: tuple,
    lay: SlabLayout,
    settings: SubstructureSettings,
    f_cut: float,
    prefix: str,
    serial_opts: dict[str, str],
    rank: int,
) -> _Slab:
    """Step 2 for slab ``s`` (its K_ss, M_ss, K_sG, M_sG in ``matrices``): the static responses to
    the zone coordinates and their inertia, the trace extensions and the fixed-interface modes,
    all with the slab's one factorization, and the slab's own blocks of K_V, M_V."""
    K_ss, M_ss, K_sg_csr, M_sg_csr = matrices
    n_b, n_t, T_full = lay.n_b, lay.n_t, lay.T_full
    rows = lay.slab_rows[s]
    ts = time.perf_counter()
    ksp = create_factored_solver(K_ss, prefix, serial_opts)
    t_factor = time.perf_counter() - ts
    # the traces that reach the slab: those of the cuts its rows couple to (a dense K_sG T of
    # every trace would be ~1 GB a slab at the plan's 1.2M DOFs)
    C_s = lay.CD_full[rows][:, :n_b]
    used_t = np.bincount(T_full[np.unique(K_sg_csr.indices)].indices, minlength=n_t) > 0
    used = np.concatenate([np.bincount(C_s.indices, minlength=n_b) > 0, used_t])
    rhs = sp.hstack([C_s[:, used[:n_b]], K_sg_csr @ T_full[:, used_t]]).tocsr()
    X = -_solve(ksp, rhs.toarray()) if used.any() else np.zeros((len(rows), 0))
    # second-order statics: the response to the inertia of the slab's zone statics, M_ss Z_s + M_sz
    n_zone = int(used[:n_b].sum())
    D_s = lay.CD_full[rows][:, n_b:][:, used[:n_b]].tocsr()
    X2 = (
        _solve(ksp, _mult_local(M_ss, X[:, :n_zone], MPI.COMM_SELF) + D_s.toarray())
        if n_zone
        else np.zeros((len(rows), 0))
    )
    t_static = time.perf_counter() - ts - t_factor
    te = time.perf_counter()
    f_s, vecs, _ = compute_modes(
        K_ss, M_ss, ksp, settings.f_factor * f_cut, None, prefix, serial_opts, count_first=True
    )
    t_eigen = time.perf_counter() - te
    Phi_s = np.column_stack([v.getArray(readonly=True) for v in vecs]) if vecs else np.zeros((len(rows), 0))
    for v in vecs:
        v.destroy()
    ksp.destroy()
    return_freed_memory()  # the slab's factors and Krylov basis: the next slab's room
    B = np.hstack([X, Phi_s, X2])
    del X, X2
    tb = time.perf_counter()
    blocks = _slab_blocks(K_ss, M_ss, B, -rhs, D_s, Phi_s.shape[1])
    del rhs, D_s
    slab = _Slab(
        s,
        rows,
        K_ss,
        M_ss,
        K_sg_csr,
        M_sg_csr,
        B,
        used,
        Phi_s.shape[1] + n_zone,
        blocks,
        {
            "slab": s,
            "rank": rank,
            "dofs": len(rows),
            "modes": int(Phi_s.shape[1]),
            "static_columns": int(used.sum()) + n_zone,
            "factor_s": round(t_factor, 3),
            "statics_s": round(t_static, 3),
            "eigen_s": round(t_eigen, 3),
            "blocks_s": round(time.perf_counter() - tb, 3),
            "total_s": round(time.perf_counter() - ts, 3),
            "peak_rss_gb": _peak_rss_gb(),
        },
    )
    log.info("substructures %s: slab %d on rank %d: %s", prefix, s, rank, slab.stats)
    return slab


def _first_projection(
    mine: list[_Slab], lay: SlabLayout, KT_gg: np.ndarray, MT_gg: np.ndarray, comm: MPI.Comm
) -> _RitzSystem:
    """Step 3's matrices after the first pass: the Ritz columns numbered slab by slab on every rank
    alike, and K_V, M_V, C_V on rank 0."""
    layout = sorted(x for part in comm.allgather([(sl.index, sl.used, sl.n_own) for sl in mine]) for x in part)
    n_cols, cols_of = lay.n_b + lay.n_t, {}
    for s, used, own in layout:
        cols_of[s] = np.concatenate([np.nonzero(used)[0], n_cols + np.arange(own)])
        n_cols += own
    for sl in mine:
        sl.cols = cols_of[sl.index]
    # the dense Ritz matrices live on rank 0 alone, which solves the Rayleigh-Ritz and broadcasts
    # its results: the same numbers as every rank solving it (the sums are one reduction), without
    # the other ranks' copies and workspaces (~1 GB a rank at the plan's 1.2M DOFs, 4,368 columns)
    KV = MV = CV = None
    t_idx, n_b = lay.t_idx, lay.n_b
    if comm.rank == 0:
        KV, MV, CV = np.zeros((n_cols, n_cols)), np.zeros((n_cols, n_cols)), np.zeros((n_cols, 2 * n_b))
        KV[np.ix_(t_idx, t_idx)], MV[np.ix_(t_idx, t_idx)] = KT_gg, MT_gg
        CV[t_idx] = (lay.CD_full[lay.gamma_glob].T @ lay.T_full).T.toarray()  # replicated data: no sum
    KV, MV, CV = _project(mine, lay.T_full, t_idx, lay.CD_full, (KV, MV, CV), comm, n_cols=n_cols, n_rhs=2 * n_b)
    return _RitzSystem(KV, MV, CV, n_cols)


def _second_pass(
    mine: list[_Slab],
    lay: SlabLayout,
    system: _RitzSystem,
    settings: SubstructureSettings,
    f_cut: float,
    prefix: str,
    serial_opts: dict[str, str],
    phase: dict[str, float],
    comm: MPI.Comm,
) -> None:
    """Step 4: each slab's static response (Gamma held) to the inertia of the first pass's modes and
    constraint modes, M_ii Phi and A_b = M_ii Psi + M_ib (one step of inverse iteration on them),
    joins the basis; ``system`` projected and solved again. A slab's rows of M_ii V couple its own
    rows and Gamma's only. The slabs' matrices are freed after the last projection."""
    n_b, ritz = lay.n_b, system.ritz
    assert ritz is not None, "the second pass follows the first Rayleigh-Ritz"
    if not n_b + ritz["m"]:
        _release_slab_matrices(mine)  # the first projection was the last
        return
    t0 = time.perf_counter()
    coef = np.hstack([ritz["psi"], ritz["phi"]])
    first_gamma = lay.T_full @ coef[lay.t_idx]
    for sl in mine:
        ts = time.perf_counter()
        load = _mult_local(sl.M_ss, sl.B @ coef[sl.cols], MPI.COMM_SELF) + sl.M_sg @ first_gamma
        load[:, :n_b] += lay.CD_full[sl.rows][:, n_b:].toarray()
        ksp = create_factored_solver(sl.K_ss, prefix, serial_opts)
        X3 = _solve(ksp, load)
        del load
        ksp.destroy()
        if settings.compress > 0:
            # the responses to ~n_b + m loads are nearly dependent away from the zone (157k-DOF
            # panel, 4 slabs: 301 columns a slab -> 97-278, the Ritz basis 2193 -> 1602)
            X3 = mass_orthonormal_columns(X3, sl.M_ss, settings.compress)
        sl.B = np.hstack([sl.B, X3])
        sl.n_new = X3.shape[1]
        sl.stats["inertia_statics_s"] = round(time.perf_counter() - ts, 3)
        sl.stats["inertia_columns"] = int(X3.shape[1])
        sl.stats["peak_rss_gb_pass2"] = _peak_rss_gb()
    counts = dict(x for part in comm.allgather([(sl.index, sl.n_new) for sl in mine]) for x in part)
    offsets = np.cumsum([0] + [counts[s] for s in lay.slab_ids])
    for sl in mine:
        k = lay.slab_ids.index(sl.index)
        sl.cols = np.concatenate([sl.cols, system.n_cols + offsets[k] + np.arange(sl.n_new)])
    phase["pass2_s"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    system.n_cols += int(offsets[-1])
    system.KV, system.MV, system.CV = _project(
        mine,
        lay.T_full,
        lay.t_idx,
        lay.CD_full,
        (system.KV, system.MV, system.CV),
        comm,
        n_cols=system.n_cols,
        n_rhs=2 * n_b,
    )
    _release_slab_matrices(mine)
    phase["project_s"] += time.perf_counter() - t0
    t0 = time.perf_counter()
    system.ritz = None  # the first Rayleigh-Ritz's results, before the second's
    system.ritz = _ritz_on_root(system.KV, system.MV, system.CV, n_b, f_cut, comm)
    phase["ritz_s"] += time.perf_counter() - t0


def _expand(
    mine: list[_Slab],
    lay: SlabLayout,
    system: _RitzSystem,
    patterns: bool,
    zone_couplings: tuple[sp.csr_matrix, sp.csr_matrix] | None,
    recovery_rows: np.ndarray | None,
    comm: MPI.Comm,
) -> tuple:
    """Psi, Phi, R A_b (or with ``patterns``: Phi with the pattern vectors, their frequencies, the
    Ritz-space recovery and Grams) expanded from the Ritz coefficients, straight into their final
    storage; each slab's rows sent to the ranks owning them. The dense Ritz matrices of ``system``
    are dropped before the rows travel."""
    ritz, KV, MV, T, t_idx, n_loc, n_b = system.ritz, system.KV, system.MV, lay.T, lay.t_idx, lay.n_loc, lay.n_b
    assert ritz is not None, "the expansion follows the last Rayleigh-Ritz"
    m = ritz["m"]
    recovery = grams = None
    f_pat = np.zeros(0)
    targets: tuple[np.ndarray, ...]  # the results' storage, and their Ritz coefficients
    parts: tuple[np.ndarray, ...]
    if patterns:
        f_pat, c_pat, grams = computed_on_root(
            comm, lambda kv=KV, mv=MV, rz=ritz: _patterns_and_grams(_on_root(kv), _on_root(mv), rz)
        )
        A = np.hstack([ritz["phi"], c_pat])
        if zone_couplings is not None:
            recovery = ritz_recovery(
                mine,
                lay.T_full,
                t_idx,
                lay.gamma_glob,
                ritz,
                MV,
                A,
                _global_rows(sp.hstack(zone_couplings).tocsr(), lay.r0, lay.n_i, comm),
                np.asarray(recovery_rows if recovery_rows is not None else [], dtype=np.int64),
                system.n_cols,
                comm,
            )
        Psi = flex = None
        Phi = np.zeros((n_loc, m + len(f_pat)), order="F")  # PETSc's dense layout: shared, not copied
        targets, parts = (Phi,), (A,)
    else:
        Psi, flex = _dense_zeros(n_loc, n_b, comm), _dense_zeros(n_loc, n_b, comm)
        Phi = np.zeros((n_loc, m), order="F")
        targets, parts = (Psi.getDenseArray(), flex.getDenseArray(), Phi), (ritz["psi"], ritz["flex"], ritz["phi"])
    for out, c in zip(targets, parts):
        out[lay.gamma] = T @ c[t_idx]
    starts = np.array(comm.allgather(lay.r0) + [lay.n_i])
    bounds = np.cumsum([0] + [c.shape[1] for c in parts])

    def put(local_rows: np.ndarray, block: np.ndarray) -> None:
        for out, a, b in zip(targets, bounds[:-1], bounds[1:]):
            out[local_rows] = block[:, a:b]

    coef = np.hstack(parts)
    # the dense Ritz matrices: not needed for the expansion
    del KV, MV, ritz, parts
    system.KV = system.MV = system.CV = system.ritz = None
    if patterns:
        del A

    def pieces():
        """This rank's slabs' rows of the results, EXPAND_ROWS at a time; a slab's matrices and
        basis freed once its rows are out (they are not needed after the projections)."""
        for sl in mine:
            c = coef[sl.cols]
            for j in range(0, len(sl.rows), EXPAND_ROWS):
                yield sl.rows[j : j + EXPAND_ROWS], sl.B[j : j + EXPAND_ROWS] @ c
            sl.release()
            return_freed_memory()

    deliver_rows(pieces(), starts, coef.shape[1], put, comm)
    for M in (Psi, flex):
        if M is not None:
            M.assemble()
    return Psi, Phi, flex, f_pat, recovery, grams


def _slab_statistics(
    mine: list[_Slab],
    lay: SlabLayout,
    phase: dict[str, float],
    n_cols: int,
    ritz_rank,
    patterns: bool,
    n_pattern_vectors: int,
    t_start: float,
    comm: MPI.Comm,
) -> dict:
    """The slabs' statistics (every rank's slabs) and the phases' times (s): this rank's slabs, and on
    rank 0 the projections, the dense Ritz solves, the second pass, the expansion and Psi's residual."""
    slab_stats = sorted(
        (x for part in comm.allgather([sl.stats for sl in mine]) for x in part), key=lambda x: x["slab"]
    )
    n_b = lay.n_b
    return {
        "slabs": slab_stats,
        **lay.cut.stats(),
        "interface_faces": len(lay.faces),
        "interface_dofs": len(lay.gamma_glob),
        "traces": lay.n_t,
        **(
            {"zone_patterns": n_b, "pattern_vectors": n_pattern_vectors} if patterns else {"interface_coordinates": n_b}
        ),
        "ritz_columns": n_cols,
        "ritz_rank": ritz_rank,
        "slab_modes": int(sum(x["modes"] for x in slab_stats)),
        "pass1_s_by_rank": [round(x, 3) for x in comm.allgather(phase.pop("pass1_s"))],
        **{k: round(v, 3) for k, v in phase.items()},
        "total_s": round(time.perf_counter() - t_start, 3),
    }


def ritz_recovery(
    slabs: list[_Slab],
    T_full: sp.csr_matrix,
    t_idx: np.ndarray,
    gamma_glob: np.ndarray,
    ritz: dict,
    MV: np.ndarray | None,
    A: np.ndarray,
    CDz: sp.csr_matrix,
    rows: np.ndarray,
    n_cols: int,
    comm: MPI.Comm,
) -> dict:
    """Output recovery without constraint modes, from the Ritz space V (replicated, small).

    The interior obeys K_ii u_i = -C q - D q'' - M_ii u_i'' (no load of its own; C = K_iz G,
    D = M_iz G on the zone's interface coordinates). With K_ii^-1 replaced by its Galerkin image in
    V, V H V^T (H = K_V^+), and the interior's reduced acceleration V A x'' (A: the coefficients of
    the body's vectors, x their coordinates), an output row a reads
    a u_i = (a V) [H_C q + H_D q'' + H_M x''], H_C = -H V^T C, H_D = -H V^T D, H_M = -H M_V A:
    mode acceleration for any interior basis (for Craig-Bampton it is Psi q + Phi eta - R A_b q''
    in the Ritz space). Returns ``rows`` (the global interior rows kept), ``V`` (those rows of the
    basis), H_C, H_D and H_M. ``CDz``: [C | D], every rank's rows (global interior numbering);
    ``MV`` rank 0's (None elsewhere)."""
    n_b = CDz.shape[1] // 2
    CV = np.zeros((n_cols, 2 * n_b))
    keep = np.zeros((len(rows), n_cols))
    for sl in slabs:
        CV[sl.cols] += np.asarray((CDz[sl.rows].T @ sl.B).T)
        pos, hit = positions_in(sl.rows, rows)
        keep[np.ix_(np.nonzero(hit)[0], sl.cols)] = sl.B[pos[hit]]
    CV_sum, keep = _sum_on_root(CV, comm), reduce_array(keep, MPI.SUM, comm)
    pos, on_g = positions_in(gamma_glob, rows)  # gamma_glob: the ranks' sorted rows in rank order
    keep[np.ix_(np.nonzero(on_g)[0], t_idx)] = T_full[pos[on_g]].toarray()

    def images():  # K_V, M_V and the eigenpairs are rank 0's
        CV_r = _on_root(CV_sum)
        CV_r[t_idx] += (CDz[gamma_glob].T @ T_full).T.toarray()  # replicated data: no sum
        H = ritz["solve"]  # K_V^+: the final Rayleigh-Ritz's factor
        return -H(CV_r[:, :n_b]), -H(CV_r[:, n_b:]), -H(_on_root(MV) @ A)

    H_C, H_D, H_M = computed_on_root(comm, images)
    return {"rows": rows, "V": keep, "H_C": H_C, "H_D": H_D, "H_M": H_M}


def pattern_vectors(KV: np.ndarray, MV: np.ndarray, ritz: dict) -> tuple[np.ndarray, np.ndarray]:
    """The zone-interface patterns' static responses (Ritz coefficients ``ritz["psi"]``) as extra
    interior vectors beside the Ritz modes: made M_V-orthogonal to them, dependent directions
    dropped, and diagonalized by a Rayleigh-Ritz in their span (so K_V and M_V stay block-diagonal
    between modes and pattern vectors, as for modal truncation augmentation vectors). Their Ritz
    frequencies (Hz) and coefficients."""
    phi, psi = ritz["phi"], ritz["psi"]
    psi = psi - phi @ (phi.T @ (MV @ psi))
    psi = psi - phi @ (phi.T @ (MV @ psi))  # twice: classical Gram-Schmidt's loss of orthogonality
    W = psi @ gram_basis(psi.T @ MV @ psi, DEPENDENT_TOL)
    lam, Y = np.linalg.eigh(W.T @ KV @ W)
    return np.sqrt(np.maximum(lam, 0.0)) / (2 * math.pi), W @ Y


def constraint_residual(K_ii: PETSc.Mat, Psi: PETSc.Mat, C: sp.csr_matrix, comm: MPI.Comm, chunk: int = 64) -> float:
    """||K_ii Psi + C||_F / ||C||_F, in blocks of ``chunk`` columns (no second n_i x n_b array)."""
    P = Psi.getDenseArray()
    num = 0.0
    for j in range(0, P.shape[1], chunk):
        R = _mult_local(K_ii, P[:, j : j + chunk], comm) + C[:, j : j + chunk].toarray()
        num += float(np.sum(R * R))
    num, den = reduce_array(np.array([num, float(C.multiply(C).sum())]), MPI.SUM, comm)
    return math.sqrt(num) / max(math.sqrt(den), 1e-300)


def _slab_blocks(
    K_ss: PETSc.Mat, M_ss: PETSc.Mat, B: np.ndarray, K_X: sp.csr_matrix, D_s: sp.csr_matrix, n_modes: int
) -> tuple[np.ndarray, np.ndarray]:
    """A slab's own blocks B^T K_ss B and B^T M_ss B of its first-pass columns B = [X | Phi_s | X2],
    with K_ss B taken from what the statics solved rather than multiplied out: K_ss X = ``K_X``
    (sparse: the zone couplings and K_sG T, X = -K_ss^-1 [C_s | K_sG T]) and K_ss X2 = M_ss X_z +
    ``D_s`` (the second-order statics' load, X_z the first D_s.shape[1] columns of X); only the
    ``n_modes`` modes' K_ss Phi_s is a product. The statics are most of a slab's columns (liner
    panel: 150-579 against 0-24 modes), so the dense (columns x dofs x columns) product is done
    once, for M, not twice. (K_ss X = K_X to the direct solve's backward error, the rounding of
    the product it replaces.)"""
    MB = _mult_local(M_ss, B, MPI.COMM_SELF)
    PM = MB.T @ B
    n_x, n_zone = K_X.shape[1], D_s.shape[1]
    KPhi = _mult_local(K_ss, B[:, n_x : n_x + n_modes], MPI.COMM_SELF)
    PK = np.vstack([np.asarray(K_X.T @ B), KPhi.T @ B, PM[:n_zone] + np.asarray(D_s.T @ B)])
    return PK, PM


def _project(
    slabs: list[_Slab],
    T_full: sp.csr_matrix,
    t_idx: np.ndarray,
    CD_full: sp.csr_matrix,
    current: tuple,
    comm: MPI.Comm,
    n_cols: int,
    n_rhs: int,
) -> tuple:
    """K_V = V^T K_ii V, M_V = V^T M_ii V and [V^T C | V^T D] (n_cols Ritz columns, n_rhs columns
    of [C | D]) with the columns of each rank's slabs not yet projected (``projected`` onward)
    added to ``current`` (rank 0's matrices, grown to n_cols): a slab's own block and its coupling
    to Gamma (the slabs are uncoupled), summed on rank 0 (the other ranks get None)."""
    KV, MV, CV = np.zeros((n_cols, n_cols)), np.zeros((n_cols, n_cols)), np.zeros((n_cols, n_rhs))
    for sl in slabs:
        new = slice(sl.projected, None)
        B, Bn, cols, cn = sl.B, sl.B[:, new], sl.cols, sl.cols[new]
        for k, (V_, A_, A_g) in enumerate(((KV, sl.K_ss, sl.K_sg), (MV, sl.M_ss, sl.M_sg))):
            # new rows x all columns (the first pass's were formed with the slab: _slab_blocks)
            P = sl.first_blocks[k] if sl.first_blocks is not None else _mult_local(A_, Bn, MPI.COMM_SELF).T @ B
            V_[np.ix_(cn, cols)] += P
            V_[np.ix_(cols, cn)] += P.T
            V_[np.ix_(cn, cn)] -= P[:, new]  # the new-new block once
            G = ((A_g @ T_full).T @ Bn).T
            V_[np.ix_(cn, t_idx)] += G
            V_[np.ix_(t_idx, cn)] += G.T
        CV[cn] += np.asarray((CD_full[sl.rows].T @ Bn).T)
        sl.projected = B.shape[1]
        sl.first_blocks = None
    sums = [_sum_on_root(x, comm) for x in (KV, MV, CV)]
    if comm.rank != 0:
        return None, None, None
    KV, MV, CV = (_on_root(x) for x in sums)
    k = current[0].shape[0]
    KV[:k, :k] += current[0]
    MV[:k, :k] += current[1]
    CV[:k] += current[2]
    for A in (KV, MV):  # symmetrized in place: no second n x n array
        A += A.T
        A *= 0.5
    return KV, MV, CV


def _sum_on_root(a: np.ndarray, comm: MPI.Comm) -> np.ndarray | None:
    """The element-wise sum of every rank's ``a`` on rank 0 (None on the others)."""
    a = np.ascontiguousarray(a, dtype=float)
    if comm.size == 1:
        return a
    out = np.empty_like(a) if comm.rank == 0 else None
    comm.Reduce(a, out, op=MPI.SUM, root=0)
    return out


def _on_root(a: np.ndarray | None) -> np.ndarray:
    """``a``, an array rank 0 holds (a sum of :func:`_sum_on_root`, the dense Ritz matrices), on rank 0."""
    assert a is not None, "an array that only rank 0 holds, read on another rank"
    return a


def _ritz_on_root(KV, MV, CV, n_b: int, f_cut: float, comm: MPI.Comm) -> dict:
    """:func:`~.ritz.rayleigh_ritz` on rank 0 (which holds K_V, M_V, C_V) with the waiting ranks' cores,
    its results broadcast; the solver ``solve`` (K_V^+, for :func:`ritz_recovery`) stays on rank 0."""
    return computed_on_root(
        comm,
        lambda: rayleigh_ritz(KV, MV, CV, n_b, f_cut),
        lambda ritz: {k: v for k, v in ritz.items() if k != "solve"},
    )


def _patterns_and_grams(KV: np.ndarray, MV: np.ndarray, ritz: dict):
    """(frequencies, coefficients) of the pattern vectors (:func:`pattern_vectors`) and the Ritz
    space's Grams (A^T M_V A, A^T K_V A) of A = [phi | pattern coefficients] (rank 0's)."""
    f_pat, c_pat = pattern_vectors(KV, MV, ritz)
    A = np.hstack([ritz["phi"], c_pat])
    return f_pat, c_pat, (A.T @ MV @ A, A.T @ KV @ A)
