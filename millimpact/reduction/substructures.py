"""Substructured (two-level) Craig-Bampton of a body's interior: the constraint modes Psi and the
fixed-interface modes Phi from a Ritz basis built slab by slab, without factorizing the whole interior.

Why: one Cholesky factorization of a large region fills like N^1.47 (liner panel: 78M nonzeros at
147k region dofs, 1.52e9 and 14.4 GB at 1.12M, docs/scenes.md); the eigensolver's basis (~5x the
modes) and the inertia count's second factorization come on top. Cut into S slabs, each factor is
~S^-1.47 of that and only one slab's is held at a time.

The method (component mode synthesis: Hurty 1965, Craig and Bampton 1968; with the interface
reduced, Krattiger et al., "Interface reduction for Hurty/Craig-Bampton substructured models:
review and improvements", Mech. Syst. Signal Process. 114 (2019) 579-603):

1. The interior's dofs are cut into S slabs along the longest extent of the body, at quantiles of
   the dof count, moved at least ``margin`` (half a shear wavelength at f_cut) away from the dofs
   coupled to the contact zone and from the gauges; a slab of more than ``across`` x the mean
   (the zone's) is cut again across (:mod:`.slab_cuts`; "slab" below is any piece). The dofs of a
   slab that couple to a later slab form the interface Gamma; the slabs' remaining dofs P_s are
   then uncoupled from each other: K_ii = [diag(K_ss)  K_PG; K_GP  K_GG].
2. A Ritz basis V of the interior, per slab s (the slab's factorization serves all three):

   * fixed-interface modes of P_s (Gamma and the zone held) up to ``f_factor`` x f_cut;
   * static responses to the zone coordinates, Z_s = -K_ss^-1 C_s (zero on Gamma), and to their
     inertia, K_ss^-1 (M_ss Z_s + M_sz);
   * trace extensions: Gamma moves as t_k, the slabs follow statically, X_s = -K_ss^-1 K_sG t_k.
     The traces t_k are per interface face and per displacement component tensor Legendre
     polynomials of the face's two in-plane coordinates, degree ``trace_density`` x (extent /
     shear wavelength at f_cut) in each (``trace_density`` 0: every Gamma dof its own trace, the
     exact interface).
3. Rayleigh-Ritz of the interior in span(V) (dense, a few thousand columns): K_V = V^T K_ii V,
   M_V = V^T M_ii V, C_V = V^T C (columns scaled to unit M-norm first). Then Psi = V psi with
   K_V psi = -C_V, and Phi = V phi with K_V phi = lambda M_V phi, lambda <= (2 pi f_cut)^2.
4. One step of inverse iteration: each slab's static response (Gamma held) to the inertia of the
   first Ritz modes and constraint modes, K_ss^-1 (M_ii [Phi, Psi] + [0, M_ib])_s, joins V and
   step 3 is repeated (each slab's new columns first made M-orthonormal, dropping directions under
   ``compress`` x the largest eigenvalue of their Gram: the responses to the ~n_b + m loads are
   nearly dependent away from the zone; 157k-DOF panel, 4 slabs: 301 columns a slab -> 97-278).
   This is what makes the modes near f_cut accurate with few slab modes
   (paper-rig test mesh, every Gamma dof a trace: the highest mode 0.84 % high with slab modes
   to 2 f_cut and no step 4, 0.018 % with them to 1.5 f_cut and step 4), and it puts
   K_ii^-1 A_b, which the mode-acceleration rows need, in the span (R A_b 18 % -> 0.24 %).

With every Gamma dof as a trace, Psi is the exact -K_ii^-1 C (the span holds it); with polynomial
traces it is the Galerkin approximation, and the Ritz frequencies are upper bounds of the exact
ones either way (Rayleigh's principle): a mode just under f_cut can rise above it and drop out
(coarse liner panel: 160-162 modes against 164).

Zone-interface patterns (``substructure_zone_degree`` d >= 1; 0, the default, keeps the exact
constraint modes). The n_b constraint modes Psi drive the cost of the statics, the second pass,
the projections and the expansion (n_b = 583 at the plan's 1.2M DOFs; every dense n_i x n_b array
is 5.2 GB there). With patterns the interior's vectors are instead the static responses
X = -K_ii^-1 K_iz W to p smooth interface motions W (per displacement component the monomials of
total degree <= d in the interface nodes' coordinates: the rigid motions among them; p = 60 at
d = 3; :mod:`.interface_patterns`), with coordinates of their own beside the modes (made M-orthogonal to them and
Ritz-diagonalized: :func:`pattern_vectors`); the zone couples to them through K_iz and M_iz only
(characteristic-constraint-mode-like interface reduction: Castanier, Tan and Pierre, AIAA J. 39
(2001) 1182-1187, and the review of Krattiger et al. above). A Ritz approximation: the statics
are exact once the patterns span the interface (paper-rig test mesh: 258 interface dofs, d = 8)
and stiffer before (compliance -3.7e-3 at d = 1, -6.0e-5 at d = 2, -3.2e-6 at d = 4). The output
rows are then recovered in the Ritz space (:func:`ritz_recovery`: the interior's static response to
the zone's motion and to all inertia, a displacement term as well as an acceleration term).

Options (prefix ``impact_reduction_<body>_``): ``substructures`` S (0 or 1: one factorization,
:mod:`.craig_bampton`), ``substructure_f_factor`` (1.5), ``substructure_trace_density`` (4),
``substructure_margin`` (0.5 shear wavelengths at f_cut between a cut and the zone-coupled dofs
or a gauge: closer, the static response to the zone varies too fast for the polynomial traces;
the coarse panel's bolt gauge was off by 3x with a cut next to it), ``substructure_compress``
(1e-12; 0 keeps every column of step 4), ``substructure_zone_degree`` (0), ``substructure_across``
(2; 0 keeps the slabs whole), ``substructure_eps_tol`` (1e-4: the slabs' modes are Ritz vectors,
converged more loosely than the body's modes, :data:`SLAB_EPS_TOL`).

Under MPI each rank takes whole slabs, the costliest first to the least loaded rank
(:func:`slab_owners`), gathers all its slabs' rows in one collective call and then works alone
until the Ritz matrices are summed on rank 0, which solves the dense Rayleigh-Ritz and broadcasts
its results (the other ranks hold no copy of K_V, M_V: ~1 GB a rank at 4,368 columns). 157k-DOF
panel, 4 slabs (``benchmarks/panel_scaling.py --h-far 0.025 --slabs 4``): 97.8 s at 1 rank,
62.9 s at 2 (1.55x; one factorization beside it 90.6 -> 69.4 s, 1.30x); with the slabs dealt in
turn and gathered round by round it was 1.41x. The slabs' factorizations and eigensolvers read the
body's own options (``pc_``, ``eps_``, ``block_krylov_size``). The mode-acceleration output rows
take R A_b from the Ritz space (:class:`~.reduced_model.BodyReduction` ``residual_b``) instead of
K_ii's factorization.

Measured (``benchmarks/panel_substructures.py``, coarse liner panel, 31k P2 DOFs, 4 slabs,
defaults): F_max -0.04 %, t_c -0.12 %, e +0.2 %, the bolt and root gauges -1.9 % / +2.1 % from
the one-factorization run (every Gamma dof a trace, 3 slabs: all within 0.005 %); docs/scenes.md
has the 157k-DOF rows.
"""
from __future__ import annotations

