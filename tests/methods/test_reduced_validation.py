"""Validation of the reduced methods against independent references (issue 5), on small meshes.

* mode convergence: F_max, t_c and the gauge stresses converge to the full model's as the modal
  cutoff rises (traditional against full P1 and improved against full P2, same mesh and same
  contact candidates, so that with every mode the two are the same model); the gauge stresses,
  recovered by mode acceleration, in the band below the cutoff over the first bending swing;
* the clamped block's free-vibration frequencies of the improved reduced model against an
  independent P2 model of a finer mesh;
* a second impact: the modal free phase hands the state back to the integrator, checked against
  stepping all the way (free_phase = step);
* mpirun -n 2 gives the serial numbers for ``improved``.

The small mesh is test_reduction.py's (h_contact 0.8 mm, h_far 8 mm, zone radius 5 mm, half model:
~1.8k P1 / ~10.6k P2 dofs). Runs cover the first contact (gap / v + 1.6 t_c), the band-limited
gauge test gap / v + 5 t_c.
"""
from __future__ import annotations

import json
import math

import numpy as np
import pytest
import scipy.sparse as sp
import scipy.sparse.linalg as spla
from mpi4py import MPI

from conftest import run_mpi_script, run_script_here, small_rig_scene

SMALL = {"model.h_contact": 0.8e-3, "model.h_far": 8e-3, "model.zone_radius": 5e-3}
serial = pytest.mark.skipif(MPI.COMM_WORLD.size > 1, reason="serial test (launches mpirun itself / scipy)")


def small_scene(**extra):
    from millimpact.scene.plan import make_plan
    from millimpact.scene.builtin import builtin_scene

    scene = builtin_scene("paper-rig")
    for key, value in {**SMALL, **extra}.items():
        scene = scene.with_value(key, value)
    return scene, make_plan(scene)


def first_contact_end(scene, plan) -> float:
    return plan.gap / scene.impact.speed + 1.6 * plan.hertz.contact_time


def metrics(out) -> dict:
    """F_max (N), t_c (s) and each gauge's peak |stress| (Pa) while the bodies touch (the gauges'
    quasi-static Hertz field; after separation the peaks are a few samples of ringing)."""
    from millimpact.results.timeseries import contact_metrics

    ts = out.series
    m = contact_metrics(ts)
    on = ts["contact_force_N"] > 0
    gauges = {k: float(np.max(np.abs(ts[k][on]))) for k in ts.columns if k.startswith("gauge_")}
    return {"F": m["peak_contact_force_N"], "tc": m["contact_duration_s"], "gauges": gauges}


def rel(a: float, b: float) -> float:
    return abs(a / b - 1.0)


def same_model_full(scene, plan, t_end, degree, reduced_out) -> dict:
    """Full P``degree`` with the reduced run's contact candidates: the very model the reduced run
    projects (same mesh, same massless contact nodes of the mass redistribution). With the full
    method's own candidates (2.5 a_max against the reduced 1.75 a_max) the two models differ by
    a ring of massless nodes: on this mesh that alone moves the gauge peaks by up to 2 % (B), more
    than the reduction's own error at 16 / t_c."""
    from millimpact.methods import full as fe_methods

    radius = reduced_out.model["candidate_radius_m"]
    return metrics(fe_methods.run_fe(scene, plan, {"t_end": t_end, "degree": degree, "candidate_radius": radius},
                                     False))


@pytest.fixture(scope="module")
def traditional_runs():
    from millimpact.methods import reduced as reduced_methods

    scene, plan = small_scene()
    t_end = first_contact_end(scene, plan)
    tc = plan.hertz.contact_time
    runs, outs = {}, {}
    # 4 / t_c is the plan's default cutoff; "1+aug": 1 / t_c with the modal truncation augmentation
    for key, opts in ((1, {"f_cut": 1 / tc}), (4, {"f_cut": 4 / tc}), (32, {"f_cut": 32 / tc}),
                      ("all", {"modes": 100000}), ("1+aug", {"f_cut": 1 / tc, "augment": "boussinesq"})):
        outs[key] = reduced_methods.run_reduced(scene, plan, {"t_end": t_end, "free_phase": "step", **opts}, False,
                                                "traditional")
        runs[key] = metrics(outs[key])
    runs["full"] = same_model_full(scene, plan, t_end, 1, outs[4])
    return runs


