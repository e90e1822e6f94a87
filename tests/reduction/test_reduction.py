"""Reduced models: Craig-Bampton (millimpact.reduction.craig_bampton), manifold enrichment (millimpact.reduction.nmm_zone)
and the reduced run methods (millimpact.methods.reduced), on a small paper-rig mesh.

The small mesh (h_contact 0.8 mm, h_far 8 mm, zone radius 5 mm; half model) has ~1.8k P1 and
~10.6k P2 dofs; its contact candidates (2.5 a_max = 2.9 mm) stay inside the zone.
"""
from __future__ import annotations

import logging
import math

import numpy as np
import pytest
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from conftest import SMALL_RIG, run_mpi_script, small_rig_mesh

from mpi4py import MPI

SMALL = SMALL_RIG
serial = pytest.mark.skipif(MPI.COMM_WORLD.size > 1, reason="serial test (scipy on gathered matrices)")


# --- fixtures ------------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def setup():
    return small_rig_mesh()


@pytest.fixture(scope="module")
def p1(setup):
    from millimpact.fem.model import create_fe_model

    scene, plan, md = setup
    return create_fe_model(md, plan, 1)


@pytest.fixture(scope="module")
def p2(setup):
    from millimpact.fem.model import create_fe_model

    scene, plan, md = setup
    return create_fe_model(md, plan, 2)


@pytest.fixture(scope="module")
def traditional(p1, setup):
    from millimpact.reduction.craig_bampton import reduce_model

    return reduce_model(p1, f_cut=setup[1].f_cut)


# --- helpers -------------------------------------------------------------------------------------
def csr(A) -> sp.csr_matrix:
    """A serial PETSc AIJ matrix as scipy CSR."""
    indptr, indices, data = A.getValuesCSR()
    return sp.csr_matrix((data, indices, indptr), shape=A.getSize())


def lowest_hz(K: sp.spmatrix, M: sp.spmatrix, k: int) -> np.ndarray:
    """The k lowest natural frequencies (Hz) of K x = w^2 M x (shift-invert at 0)."""
    lam = spla.eigsh(K.tocsc(), k=k, M=M.tocsc(), sigma=0.0, which="LM", return_eigenvectors=False)
    return np.sqrt(np.sort(lam)) / (2 * math.pi)


def clamped_block(model) -> tuple[sp.csr_matrix, sp.csr_matrix]:
    """K and M of the clamped block of a full model (the ball is a separate body)."""
    sel = np.zeros(model.K.getSize()[0], dtype=bool)
    sel[model.block_dofs] = True
    sel[model.fixed_dofs] = False
    return csr(model.K)[sel][:, sel].tocsr(), csr(model.M)[sel][:, sel].tocsr()


def block_hz(model, k: int = 6) -> np.ndarray:
    """Lowest frequencies of the clamped block of a full model."""
    return lowest_hz(*clamped_block(model), k)


def block_hz_reduced(red, k: int = 6) -> np.ndarray:
    """Lowest frequencies of the block's reduced coordinates."""
    sel = np.ones(red.n_global, dtype=bool)
    sel[red.ball_coords] = False
    return lowest_hz(csr(red.K)[sel][:, sel], csr(red.M)[sel][:, sel], k)


def rigid_field(model, centre, kind: str):
    """A rigid motion of the ball (zero on the block and on fixed dofs) as a model vector."""
    from millimpact.reduction.partition import partition_dofs

    V = model.V
    n_own = V.dofmap.index_map.size_local
    x = V.tabulate_dof_coordinates()[:n_own]
    if kind == "ty":
        U = np.tile([0.0, 1.0, 0.0], (n_own, 1))
    elif kind == "tz":
        U = np.tile([0.0, 0.0, 1.0], (n_own, 1))
    else:  # rotation about the x axis through the ball's centre (allowed by the x symmetry plane)
        U = np.cross(np.array([1.0, 0.0, 0.0]), x - np.asarray(centre))
    U[~partition_dofs(model).ball_node[:n_own]] = 0.0
    u = model.M.createVecRight()
    u.array[:] = U.ravel()
    u.array[model.fixed_dofs] = 0.0
    return u


# --- Craig-Bampton ---------------------------------------------------------------------------------
@serial
def test_all_modes_reproduce_full_model(p1):
    """With every fixed-interface mode kept, T is square and invertible: the reduced model is the
    full model in other coordinates (same eigenfrequencies), and the closed-form reduced matrices
    equal T^T M T and T^T K T formed by PETSc's PtAP from the explicit T."""
    from millimpact.reduction.craig_bampton import reduce_model

    red = reduce_model(p1, n_modes=10**6)
    n_free = p1.K.getSize()[0] - len(p1.fixed_dofs)
    assert red.n_global == n_free
    T = red.assemble_T()
    for A, Ar in ((p1.M, red.M), (p1.K, red.K)):
        ref = csr(A.PtAP(T))
        # rounding of the dense blocks (products of ~1e3 terms): ~1e-15 of the largest entry
        assert abs(csr(Ar) - ref).max() <= 1e-12 * abs(ref).max()
    f_full = block_hz(p1)
    f_red = block_hz_reduced(red)
    # same eigenproblem in other coordinates: rounding of the shift-invert solves only
    np.testing.assert_allclose(f_red, f_full, rtol=1e-8)


@serial
def test_cutoff_reproduces_low_frequencies(p1, traditional, setup):
    """At the plan's cutoff (4 / t_c = 45.5 kHz) the reduced model reproduces the block's modes
    well below the cutoff; being a Rayleigh-Ritz approximation it never lies below the full model."""
    f_cut = setup[1].f_cut
    f_full = block_hz(p1, 8)
    f_red = block_hz_reduced(traditional, 8)
    assert np.all(f_red >= f_full * (1 - 1e-9))           # Rayleigh-Ritz upper bound (rounding)
    low = f_full < 0.5 * f_cut
    assert np.count_nonzero(low) >= 3
    # measured 2e-5 .. 5e-4 for modes below f_cut / 2 on this mesh: a Craig-Bampton mode at f
    # errs by O((f / f_cut)^2) of its mass fraction beyond the cut; 2e-3 leaves a 4x margin
    assert np.all(f_red[low] / f_full[low] - 1 < 2e-3)
    rep = traditional.report()
    for body in ("ball", "block"):
        b = rep["bodies"][body]
        assert b["modes"] >= 1 and b["highest_frequency_Hz"] <= f_cut < b["next_frequency_Hz"]


