"""The liner model: a shell plate with lifter bars (:class:`millimpact.scene.liner_shape.LinerShape`), its
contact zone on a lifter face, optionally the ball; gmsh OpenCASCADE, meshed on rank 0.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Sequence

import gmsh
import numpy as np

from ..errors import MeshError
from ..scene.liner_shape import LinerShape
from ..scene.schema import Vec3
from .builders import (
    BACKING,
    BALL_CONTACT,
    BALL_SURFACE,
    BLOCK_CONTACT,
    BLOCK_SURFACE,
    SUPPORT,
    SYM_X,
    MeshSizes,
    ModelInfo,
    check_zone_fits,
    generate_mesh,
    keep_box,
    on_plane,
    polygon_face,
    positive_size,
    run_gmsh,
    size_field,
    split_body,
    surface_samples,
    symmetry_tag,
    tag_groups,
    zone_axis,
)

logger = logging.getLogger(__name__)


# --- the liner model -----------------------------------------------------------------------------
def build_liner_model(
    liner: LinerShape,
    sizes: MeshSizes,
    *,
    lifter: int = 0,
    face: str = "+z",
    height_fraction: float = 0.5,
    x: float = 0.0,
    ball_radius: float | None = None,
    gap: float = 0.0,
    symmetry_planes: Sequence[str] = (),
    generate: bool = True,
    place: str = "lifter_face",
    arc: float = 0.0,
) -> ModelInfo:
    """Build a liner segment (tagged as the block) with a contact zone on a lifter face, optionally
    with a ball (radius ``ball_radius``, m) a ``gap`` (m) off the face along its normal, and mesh it.

    The contact point is ``liner.impact_site(place, lifter, face, height_fraction, x, arc)`` (by
    default ``liner.lifter_face_point(lifter, face, height_fraction, x)``; ``place`` ``"lifter_top"``
    or ``"plate"`` puts it on the lifter's top or the plate, ``arc`` m from the lifter's centre line).
    ``symmetry_planes`` may be ``("x",)``: keep ``x >= x`` (the liner is prismatic along x).
    ``SUPPORT`` is the plate's back face (on the mill shell; ``BACKING`` when ``liner.backing`` is
    ``"rubber"``) and the bolt holes' surfaces (:meth:`LinerShape.bolt_holes`). Sizes in m.
    """
    liner.validate_shape()
    sizes.validate()
    planes = tuple(symmetry_planes)
    if any(p != "x" for p in planes):
        raise MeshError(f"symmetry_planes = {planes!r}: a liner allows only ('x',)")
    point, normal = liner.impact_site(place, lifter, face, height_fraction, x, arc)
    check_zone_fits("liner", sizes.zone_radius, min(liner.thickness, liner.lifter_top_width, liner.length))
    ball = None
    if ball_radius is not None:
        positive_size("ball_radius", ball_radius)
        if not (math.isfinite(gap) and gap >= 0):
            raise MeshError(f"gap = {gap!r} m: must be >= 0")
        check_zone_fits("ball", sizes.ball_zone, ball_radius)
        ball = (
            ball_radius,
            tuple(p + (ball_radius + gap) * n for p, n in zip(point, normal)),
            tuple(p + gap * n for p, n in zip(point, normal)),
        )
    return run_gmsh(lambda: _liner(liner, sizes, point, normal, ball, planes, generate))


def _liner(liner: LinerShape, sizes: MeshSizes, point: Vec3, normal: Vec3, ball, planes, generate) -> ModelInfo:
    occ = gmsh.model.occ
    L, w, t, R = liner.length, liner.width, liner.thickness, liner.mill_radius
    x0 = -0.5 * L
    # cross-section in the plane x = x0, then extruded along x
    if R == 0:
        plate = polygon_face([(0.0, -t, 0.0), (0.0, -t, w), (0.0, 0.0, w), (0.0, 0.0, 0.0)], x0)
    else:
        alpha = 0.5 * w / R

        def on(r: float, phi: float) -> tuple[float, float]:
            return R - r * math.cos(phi), 0.5 * w + r * math.sin(phi)

        pts = [on(R + t, -alpha), on(R + t, alpha), on(R, alpha), on(R, -alpha)]
        tags = [occ.addPoint(x0, y, z) for y, z in pts]
        ctr = occ.addPoint(x0, R, 0.5 * w)
        curves = [
            occ.addCircleArc(tags[0], ctr, tags[1]),
            occ.addLine(tags[1], tags[2]),
            occ.addCircleArc(tags[2], ctr, tags[3]),
            occ.addLine(tags[3], tags[0]),
        ]
        plate = occ.addPlaneSurface([occ.addCurveLoop(curves)])
        occ.remove([(0, ctr)])
    sections = [(2, plate)]
    hb, ht, h = 0.5 * liner.lifter_base_width, 0.5 * liner.lifter_top_width, liner.lifter_height
    d = liner.foot_depth
    for c in liner.lifter_centres():
        local = [(-hb, -d), (hb, -d), (hb, 0.0), (ht, h), (-ht, h), (-hb, 0.0)]  # (zeta, eta); foot overlaps the plate
        sections.append((2, polygon_face([(0.0, *liner.lifter_to_global(c, zt, et)) for zt, et in local], x0)))
    if len(sections) > 1:
        sections, _ = occ.fuse(sections[:1], sections[1:])
    vols = []
    for s in sections:
        out = occ.extrude([s], L, 0.0, 0.0)
        vols += [e for e in out if e[0] == 3]
    if len(vols) != 1:
        raise MeshError(f"the liner cross-section did not fuse into one body ({len(vols)} pieces)")
    body = vols[0][1]
    holes = liner.bolt_holes()
    if holes:
        body = _drill(body, liner, holes)
    scale = max(L, w, t + liner.lifter_height, ball[0] * 2 if ball else 0.0)
    lo = (-scale - L, -scale - t - 2 * R, -scale - w)
    hi = (scale + L, scale + liner.lifter_height + 2 * R, scale + 2 * w)
    if ball is not None:
        rb, centre, _ = ball
        sphere = occ.addSphere(*centre, rb)
        overlap, _ = occ.intersect([(3, sphere)], [(3, body)], removeObject=False, removeTool=False)
        common = sum(occ.getMass(*e) for e in overlap if e[0] == 3)
        if overlap:
            occ.remove(overlap, recursive=True)
        if common > 1e-9 * rb**3:
            raise MeshError(
                f"ball_radius = {rb:g} m: the ball overlaps the liner at this contact point "
                "(choose a smaller ball, a larger gap or a point higher on the lifter face)"
            )
    # the zone spheres' poles on the contact normal where OCC's z axis would put one next to the
    # surface (a plate or lifter top, whose normal is ~ y: builders.zone_axis, orient_poles)
    axis = zone_axis(normal)
    zone, region, v_liner = split_body(
        body, point, sizes.zone_radius, keep_box(planes, point[0], 0.0, scale, lo, hi), "liner", axis=axis
    )
    ball_zone: list[int] = []
    ball_region: list[int] = []
    v_ball: int | None = None
    if ball is not None:
        ball_zone, ball_region, v_ball = split_body(
            sphere, ball[2], sizes.ball_zone, keep_box(planes, point[0], 0.0, scale, lo, hi), "ball", axis=axis
        )
    occ.synchronize()
    tol = 1e-9 * scale

    def on_support(s: int) -> bool:
        if R == 0:
            return on_plane(s, 1, -t, tol)
        pts = surface_samples(s)
        r = np.hypot(pts[:, 1] - R, pts[:, 2] - 0.5 * w)
        return bool(np.all(np.abs(r - (R + t)) < tol))

    hole_surfaces: list[int] = []

    def on_hole(s: int) -> bool:
        if not holes or gmsh.model.getType(2, s) != "Cylinder":
            return False
        pts = surface_samples(s)
        r = 0.5 * liner.bolt_hole_diameter
        if any(all(abs(liner.hole_distance(tuple(p), hx, hs) - r) < 1e-6 * scale for p in pts) for hx, hs in holes):
            hole_surfaces.append(s)
            return True
        return False

    def liner_facet(s: int, in_zone: bool) -> int:
        if symmetry_tag(s, planes, point[0], 0.0, tol):
            return SYM_X
        if on_support(s):
            return BACKING if liner.backing == "rubber" else SUPPORT
        if on_hole(s):
            return SUPPORT
        return BLOCK_CONTACT if in_zone else BLOCK_SURFACE

    def ball_facet(s: int, in_zone: bool) -> int:
        return symmetry_tag(s, planes, point[0], 0.0, tol) or (BALL_CONTACT if in_zone else BALL_SURFACE)

    volumes = tag_groups(zone, region, ball_zone, ball_region, liner_facet, ball_facet)
    vertices = [v_liner] + ([v_ball] if v_ball is not None else [])
    info = ModelInfo(
        contact_block=point,
        contact_ball=ball[2] if ball else None,
        volumes=volumes,
        symmetry_planes=planes,
        sizes=sizes,
        contact_vertices=tuple(vertices),
        block_volumes=tuple(zone + region),
        ball_volumes=tuple(ball_zone + ball_region),
    )
    # the holes' edges (and seams) get the hole size: their walls are the clamped support
    hole_curves = sorted({int(c) for s in hole_surfaces for c in gmsh.model.getAdjacencies(2, s)[1]})
    size_field(
        vertices,
        sizes,
        holes=[(c, liner.bolt_hole_diameter) for c in hole_curves],
        ball=(ball[1], ball[0]) if ball else None,
    )
    if generate:
        info = generate_mesh(info)
    return info


def _drill(body: int, liner: LinerShape, holes) -> int:
    """Cut the bolt holes (cylinders of ``liner.bolt_hole_diameter`` along each hole's axis,
    through the plate and a little beyond) out of the liner volume ``body``; returns the new tag."""
    occ = gmsh.model.occ
    t = liner.thickness
    margin = 0.5 * t
    tools = []
    for hx, hs in holes:
        (ax, ay, az), (ex, ey, ez) = liner.hole_axis(hx, hs)
        start = (ax - margin * ex, ay - margin * ey, az - margin * ez)
        span = t + 2 * margin
        tools.append((3, occ.addCylinder(*start, span * ex, span * ey, span * ez, 0.5 * liner.bolt_hole_diameter)))
    out, _ = occ.cut([(3, body)], tools)
    vols = [v for d, v in out if d == 3]
    if len(vols) != 1:
        raise MeshError(f"drilling the bolt holes left {len(vols)} liner pieces (expected one)")
    return vols[0]
