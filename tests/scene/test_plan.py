"""The plan carries the scene's derived numbers down the flow (millimpact.scene.plan), so that the
scene itself stops at the methods: the FE model, the contact rows and the recorders never see it.
"""
from __future__ import annotations

import ast
import dataclasses
import math
from pathlib import Path

import numpy as np
import pytest

from millimpact.scene.plan import make_plan
from millimpact.scene.schema import Gauge
from millimpact.scene.builtin import builtin_scene

PACKAGE = Path(__file__).resolve().parents[2] / "millimpact"


def test_plan_carries_the_scenes_numbers():
    rig = builtin_scene("paper-rig")
    p = make_plan(rig)
    assert p.normal_speed == rig.normal_speed == p.hertz.speed
    assert p.impact_point == rig.impact_point and p.contact_normal == rig.contact_normal
    assert p.velocity == tuple(rig.impact.velocity) and p.friction == rig.contact.friction
    assert p.ball == rig.ball and p.ball.mass == rig.ball.mass and p.target == rig.target_material
    assert p.probes.material == rig.target_material and p.probes.gap == p.gap
    assert p.probes.gauge_names == tuple(g.name for g in rig.gauges)
    # what users see is unchanged: the ten modelling choices, not the carried numbers
    assert [row[0] for row in p.table()] == ["symmetry", "h_contact", "h_far", "zone_radius", "fine_radius", "gap",
                                             "dt_contact", "dt_free", "f_cut", "degree"]
    liner = builtin_scene("liner-segment")
    pl = make_plan(liner)
    assert pl.normal_speed == liner.normal_speed and pl.contact_normal == liner.contact_normal
    assert pl.target == liner.liner.material and pl.probes.liner and not p.probes.liner


def test_probes_sit_inside_the_kept_part_of_a_symmetric_model():
    rig = builtin_scene("paper-rig")
    eps = 1e-6 * make_plan(rig).h_contact
    # a gauge on the cut half (x < x_p = 0) of the half model, pointing across the cut plane
    scene = dataclasses.replace(rig, gauges=(Gauge("D", (-0.005, 0.0, 0.03), (-1.0, 0.0, 1.0)),))
    p = make_plan(scene)
    assert p.symmetry_planes == ("x",)
    (d,) = p.probes.gauges
    assert d.point == pytest.approx((0.005, -eps, 0.03), abs=1e-15)      # mirrored, just inside (y < 0)
    assert d.direction == pytest.approx((1.0 / math.sqrt(2.0), 0.0, 1.0 / math.sqrt(2.0)), rel=1e-15)
    x, y, z = p.probes.contact_point                                      # off the cut plane, inside
    assert x == pytest.approx(eps) and y == pytest.approx(-eps) and z == rig.impact_point[2]
    # quarter model (back clamp, mid-height): a gauge below z_p is mirrored above it
    back = dataclasses.replace(rig.with_value("block.support", "back"),
                               gauges=(Gauge("E", (0.004, 0.0, 0.03), (0.0, 0.0, -1.0)),))
    q = make_plan(back)
    assert q.symmetry_planes == ("x", "z")
    (e,) = q.probes.gauges
    assert e.point == pytest.approx((0.004, -eps, 0.05), abs=1e-15) and e.direction == (0.0, 0.0, 1.0)
    # the liner's contact point lies just inside the lifter, along -n
    liner = builtin_scene("liner-segment")
    pl = make_plan(liner)
    inside = np.subtract(pl.probes.contact_point, pl.impact_point)
    assert float(inside @ np.array(pl.contact_normal)) < 0 and np.linalg.norm(inside) < 1e-5 * pl.h_contact


def test_slide_direction_of_an_oblique_impact():
    rig = builtin_scene("paper-rig")
    assert make_plan(rig).probes.slide_direction is None                 # normal impact
    t = np.array(make_plan(rig.with_value("impact.velocity", [1.0, -3.0, 0.0])).probes.slide_direction)
    assert t == pytest.approx([1.0, 0.0, 0.0])
    liner = make_plan(builtin_scene("liner-segment"))
    t = np.array(liner.probes.slide_direction)
    assert np.linalg.norm(t) == pytest.approx(1.0) and abs(t @ np.array(liner.contact_normal)) < 1e-12


def _reads_the_scene(path: Path) -> list[str]:
    """Where a module names the Scene type or reads a ``.scene`` attribute."""
    found = []
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.ImportFrom) and any(a.name == "Scene" for a in node.names):
            found.append(f"{path.name}:{node.lineno} imports Scene")
        elif isinstance(node, ast.Attribute) and node.attr == "scene":
            found.append(f"{path.name}:{node.lineno} reads .scene")
    return found


@pytest.mark.parametrize("module", ["fem/model.py", "fem/contact.py", "fem/probes.py", "results/recorder.py",
                                    "results/reduced_recorder.py", "results/fields.py"])
def test_the_scene_stops_at_the_methods(module):
    """The FE model, its contact rows and the recorders are built from the mesh and the plan."""
    assert _reads_the_scene(PACKAGE / module) == []


def test_the_fe_model_holds_no_scene_or_plan():
    from millimpact.fem.model import FEModel

    names = {f.name for f in dataclasses.fields(FEModel)}
    assert not names & {"scene", "plan"}
    assert {"symmetry_planes", "ball_material", "target_material", "impact_point", "contact_normal"} <= names
