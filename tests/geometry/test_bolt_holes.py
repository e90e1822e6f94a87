"""Bolt holes and the rubber backing's tags on a liner: the clamped SUPPORT facets are the holes'
walls, the BACKING facets the back face; a liner without them keeps its cache key's parameters.

Small flat liner (the holes' walls are then exact cylinders of height t): the meshed wall is a
polygon inscribed in each circle, so its area lies below pi d t by at most 1 - sin(pi/n)/(pi/n) for
n segments around; the builder puts HOLE_ELEMENTS_AROUND = 16 on each edge circle
(:func:`builders.hole_size`; 0.64 %), but the wall's triangles between the circles are chords of
the cylinder in both directions and span up to ~1.6x that angle (measured: 1.24 % at 16 on the
circles), so the test allows the deficit of n = 10 (1.64 %).
"""
from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
from mpi4py import MPI

from millimpact.errors import SceneError
from millimpact.geometry import builders as geo
from millimpact.geometry.mesh import create_liner_mesh, facet_indices
from millimpact.scene.liner_shape import LinerShape

comm = MPI.COMM_WORLD

#: a flat liner, 2 lifters, 2 holes between them (1 kept in the half model x >= 0)
HOLED = dict(length=0.20, width=0.30, thickness=0.03, n_lifters=2, lifter_height=0.05, lifter_top_width=0.04,
             lifter_face_angle=15.0, lifter_spacing=0.15, mill_radius=0.0, bolt_hole_diameter=0.02,
             bolt_x=(-0.05, 0.05), bolt_arc=(0.15,))
SIZES = geo.MeshSizes(h_contact=4e-3, h_far=1.5e-2, zone_radius=1.2e-2, fine_radius=6e-3)
#: the inscribed polygon's deficit with 10 segments around (module docstring)
POLYGON_DEFICIT = 1.0 - math.sin(math.pi / 10) / (math.pi / 10)


@pytest.fixture(scope="module")
def cache(tmp_path_factory):
    return Path(comm.bcast(str(tmp_path_factory.mktemp("mesh-cache")) if comm.rank == 0 else None, root=0))


def facet_area(md, tag: int) -> float:
    """Global area (m^2) of the facets with ``tag`` (triangles of the P1 geometry)."""
    mesh = md.mesh
    fdim = mesh.topology.dim - 1
    mesh.topology.create_connectivity(fdim, 0)
    f2v = mesh.topology.connectivity(fdim, 0)
    n_owned = mesh.topology.index_map(fdim).size_local
    # vertex -> geometry node: the P1 geometry's nodes are the vertices (cell dofmaps agree)
    mesh.topology.create_connectivity(mesh.topology.dim, 0)
    c2v = mesh.topology.connectivity(mesh.topology.dim, 0)
    gdofs = mesh.geometry.dofmap
    v2g = np.empty(mesh.topology.index_map(0).size_local + mesh.topology.index_map(0).num_ghosts, dtype=np.int64)
    for c in range(mesh.topology.index_map(mesh.topology.dim).size_local):
        v2g[c2v.links(c)] = gdofs.links(c)
    area = 0.0
    for f in facet_indices(md, tag):
        if f >= n_owned:
            continue
        p = mesh.geometry.x[v2g[f2v.links(f)]]
        area += 0.5 * np.linalg.norm(np.cross(p[1] - p[0], p[2] - p[0]))
    return comm.allreduce(area, op=MPI.SUM)


@pytest.mark.parametrize("backing", ["rubber", "clamped"])
def test_support_is_the_holes_walls(cache, backing):
    liner = LinerShape(**HOLED, backing=backing)
    liner.validate_shape()
    md = create_liner_mesh(liner, SIZES, comm, cache_dir=cache, lifter=0, face="+z", height_fraction=0.6,
                           ball_radius=0.025, gap=5e-4, symmetry_planes=("x",))
    walls = math.pi * liner.bolt_hole_diameter * liner.thickness          # the hole at x = 0.05
    back = 0.5 * liner.length * liner.width - math.pi * liner.bolt_hole_diameter**2 / 4
    support = facet_area(md, geo.SUPPORT)
    if backing == "rubber":
        assert 0.0 <= 1.0 - support / walls <= POLYGON_DEFICIT, support / walls
        # the back face less the holes' polygons (which are a little smaller than the circles)
        assert facet_area(md, geo.BACKING) == pytest.approx(back, abs=POLYGON_DEFICIT * (0.5 * math.pi * 0.02**2))
    else:
        assert geo.BACKING not in md.info.n_facets
        assert 0.0 <= 1.0 - (support - back) / walls <= POLYGON_DEFICIT * 1.01 + 1e-9, (support - back) / walls


def test_liner_without_holes_keys_as_before(cache):
    """The cache key's parameters of a liner without holes and clamped name none of the new fields
    (so liner-segment's cached mesh and its key stay those of before the holes)."""
    liner = LinerShape(length=0.12, width=0.30, thickness=0.04, n_lifters=1, lifter_height=0.05, lifter_top_width=0.04,
                       lifter_face_angle=15.0, mill_radius=1.0)
    create_liner_mesh(liner, SIZES, comm, cache_dir=cache, lifter=0, face="+z", height_fraction=0.7,
                      ball_radius=0.025, gap=5e-4, symmetry_planes=("x",))
    if comm.rank == 0:
        params = [json.loads(p.read_text())["params"] for p in Path(cache).glob("*.json")]
        plain = [p["liner"] for p in params if p["liner"]["thickness"] == 0.04]
        assert len(plain) == 1 and "lifter_spacing" in plain[0]
        assert not set(plain[0]) & set(LinerShape.OPTIONAL_DEFAULTS), plain[0]


@pytest.mark.parametrize("kwargs, field", [
    (dict(bolt_arc=(0.075,)), r"liner\.bolt_arc\[0\]"),                 # under the first lifter's foot
    (dict(bolt_x=(0.095,)), r"liner\.bolt_x\[0\]"),                     # through the plate's end
    (dict(bolt_x=(0.0, 0.01)), r"liner\.bolt_x"),                       # overlapping holes
    (dict(bolt_hole_diameter=0.0), r"liner\.bolt_hole_diameter"),       # positions without a diameter
    (dict(bolt_hole_diameter=0.0, bolt_x=(), bolt_arc=(), backing="rubber"), r"liner\.backing"),
    (dict(backing="glue"), r"liner\.backing"),
])
def test_bad_bolts_are_refused(kwargs, field):
    with pytest.raises(SceneError, match=field):
        LinerShape(**{**HOLED, **kwargs}).validate_shape()


def test_contains():
    liner = LinerShape(**HOLED)
    (x, y, z), e = liner.hole_axis(0.05, 0.15)
    assert not liner.contains((x, y - 0.01, z))                          # in the hole
    assert liner.contains((x + 0.011, y - 0.01, z))                      # beside it, in the plate
    p, n = liner.lifter_face_point(0, "+z", 0.5)
    assert liner.contains(tuple(a - 1e-4 * b for a, b in zip(p, n)))
    assert not liner.contains(tuple(a + 1e-4 * b for a, b in zip(p, n)))
