"""The liner-panel scene: it validates, its gauges lie in the liner, its plan reaches >= 1M P2
DOFs (the plan's mesh estimate, :mod:`millimpact.scene.sizing`, without meshing the million), and
the estimate agrees with a coarse gmsh mesh of it.

Tolerances: the estimate's constants were fitted to panel meshes at h_far 50, 25 and 15.6 mm
(within 2 % there); at another size (35 mm) it was 0.1-2 % off: the test allows 10 %.
"""
from __future__ import annotations

import math

import numpy as np
import pytest

from millimpact.errors import SceneError
from millimpact.scene.builtin import builtin_scene
from millimpact.scene.plan import make_plan
from millimpact.scene.sizing import body_volume, estimate_mesh


def test_panel_validates_with_its_sources():
    scene = builtin_scene("liner-panel")
    ln = scene.liner
    assert ln.n_lifters >= 3 and ln.mill_radius == 5.5 and len(ln.bolt_holes()) == 4
    assert 0.9 <= ln.length <= 1.2 and 0.9 <= ln.width <= 1.3          # ~1 m x ~1 m
    assert scene.ball.radius == 0.0625 and scene.impact.speed == pytest.approx(8.0)
    assert scene.contact.friction == 0.2 and scene.target_material.plastic
    # 30 deg off the face normal
    cos = scene.normal_speed / scene.impact.speed
    assert math.degrees(math.acos(cos)) == pytest.approx(30.0)
    assert {g.name for g in scene.gauges} == {"bolt", "root"}
    for source in ("Royston", "Gent", "Lindley", "Unicast", "Reglin"):
        assert source in scene.description
    assert ln.backing == "rubber" and ln.backing_stiffness == pytest.approx(ln.backing_modulus / 0.006)


def test_panel_plan_reaches_a_million_p2_dofs():
    scene = builtin_scene("liner-panel")
    plan = make_plan(scene)
    est = estimate_mesh(scene, plan)
    assert est.dofs(2) >= 1_000_000, est
    # graded: the far size is several times the contact size
    assert plan.h_far > 5 * plan.h_contact
    assert plan.backing_stiffness > 0


def test_liner_segment_plan_is_unchanged_by_the_panel_rule():
    """The far-size rule for liners with gauges leaves liner-segment (no gauges) at smallest / 4."""
    plan = make_plan(builtin_scene("liner-segment"))
    assert plan.h_far == pytest.approx(0.0625 / 4) and plan.backing_stiffness == 0.0


def test_estimate_agrees_with_a_coarse_mesh():
    gmsh = pytest.importorskip("gmsh")
    from millimpact.geometry.builders import MeshSizes, gmsh_session
    from millimpact.geometry.liner import build_liner_model

    scene = (builtin_scene("liner-panel").with_value("model.h_far", 0.04).with_value("model.h_contact", 0.004)
             .with_value("model.zone_radius", 0.022))
    plan = make_plan(scene)
    ln = scene.liner
    with gmsh_session("panel-estimate"):
        build_liner_model(ln, MeshSizes.from_plan(plan), lifter=ln.impact_lifter, face=ln.impact_face,
                          height_fraction=ln.impact_height, x=ln.impact_x, ball_radius=scene.ball.radius,
                          gap=plan.gap, symmetry_planes=plan.symmetry_planes)
        _, _, enodes = gmsh.model.mesh.getElements(3)
    tets = np.concatenate(enodes).reshape(-1, 4)
    edges = np.unique(np.sort(np.vstack([tets[:, [i, j]] for i in range(4) for j in range(i + 1, 4)]), axis=1), axis=0)
    measured = 3 * (len(np.unique(tets)) + len(edges))
    assert estimate_mesh(scene, plan).dofs(2) == pytest.approx(measured, rel=0.10)


def test_panel_volume():
    """The body volume the estimate uses: annular-sector plate + trapezoid lifters - holes (exact)."""
    ln = builtin_scene("liner-panel").liner
    plate = ln.length * ln.width / ln.mill_radius * 0.5 * ((ln.mill_radius + ln.thickness) ** 2 - ln.mill_radius**2)
    lifters = 3 * ln.length * 0.5 * (ln.lifter_base_width + ln.lifter_top_width) * ln.lifter_height
    holes = 4 * math.pi * 0.021**2 * ln.thickness
    assert body_volume(builtin_scene("liner-panel")) == pytest.approx(plate + lifters - holes, rel=1e-12)


@pytest.mark.parametrize("position", [(0.0, 0.05, 0.3), (0.226, -0.1, 0.82)])
def test_gauge_off_the_liner_is_refused(position):
    scene = builtin_scene("liner-panel")
    with pytest.raises(SceneError, match=r"gauges\[0\]\.position"):
        scene.with_value("gauges", [{"name": "off", "position": list(position), "direction": [0, 0, 1]}])


def test_liner_segment_writes_as_before_the_new_fields():
    """A liner without holes and clamped: its TOML (which the study, table and bench cache keys hash)
    names none of the bolt and backing fields; the panel's round-trips them."""
    from millimpact.scene.toml_io import dump_scene, scene_from_dict, scene_to_dict

    text = dump_scene(builtin_scene("liner-segment"))
    assert "bolt" not in text and "backing" not in text
    panel = builtin_scene("liner-panel")
    assert scene_from_dict(scene_to_dict(panel)) == panel
