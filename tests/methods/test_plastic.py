"""Elastoplastic impacts (issue 15), full FE on a coarse hertz-halfspace (P1, h_c = a_max/2):
energy with dissipation conserved, the plastic work and restitution in the physical range,
below the yield-onset speed exactly elastic, MPI equals serial, and the failure modes."""
from __future__ import annotations

import json

import numpy as np
import pytest

from conftest import run_cli
from millimpact.results.timeseries import TimeSeries

#: coarse, short: contact (~88 us) and a little rebound; the zone (4 a_max) holds the plastic region
COARSE = ["hertz-halfspace", "--method", "full", "-q", "--set", "model.h_contact=5.8e-4",
          "--set", "model.h_far=0.012", "--set", "time.end=2.0e-4"]


def _run(tmp_path, name, *extra, np_=1):
    out = tmp_path / name
    r = run_cli("run", *COARSE, *extra, "--out", str(out), np=np_)
    assert r.returncode == 0, r.stderr[-3000:]
    return json.loads((out / "summary.json").read_text()), TimeSeries.read_csv(out / "timeseries.csv")


@pytest.fixture(scope="module")
def plastic(plastic_halfspace_run):
    """Y = 1 GPa block under a 3 m/s steel ball: V/V_y ~ 17 (Thornton 1997: V_y = 0.18 m/s). The run
    is conftest's (COARSE with that yield stress), shared with test_plastic_linearisation.py."""
    out = plastic_halfspace_run
    return json.loads((out / "summary.json").read_text()), TimeSeries.read_csv(out / "timeseries.csv")


@pytest.fixture(scope="module")
def elastic(tmp_path_factory):
    return _run(tmp_path_factory.mktemp("elastic"), "el")


def test_energy_with_plastic_work_is_conserved(plastic):
    """kinetic + elastic strain + plastic work constant within 0.5 % (the issue's bound; the
    scheme's own error is the release/impact O(dt) of the elastic case, ~0.02 %)."""
    s, ts = plastic
    e = ts["total_energy_J"] + ts["plastic_dissipation_J"]
    assert np.max(np.abs(e / e[0] - 1)) < 5e-3
    assert s["energy_drift_max_rel"] < 5e-3


def test_plastic_impact_dissipates_and_rebounds_slower(plastic, elastic):
    """At V/V_y ~ 17 FE studies of steel spheres give e ~ 0.8 with ~1/3 of the energy dissipated
    (Wu, Li & Thornton 2005; the issue's figures); Thornton's 1997 model (which over-dissipates) a
    lower bound of 0.58. Elastic: ~0.99 (Hunter's wave loss). The peak force drops below the
    elastic one and the liner keeps a dent."""
    s, ts = plastic
    se, _ = elastic
    assert 0.6 < s["restitution"] < 0.9 < se["restitution"]
    assert 0.15 < s["plastic_dissipation_share"] < 0.45
    assert s["peak_contact_force_N"] < se["peak_contact_force_N"]
    assert s["max_equivalent_plastic_strain"] > 1e-3
    assert 0 < s["residual_dent_depth_m"] < 0.5 * s["max_approach_m"]
    # the permanent dent is about the size of the contact patch (a_max = 1.16 mm at 3 m/s)
    assert 0.5e-3 < s["residual_dent_radius_m"] < 3e-3
    # plastic work never decreases
    assert np.all(np.diff(ts["plastic_dissipation_J"]) >= -1e-12)


def test_below_yield_onset_is_elastic(tmp_path, elastic):
    """V = 0.85 V_y: the Hertz pressure p0 = 4.92 GPa is below the first-yield pressure 1.6 Y
    (Y = 3.6 GPa: 1.6 Y = 5.76 GPa, V_y = 3 (5.76/4.92)^(5/2) m/s): no point yields, and the run
    is the elastic one (the same answers to solver round-off)."""
    s, ts = _run(tmp_path, "below", "--set", "block.material.yield_stress=3.6e9")
    se, tse = elastic
    assert s["max_equivalent_plastic_strain"] == 0.0 and s["plastic_dissipation_J"] == 0.0
    for key in ("peak_contact_force_N", "restitution", "max_approach_m"):
        assert s[key] == pytest.approx(se[key], rel=1e-9), key


