"""The mill in LIGGGHTS (``millimpact mill --engine liggghts``): the drive's power from the liner's
torque against the torque the charge's weight puts about the axis, a slice and a mill with end
plates, on one and two MPI ranks; and bad input.

The reference is the charge's angular momentum balance about the axis, which uses the particles'
positions alone (not the mesh's stress fix): d L_z / dt = T_liner + T_gravity, T_gravity =
-g sum m_i x_i, so over a window [t0, t1] the liner's mean torque on the charge is
g <sum m_i x_i> + (L_z(t1) - L_z(t0)) / (t1 - t0) and the drive's power omega times it.
"""

from __future__ import annotations

import shutil

import numpy as np
import pytest
from conftest import run_cli
from mill_scenes import small_mill_scene

from millimpact.dem.mill.liggghts_mill import plan_liggghts_mill, read_dump, run_liggghts_mill
from millimpact.dem.mill.setup import MillOptions

#: the balance holds exactly in continuous time; velocity Verlet's impulse over a window of N steps
#: is dt (sum_1^N T_k + (T_0 - T_N) / 2), the average counts the sum alone: the torques at the
#: window's ends differ by up to ~10x the mean (an impact), over ~13,000 steps that is ~4e-4; and
#: LIGGGHTS writes the averages and the snapshots with 6 digits. Measured 0.6-2.3e-4 over whole
#: revolutions, 1.05e-3 over the quarter revolution of the two-rank case
TOLERANCE = 3e-3
needs_liggghts = pytest.mark.skipif(
    shutil.which("liggghts") is None, reason="LIGGGHTS is not installed (apt-get install liggghts)"
)


def _balance_power(summary: dict, snapshots: dict, setup) -> float:
    """omega (g M <x_cm> + Delta L_z / Delta t) (W): <x_cm> LIGGGHTS' every-step mean over the
    logged window (the summary's power_from_charge_position_W is omega g M <x_cm>), L_z = sum m (x v_y
    - y v_x) + (2/5) m r^2 omega_z from the snapshots at the window's ends."""
    k = snapshots["snapshot"].astype(int)
    m, r = setup.ball_mass, setup.ball_radius
    x, y, vx, vy, wz = (snapshots[c] for c in ("x_m", "y_m", "vx_m_s", "vy_m_s", "wz_rad_s"))
    lz = np.bincount(k, weights=m * (x * vy - y * vx) + 0.4 * m * r**2 * wz)
    t0, t1 = snapshots["time_s"][k == 0][0], snapshots["time_s"][k == k.max()][0]
    window = summary["power"]["measured"]["window_s"]
    assert t0 == pytest.approx(window[0]) and t1 == pytest.approx(window[1])
    return summary["power"]["power_from_charge_position_W"] + setup.omega * (lz[-1] - lz[0]) / (t1 - t0)


def _run(tmp_path, length, ranks, revolutions):
    opts = MillOptions(revolutions=revolutions, fill=0.2, warmup=revolutions)
    scene = small_mill_scene()
    plan = plan_liggghts_mill(scene, opts, length, ranks)
    stage = tmp_path / f"run-{length}-{ranks}"
    stage.mkdir()
    summary = run_liggghts_mill(scene, opts, stage, plan, plots=False, quiet=True, timeout=300)
    return plan, summary, read_dump(stage / "liggghts" / "charge.dump", plan.setup.dt)


@needs_liggghts
@pytest.mark.parametrize("length, ranks, revolutions", [(None, 1, 0.5), ("0.2", 2, 0.25)])
def test_the_drive_power_balances_the_charges_weight_about_the_axis(tmp_path, length, ranks, revolutions):
    """The small mill at 20 % fill and 75 % of n_c, a warm-up and a logged window of ``revolutions``:
    the net power from the liner's torque (the stress fix, shell and end plates) equals omega times
    the torque of the charge's weight plus its change of angular momentum (_balance_power). The
    slice on one rank (59 balls between frictionless ends), and 0.2 m between turning end plates
    on two ranks cut along the axis (98 balls; the end plates carry part of the torque)."""
    plan, summary, snaps = _run(tmp_path, length, ranks, revolutions)
    measured = summary["power"]["measured"]["net_W"]
    reference = _balance_power(summary, snaps, plan.setup)
    assert measured > 0.0
    assert measured == pytest.approx(reference, rel=TOLERANCE), (measured, reference)
    assert summary["liggghts"]["ranks"] == ranks and summary["liggghts"]["steps"] == plan.warm_steps + plan.run_steps
    assert summary["toe_deg"] is not None and summary["toe_deg"] < summary["shoulder_deg"]
    if length is not None:
        assert plan.end_plates and summary["power"]["ends_share"] > 0.0
        # the whole length is the mill: its power is the run's, per metre the run's over 0.2 m
        m = summary["power"]["measured"]
        assert m["net_mill_W"] == pytest.approx(measured) and m["net_per_metre_W_m"] == pytest.approx(measured / 0.2)