@serial
def test_p1_improved_p2_frequency_nesting(p1, p2):
    """Rayleigh-Ritz nesting of the unreduced spaces on one mesh, P1 in NMM-zone+P2 in P2:
    f(P2) <= f(improved space) <= f(P1), and P1 converges towards P2 (a refinement check: P2 is
    the richer discretization of the same mesh)."""
    from millimpact.reduction.nmm_zone import create_nmm_zone
    from millimpact.reduction.partition import partition_dofs

    f1, f2 = block_hz(p1), block_hz(p2)
    part = partition_dofs(p2)
    P = csr(create_nmm_zone(p2, part).basis.G)
    n = P.shape[0]
    inner = np.concatenate([part.interior["ball"], part.interior["block"]])
    E = sp.hstack([P, sp.csr_matrix((np.ones(len(inner)), (inner, np.arange(len(inner)))),
                                    shape=(n, len(inner)))]).tocsr()       # unreduced improved space
    blk = np.zeros(n, dtype=bool)
    blk[p2.block_dofs] = True
    cols = np.asarray(abs(E[blk]).sum(axis=0)).ravel() > 0                  # block coordinates
    Eb = E[:, cols]
    fi = lowest_hz((Eb.T @ csr(p2.K) @ Eb), (Eb.T @ csr(p2.M) @ Eb), 6)
    tol = 1e-9   # rounding of the shift-invert solves
    assert np.all(f2 <= fi * (1 + tol)) and np.all(fi <= f1 * (1 + tol))
    # the zone is a small part of the block: the NMM zone costs < 1e-4 of these frequencies
    # (measured <= 3e-5), while P1 on this coarse mesh is 0.6-6 % stiffer than P2 (measured)
    assert np.all(fi / f2 - 1 < 1e-4)
    assert np.all(f1 / f2 - 1 < 0.08)


@serial
def test_block_frequencies_converge(setup, p1, p2):
    """A refinement check of the clamped block's lowest frequencies: P2 barely moves when h_far
    drops from 8 to 5.6 mm (measured <= 0.1 %, so it serves as the reference), and the P1 error
    against it falls with h at a rate ~1.6 (measured; np.polyfit of log err on log h)."""
    from millimpact.geometry.mesh import create_mesh
    from millimpact.fem.model import create_fe_model
    from millimpact.scene.plan import make_plan

    scene, plan, _ = setup
    fine_scene = scene.with_value("model.h_far", 5.6e-3)
    fine_plan = make_plan(fine_scene)
    md = create_mesh(fine_scene, fine_plan, MPI.COMM_WORLD)
    f1_fine = block_hz(create_fe_model(md, fine_plan, 1), 4)
    f2_fine = block_hz(create_fe_model(md, fine_plan, 2), 4)
    f1, f2 = block_hz(p1, 4), block_hz(p2, 4)
    assert np.all(np.abs(f2 / f2_fine - 1) < 3e-3)          # P2 converged to 0.1 % (measured)
    err = np.array([np.mean(f1 / f2_fine - 1), np.mean(f1_fine / f2_fine - 1)])
    rate = np.polyfit(np.log([8e-3, 5.6e-3]), np.log(err), 1)[0]
    assert err[1] < err[0] and rate > 1.0                    # measured rate 1.57 (3.8 % -> 2.2 %)
    assert err[1] < 0.03                                      # P1 within 3 % at h_far 5.6 mm


@pytest.mark.parametrize("kind", ["nodal", "nmm"])
def test_ball_rigid_motion_is_exact(kind, p1, p2, setup):
    """Constraint modes reproduce a rigid interface motion exactly in the ball's interior: the
    projection of a rigid motion is exact (T q = u) and strain-free."""
    from millimpact.reduction.nmm_zone import create_nmm_zone
    from millimpact.reduction.craig_bampton import reduce_model
    from millimpact.reduction.partition import partition_dofs

    scene, plan, _ = setup
    model = p1 if kind == "nodal" else p2
    zone = create_nmm_zone(model).basis if kind == "nmm" else None
    red = reduce_model(model, zone, f_cut=plan.f_cut, partition=partition_dofs(model))
    centre = scene.ball_centre(plan.gap)
    for motion in ("ty", "tz", "rx"):
        u = rigid_field(model, centre, motion)
        q = red.project_state(u)
        err = red.expand(q)
        err.axpy(-1.0, u)
        # direct solves of well-conditioned systems: ~1e-13 measured
        assert err.norm() <= 1e-10 * u.norm()
        Kq = red.K.createVecLeft()
        red.K.mult(q, Kq)
        Mq = red.M.createVecLeft()
        red.M.mult(q, Mq)
        # u.K u of a rigid motion is rounding: K ~ 1e11 N/m times cancellation, relative to the
        # stiffness scale ||K|| |q|^2 (measured ~1e-13)
        assert abs(Kq.dot(q)) <= 1e-10 * red.K.norm() * q.dot(q)


def test_static_solve_keeps_one_factorization_per_shift(traditional):
    """ReducedModel.static_solve (the dent, the residual state q_s): (K_r + s M_r) q = rhs for every
    right-hand side, with one factorization per shift, kept and reused (a contact table's cases)."""
    red = traditional
    shift = 1e-3 * red.K.getDiagonal().max()[1] / red.M.getDiagonal().max()[1]
    for seed in (1, 2, 3):
        rhs = red.create_vector()
        rhs.setArray(np.random.default_rng(seed).normal(size=rhs.getLocalSize()))
        q = red.static_solve(rhs, shift, "test_static_", "test solve")
        A = red.K.copy()
        A.axpy(shift, red.M)
        r = rhs.duplicate()
        A.mult(q, r)
        r.axpy(-1.0, rhs)
        # a direct solve of K_r + s M_r (s 1e-3 of the largest diagonal ratio): 1.5-4e-13 measured
        assert r.norm() <= 1e-10 * rhs.norm()
        assert len(red._static) == 1            # the same factorization each time
    q2 = red.static_solve(rhs, 2.0 * shift, "test_static_", "test solve")
    assert len(red._static) == 2 and not np.allclose(q2.array, q.array)