import logging
import math
import resource
import time
from dataclasses import dataclass
from typing import Optional

import numpy as np
import scipy.sparse as sp
from mpi4py import MPI
from petsc4py import PETSc

from ..integration.solvers import check_type_options, create_factored_solver, petsc_options, return_freed_memory
from .distributed import (DEPENDENT_TOL, computed_on_root, deliver_rows, dense_from_rows, gram_basis, positions_in,
                          reduce_array)
from .eigen import compute_modes
from .ritz import rayleigh_ritz
from .slab_cuts import ACROSS_RATIO, cut_slabs, interface_faces, interface_next, polynomial_traces

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
    margin: float = 0.5            #: shear wavelengths at f_cut between a cut and the zone or a gauge
    compress: float = 1e-12        #: second pass: relative Gram eigenvalue of a dropped direction (0: keep all)
    zone_degree: int = 0           #: zone-interface patterns' polynomial degree (0: exact constraint modes)
    across: float = ACROSS_RATIO   #: a slab over this x the mean is cut again across (0: never)
    eps_tol: float = SLAB_EPS_TOL  #: the slabs' eigensolver tolerance


def substructure_settings(prefix: str, options: Optional[dict[str, str]],
                          n_interior: int = 0) -> Optional[SubstructureSettings]:
    """The body's settings from the command line (``-<prefix>substructures`` ...) or ``options``
    (their ranges checked by :func:`~millimpact.integration.solvers.check_type_options`, the CLI's
    check); None for one factorization (S < 2). Without ``substructures`` a body of
    ``n_interior`` >= :data:`AUTO_MIN_DOFS` interior dofs is cut by itself (:func:`auto_slabs`),
    with the margin and zone-interface patterns of the liner panel's million-DOF run
    (:data:`AUTO_MARGIN`, :data:`AUTO_ZONE_DEGREE`) unless given."""
    keys = ("substructures", "substructure_f_factor", "substructure_trace_density", "substructure_margin",
            "substructure_compress", "substructure_zone_degree", "substructure_across", "substructure_eps_tol")
    with petsc_options({}, {k: v for k, v in (options or {}).items() if k in keys}, prefix=prefix):
        db = PETSc.Options()
        raw = {k: db.getString(prefix + k, "") for k in keys}
    check_type_options({prefix + k: v for k, v in raw.items() if v})
    default = SubstructureSettings(0)
    auto = not raw["substructures"] and auto_slabs(n_interior) >= 2
    settings = SubstructureSettings(auto_slabs(n_interior) if auto else int(raw["substructures"] or 0),
                                    float(raw["substructure_f_factor"] or default.f_factor),
                                    float(raw["substructure_trace_density"] or default.trace_density),
                                    float(raw["substructure_margin"] or (AUTO_MARGIN if auto else default.margin)),
                                    float(raw["substructure_compress"] or default.compress),
                                    int(raw["substructure_zone_degree"]
                                        or (AUTO_ZONE_DEGREE if auto else default.zone_degree)),
                                    float(raw["substructure_across"] or default.across),
                                    float(raw["substructure_eps_tol"] or default.eps_tol))
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