@serial
def test_traditional_converges_to_full_p1_with_the_cutoff(traditional_runs):
    """Traditional (P1 zone + Craig-Bampton) against full P1 of the same mesh and contact
    candidates: with all modes the two are the same model, so the gap is the modal truncation."""
    r = traditional_runs
    full = r["full"]
    # every mode kept: the same model, time steps, gauge element and stress recovery, so however
    # the gauge peak is sampled it cancels: measured 1.4e-11 (rounding); 1e-6
    for g, ref in full["gauges"].items():
        assert rel(r["all"]["gauges"][g], ref) < 1e-6, (g, r["all"]["gauges"][g], ref)
    assert rel(r["all"]["F"], full["F"]) < 1e-6
    err_F = {k: rel(r[k]["F"], full["F"]) for k in (1, 4, 32, "1+aug")}
    # measured: 3.0 % at 1/t_c (below ~1/t_c a mode's dynamic error is large, foundations.md section 4),
    # 0.20 % at 4/t_c, 0.06 % at 32/t_c
    assert err_F[4] < 0.5 * err_F[1] and err_F[32] < 0.5 * err_F[1]
    # brief: within 1 % on F_max and t_c at the default cutoff (measured 0.20 %, 0.17 %)
    assert err_F[4] < 0.01
    assert rel(r[4]["tc"], full["tc"]) < 0.01
    # the augmentation vectors (one per body) restore the truncated modes' quasi-static response
    # to the contact pulse: F_max at 1/t_c measured 3.0 % -> 0.05 %
    assert err_F["1+aug"] < 0.1 * err_F[1]
    # unfiltered in-contact gauge peaks (outputs by mode acceleration, the default): measured
    # A/B/C 6.5/7.2/3.6 % at 1/t_c (47 % on B by mode displacement), 2.5/1.0/0.9 % at 4/t_c. They
    # are not a converged quantity (4.0/0.5/2.3 % at 32/t_c, 0.6/4.8/0.1 % at 8/t_c): the reference
    # peak falls on the last contact sample while the signal still changes, and the full P1 peak
    # itself moves by +2.9 / +4.9 / +18.9 % (A/B/C) when its time step is quartered. So the bound here is loose
    # (measured, rounded up); test_band_limited_gauge_peaks_converge_with_the_cutoff checks the
    # convergence and the brief's 2 % on the part of the signal the reference resolves.
    for g, ref in full["gauges"].items():
        assert rel(r[4]["gauges"][g], ref) < 0.03, (g, r[4]["gauges"][g], ref)


@pytest.fixture(scope="module")
def improved_default():
    """``improved`` with the plan's settings over the first contact: (scene, plan, run output). Its
    cutoff is the plan's 4 / t_c (plan.F_CUT_FACTOR / t_c, the same float as 4 / t_c below)."""
    from millimpact.methods import reduced as reduced_methods

    scene, plan = small_scene()
    return scene, plan, reduced_methods.run_reduced(scene, plan, {"t_end": first_contact_end(scene, plan)}, False,
                                                    "improved")


@pytest.fixture(scope="module")
def improved_runs(improved_default):
    from millimpact.methods import reduced as reduced_methods

    scene, plan, default = improved_default
    t_end = first_contact_end(scene, plan)
    tc = plan.hertz.contact_time
    assert default.model["reduction"]["bodies"]["block"]["f_cut_Hz"] == 4 / tc
    outs = {4: default}
    for key, k, extra in ((2, 2, {}), ("anchors", 4, {"nmm_remedy": "anchors"})):
        outs[key] = reduced_methods.run_reduced(scene, plan, {"t_end": t_end, "f_cut": k / tc, **extra}, False,
                                                "improved")
    runs = {key: metrics(out) for key, out in outs.items()}
    runs["full"] = same_model_full(scene, plan, t_end, 2, outs[4])
    return runs


