"""Reduction: Craig-Bampton projection of a finite-element model, u = T q (DESIGN.md section 4).

Stage ``reduction`` of a run (DESIGN.md section 1). Every reduced method is a Galerkin projection
of a full model (:class:`millimpact.fem.model.FEModel`): the time loop, the contact rows and the
outputs run on ``M_r = T^T M T``, ``K_r = T^T K T`` and ``B_r = B T``.

The owned dofs of the model fall into three sets:

* ``fixed``: clamped and symmetry dofs (``FEModel.fixed_dofs``). ``T`` has zero rows there, so
  every reduced state keeps them at zero; they carry no reduced coordinate.
* ``zone``: the dofs of the cells tagged ``BALL_ZONE`` / ``BLOCK_ZONE`` (including the nodes on the
  zone/region interface). They are described by a :class:`~.partition.ZoneBasis` ``u_z = G q_z``: the identity
  (``traditional``, ``modal-p2``: nodal dofs kept physical) or the manifold prolongation of
  :mod:`millimpact.reduction.nmm_zone` (``improved``).
* ``interior``: the rest (the non-contact region of each body), reduced per body by Craig-Bampton:

      u_i = Psi q_b + Phi eta,   Psi = -K_ii^-1 K_iz G  (static constraint modes),
      K_ii phi_k = omega_k^2 M_ii phi_k                 (fixed-interface modes, SLEPc).

  ``Psi`` has non-zero columns only for the zone coordinates ``q_b`` that touch the interface
  (``K_iz G`` couples interior dofs to interface nodes only). One Cholesky factorization of
  ``K_ii`` per body serves the multi-right-hand-side solve for ``Psi`` and the shift-and-invert
  spectral transformation of the eigensolver (shift 0).

Modes are kept up to a cutoff frequency (``f_cut``, default the plan's 4 / t_c: below ~1/t_c a
mode's dynamic error is large, DESIGN.md section 4) or a fixed count per body. Because ``Psi`` is
the static response of the interior to the interface, the constraint modes reproduce every
zero-energy motion of the interface exactly: the free ball keeps its rigid motion.

On-disk cache (:mod:`.cache`): a body's Psi and Phi are kept under a hash of the matrices they
come from (K_ii, M_ii, C, D, each rank's rows), the cutoff and the solver options, so a rerun, a
second contact table or a study over parameters that leave the body alone skips the
factorization, the constraint-mode solve and the eigensolve; K_ii is then factored only if the
mode-acceleration rows need it. paper-rig: the offline reduction 13.5 s -> 5.2 s, F_max and e
identical.

Optional modal truncation augmentation (``augment``, off by default): per body and zone-motion
pattern one more interior vector, the static response of the interior to the inertia load of that
motion, orthogonalised against the kept modes (Dickens et al. 1997). It restores the quasi-static
response of the truncated modes to the contact pulse: F_max at a 1 / t_c cutoff 3.0 % -> 0.05 %
from full P1 (tests/methods/test_reduced_validation.py). Measured effect on the gauge peaks at 4 / t_c
(issue 5; gauges 7.5-15 mm from the contact): on the default mesh traditional 9.0 / 7.3 / 0.5 %
-> 2.8 / 3.2 / 1.8 % (A / B / C) and improved 4.5 / 2.4 / 1.4 % -> 1.1 / 2.4 / 0.9 %, but on the
coarse test mesh traditional 2.0 / 1.5 / 2.6 % -> 5.6 / 5.4 / 12 %: the gauge stresses carry
content far above any affordable cutoff, so they are not a smooth function of the basis, and the
augmentation is not the default.

Output recovery by mode acceleration (:meth:`~.reduced_model.ReducedModel.mode_acceleration_rows`, the default of
the reduced methods' recorder): outputs in a body's interior (the gauges) add ``C q''`` to
``A T q``, the truncated modes' quasi-static response to the interior's inertia (residual
flexibility ``K_ii^-1 - Phi Omega^-2 Phi^T`` applied to ``(M_ii Psi + M_ib) q_b''``). The dynamics
do not change; the stresses next to the zone converge much faster with the cutoff: gauge A of the
block's 15.4 kHz free mode -14 % -> +0.3 %, and the band-limited gauge peaks of an impact 4.5 % ->
0.5 % (test mesh, 4/t_c; tests/methods/test_reduced_validation.py). Cost: one solve per output row with
the factorization of ``K_ii`` (kept until :meth:`~.reduced_model.ReducedModel.release_recovery`).

The reduced matrices have a sparse zone block ``G^T K_zz G`` plus dense blocks on the interface
coordinates and the modes (in closed form, no dense ``n x n`` matrix is ever formed)::

    K_r = [ G^T K_zz G + C^T Psi      0          ]     C = K_iz G,  D = M_iz G
          [ 0                         Phi^T K Phi ]
    M_r = [ G^T M_zz G + D^T Psi + Psi^T D + Psi^T M_ii Psi    D^T Phi + Psi^T M_ii Phi ]
          [ sym.                                               Phi^T M_ii Phi            ]

Reduced coordinates are numbered rank by rank: first the zone coordinates a rank owns, then its
share of the modes (all ball modes before all block modes in the global mode order).

With ``<prefix>substructures S`` (S >= 2) a body's Psi and Phi come instead from a Ritz basis
built slab by slab (:mod:`.substructures`): no factorization of the whole K_ii, the mode-acceleration
rows from the Ritz space (``BodyReduction.residual_b``).

The stage's other modules: :mod:`.partition` (dof sets, zone bases), :mod:`.eigen` (SLEPc),
:mod:`.augmentation`, :mod:`.reduced_model` (M_r, K_r, T, recovery), :mod:`.distributed` (PETSc
helpers) and :mod:`.free_modes`: the lowest free-vibration modes of a reduced model
(u = T Phi eta), which the reduced methods propagate in closed form
between impacts (:mod:`millimpact.methods.reduced`).

PETSc and SLEPc objects live here and in :mod:`millimpact.reduction.nmm_zone` only (STYLE.md). Options
prefixes: ``impact_reduction_<body>_`` for the factorization of ``K_ii`` (``ksp_``, ``pc_``)
and its eigensolver (``eps_``, ``st_``; ``inertia_`` the count of modes under the cutoff,
``block_krylov_size`` the block Krylov solver's block, :mod:`.eigen`; ``substructures`` and
``substructure_*``, :mod:`.substructures`);
``impact_reduction_free_<body>_`` for the free-vibration modes; ``impact_reduction_mass_`` for
the solve with ``M_r`` that projects initial states.
Defaults come from :func:`default_solver_options`, the ``solver_options`` arguments merge over
them and the command line wins.
"""
from __future__ import annotations