# --- manifold enrichment -------------------------------------------------------------------------
@serial
def test_nmm_zone_mass_null_space_and_remedies(p2):
    """With every vertex enriched the zone mass P^T M P is singular: a = 0, b_i = c + W x_i
    (W antisymmetric) vanishes at every P2 node, 6 per scalar field and zone; on the x symmetry
    plane the u_x field keeps only 3 (its b^x_y, b^x_z are removed there), so 15 per zone and 30
    for ball + block. Each remedy makes it positive definite."""
    from millimpact.reduction.nmm_zone import create_nmm_zone
    from millimpact.reduction.partition import partition_dofs

    part = partition_dofs(p2)
    ratios = {}
    for remedy in ("none", "interface", "anchors"):
        z = create_nmm_zone(p2, part, remedy=remedy)
        P = csr(z.basis.G)
        fixed_rows = P[p2.fixed_dofs]
        assert fixed_rows.nnz == 0                       # clamped/symmetry dofs stay zero
        Mz = (P.T @ csr(p2.M) @ P).toarray()
        w = np.linalg.eigvalsh(Mz)
        ratios[remedy] = w[0] / w[-1]
        null = int(np.count_nonzero(w < 1e-12 * w[-1]))  # exact zeros sit at ~1e-17 (rounding)
        if remedy == "none":
            assert null == 30
        else:
            assert null == 0
    # measured 6.6e-5 (interface) and 3.5e-5 (anchors): the scale of the smallest cover functions
    # (mass ~ h^3 at the coarsest zone vertices) against the largest, nothing near rounding
    assert ratios["interface"] > 1e-6 and ratios["anchors"] > 1e-6


@serial
def test_a_whole_body_in_the_zone_is_kept_whole_and_its_covers_regular(setup):
    """A body the plan makes wholly plastic (``with_whole_bodies_in_zone``): its region cells join
    its zone, so it has no interior left to reduce, and its covers have no interface to take the
    edge framework's null space (without a remedy: 15 exact zeros per body, 30 here); three
    anchors among its vertices remove it: no exact zero (below 1e-12 of the largest; exact zeros
    sit at ~1e-17). The smallest eigenvalue, 4e-10 of the largest, is the whole ball's graded
    mesh (its coarse far cells' covers beside the contact's fine ones), not a null vector. The
    other body keeps its interior."""
    from millimpact.fem.model import create_fe_model
    from millimpact.geometry import builders as G
    from millimpact.geometry.mesh import with_whole_bodies_in_zone
    from millimpact.reduction.nmm_zone import create_nmm_zone
    from millimpact.reduction.partition import partition_dofs

    scene, plan, md = setup
    whole = with_whole_bodies_in_zone(md, ["ball"])
    values = whole.cell_tags.values
    assert not np.any(values == G.BALL_REGION) and np.count_nonzero(values == G.BLOCK_REGION) == np.count_nonzero(
        md.cell_tags.values == G.BLOCK_REGION
    )
    model = create_fe_model(whole, plan, 2)
    part = partition_dofs(model)
    assert len(part.interior["ball"]) == 0 and len(part.interior["block"]) > 0
    zeros = {}
    for remedy in ("none", "interface"):
        P = csr(create_nmm_zone(model, part, remedy=remedy).basis.G)
        w = np.linalg.eigvalsh((P.T @ csr(model.M) @ P).toarray())
        zeros[remedy] = int(np.count_nonzero(w < 1e-12 * w[-1]))
    assert zeros == {"none": 30, "interface": 0}


def test_nmm_prolongation_has_no_round_off_entries(p2):
    """P's entries are 1, 1/2 and d_k / (4 h) for the edge vector d; components with
    |d_k| <= DIRECTION_TOL |d| (edges in the symmetry plane, where the P2 node coordinates carry
    ~1e-20 m of round-off that depends on the partition and the BLAS) are exact zeros. A 1e-17
    entry would make a gradient coordinate "touch" a contact dof and change the set that mass
    redistribution makes massless: mpirun -n 2 differed from serial by 1.7e-5 on F_max."""
    from millimpact.reduction.nmm_zone import DIRECTION_TOL, create_nmm_zone

    _, _, vals = create_nmm_zone(p2).basis.G.getValuesCSR()
    # smallest genuine entry measured 1.3e-5; the bound DIRECTION_TOL / 4 x (|d| / h >= 0.1)
    assert np.abs(vals).min() > 0.025 * DIRECTION_TOL


@serial
def test_nmm_reproduces_linear_fields(p2):
    """Every linear field lies in the manifold space with its exact gradient: the prolongation of
    a_i = c + A x_i, b_i = h_i A is the P2 interpolant of c + A x at every zone node. Where a
    remedy removes b (interface vertices), the vertex values stay exact (P1 lies in the space)."""
    from millimpact.reduction.nmm_zone import create_nmm_zone
    from millimpact.reduction.partition import partition_dofs

    part = partition_dofs(p2)
    c = np.array([0.0, -2e-6, 3e-6])      # u_x = 0 on the x symmetry plane: c_x = 0, A[0] = 0
    A = np.array([[0.0, 0.0, 0.0], [-3e-4, 5e-5, 1e-4], [2e-4, 1e-4, -2e-4]])
    n_own = p2.V.dofmap.index_map.size_local
    x = p2.V.tabulate_dof_coordinates()[:n_own]
    ref = (c[None, :] + x @ A.T).ravel()
    scale = np.abs(ref[part.zone]).max()
    for remedy in ("none", "interface"):
        z = create_nmm_zone(p2, part, remedy=remedy)
        q = z.basis.G.createVecRight()
        q.array[:] = z.linear_field(c, A)
        u = z.basis.G.createVecLeft()
        z.basis.G.mult(q, u)
        err = np.abs(u.array - ref)
        vertex_dofs = (z.nodes[:, None] * 3 + np.arange(3)[None, :]).ravel()
        vertex_dofs = np.intersect1d(vertex_dofs, part.zone)
        assert err[vertex_dofs].max() <= 1e-12 * scale          # rounding
        if remedy == "none":
            assert err[part.zone].max() <= 1e-12 * scale        # midpoints too: exact