def _gather_slab_matrices(K_ii: PETSc.Mat, M_ii: PETSc.Mat, slab_rows: list[np.ndarray],
                          gamma: np.ndarray) -> list[tuple]:
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
    used: np.ndarray               #: which shared columns (zone statics, traces) reach the slab
    n_own: int                     #: the slab's own columns (modes, second-order statics)
    first_blocks: Optional[tuple]  #: (B^T K_ss B, B^T M_ss B) of the first pass until projected (:func:`_slab_blocks`)
    stats: dict
    cols: np.ndarray = None
    projected: int = 0             #: columns of B already in K_V, M_V (see _project_slab)
    n_new: int = 0                 #: columns the second pass added

    def release_matrices(self) -> None:
        """Free the slab's matrices (after the last projection: the Rayleigh-Ritz, the recovery
        and the expansion read only the basis rows B)."""
        if self.K_ss is not None:
            self.K_ss.destroy()
            self.M_ss.destroy()
        self.K_ss = self.M_ss = self.K_sg = self.M_sg = None

    def release(self) -> None:
        """Free the slab's matrices and basis rows (after the expansion)."""
        self.release_matrices()
        self.B = None


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
        R = dense_from_rows(np.ascontiguousarray(rhs[:, j:j + chunk]), MPI.COMM_SELF)
        X = R.duplicate()
        F.matSolve(R, X)
        out[:, j:j + chunk] = X.getDenseArray()
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
    return sp.csr_matrix((np.concatenate([p[2] for p in parts]),
                          (np.concatenate([p[0] for p in parts]), np.concatenate([p[1] for p in parts]))),
                         shape=(n, A.shape[1]))


def _serial_options(options: Optional[dict[str, str]], eps_tol: float) -> dict[str, str]:
    """A slab is factored by one rank: CHOLMOD unless another package was asked for; its modes are
    converged to ``eps_tol`` (``substructure_eps_tol``; a command-line ``eps_tol`` still wins)."""
    opts = dict(options or {})
    if opts.get("pc_factor_mat_solver_type", "mumps") == "mumps":
        opts["pc_factor_mat_solver_type"] = "cholmod"
    opts["eps_tol"] = repr(eps_tol)
    return opts