@serial
def test_improved_converges_to_full_p2(improved_runs):
    """Improved (NMM zone in a P2 mesh + Craig-Bampton) against full P2 of the same mesh and
    contact candidates. Its zone space is a subspace of P2's, so even with all modes a small gap
    remains: on this mesh the contact patch spans only 1.4 elements (a_max / h_contact) and the NMM
    zone resolves it a little less well than P2 (on the default mesh, a_max / 4, the gap is 0.2 %
    on F_max and 0.05 % on t_c: benchmarks/reduced_vs_full.py)."""
    r = improved_runs
    full = r["full"]
    # measured: F_max +2.3 % at 2/t_c, -0.8 % at 4/t_c; 8/t_c equals 4/t_c to 1e-4 (converged)
    assert rel(r[4]["F"], full["F"]) < 0.5 * rel(r[2]["F"], full["F"])
    assert rel(r[4]["F"], full["F"]) < 0.01                   # brief: 1 %
    assert rel(r[4]["tc"], full["tc"]) < 0.015                # measured -1.0 % (zone space, above)
    # gauges (outputs by mode acceleration), brief 2 %: measured B +0.8 %, C +1.1 % (by mode
    # displacement +1.3 %, -1.4 %)
    for g in ("gauge_B_stress_Pa", "gauge_C_stress_Pa"):
        assert rel(r[4]["gauges"][g], full["gauges"][g]) < 0.02, (g, r[4]["gauges"][g], full["gauges"][g])
    # gauge A (7.5 mm above the contact, 2.5 mm beyond the zone): -21 % with the default null-space
    # remedy. Not the reference (modal-p2, the nodal P2 zone with the same modes, is within 0.9 %
    # of it) nor the modes (-19 % at 16/t_c): the remedy drops the gradient covers at the interface
    # vertices, so the zone's trace on the interface is piecewise linear and the constraint modes
    # feed the region a P1 interface motion, 0.8-2 mm edges on this mesh. Three anchor vertices
    # instead (nmm_remedy = anchors, 4x the interface coordinates) give the P2 trace back: measured
    # -0.4 % (B +0.5 %, C +0.6 %; by mode displacement -2.0 / +0.9 / -2.4 %). On the default mesh
    # (0.29 mm interface edges) the two remedies' 40 ms gauge peaks differ by 0.3 % at 3x the run
    # time, so "interface" stays the default.
    for g in ("gauge_A_stress_Pa", "gauge_B_stress_Pa", "gauge_C_stress_Pa"):
        assert rel(r["anchors"]["gauges"][g], full["gauges"][g]) < 0.02, (g, r["anchors"]["gauges"][g],
                                                                           full["gauges"][g])
    assert rel(r["anchors"]["F"], full["F"]) < 0.015          # measured -0.9 %


def band_limited_gauge_peaks(out, f_band: float, t_max: float) -> dict:
    """Each gauge's peak |stress| (Pa) up to ``t_max`` after a zero-phase low-pass at ``f_band``
    (Hz; 4th-order Butterworth, forward and back, on the series resampled to its smallest step):
    the part of the signal the reduced model claims (its modes reach f_cut). The run should last
    ~1 / f_band beyond t_max, where the filter's end effects fade."""
    from scipy.signal import butter, sosfiltfilt

    ts = out.series
    t = np.asarray(ts["time_s"])
    dt = float(np.min(np.diff(t)))          # outputs switch from dt_contact to dt_free after the contact
    grid = np.arange(t[0], t[-1] + 0.5 * dt, dt)
    sos = butter(4, 2.0 * f_band * dt, output="sos")
    keep = grid <= t_max
    return {k: float(np.max(np.abs(sosfiltfilt(sos, np.interp(grid, t, ts[k]))[keep])))
            for k in ts.columns if k.startswith("gauge_")}