# --- runs ----------------------------------------------------------------------------------------
def test_traditional_impact_matches_full(setup):
    """A short impact (contact and a little rebound) on the same mesh: the traditional reduced
    model at the default cutoff against the full P1 model."""
    from millimpact.methods import full as fe_methods
    from millimpact.methods import reduced as reduced_methods
    from millimpact.results.timeseries import contact_metrics

    scene, plan, _ = setup
    t_end = plan.gap / scene.impact.speed + 1.6 * plan.hertz.contact_time
    full = fe_methods.run_fe(scene, plan, {"t_end": t_end, "degree": 1}, False)
    red = reduced_methods.run_reduced(scene, plan, {"t_end": t_end}, False, "traditional")
    mf, mr = contact_metrics(full.series), contact_metrics(red.series)
    # brief: within 1 %; measured +0.25 % on F_max and +0.15 % on t_c
    assert abs(mr["peak_contact_force_N"] / mf["peak_contact_force_N"] - 1) < 0.01
    assert abs(mr["contact_duration_s"] / mf["contact_duration_s"] - 1) < 0.01
    # the reduced scheme conserves energy like the full one (measured 3e-4 both)
    assert red.results["energy_drift_max_rel"] < 2e-3
    assert red.model["reduced_dofs"] < 0.3 * red.model["dofs"]


def test_improved_and_modal_p2_run(setup):
    """The P2-based methods run the same short impact; the improved method lies between the
    P1 and P2 answers of the same mesh (its space lies between them)."""
    from millimpact.methods import reduced as reduced_methods
    from millimpact.results.timeseries import contact_metrics

    scene, plan, _ = setup
    t_end = plan.gap / scene.impact.speed + 1.6 * plan.hertz.contact_time
    f = {}
    for method in ("improved", "modal-p2"):
        out = reduced_methods.run_reduced(scene, plan, {"t_end": t_end}, False, method)
        f[method] = contact_metrics(out.series)["peak_contact_force_N"]
        assert out.results["energy_drift_max_rel"] < 2e-3
        assert out.model["reduction"]["modes"] >= 2
    # measured: modal-p2 13.35 kN, improved 13.24 kN, traditional (P1) 14.33 kN: the P2 zone
    # resolves the contact patch better than P1 on this coarse mesh; NMM and P2 agree within 2 %
    assert abs(f["improved"] / f["modal-p2"] - 1) < 0.02


@pytest.mark.mpi
def test_reduction_under_mpi_matches_serial(setup, traditional):
    """Under mpirun -n 2 the reduced model has the same size, modes and frequencies as in serial,
    and the traditional impact the same peak force."""
    from millimpact.methods import reduced as reduced_methods
    from millimpact.results.timeseries import contact_metrics

    if MPI.COMM_WORLD.size > 1:
        pytest.skip("launches its own mpirun")
    scene, plan, _ = setup
    t_end = plan.gap / scene.impact.speed + 1.6 * plan.hertz.contact_time
    out = reduced_methods.run_reduced(scene, plan, {"t_end": t_end}, False, "traditional")
    f_serial = contact_metrics(out.series)["peak_contact_force_N"]
    code = f"""
import json
from mpi4py import MPI
from millimpact.scene.builtin import builtin_scene
from millimpact.scene.plan import make_plan
from millimpact.methods import reduced as reduced_methods
from millimpact.results.timeseries import contact_metrics
scene = builtin_scene("paper-rig")
for k, v in {SMALL!r}.items():
    scene = scene.with_value(k, v)
plan = make_plan(scene)
out = reduced_methods.run_reduced(scene, plan, {{"t_end": {t_end!r}}}, False, "traditional")
rep = out.model["reduction"]
if MPI.COMM_WORLD.rank == 0:
    f = contact_metrics(out.series)["peak_contact_force_N"]
    print("RESULT", json.dumps({{"n": out.model["reduced_dofs"], "f": f,
          "hi": {{b: r["highest_frequency_Hz"] for b, r in rep["bodies"].items()}}}}))
"""
    res = run_mpi_script(code, np=2)
    assert res.returncode == 0, res.stderr[-3000:]
    import json

    line = [ln for ln in res.stdout.splitlines() if ln.startswith("RESULT")][0]
    got = json.loads(line.split(" ", 1)[1])
    assert got["n"] == traditional.n_global
    for body, r in traditional.report()["bodies"].items():
        # eigensolver tolerance 1e-10 (default_solver_options)
        assert got["hi"][body] == pytest.approx(r["highest_frequency_Hz"], rel=1e-8)
    # measured identical to ~1e-12 (same factorization-based solves, other orderings)
    assert got["f"] == pytest.approx(f_serial, rel=1e-6)


def test_modal_free_phase_continues_the_stepping(setup):
    """After the bodies separate, the closed-form modal free phase replaces the time steps: same
    contact, same rebound, energy conserved, far fewer integrator steps."""
    from millimpact.methods import reduced as reduced_methods
    from millimpact.results.timeseries import contact_metrics

    scene, plan, _ = setup
    t_end = 8e-4
    runs = {fp: reduced_methods.run_reduced(scene, plan, {"t_end": t_end, "free_phase": fp}, False, "traditional")
            for fp in ("step", "modal")}
    fp = runs["modal"].results["free_phase"]
    assert [s[0] for s in fp["segments"]] == ["step", "modal"]
    assert fp["modal_rows"] > 200 and fp["free_modes"] >= 4
    ms, mm = (contact_metrics(runs[k].series) for k in ("step", "modal"))
    # the contact phases differ only by the step grids' rounding (t_end / n, dt < 1e-3 apart):
    # measured 3e-5 on F_max and 4e-5 on the rebound velocity
    assert mm["peak_contact_force_N"] == pytest.approx(ms["peak_contact_force_N"], rel=1e-3)
    # the ball's rigid motion lies in the modal basis exactly: only the contact phase differs
    vs, vm = (runs[k].series["ball_velocity_m_s"][-1] for k in ("step", "modal"))
    assert vm == pytest.approx(vs, rel=1e-4)
    e = runs["modal"].series["total_energy_J"]
    e0 = e[0]
    # energy dropped at the switch (modes above 4 f_cut): measured 5e-5 of the impact energy;
    # the recorded energy (consistent mass) varies by 3e-4 over the run, as with stepping
    assert fp["energy_dropped_J"] < 1e-3 * e0
    assert np.max(np.abs(e - e0)) < 2e-3 * e0
    # the integrator stops at the switch (gap / v + 1.5 t_c), with one step size (one factorization)
    integ = runs["modal"].results["integration"]
    span = fp["segments"][0][2]
    assert span <= plan.gap / scene.impact.speed + 1.5 * plan.hertz.contact_time + plan.dt_contact
    assert integ["n_factorizations"] == 1
    assert integ["n_steps"] < 0.35 * runs["step"].results["integration"]["n_steps"]


