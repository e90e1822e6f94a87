"""Reduction: Craig-Bampton projection of a finite-element model, u = T q.

Every reduced method is a Galerkin projection of a full model (:class:`~millimpact.fem.model.FEModel`):
time loop, contact rows and outputs run on ``M_r = T^T M T``, ``K_r = T^T K T``, ``B_r = B T`` (Craig
and Bampton, "Coupling of substructures for dynamic analyses", AIAA J. 6 (1968) 1313-1319).

The owned dofs fall into three sets: ``fixed`` (clamps, symmetry planes: zero rows of ``T``),
``zone`` (the cells tagged ``BALL_ZONE`` / ``BLOCK_ZONE`` with their interface nodes, described by a
:class:`~.partition.ZoneBasis` ``u_z = G q_z``: the identity, or the manifold covers of
:mod:`.nmm_zone`) and ``interior`` (the rest of each body), reduced per body::

    u_i = Psi q_b + Phi eta,   Psi = -K_ii^-1 K_iz G       (static constraint modes)
    K_ii phi_k = omega_k^2 M_ii phi_k                       (fixed-interface modes, SLEPc)

``q_b`` are the zone coordinates that touch the interior. One Cholesky factorization of ``K_ii`` per
body serves the solve for ``Psi`` and the shift-and-invert eigensolve. Modes are kept up to
``f_cut`` (Hz) or a count per body; ``Psi`` reproduces every zero-energy motion of the interface,
so the free ball keeps its rigid motion. With ``C = K_iz G`` and ``D = M_iz G``::

    K_r = [ G^T K_zz G + C^T Psi      0          ]
          [ 0                         Phi^T K Phi ]
    M_r = [ G^T M_zz G + D^T Psi + Psi^T D + Psi^T M_ii Psi    D^T Phi + Psi^T M_ii Phi ]
          [ sym.                                               Phi^T M_ii Phi            ]

(no dense ``n x n`` matrix formed). Reduced coordinates are numbered rank by rank: the zone
coordinates a rank owns, then its share of the modes (ball modes before block modes).

A body's interior basis comes from the on-disk cache (:mod:`.cache`), slabs (``substructures``
S >= 2: :mod:`.substructures`) or one factorization of ``K_ii``, optionally with modal truncation
augmentation vectors (``augment``: the interior's static response to a zone motion's inertia,
orthogonalised against the modes; Dickens, Nakagawa and Wittbrodt, Comput. Struct. 62 (1997)
985-998). Output recovery: :meth:`~.reduced_model.ReducedModel.mode_acceleration_rows`.

Options prefixes: ``impact_reduction_<body>_`` for the factorization of ``K_ii`` (``ksp_``,
``pc_``) and its eigensolver (``eps_``, ``st_``, ``inertia_``, ``block_krylov_size``: :mod:`.eigen`;
``substructures``, ``substructure_*``: :mod:`.substructures`); ``impact_reduction_free_<body>_``
for the free-vibration modes; ``impact_reduction_mass_`` for the solve with ``M_r``. Defaults:
:func:`default_solver_options`; ``solver_options`` merge over them, the command line wins.
Measured costs and accuracies: docs/development/reduction-notes.md.
"""

from __future__ import annotations

import logging
import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from mpi4py import MPI
from petsc4py import PETSc

from ..errors import InputError, SolverError
from ..fem.model import FEModel
from ..integration.solvers import create_factored_solver, note_option_read, return_freed_memory
from . import cache as reduction_cache
from .augmentation import (
    AUGMENTATION_PATTERNS,
    compute_augmentation_load,
    compute_augmentation_vectors,
    interface_motion_pattern,
)
from .distributed import (
    dense_columns,
    dense_from_rows,
    detached,
    gather_rows,
    local_columns_csr,
    ownership_offsets,
    split_evenly,
)
from .eigen import compute_modes, default_solver_options
from .interface_patterns import probe_interior_rows, zone_pattern_couplings
from .partition import BODIES, DofPartition, ZoneBasis, create_nodal_zone_basis, partition_dofs
from .reduced_model import BodyReduction, ReducedModel
from .substructures import SubstructureSettings, substructure_settings, substructured_modes

log = logging.getLogger(__name__)

#: the arrays of a body's Ritz-space output recovery (substructures.ritz_recovery), as cached
RECOVERY_KEYS = ("rows", "V", "H_C", "H_D", "H_M")
#: relative residual accepted for the constraint modes K_ii Psi = -C (a direct solve gives ~1e-12)
CONSTRAINT_RESIDUAL_TOL = 1e-8


