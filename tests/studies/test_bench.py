"""The light hertz-modal method against full FE, and ``millimpact bench --quick``.

hertz-modal vs full P2 on the small paper-rig mesh of tests/test_reduction.py (~10.6k P2 dofs,
a short impact): ~10 s. The quick bench (every method at two coarse levels, reference cached in
a temporary folder): ~2 minutes on the shared 2-core machine.
"""
from __future__ import annotations

import json
import math

import numpy as np
import pytest

from conftest import SMALL_RIG as SMALL, run_cli, small_rig_scene


def test_hertz_modal_matches_full():
    from millimpact.scene.plan import make_plan
    from millimpact.results.timeseries import contact_metrics
    from millimpact.methods.run import compute

    scene = small_rig_scene()
    plan = make_plan(scene)
    t_end = plan.gap / scene.impact.speed + 1.6 * plan.hertz.contact_time
    hm, _ = compute(scene, "hertz-modal", {"t_end": t_end})
    full, _ = compute(scene, "full", {"t_end": t_end, "degree": 2})
    a, b = contact_metrics(hm.series), contact_metrics(full.series)
    # the light model: a quasi-static Hertz spring (no wave radiation from the patch, rigid ball)
    # on the block's modes up to 4/t_c; full P2 on this coarse mesh is itself within ~1-2 % of
    # the bench's converged reference. Measured: F_max -1.5 %, t_c -1.7 %: tolerance 3 %.
    assert a["peak_contact_force_N"] == pytest.approx(b["peak_contact_force_N"], rel=0.03)
    assert a["contact_duration_s"] == pytest.approx(b["contact_duration_s"], rel=0.03)
    assert a["impulse_N_s"] == pytest.approx(b["impulse_N_s"], rel=0.03)
    # the ODE (DOP853, rtol 1e-8) conserves the energy of ball + spring + modes (measured 3e-8)
    assert hm.results["energy_drift_max_rel"] < 1e-5
    # the block keeps part of the energy in vibration: the ball rebounds slower than it came
    assert 0.5 < hm.results["restitution"] < 1.0
    assert hm.model["modes"] >= 2 and hm.model["dofs"] == 1 + hm.model["modes"]
    for g in ("A", "B", "C"):
        x = hm.series[f"gauge_{g}_stress_Pa"]
        assert np.all(np.isfinite(x)) and np.max(np.abs(x)) > 0


@pytest.fixture(scope="module")
def quick_bench(tmp_path_factory):
    import os

    root = tmp_path_factory.mktemp("bench")
    os.environ["MILLIMPACT_BENCH_CACHE"] = str(root / "cache")
    try:
        r = run_cli("bench", "--quick", "--out", str(root / "out"), timeout=900)
    finally:
        os.environ.pop("MILLIMPACT_BENCH_CACHE", None)
    assert r.returncode == 0, r.stdout[-2000:] + r.stderr[-2000:]
    return root, r


def test_bench_quick_every_method(quick_bench):
    from millimpact.studies.bench import ENTRIES, read_csv

    root, r = quick_bench
    out = root / "out"
    rows = read_csv(out / "bench.csv")
    assert {row["method"] for row in rows} == set(ENTRIES)
    for m in ENTRIES:
        ok = [row for row in rows if row["method"] == m and row["status"] == "ok"]
        assert ok, f"{m}: no successful run"
        for row in ok:
            for k in ("err_F_max", "err_t_c", "err_impulse", "err_force_L2", "wall_s", "peak_rss_MB"):
                assert math.isfinite(float(row[k])), (m, k, row)
            assert int(row["dofs"]) >= 1
            if m != "hertz":           # hertz has no gauges
                assert math.isfinite(float(row["err_gauge_L2"])), row
    # mesh refinement: full P2 at the reference's own mesh (half its step) is much closer to it
    # than at the coarser level; Newmark's dt^2 error at t_c/100 is ~1e-3 of the pulse
    p2 = sorted((row for row in rows if row["method"] == "full-p2"), key=lambda x: float(x["level"]))
    assert float(p2[-1]["err_force_L2"]) < 0.01 < float(p2[0]["err_force_L2"])
    for f in ("pareto.png", "reference_convergence.png"):
        assert (out / f).stat().st_size > 0
    meta = json.loads((out / "bench.json").read_text())
    assert "improved/full-p2" in meta["equal_error_wall_ratio"]
    # the reference levels are cached, keyed by scene + options
    cached = list((root / "cache").glob("*/result.json"))
    assert len(cached) == 2


def test_bench_bad_input():
    r = run_cli("bench", "--methods", "full,magic")
    assert r.returncode == 2
    assert "--methods" in r.stderr and "Traceback" not in r.stderr


def test_hertz_modal_mpi_equals_serial(capsys):
    # the block's modes are computed by SLEPc on the distributed mesh; the ODE runs on the modal
    # coordinates, replicated. Modes agree to the eigensolver's tolerance (eps_tol 1e-10), so the
    # force history agrees far below the 1e-6
    from conftest import run_mpi_script, run_script_here

    code = f"""
from mpi4py import MPI
from millimpact.scene.plan import make_plan
from millimpact.results.timeseries import contact_metrics
from millimpact.methods.run import compute
from millimpact.scene.builtin import builtin_scene
scene = builtin_scene("paper-rig")
for k, v in {SMALL!r}.items():
    scene = scene.with_value(k, v)
plan = make_plan(scene)
out, _ = compute(scene, "hertz-modal", {{"t_end": plan.gap / scene.impact.speed + 1.6 * plan.hertz.contact_time}})
m = contact_metrics(out.series)
if MPI.COMM_WORLD.rank == 0:
    print("RESULT", repr(m["peak_contact_force_N"]), repr(m["contact_duration_s"]),
          repr(float(abs(out.series["gauge_A_stress_Pa"]).max())))
"""
    r = run_mpi_script(code, np=2)
    assert r.returncode == 0, r.stderr[-3000:]
    v1, v2 = ([float(x) for x in next(ln for ln in out.splitlines() if ln.startswith("RESULT")).split()[1:]]
              for out in (run_script_here(code, capsys), r.stdout))
    for a, b in zip(v1, v2):
        assert b == pytest.approx(a, rel=1e-6)