def test_auto_free_phase_takes_the_cheaper_phase():
    """free_phase = auto steps a free span of at most STEPS_PER_MODAL_COORDINATE free steps per
    modal coordinate (the free modes' measured cost: 15 steps a coordinate on the rig) and takes
    the modal phase beyond (with finite strain, a free step counted as FINITE_FREE_STEP_COST); an
    asked phase is kept. The plan's numbers: t_c 80 us, dt_free 2 us."""
    from types import SimpleNamespace

    from millimpact.methods.free_phase import (
        FINITE_FREE_STEP_COST,
        FIRST_SPAN_CONTACTS,
        STEPS_PER_MODAL_COORDINATE,
        resolve_free_phase,
    )

    t_c, dt_free = 80e-6, 2e-6
    plan = SimpleNamespace(gap=1e-5, hertz=SimpleNamespace(speed=1.0, contact_time=t_c), dt_free=dt_free)
    red = SimpleNamespace(n_global=1010, n_zone=1000)        # 10 modal coordinates
    t_first = plan.gap / plan.hertz.speed + FIRST_SPAN_CONTACTS * t_c
    border = t_first + STEPS_PER_MODAL_COORDINATE * 10 * dt_free
    assert resolve_free_phase("auto", red, plan, border * (1 - 1e-9))[0] == "step"
    assert resolve_free_phase("auto", red, plan, border * (1 + 1e-3))[0] == "modal"
    assert resolve_free_phase("auto", red, plan, 40e-3)[0] == "modal"        # the rig's 40 ms
    assert resolve_free_phase("auto", red, plan, t_first / 2)[0] == "step"   # no free span
    for asked in ("modal", "step"):
        assert resolve_free_phase(asked, red, plan, 40e-3 if asked == "step" else t_first) == (asked, "asked")
    # a finite-strain zone's free step iterates: it counts FINITE_FREE_STEP_COST elastic ones
    finite = SimpleNamespace(**vars(plan), strain="finite")
    border = t_first + STEPS_PER_MODAL_COORDINATE * 10 * dt_free / FINITE_FREE_STEP_COST
    assert resolve_free_phase("auto", red, finite, border * (1 - 1e-9))[0] == "step"
    assert resolve_free_phase("auto", red, finite, border * (1 + 1e-3))[0] == "modal"


def free_rows_mismatch(n_times: int = 40) -> tuple[float, float]:
    """The closed-form free phase's vectorised rows (ReducedRecorder.record_free) against the
    per-state recorder (Recorder.__call__) on the same modal states, on the SMALL traditional
    model: (max relative difference per column, max relative difference of the XDMF fields).
    The modal states are random: both recorders are the same linear/quadratic maps of them."""
    from millimpact.integration import integrators
    from millimpact.fem.contact import create_contact
    from millimpact.geometry.mesh import create_mesh
    from millimpact.fem.model import create_fe_model
    from millimpact.scene.plan import make_plan
    from millimpact.methods.reduced import reduced_plan
    from millimpact.results.reduced_recorder import ReducedRecorder
    from millimpact.reduction.craig_bampton import reduce_model
    from millimpact.reduction.free_modes import compute_free_modes
    from millimpact.scene.builtin import builtin_scene

    scene = builtin_scene("paper-rig")
    for key, value in SMALL.items():
        scene = scene.with_value(key, value)
    scene, plan, radius, _ = reduced_plan(scene, make_plan(scene))
    model = create_fe_model(create_mesh(scene, plan, MPI.COMM_WORLD), plan, 1)
    red = reduce_model(model, f_cut=plan.f_cut)
    contact = create_contact(model, plan, radius=radius)
    modal = compute_free_modes(red, 4 * plan.f_cut)
    rng = np.random.default_rng(7)
    m = modal.n_global
    times = 1e-4 + 2e-6 * np.arange(n_times)
    eta, etad, etadd = (rng.standard_normal((m, n_times)) * s for s in (1e-6, 1e-1, 1e4))
    field_times = (times[3], times[17] + 1e-7)
    recs = [ReducedRecorder(red, contact, plan.probes, field_times) for _ in range(2)]
    recs[0].record_free(modal, times, eta, etad, etadd)
    rec = recs[1]
    rec.set_projection(modal)
    lo, hi = modal.Phi.getOwnershipRangeColumn()
    vecs = [modal.create_vector() for _ in range(3)]
    for k, t in enumerate(times):
        for v, x in zip(vecs, (eta, etad, etadd)):
            v.array[:] = x[lo:hi, k]
        rec(integrators.StepState(t=float(t), dt=2e-6, u=vecs[0], v=vecs[1], a=vecs[2], lam=np.zeros(contact.n),
                                  gap=np.zeros(contact.n), n_active=0, n_newton=0, step=k + 1,
                                  mass=modal.M_scheme))
    a, b = (np.array(r.rows) for r in recs)
    scale = np.maximum(np.max(np.abs(b), axis=0), 1e-300)
    rows = float(np.max(np.max(np.abs(a - b), axis=0) / scale))
    assert [t for t, _ in recs[0].fields] == [t for t, _ in recs[1].fields] == [times[3], times[18]]
    fields = max(float(np.max(np.abs(fa - fb)) / max(np.max(np.abs(fb)), 1e-300))
                 for (_, fa), (_, fb) in zip(recs[0].fields, recs[1].fields))
    return MPI.COMM_WORLD.allreduce(rows, op=MPI.MAX), MPI.COMM_WORLD.allreduce(fields, op=MPI.MAX)