def substructured_modes(K_ii: PETSc.Mat, M_ii: PETSc.Mat, C: sp.csr_matrix, D: sp.csr_matrix, coords: np.ndarray,
                        comps: np.ndarray, f_cut: float, shear_speed: float, settings: SubstructureSettings,
                        prefix: str, options: Optional[dict[str, str]] = None,
                        keep_away: Optional[np.ndarray] = None, patterns: bool = False,
                        zone_couplings: Optional[tuple[sp.csr_matrix, sp.csr_matrix]] = None,
                        recovery_rows: Optional[np.ndarray] = None, release: bool = False) -> dict:
    """Psi (dense PETSc, n_i x n_b), Phi (owned rows, n_i_loc x m), the residual flexibility's
    response to the interface inertia R A_b (dense PETSc, n_i x n_b), frequencies (Hz), the next
    frequency, Psi's relative residual ||K_ii Psi + C|| / ||C|| and statistics, from the slab-wise
    Ritz basis (module docstring). ``C``, ``D``: owned rows of K_iz G and M_iz G on the interface
    coordinates (sparse: only the zone's slab has rows there); ``coords``, ``comps``: each owned
    interior dof's node coordinates and displacement component; ``shear_speed`` (m/s) sets the
    margin and the traces' degrees; ``keep_away`` (k x 3, m): points the cuts keep the margin from
    (the gauges). Collective.

    ``patterns``: the columns of C and D are the couplings of zone-interface patterns
    (:func:`~.interface_patterns.zone_interface_patterns`), not of the zone's coordinates: their static responses are
    then returned as extra columns of Phi (made M-orthogonal to the modes and Ritz-diagonalized,
    frequencies appended, ``n_patterns`` of them) and Psi and R A_b are None. The output rows are
    then recovered from the Ritz space (:func:`ritz_recovery`, result ``recovery``): give
    ``zone_couplings`` (the owned rows of K_iz G and M_iz G on the zone's interface coordinates)
    and ``recovery_rows`` (global interior rows the output rows reach, e.g. the gauges' cells).
    The Ritz space's Grams of Phi (``grams``: Phi^T M_ii Phi, Phi^T K_ii Phi) come with it, and
    ``release`` destroys K_ii and M_ii once the slabs hold their blocks (2.2 GB at 1.2M DOFs).

    Two passes over the slabs (steps 1-3 and step 4 of the module docstring). Under MPI the slabs
    are shared out by size (:func:`slab_owners`): each rank gathers its slabs' rows
    (MatCreateSubMatrices), factors and solves it alone (CHOLMOD), and only the Ritz matrices
    (summed on rank 0, which solves the Rayleigh-Ritz and broadcasts its results) and the final
    rows travel; a rank holds one slab's factor at a time. No dense n_i x n_b array but the two
    results is formed (at the plan's 1.2M DOFs each is 5.2 GB)."""
    comm = K_ii.getComm().tompi4py()
    size, rank = comm.size, comm.rank
    t_start = time.perf_counter()
    wavelength = shear_speed / f_cut
    zone_rows = np.nonzero(np.diff(C.indptr))[0]
    cut = cut_slabs(coords, zone_rows, settings.slabs, settings.margin * wavelength, comm, keep_away,
                    settings.across)
    labels = cut.labels
    nxt = interface_next(K_ii, labels)
    on_gamma = nxt >= 0
    r0 = K_ii.getOwnershipRange()[0]
    n_i = K_ii.getSize()[0]
    n_loc = len(labels)
    gamma = np.nonzero(on_gamma)[0]
    face, faces = interface_faces(labels, nxt, comm)
    traces = polynomial_traces(coords[gamma], comps[gamma], face, [cut.normal(a, b) for a, b in faces],
                               wavelength, settings.trace_density, comm)
    T = sp.hstack(traces).tocsr() if traces else sp.csr_matrix((len(gamma), 0))
    n_t, n_b = T.shape[1], C.shape[1]
    t_idx = n_b + np.arange(n_t)          # Ritz columns: [zone statics (n_b) | traces (n_t) | slabs' own]
    # what every slab's owner needs whole: Gamma's global rows and traces, the sparse couplings
    gamma_glob = np.concatenate(comm.allgather((r0 + gamma).astype(np.int64)))
    # sparse: a Gamma row has only its own cut's traces (dense, 1.6 GB a rank at 1.2M DOFs, 15 cuts)
    T_full = sp.vstack(comm.allgather(T)).tocsr() if n_t else sp.csr_matrix((len(gamma_glob), 0))
    CD_full = _global_rows(sp.hstack([C, D]).tocsr(), r0, n_i, comm)
    n_slabs = cut.pieces
    slab_rows = [np.concatenate(comm.allgather((r0 + np.nonzero((labels == s) & ~on_gamma)[0]).astype(np.int64)))
                 for s in range(n_slabs)]
    slab_ids = [s for s in range(n_slabs) if len(slab_rows[s])]
    owners = slab_owners([len(slab_rows[s]) for s in slab_ids], size)
    my_ids = [s for s, o in zip(slab_ids, owners) if o == rank]
    serial_opts = _serial_options(options, settings.eps_tol)
    mine: list[_Slab] = []
    # pass 1: every rank gathers the rows of all its slabs in one collective call (a slab's matrices
    # are kept to the end anyway), then reduces them alone: no rank waits for another between slabs
    t_pass1 = time.perf_counter()
    gathered = _gather_slab_matrices(K_ii, M_ii, [slab_rows[s] for s in my_ids], gamma_glob)
    # Gamma's own block of the Ritz matrices, T^T A_GG T with the owned rows of A_GG (columns
    # numbered as gamma_glob, the IS's order); then (``release``) K_ii and M_ii are not needed
    is_gamma = PETSc.IS().createGeneral((r0 + gamma).astype(np.int32), comm=comm)
    Kgg, Mgg = K_ii.createSubMatrix(is_gamma, is_gamma), M_ii.createSubMatrix(is_gamma, is_gamma)
    KT_gg, MT_gg = (reduce_array((T.T @ (_csr_rows(A) @ T_full)).toarray(), MPI.SUM, comm) for A in (Kgg, Mgg))
    for obj in (Kgg, Mgg, is_gamma) + ((K_ii, M_ii) if release else ()):
        obj.destroy()
    for s, (K_ss, M_ss, K_sg_csr, M_sg_csr) in zip(my_ids, gathered):
        rows = slab_rows[s]
        ts = time.perf_counter()
        ksp = create_factored_solver(K_ss, prefix, serial_opts)
        t_factor = time.perf_counter() - ts
        # the traces that reach the slab: those of the cuts its rows couple to (a dense K_sG T of
        # every trace would be ~1 GB a slab at the plan's 1.2M DOFs)
        C_s = CD_full[rows][:, :n_b]
        used_t = np.bincount(T_full[np.unique(K_sg_csr.indices)].indices, minlength=n_t) > 0
        used = np.concatenate([np.bincount(C_s.indices, minlength=n_b) > 0, used_t])
        rhs = sp.hstack([C_s[:, used[:n_b]], K_sg_csr @ T_full[:, used_t]]).tocsr()
        X = -_solve(ksp, rhs.toarray()) if used.any() else np.zeros((len(rows), 0))
        # second-order statics: the response to the inertia of the slab's zone statics, M_ss Z_s + M_sz
        n_zone = int(used[:n_b].sum())
        D_s = CD_full[rows][:, n_b:][:, used[:n_b]].tocsr()
        X2 = (_solve(ksp, _mult_local(M_ss, X[:, :n_zone], MPI.COMM_SELF) + D_s.toarray())
              if n_zone else np.zeros((len(rows), 0)))
        t_static = time.perf_counter() - ts - t_factor
        te = time.perf_counter()
        f_s, vecs, _ = compute_modes(K_ss, M_ss, ksp, settings.f_factor * f_cut, None, prefix, serial_opts,
                                     count_first=True)
        t_eigen = time.perf_counter() - te
        Phi_s = np.column_stack([v.getArray(readonly=True) for v in vecs]) if vecs else np.zeros((len(rows), 0))
        for v in vecs:
            v.destroy()
        ksp.destroy()
        return_freed_memory()      # the slab's factors and Krylov basis: the next slab's room
        B = np.hstack([X, Phi_s, X2])
        del X, X2
        tb = time.perf_counter()
        blocks = _slab_blocks(K_ss, M_ss, B, -rhs, D_s, Phi_s.shape[1])
        del rhs, D_s
        mine.append(_Slab(s, rows, K_ss, M_ss, K_sg_csr, M_sg_csr, B, used,
                          Phi_s.shape[1] + n_zone, blocks,
                          {"slab": s, "rank": rank, "dofs": len(rows), "modes": int(Phi_s.shape[1]),
                           "static_columns": int(used.sum()) + n_zone, "factor_s": round(t_factor, 3),
                           "statics_s": round(t_static, 3), "eigen_s": round(t_eigen, 3),
                           "blocks_s": round(time.perf_counter() - tb, 3),
                           "total_s": round(time.perf_counter() - ts, 3),
                           "peak_rss_gb": _peak_rss_gb()}))
        log.info("substructures %s: slab %d on rank %d: %s", prefix, s, rank, mine[-1].stats)
    phase = {"pass1_s": time.perf_counter() - t_pass1}        # this rank's slabs (before any wait)
    t0 = time.perf_counter()
    # the Ritz columns, numbered slab by slab on every rank alike
    layout = sorted(x for part in comm.allgather([(sl.index, sl.used, sl.n_own) for sl in mine]) for x in part)
    n_cols, cols_of = n_b + n_t, {}
    for s, used, own in layout:
        cols_of[s] = np.concatenate([np.nonzero(used)[0], n_cols + np.arange(own)])
        n_cols += own
    for sl in mine:
        sl.cols = cols_of[sl.index]
    # the dense Ritz matrices live on rank 0 alone, which solves the Rayleigh-Ritz and broadcasts
    # its results: the same numbers as every rank solving it (the sums are one reduction), without
    # the other ranks' copies and workspaces (~1 GB a rank at the plan's 1.2M DOFs, 4,368 columns)
    KV = MV = CV = None
    if rank == 0:
        KV, MV, CV = np.zeros((n_cols, n_cols)), np.zeros((n_cols, n_cols)), np.zeros((n_cols, 2 * n_b))
        KV[np.ix_(t_idx, t_idx)], MV[np.ix_(t_idx, t_idx)] = KT_gg, MT_gg
        CV[t_idx] = (CD_full[gamma_glob].T @ T_full).T.toarray()      # replicated data: no sum
    KV, MV, CV = _project(mine, T_full, t_idx, CD_full, (KV, MV, CV), comm, n_cols=n_cols, n_rhs=2 * n_b)
    phase["project_s"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    ritz = _ritz_on_root(KV, MV, CV, n_b, f_cut, comm)
    phase["ritz_s"] = time.perf_counter() - t0
    # pass 2: each slab's static response (Gamma held) to the inertia of the first pass's modes and
    # constraint modes, M_ii Phi and A_b = M_ii Psi + M_ib: one step of inverse iteration on them.
    # A slab's rows of M_ii V couple its own rows and Gamma's only
    n_new = n_b + ritz["m"]
    if n_new:
        t0 = time.perf_counter()
        coef = np.hstack([ritz["psi"], ritz["phi"]])
        first_gamma = T_full @ coef[t_idx]
        for sl in mine:
            ts = time.perf_counter()
            load = _mult_local(sl.M_ss, sl.B @ coef[sl.cols], MPI.COMM_SELF) + sl.M_sg @ first_gamma
            load[:, :n_b] += CD_full[sl.rows][:, n_b:].toarray()
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
        offsets = np.cumsum([0] + [counts[s] for s in slab_ids])
        for sl in mine:
            k = slab_ids.index(sl.index)
            sl.cols = np.concatenate([sl.cols, n_cols + offsets[k] + np.arange(sl.n_new)])
        phase["pass2_s"] = time.perf_counter() - t0
        t0 = time.perf_counter()
        n_cols += int(offsets[-1])
        KV, MV, CV = _project(mine, T_full, t_idx, CD_full, (KV, MV, CV), comm, n_cols=n_cols, n_rhs=2 * n_b)
        _release_slab_matrices(mine)
        phase["project_s"] += time.perf_counter() - t0
        t0 = time.perf_counter()
        ritz = _ritz_on_root(KV, MV, CV, n_b, f_cut, comm)
        phase["ritz_s"] += time.perf_counter() - t0
    else:
        _release_slab_matrices(mine)   # the first projection was the last
    return_freed_memory()          # the second pass's factors and solves, before the expansion
    t0 = time.perf_counter()
    m = ritz["m"]
    freq = ritz["freq"]
    # the results straight into their final storage; each slab's rows sent to the ranks owning them
    recovery = grams = None
    if patterns:
        f_pat, c_pat, grams = computed_on_root(comm, lambda: _patterns_and_grams(KV, MV, ritz))
        A = np.hstack([ritz["phi"], c_pat])
        if zone_couplings is not None:
            recovery = ritz_recovery(mine, T_full, t_idx, gamma_glob, ritz, MV, A,
                                     _global_rows(sp.hstack(zone_couplings).tocsr(), r0, n_i, comm),
                                     np.asarray(recovery_rows if recovery_rows is not None else [], dtype=np.int64),
                                     n_cols, comm)
        Psi = flex = None
        Phi = np.zeros((n_loc, m + len(f_pat)), order="F")       # PETSc's dense layout: shared, not copied
        targets, parts = (Phi,), (A,)
    else:
        Psi, flex = _dense_zeros(n_loc, n_b, comm), _dense_zeros(n_loc, n_b, comm)
        Phi = np.zeros((n_loc, m), order="F")
        targets, parts = (Psi.getDenseArray(), flex.getDenseArray(), Phi), (ritz["psi"], ritz["flex"], ritz["phi"])
    for out, c in zip(targets, parts):
        out[gamma] = T @ c[t_idx]
    starts = np.array(comm.allgather(r0) + [n_i])
    bounds = np.cumsum([0] + [c.shape[1] for c in parts])

    def put(local_rows: np.ndarray, block: np.ndarray) -> None:
        for out, a, b in zip(targets, bounds[:-1], bounds[1:]):
            out[local_rows] = block[:, a:b]

    coef = np.hstack(parts)
    ritz_rank = ritz["rank"]
    del KV, MV, CV, ritz, parts        # the dense Ritz matrices: not needed for the expansion

    def pieces():
        """This rank's slabs' rows of the results, EXPAND_ROWS at a time; a slab's matrices and
        basis freed once its rows are out (they are not needed after the projections)."""
        for sl in mine:
            c = coef[sl.cols]
            for j in range(0, len(sl.rows), EXPAND_ROWS):
                yield sl.rows[j:j + EXPAND_ROWS], sl.B[j:j + EXPAND_ROWS] @ c
            sl.release()
            return_freed_memory()

    deliver_rows(pieces(), starts, coef.shape[1], put, comm)
    for A in (Psi, flex):
        if A is not None:
            A.assemble()
    phase["expand_s"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    residual = constraint_residual(K_ii, Psi, C, comm) if n_b and Psi is not None else 0.0
    phase["residual_s"] = time.perf_counter() - t0
    slab_stats = sorted((x for part in comm.allgather([sl.stats for sl in mine]) for x in part),
                        key=lambda x: x["slab"])
    stats = {"slabs": slab_stats, **cut.stats(), "interface_faces": len(faces),
             "interface_dofs": len(gamma_glob), "traces": n_t,
             **({"zone_patterns": n_b, "pattern_vectors": len(f_pat)} if patterns else {"interface_coordinates": n_b}),
             "ritz_columns": n_cols, "ritz_rank": ritz_rank, "slab_modes": int(sum(x["modes"] for x in slab_stats)),
             # phases (s): this rank's slabs, and on rank 0 the projections, the dense Ritz solves, the
             # second pass, the expansion into Psi / Phi / R A_b and Psi's residual
             "pass1_s_by_rank": [round(x, 3) for x in comm.allgather(phase.pop("pass1_s"))],
             **{k: round(v, 3) for k, v in phase.items()}, "total_s": round(time.perf_counter() - t_start, 3)}
    if comm.rank == 0:
        log.info("substructures %s: %d slabs along %s (cuts %s m; %d cut again across) on %d rank(s), %d "
                 "interface dofs -> %d traces, %d slab modes, Ritz basis %d: %d modes under f_cut in %.3g s", prefix,
                 len(slab_ids), stats["axis"], ", ".join(f"{c:.4g}" for c in cut.cuts), len(cut.across), size,
                 stats["interface_dofs"], n_t,
                 stats["slab_modes"], n_cols, m, stats["total_s"])
    return {"Psi": Psi, "Phi": Phi, "flex": flex, "freq": np.concatenate([freq[:m], f_pat]) if patterns else freq[:m],
            "n_patterns": len(f_pat) if patterns else 0, "next": float(freq[m]) if m < len(freq) else math.nan,
            "residual": residual, "stats": stats,
            "recovery": recovery, "grams": grams}


def ritz_recovery(slabs: list[_Slab], T_full: sp.csr_matrix, t_idx: np.ndarray, gamma_glob: np.ndarray,
                  ritz: dict, MV: np.ndarray, A: np.ndarray, CDz: sp.csr_matrix, rows: np.ndarray,
                  n_cols: int, comm: MPI.Comm) -> dict:
    """Output recovery without constraint modes, from the Ritz space V (replicated, small).

    The interior obeys K_ii u_i = -C q - D q'' - M_ii u_i'' (no load of its own; C = K_iz G,
    D = M_iz G on the zone's interface coordinates). With K_ii^-1 replaced by its Galerkin image in
    V, V H V^T (H = K_V^+), and the interior's reduced acceleration V A x'' (A: the coefficients of
    the body's vectors, x their coordinates), an output row a reads
    a u_i = (a V) [H_C q + H_D q'' + H_M x''], H_C = -H V^T C, H_D = -H V^T D, H_M = -H M_V A:
    mode acceleration for any interior basis (for Craig-Bampton it is Psi q + Phi eta - R A_b q''
    in the Ritz space). Returns ``rows`` (the global interior rows kept), ``V`` (those rows of the
    basis), H_C, H_D and H_M. ``CDz``: [C | D], every rank's rows (global interior numbering)."""
    n_b = CDz.shape[1] // 2
    CV = np.zeros((n_cols, 2 * n_b))
    keep = np.zeros((len(rows), n_cols))
    for sl in slabs:
        CV[sl.cols] += np.asarray((CDz[sl.rows].T @ sl.B).T)
        pos, hit = positions_in(sl.rows, rows)
        keep[np.ix_(np.nonzero(hit)[0], sl.cols)] = sl.B[pos[hit]]
    CV, keep = _sum_on_root(CV, comm), reduce_array(keep, MPI.SUM, comm)
    pos, on_g = positions_in(gamma_glob, rows)          # gamma_glob: the ranks' sorted rows in rank order
    keep[np.ix_(np.nonzero(on_g)[0], t_idx)] = T_full[pos[on_g]].toarray()

    def images():                                         # K_V, M_V and the eigenpairs are rank 0's
        CV[t_idx] += (CDz[gamma_glob].T @ T_full).T.toarray()     # replicated data: no sum
        H = ritz["solve"]                                 # K_V^+: the final Rayleigh-Ritz's factor
        return -H(CV[:, :n_b]), -H(CV[:, n_b:]), -H(MV @ A)
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
    psi = psi - phi @ (phi.T @ (MV @ psi))           # twice: classical Gram-Schmidt's loss of orthogonality
    W = psi @ gram_basis(psi.T @ MV @ psi, DEPENDENT_TOL)
    lam, Y = np.linalg.eigh(W.T @ KV @ W)
    return np.sqrt(np.maximum(lam, 0.0)) / (2 * math.pi), W @ Y


def constraint_residual(K_ii: PETSc.Mat, Psi: PETSc.Mat, C: sp.csr_matrix, comm: MPI.Comm, chunk: int = 64) -> float:
    """||K_ii Psi + C||_F / ||C||_F, in blocks of ``chunk`` columns (no second n_i x n_b array)."""
    P = Psi.getDenseArray()
    num = 0.0
    for j in range(0, P.shape[1], chunk):
        R = _mult_local(K_ii, P[:, j:j + chunk], comm) + C[:, j:j + chunk].toarray()
        num += float(np.sum(R * R))
    num, den = reduce_array(np.array([num, float(C.multiply(C).sum())]), MPI.SUM, comm)
    return math.sqrt(num) / max(math.sqrt(den), 1e-300)


def _slab_blocks(K_ss: PETSc.Mat, M_ss: PETSc.Mat, B: np.ndarray, K_X: sp.csr_matrix, D_s: sp.csr_matrix,
                 n_modes: int) -> tuple[np.ndarray, np.ndarray]:
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
    KPhi = _mult_local(K_ss, B[:, n_x:n_x + n_modes], MPI.COMM_SELF)
    PK = np.vstack([np.asarray(K_X.T @ B), KPhi.T @ B, PM[:n_zone] + np.asarray(D_s.T @ B)])
    return PK, PM


def _project(slabs: list[_Slab], T_full: sp.csr_matrix, t_idx: np.ndarray, CD_full: sp.csr_matrix,
             current: tuple, comm: MPI.Comm, n_cols: int, n_rhs: int) -> tuple:
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
            V_[np.ix_(cn, cn)] -= P[:, new]                                    # the new-new block once
            G = ((A_g @ T_full).T @ Bn).T
            V_[np.ix_(cn, t_idx)] += G
            V_[np.ix_(t_idx, cn)] += G.T
        CV[cn] += np.asarray((CD_full[sl.rows].T @ Bn).T)
        sl.projected = B.shape[1]
        sl.first_blocks = None
    KV, MV, CV = (_sum_on_root(x, comm) for x in (KV, MV, CV))
    if comm.rank != 0:
        return None, None, None
    k = current[0].shape[0]
    KV[:k, :k] += current[0]
    MV[:k, :k] += current[1]
    CV[:k] += current[2]
    for A in (KV, MV):                 # symmetrized in place: no second n x n array
        A += A.T
        A *= 0.5
    return KV, MV, CV


def _sum_on_root(a: np.ndarray, comm: MPI.Comm) -> Optional[np.ndarray]:
    """The element-wise sum of every rank's ``a`` on rank 0 (None on the others)."""
    a = np.ascontiguousarray(a, dtype=float)
    if comm.size == 1:
        return a
    out = np.empty_like(a) if comm.rank == 0 else None
    comm.Reduce(a, out, op=MPI.SUM, root=0)
    return out


def _ritz_on_root(KV, MV, CV, n_b: int, f_cut: float, comm: MPI.Comm) -> dict:
    """:func:`~.ritz.rayleigh_ritz` on rank 0 (which holds K_V, M_V, C_V) with the waiting ranks' cores,
    its results broadcast; the solver ``solve`` (K_V^+, for :func:`ritz_recovery`) stays on rank 0."""
    return computed_on_root(comm, lambda: rayleigh_ritz(KV, MV, CV, n_b, f_cut),
                            lambda ritz: {k: v for k, v in ritz.items() if k != "solve"})


def _patterns_and_grams(KV: np.ndarray, MV: np.ndarray, ritz: dict):
    """(frequencies, coefficients) of the pattern vectors (:func:`pattern_vectors`) and the Ritz
    space's Grams (A^T M_V A, A^T K_V A) of A = [phi | pattern coefficients] (rank 0's)."""
    f_pat, c_pat = pattern_vectors(KV, MV, ritz)
    A = np.hstack([ritz["phi"], c_pat])
    return f_pat, c_pat, (A.T @ MV @ A, A.T @ KV @ A)
