"""Full FE impact against Hertz theory (foundations.md section 3), energy balance, and serial vs MPI.

Test meshes are coarse (h_contact = a_max/4 near contact, ~18k dofs, quarter model), so tolerances
are the issue's 5 % on F_max and t_c; the benchmark (benchmarks/full_hertz.py) runs finer meshes.
"""
import json

import numpy as np
import pytest

from conftest import run_cli
from millimpact.results.timeseries import TimeSeries

# a_max = 1.159 mm for the default ball at 3 m/s: h_contact = a_max / 4 (the plan's default)
HALFSPACE = ["run", "hertz-halfspace", "--method", "full", "--set", "time.end=1.2e-4", "-q"]


@pytest.fixture(scope="module")
def halfspace_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("hh") / "run"
    r = run_cli(*HALFSPACE, "--out", str(out))
    assert r.returncode == 0, r.stderr[-2000:]
    return json.loads((out / "summary.json").read_text()), TimeSeries.read_csv(out / "timeseries.csv"), out


def test_impact_matches_hertz(halfspace_run):
    s, ts, _ = halfspace_run
    h = s["hertz"]
    # Hertz is exact for a quasi-static half-space; the block is a 100 mm cube (not a half-space) and
    # the mesh coarse: the 5 % on F_max and t_c
    assert s["peak_contact_force_N"] == pytest.approx(h["F_max_N"], rel=0.05)
    assert s["contact_duration_s"] == pytest.approx(h["t_c_s"], rel=0.05)
    assert s["max_approach_m"] == pytest.approx(h["delta_max_m"], rel=0.05)
    # the plan's default is P1: the notes say what error to expect and how to reach ~1 % (issue 18),
    # and the run bears it out (P1 is stiff: F_max above Hertz)
    assert any(n.startswith("expected accuracy: P1 is too stiff") and "--degree 2" in n for n in s["notes"])
    assert s["peak_contact_force_N"] > h["F_max_N"]


def test_restitution_and_energy(halfspace_run):
    s, ts, _ = halfspace_run
    # Hunter (1957): ~1.3 % of the energy radiates as waves at 3 m/s -> e ~ 0.99; much lower means
    # numerical dissipation; above 1 would mean energy creation
    assert 0.98 < s["restitution"] < 1.001
    # Newmark average acceleration with mass redistribution conserves energy (Khenous et al. 2008)
    assert s["energy_drift_over_impact_rel"] < 0.01
    e = ts["total_energy_J"]
    assert e[0] == pytest.approx(0.5 * s["hertz"]["mass_kg"] * 3.0**2, rel=1e-6)  # exact ball mass


def test_contact_radius_at_peak(halfspace_run):
    # Hertz: a_max = sqrt(R delta_max) = 1.159 mm. The discrete radius (outermost node with lambda > 0)
    # lies within one contact element h_c = a_max / 4 (plus the node spacing on the sphere) below it.
    s, ts, _ = halfspace_run
    a_hertz = s["hertz"]["a_max_m"]
    a = ts["contact_radius_m"][np.argmax(ts["contact_force_N"])]
    assert a_hertz - 1.5 * a_hertz / 4 <= a <= 1.05 * a_hertz


def test_outputs_written(halfspace_run):
    s, ts, out = halfspace_run
    for f in ("contact_force.png", "contact_point.png", "gauges.png", "energy.png", "timeseries.h5"):
        assert (out / f).stat().st_size > 0
    for g in ("A", "B", "C"):
        assert f"gauge_{g}_stress_Pa" in ts
    # the liner's contact point is pushed in and compressed during contact
    assert ts["contact_point_displacement_m"].max() > 0
    assert ts["contact_point_stress_Pa"].min() < 0


@pytest.mark.mpi
def test_mpi_equals_serial(tmp_path):
    # same coarse impact serially and on 2 ranks: the same numbers to solver tolerance (1e-6 relative)
    args = ["run", "hertz-halfspace", "--method", "full", "--set", "time.end=1.0e-4", "--set", "model.h_far=1.5e-2",
            "--set", "model.h_contact=4e-4", "-q"]
    r1 = run_cli(*args, "--out", str(tmp_path / "np1"))
    r2 = run_cli(*args, "--out", str(tmp_path / "np2"), np=2)
    assert r1.returncode == 0, r1.stderr[-2000:]
    assert r2.returncode == 0, r2.stderr[-2000:]
    a = TimeSeries.read_csv(tmp_path / "np1" / "timeseries.csv")
    b = TimeSeries.read_csv(tmp_path / "np2" / "timeseries.csv")
    assert len(a.time) == len(b.time)
    fmax = a["contact_force_N"].max()
    assert np.max(np.abs(a["contact_force_N"] - b["contact_force_N"])) < 1e-6 * fmax
    e0 = a["total_energy_J"][0]
    assert np.max(np.abs(a["total_energy_J"] - b["total_energy_J"])) < 1e-6 * e0
    sa = json.loads((tmp_path / "np2" / "summary.json").read_text())
    assert sa["model"]["mpi_ranks"] == 2
