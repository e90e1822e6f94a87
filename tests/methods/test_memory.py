"""The up-front memory refusal (:mod:`millimpact.methods.memory`): a run whose estimate does not fit
the available memory ends before meshing with one line naming the estimate, the available memory
and the option to change, and exit status 2; one that fits is not refused."""
from __future__ import annotations

import os
import subprocess
import sys

import pytest

from millimpact.errors import InputError
from millimpact.methods.memory import check_memory, estimate_memory
from millimpact.scene.builtin import builtin_scene
from millimpact.scene.plan import make_plan
from tests.conftest import ROOT, mpi_env


def test_refusal_from_the_cli_is_one_line_exit_2(tmp_path):
    env = {**mpi_env(), "MILLIMPACT_AVAILABLE_MEMORY": "4e9"}    # a 4 GB machine: the 1.2M-DOF P2 run needs ~15 GB
    p = subprocess.run([sys.executable, "-m", "millimpact.cli", "run", "liner-panel", "--method", "improved",
                        "--out", str(tmp_path / "out")], capture_output=True, text=True, env=env, cwd=ROOT,
                       timeout=120)
    assert p.returncode == 2, p.stderr
    lines = p.stderr.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in p.stderr, p.stderr
    assert "estimated peak memory" in lines[0] and "available 4 GB" in lines[0] and "--set model.h_far=" in lines[0]
    assert not (tmp_path / "out" / "summary.json").exists()


def test_the_suggested_far_size_fits():
    scene, method = builtin_scene("liner-panel"), "improved"
    plan = make_plan(scene)
    os.environ["MILLIMPACT_AVAILABLE_MEMORY"] = "4e9"
    try:
        with pytest.raises(InputError) as info:
            check_memory(scene, plan, method)
        h = float(str(info.value).split("--set model.h_far=")[1].split()[0])
        coarse = make_plan(scene.with_value("model.h_far", h))
        assert check_memory(scene.with_value("model.h_far", h), coarse, method) is not None
    finally:
        del os.environ["MILLIMPACT_AVAILABLE_MEMORY"]


def test_per_rank_estimate_falls_with_ranks():
    # one factorization (a panel below the slab path's 600k interior dofs): MUMPS spreads it
    scene = builtin_scene("liner-panel").with_value("model.h_far", 0.03)
    plan = make_plan(scene)
    one, two = estimate_memory(scene, plan, "improved", ranks=1), estimate_memory(scene, plan, "improved", ranks=2)
    assert two.dofs == one.dofs and two.per_rank < one.per_rank
    assert estimate_memory(scene, plan, "full").degree == 1 and one.degree == 2


def test_refusal_under_mpi_is_per_rank_and_said_once(tmp_path):
    """Two ranks on this node: the estimate is per rank, the ranks share the node's memory, rank 0
    decides and says it once, every rank exits 2 (no rank left waiting)."""
    import shutil

    if shutil.which("mpirun") is None:
        pytest.skip("mpirun not installed")
    env = {**mpi_env(), "MILLIMPACT_AVAILABLE_MEMORY": "4e9"}
    p = subprocess.run(["mpirun", "-n", "2", sys.executable, "-m", "millimpact.cli", "run", "liner-panel", "--method",
                        "improved", "--out", str(tmp_path / "out")], capture_output=True, text=True, env=env,
                       cwd=ROOT, timeout=120)
    ours = [line for line in p.stderr.splitlines() if line.startswith("millimpact:")]
    assert p.returncode == 2 and len(ours) == 1, p.stderr
    assert "x 2 rank(s) on this node" in ours[0] and "Traceback" not in p.stderr


def test_a_million_dof_reduction_is_estimated_by_its_slabs():
    """The plan's default panel (~1.2M P2 DOFs) is cut into slabs by itself: its estimate is the
    slab model's, far below one factorization's (asked for with substructures 1); a coarse panel
    keeps one factorization and the old estimate."""
    scene = builtin_scene("liner-panel")
    plan = make_plan(scene)
    slabs = estimate_memory(scene, plan, "improved", ranks=2)
    one = estimate_memory(scene, plan, "improved", {"reduction_block_substructures": "1"}, ranks=2)
    assert slabs.dofs > 1_000_000 and slabs.per_rank < 0.5 * one.per_rank
    coarse_scene = scene.with_value("model.h_far", 0.05)
    coarse = make_plan(coarse_scene)
    assert (estimate_memory(coarse_scene, coarse, "improved").per_rank
            == estimate_memory(coarse_scene, coarse, "improved", {"reduction_block_substructures": "1"}).per_rank)


@pytest.mark.parametrize("variable,value,expect", [
    ("MILLIMPACT_AVAILABLE_MEMORY", "abc", "MILLIMPACT_AVAILABLE_MEMORY='abc': must be a number of bytes > 0"),
    ("MILLIMPACT_AVAILABLE_MEMORY", "-4e9", "MILLIMPACT_AVAILABLE_MEMORY='-4e9': must be a number of bytes > 0"),
    ("MILLIMPACT_MEMORY_CHECK", "maybe", "MILLIMPACT_MEMORY_CHECK='maybe': must be off"),
])
@pytest.mark.parametrize("method", ["improved", "hertz"])
def test_a_bad_memory_variable_is_one_line_exit_2(variable, value, expect, method, tmp_path):
    # issue 35, row 16: a traceback (abc) or silently accepted (maybe) before
    env = {**mpi_env(), variable: value}
    p = subprocess.run([sys.executable, "-m", "millimpact.cli", "run", "--method", method, "-q",
                        "--out", str(tmp_path / "out")], capture_output=True, text=True, env=env, cwd=ROOT,
                       timeout=300)
    assert p.returncode == 2, p.stderr
    lines = p.stderr.strip().splitlines()
    assert len(lines) == 1 and expect in lines[0] and "Traceback" not in p.stderr, p.stderr
    assert not (tmp_path / "out" / "summary.json").exists()