def test_free_phase_rows_equal_the_per_state_recorder():
    """The free phase records its thousands of rows at once: the same numbers as recording each
    state (differences are summation order, ~1e-15 of each column's scale)."""
    rows, fields = free_rows_mismatch()
    assert rows < 1e-12 and fields < 1e-12, (rows, fields)


@pytest.mark.mpi
def test_free_phase_rows_under_mpi():
    """The same under mpirun -n 2: the probe rows, ball rows and energies are gathered from the
    ranks' modal columns."""
    if MPI.COMM_WORLD.size > 1:
        pytest.skip("launches its own mpirun")
    code = ("import sys; sys.path[:0] = ['tests', 'tests/reduction']\n"
            "from test_reduction import free_rows_mismatch\n"
            "r = free_rows_mismatch()\n"
            "from mpi4py import MPI\n"
            "if MPI.COMM_WORLD.rank == 0: print('RESULT', r[0], r[1])\n")
    res = run_mpi_script(code, np=2)
    assert res.returncode == 0, res.stderr[-3000:]
    line = [ln for ln in res.stdout.splitlines() if ln.startswith("RESULT")][0]
    rows, fields = (float(x) for x in line.split()[1:])
    assert rows < 1e-12 and fields < 1e-12, (rows, fields)


@serial
def test_mode_acceleration_recovers_free_mode_gauge_stresses(setup, p1):
    """Gauge stresses of the reduced model's free-vibration modes against the full model's
    (dense eigenvectors of the clamped block, P1, same mesh): by mode displacement (A T q) they
    converge slowly with the cutoff next to the zone; by mode acceleration (A T q + C q'', here
    q'' = -omega^2 q) the truncated modes' quasi-static part is restored."""
    import scipy.linalg as sla

    from millimpact.fem.contact import create_contact
    from millimpact.results.recorder import Recorder
    from millimpact.methods.reduced import reduced_plan
    from millimpact.reduction.craig_bampton import reduce_model
    from millimpact.reduction.free_modes import compute_free_modes
    from millimpact.reduction.distributed import local_rows_to_aij

    scene, plan, _ = setup
    _, _, radius, _ = reduced_plan(scene, plan)
    rec = Recorder(p1, create_contact(p1, plan, radius=radius), plan.probes, ())
    K, M = csr(p1.K), csr(p1.M)
    sel = np.zeros(K.shape[0], dtype=bool)
    sel[p1.block_dofs] = True
    sel[p1.fixed_dofs] = False
    idx = np.nonzero(sel)[0]
    w, V = sla.eigh(K[idx][:, idx].toarray(), M[idx][:, idx].toarray(), subset_by_index=[0, 2])
    Pg = rec.probe.P_grad

    def gauges(grad_rows: np.ndarray) -> np.ndarray:
        g = grad_rows.reshape(-1, 3, 3)[1:]
        return np.array([d @ (0.5 * (gr + gr.T)) @ d for d, gr in zip(rec.gauge_dirs, g)])

    ref = []
    for k in range(3):
        u = np.zeros(K.shape[0])
        u[idx] = V[:, k]
        ref.append(gauges(Pg @ u))
    red = reduce_model(p1, f_cut=plan.f_cut)
    C = red.mode_acceleration_rows(local_rows_to_aij(Pg, p1.V))
    modal = compute_free_modes(red, 2 * plan.f_cut)
    block = np.nonzero(modal.body == 1)[0][:3]
    err = {"displacement": [], "acceleration": []}
    for k, j in enumerate(block):
        # the same modes: frequencies within 0.1 % (measured 0.01 %)
        assert math.sqrt(modal.omega2[j]) == pytest.approx(math.sqrt(w[k]), rel=1e-3)
        x = modal.create_vector()
        x.array[j] = 1.0
        q = modal.lift(x)
        g_u = Pg @ red.expand(q).array
        for kind, g in (("displacement", g_u), ("acceleration", g_u - modal.omega2[j] * (C @ q.array))):
            s = gauges(g)
            s = s * np.sign(s @ ref[k])
            err[kind].append(np.max(np.abs(s / ref[k] - 1)))
    # measured worst gauge per mode: 1.9 / 14.1 / 5.9 % by mode displacement, 0.02 / 0.5 / 0.3 %
    # by mode acceleration
    assert max(err["acceleration"]) < 0.01, err
    assert max(err["displacement"]) > 5 * max(err["acceleration"]), err


@serial
def test_reduction_cache_gives_the_same_model(setup, p1, tmp_path, monkeypatch):
    """reduction.cache: a second reduction of the same matrices takes Psi and Phi from disk and
    gives the same reduced matrices, frequencies and mode-acceleration rows (the K_ii factorization
    made on demand; float64 stored, so equal to round-off); another cutoff is another key
    (computed, not reused); "off" writes nothing."""
    from millimpact.fem.contact import create_contact
    from millimpact.methods.reduced import reduced_plan
    from millimpact.reduction import cache as reduction_cache
    from millimpact.reduction.craig_bampton import reduce_model
    from millimpact.reduction.distributed import local_rows_to_aij
    from millimpact.results.recorder import Recorder

    scene, plan, _ = setup
    folder = tmp_path / "rc"
    monkeypatch.setenv(reduction_cache.CACHE_ENV, str(folder))
    a = reduce_model(p1, f_cut=plan.f_cut)
    assert len(list(folder.iterdir())) == 2 and not any(b.from_cache for b in a.bodies)   # ball, block
    b = reduce_model(p1, f_cut=plan.f_cut)
    assert all(x.from_cache for x in b.bodies if x.n_interior)
    for A, B in ((a.K, b.K), (a.M, b.M)):
        D = A.copy()
        D.axpy(-1.0, B)
        assert D.norm() <= 1e-12 * A.norm()
    for x, y in zip(a.bodies, b.bodies):
        assert np.array_equal(x.frequencies_hz, y.frequencies_hz)
    _, _, radius, _ = reduced_plan(scene, plan)
    rec = Recorder(p1, create_contact(p1, plan, radius=radius), plan.probes, ())
    rows = local_rows_to_aij(rec.probe.P_grad, p1.V)
    Ca, Cb = a.mode_acceleration_rows(rows), b.mode_acceleration_rows(rows)
    assert np.abs(Ca).max() > 0 and np.allclose(Ca, Cb, rtol=1e-9, atol=1e-12 * np.abs(Ca).max())
    c = reduce_model(p1, f_cut=0.5 * plan.f_cut)
    assert not any(x.from_cache for x in c.bodies) and len(list(folder.iterdir())) == 4
    monkeypatch.setenv(reduction_cache.CACHE_ENV, "off")
    d = reduce_model(p1, f_cut=0.25 * plan.f_cut)
    assert not any(x.from_cache for x in d.bodies) and len(list(folder.iterdir())) == 4


