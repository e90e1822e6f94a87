"""Liner scenes struck on the lifter top or the plate (``liner.impact_place``), and the damage
map's placement of a bin: geometry against the liner's own construction (the inner circle of
radius mill_radius, the lifter's centre line), refusals, and face scenes unchanged."""
from __future__ import annotations

import dataclasses
import math

import pytest

from millimpact.damage.places import place_scene
from millimpact.errors import SceneError
from millimpact.scene.builtin import builtin_scene
from millimpact.scene.toml_io import dump_scene

SEG = builtin_scene("liner-segment")


def _at(place, arc, scene=SEG):
    ln = dataclasses.replace(scene.liner, impact_place=place, impact_arc=arc)
    n = ln.impact_site(place, ln.impact_lifter, ln.impact_face, ln.impact_height, ln.impact_x, arc)[1]
    return dataclasses.replace(scene, liner=ln, impact=dataclasses.replace(scene.impact, velocity=tuple(-c for c in n)))


def test_plate_point_is_on_the_inner_circle_with_a_radial_normal():
    s = _at("plate", 0.2)
    ln, (x, y, z), n = s.liner, s.impact_point, s.contact_normal
    R, w = ln.mill_radius, ln.width
    # on the inner face: distance R from the mill axis (y, z) = (R, w/2), at arc length 0.2 from the lifter
    assert math.hypot(y - R, z - 0.5 * w) == pytest.approx(R, rel=1e-12)
    assert R * math.atan2(z - 0.5 * w, R - y) == pytest.approx(0.2 + ln.lifter_centres()[0] - 0.5 * w, rel=1e-12)
    # the normal points to the axis
    assert (n[1], n[2]) == pytest.approx(((R - y) / R, (0.5 * w - z) / R), rel=1e-12)
    assert s.normal_speed == pytest.approx(1.0)


def test_top_point_is_on_the_lifter_top():
    s = _at("lifter_top", 0.03)
    ln = s.liner
    # the top is the lifter height above the plate along the centre line (here radial: the lifter is
    # at the plate's middle) and 0.03 across it towards the +z face
    assert s.impact_point == pytest.approx((0.0, ln.lifter_height, ln.lifter_centres()[0] + 0.03), abs=1e-12)
    assert s.contact_normal == pytest.approx((0.0, 1.0, 0.0), abs=1e-12)
    assert ln.contains(tuple(c - 1e-6 * nc for c, nc in zip(s.impact_point, s.contact_normal)))


@pytest.mark.parametrize("place, arc, words", [
    ("plate", 0.05, "under a lifter's foot"),
    ("plate", 0.13, "touch the liner elsewhere"),
    ("plate", 0.3, "must lie on the plate"),
    ("lifter_top", 0.06, "on the lifter top"),
    ("shell", 0.0, "lifter_face, lifter_top, plate"),
])
def test_places_the_scene_cannot_hold_are_refused_naming_the_field(place, arc, words):
    with pytest.raises(SceneError, match=words):
        _at(place, arc) if place != "shell" else dataclasses.replace(SEG, liner=dataclasses.replace(SEG.liner, impact_place=place))


def test_a_face_scene_writes_as_before():
    # the new fields at their defaults are left out: cache keys of tables, studies and meshes unchanged
    text = dump_scene(SEG)
    assert "impact_place" not in text and "impact_arc" not in text
    assert "impact_place = \"plate\"" in dump_scene(_at("plate", 0.2))


def test_a_bin_off_the_scene_is_moved_and_said():
    p = place_scene(SEG, "plate", 0.13)     # the ball would touch the lifter's foot
    assert p.scene is not None and p.arc_used_m > 0.13 and "touch the liner" in p.note
    q = place_scene(SEG, "lifter_face", -0.1)    # the trailing face
    assert q.scene.liner.impact_face == "-z" and q.scene.contact_normal[2] < 0
    assert place_scene(SEG, "lifter_face", 0.1).scene.liner.impact_height == pytest.approx(
        (0.5 * SEG.liner.lifter_base_width - 0.1) / (0.5 * (SEG.liner.lifter_base_width - SEG.liner.lifter_top_width)))


def test_speed_edges_keep_thorntons_restitution_within_the_tolerance():
    from millimpact.damage.bins import speed_edges
    from millimpact.theory.thornton import restitution_thornton

    v_y = 0.12
    edges = speed_edges(0.05, 9.0, v_y, 0.02)
    assert edges[0] == 0.05 and edges[1] == v_y and edges[-1] >= 9.0
    spreads = [restitution_thornton(a, v_y) - restitution_thornton(b, v_y) for a, b in zip(edges[1:], edges[2:])]
    # every bin above V_y at the tolerance (the last one may be narrower), to the bisection's 2^-60
    assert max(spreads) == pytest.approx(0.02, rel=1e-9) and spreads[-1] <= 0.02 * (1 + 1e-9)
    assert all(s == pytest.approx(0.02, rel=1e-9) for s in spreads[:-1])
    # the edges above V_y do not depend on the slowest impact
    assert speed_edges(1.0, 9.0, v_y, 0.02) == edges[1:]