import logging
import math
import time
from typing import Any, Optional, Sequence

import numpy as np
import scipy.sparse as sp
from mpi4py import MPI
from petsc4py import PETSc

from ..errors import InputError, SolverError
from ..fem.model import FEModel
from ..integration.solvers import create_factored_solver, note_option_read, return_freed_memory

log = logging.getLogger(__name__)

from . import cache as reduction_cache
from .partition import BODIES, DofPartition, ZoneBasis, create_nodal_zone_basis, partition_dofs
from .distributed import (dense_columns, dense_from_rows, detached, gather_rows, local_columns_csr, ownership_offsets,
                          split_evenly)
from .eigen import compute_modes, default_solver_options
from .augmentation import AUGMENTATION_PATTERNS, compute_augmentation_load, compute_augmentation_vectors, interface_motion_pattern
from .reduced_model import BodyReduction, ReducedModel
from .interface_patterns import probe_interior_rows, zone_pattern_couplings
from .substructures import substructure_settings, substructured_modes


#: the arrays of a body's Ritz-space output recovery (substructures.ritz_recovery), as cached
RECOVERY_KEYS = ("rows", "V", "H_C", "H_D", "H_M")
#: relative residual accepted for the constraint modes K_ii Psi = -C (a direct solve gives ~1e-12)
CONSTRAINT_RESIDUAL_TOL = 1e-8