# --- typed records -------------------------------------------------------------------------------
@dataclass(frozen=True)
class ReductionRequest:
    """What a reduction is asked for: the model, its dof sets and zone basis, the cutoff ``f_cut``
    (Hz) or mode count per body, the solver options (defaults merged), the augmentation patterns
    and the points ``keep_away`` (k x 3, m) a substructured body's cuts keep away from."""

    model: FEModel
    part: DofPartition
    zone: ZoneBasis
    f_cut: float | None
    n_modes: int | None
    opts: dict[str, str]
    augment: tuple[str, ...]
    keep_away: np.ndarray | None
    all_cols: PETSc.IS  #: every owned model dof (the columns of the interior's rows)

    @property
    def comm(self) -> MPI.Comm:
        return self.model.comm


@dataclass(frozen=True)
class InteriorCouplings:
    """One body's interior (``n_i`` > 0 dofs): its blocks and its coupling to the zone.

    ``C = K_iz G``, ``D = M_iz G`` (n_i x n_q); ``qb`` the interface coordinates (their non-zero
    columns, zone numbering, replicated); ``Cb``, ``Db`` those columns (None without any);
    ``rhs`` a dense copy of ``Cb`` for the one-factorization solve; ``sub`` the slabs' settings
    (None: one factorization); ``CD_pat`` the zone-interface patterns' couplings (with ``sub``)."""

    name: str
    prefix: str  #: the body's PETSc options prefix
    idx: np.ndarray  #: owned interior dofs (local model indices)
    I: PETSc.IS
    n_i: int
    K_ii: PETSc.Mat
    M_ii: PETSc.Mat
    C: PETSc.Mat
    D: PETSc.Mat
    qb: np.ndarray
    Cb: PETSc.Mat | None
    Db: PETSc.Mat | None
    rhs: PETSc.Mat | None
    sub: SubstructureSettings | None
    CD_pat: tuple[sp.csr_matrix, sp.csr_matrix] | None

    @property
    def patterns(self) -> bool:
        """Zone-interface patterns replace the constraint modes."""
        return self.CD_pat is not None


@dataclass(frozen=True)
class InteriorBasis:
    """What a strategy gives for a body's interior: the constraint modes ``Psi`` (None with
    zone-interface patterns or without interface), the owned rows of ``Phi`` (modes, then
    augmentation or pattern vectors), their frequencies (Hz), the lowest frequency not kept and
    what the output recovery and the reduced blocks need."""

    Psi: PETSc.Mat | None
    phi_cols: np.ndarray
    freq: np.ndarray
    next: float
    n_aug: int = 0
    n_pat: int = 0
    constraint_residual: float = 0.0  #: ||K_ii Psi + C|| / ||C|| (0 when not computed)
    residual_b: PETSc.Mat | None = None  #: R A_b from the slabs' Ritz space
    ritz_recovery: dict | None = None  #: the Ritz-space recovery (zone-interface patterns)
    grams: tuple[np.ndarray, np.ndarray] | None = None  #: (Phi^T M_ii Phi, Phi^T K_ii Phi)
    substructures: dict | None = None  #: the slabs' statistics
    ksp: PETSc.KSP | None = None  #: the factored K_ii (one factorization)
    released: bool = False  #: K_ii and M_ii destroyed by the slabs


@dataclass(frozen=True)
class ReducedInterior:
    """A body's interior reduced, before the reduced numbering (``couplings``, ``basis`` and
    ``Phi`` are None for a body without interior)."""

    name: str
    n_i: int
    I: PETSc.IS
    timings: dict[str, float]
    couplings: InteriorCouplings | None = None
    basis: InteriorBasis | None = None
    Phi: PETSc.Mat | None = None
    factor: Callable[[], PETSc.KSP] | None = None
    from_cache: bool = False


@dataclass(frozen=True)
class ReducedNumbering:
    """The reduced coordinates' numbering: per rank its zone coordinates, then its modes.
    ``q_off``, ``m_off``: first zone coordinate and first mode of each rank (size + 1)."""

    q_off: np.ndarray
    m_off: np.ndarray
    n_loc: int
    n: int
    lo: int

    def of_zone(self, gq: np.ndarray) -> np.ndarray:
        """Reduced indices of global zone coordinates."""
        owner = np.searchsorted(self.q_off, gq, side="right") - 1
        return gq + self.m_off[owner]

    def of_modes(self, gm: np.ndarray) -> np.ndarray:
        """Reduced indices of global mode numbers."""
        owner = np.searchsorted(self.m_off, gm, side="right") - 1
        return gm + self.q_off[owner + 1]


