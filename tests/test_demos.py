"""The demos run as-is at reduced size (``--small``) and pass their own checks (each demo asserts
its physics: Hertz exponents, the rig's 5 % to Hertz and 1 % energy balance, ...)."""
import subprocess
import sys

import pytest

from conftest import ROOT, mpi_env, shared_out

DEMOS = ["paper_rig.py", "study_velocity.py", "study_radius.py", "study_poisson.py", "study_thickness.py"]


@pytest.mark.parametrize("demo", DEMOS)
def test_demo_runs_at_reduced_size(demo, tmp_path, tmp_path_factory):
    if demo.startswith("study_"):
        # the folder test_study.py uses for the same study: the case cache serves both
        out = shared_out(tmp_path_factory, demo[len("study_"):-len(".py")])
        extra = ["--jobs", "2"]
    else:
        out, extra = tmp_path / "out", []
    args = [sys.executable, str(ROOT / "demos" / demo), "--small", "--out", str(out), *extra]
    r = subprocess.run(args, capture_output=True, text=True, env=mpi_env(), cwd=ROOT, timeout=600)
    assert r.returncode == 0, (r.stdout + r.stderr)[-3000:]
    assert (out / ("summary.json" if demo == "paper_rig.py" else "study.md")).is_file()