# --- eigensolver ------------------------------------------------------------------------------------
@serial
def test_inertia_count_and_single_round_match_scipy(p1, monkeypatch, caplog):
    """The count of modes under a cutoff from the inertia of K - lambda M (Sylvester) equals the
    count from scipy's eigensolve, and the eigensolver that jumps to that count (the inertia path)
    keeps the same modes, to solver tolerance, as the one that doubles its request."""
    from petsc4py import PETSc

    from millimpact.integration.solvers import create_factored_solver
    from millimpact.reduction import eigen

    K, M = clamped_block(p1)
    f_ref = lowest_hz(K, M, 40)
    k = 25                                         # a cutoff between the 25th and 26th modes
    f_cut = 0.5 * (f_ref[k - 1] + f_ref[k])
    assert f_ref[k] / f_ref[k - 1] - 1 > 1e-6      # a gap to cut in (no multiple mode at the cut)

    def petsc(A):
        return PETSc.Mat().createAIJ(A.shape, csr=(A.indptr, A.indices, A.data), comm=MPI.COMM_SELF)

    K_p, M_p = petsc(K), petsc(M)
    prefix = "test_inertia_"
    assert eigen.count_below(K_p, M_p, (2 * math.pi * f_cut) ** 2, prefix) == k
    assert eigen.count_below(K_p, M_p, (2 * math.pi * 0.5 * f_ref[0]) ** 2, prefix) == 0

    results = {}
    # the inertia count then the block Krylov solver (the default), the inertia count then one
    # Krylov-Schur round (block_krylov_size 0), and the doubling Krylov-Schur rounds
    for name, threshold, block in (("block", 0, 32), ("inertia", 0, 0), ("doubling", 10**9, 32)):
        monkeypatch.setattr(eigen, "INERTIA_MIN_DOFS", threshold)
        ksp = create_factored_solver(K_p, prefix, eigen.default_solver_options(1))
        caplog.clear()
        with caplog.at_level(logging.INFO, logger="millimpact.reduction.eigen"):
            results[name] = eigen.compute_modes(K_p, M_p, ksp, f_cut, None, prefix,
                                                {**eigen.default_solver_options(1), "block_krylov_size": str(block)})
        assert ("by block Krylov" in caplog.text) == (name == "block"), name
        ksp.destroy()
    for name, (freq, vecs, nxt) in results.items():
        assert len(freq) == k, name
        # shift-and-invert at eps_tol 1e-10 against ARPACK's default: 1e-8 relative
        np.testing.assert_allclose(freq, f_ref[:k], rtol=1e-8, err_msg=name)
        assert nxt == pytest.approx(f_ref[k], rel=1e-8), name


@serial
def test_count_first_keeps_the_modes(p1, monkeypatch):
    """``count_first`` (the slabs of the substructured reduction): the inertia count before any
    Krylov-Schur round gives the same modes as the default path, to solver tolerance, with many
    modes under the cutoff (block Krylov), with fewer than a first round's (one round of count + 1)
    and none (nothing returned, the next frequency not computed)."""
    from petsc4py import PETSc

    from millimpact.integration.solvers import create_factored_solver
    from millimpact.reduction import eigen

    K, M = clamped_block(p1)
    f_ref = lowest_hz(K, M, 30)
    K_p, M_p = (PETSc.Mat().createAIJ(A.shape, csr=(A.indptr, A.indices, A.data), comm=MPI.COMM_SELF)
                for A in (K, M))
    monkeypatch.setattr(eigen, "INERTIA_MIN_DOFS", 0)
    prefix = "test_count_first_"
    opts = eigen.default_solver_options(1)
    for k in (25, 5):                 # more modes than FIRST_NEV (8) under the cutoff, and fewer
        assert f_ref[k] / f_ref[k - 1] - 1 > 1e-6
        f_cut = 0.5 * (f_ref[k - 1] + f_ref[k])
        ksp = create_factored_solver(K_p, prefix, opts)
        freq, vecs, nxt = eigen.compute_modes(K_p, M_p, ksp, f_cut, None, prefix, opts, count_first=True)
        ksp.destroy()
        assert len(freq) == len(vecs) == k
        # shift-and-invert or block Krylov at eps_tol 1e-10 against ARPACK's default: 1e-8 relative
        np.testing.assert_allclose(freq, f_ref[:k], rtol=1e-8, err_msg=str(k))
        assert nxt == pytest.approx(f_ref[k], rel=1e-8)
    ksp = create_factored_solver(K_p, prefix, opts)
    freq, vecs, nxt = eigen.compute_modes(K_p, M_p, ksp, 0.5 * f_ref[0], None, prefix, opts, count_first=True)
    ksp.destroy()
    assert len(freq) == 0 and vecs == [] and math.isnan(nxt)


