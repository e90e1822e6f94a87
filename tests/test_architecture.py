"""The package's layers (pyproject.toml [tool.importlinter]): each stage imports only the stages
below it. Checked with import-linter on the package, and shown to bite on a copy with one
deliberate upward import (a contract that cannot fail would prove nothing)."""
from __future__ import annotations

import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
LINT = Path(sys.executable).with_name("lint-imports")

pytestmark = pytest.mark.skipif(not LINT.exists(), reason="import-linter is installed by ./dev install")


def _lint(project: Path) -> subprocess.CompletedProcess:
    env = {"PYTHONPATH": str(project), "PATH": "/usr/bin:/bin"}
    return subprocess.run([str(LINT), "--config", str(project / "pyproject.toml"), "--no-cache"],
                          cwd=project, env=env, capture_output=True, text=True, timeout=300)


def test_layers_contract_is_kept():
    res = _lint(ROOT)
    assert res.returncode == 0, res.stdout + res.stderr
    assert "2 kept, 0 broken" in res.stdout   # the stages' layers and dem's two commands


@pytest.mark.parametrize("module, line, shown", [
    # the scene (a low stage) importing the mesher (a higher one)
    ("scene/schema.py", "from ..geometry import mesh as _upward", "millimpact.scene.schema -> millimpact.geometry.mesh"),
    # one DEM command importing the other (they share only dem/impacts.py and dem/yade.py)
    ("dem/mill/law.py", "from ..export import files as _sideways", "millimpact.dem.mill.law -> millimpact.dem.export.files"),
])
def test_a_forbidden_import_breaks_the_contract(tmp_path, module, line, shown):
    """A copy of the package with one forbidden import is refused, naming it."""
    copy = tmp_path / "project"
    shutil.copytree(ROOT / "millimpact", copy / "millimpact", ignore=shutil.ignore_patterns("__pycache__"))
    shutil.copy(ROOT / "pyproject.toml", copy / "pyproject.toml")
    path = copy / "millimpact" / module
    path.write_text(path.read_text() + f"\n{line}  # noqa\n")
    res = _lint(copy)
    assert res.returncode != 0
    assert shown in res.stdout
