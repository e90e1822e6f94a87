"""Building the command line imports nothing heavy: ``--help``, ``--version`` and the refusals of
bad input stay fast because the computing stack (numpy, scipy, gmsh, PETSc, DOLFINx, matplotlib,
MPI) is imported only once a command computes (issue 35, row 6).

These tests check which modules a process has loaded, not how long it took (timing is never
asserted: benchmarks measure it)."""
import json
import subprocess
import sys

import pytest

from conftest import ROOT, mpi_env

#: the stack a command imports when it computes: none of it is needed to parse a command line
HEAVY = ("numpy", "scipy", "matplotlib", "gmsh", "petsc4py", "slepc4py", "dolfinx", "ufl", "basix", "mpi4py", "h5py")


def loaded_after(code: str) -> list[str]:
    """The HEAVY modules a fresh Python has loaded after running ``code``."""
    probe = (f"import sys, json\n{code}\n"
             f"print(json.dumps([m for m in {HEAVY!r} if m in sys.modules]))")
    r = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, env=mpi_env(), cwd=ROOT,
                       timeout=120)
    assert r.returncode == 0, r.stderr
    return json.loads(r.stdout.strip().splitlines()[-1])


def test_building_the_parser_imports_no_heavy_module():
    # every command module of EXTRA_COMMANDS is imported for its HELP and add_arguments here
    assert loaded_after("from millimpact.cli import build_parser\nbuild_parser()") == []


def test_version_reads_the_stack_versions_without_importing_it():
    assert loaded_after("from millimpact.cli import version_text\nversion_text()") == []
    # ... and they are the versions the imported modules report
    r = subprocess.run([sys.executable, "-c", "from millimpact.cli import version_text; print(version_text())\n"
                        "import dolfinx, petsc4py, slepc4py, gmsh\n"
                        "print(dolfinx.__version__, petsc4py.__version__, slepc4py.__version__, gmsh.__version__)"],
                       capture_output=True, text=True, env=mpi_env(), cwd=ROOT, timeout=300)
    assert r.returncode == 0, r.stderr
    text, versions = r.stdout.strip().splitlines()
    d, p, s, g = versions.split()
    assert f"DOLFINx {d}" in text and f"PETSc {p}" in text and f"SLEPc {s}" in text and f"gmsh {g}" in text


@pytest.mark.parametrize("argv", [
    ["--help"],
    ["run", "--help"],
    ["table", "--help"],
    ["run", "no-such-scene", "--method", "hertz"],
    ["run", "--method", "hertz", "--set", "ball.radius=abc"],
    ["run", "--method", "teleport"],
    ["hertz", "no-such-scene"],
    ["scene", "show", "no-such-scene"],
    ["mesh", "--set", "ball.nosuch=1"],
    ["study", "no-such-study"],
    ["study", "velocity", "--set", "nosuch=1"],
    ["table", "--velocity", "abc"],
    ["table", "--velocity", "1,2", "--tolerance", "0.7"],
    ["table", "--velocity", "1,2", "--angle", "0,30", "--tolerance", "0.01", "--max-cases", "4"],
])
def test_help_and_refusals_import_no_heavy_module(argv):
    code = ("import sys, contextlib, io\nfrom millimpact.cli import main\n"
            "with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):\n"
            f"    try:\n        code = main({argv!r})\n    except SystemExit as exc:\n        code = exc.code\n"
            f"assert code == (0 if '--help' in {argv!r} else 2), code")
    assert loaded_after(code) == []