@serial
def test_block_krylov_modes_match_scipy(p1):
    """The block Krylov solver's lowest modes of the clamped block against scipy's: frequencies to
    1e-8 relative (its residual tolerance 1e-10 on the transformed problem, as SLEPc's eps_tol),
    M-orthonormal vectors that satisfy K x = lambda M x, and the same at block sizes 7 and 32 (a
    basis that ends in the middle of a block); a basis cap too small to converge returns None (the
    caller falls back to Krylov-Schur)."""
    from petsc4py import PETSc

    from millimpact.integration.solvers import create_factored_solver
    from millimpact.reduction import eigen
    from millimpact.reduction.block_krylov import block_krylov_modes

    K, M = clamped_block(p1)
    k = 30
    f_ref = lowest_hz(K, M, k)

    def petsc(A):
        return PETSc.Mat().createAIJ(A.shape, csr=(A.indptr, A.indices, A.data), comm=MPI.COMM_SELF)

    K_p, M_p = petsc(K), petsc(M)
    ksp = create_factored_solver(K_p, "test_block_", eigen.default_solver_options(1))
    F = ksp.getPC().getFactorMatrix()
    for block in (7, 32):
        lam, vecs, stats = block_krylov_modes(K_p, M_p, F, k, block=block)
        np.testing.assert_allclose(np.sqrt(lam) / (2 * math.pi), f_ref, rtol=1e-8, err_msg=f"block {block}")
        X = np.column_stack([v.getArray() for v in vecs])
        np.testing.assert_allclose(X.T @ (M @ X), np.eye(k), atol=1e-10)
        res = np.linalg.norm(K @ X - (M @ X) * lam, axis=0) / np.linalg.norm(K @ X, axis=0)
        assert res.max() < 1e-6, f"block {block}: residual {res.max():.3g}"
        assert stats["basis"] >= k
        for v in vecs:
            v.destroy()
    assert block_krylov_modes(K_p, M_p, F, k, block=8, max_dim=40) is None
    ksp.destroy()


def test_run_options_reach_the_reduction_solvers(setup, monkeypatch, caplog):
    """A run's ``-impact_reduction_<body>_`` options reach the reduction's solvers: with
    ``block_krylov_size 0`` the region's modes come from a second Krylov-Schur round, without it
    from the block Krylov solver. (Until 2026-11-26 they did not: the reduction reads PETSc's
    options database, which the run's options never entered.)"""
    from millimpact.methods.reduced import build_reduced_setup
    from millimpact.reduction import eigen

    scene, plan, _ = setup
    monkeypatch.setenv("MILLIMPACT_REDUCTION_CACHE", "off")
    monkeypatch.setattr(eigen, "INERTIA_MIN_DOFS", 0)   # the small block: its modes counted ...
    monkeypatch.setattr(eigen, "FIRST_NEV", 2)          # ... after a first round that falls short
    logs = {}
    for size in (None, "0"):
        options = {} if size is None else {"impact_reduction_block_block_krylov_size": size}
        caplog.clear()
        with caplog.at_level(logging.INFO, logger="millimpact.reduction.eigen"):
            build_reduced_setup(scene, plan, options, "improved")
        logs[size] = caplog.text
    lines = {size: [ln for ln in text.splitlines() if "eigensolver impact_reduction_" in ln] for size, text in logs.items()}
    for body in ("ball", "block"):
        assert any(f"_{body}_:" in ln and "by block Krylov" in ln for ln in lines[None]), lines[None]
    # the option names the block body: it alone changes solver, the ball keeps the block solver
    assert any("_block_:" in ln and "asking" in ln for ln in lines["0"]), lines["0"]
    assert not any("_block_:" in ln and "by block Krylov" in ln for ln in lines["0"]), lines["0"]
    assert any("_ball_:" in ln and "by block Krylov" in ln for ln in lines["0"]), lines["0"]


def test_a_detached_product_lets_its_operands_go():
    """PETSc's products keep their operands referenced (for a recomputation): K_ia, M_ia (the
    interior rows of K and M, ~1 GB a rank at 1.2M DOFs) lived through the run behind K_iz G.
    detached() gives the same values with the operands' reference counts back to 1."""
    from petsc4py import PETSc

    from millimpact.reduction.distributed import detached

    A = PETSc.Mat().createAIJ((6, 6), nnz=2, comm=PETSc.COMM_SELF)
    for i in range(6):
        A.setValue(i, i, 2.0 + i)
        A.setValue(i, (i + 1) % 6, 1.0)
    A.assemble()
    B = A.duplicate(copy=True)
    P = A.matMult(B)
    assert A.getRefCount() == 2          # what detached() is for
    want = P.convert("dense").getDenseArray().copy()
    Q = detached(P)
    assert A.getRefCount() == 1 and B.getRefCount() == 1
    assert (Q.convert("dense").getDenseArray() == want).all()


DELIVER_ROWS_SCRIPT = r"""
import numpy as np
from mpi4py import MPI
from millimpact.reduction.distributed import deliver_rows
comm = MPI.COMM_WORLD
rank, size = comm.rank, comm.size
n, k = 1000, 3
starts = np.array([0, 380, n]) if size == 2 else np.array([0, n])
value = lambda rows: np.outer(rows, [1.0, -2.0, 0.5]) + np.arange(k)     # a row's values name it
# every row sent by exactly one rank, in uneven pieces: rank 0 three pieces, rank 1 one (the ranks
# take different numbers of rounds), rows of both owners mixed in each piece
rng = np.random.default_rng(3)
perm = rng.permutation(n)
mine = perm[: 700] if rank == 0 else perm[700:]
bounds = [0, 50, 420, 700] if rank == 0 else [0, 300]
pieces = ((mine[a:b], value(mine[a:b])) for a, b in zip(bounds[:-1], bounds[1:]))
out = np.full((starts[rank + 1] - starts[rank], k), np.nan)
hits = np.zeros(len(out), int)
def put(local_rows, vals):
    out[local_rows] = vals
    hits[local_rows] += 1
deliver_rows(pieces, starts, k, put, comm)
ok = (hits == 1).all() and np.array_equal(out, value(np.arange(starts[rank], starts[rank + 1])))
verdict = "OK" if comm.allreduce(ok, op=MPI.LAND) else "BAD"
if rank == 0:
    print(verdict)
"""


def test_rows_delivered_to_their_owners_piece_by_piece():
    """deliver_rows (the expansion of the slabs' results into the owners' rows, one bounded piece a
    round): under mpirun -n 2, with the ranks sending different numbers of pieces and each piece
    mixing both owners' rows, every owned row arrives exactly once with its own values (exact)."""
    res = run_mpi_script(DELIVER_ROWS_SCRIPT, np=2)
    assert res.returncode == 0, res.stderr[-2000:]
    assert res.stdout.split()[-1] == "OK", res.stdout
