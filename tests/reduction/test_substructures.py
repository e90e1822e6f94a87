"""Substructured (two-level) Craig-Bampton (millimpact.reduction.substructures) against the
one-factorization reduction, on the small paper-rig mesh of test_reduction.py (P2: 5.4k block
interior dofs, 7 block modes under f_cut).

The cuts' margin is set to 0 (the rig's block is smaller than the default margin of half a shear
wavelength at f_cut, which would leave it uncut)."""
from __future__ import annotations

import numpy as np
import pytest
from mpi4py import MPI

from conftest import SMALL_RIG as SMALL, run_mpi_script, small_rig_mesh


@pytest.fixture(scope="module")
def rig():
    from millimpact.fem.model import create_fe_model

    _, plan, md = small_rig_mesh()
    return create_fe_model(md, plan, 2), plan


@pytest.fixture(scope="module")
def one_factor(rig):
    from millimpact.reduction.craig_bampton import reduce_model

    model, plan = rig
    return reduce_model(model, f_cut=plan.f_cut)


def substructured(rig, slabs: int = 2, density: float = 0.0, f_factor: float = 1.5, compress: float = 1e-12,
                  zone_degree: int = 0, across: float = 0.0, eps_tol: float = 1e-4):
    from millimpact.reduction.craig_bampton import reduce_model

    model, plan = rig
    return reduce_model(model, f_cut=plan.f_cut, solver_options={
        "substructures": str(slabs), "substructure_trace_density": str(density),
        "substructure_f_factor": str(f_factor), "substructure_margin": "0", "substructure_compress": str(compress),
        "substructure_zone_degree": str(zone_degree), "substructure_across": str(across),
        "substructure_eps_tol": str(eps_tol)},
        keep_away=np.array([g.point for g in plan.probes.gauges]))


@pytest.fixture(scope="module")
def reductions(rig):
    """``get(**settings)``: :func:`substructured` of the rig, computed once per settings for the tests
    that check the same reduction (they only read it)."""
    done = {}

    def get(**settings):
        key = tuple(sorted(settings.items()))
        if key not in done:
            done[key] = substructured(rig, **settings)
        return done[key]
    return get


def _csr(A):
    import scipy.sparse as sp

    indptr, indices, data = A.getValuesCSR()
    return sp.csr_matrix((data, indices, indptr), shape=A.getSize())


