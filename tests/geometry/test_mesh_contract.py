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


def test_gmsh_api_is_not_called_outside_initialize(monkeypatch, tmp_path):
    """gmsh 4.8: an API call before gmsh.initialize() (or after finalize) goes to Msg::Error, which
    can end the process with exit(1) and no message (the silent deaths of CI runs, traced with an
    exit() hook to a gmsh.model.list() probe). A mesh built and a nested session open and close gmsh
    with every API call in between; the outer session alone finalizes."""
    import gmsh

    from millimpact.geometry import builders
    from millimpact.geometry.mesh import create_mesh
    from millimpact.scene.builtin import builtin_scene
    from millimpact.scene.plan import make_plan

    state = {"initialized": False, "outside": [], "finalize": 0}
    real_init, real_fin = gmsh.initialize, gmsh.finalize

    def initialize(*a, **k):
        state["initialized"] = True
        return real_init(*a, **k)

    def finalize():
        state["initialized"] = False
        state["finalize"] += 1
        return real_fin()

    monkeypatch.setattr(gmsh, "initialize", initialize)
    monkeypatch.setattr(gmsh, "finalize", finalize)
    for module, names in ((gmsh.model, ("list", "getCurrent", "add", "remove", "setCurrent")),
                          (gmsh.option, ("getNumber", "setNumber")), (gmsh, ("merge", "write"))):
        for name in names:
            real = getattr(module, name)

            def guarded(*a, _real=real, _name=name, **k):
                if not state["initialized"]:
                    state["outside"].append(_name)
                return _real(*a, **k)

            monkeypatch.setattr(module, name, guarded)

    scene = builtin_scene("paper-rig").with_value("model.h_far", 0.012).with_value("model.h_contact", 6e-4)
    monkeypatch.setenv("MILLIMPACT_MESH_CACHE", str(tmp_path))
    for _ in range(2):                     # meshed, then loaded from the mesh cache
        create_mesh(scene, make_plan(scene), MPI.COMM_SELF)
    with builders.gmsh_session("outer"):
        with builders.gmsh_session("inner"):
            assert state["initialized"]
        assert state["initialized"]        # the inner session did not finalize the outer's gmsh
    assert state["outside"] == [] and not state["initialized"]
    assert state["finalize"] == 3