@serial
def test_band_limited_gauge_peaks_converge_with_the_cutoff():
    """Gauge peaks over the first contact and the first bending swing (to gap / v + 4 t_c), in the
    band below the default cutoff (4/t_c): traditional against full P1 of the same mesh, contact
    candidates and time steps. Unfiltered, the reference's peaks are not converged (they move by
    4-7 % when its steps are halved: content far above f_cut, see the test above). The reduced
    outputs are recovered by mode acceleration (ReducedModel.mode_acceleration_rows)."""
    from millimpact.methods import full as fe_methods
    from millimpact.methods import reduced as reduced_methods
    from millimpact.scene.plan import make_plan

    scene, plan = small_scene()
    tc = plan.hertz.contact_time
    t_max = plan.gap / scene.impact.speed + 4.0 * tc
    t_end = t_max + tc
    band = plan.f_cut
    red = {}
    for k, extra in ((4, {}), (8, {}), (16, {}), ("4 modal", {"recovery": "modal"})):
        f_cut = (4 if k == "4 modal" else k) / tc
        out = reduced_methods.run_reduced(scene, plan, {"t_end": t_end, "f_cut": f_cut, "free_phase": "step", **extra},
                                          False, "traditional")
        red[k] = band_limited_gauge_peaks(out, band, t_max)
    # run_fe takes (pops) its settings out of the dict: each run gets its own copy. The dt/2 run
    # shared one and ran the scene's 40 ms with the full method's own candidates (~45k steps,
    # most of this test's time; its differences below were 1.5 / 1.6 / 1.8 % then)
    opts = {"t_end": t_end, "degree": 1, "candidate_radius": out.model["candidate_radius_m"]}
    full = band_limited_gauge_peaks(fe_methods.run_fe(scene, plan, dict(opts), False), band, t_max)
    fine_scene = scene.with_value("time.dt_contact", plan.dt_contact / 2).with_value("time.dt_free", plan.dt_free / 2)
    fine = band_limited_gauge_peaks(fe_methods.run_fe(fine_scene, make_plan(fine_scene), dict(opts), False), band,
                                    t_max)
    errs = {g: {k: rel(red[k][g], ref) for k in red} for g, ref in full.items()}
    for g, ref in full.items():
        # the reference in time, within the band: measured 1.45 / 1.59 / 1.79 % (A/B/C) under dt/2
        # (dt_free = 1 / (10 f_cut) has 3 % period error at the band's edge; plan.py)
        assert rel(fine[g], ref) < 0.025, (g, fine[g], ref)
        e = errs[g]
        # outputs by mode acceleration (the default): measured A 0.50 / 0.03 / 0.01 %,
        # B 1.1 / 0.02 / 0.01 %, C 0.18 / 0.06 / 0.02 % at 4 / 8 / 16 t_c: the brief's 2 % at the
        # default cutoff, and converged to the reference's own accuracy (above) from 8/t_c
        assert e[4] < 0.02, (g, e)
        assert e[8] < 0.005 and e[16] < 0.005, (g, e)
    # by mode displacement (u = T q alone) gauge A was 4.5 % off at 4/t_c (1.7 % at 8/t_c): the
    # free modes' stresses next to the zone converge slowly with the cutoff (the 15.4 kHz mode's
    # gauge A stress: -14 % by mode displacement, +0.3 % by mode acceleration)
    eA = errs["gauge_A_stress_Pa"]
    assert eA["4 modal"] > 4 * eA[4], eA