@pytest.mark.mpi
def test_plastic_mpi_equals_serial(tmp_path, plastic):
    s2, _ = _run(tmp_path, "np2", "--set", "block.material.yield_stress=1e9", np_=2)
    s1, _ = plastic
    for key in ("peak_contact_force_N", "plastic_dissipation_J", "restitution", "max_equivalent_plastic_strain"):
        assert s2[key] == pytest.approx(s1[key], rel=1e-9), key


def test_newton_failure_is_one_line_and_writes_nothing(tmp_path):
    out = tmp_path / "fail"
    r = run_cli("run", *COARSE, "--set", "block.material.yield_stress=1e9", "--out", str(out),
                "-impact_plastic_max_iterations", "1")
    assert r.returncode == 1 and "Traceback" not in r.stderr
    line = r.stderr.strip().splitlines()[-1]
    assert "plastic Newton did not converge" in line and "at step" in line and "t = " in line
    assert not out.exists() and list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("setting, field", [
    ("block.material.yield_stress=-1e9", "block.material.yield_stress"),
    ("block.material.yield_stress=0", "block.material.yield_stress"),
    ("block.material.hardening_modulus=-1e9", "block.material.hardening_modulus"),
    ("block.material.flow_curve=[[0.0,4e8],[0.1,3e8]]", "block.material.flow_curve"),
    ("block.material.flow_curve=[[0.01,4e8],[0.1,5e8]]", "block.material.flow_curve"),
    ("block.material=\"no-such-steel\"", "block.material"),
])
def test_bad_plastic_input_is_one_line(setting, field):
    r = run_cli("run", "hertz-halfspace", "--method", "hertz", "--set", setting, "--out", "out/never")
    assert r.returncode == 2 and r.stderr.count("\n") == 1 and r.stderr.startswith(f"millimpact: error: {field}")


def test_improved_equals_full_p2_of_the_same_mesh(tmp_path):
    """The improved method projects the zone's plasticity exactly (NMM covers in the P2 space of the
    quadrature points) and keeps the region modal: against full P2 of the same mesh, zone and
    contact candidates (the notes print both radii), the issue's bounds: F_max within 1 %,
    restitution within 0.01, dent depth within 2 % (measured 0.6 %, 0.0035, 0.9 %; the dent from
    the reduced model's own static solve since 2026-11-26, -0.95 %)."""
    y = ["--set", "block.material.yield_stress=1e9"]
    si, _ = _run(tmp_path, "improved", *y, "--method", "improved")
    zone, cand = si["model"]["zone_radius_m"], si["model"]["candidate_radius_m"]
    sf, _ = _run(tmp_path, "fullp2", *y, "--method", "full", "--degree", "2", "--set", f"model.zone_radius={zone!r}",
                 "-candidate_radius", repr(cand))
    assert si["peak_contact_force_N"] == pytest.approx(sf["peak_contact_force_N"], rel=0.01)
    assert abs(si["restitution"] - sf["restitution"]) < 0.01
    assert si["residual_dent_depth_m"] == pytest.approx(sf["residual_dent_depth_m"], rel=0.02)
    assert si["plastic_dissipation_J"] == pytest.approx(sf["plastic_dissipation_J"], rel=0.03)


def test_zone_boundary_check(tmp_path, plastic):
    """The plan's zone (4 a_max) holds the plastic region at V/V_y ~ 17: its boundary stays elastic;
    a zone of 1.4 a_max does not, and the notes say so with a radius to use."""
    s, _ = plastic
    assert s["zone_boundary_elastic"] and s["zone_boundary_max_equivalent_plastic_strain"] == 0.0
    # the plan's prediction (Johnson's cavity model on Thornton's contact radius) against the
    # plastic region measured: the zone margin 1.75 (plan.py) must cover it, and the model is not
    # off by more than 2x (measured 1.31x the prediction here)
    r = s["plastic_zone_radius_m"]
    assert 0.5 * r["predicted"] < r["struck_body"] < 1.75 * r["predicted"] < r["contact_zone"]
    small, _ = _run(tmp_path, "small-zone", "--set", "block.material.yield_stress=1e9", "--set", "model.zone_radius=0.0016")
    assert not small["zone_boundary_elastic"]
    assert any(n.startswith("WARNING: plastic strain") and "model.zone_radius=0.0024" in n for n in small["notes"])


