"""Interrupting a study (issue 18): Ctrl-C or SIGTERM during `--jobs 2` stops every worker, exits
130 / 143 with one line saying how many cases are done, and a rerun completes the rest."""
from __future__ import annotations

import signal
import subprocess
import sys
import time

import pytest

from conftest import ROOT, default_sigint, mpi_env

# 3 ms per case: ~10 s each, so the signal (2 s after the workers start) lands while they compute
ARGS = ["study", "velocity", "--end", "3e-3", "--jobs", "2", "--no-case-figures", "--method", "traditional", "-q"]


def _children(pid: int) -> list[int]:
    out = subprocess.run(["ps", "-o", "pid=", "--ppid", str(pid)], capture_output=True, text=True).stdout
    return [int(x) for x in out.split()]


@pytest.mark.parametrize("sig, code", [(signal.SIGINT, 130), (signal.SIGTERM, 143)])
def test_study_interrupt_stops_workers_and_rerun_finishes(tmp_path, sig, code):
    out = tmp_path / "study"
    p = subprocess.Popen([sys.executable, "-m", "millimpact.cli", *ARGS, "--out", str(out)], cwd=ROOT, env=mpi_env(),
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, preexec_fn=default_sigint)
    deadline = time.time() + 60
    while time.time() < deadline and len(_children(p.pid)) < 3:   # the resource tracker and two workers are up
        time.sleep(0.5)
    workers = _children(p.pid)
    time.sleep(2.0)
    p.send_signal(sig)
    _, err = p.communicate(timeout=120)
    assert p.returncode == code, err
    last = [l for l in err.splitlines() if l.strip()][-1]
    assert last.startswith("millimpact: interrupted") and "cases done" in last and "rerun" in last, err
    assert "Traceback" not in err
    for _ in range(20):                                         # the resource tracker leaves within a second or two
        alive = [w for w in workers if subprocess.run(["ps", "-p", str(w)], capture_output=True).returncode == 0]
        if not alive:
            break
        time.sleep(0.5)
    assert len(workers) >= 3 and alive == []                    # no orphaned worker
    if sig != signal.SIGINT:
        return  # the rerun's path does not depend on the signal: it runs once, after Ctrl-C
    r = subprocess.run([sys.executable, "-m", "millimpact.cli", *ARGS, "--out", str(out)], cwd=ROOT, env=mpi_env(),
                       capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stderr[-2000:]
    assert (out / "study.md").is_file()


def test_gmsh_import_keeps_ctrl_c():
    """gmsh 4.8's module sets SIGINT to SIG_DFL on import: Ctrl-C would kill a study outright
    (exit -2, no message, orphaned workers). Importing millimpact's geometry puts Python's handler
    back. In a fresh interpreter: pytest's process has its own handlers."""
    code = ("import signal, millimpact.geometry.mesh, gmsh; "
            "print(signal.getsignal(signal.SIGINT) is signal.default_int_handler)")
    r = subprocess.run([sys.executable, "-c", code], cwd=ROOT, env=mpi_env(), capture_output=True, text=True, timeout=120,
                       preexec_fn=default_sigint)
    assert r.stdout.strip() == "True", r.stderr[-2000:]
