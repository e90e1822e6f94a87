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
# each test worker's MPI processes keep their session directories under a folder of their own: Open
# MPI's singletons share /tmp/ompi.<host>.<uid>/ otherwise, and one finishing removes that folder
# while another, started by the other worker, is creating its own inside it ("A call to mkdir was
# unable to create the desired directory: /tmp/ompi.vm.0/jf.0", MPI_Init aborts): seen once in a
# clean-clone run of the suite on 2 workers. Set in every process that loads this file (the
# controller and each worker: a worker inherits the controller's environment)
import atexit  # noqa: E402
import tempfile  # noqa: E402

_ompi_tmp = tempfile.mkdtemp(prefix="millimpact-tests-ompi-")
os.environ["OMPI_MCA_orte_tmpdir_base"] = _ompi_tmp
atexit.register(shutil.rmtree, _ompi_tmp, ignore_errors=True)
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


def made_once(tmp_path_factory, name: str, make) -> Path:
    """The folder ``name`` that ``make(folder)`` fills, made once for the whole run: the test workers
    share it (it lies in their common temporary root), the first to ask makes it under a lock and
    the others wait for it. For a session fixture's output that the tests read and never write."""
    import fcntl

    root = tmp_path_factory.getbasetemp()
    if os.environ.get("PYTEST_XDIST_WORKER"):
        root = root.parent  # each worker's base is a folder of the run's own
    base = root / "made-once"
    base.mkdir(parents=True, exist_ok=True)
    folder, done = base / name, base / f"{name}.done"
    with open(base / f"{name}.lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        if not done.exists():
            shutil.rmtree(folder, ignore_errors=True)  # a failed attempt's
            make(folder)
            done.touch()
    return folder


@pytest.fixture(scope="session")
def rig_contact_table(tmp_path_factory):
    """The contact table of tests/dem (test_export.py, test_mill_law.py, which built it each):
    paper-rig on :data:`SMALL_RIG`, improved, Coulomb mu = 0.2, speeds 1 and 3 m/s x angles 0 and
    40 deg. Its folder: read it, do not write in it."""

    def make(out):
        small = [a for k, v in SMALL_RIG.items() for a in ("--set", f"{k}={v!r}")]
        r = run_cli("table", "paper-rig", "--velocity", "1,3", "--angle", "0,40", *small, "--set",
                    "contact.friction=0.2", "--out", str(out), "-q")
        assert r.returncode == 0, r.stderr[-3000:]

    return made_once(tmp_path_factory, "rig-table", make)


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

    def make(out):
        r = run_cli("run", *PLASTIC_HALFSPACE, "--out", str(out))
        assert r.returncode == 0, r.stderr[-3000:]

    return made_once(tmp_path_factory, "plastic-halfspace", make)


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


# --- the quick tier ---------------------------------------------------------------------------
#: each test's measured time (setup + call + teardown, seconds, on the 2-core machine with 2
#: workers), written by ``./dev test --store-durations``. ``./dev test --quick`` runs the test
#: modules whose tests together were measured under QUICK_MODULE_S (module fixtures included),
#: that start no mpirun and use none of the session's FE runs below, and every module not measured yet
DURATIONS = Path(__file__).with_name("durations.json")
QUICK_MODULE_S = 10.0
#: the session fixtures above that run finite-element cases (tens of seconds on first use)
SESSION_RUNS = {"rig_contact_table", "plastic_halfspace_run"}


def pytest_addoption(parser):
    parser.addoption("--quick", action="store_true",
                     help=f"the quick tier: test modules measured under {QUICK_MODULE_S:g} s in all "
                          "(tests/durations.json) that start no mpirun")
    parser.addoption("--store-durations", action="store_true",
                     help="write each test's measured time to tests/durations.json")


#: the times of this run's tests, when they are to be stored (``--store-durations``)
_TIMES: dict[str, float] | None = None


def pytest_configure(config):
    global _TIMES
    config.addinivalue_line("markers", "quick: in the quick tier (chosen from tests/durations.json)")
    if config.getoption("--store-durations") and not hasattr(config, "workerinput"):
        _TIMES = {}


def _measured() -> dict[str, float]:
    import json

    try:
        return json.loads(DURATIONS.read_text())
    except (OSError, ValueError):
        return {}


def _module_seconds(measured: dict[str, float]) -> dict[str, float]:
    total: dict[str, float] = {}
    for nodeid, seconds in measured.items():
        module = nodeid.split("::", 1)[0]
        total[module] = total.get(module, 0.0) + seconds
    return total


def pytest_collection_modifyitems(config, items):
    per_module = _module_seconds(_measured())
    quick, rest = [], []
    for item in items:
        module = item.nodeid.split("::", 1)[0]
        fast = per_module.get(module, 0.0) < QUICK_MODULE_S and not SESSION_RUNS & set(item.fixturenames) \
            and item.get_closest_marker("mpi") is None and item.get_closest_marker("slow") is None
        if fast:
            item.add_marker(pytest.mark.quick)
        (quick if fast else rest).append(item)
    if config.getoption("--quick"):
        items[:] = quick
        config.hook.pytest_deselected(items=rest)


def pytest_runtest_logreport(report):
    # on the controller (xdist sends every worker's reports here) and in a plain run alike
    if _TIMES is not None:
        _TIMES[report.nodeid] = _TIMES.get(report.nodeid, 0.0) + report.duration


def pytest_sessionfinish(session, exitstatus):
    if _TIMES is None:
        return
    import json

    measured = _measured()
    measured.update({k: round(v, 2) for k, v in _TIMES.items()})
    tmp = DURATIONS.with_suffix(".json.tmp")
    tmp.write_text(json.dumps(dict(sorted(measured.items())), indent=0) + "\n")
    tmp.replace(DURATIONS)


# --- the workers' schedule --------------------------------------------------------------------
#: a module not measured yet (tests/durations.json) counts as this many seconds
UNMEASURED_MODULE_S = 10.0
#: modules one worker runs together, in collection order: the demos' reduced studies take their
#: cases from the studies test_study.py ran before them (shared_out: a worker's own folder)
SAME_WORKER = {"tests/studies/test_study.py": "studies and demos", "tests/test_demos.py": "studies and demos"}


@pytest.hookimpl(optionalhook=True)  # pytest-xdist's hook: a run without xdist (-p no:xdist) has none
def pytest_xdist_make_scheduler(config, log):
    """Whole test modules to the workers, the longest first (tests/durations.json).

    pytest-xdist's default (``--dist load``) sends the collection in file order in chunks of
    consecutive tests, a quarter of a worker's share at first: a worker whose chunk holds the long
    tests ends minutes after the other, and a module's fixtures are set up on both workers. Whole
    modules, the longest first, each to the worker that asks next (the longest-processing-time
    rule), keep the two workers' ends within about the last module's time, and a module's
    fixtures are made once. The modules of :data:`SAME_WORKER` go as one. Only for the default;
    ``--dist`` set to another mode is kept.
    """
    if config.getvalue("dist") != "load":
        return None
    from xdist.scheduler import LoadFileScheduling

    seconds: dict[str, float] = {}
    for module, s in _module_seconds(_measured()).items():
        unit = SAME_WORKER.get(module, module)
        seconds[unit] = seconds.get(unit, 0.0) + s

    class LongestModuleFirst(LoadFileScheduling):
        def _split_scope(self, nodeid):
            module = super()._split_scope(nodeid)
            return SAME_WORKER.get(module, module)

        def _assign_work_unit(self, node):
            unit = max(self.workqueue, key=lambda m: seconds.get(m, UNMEASURED_MODULE_S))
            self.workqueue.move_to_end(unit, last=False)
            super()._assign_work_unit(node)

    return LongestModuleFirst(config, log)
