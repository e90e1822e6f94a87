"""Shared test helpers: the CLI as a subprocess, and mpirun."""
from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]

# the test process is an MPI singleton too (tests import mpi4py before millimpact): no helper
# daemon, as millimpact/__init__.py sets for its own processes (the reason is there)
os.environ.setdefault("OMPI_MCA_ess_singleton_isolated", "1")
# the suite runs on 2 workers (./dev test) over the machine's cores, and its mpirun tests start 2
# ranks beside the other worker: one BLAS thread a process (a serial run alone takes its cores,
# millimpact/__init__.py), set here so that every process the tests start keeps it
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
# OpenBLAS's kernels for this CPU (OPENBLAS_CORETYPE, millimpact/__init__.py), chosen before numpy
# loads OpenBLAS in this process and kept by every process the tests start
import millimpact  # noqa: E402,F401


def mpi_env() -> dict[str, str]:
    env = dict(os.environ)
    env.update(OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1",
               OMPI_MCA_rmaps_base_oversubscribe="1", MPLBACKEND="Agg")
    return env


def default_sigint() -> None:
    """``preexec_fn`` of a child that must answer Ctrl-C as a user's terminal would: a test run
    started in the background by a shell (``./dev test &``) ignores SIGINT, and a child inherits
    that (Python then installs no KeyboardInterrupt handler)."""
    import signal

    signal.signal(signal.SIGINT, signal.SIG_DFL)


def run_cli(*args: str, np: int = 1, timeout: float = 600) -> subprocess.CompletedProcess:
    """``millimpact ARGS`` (under ``mpirun -n np`` when np > 1), captured."""
    cmd = [sys.executable, "-m", "millimpact.cli", *args]
    if np > 1:
        cmd = ["mpirun", "-n", str(np), *cmd]
    return subprocess.run(cmd, capture_output=True, text=True, env=mpi_env(), cwd=ROOT, timeout=timeout)


def run_mpi_script(code: str, np: int = 2, timeout: float = 600) -> subprocess.CompletedProcess:
    """Run a python snippet under ``mpirun -n np``."""
    if shutil.which("mpirun") is None:
        pytest.skip("mpirun not installed")
    return subprocess.run(["mpirun", "-n", str(np), sys.executable, "-c", code], capture_output=True,
                          text=True, env=mpi_env(), cwd=ROOT, timeout=timeout)


def run_script_here(code: str, capsys) -> str:
    """The serial side of a :func:`run_mpi_script` comparison, in this process (one rank, as the
    suite's other serial runs): the snippet's standard output. Under ``mpirun -n 1`` it paid a
    process start (mpirun, the imports: ~3 s) for the same numbers."""
    capsys.readouterr()
    exec(compile(code, "<serial snippet>", "exec"), {"__name__": "__serial__"})
    return capsys.readouterr().out


def shared_out(tmp_path_factory, name):
    """One folder per study for the whole session: tests/test_demos.py runs the demos' reduced studies
    (the first and last of these cases) into the same folders, so the case cache serves both."""
    return tmp_path_factory.getbasetemp() / "shared-studies" / name


#: the small paper-rig mesh of the reduction tests (h_contact 0.8 mm, h_far 8 mm, zone radius 5 mm;
#: half model): ~1.8k P1 and ~10.6k P2 dofs, its contact candidates (2.9 mm) inside the zone
SMALL_RIG = {"model.h_contact": 0.8e-3, "model.h_far": 8e-3, "model.zone_radius": 5e-3}


@pytest.fixture(scope="session")
def rig_contact_table(tmp_path_factory):
    """The contact table of tests/dem (test_export.py, test_mill_law.py, which built it each):
    paper-rig on :data:`SMALL_RIG`, improved, Coulomb mu = 0.2, speeds 1 and 3 m/s x angles 0 and
    40 deg. Its folder: read it, do not write in it."""
    out = tmp_path_factory.mktemp("rig-table") / "table"
    small = [a for k, v in SMALL_RIG.items() for a in ("--set", f"{k}={v!r}")]
    r = run_cli("table", "paper-rig", "--velocity", "1,3", "--angle", "0,40", *small, "--set", "contact.friction=0.2",
                "--out", str(out), "-q")
    assert r.returncode == 0, r.stderr[-3000:]
    return out


#: the coarse plastic half-space of tests/methods/test_plastic.py and
#: tests/integration/test_plastic_linearisation.py: full P1, h_contact 0.58 mm = a_max / 2, h_far
#: 12 mm, 0.2 ms (contact, ~88 us, and a little rebound), the block's yield stress 1 GPa
PLASTIC_HALFSPACE = ["hertz-halfspace", "--method", "full", "-q", "--set", "model.h_contact=5.8e-4",
                     "--set", "model.h_far=0.012", "--set", "time.end=2.0e-4",
                     "--set", "block.material.yield_stress=1e9"]


@pytest.fixture(scope="session")
def plastic_halfspace_run(tmp_path_factory):
    """The run of :data:`PLASTIC_HALFSPACE` with the default options (plastic linearisation
    "elastic"): its folder. Both modules checked this very run (one with figures, one without)."""
    out = tmp_path_factory.mktemp("plastic-halfspace") / "y1"
    r = run_cli("run", *PLASTIC_HALFSPACE, "--out", str(out))
    assert r.returncode == 0, r.stderr[-3000:]
    return out


def small_rig_scene():
    """paper-rig with :data:`SMALL_RIG`."""
    from millimpact.scene.builtin import builtin_scene

    scene = builtin_scene("paper-rig")
    for key, value in SMALL_RIG.items():
        scene = scene.with_value(key, value)
    return scene


def small_rig_mesh():
    """(scene, plan, mesh data) of :func:`small_rig_scene` (collective)."""
    from mpi4py import MPI

    from millimpact.geometry.mesh import create_mesh
    from millimpact.scene.plan import make_plan

    scene = small_rig_scene()
    plan = make_plan(scene)
    return scene, plan, create_mesh(scene, plan, MPI.COMM_WORLD)