# --- Craig-Bampton -------------------------------------------------------------------------------
def reduce_model(
    model: FEModel,
    zone: ZoneBasis | None = None,
    *,
    f_cut: float | None = None,
    n_modes: int | None = None,
    partition: DofPartition | None = None,
    solver_options: dict[str, str] | None = None,
    augment: Sequence[str] = (),
    keep_away: np.ndarray | None = None,
) -> ReducedModel:
    """Craig-Bampton reduction of ``model``: the zone described by ``zone`` (default: nodal, the
    identity), each body's interior by constraint modes and fixed-interface modes up to ``f_cut``
    (Hz) or ``n_modes`` per body (``n_modes`` wins if both are given; ``n_modes >=`` the interior
    size keeps every mode and reproduces the full model exactly). ``augment``: zone-motion
    patterns (:data:`AUGMENTATION_PATTERNS`) whose modal truncation augmentation vectors are
    appended to each body's modes (one per pattern and body, see
    :func:`compute_augmentation_vectors`). ``keep_away`` (k x 3, m): points a substructured body's
    cuts keep away from (the gauges, :mod:`.substructures`). Collective."""
    _check_request(f_cut, n_modes, augment)
    t_start = time.perf_counter()
    comm = model.comm
    opts = default_solver_options(comm.size)
    opts.update(solver_options or {})
    part = partition or partition_dofs(model)
    zone = zone or create_nodal_zone_basis(model, part)
    r0 = model.K.getOwnershipRange()[0]
    all_cols = PETSc.IS().createStride(part.n_owned, r0, 1, comm=comm)
    req = ReductionRequest(model, part, zone, f_cut, n_modes, opts, tuple(augment), keep_away, all_cols)
    interiors = [_reduce_interior(req, name) for name, _tags in BODIES]
    return _assemble_reduced_model(req, interiors, t_start)


def _check_request(f_cut: float | None, n_modes: int | None, augment: Sequence[str]) -> None:
    """One clear line for a cutoff, mode count or augmentation pattern out of range."""
    if f_cut is None and n_modes is None:
        raise InputError("reduction: give a modal cutoff f_cut (Hz) or a mode count per body")
    if f_cut is not None and not (f_cut > 0):
        raise InputError(f"reduction: f_cut = {f_cut!r} Hz must be > 0")
    if n_modes is not None and n_modes < 0:
        raise InputError(f"reduction: modes = {n_modes!r} must be >= 0")
    bad = [a for a in augment if a not in AUGMENTATION_PATTERNS]
    if bad:
        raise InputError(
            f"reduction: augment = {','.join(bad)}: choose from {', '.join(AUGMENTATION_PATTERNS)} or none"
        )


def _reduce_interior(req: ReductionRequest, name: str) -> ReducedInterior:
    """One body's interior through the strategy that applies: the on-disk cache, slabs or one
    factorization of K_ii (module docstring). Collective."""
    tb = time.perf_counter()
    comm = req.comm
    idx = req.part.interior[name]
    r0 = req.model.K.getOwnershipRange()[0]
    I = PETSc.IS().createGeneral((r0 + idx).astype(np.int32), comm=comm)
    n_i = comm.allreduce(len(idx))
    timings: dict[str, float] = {}
    if n_i == 0:
        return ReducedInterior(name, 0, I, timings)
    c = _interior_couplings(req, name, idx, I, n_i)
    # Psi, Phi from the on-disk cache when the same matrices and settings were reduced before
    # (reduction.cache; not with augmentation vectors)
    t0 = time.perf_counter()
    key = _cache_key(req, c)
    cached = reduction_cache.load(comm, key) if key else None
    if cached is not None:
        basis = _basis_from_cache(req, c, cached, t0, timings)
    elif c.sub is not None:
        basis = _basis_from_slabs(req, c, t0, timings)
    else:
        basis = _basis_from_factorization(req, c, t0, timings)
    if key and cached is None:
        _store_in_cache(comm, key, basis)
    if c.rhs is not None:
        c.rhs.destroy()
    Phi = None
    if basis.phi_cols.shape[1]:
        # on phi_cols' own storage when it is column-major (the slabs' Phi): no second copy
        Phi = PETSc.Mat().createDense(
            ((len(idx), n_i), (PETSc.DECIDE, basis.phi_cols.shape[1])),
            array=np.asfortranarray(basis.phi_cols),
            comm=comm,
        )
        Phi.assemble()
    # the mode-acceleration rows factor K_ii on demand; not for a substructured body (the point of
    # substructuring is never to hold that factorization)
    factor = (
        None
        if c.sub is not None
        else (lambda K_ii=c.K_ii, prefix=c.prefix: create_factored_solver(K_ii, prefix, req.opts))
    )
    timings["total"] = time.perf_counter() - tb
    return ReducedInterior(name, n_i, I, timings, c, basis, Phi, factor, cached is not None)