@serial
def test_reduced_block_frequencies_match_a_finer_p2_model():
    """The clamped block's lowest free-vibration frequencies of the improved reduced model (the
    modes its free phase propagates) against full P2 on a finer far mesh (h_far 5.6 mm; P2 moves
    by <= 0.1 % under that refinement, test_reduction.test_block_frequencies_converge): brief 1 %."""
    from millimpact.geometry.mesh import create_mesh
    from millimpact.fem.model import create_fe_model
    from millimpact.methods.reduced import build_reduced_model
    from millimpact.reduction.free_modes import compute_free_modes

    scene, plan = small_scene()
    md = create_mesh(scene, plan, MPI.COMM_WORLD)
    red = build_reduced_model(create_fe_model(md, plan, 2), "nmm", f_cut=plan.f_cut, n_modes=None)
    modal = compute_free_modes(red, 2.0 * plan.f_cut)
    f_red = np.sort(np.sqrt(modal.omega2[modal.body == 1])) / (2 * math.pi)

    fine_scene, fine_plan = small_scene(**{"model.h_far": 5.6e-3})
    fine = create_fe_model(create_mesh(fine_scene, fine_plan, MPI.COMM_WORLD), fine_plan, 2)
    n = fine.K.getSize()[0]
    sel = np.zeros(n, dtype=bool)
    sel[fine.block_dofs] = True
    sel[fine.fixed_dofs] = False

    def csr(A):
        indptr, indices, data = A.getValuesCSR()
        return sp.csr_matrix((data, indices, indptr), shape=A.getSize())[sel][:, sel].tocsc()

    k = 4
    lam = spla.eigsh(csr(fine.K), k=k, M=csr(fine.M), sigma=0.0, which="LM", return_eigenvectors=False)
    f_ref = np.sqrt(np.sort(lam)) / (2 * math.pi)
    assert len(f_red) >= k
    np.testing.assert_array_less(np.abs(f_red[:k] / f_ref - 1), 0.01)


@serial
def test_second_impact_hands_back_to_the_integrator():
    """A heavy ball (r 25 mm) on a thin plate (12 mm) clamped at its base: the plate swings back and
    strikes the ball again ~0.28 ms later. With free_phase = modal the run goes step -> modal ->
    (gap predicted to close) step -> modal; against stepping all the way the second impact comes at
    the same time and the ball leaves with the same velocity, energy conserved in both."""
    from millimpact.methods import reduced as reduced_methods

    scene, plan = small_scene(**{"block.thickness": 12e-3, "ball.radius": 25e-3})
    opts = {"t_end": 6e-4, "modal_min_span": 10 * plan.dt_contact}
    runs = {fp: reduced_methods.run_reduced(scene, plan, {**opts, "free_phase": fp}, False, "traditional")
            for fp in ("modal", "step")}
    seg = [s[0] for s in runs["modal"].results["free_phase"]["segments"]]
    assert seg[:4] == ["step", "modal", "step", "modal"], seg       # the hand-back happened

    def impacts(out):
        t, f = out.series.time, out.series["contact_force_N"]
        on = f > 0
        starts = t[1:][on[1:] & ~on[:-1]]
        return starts, float(np.max(f[t > 0.5 * (starts[0] + starts[-1])]))

    (tm, f2m), (ts_, f2s) = impacts(runs["modal"]), impacts(runs["step"])
    assert len(tm) == len(ts_) == 2
    # onset within 2 contact steps (the stepping run approaches on the dt_free grid)
    assert abs(tm[1] - ts_[1]) < 2 * plan.dt_contact
    # second peak: measured -2.3 % (modes above 4 f_cut dropped at the switch, other step grid)
    assert rel(f2m, f2s) < 0.04
    # the momentum the two impacts exchange: measured 5e-5 apart
    vm, vs = (runs[k].series["ball_velocity_m_s"][-1] for k in ("modal", "step"))
    assert vm == pytest.approx(vs, rel=1e-3)
    for out in runs.values():
        e = out.series["total_energy_J"]
        assert np.max(np.abs(e / e[0] - 1)) < 1e-3            # measured 2.1e-4 both