@pytest.mark.parametrize(
    "args, words",
    [
        (["--engine", "liggghts", "--charge", "sag"], "--charge sag: not run by --engine liggghts"),
        (["--engine", "liggghts", "--threads", "2"], "--threads: not run by --engine liggghts"),
        (["--engine", "liggghts", "--ranks", "0"], "--ranks 0: must be an integer in [1, 256]"),
        (["--engine", "liggghts", "--length", "short"], "--length 'short': must be 'full' or a length in metres"),
        (["--engine", "liggghts", "--length", "-1"], "--length -1: must be 'full' or a length in [0.05, 100] m"),
        (["--engine", "liggghts", "--length", "full", "--balls", "10"], "--balls with --length: give --fill"),
        (["--ranks", "2"], "--ranks: an option of --engine liggghts"),
        (["--engine", "lammps"], "invalid choice: 'lammps'"),
    ],
)
def test_bad_input_is_one_line_and_exit_2_and_no_folder(tmp_path, args, words):
    out = tmp_path / "mill"
    res = run_cli("mill", "liner-panel", *args, "--revolutions", "1", "--out", str(out), timeout=120)
    assert res.returncode == 2, res.stderr
    lines = res.stderr.strip().splitlines()
    assert len(lines) == 1 and words in lines[0], res.stderr
    assert not list(tmp_path.iterdir())


def test_without_liggghts_one_line_says_how_to_install_it(tmp_path, monkeypatch):
    import subprocess
    import sys

    from conftest import ROOT, mpi_env

    out = tmp_path / "mill"
    env = {**mpi_env(), "MILLIMPACT_LIGGGHTS": str(tmp_path / "no-liggghts-here")}
    cmd = [sys.executable, "-m", "millimpact.cli", "mill", "liner-panel", "--engine", "liggghts"]
    res = subprocess.run(
        [*cmd, "--revolutions", "1", "--out", str(out)], capture_output=True, text=True, env=env, cwd=ROOT, timeout=120
    )
    assert res.returncode == 2
    lines = res.stderr.strip().splitlines()
    assert len(lines) == 1 and "apt-get install liggghts" in lines[0], res.stderr
    assert not list(tmp_path.iterdir())


@needs_liggghts
def test_the_command_writes_the_summary_and_the_liggghts_folder(tmp_path):
    """``millimpact mill liner-panel --engine liggghts``, 50 balls for one snapshot interval (1/36
    revolution, 3,320 steps) from rest: exit 0, the printed lines, summary.json's engine, the
    run's cost and its files; the balls have not left the box (LIGGGHTS stops on a lost atom)."""
    import json

    out = tmp_path / "mill"
    args = ["--engine", "liggghts", "--balls", "50", "--warmup", "0", "--revolutions", "0.0277"]
    res = run_cli("mill", "liner-panel", *args, "--out", str(out), "--no-plots", timeout=300)
    assert res.returncode == 0, res.stderr
    assert "steps/s on 1 rank(s)" in res.stdout and "net power" in res.stdout, res.stdout
    summary = json.loads((out / "summary.json").read_text())
    assert summary["engine"] == "liggghts" and summary["charge"]["balls"] == 50
    assert summary["liggghts"]["steps"] == summary["run"]["steps"] == 3320
    assert summary["power"]["ends_share"] is None  # a slice: frictionless ends
    for name in ("mill.in", "params.in", "walls.in", "shell.stl", "particles.data", "torque.txt", "charge.dump"):
        assert (out / "liggghts" / name).is_file(), name