def _interior_couplings(req: ReductionRequest, name: str, idx: np.ndarray, I: PETSc.IS, n_i: int) -> InteriorCouplings:
    """The interior's blocks K_ii, M_ii, its couplings C = K_iz G, D = M_iz G to the zone and the
    interface coordinates; the slabs' settings and zone-interface patterns' couplings if any."""
    comm, model, G_q = req.comm, req.model, req.zone.G
    K_ii = model.K.createSubMatrix(I, I)
    M_ii = model.M.createSubMatrix(I, I)
    K_ia, M_ia = model.K.createSubMatrix(I, req.all_cols), model.M.createSubMatrix(I, req.all_cols)
    C = detached(K_ia.matMult(G_q))  # K_iz G   (n_i x n_q)
    D = detached(M_ia.matMult(G_q))  # M_iz G
    # interface coordinates: the non-zero columns of C and D
    cols_loc = np.unique(np.concatenate([C.getValuesCSR()[1], D.getValuesCSR()[1]]))
    qb = np.unique(np.concatenate(comm.allgather(cols_loc.astype(np.int64))))
    prefix = f"impact_reduction_{name}_"
    # slab-wise Ritz basis instead of one factorization of K_ii (option <prefix>substructures)
    sub = (
        substructure_settings(prefix, req.opts, n_i)
        if req.f_cut is not None and req.n_modes is None and not req.augment
        else None
    )
    zone_degree = sub.zone_degree if sub is not None else 0
    patterns = bool(zone_degree and len(qb))
    # zone-interface patterns: the interior's static responses to a few smooth interface motions
    # replace the n_b constraint modes (K_iz W, M_iz W instead of C, D; K_ia and M_ia, a copy of
    # the interior's rows of K and M, freed at once: 2.2 GB at the plan's 1.2M DOFs)
    CD_pat = zone_pattern_couplings(model, req.part, name, zone_degree, K_ia, M_ia) if patterns else None
    K_ia.destroy()
    M_ia.destroy()
    return_freed_memory()
    Cb = Db = rhs = None
    if len(qb):
        # sparse interface columns (for the products) and a dense copy of C's (the right-hand
        # sides of the multi-RHS solve: MUMPS takes dense right-hand sides)
        q_lo_b, q_hi_b = G_q.getOwnershipRangeColumn()
        is_qb = PETSc.IS().createGeneral(qb[(qb >= q_lo_b) & (qb < q_hi_b)].astype(np.int32), comm=comm)
        rows_I = PETSc.IS().createStride(len(idx), C.getOwnershipRange()[0], 1, comm=comm)
        Cb = C.createSubMatrix(rows_I, is_qb)
        Db = D.createSubMatrix(rows_I, is_qb)
        # (not for slabs: they take C and D sparse, and a dense copy of the 1.2M-DOF panel's is 5.2 GB)
        rhs = dense_columns(C, qb, comm) if sub is None else None
    return InteriorCouplings(name, prefix, idx, I, n_i, K_ii, M_ii, C, D, qb, Cb, Db, rhs, sub, CD_pat)


def _cache_key(req: ReductionRequest, c: InteriorCouplings) -> str | None:
    """The body's key in the on-disk cache (None with augmentation vectors: not cached)."""
    if req.augment:
        return None
    return reduction_cache.body_key(
        req.comm,
        [c.K_ii, c.M_ii, c.C, c.D],
        {
            "body": c.name,
            "f_cut": req.f_cut,
            "n_modes": req.n_modes,
            "options": sorted((k, str(v)) for k, v in req.opts.items()),
            # the command line's options for this body's solvers too
            "petsc": sorted((k, str(v)) for k, v in PETSc.Options().getAll().items() if k.startswith(c.prefix)),
        },
    )


def _basis_from_cache(
    req: ReductionRequest, c: InteriorCouplings, cached: dict, t0: float, timings: dict[str, float]
) -> InteriorBasis:
    """Strategy 1: Psi, Phi (and the slabs' recovery data) as stored by an earlier reduction."""
    comm = req.comm
    for k in PETSc.Options().getAll():  # in the key: they shaped these modes (no "unused" warning)
        if k.startswith(c.prefix):
            note_option_read(k)
    n_pat = int(cached.get("n_patterns", 0))
    recovery = {k: cached["recovery_" + k] for k in RECOVERY_KEYS} if "recovery_V" in cached else None
    Psi = residual_b = None
    residual = 0.0
    if len(c.qb) and not n_pat:
        Psi = dense_from_rows(cached["Psi"], comm)
        residual = float(cached["residual"])
        if c.sub is not None and "flex" in cached:
            residual_b = dense_from_rows(cached["flex"], comm)
    timings["from_cache"] = time.perf_counter() - t0
    return InteriorBasis(
        Psi,
        cached["Phi"],
        np.asarray(cached["freq"]),
        float(cached["next"]),
        n_pat=n_pat,
        constraint_residual=residual,
        residual_b=residual_b,
        ritz_recovery=recovery,
    )