@pytest.mark.mpi
@serial
def test_improved_under_mpi_matches_serial(improved_default):
    """mpirun -n 2 gives the serial numbers for ``improved`` (same model sizes, modes, F_max, t_c and
    the contact force at every step)."""
    scene, plan, out = improved_default
    t_end = first_contact_end(scene, plan)
    ser = metrics(out)
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
out = reduced_methods.run_reduced(scene, plan, {{"t_end": {t_end!r}}}, False, "improved")
m = contact_metrics(out.series)
if MPI.COMM_WORLD.rank == 0:
    print("RESULT", json.dumps({{"n": out.model["reduced_dofs"], "F": m["peak_contact_force_N"],
          "tc": m["contact_duration_s"], "modes": out.model["reduction"]["modes"],
          "t": out.series["time_s"].tolist(), "Ft": out.series["contact_force_N"].tolist(),
          "gauges": {{k: out.series[k].tolist() for k in out.series.columns if k.startswith("gauge_")}}}}))
"""
    res = run_mpi_script(code, np=2)
    assert res.returncode == 0, res.stderr[-3000:]
    got = json.loads([ln for ln in res.stdout.splitlines() if ln.startswith("RESULT")][0].split(" ", 1)[1])
    assert got["n"] == out.model["reduced_dofs"]
    assert got["modes"] == out.model["reduction"]["modes"]
    # Same model, other orderings of the parallel direct solves: round-off (~1e-16) amplified by the
    # contact operator S = B_r A^-1 B_r^T (condition 4.7e3 on this mesh) over ~150 steps. Measured
    # 6e-13 on F_max, 5e-16 on t_c and 2.4e-12 F_max on the force at every step, like traditional
    # and modal-p2 (1e-12); 1e-9 leaves room for other BLAS / MUMPS orderings. It was 1.7e-5 (2e-4
    # on the force history) while the NMM prolongation kept ~1e-17 entries from the ~1e-20 m
    # round-off of the P2 node coordinates in the symmetry plane: they differ with the partition
    # (and the BLAS), and changed which coordinates mass redistribution made massless
    # (448 serial, 457 on 2 ranks; 397 without them).
    assert got["F"] == pytest.approx(ser["F"], rel=1e-9)
    assert got["tc"] == pytest.approx(ser["tc"], rel=1e-9)
    assert np.array_equal(got["t"], out.series["time_s"])
    assert np.max(np.abs(np.array(got["Ft"]) - out.series["contact_force_N"])) < 1e-9 * ser["F"]
    # the gauges, recovered by mode acceleration (rows solved with each rank's share of K_ii):
    # the same bound relative to each gauge's peak
    for g, series in got["gauges"].items():
        ref = np.asarray(out.series[g])
        assert np.max(np.abs(np.array(series) - ref)) < 1e-9 * np.max(np.abs(ref)), g


@pytest.mark.mpi
@serial
def test_augmentation_under_mpi_matches_serial(capsys):
    """The modal truncation augmentation (one vector per body, traditional at 1/t_c where it
    matters most) gives the serial numbers on 2 ranks: measured 4e-13 on F_max (traditional's
    direct solves agree to ~1e-12); 1e-9."""
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
t_end = plan.gap / scene.impact.speed + 1.6 * plan.hertz.contact_time
out = reduced_methods.run_reduced(scene, plan, {{"t_end": t_end, "f_cut": 1 / plan.hertz.contact_time,
                                  "augment": "boussinesq"}}, False, "traditional")
if MPI.COMM_WORLD.rank == 0:
    print("RESULT", json.dumps({{"F": contact_metrics(out.series)["peak_contact_force_N"],
          "n": out.model["reduced_dofs"], "aug": out.model["reduction"]["augmentation_vectors"],
          "A": float(max(abs(out.series["gauge_A_stress_Pa"])))}}))
"""
    res = run_mpi_script(code, np=2)
    assert res.returncode == 0, res.stderr[-3000:]
    ser, par = (json.loads([ln for ln in out.splitlines() if ln.startswith("RESULT")][0].split(" ", 1)[1])
                for out in (run_script_here(code, capsys), res.stdout))
    assert ser["aug"] == par["aug"] == 2
    assert ser["n"] == par["n"]
    assert par["F"] == pytest.approx(ser["F"], rel=1e-9)
    assert par["A"] == pytest.approx(ser["A"], rel=1e-9)


