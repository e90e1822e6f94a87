"""The stability sweep (millimpact.studies.stability) on the 1D bar with its exact solution.

Bar runs take ~0.05 s each (50 or 100 P1 elements); the CLI test runs the --quick sweep on the
bar only. The sphere part of the sweep is exercised by benchmarks/stability.py.
"""
from __future__ import annotations

import math

import pytest

from conftest import run_cli
from millimpact.studies import stability as S


@pytest.mark.parametrize("v0", [0.01, 1.0, 20.0])      # 0.01 m/s: the grazing case
def test_plain_newmark_chatter_flagged_mass_redistribution_passes(v0):
    for courant in (0.5, 1.0):
        mr = S.run_bar_case("newmark-mr", courant, v0, 100)
        nm = S.run_bar_case("newmark", courant, v0, 100)
        # Khenous-Laborde-Renard: one clean contact (closed once, opened once), energy kept within
        # the impact/release steps' error (measured < 0.3 %; threshold 5 % from the map's rule)
        assert mr.status == "pass", (mr.reason, mr)
        assert mr.status_switches == 2 and mr.pulse_breaks == 0
        # plain Newmark: the tip rattles (foundations.md section 4) -> flagged, with the chatter named
        assert nm.status in ("degraded", "failed"), nm
        assert nm.pulse_breaks >= 10 and nm.status_switches >= 10 * mr.status_switches, nm
        assert nm.energy_drift_rel > 10 * mr.energy_drift_rel


def test_explicit_critical_step_where_theory_puts_it():
    """Central differences with the step limit off: the sweep's stability boundary on the bar must
    bracket the theoretical critical step in contact, 2/sqrt(lambda_max(M_L^-1 (K + k_p e e^T)))
    (0.910 h/c for k_p = E/h), and lie below the free bar's h/c."""
    n_el = 50
    th = S.bar_critical_step_theory(n_el)
    assert th["free"] == pytest.approx(1.0, rel=1e-12)      # lumped P1: omega_max = 2c/h exactly
    assert 0.5 < th["contact"] < 1.0
    courants = (0.8, 0.85, 0.9, 0.95, 1.0, 1.05, 1.2)
    cases = [S.run_bar_case("central-penalty", cr, 1.0, n_el) for cr in courants]
    rep = S.critical_step_report(cases, n_el)
    lo, hi = rep["bar_measured_courant"]["largest_stable"], rep["bar_measured_courant"]["smallest_failed"]
    # the boundary lies between two sweep points: the theory must fall in that bracket, whose
    # width is the sweep's resolution (0.05 h/c here, i.e. within a factor 1.06 of theory)
    assert lo <= th["contact"] <= hi, rep
    assert hi / lo <= 1.07
    # every step below is stable, every one above fails (no isolated unstable point)
    for c in cases:
        assert (c.status == "failed") == (c.dt_rel > th["contact"]), (c.dt_rel, c.status, c.reason)
    # the integrator's own estimate (SLEPc) agrees with the dense theory
    assert rep["bar_integrator_estimate_courant"] == pytest.approx(th["contact"], rel=1e-6)


def test_stability_cli_quick_bar(tmp_path):
    out = tmp_path / "stab"
    r = run_cli("stability", "--quick", "--problems", "bar", "--out", str(out), timeout=300)
    assert r.returncode == 0, r.stderr[-2000:]
    rows = S.read_csv(out / "stability.csv")
    # 3 integrators x quick grid (4 Courant numbers x 3 velocities)
    assert len(rows) == 3 * 4 * 3
    assert {r["status"] for r in rows} <= {"pass", "degraded", "failed"}
    for integ in S.INTEGRATORS:
        assert (out / f"map_{integ}.png").stat().st_size > 0
    failed_nm = [r for r in rows if r["integrator"] == "newmark" and r["status"] != "pass"]
    assert failed_nm, "plain Newmark must be flagged somewhere on the bar"
    ok = [float(r["energy_drift_rel"]) for r in rows if r["status"] == "pass"]
    assert ok and all(math.isfinite(x) for x in ok)


def test_stability_bad_input():
    r = run_cli("stability", "--integrators", "leapfrog", "--out", "/tmp/never")
    assert r.returncode == 2
    assert "--integrators" in r.stderr and "Traceback" not in r.stderr