def _basis_from_slabs(
    req: ReductionRequest, c: InteriorCouplings, t0: float, timings: dict[str, float]
) -> InteriorBasis:
    """Strategy 2: the slab-wise Ritz basis of :func:`~.substructures.substructured_modes` (no
    factorization of the whole K_ii)."""
    model, qb, keep_away = req.model, c.qb, req.keep_away
    # _interior_couplings sets slabs for a reduction to a cutoff only
    assert c.sub is not None and req.f_cut is not None, "slabs without their settings or a cutoff"
    material = model.ball_material if c.name == "ball" else model.target_material
    node_xyz = model.V.tabulate_dof_coordinates()[c.idx // 3]
    zone_cd = (local_columns_csr(c.C, qb), local_columns_csr(c.D, qb))
    C_s, D_s = c.CD_pat if c.CD_pat is not None else zone_cd
    probes = (
        probe_interior_rows(model, c.idx, keep_away)
        if c.patterns and c.name == "block" and keep_away is not None and len(keep_away)
        else None
    )
    res = substructured_modes(
        c.K_ii,
        c.M_ii,
        C_s,
        D_s,
        node_xyz,
        c.idx % 3,
        req.f_cut,
        math.sqrt(material.shear_modulus / material.density),
        c.sub,
        c.prefix,
        req.opts,
        keep_away,
        patterns=c.patterns,
        zone_couplings=zone_cd if c.patterns else None,
        recovery_rows=probes,
        release=c.patterns,
    )
    Psi = residual_b = None
    residual = 0.0
    if len(qb) and not c.patterns:
        Psi, residual_b = res.Psi, res.flex
        # a Galerkin Psi: reported, not checked (exact only with every interface dof a trace)
        residual = res.residual
    else:
        for m in (res.Psi, res.flex):
            if m is not None:
                m.destroy()
    timings["substructures"] = time.perf_counter() - t0
    return_freed_memory()
    # with patterns K_ii and M_ii were destroyed by substructured_modes: its Grams replace the products
    return InteriorBasis(
        Psi,
        res.Phi,
        res.freq,
        res.next,
        n_pat=res.n_patterns,
        constraint_residual=residual,
        residual_b=residual_b,
        ritz_recovery=res.recovery,
        grams=res.grams,
        substructures=res.stats,
        released=c.patterns,
    )


def _basis_from_factorization(
    req: ReductionRequest, c: InteriorCouplings, t0: float, timings: dict[str, float]
) -> InteriorBasis:
    """Strategy 3: one Cholesky factorization of K_ii for the constraint modes, the eigensolve and
    the augmentation vectors (if asked)."""
    ksp = create_factored_solver(c.K_ii, c.prefix, req.opts)
    timings["factor"] = time.perf_counter() - t0
    Psi, residual = _constraint_modes(c, ksp, timings) if len(c.qb) else (None, 0.0)
    t0 = time.perf_counter()
    xs = []
    for kind in dict.fromkeys(req.augment):
        u_w = interface_motion_pattern(req.model, req.part, c.name, kind)
        xs.append(compute_augmentation_load(req.model.K, req.model.M, c.I, req.all_cols, c.K_ii, c.M_ii, ksp, u_w))
        u_w.destroy()
    t_aug = time.perf_counter() - t0
    t0 = time.perf_counter()
    freq, vecs, nxt = compute_modes(c.K_ii, c.M_ii, ksp, req.f_cut, req.n_modes, c.prefix, req.opts)
    timings["eigenmodes"] = time.perf_counter() - t0
    n_aug = 0
    if xs:
        t0 = time.perf_counter()
        f_aug, v_aug = compute_augmentation_vectors(c.K_ii, c.M_ii, xs, vecs)
        for x in xs:
            x.destroy()
        freq = np.concatenate([freq, f_aug])
        vecs = list(vecs) + v_aug
        n_aug = len(v_aug)
        timings["augmentation"] = t_aug + time.perf_counter() - t0
    phi_cols = np.zeros((len(c.idx), len(vecs)))
    for k, v in enumerate(vecs):
        phi_cols[:, k] = v.getArray(readonly=True)
        v.destroy()
    return InteriorBasis(Psi, phi_cols, freq, nxt, n_aug=n_aug, constraint_residual=residual, ksp=ksp)


def _constraint_modes(c: InteriorCouplings, ksp: PETSc.KSP, timings: dict[str, float]) -> tuple[PETSc.Mat, float]:
    """Psi = -K_ii^-1 C with the factored K_ii, and its relative residual (checked)."""
    t0 = time.perf_counter()
    # rhs is the dense copy of C's interface columns, made for the one-factorization reduction
    assert c.rhs is not None, f"constraint modes of the {c.name} without the dense right-hand sides"
    Psi = c.rhs.duplicate()
    ksp.getPC().getFactorMatrix().matSolve(c.rhs, Psi)
    Psi.scale(-1.0)
    # residual check: K_ii Psi + C = 0
    R = c.K_ii.matMult(Psi)
    R.axpy(1.0, c.rhs)
    res = R.norm(PETSc.NormType.FROBENIUS) / max(c.rhs.norm(PETSc.NormType.FROBENIUS), 1e-300)
    R.destroy()
    if not res < CONSTRAINT_RESIDUAL_TOL:
        raise SolverError(f"constraint modes of the {c.name}: relative residual {res:.3g} (factorization {c.prefix})")
    timings["constraint_modes"] = time.perf_counter() - t0
    return Psi, res


def _store_in_cache(comm: MPI.Comm, key: str, basis: InteriorBasis) -> None:
    """Keep a freshly computed basis in the on-disk cache."""
    flex = basis.residual_b
    reduction_cache.store(
        comm,
        key,
        {
            "Psi": basis.Psi.getDenseArray().copy() if basis.Psi is not None else np.zeros((0, 0)),
            "Phi": basis.phi_cols,
            "freq": np.asarray(basis.freq),
            "next": np.asarray(basis.next),
            "n_patterns": np.asarray(basis.n_pat),
            **{"recovery_" + k: v for k, v in (basis.ritz_recovery or {}).items()},
            **({"flex": flex.getDenseArray()} if flex is not None else {}),
            "residual": np.asarray(basis.constraint_residual),
        },
    )


# --- the reduced matrices ------------------------------------------------------------------------
def _reduced_numbering(comm: MPI.Comm, zone: ZoneBasis, interiors: list[ReducedInterior]) -> ReducedNumbering:
    """Per rank its zone coordinates, then its share of all modes (ball's before block's)."""
    q_off = ownership_offsets(comm, zone.n_local)
    m_total = sum(len(b.basis.freq) for b in interiors if b.basis is not None)
    m_loc = split_evenly(m_total, comm.size, comm.rank)
    m_off = ownership_offsets(comm, m_loc)
    red_off = q_off + m_off  # first reduced index of each rank
    return ReducedNumbering(q_off, m_off, zone.n_local + m_loc, int(red_off[-1]), int(red_off[comm.rank]))


def _assemble_reduced_model(req: ReductionRequest, interiors: list[ReducedInterior], t_start: float) -> ReducedModel:
    """M_r, K_r on one pattern: the sparse zone blocks G^T K G, G^T M G and each body's dense blocks."""
    comm, zone, K, M = req.comm, req.zone, req.model.K, req.model.M
    timings: dict[str, float] = {}
    num = _reduced_numbering(comm, zone, interiors)
    # T's zone part with reduced column numbering: G_r = G E
    q_lo = int(num.q_off[comm.rank])
    rows = np.arange(q_lo, q_lo + zone.n_local)
    E_csr = (np.arange(zone.n_local + 1, dtype=np.int32), num.of_zone(rows).astype(np.int32), np.ones(zone.n_local))
    E = PETSc.Mat().createAIJ(((zone.n_local, PETSc.DETERMINE), (num.n_loc, num.n)), csr=E_csr, comm=comm)
    E.assemble()
    Gr = zone.G.matMult(E)
    t0 = time.perf_counter()
    Kzz = K.PtAP(Gr)
    Mzz = M.PtAP(Gr)
    timings["zone_projection"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    blocks_K: list[tuple[np.ndarray, np.ndarray, np.ndarray]] = []  # (rows, cols, dense values)
    blocks_M: list[tuple[np.ndarray, np.ndarray, np.ndarray]] = []
    bodies: list[BodyReduction] = []
    mode_start = 0
    for b in interiors:
        bodies.append(_body_blocks(b, num, mode_start, req.f_cut, blocks_K, blocks_M, comm))
        mode_start += bodies[-1].n_modes
    timings["dense_blocks"] = time.perf_counter() - t0
    sizes = ((num.n_loc, num.n), (num.n_loc, num.n))
    K_r, M_r = combine_blocks(Kzz, Mzz, blocks_K, blocks_M, num.lo, num.n_loc, num.n, sizes, comm)
    for m in (Kzz, Mzz, E):
        m.destroy()
    # ball coordinates: zone coordinates of the ball and the ball's modes (zone coordinates sit
    # first in each rank's block, so their local index is unchanged)
    ball = [np.nonzero(zone.body == 0)[0]]
    for body in bodies:
        if body.name == "ball" and body.n_modes:
            ball.append(body.modes[(body.modes >= num.lo) & (body.modes < num.lo + num.n_loc)] - num.lo)
    ball_coords = np.unique(np.concatenate(ball)).astype(np.int32)
    timings["total"] = time.perf_counter() - t_start
    red = ReducedModel(req.model, zone, req.part, M_r, K_r, Gr, bodies, ball_coords, zone.n_global, timings)
    if comm.rank == 0:
        _log_reduction(red)
    return red


def _body_blocks(
    b: ReducedInterior,
    num: ReducedNumbering,
    mode_start: int,
    f_cut: float | None,
    blocks_K: list,
    blocks_M: list,
    comm: MPI.Comm,
) -> BodyReduction:
    """A body's dense blocks of K_r and M_r (appended to ``blocks_K``, ``blocks_M`` with global
    reduced indices) and its :class:`BodyReduction`; its first mode is number ``mode_start``."""
    if b.n_i == 0:
        return BodyReduction(
            b.name,
            0,
            b.I,
            None,
            np.zeros(0, np.int64),
            None,
            np.zeros(0, np.int64),
            np.zeros(0),
            f_cut,
            math.nan,
            b.timings,
        )
    c, basis, Phi = b.couplings, b.basis, b.Phi
    assert c is not None and basis is not None, f"{b.name}: an interior without its couplings or basis"
    Psi = basis.Psi
    K_ii, M_ii = (None, None) if basis.released else (c.K_ii, c.M_ii)
    Cb, Db = c.Cb, c.Db
    freq = basis.freq
    modes = num.of_modes(np.arange(mode_start, mode_start + len(freq)))
    qb = num.of_zone(c.qb)
    M_ib = None
    if Psi is not None:
        # constraint modes exist for interface columns (Cb, Db) and a kept interior (M_ii)
        assert Cb is not None and Db is not None and M_ii is not None, f"{b.name}: Psi without Cb, Db or M_ii"
        Kbb = gather_rows(Cb.transposeMatMult(Psi), comm)
        Kbb = 0.5 * (Kbb + Kbb.T)
        MPsi = M_ii.matMult(Psi)
        # the mode-acceleration rows need A_b = M_ii Psi + M_ib: kept as M_ib (sparse) and formed
        # against their few columns, not as a dense n_i x n_b copy (5.2 GB at the plan's 1.2M DOFs)
        if b.factor is not None:
            M_ib = Db
        DtPsi = gather_rows(Db.transposeMatMult(Psi), comm)
        Mbb = DtPsi + DtPsi.T + gather_rows(Psi.transposeMatMult(MPsi), comm)
        Mbb = 0.5 * (Mbb + Mbb.T)
        MPsi.destroy()
        blocks_K.append((qb, qb, Kbb))
        blocks_M.append((qb, qb, Mbb))
    if Phi is not None:
        _mode_blocks(basis, Phi, Psi, K_ii, M_ii, Cb, Db, qb, modes, blocks_K, blocks_M, comm)
    for m in (c.C, c.D, Cb, Db if M_ib is None else None):
        if m is not None:
            m.destroy()
    return BodyReduction(
        b.name,
        b.n_i,
        b.I,
        Psi,
        qb,
        Phi,
        modes,
        freq,
        f_cut,
        basis.next,
        b.timings,
        basis.n_aug,
        n_patterns=basis.n_pat,
        ksp=basis.ksp,
        M_ib=M_ib,
        K_ii=K_ii,
        factor=b.factor,
        from_cache=b.from_cache,
        substructures=basis.substructures,
        residual_b=basis.residual_b,
        ritz_recovery=basis.ritz_recovery,
    )


def _mode_blocks(
    basis: InteriorBasis,
    Phi: PETSc.Mat,
    Psi: PETSc.Mat | None,
    K_ii: PETSc.Mat | None,
    M_ii: PETSc.Mat | None,
    Cb: PETSc.Mat | None,
    Db: PETSc.Mat | None,
    qb: np.ndarray,
    modes: np.ndarray,
    blocks_K: list,
    blocks_M: list,
    comm: MPI.Comm,
) -> None:
    """The blocks of a body's modes: Phi^T K Phi, Phi^T M_ii Phi and their couplings to the
    interface coordinates (appended to ``blocks_K``, ``blocks_M``)."""
    if basis.grams is not None:  # from the Ritz space: no n_i x m products
        Mmm, Kmm = basis.grams
    else:
        # without the Ritz-space Grams the interior's blocks were kept (released only with patterns)
        assert M_ii is not None and K_ii is not None, "mode blocks without K_ii, M_ii or their Grams"
        MPhi = M_ii.matMult(Phi)
        KPhi = K_ii.matMult(Phi)
        Mmm = gather_rows(Phi.transposeMatMult(MPhi), comm)
        Kmm = gather_rows(Phi.transposeMatMult(KPhi), comm)
    blocks_M.append((modes, modes, 0.5 * (Mmm + Mmm.T)))
    blocks_K.append((modes, modes, 0.5 * (Kmm + Kmm.T)))
    if Psi is not None:
        # constraint modes exist for interface coordinates only, which come with their columns Cb, Db
        assert Cb is not None and Db is not None, "constraint modes without the couplings' interface columns"
        Mbm = gather_rows(Db.transposeMatMult(Phi), comm) + gather_rows(Psi.transposeMatMult(MPhi), comm)
        blocks_M.append((qb, modes, Mbm))
        blocks_M.append((modes, qb, Mbm.T))
        # C^T Phi + Psi^T K_ii Phi = 0 in exact arithmetic (Craig-Bampton decoupling);
        # kept as computed so that K_r = T^T K T to rounding
        Kbm = gather_rows(Cb.transposeMatMult(Phi), comm) + gather_rows(Psi.transposeMatMult(KPhi), comm)
        blocks_K.append((qb, modes, Kbm))
        blocks_K.append((modes, qb, Kbm.T))
    elif len(qb):
        # interface patterns instead of constraint modes: the zone's interface coordinates
        # couple to the interior's vectors through K_iz, M_iz only (C^T Phi, D^T Phi)
        assert Cb is not None and Db is not None, "interface coordinates without the couplings' columns"
        Mbm = gather_rows(Db.transposeMatMult(Phi), comm)
        Kbm = gather_rows(Cb.transposeMatMult(Phi), comm)
        blocks_M += [(qb, modes, Mbm), (modes, qb, Mbm.T)]
        blocks_K += [(qb, modes, Kbm), (modes, qb, Kbm.T)]
    if basis.grams is None:
        MPhi.destroy()
        KPhi.destroy()


def _log_reduction(red: ReducedModel) -> None:
    """One line per body and one for the reduced model (rank 0)."""
    for b in red.bodies:
        f = b.frequencies_hz[: b.n_modes - b.n_augmented - b.n_patterns]
        log.info(
            "reduction %s: %d interior dofs -> %d modes (%s)%s, %d interface coordinates",
            b.name,
            b.n_interior,
            len(f),
            f"{f[0]:.4g}-{f[-1]:.4g} Hz" if len(f) else "none",
            f" + {b.n_augmented} augmentation vectors"
            if b.n_augmented
            else f" + {b.n_patterns} zone-interface pattern vectors"
            if b.n_patterns
            else "",
            len(b.qb),
        )
    log.info(
        "reduced model: %d coordinates (%d zone, %d modal) in %.2f s",
        red.n_global,
        red.n_zone,
        red.n_modes,
        red.timings["total"],
    )


def combine_blocks(
    Sk: PETSc.Mat, Sm: PETSc.Mat, blocks_K: list, blocks_M: list, red_lo: int, n_loc: int, n: int, sizes, comm: MPI.Comm
) -> tuple[PETSc.Mat, PETSc.Mat]:
    """K_r and M_r as AIJ matrices on one common non-zero pattern: the sparse zone blocks Sk, Sm
    plus dense blocks (rows, cols, values with global reduced indices). The common pattern lets
    the integrators form K + c M with MatAXPY(SAME/SUBSET_NONZERO_PATTERN), which in parallel
    fails on differing patterns."""
    rows_l, cols_l, vals_l = [], [], []
    for S, unit in ((Sk, 1.0), (Sm, 1.0j)):
        indptr, indices, data = S.getValuesCSR()
        rows_l.append(np.repeat(np.arange(n_loc), np.diff(indptr)))
        cols_l.append(np.asarray(indices, dtype=np.int64))
        vals_l.append(unit * np.asarray(data))
    for blocks, unit in ((blocks_K, 1.0), (blocks_M, 1.0j)):
        for rows, cols, vals in blocks:
            mine = (rows >= red_lo) & (rows < red_lo + n_loc)
            if not np.any(mine) or len(cols) == 0:
                continue
            r = rows[mine] - red_lo
            rows_l.append(np.repeat(r, len(cols)))
            cols_l.append(np.tile(np.asarray(cols, dtype=np.int64), len(r)))
            vals_l.append(unit * vals[mine].ravel())
    # complex data: real part K, imaginary part M, summed on one pattern (zeros are kept)
    A = sp.coo_matrix(
        (np.concatenate(vals_l), (np.concatenate(rows_l), np.concatenate(cols_l))), shape=(n_loc, n)
    ).tocsr()
    A.sum_duplicates()
    A.sort_indices()
    out = []
    for part in (A.data.real.copy(), A.data.imag.copy()):
        B = PETSc.Mat().createAIJ(sizes, csr=(A.indptr.astype(np.int32), A.indices.astype(np.int32), part), comm=comm)
        B.assemble()
        out.append(B)
    return out[0], out[1]