@serial
def test_improved_slow_impact_runs():
    """study-base at 1 m/s with the plan's mesh: the NMM zone's reduced mass is too ill-conditioned
    for the Jacobi-CG projection of the initial state (it stopped the velocity study); the run
    must fall back to a factorization and give the Hertz pulse (the clamped 40 mm block bends:
    F_max measured -5.6 % against Hertz at 40 ms, so 10 %)."""
    from millimpact.methods import reduced as reduced_methods
    from millimpact.scene.plan import make_plan
    from millimpact.results.timeseries import contact_metrics
    from millimpact.scene.builtin import builtin_scene

    scene = builtin_scene("study-base").with_value("impact.velocity", (0.0, -1.0, 0.0))
    plan = make_plan(scene)
    out = reduced_methods.run_reduced(scene, plan, {"t_end": first_contact_end(scene, plan)}, False, "improved")
    m = contact_metrics(out.series)
    assert m["peak_contact_force_N"] == pytest.approx(plan.hertz.force_max, rel=0.10)
    assert m["contact_duration_s"] == pytest.approx(plan.hertz.contact_time, rel=0.05)


@serial
def test_mass_redistribution_second_ring_serial_equals_mpi(capsys):
    """study-base with the reduced zone of 2.5 a_max: some contact nodes at the zone's edge have
    only contact neighbours, and their mass goes to the next ring through the two-step couplings
    (|M| |M|), whichever rank owns the neighbours: serial and 2 ranks agree (direct solves: ~1e-11;
    the issue's 1e-6)."""
    code = '''
from mpi4py import MPI
from millimpact.scene.builtin import builtin_scene
from millimpact.scene.plan import make_plan
from millimpact.methods import reduced as reduced_methods
from millimpact.results.timeseries import contact_metrics
scene = builtin_scene("study-base").with_value("time.end", 1.6e-4)
scene = scene.with_value("model.zone_radius", 2.5 * make_plan(scene).hertz.a_max)
out = reduced_methods.run_reduced(scene, make_plan(scene), {}, False, "traditional")
if MPI.COMM_WORLD.rank == 0:
    print("RESULT", repr(contact_metrics(out.series)["peak_contact_force_N"]))
'''
    par = run_mpi_script(code, np=2)
    assert par.returncode == 0, par.stderr[-3000:]
    f1, f2 = (float(next(ln for ln in out.splitlines() if ln.startswith("RESULT")).split()[1])
              for out in (run_script_here(code, capsys), par.stdout))
    assert f2 == pytest.approx(f1, rel=1e-6)


def test_reduced_notes_give_the_full_run_of_the_same_mesh():
    """The reduced run's note "full on the same mesh: --set model.zone_radius=R" names the very
    mesh (the same cache key): printed to 6 digits, R meshed a different mesh (67,524 against
    67,272 P2 dofs on the default scene)."""
    import re

    from millimpact.geometry.mesh import cache_key, mesh_parameters
    from millimpact.scene.plan import make_plan
    from millimpact.methods.reduced import reduced_plan
    from millimpact.scene.builtin import builtin_scene

    base = builtin_scene("paper-rig")
    scene, plan, _, notes = reduced_plan(base, make_plan(base))
    value = re.search(r"--set model\.zone_radius=(\S+)\)", " ".join(notes)).group(1)
    full_scene = base.with_value("model.zone_radius", float(value))
    assert cache_key(mesh_parameters(full_scene, make_plan(full_scene))) == cache_key(mesh_parameters(scene, plan))


