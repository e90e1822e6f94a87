"""The mesh contract (meshes/README.md): `millimpact mesh` writes a .msh with the physical groups,
load_msh reads it back identically, and a mesh missing a group is refused naming it."""
from __future__ import annotations

import numpy as np
import pytest
from mpi4py import MPI

from conftest import run_cli
from millimpact.errors import MeshError
from millimpact.geometry.builders import CELL_TAG_NAMES, gmsh_session
from millimpact.geometry.mesh import load_msh

COARSE = ["--set", "model.h_contact=6e-4", "--set", "model.h_far=0.012"]


def test_exported_mesh_loads_with_every_group(tmp_path):
    r = run_cli("mesh", *COARSE, "--out", str(tmp_path))
    assert r.returncode == 0, r.stderr
    mesh, cells, facets = load_msh(tmp_path / "mesh.msh", MPI.COMM_WORLD)
    counts = {t: int((cells.values == t).sum()) for t in CELL_TAG_NAMES}
    assert all(n > 0 for n in counts.values())
    # the same element count as the report of the command that wrote it
    assert f"{mesh.topology.index_map(3).size_global}" in r.stdout.replace(",", "")


def test_mesh_without_a_group_is_refused(tmp_path):
    import gmsh

    path = tmp_path / "box.msh"
    with gmsh_session("contract-test"):
        gmsh.model.occ.addBox(0, 0, 0, 1, 1, 1)
        gmsh.model.occ.synchronize()
        gmsh.model.addPhysicalGroup(3, [1], 3)       # only the block zone
        gmsh.model.mesh.generate(3)
        gmsh.write(str(path))
    with pytest.raises(MeshError, match=r"missing physical cell group 1 \(ball_zone\)"):
        load_msh(path, MPI.COMM_WORLD)
