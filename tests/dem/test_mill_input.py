"""Bad input to ``millimpact mill``: one line naming the option and its range, exit 2, no folder."""
from __future__ import annotations

import pytest

from conftest import run_cli


@pytest.mark.parametrize("args, words", [
    (["liner-panel", "--speed-fraction", "0"], "--speed-fraction 0: must lie in (0, 2]"),
    (["liner-panel", "--speed-fraction", "2.1"], "--speed-fraction 2.1: must lie in (0, 2]"),
    (["liner-panel", "--speed-fraction", "-0.5"], "--speed-fraction -0.5"),
    (["liner-panel", "--fill", "0.04"], "--fill 0.04: must lie in [0.05, 0.5]"),
    (["liner-panel", "--fill", "0.55"], "--fill 0.55: must lie in [0.05, 0.5]"),
    (["liner-panel", "--fill", "nan"], "--fill nan: must be a finite number"),
    (["paper-rig"], "scene 'paper-rig': has no liner"),
    (["liner-segment", "--set", "liner.mill_radius=0"], "liner.mill_radius = 0.0: a mill run needs a curved liner"),
    (["liner-panel", "--balls", "10", "--fill", "0.1"], "give one of them"),
    (["liner-panel", "--threads", "0"], "--threads 0: must be an integer in [1, 64]"),
])
def test_bad_input_is_one_line_and_exit_2_and_no_folder(tmp_path, args, words):
    out = tmp_path / "mill"
    res = run_cli("mill", *args, "--revolutions", "1", "--out", str(out), timeout=120)
    assert res.returncode == 2, res.stderr
    lines = res.stderr.strip().splitlines()
    assert len(lines) == 1 and words in lines[0], res.stderr
    assert "Traceback" not in res.stderr
    assert not out.exists() and not list(tmp_path.iterdir())


def test_without_yade_one_line_says_how_to_install_it(tmp_path):
    import subprocess
    import sys

    from conftest import ROOT, mpi_env

    out = tmp_path / "mill"
    env = {**mpi_env(), "MILLIMPACT_YADE": str(tmp_path / "no-yade-here")}
    res = subprocess.run([sys.executable, "-m", "millimpact.cli", "mill", "liner-panel", "--revolutions", "1",
                          "--balls", "10", "--out", str(out)], capture_output=True, text=True, env=env, cwd=ROOT,
                         timeout=120)
    assert res.returncode == 2
    lines = res.stderr.strip().splitlines()
    assert len(lines) == 1 and "apt-get install yade" in lines[0], res.stderr
    assert not list(tmp_path.iterdir())


def test_a_centrifuging_charge_is_said_so():
    """No shoulder or toe (a ring of balls on the shell, --speed-fraction 1.6): said in words, not
    "shoulder None deg"."""
    from millimpact.dem.mill.command import _charge_text

    assert _charge_text({"shoulder_deg": None, "toe_deg": None, "centrifuged_fraction": 0.97}) == \
        "no shoulder or toe: the charge centrifuges (97 % of the balls turn with the shell)"
    assert _charge_text({"shoulder_deg": 41.25, "toe_deg": -35.0}) == "shoulder 41.25 deg, toe -35 deg"


def test_a_killed_yade_is_one_line_saying_the_earlier_folder_is_kept(tmp_path):
    """A Yade killed mid-run (SIGKILL: the out-of-memory killer): one line naming the signal and
    saying the earlier output is kept (before: ~20 lines of Yade's log, nothing on the folder)."""
    import subprocess
    import sys

    from conftest import ROOT, mpi_env

    fake = tmp_path / "yade"
    fake.write_text("#!/bin/sh\nfor i in $(seq 1 30); do echo \"yade log line $i\"; done\nkill -9 $$\n")
    fake.chmod(0o755)
    out = tmp_path / "mill"
    out.mkdir()
    (out / ".millimpact-output").write_text('{"kind": "mill", "files": ["summary.json"]}')
    (out / "summary.json").write_text("{}")
    env = {**mpi_env(), "MILLIMPACT_YADE": str(fake)}
    res = subprocess.run([sys.executable, "-m", "millimpact.cli", "mill", "liner-panel", "--revolutions", "1",
                          "--balls", "10", "--out", str(out)], capture_output=True, text=True, env=env, cwd=ROOT,
                         timeout=300)
    lines = res.stderr.strip().splitlines()
    assert res.returncode == 1 and "yade was killed by SIGKILL" in lines[-1], res.stderr[-2000:]
    assert "yade log line 29" not in res.stderr and "its earlier content is kept" in lines[-1]
    assert sorted(p.name for p in out.iterdir()) == [".millimpact-output", "summary.json"]


def test_a_ctrl_c_during_the_dem_run_stops_yade_and_writes_nothing(tmp_path):
    """Ctrl-C once the DEM run's progress line is out: Yade is stopped, one interrupt line, exit
    130, no folder (a fake Yade that reports 10 % and then computes for a minute)."""
    import signal
    import subprocess
    import sys

    from conftest import ROOT, default_sigint, mpi_env

    fake = tmp_path / "yade"
    fake.write_text("#!/bin/sh\necho 'PROGRESS 0.10 warm-up'\nexec sleep 60\n")
    fake.chmod(0o755)
    out = tmp_path / "mill"
    env = {**mpi_env(), "MILLIMPACT_YADE": str(fake)}
    p = subprocess.Popen([sys.executable, "-m", "millimpact.cli", "mill", "liner-panel", "--revolutions", "1",
                          "--balls", "10", "--out", str(out)], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                         text=True, env=env, cwd=ROOT, preexec_fn=default_sigint)
    for line in p.stderr:
        if "DEM " in line:
            break
    p.send_signal(signal.SIGINT)
    _, err = p.communicate(timeout=60)
    assert p.returncode == 130 and "millimpact: interrupted (SIGINT)" in err, (p.returncode, err[-2000:])
    assert not out.exists()