@serial
def test_contact_point_kinematics_match_the_quasi_static_patch(improved_default):
    """The contact point's velocity and acceleration (issue 18): the FE methods report the motion of
    the centre of mass of the half-ball of radius a_max under the contact point, band-limited to
    4 / t_c (results.band_limit). Independent reference: the Boussinesq field of the Hertz pressure
    averaged over that half-ball (theory.hertz.patch_mean_displacement), driven by the Hertz force
    history, differentiated and band-limited the same way. It neglects the patch's inertia and the
    block's finite size: on the default mesh the FE gives v 0.998 m/s and a_min -54.2 km/s^2
    against 0.962 and -53.8 (benchmarks/contact_point_convergence.py, which also shows <= 0.5 %
    change under dt/4 and h/2). On this coarse mesh (a_max / h = 1.45) measured +2.9 % and -5.8 %;
    8 % and 12 % allowed. The surface node's own velocity jumped 0 -> 1.45 m/s in one step (a
    step change of ~1 peak); the patch's largest step change is measured 0.064 of its peak."""
    from millimpact.results.band_limit import gaussian_low_pass
    from millimpact.theory.hertz import hertz_history, patch_mean_displacement

    scene, plan, out = improved_default
    h, m = plan.hertz, plan.target
    hist = hertz_history(h, n=4001)
    w = patch_mean_displacement(hist.force, hist.contact_radius, h.a_max, 2 * m.shear_modulus * (1 + m.poisson),
                                m.poisson)
    t = hist.time
    v = np.gradient(w, t)
    a = np.gradient(v, t)
    pad = np.arange(1, 400) * (t[1] - t[0])         # at rest before and after the contact
    tg, z = np.concatenate([t[0] - pad[::-1], t, t[-1] + pad]), np.zeros(len(pad))
    v_ref = gaussian_low_pass(tg, np.concatenate([z, v, z]), 4.0 / h.contact_time)
    a_ref = gaussian_low_pass(tg, np.concatenate([z, a, z]), 4.0 / h.contact_time)
    V = out.series["contact_point_velocity_m_s"]
    A = out.series["contact_point_acceleration_m_s2"]
    assert rel(V.max(), v_ref.max()) < 0.08
    assert rel(A.min(), a_ref.min()) < 0.12
    assert np.abs(np.diff(V)).max() < 0.15 * V.max()


@serial
def test_the_modal_free_phase_starts_soon_after_the_bodies_part(monkeypatch):
    """The steps end 10 contact steps after the contact does (SEPARATED_STEPS), before the first
    span's latest end gap / v + 1.5 t_c, and the free modes take the rest. Against the steps run to
    that latest end (SEPARATED_STEPS out of reach) the impact is the same, step for step: F_max,
    t_c and the impulse to 1e-12; the later vibration (modes up to 4 f_cut from an earlier state)
    moves the gauges' peaks by 0.25 % on the default scene's 40 ms: within 1 % here."""
    from millimpact.methods import free_phase
    from millimpact.methods.run import compute
    from millimpact.results.timeseries import contact_metrics
    from millimpact.scene.plan import make_plan

    scene = small_rig_scene()
    plan = make_plan(scene)
    options = {"t_end": 3e-4, "free_phase": "modal"}
    soon, _ = compute(scene, "improved", dict(options))
    quiet = free_phase.SEPARATED_STEPS
    monkeypatch.setattr(free_phase, "SEPARATED_STEPS", 10**9)
    late, _ = compute(scene, "improved", dict(options))
    s_soon, s_late = (r.results["free_phase"]["segments"] for r in (soon, late))
    assert [s[0] for s in s_soon[:2]] == [s[0] for s in s_late[:2]] == ["step", "modal"]
    assert s_late[0][2] == pytest.approx(free_phase.first_span_end(plan), rel=1e-9)
    force, t = np.asarray(late.series["contact_force_N"]), np.asarray(late.series.time)
    contact_end = float(t[np.nonzero(force > 0)[0][-1]])       # the last contact row
    assert contact_end < s_soon[0][2] <= contact_end + (quiet + 2) * plan.dt_contact
    assert s_soon[0][2] < s_late[0][2]
    a, b = contact_metrics(soon.series), contact_metrics(late.series)
    for k in ("peak_contact_force_N", "contact_duration_s", "impulse_N_s"):
        assert a[k] == pytest.approx(b[k], rel=1e-12), k
    for g in ("A", "B", "C"):
        x, y = (np.max(np.abs(r.series[f"gauge_{g}_stress_Pa"])) for r in (soon, late))
        assert x == pytest.approx(y, rel=0.01), g
