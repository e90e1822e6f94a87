"""Impact-only reduced runs (the cases of a contact table, ``run_reduced_case(impact_only=True)``):
the run ends IMPACT_QUIET_CONTACTS t_c after separation and records the energies on every
ENERGY_EVERY_IMPACT_ONLY-th row and the last. Checked against the same impact run to its full
end on the same setup (coarse half-space, improved: ~1.3k reduced coordinates, ~10 s).
"""
from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pytest
from mpi4py import MPI

from millimpact.integration.integrators import SeparationStop
from millimpact.methods.reduced import (ENERGY_EVERY_IMPACT_ONLY, IMPACT_QUIET_CONTACTS, build_reduced_setup,
                                        run_reduced_case)
from millimpact.scene.builtin import builtin_scene
from millimpact.scene.plan import make_plan

ENERGIES = ("ball_kinetic_energy_J", "kinetic_energy_J", "strain_energy_J", "total_energy_J")


def test_separation_stop_counts_quiet_steps_after_a_contact():
    stop = SeparationStop(4)
    seq = [0, 0, 3, 5, 0, 0, 2, 0, 0, 0, 0]      # active contacts per step: apart, touch, chatter, apart
    said = [stop(SimpleNamespace(n_active=n)) for n in seq]
    # never before the first touch; the re-touch at index 6 restarts the count; True at the 4th quiet step
    assert said == [False] * 10 + [True]
    assert SeparationStop(1).quiet_steps == 3      # restitution reads two rows after the last contact


@pytest.fixture(scope="module")
def runs():
    scene = builtin_scene("hertz-halfspace").with_value("model.h_contact", 5.8e-4).with_value("model.h_far", 0.012)
    plan = make_plan(scene)
    opts = {"contact_solve": "schur"}
    setup = build_reduced_setup(scene, plan, dict(opts), "improved", MPI.COMM_WORLD, share_operators=True)
    t_end = setup.plan.gap / setup.plan.normal_speed + 1.5 * setup.plan.hertz.contact_time
    full = run_reduced_case(setup, setup.scene, setup.plan, dict(opts), False, t_end=t_end)
    cut = run_reduced_case(setup, setup.scene, setup.plan, dict(opts), False, t_end=t_end, impact_only=True)
    return setup.plan, full, cut


def test_impact_only_run_stops_after_separation(runs):
    plan, full, cut = runs
    f = cut.series["contact_force_N"]
    last = int(np.nonzero(f > 0)[0][-1])
    quiet = math.ceil(IMPACT_QUIET_CONTACTS * plan.hertz.contact_time / plan.dt_contact)
    # the last contact row, then exactly `quiet` rows apart
    assert len(f) - 1 - last == quiet
    assert len(f) < 0.9 * len(full.series["contact_force_N"])
    assert cut.results["integration"]["stopped_at"] == pytest.approx(cut.series.time[-1], rel=1e-12)


def test_impact_only_run_gives_the_full_runs_numbers(runs):
    _, full, cut = runs
    n = len(cut.series.time)
    # the same steps from the same state on the same factorization: equal to rounding (the state
    # update sums W's active columns in another order than W.mult would: ~1e-15 a step)
    for name in ("contact_force_N", "ball_velocity_m_s", "approach_m"):
        np.testing.assert_allclose(cut.series[name], full.series[name][:n], rtol=1e-10,
                                   atol=1e-10 * np.max(np.abs(full.series[name])))
    for key in ("restitution", "time_of_peak_force_s", "energy_initial_J"):
        assert cut.results[key] == pytest.approx(full.results[key], rel=1e-10)


def test_impact_only_energies_on_the_first_every_tenth_and_last_row(runs):
    _, full, cut = runs
    n = len(cut.series.time)
    for name in ENERGIES:
        e, ref = cut.series[name], full.series[name][:n]
        rows = np.arange(n)
        kept = (rows % ENERGY_EVERY_IMPACT_ONLY == 0) | (rows == n - 1)
        assert np.all(np.isfinite(e[kept])) and np.all(np.isnan(e[~kept]))
        # the last row's energies are filled from its kept state when the stride skipped it
        np.testing.assert_allclose(e[kept], ref[kept], rtol=1e-9, atol=1e-12 * np.max(np.abs(ref)))
    # the drift over the rows that have energies: no NaN leaks into the results, and a subset of
    # the full run's rows cannot drift more than they do
    assert math.isfinite(cut.results["energy_drift_max_rel"])
    assert cut.results["energy_drift_max_rel"] <= full.results["energy_drift_max_rel"] * (1 + 1e-9)