@pytest.fixture(scope="module")
def block_static(rig):
    """The block's exact static response to a load on its zone (a uniform -z force on every block
    zone node; the ball left out: it is free), from a sparse direct solve of the whole model."""
    import scipy.sparse.linalg as sla

    from millimpact.reduction.partition import partition_dofs

    model, _ = rig
    part = partition_dofs(model)
    K = _csr(model.K)
    n = K.shape[0]
    block_zone = part.zone[part.zone_body == 1]
    f = np.zeros(n)
    f[block_zone[block_zone % 3 == 2]] = -1.0
    fixed = np.zeros(n, dtype=bool)
    fixed[model.fixed_dofs] = True
    S = np.nonzero(~np.repeat(part.ball_node[:n // 3], 3) & ~fixed)[0]
    u = np.zeros(n)
    u[S] = sla.spsolve(K[S][:, S].tocsc(), f[S])
    return f, u, part


def reduced_static(red, f: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(q, T q): the reduced model's static response to the load f on the block (ball coordinates
    left out: the free ball makes K_r singular)."""
    K_r = _csr(red.K).toarray()
    fv = red.model.K.createVecRight()
    fv.array[:] = f
    r = red.restrict(fv).array.copy()
    B = np.setdiff1d(np.arange(len(r)), red.ball_coords)
    q = np.zeros(len(r))
    q[B] = np.linalg.solve(K_r[np.ix_(B, B)], r[B])
    qv = red.create_vector()
    qv.array[:] = q
    return q, red.expand(qv).array.copy()


def test_exact_interface_gives_the_constraint_modes_and_upper_bound_frequencies(rig, one_factor):
    """Every interface dof its own trace: span(V) holds K_ii^-1 C, so Psi is the one-factorization
    Psi to the dense Ritz solve's rounding (2e-8 measured; 1e-6 allowed); the Ritz frequencies are
    upper bounds of the exact ones (Rayleigh: -1e-9 allowed for rounding, 3e-9 measured) and,
    after the inverse-iteration pass, close to them (2e-5 measured at 1.5 f_cut; 1e-3 allowed)."""
    red = substructured(rig, slabs=2)
    ref, sub = one_factor.bodies[1], red.bodies[1]
    assert sub.substructures is not None and len(sub.substructures["cuts_m"]) == 1
    assert sub.substructures["traces"] == sub.substructures["interface_dofs"] > 0
    P0, P = ref.Psi.getDenseArray(), sub.Psi.getDenseArray()
    assert np.linalg.norm(P - P0) / np.linalg.norm(P0) < 1e-6
    assert sub.n_modes == ref.n_modes
    rel = sub.frequencies_hz / ref.frequencies_hz - 1
    assert rel.min() > -1e-9
    assert rel.max() < 1e-3


def test_slabs_cut_across_keep_the_exact_interface(rig, one_factor):
    """Both slabs cut again across (across 0.5: any slab over half the mean): the pieces' interfaces
    meet at right angles (faces across either axis), and with every interface dof its own trace
    Psi is still the one-factorization Psi (1e-6 as above) and the frequencies upper bounds
    within 1e-3: the pieces' remaining dofs are uncoupled, or the Ritz space would miss K_ii^-1 C."""
    red = substructured(rig, slabs=2, across=0.5)
    ref, sub = one_factor.bodies[1], red.bodies[1]
    st = sub.substructures
    assert len(st["cuts_m"]) == 1 and len(st["across"]) == 2
    assert len(st["slabs"]) == 2 + sum(len(a["cuts_m"]) for a in st["across"].values()) >= 4
    assert st["interface_faces"] > 1 + len(st["across"])       # the cross faces and the first cut's
    assert st["traces"] == st["interface_dofs"] > 0
    P0, P = ref.Psi.getDenseArray(), sub.Psi.getDenseArray()
    assert np.linalg.norm(P - P0) / np.linalg.norm(P0) < 1e-6
    rel = sub.frequencies_hz / ref.frequencies_hz - 1
    assert sub.n_modes == ref.n_modes and rel.min() > -1e-9 and rel.max() < 1e-3


def test_the_zone_slab_is_cut_across_outside_the_bands():
    """cut_slabs on a synthetic body (1 x 0.6 x 0.1 m, a dense cluster of dofs at the 'zone'): the
    zone's band widens its slab past twice the mean, so it is cut again along the longest other
    extent (y), every cut at least the margin from the zone's dofs along its axis; across 0 keeps
    the slabs whole."""
    from millimpact.reduction.slab_cuts import cut_slabs

    rng = np.random.default_rng(0)
    far = rng.uniform([0, 0, 0], [1.0, 0.6, 0.1], size=(20000, 3))
    near = np.array([0.5, 0.3, 0.1]) + rng.uniform([-0.15, -0.15, -0.05], [0.15, 0.15, 0.0], size=(20000, 3))
    coords = np.vstack([far, near])
    zone = np.nonzero(np.linalg.norm(coords - [0.5, 0.3, 0.1], axis=1) < 0.03)[0]
    margin = 0.08
    cut = cut_slabs(coords, zone, 6, margin, MPI.COMM_SELF)
    assert cut.axis == 0
    zx = coords[zone]
    assert all(c <= zx[:, 0].min() - margin + 1e-9 or c >= zx[:, 0].max() + margin - 1e-9 for c in cut.cuts)
    (s, (a2, sub)), = cut.across.items()                # the zone's slab alone is cut across
    assert a2 == 1 and len(sub) >= 1
    assert all(c <= zx[:, 1].min() - margin + 1e-9 or c >= zx[:, 1].max() + margin - 1e-9 for c in sub)
    assert cut.pieces == len(cut.cuts) + 1 + len(sub)
    assert np.array_equal(np.unique(cut.labels), np.arange(cut.pieces))
    assert cut.normal(s + 0, s + 1) == 1 and cut.normal(0, 1) == 0
    whole = cut_slabs(coords, zone, 6, margin, MPI.COMM_SELF, across_ratio=0.0)
    assert not whole.across and whole.pieces == len(whole.cuts) + 1


def test_inverse_iteration_pass_makes_the_modes_near_f_cut_accurate(reductions, one_factor):
    """Slab modes only up to f_cut (f_factor 1): the first pass alone leaves the highest modes
    percents high (0.84 % even at 2 f_cut); the inverse-iteration pass brings them within 0.11 %
    (measured, 3 slabs; 0.3 % allowed). A mode just under f_cut may rise above it and drop out
    (Rayleigh), so the lowest n - 1 are compared."""
    ref = one_factor.bodies[1].frequencies_hz
    sub = reductions(slabs=3, f_factor=1.0).bodies[1].frequencies_hz
    assert len(sub) >= len(ref) - 1
    rel = sub[:len(ref) - 1] / ref[:len(sub)][:len(ref) - 1] - 1
    assert rel.min() > -1e-9
    assert rel.max() < 3e-3


def test_compressed_second_pass_keeps_the_modes(rig, reductions, one_factor):
    """The second pass's columns compressed (default: directions under 1e-12 of the Gram's largest
    eigenvalue dropped, each slab's columns M-orthonormal) against all kept, 3 slabs, slab modes to
    f_cut, every interface dof a trace: fewer Ritz columns (2069 -> 1632 measured) and modes as
    close to the one-factorization ones (largest error 1.11e-3 -> 1.07e-3 measured: the better
    conditioned columns lose fewer directions in the global Gram; at 1e-10 it was 1.18e-3, so
    2e-5 worse is allowed) with Psi still exact (6e-10 measured; 1e-6 as above)."""
    ref = one_factor.bodies[1]
    full = substructured(rig, slabs=3, f_factor=1.0, compress=0.0).bodies[1]
    comp = reductions(slabs=3, f_factor=1.0).bodies[1]         # compress 1e-12, the default
    assert comp.substructures["ritz_columns"] < 0.9 * full.substructures["ritz_columns"]
    # the 7th mode sits just under f_cut and rises above it in both (Rayleigh): the lowest 6 compared
    assert comp.n_modes == full.n_modes >= ref.n_modes - 1
    n = ref.n_modes - 1
    err = [np.max(b.frequencies_hz[:n] / ref.frequencies_hz[:n] - 1) for b in (full, comp)]
    assert err[1] < err[0] + 2e-5
    P0 = ref.Psi.getDenseArray()
    assert np.linalg.norm(comp.Psi.getDenseArray() - P0) / np.linalg.norm(P0) < 1e-6


def test_slabs_go_to_the_least_loaded_rank_largest_first():
    """Graham's rule (a slab's cost dofs^1.5) on the 157k-DOF panel's slabs (dofs 34k, 20k, 48k,
    36k): 68k against 71k dofs on 2 ranks (dealt in turn: 82k against 57k); every slab has one
    owner; more ranks than slabs leave ranks idle."""
    from millimpact.reduction.substructures import slab_owners

    dofs = [34174, 20139, 48014, 36412]
    owners = slab_owners(dofs, 2)
    loads = np.bincount(owners, weights=dofs, minlength=2)
    assert sorted(loads) == [48014 + 20139, 36412 + 34174]
    assert sorted(slab_owners(dofs, 8)) == [0, 1, 2, 3]
    assert list(slab_owners(dofs, 1)) == [0, 0, 0, 0]
    # the 1.2M-DOF panel's 14 slabs: the zone's slab (244k dofs, 133 s measured against 3-20 s for
    # the others) with the fewest dofs beside it: 374k of 963k dofs on its rank (by dofs alone 466k,
    # and 171 s against 88 s measured)
    big = [57782, 69895, 54861, 36157, 62702, 65103, 53898, 58519, 244114, 54571, 54759, 57160, 38797, 54848]
    owners = slab_owners(big, 2)
    assert sum(d for d, o in zip(big, owners) if o == owners[8]) < 0.4 * sum(big)


def test_polynomial_traces_converge_to_the_exact_interface(rig, one_factor):
    """Polynomial traces of growing degree (trace_density 1, 3: nested spaces) bring Psi closer to
    the exact constraint modes (measured on this mesh: 19 % at density 1); and the run reports
    fewer traces than interface dofs."""
    ref = one_factor.bodies[1].Psi.getDenseArray()
    err, traces = [], []
    for density in (1.0, 3.0):
        b = substructured(rig, slabs=2, density=density).bodies[1]
        err.append(np.linalg.norm(b.Psi.getDenseArray() - ref) / np.linalg.norm(ref))
        traces.append(b.substructures["traces"])
        assert b.substructures["traces"] < b.substructures["interface_dofs"]
    assert traces[1] > traces[0]
    assert err[1] < err[0]


@pytest.mark.parametrize("slabs, zone_degree, across", [(2, 0, 0), (3, 0, 0), (3, 2, 0), (2, 2, 0.5)])
def test_substructured_reduction_under_mpi_matches_serial(rig, tmp_path, slabs, zone_degree, across):
    """mpirun -n 2 gives the serial frequencies and constraint-mode norms (1e-9: the slabs'
    factorizations are MUMPS against CHOLMOD in serial, to rounding). 3 slabs on 2 ranks: one rank
    reduces two, the other one (the collective gathering with unequal slab counts). With
    zone-interface patterns (no Psi): the norm of Phi (rotations of its columns leave it alone).
    Slabs cut across (across 0.5): the pieces' labels and faces agree over the ranks.
    The slabs' modes converged to 1e-10 here (substructure_eps_tol; 1e-4 by default): at 1e-4 a
    frequency differed by 1.9e-9 in one run of six (likely cause: the distributed assembly's
    rounding ends a slab's block Krylov solve a block earlier or later), a difference of the slab
    bases' convergence, not of the distribution this test checks; at 1e-10, 32 of 32 passed."""
    if MPI.COMM_WORLD.size > 1:
        pytest.skip("runs its own mpirun")
    red = substructured(rig, slabs=slabs, density=2.0, zone_degree=zone_degree, across=across, eps_tol=1e-10)
    b = red.bodies[1]
    serial = np.concatenate([b.frequencies_hz, [(b.Psi or b.Phi).norm(), red.K.norm(), red.M.norm()]])
    code = f"""
import numpy as np
from mpi4py import MPI
from millimpact.fem.model import create_fe_model
from millimpact.geometry.mesh import create_mesh
from millimpact.scene.builtin import builtin_scene
from millimpact.scene.plan import make_plan
from millimpact.reduction.craig_bampton import reduce_model
scene = builtin_scene("paper-rig")
for k, v in {SMALL!r}.items():
    scene = scene.with_value(k, v)
plan = make_plan(scene)
model = create_fe_model(create_mesh(scene, plan, MPI.COMM_WORLD), plan, 2)
red = reduce_model(model, f_cut=plan.f_cut, solver_options={{"substructures": "{slabs}",
    "substructure_trace_density": "2.0", "substructure_margin": "0", "substructure_zone_degree": "{zone_degree}",
    "substructure_across": "{across}", "substructure_eps_tol": "1e-10"}},
    keep_away=np.array([g.point for g in plan.probes.gauges]))
b = red.bodies[1]
out = np.concatenate([b.frequencies_hz, [(b.Psi or b.Phi).norm(), red.K.norm(), red.M.norm()]])
if MPI.COMM_WORLD.rank == 0:
    np.save({str(tmp_path / "np2.npy")!r}, out)
"""
    proc = run_mpi_script(code, 2)
    assert proc.returncode == 0, proc.stderr[-2000:]
    par = np.load(tmp_path / "np2.npy")
    assert par.shape == serial.shape
    assert np.max(np.abs(par / serial - 1)) < 1e-9


@pytest.mark.parametrize("zone_degree", [0, 2])
def test_substructured_reduction_from_the_cache_and_its_gauge_rows(rig, tmp_path, monkeypatch, zone_degree):
    """reduction.cache with slabs: a second reduction takes Psi, Phi and R A_b (with zone-interface
    patterns: Phi and the Ritz-space recovery) from disk (the same frequencies, the same recovery
    rows to round-off), and those rows are not zero: the gauges get the truncated modes'
    quasi-static response without a factorization of K_ii."""
    from millimpact.fem.contact import create_contact
    from millimpact.methods.reduced import reduced_plan
    from millimpact.reduction import cache as reduction_cache
    from millimpact.reduction.distributed import local_rows_to_aij
    from millimpact.results.recorder import Recorder
    from millimpact.scene.builtin import builtin_scene

    model, plan = rig
    monkeypatch.setenv(reduction_cache.CACHE_ENV, str(tmp_path / "rc"))
    a = substructured(rig, slabs=2, density=2.0, zone_degree=zone_degree)
    b = substructured(rig, slabs=2, density=2.0, zone_degree=zone_degree)
    assert not a.bodies[1].from_cache and b.bodies[1].from_cache
    assert a.bodies[1].factor is None and b.bodies[1].factor is None     # no K_ii factorization on demand
    assert np.array_equal(a.bodies[1].frequencies_hz, b.bodies[1].frequencies_hz)
    scene = builtin_scene("paper-rig")
    for key, value in SMALL.items():
        scene = scene.with_value(key, value)
    _, _, radius, _ = reduced_plan(scene, plan)
    rec = Recorder(model, create_contact(model, plan, radius=radius), plan.probes, ())
    rows = local_rows_to_aij(rec.probe.P_grad, model.V)
    Ca, Cb = a.mode_acceleration_rows(rows), b.mode_acceleration_rows(rows)
    assert np.abs(Ca).max() > 0 and np.allclose(Ca, Cb, rtol=1e-9, atol=1e-12 * np.abs(Ca).max())
    Da, Db = a.displacement_recovery_rows(rows), b.displacement_recovery_rows(rows)
    assert (Da is None) == (Db is None) == (zone_degree == 0)
    if zone_degree:
        assert np.abs(Da).max() > 0 and np.allclose(Da, Db, rtol=1e-9, atol=1e-12 * np.abs(Da).max())


def test_zone_patterns_converge_from_the_stiff_side_to_the_exact_statics(reductions, block_static):
    """Zone-interface patterns instead of constraint modes (substructure_zone_degree d): the
    reduced model is a Ritz approximation, so the block's static compliance under a zone load is
    a lower bound of the exact one (-1e-10 allowed for rounding) and grows with d (nested
    polynomial spaces); at d = 8 the 258 patterns span every block interface dof and the statics
    are exact (compliance 1.5e-12, displacement 2.9e-8 measured; 1e-9 and 1e-6 allowed). Every
    Gamma dof a trace, so the slabs add no error of their own. Measured compliance errors:
    d 1 -3.7e-3, 2 -6.0e-5, 4 -3.2e-6."""
    f, u, _ = block_static
    exact = f @ u
    errors = []
    for degree in (1, 2, 4, 8):
        red = reductions(slabs=2, zone_degree=degree)
        b = red.bodies[1]
        assert b.Psi is None and b.n_patterns > 0 and b.substructures["zone_patterns"] >= b.n_patterns
        _, Tq = reduced_static(red, f)
        errors.append(f @ Tq / exact - 1)
        if degree == 8:
            assert abs(errors[-1]) < 1e-9
            assert np.linalg.norm(Tq - u) / np.linalg.norm(u) < 1e-6
    assert min(errors) > -1e-2 and max(errors) < 1e-10
    assert errors[0] < errors[1] < errors[2] < 0.0


def test_zone_patterns_hold_the_rigid_motions():
    """Degree 1 patterns on any point set: the six rigid motions (translations, and rotations
    omega x r) lie in their span to rounding, and the columns are orthonormal."""
    from millimpact.reduction.interface_patterns import zone_interface_patterns

    rng = np.random.default_rng(1)
    xyz = rng.normal(size=(40, 3)) * 0.01 + np.array([0.1, 0.2, 0.3])
    nodes = np.repeat(xyz, 3, axis=0)
    comps = np.tile(np.arange(3), 40)
    W = zone_interface_patterns(nodes, comps, 1, MPI.COMM_SELF)
    assert W.shape[1] == 12 and np.allclose(W.T @ W, np.eye(12), atol=1e-12)
    rigid = [np.tile(e, 40) for e in np.eye(3)] + [np.cross(w, xyz).ravel() for w in np.eye(3)]
    for v in rigid:
        assert np.linalg.norm(v - W @ (W.T @ v)) < 1e-10 * np.linalg.norm(v)


def test_zone_pattern_recovery_of_a_harmonic_state(rig, reductions, block_static):
    """The Ritz-space recovery of the gauge rows (values and gradients) for a body reduced with
    zone-interface patterns (ReducedModel.displacement_recovery_rows and mode_acceleration_rows).
    The zone held in a harmonic motion at f_cut / 2 (its static shape under the zone load), the
    exact interior u_i = -(K_ii - w^2 M_ii)^-1 (K_iz - w^2 M_iz) u_z against the recovery
    P (T + D) x - w^2 C x, x the reduced model's own harmonic response. Measured relative errors
    (P T x alone -> recovered): degree 2 1.7 % -> 0.33 %, degree 8 2.1 % -> 0.18 %, and the
    one-factorization Craig-Bampton with its mode-acceleration rows 1.3 % -> 0.21 %. Allowed:
    recovered below 0.5 % and at least 3x better than P T x; a wrong sign in any of the
    recovery's three terms gives several percent."""
    import scipy.sparse as sp
    import scipy.sparse.linalg as sla

    from millimpact.fem.contact import create_contact
    from millimpact.methods.reduced import reduced_plan
    from millimpact.reduction.distributed import local_rows_to_aij
    from millimpact.results.recorder import Recorder
    from conftest import small_rig_scene

    model, plan = rig
    _, u, part = block_static
    _, _, radius, _ = reduced_plan(small_rig_scene(), plan)
    probe = Recorder(model, create_contact(model, plan, radius=radius), plan.probes, ()).probe
    P = sp.vstack([probe.P_val, probe.P_grad]).tocsr()
    rows = local_rows_to_aij(P, model.V)
    w = 2 * np.pi * 0.5 * plan.f_cut
    A = (_csr(model.K) - w ** 2 * _csr(model.M)).tocsr()
    I = part.interior["block"]
    block_zone = part.zone[part.zone_body == 1]
    u_z = np.zeros(len(u))
    u_z[block_zone] = u[block_zone]
    u_i = np.zeros(len(u))
    u_i[I] = -sla.spsolve(A[I][:, I].tocsc(), A[I] @ u_z)
    exact = P @ (u_z + u_i)
    for degree in (2, 8):
        red = reductions(slabs=2, zone_degree=degree)
        m = red.bodies[1].modes
        K_r, M_r = _csr(red.K).toarray(), _csr(red.M).toarray()
        x = _csr(red.Gr).T @ u_z            # the nodal zone: its coordinates are the zone's dofs
        x[m] = np.linalg.solve(K_r[np.ix_(m, m)] - w ** 2 * M_r[np.ix_(m, m)], -(K_r[m] - w ** 2 * M_r[m]) @ x)
        xv = red.create_vector()
        xv.array[:] = x
        PT = P @ red.expand(xv).array
        D, C = red.displacement_recovery_rows(rows), red.mode_acceleration_rows(rows)
        assert D is not None
        plain = np.linalg.norm(PT - exact) / np.linalg.norm(exact)
        recovered = np.linalg.norm(PT + D @ x - w ** 2 * (C @ x) - exact) / np.linalg.norm(exact)
        assert recovered < 5e-3 and recovered < plain / 3


def test_a_large_body_is_cut_into_slabs_by_itself():
    """Without -..._substructures a body from AUTO_MIN_DOFS interior dofs is cut (one slab per
    AUTO_SLAB_DOFS, the million-DOF run's margin and pattern degree); below it, or asked for 1,
    one factorization; options given still win."""
    from millimpact.reduction.substructures import (AUTO_MARGIN, AUTO_MIN_DOFS, AUTO_SLAB_DOFS,
                                                    AUTO_ZONE_DEGREE, substructure_settings)
    pre = "impact_reduction_block_"
    assert substructure_settings(pre, {}, AUTO_MIN_DOFS - 1) is None
    s = substructure_settings(pre, {}, 16 * AUTO_SLAB_DOFS)
    assert (s.slabs, s.margin, s.zone_degree) == (16, AUTO_MARGIN, AUTO_ZONE_DEGREE)
    assert substructure_settings(pre, {"substructures": "1"}, 16 * AUTO_SLAB_DOFS) is None
    s = substructure_settings(pre, {"substructure_margin": "0.5", "substructure_zone_degree": "2"}, 16 * AUTO_SLAB_DOFS)
    assert (s.slabs, s.margin, s.zone_degree) == (16, 0.5, 2)


def test_root_work_takes_the_waiting_ranks_cores_and_gives_them_back():
    """root_on_idle_cores (the dense Rayleigh-Ritz on rank 0): inside the block rank 0 may run on
    every core of its node's ranks, with as many BLAS threads; after it, its own core mask and
    thread count again. The result is the one a single thread gives, to rounding (1e-12: the
    same eigenvalues of a well-conditioned matrix, summed in another order)."""
    if MPI.COMM_WORLD.size > 1:
        pytest.skip("runs its own mpirun")
    code = """
import os
import numpy as np
from mpi4py import MPI
from millimpact.reduction.distributed import _openblas, root_on_idle_cores
comm = MPI.COMM_WORLD
blas = _openblas()
rng = np.random.default_rng(1)
X = rng.standard_normal((400, 400))
A = X @ X.T + 400 * np.eye(400)
before = (os.sched_getaffinity(0), blas.openblas_get_num_threads() if blas else 1)
ref = np.linalg.eigvalsh(A)
union = set().union(*comm.allgather(os.sched_getaffinity(0)))
inside = None
with root_on_idle_cores(comm):
    if comm.rank == 0:
        inside = (os.sched_getaffinity(0), blas.openblas_get_num_threads() if blas else 2)
        lam = np.linalg.eigvalsh(A)
after = (os.sched_getaffinity(0), blas.openblas_get_num_threads() if blas else 1)
if comm.rank == 0:
    print("OK" if inside[0] == union and inside[1] == 2 * before[1] and after == before
          and np.max(np.abs(lam - ref)) <= 1e-12 * ref.max() else f"BAD {before} {inside} {after}")
"""
    out = run_mpi_script(code)
    assert out.returncode == 0, out.stderr[-2000:]
    assert out.stdout.strip() == "OK", out.stdout


@pytest.mark.parametrize("gap", [False, True])
def test_lowest_eigenpairs_are_the_full_solvers(gap):
    """The windowed eigensolve gives the lowest eigenpairs of a full dsyevd up to the cutoff and the
    next one, also when no eigenvalue lies in the first window and it is widened (``gap``). Rounding
    tolerance: eigenvalues of a matrix of norm ~1e3 to 1e-12 of the largest, vectors (up to sign)
    to 1e-9 (their separation is >= 1e-2: perturbation theory, eps ||A|| / gap)."""
    from millimpact.reduction.ritz import WINDOW, lowest_eigenpairs

    rng = np.random.default_rng(3)
    n = 120
    lam = np.concatenate([np.linspace(1.0, 8.5, 12), np.linspace(9.0 * (WINDOW * 30.0 if gap else 1.1), 1e3, n - 12)])
    Q, _ = np.linalg.qr(rng.standard_normal((n, n)))
    A = (Q * lam) @ Q.T
    got, Y = lowest_eigenpairs(A, 9.0)
    ref, R = np.linalg.eigh(A)
    assert len(got) >= 13 and got[12] > 9.0 and np.all(got[:12] <= 9.0)
    assert np.max(np.abs(got - ref[:len(got)])) < 1e-12 * ref[-1]
    assert np.max(np.abs(np.abs(np.sum(Y * R[:, :len(got)], axis=0)) - 1)) < 1e-9


def test_ritz_statics_and_residual_flexibility_match_the_full_eigenbasis():
    """The Rayleigh-Ritz with K_W's Cholesky factor and only the modes under the cutoff gives the
    statics psi = -K_V^+ C, the modes and the residual flexibility sum_{i>m} y_i y_i^T A_b / lam_i
    of the full eigendecomposition on a pencil with two dependent columns (dropped). Compared as
    vectors of span(V), in the M_V norm (coefficients of dependent columns are not unique):
    within 1e-10 (rounding, condition of K_W ~1e4)."""
    from millimpact.reduction.distributed import DEPENDENT_TOL, gram_basis
    from millimpact.reduction.ritz import rayleigh_ritz

    rng = np.random.default_rng(5)
    n, n_b = 90, 4
    V = rng.standard_normal((200, n))
    V[:, -2:] = V[:, :2] @ rng.standard_normal((2, 2))        # two dependent columns
    K0 = rng.standard_normal((200, 200))
    Kf, Mf = K0 @ K0.T + 200 * np.eye(200), np.diag(rng.uniform(1.0, 2.0, 200))
    KV, MV, CV = V.T @ Kf @ V, V.T @ Mf @ V, rng.standard_normal((n, 2 * n_b))
    f_cut = np.sqrt(np.median(np.linalg.eigvalsh(np.linalg.solve(Mf, Kf)))) / (2 * np.pi)
    got = rayleigh_ritz(KV.copy(), MV.copy(), CV.copy(), n_b, f_cut)
    # the reference: every eigenpair of the pencil in the M_V-orthonormal basis
    W = gram_basis(MV, DEPENDENT_TOL)
    lam, Y = np.linalg.eigh(W.T @ KV @ W)
    WY = W @ Y
    m = int(np.searchsorted(lam, (2 * np.pi * f_cut) ** 2, side="right"))
    psi = -WY @ ((WY.T @ CV[:, :n_b]) / lam[:, None])
    Ab = MV @ psi + CV[:, n_b:]
    flex = WY[:, m:] @ ((WY[:, m:].T @ Ab) / lam[m:, None])
    assert got["m"] == m and 0 < m < W.shape[1] and got["rank"] == n - 2
    m_norm = lambda X: np.sqrt(np.sum(X * (MV @ X)))           # noqa: E731
    assert m_norm(got["psi"] - psi) < 1e-10 * m_norm(psi)
    assert m_norm(got["flex"] - flex) < 1e-10 * m_norm(flex)
    assert np.max(np.abs(np.abs(np.sum(got["phi"] * (MV @ WY[:, :m]), axis=0)) - 1)) < 1e-10   # up to sign
    assert np.allclose(got["freq"][:m + 1], np.sqrt(lam[:m + 1]) / (2 * np.pi), rtol=1e-12)