def test_plastic_fields_in_xdmf(tmp_path):
    """fields.xdmf carries the cellwise equivalent plastic strain and von Mises stress beside the
    displacement; at the end its largest plastic strain is the time series' (the same quadrature
    points), and the von Mises stress stays within the flow stress (perfect plasticity: <= Y)."""
    import h5py

    s, _ = _run(tmp_path, "fields", "--set", "block.material.yield_stress=1e9", "--set", "outputs.field_times=[1.9e-4]")
    with h5py.File(tmp_path / "fields" / "fields.h5") as h5:
        f = h5["Function"]
        assert {"displacement_m", "equivalent_plastic_strain", "von_mises_Pa"} <= set(f)
        alpha = max(float(np.max(f["equivalent_plastic_strain"][k][...])) for k in f["equivalent_plastic_strain"])
        vm = max(float(np.max(f["von_mises_Pa"][k][...])) for k in f["von_mises_Pa"])
    assert alpha == pytest.approx(s["max_equivalent_plastic_strain"], rel=1e-12)
    assert 0 < vm <= 1e9 * (1 + 1e-9)


#: the improved method on the coarse half-space, to 0.4 ms: contact, then the modal free phase
IMPROVED = ["--method", "improved", "--set", "block.material.yield_stress=1e9", "--set", "time.end=4.0e-4"]
#: the same with the modal free phase asked (auto steps a free span this short)
IMPROVED_MODAL = IMPROVED + ["-free_phase", "modal"]


@pytest.fixture(scope="module")
def improved_modal(tmp_path_factory):
    folder = tmp_path_factory.mktemp("improved")
    return (*_run(folder, "modal", *IMPROVED_MODAL), folder / "modal")


@pytest.mark.mpi
def test_improved_plastic_mpi_equals_serial(tmp_path, improved_modal):
    """mpirun -n 2 of the improved plastic run (projected zone, tangent reuse, modal phase about the
    residual state): the issue's 1e-9 relative on F_max and the dissipation (measured 3e-13)."""
    s1, t1, _ = improved_modal
    s2, t2 = _run(tmp_path, "np2", *IMPROVED_MODAL, np_=2)
    for k in ("peak_contact_force_N", "plastic_dissipation_J", "restitution", "residual_dent_depth_m"):
        assert s2[k] == pytest.approx(s1[k], rel=1e-9), k
    assert s2["free_phase"]["segments"] == s1["free_phase"]["segments"]
    assert np.max(np.abs(t2["contact_point_displacement_m"] - t1["contact_point_displacement_m"])) < \
        1e-9 * np.max(np.abs(t1["contact_point_displacement_m"]))


def test_modal_free_phase_continues_about_the_residual_state(tmp_path, improved_modal):
    """After separation the plastic strain is frozen and the improved method switches to the
    closed-form free vibration about the residual state q_s (K_r q_s = -f_frozen: the dent and the
    residual stress). Against stepping the same model to the end (-free_phase step): the residual
    dent under the contact point and its residual stress agree (the modal phase drops the modes
    above 4 f_cut: measured 0.3 % and 0.3 %; bound 2 %), the plastic work is frozen, and kinetic +
    elastic + plastic dissipation stays constant through the modal phase (0.03 % measured; the
    issue's 0.5 %)."""
    sm, tm, folder = improved_modal
    ss, tss = _run(tmp_path, "step", *IMPROVED, "-free_phase", "step")
    assert [seg[0] for seg in sm["free_phase"]["segments"]] == ["step", "modal"]
    assert [seg[0] for seg in ss["free_phase"]["segments"]] == ["step"]
    for c in ("contact_point_displacement_m", "contact_point_stress_Pa"):
        assert tm[c][-1] == pytest.approx(tss[c][-1], rel=0.02), c
    assert tm[c][-1] > 0.0
    modal = tm["time_s"] > sm["free_phase"]["segments"][1][1]
    assert np.ptp(tm["plastic_dissipation_J"][modal]) == 0.0
    budget = tm["total_energy_J"] + tm["plastic_dissipation_J"]
    assert np.ptp(budget) < 0.005 * budget[0]
    assert sm["restitution"] == pytest.approx(ss["restitution"], abs=1e-3)
    assert (folder / "plastic_zone.png").stat().st_size > 0     # the section figure
