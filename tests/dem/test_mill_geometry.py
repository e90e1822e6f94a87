"""The mill's profile from a liner description, checked against the liner's own sizes; the
critical speed formula; the fill's ball count (no Yade needed)."""
from __future__ import annotations

import math

import pytest

from millimpact.dem.mill.contact import critical_rpm
from millimpact.dem.mill.geometry import build_profile, lifter_count
from millimpact.dem.mill.setup import MillOptions, lattice_positions, plan_mill
from millimpact.scene.builtin import resolve_scene


@pytest.mark.parametrize("name", ["liner-segment", "liner-panel"])
def test_profile_is_the_liner_round_the_shell(name):
    scene = resolve_scene(name)
    ln = scene.liner
    p = build_profile(ln, scene.ball.radius)
    n = round(2 * math.pi * ln.mill_radius / ln.lifter_spacing)
    assert p.n_lifters == lifter_count(ln) == n
    segs = p.segments
    # closed, counter-clockwise (positive shoelace area)
    for a, b in zip(segs, segs[1:] + segs[:1]):
        assert math.dist(a.end, b.start) < 1e-12
    assert sum(s.start[0] * s.end[1] - s.end[0] * s.start[1] for s in segs) > 0
    tops = [s for s in segs if s.place == "lifter_top"]
    assert len(tops) == n and len([s for s in segs if s.place == "lifter_face"]) == 2 * n
    for s in tops:
        # a top's corners lie at the lifter's height over the shell and its top width apart
        corner = math.hypot(ln.mill_radius - ln.lifter_height, ln.lifter_top_width / 2)
        assert math.hypot(*s.start) == pytest.approx(corner, rel=1e-12)
        assert s.length == pytest.approx(ln.lifter_top_width, rel=1e-12)
    # faces are inclined lifter_face_angle from the lifter's centre line (the radius at its centre)
    k = 3
    th = p.lifter_angle(k)
    face = [s for s in segs if s.place == "lifter_face" and s.lifter == k][1]       # the leading face
    d = (face.end[0] - face.start[0], face.end[1] - face.start[1])
    along = d[0] * math.cos(th) + d[1] * math.sin(th)
    across = -d[0] * math.sin(th) + d[1] * math.cos(th)
    assert math.degrees(math.atan2(across, along)) == pytest.approx(ln.lifter_face_angle, abs=1e-9)
    # open area: the circle less n trapezoids (top + base) h / 2, to the sliver between each foot's
    # chord and the circle (< base^3 / (12 R) per lifter)
    trapezoid = 0.5 * (ln.lifter_top_width + ln.lifter_base_width) * ln.lifter_height
    sliver = ln.lifter_base_width**3 / (12 * ln.mill_radius)
    assert abs(p.open_area() - (math.pi * ln.mill_radius**2 - n * trapezoid)) < n * sliver + 1e-3
    # the arc position: zero on a lifter's centre line, +R pi / n half way to the next lifter
    assert p.arc_position(math.cos(th), math.sin(th)) == pytest.approx(0.0, abs=1e-12)
    half = th + math.pi / n * 0.999
    assert p.arc_position(math.cos(half), math.sin(half)) == pytest.approx(ln.mill_radius * math.pi / n * 0.999)


def test_critical_speed_is_the_textbook_formula():
    # n_c = 42.3 / sqrt(D) rpm (D in m), e.g. Napier-Munn et al. 1996
    for d in (1.0, 4.0, 11.0):
        assert critical_rpm(d) == pytest.approx(42.3 / math.sqrt(d), rel=1e-3)


def test_fill_gives_the_bed_volume():
    scene = resolve_scene("liner-panel")
    s = plan_mill(scene, MillOptions(revolutions=1, fill=0.05, restitution=0.6))
    # N (4/3 pi r^3) / (1 - 0.4) = J A L: the bed's volume is the fill of the slice's open volume
    bed = s.n_balls * 4 / 3 * math.pi * s.ball_radius**3 / 0.6
    assert bed / (s.profile.open_area() * s.thickness) == pytest.approx(0.05, rel=2e-3)


def test_starting_lattice_does_not_overlap():
    scene = resolve_scene("liner-panel")
    p = build_profile(scene.liner, scene.ball.radius)
    r = scene.ball.radius
    pts = lattice_positions(p, r, 4 * r, 300)
    for i, a in enumerate(pts):
        assert r <= a[2] <= 4 * r - r
        assert math.hypot(a[0], a[1]) < p.radius - p.lifter_height - r
        for b in pts[i + 1:]:
            assert math.dist(a, b) > 2 * r