# --- Craig-Bampton -------------------------------------------------------------------------------
def reduce_model(model: FEModel, zone: Optional[ZoneBasis] = None, *, f_cut: Optional[float] = None,
                 n_modes: Optional[int] = None, partition: Optional[DofPartition] = None,
                 solver_options: Optional[dict[str, str]] = None,
                 augment: Sequence[str] = (), keep_away: Optional[np.ndarray] = None) -> ReducedModel:
    """Craig-Bampton reduction of ``model``: the zone described by ``zone`` (default: nodal, the
    identity), each body's interior by constraint modes and fixed-interface modes up to ``f_cut``
    (Hz) or ``n_modes`` per body (``n_modes`` wins if both are given; ``n_modes >=`` the interior
    size keeps every mode and reproduces the full model exactly). ``augment``: zone-motion
    patterns (:data:`AUGMENTATION_PATTERNS`) whose modal truncation augmentation vectors are
    appended to each body's modes (one per pattern and body, see
    :func:`compute_augmentation_vectors`). ``keep_away`` (k x 3, m): points a substructured body's
    cuts keep away from (the gauges, :mod:`.substructures`). Collective."""
    if f_cut is None and n_modes is None:
        raise InputError("reduction: give a modal cutoff f_cut (Hz) or a mode count per body")
    if f_cut is not None and not (f_cut > 0):
        raise InputError(f"reduction: f_cut = {f_cut!r} Hz must be > 0")
    if n_modes is not None and n_modes < 0:
        raise InputError(f"reduction: modes = {n_modes!r} must be >= 0")
    bad = [a for a in augment if a not in AUGMENTATION_PATTERNS]
    if bad:
        raise InputError(f"reduction: augment = {','.join(bad)}: choose from {', '.join(AUGMENTATION_PATTERNS)} "
                         "or none")
    t_start = time.perf_counter()
    comm = model.comm
    opts = default_solver_options(comm.size)
    opts.update(solver_options or {})
    part = partition or partition_dofs(model)
    zone = zone or create_nodal_zone_basis(model, part)
    K, M = model.K, model.M
    n_loc = part.n_owned
    r0 = K.getOwnershipRange()[0]
    all_cols = PETSc.IS().createStride(n_loc, r0, 1, comm=comm)

    # reduced numbering: per rank [owned zone coordinates, owned modes]; modes known later, so the
    # zone coordinates are numbered first in "q" numbering and moved at the end
    q_off = ownership_offsets(comm, zone.n_local)
    G_q = zone.G
    timings: dict[str, float] = {}

    body_data = []
    for name, _tags in BODIES:
        tb = time.perf_counter()
        idx = part.interior[name]
        I = PETSc.IS().createGeneral((r0 + idx).astype(np.int32), comm=comm)
        n_i = comm.allreduce(len(idx))
        data: dict[str, Any] = {"name": name, "I": I, "n_i": n_i, "timings": {}}
        if n_i == 0:
            body_data.append(data)
            continue
        K_ii = K.createSubMatrix(I, I)
        M_ii = M.createSubMatrix(I, I)
        K_ia, M_ia = K.createSubMatrix(I, all_cols), M.createSubMatrix(I, all_cols)
        C = detached(K_ia.matMult(G_q))      # K_iz G   (n_i x n_q)
        D = detached(M_ia.matMult(G_q))      # M_iz G
        # interface coordinates: the non-zero columns of C and D
        cols_loc = np.unique(np.concatenate([C.getValuesCSR()[1], D.getValuesCSR()[1]]))
        qb = np.unique(np.concatenate(comm.allgather(cols_loc.astype(np.int64))))
        n_b = len(qb)
        prefix = f"impact_reduction_{name}_"
        Psi = None
        Cb = Db = rhs = None
        # slab-wise Ritz basis instead of one factorization of K_ii (option <prefix>substructures)
        sub = (substructure_settings(prefix, opts, n_i) if f_cut is not None and n_modes is None and not augment
               else None)
        patterns = bool(sub is not None and sub.zone_degree and n_b)
        # zone-interface patterns: the interior's static responses to a few smooth interface motions
        # replace the n_b constraint modes (K_iz W, M_iz W instead of C, D; K_ia and M_ia, a copy of
        # the interior's rows of K and M, freed at once: 2.2 GB at the plan's 1.2M DOFs)
        CD_pat = zone_pattern_couplings(model, part, name, sub.zone_degree, K_ia, M_ia) if patterns else None
        K_ia.destroy()
        M_ia.destroy()
        return_freed_memory()
        if n_b:
            # sparse interface columns (for the products) and a dense copy of C's (the right-hand
            # sides of the multi-RHS solve: MUMPS takes dense right-hand sides)
            q_lo_b, q_hi_b = G_q.getOwnershipRangeColumn()
            is_qb = PETSc.IS().createGeneral(qb[(qb >= q_lo_b) & (qb < q_hi_b)].astype(np.int32), comm=comm)
            rows_I = PETSc.IS().createStride(len(idx), C.getOwnershipRange()[0], 1, comm=comm)
            Cb = C.createSubMatrix(rows_I, is_qb)
            Db = D.createSubMatrix(rows_I, is_qb)
            # (not for slabs: they take C and D sparse, and a dense copy of the 1.2M-DOF panel's is 5.2 GB)
            rhs = dense_columns(C, qb, comm) if sub is None else None
        # Psi, Phi from the on-disk cache when the same matrices and settings were reduced before
        # (reduction.cache; not with augmentation vectors)
        t0 = time.perf_counter()
        key = None if augment else reduction_cache.body_key(
            comm, [K_ii, M_ii, C, D], {"body": name, "f_cut": f_cut, "n_modes": n_modes,
                                       "options": sorted((k, str(v)) for k, v in opts.items()),
                                       # the command line's options for this body's solvers too
                                       "petsc": sorted((k, str(v)) for k, v in PETSc.Options().getAll().items()
                                                       if k.startswith(prefix))})
        cached = reduction_cache.load(comm, key) if key else None
        ksp = None
        data["n_aug"] = data["n_pat"] = 0
        if cached is not None:
            for k in PETSc.Options().getAll():     # in the key: they shaped these modes (no "unused" warning)
                if k.startswith(prefix):
                    note_option_read(k)
            data["n_pat"] = int(cached.get("n_patterns", 0))
            if "recovery_V" in cached:
                data["ritz_recovery"] = {k: cached["recovery_" + k] for k in RECOVERY_KEYS}
            if n_b and not data["n_pat"]:
                Psi = dense_from_rows(cached["Psi"], comm)
                data["constraint_residual"] = float(cached["residual"])
                if sub is not None and "flex" in cached:
                    data["residual_b"] = dense_from_rows(cached["flex"], comm)
            freq, nxt, phi_cols = np.asarray(cached["freq"]), float(cached["next"]), cached["Phi"]
            data["timings"]["from_cache"] = time.perf_counter() - t0
        elif sub is not None:
            material = model.ball_material if name == "ball" else model.target_material
            node_xyz = model.V.tabulate_dof_coordinates()[idx // 3]
            C_s, D_s = CD_pat if patterns else (local_columns_csr(C, qb), local_columns_csr(D, qb))
            res = substructured_modes(
                K_ii, M_ii, C_s, D_s, node_xyz, idx % 3, f_cut, math.sqrt(material.shear_modulus / material.density),
                sub, prefix, opts, keep_away, patterns=patterns,
                zone_couplings=(local_columns_csr(C, qb), local_columns_csr(D, qb)) if patterns else None,
                recovery_rows=(probe_interior_rows(model, idx, keep_away) if patterns and name == "block"
                               and keep_away is not None and len(keep_away) else None), release=patterns)
            freq, nxt, phi_cols = res["freq"], res["next"], res["Phi"]
            data["n_pat"], data["ritz_recovery"], data["grams"] = res["n_patterns"], res["recovery"], res["grams"]
            if patterns:        # destroyed by substructured_modes: its Grams replace the products
                K_ii = M_ii = None
            if n_b and not patterns:
                Psi, data["residual_b"] = res["Psi"], res["flex"]
                # a Galerkin Psi: reported, not checked (exact only with every interface dof a trace)
                data["constraint_residual"] = res["residual"]
            else:
                for m in (res["Psi"], res["flex"]):
                    if m is not None:
                        m.destroy()
            data["substructures"] = res["stats"]
            data["timings"]["substructures"] = time.perf_counter() - t0
            return_freed_memory()
        else:
            ksp = create_factored_solver(K_ii, prefix, opts)
            data["timings"]["factor"] = time.perf_counter() - t0
            if n_b:
                t0 = time.perf_counter()
                Psi = rhs.duplicate()
                F = ksp.getPC().getFactorMatrix()
                F.matSolve(rhs, Psi)
                Psi.scale(-1.0)
                # residual check: K_ii Psi + C = 0
                R = K_ii.matMult(Psi)
                R.axpy(1.0, rhs)
                res = R.norm(PETSc.NormType.FROBENIUS) / max(rhs.norm(PETSc.NormType.FROBENIUS), 1e-300)
                R.destroy()
                if not res < CONSTRAINT_RESIDUAL_TOL:
                    raise SolverError(f"constraint modes of the {name}: relative residual {res:.3g} "
                                      f"(factorization {prefix})")
                data["timings"]["constraint_modes"] = time.perf_counter() - t0
                data["constraint_residual"] = res
            t0 = time.perf_counter()
            xs = []
            for kind in dict.fromkeys(augment):
                u_w = interface_motion_pattern(model, part, name, kind)
                xs.append(compute_augmentation_load(K, M, I, all_cols, K_ii, M_ii, ksp, u_w))
                u_w.destroy()
            t_aug = time.perf_counter() - t0
            t0 = time.perf_counter()
            freq, vecs, nxt = compute_modes(K_ii, M_ii, ksp, f_cut, n_modes, prefix, opts)
            data["timings"]["eigenmodes"] = time.perf_counter() - t0
            if xs:
                t0 = time.perf_counter()
                f_aug, v_aug = compute_augmentation_vectors(K_ii, M_ii, xs, vecs)
                for x in xs:
                    x.destroy()
                freq = np.concatenate([freq, f_aug])
                vecs = list(vecs) + v_aug
                data["n_aug"] = len(v_aug)
                data["timings"]["augmentation"] = t_aug + time.perf_counter() - t0
            phi_cols = np.zeros((len(idx), len(vecs)))
            for k, v in enumerate(vecs):
                phi_cols[:, k] = v.getArray(readonly=True)
                v.destroy()
        if key and cached is None:
            flex = data.get("residual_b")
            reduction_cache.store(comm, key, {
                "Psi": Psi.getDenseArray().copy() if Psi is not None else np.zeros((0, 0)), "Phi": phi_cols,
                "freq": np.asarray(freq), "next": np.asarray(nxt), "n_patterns": np.asarray(data["n_pat"]),
                **{"recovery_" + k: v for k, v in (data.get("ritz_recovery") or {}).items()},
                **({"flex": flex.getDenseArray()} if flex is not None else {}),
                "residual": np.asarray(data.get("constraint_residual", 0.0))})
        if rhs is not None:
            rhs.destroy()
        Phi = None
        if phi_cols.shape[1]:
            # on phi_cols' own storage when it is column-major (the slabs' Phi): no second copy
            Phi = PETSc.Mat().createDense(((len(idx), n_i), (PETSc.DECIDE, phi_cols.shape[1])),
                                          array=np.asfortranarray(phi_cols), comm=comm)
            Phi.assemble()
        # the mode-acceleration rows factor K_ii on demand; not for a substructured body (the point of
        # substructuring is never to hold that factorization)
        data["factor"] = (None if sub is not None else
                          (lambda K_ii=K_ii, prefix=prefix: create_factored_solver(K_ii, prefix, opts)))
        data["from_cache"] = cached is not None
        data.update(K_ii=K_ii, M_ii=M_ii, C=C, D=D, Cb=Cb, Db=Db, qb_q=qb, Psi=Psi, Phi=Phi, freq=freq,
                    next=nxt, ksp=ksp)
        data["timings"]["total"] = time.perf_counter() - tb
        body_data.append(data)

    # mode numbering
    m_total = sum(len(d.get("freq", ())) for d in body_data)
    m_loc = split_evenly(m_total, comm.size, comm.rank)
    m_off = ownership_offsets(comm, m_loc)
    red_off = q_off + m_off          # first reduced index of each rank

    def q_to_red(gq: np.ndarray) -> np.ndarray:
        owner = np.searchsorted(q_off, gq, side="right") - 1
        return gq + m_off[owner]

    def mode_to_red(gm: np.ndarray) -> np.ndarray:
        owner = np.searchsorted(m_off, gm, side="right") - 1
        return gm + q_off[owner + 1]

    n_red_loc = zone.n_local + m_loc
    n_red = int(red_off[-1])
    red_lo = int(red_off[comm.rank])

    # T's zone part with reduced column numbering: G_r = G E
    q_lo = int(q_off[comm.rank])
    rows = np.arange(q_lo, q_lo + zone.n_local)
    E_csr = (np.arange(zone.n_local + 1, dtype=np.int32), q_to_red(rows).astype(np.int32), np.ones(zone.n_local))
    E = PETSc.Mat().createAIJ(((zone.n_local, PETSc.DETERMINE), (n_red_loc, n_red)), csr=E_csr, comm=comm)
    E.assemble()
    Gr = G_q.matMult(E)

    # zone blocks G^T K G, G^T M G (sparse)
    t0 = time.perf_counter()
    Kzz = K.PtAP(Gr)
    Mzz = M.PtAP(Gr)
    timings["zone_projection"] = time.perf_counter() - t0

    # dense blocks, per body
    t0 = time.perf_counter()
    blocks_K: list[tuple[np.ndarray, np.ndarray, np.ndarray]] = []   # (rows, cols, dense values)
    blocks_M: list[tuple[np.ndarray, np.ndarray, np.ndarray]] = []
    bodies: list[BodyReduction] = []
    mode_start = 0
    for d in body_data:
        name = d["name"]
        if d["n_i"] == 0:
            bodies.append(BodyReduction(name, 0, d["I"], None, np.zeros(0, np.int64), None, np.zeros(0, np.int64),
                                        np.zeros(0), f_cut, math.nan, d["timings"]))
            continue
        freq = d["freq"]
        modes = mode_to_red(np.arange(mode_start, mode_start + len(freq)))
        mode_start += len(freq)
        qb = q_to_red(d["qb_q"])
        Psi, Phi, Cb, Db, K_ii, M_ii = d["Psi"], d["Phi"], d["Cb"], d["Db"], d["K_ii"], d["M_ii"]
        M_ib = None
        if Psi is not None:
            Kbb = gather_rows(Cb.transposeMatMult(Psi), comm)
            Kbb = 0.5 * (Kbb + Kbb.T)
            MPsi = M_ii.matMult(Psi)
            # the mode-acceleration rows need A_b = M_ii Psi + M_ib: kept as M_ib (sparse) and formed
            # against their few columns, not as a dense n_i x n_b copy (5.2 GB at the plan's 1.2M DOFs)
            if d["factor"] is not None:
                M_ib = Db
            DtPsi = gather_rows(Db.transposeMatMult(Psi), comm)
            Mbb = DtPsi + DtPsi.T + gather_rows(Psi.transposeMatMult(MPsi), comm)
            Mbb = 0.5 * (Mbb + Mbb.T)
            MPsi.destroy()
            blocks_K.append((qb, qb, Kbb))
            blocks_M.append((qb, qb, Mbb))
        if Phi is not None:
            if d.get("grams") is not None:      # from the Ritz space: no n_i x m products
                Mmm, Kmm = d["grams"]
            else:
                MPhi = M_ii.matMult(Phi)
                KPhi = K_ii.matMult(Phi)
                Mmm = gather_rows(Phi.transposeMatMult(MPhi), comm)
                Kmm = gather_rows(Phi.transposeMatMult(KPhi), comm)
            blocks_M.append((modes, modes, 0.5 * (Mmm + Mmm.T)))
            blocks_K.append((modes, modes, 0.5 * (Kmm + Kmm.T)))
            if Psi is not None:
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
                Mbm = gather_rows(Db.transposeMatMult(Phi), comm)
                Kbm = gather_rows(Cb.transposeMatMult(Phi), comm)
                blocks_M += [(qb, modes, Mbm), (modes, qb, Mbm.T)]
                blocks_K += [(qb, modes, Kbm), (modes, qb, Kbm.T)]
            if d.get("grams") is None:
                MPhi.destroy()
                KPhi.destroy()
        for m in (d["C"], d["D"], Cb, Db if M_ib is None else None):
            if m is not None:
                m.destroy()
        bodies.append(BodyReduction(name, d["n_i"], d["I"], Psi, qb, Phi, modes, freq, f_cut, d["next"],
                                    d["timings"], d["n_aug"], n_patterns=d["n_pat"], ksp=d["ksp"], M_ib=M_ib, K_ii=K_ii,
                                    factor=d["factor"], from_cache=d["from_cache"],
                                    substructures=d.get("substructures"), residual_b=d.get("residual_b"),
                                    ritz_recovery=d.get("ritz_recovery")))
    timings["dense_blocks"] = time.perf_counter() - t0

    sizes = ((n_red_loc, n_red), (n_red_loc, n_red))
    K_r, M_r = combine_blocks(Kzz, Mzz, blocks_K, blocks_M, red_lo, n_red_loc, n_red, sizes, comm)
    for m in (Kzz, Mzz, E):
        m.destroy()

    # ball coordinates: zone coordinates of the ball and the ball's modes
    ball = [np.nonzero(zone.body == 0)[0]]
    for b in bodies:
        if b.name == "ball" and b.n_modes:
            own = b.modes[(b.modes >= red_lo) & (b.modes < red_lo + n_red_loc)] - red_lo
            ball.append(own)
    ball_coords = np.unique(np.concatenate(ball)).astype(np.int32)
    # zone coordinates sit first in each rank's block, so their local index is unchanged
    timings["total"] = time.perf_counter() - t_start
    red = ReducedModel(model, zone, part, M_r, K_r, Gr, bodies, ball_coords, zone.n_global, timings)
    if comm.rank == 0:
        for b in bodies:
            f = b.frequencies_hz[:b.n_modes - b.n_augmented - b.n_patterns]
            log.info("reduction %s: %d interior dofs -> %d modes (%s)%s, %d interface coordinates",
                     b.name, b.n_interior, len(f), f"{f[0]:.4g}-{f[-1]:.4g} Hz" if len(f) else "none",
                     f" + {b.n_augmented} augmentation vectors" if b.n_augmented else
                     f" + {b.n_patterns} zone-interface pattern vectors" if b.n_patterns else "", len(b.qb))
        log.info("reduced model: %d coordinates (%d zone, %d modal) in %.2f s", red.n_global, red.n_zone,
                 red.n_modes, timings["total"])
    return red


def combine_blocks(Sk: PETSc.Mat, Sm: PETSc.Mat, blocks_K: list, blocks_M: list, red_lo: int, n_loc: int, n: int,
             sizes, comm: MPI.Comm) -> tuple[PETSc.Mat, PETSc.Mat]:
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
    A = sp.coo_matrix((np.concatenate(vals_l), (np.concatenate(rows_l), np.concatenate(cols_l))),
                      shape=(n_loc, n)).tocsr()
    A.sum_duplicates()
    A.sort_indices()
    out = []
    for part in (A.data.real.copy(), A.data.imag.copy()):
        B = PETSc.Mat().createAIJ(sizes, csr=(A.indptr.astype(np.int32), A.indices.astype(np.int32), part), comm=comm)
        B.assemble()
        out.append(B)
    return out[0], out[1]


