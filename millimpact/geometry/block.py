"""The impact model of the lab rig: the ball above a rectangular block (the liner sample), each split into its
contact zone and region, with the symmetry cuts the plan allows; gmsh OpenCASCADE, meshed on rank 0.
"""

from __future__ import annotations

import logging

import gmsh

from ..errors import MeshError
from ..scene.plan import Plan
from ..scene.schema import Scene
from .builders import (
    BALL_CONTACT,
    BALL_SURFACE,
    BLOCK_CONTACT,
    BLOCK_SURFACE,
    SUPPORT,
    MeshSizes,
    ModelInfo,
    check_zone_fits,
    generate_mesh,
    keep_box,
    on_plane,
    run_gmsh,
    size_field,
    split_body,
    symmetry_tag,
    tag_groups,
)

logger = logging.getLogger(__name__)


# --- the impact model ------------------------------------------------------------------------------
def build_impact_model(scene: Scene, plan: Plan, *, generate: bool = True) -> ModelInfo:
    """Build ball + block in the current gmsh model, tag them, and (``generate``) mesh them.

    The ball (radius ``scene.ball.radius``, m) is centred at ``scene.ball_centre(plan.gap)``; the
    block spans ``[-L/2, L/2] x [-b, 0] x [0, H]``. Zones: spheres of ``plan.zone_radius`` around
    the impact point ``scene.impact_point`` (block) and the ball's lowest point
    ``(x_p, plan.gap, z_p)``. Raises :class:`MeshError` in one sentence if gmsh fails.
    """
    sizes = MeshSizes.from_plan(plan)
    sizes.validate()
    blk = scene.block
    x_p, _, z_p = scene.impact_point
    planes = tuple(plan.symmetry_planes)
    for p in planes:
        if p not in ("x", "z"):
            raise MeshError(f"symmetry plane {p!r}: must be 'x' or 'z'")
    contact_block = (x_p, 0.0, z_p)
    contact_ball = (x_p, plan.gap, z_p)
    centre = scene.ball_centre(plan.gap)
    R = scene.ball.radius
    check_zone_fits("block", sizes.zone_radius, min(blk.length, blk.thickness, blk.height))
    clearance = min(0.5 * blk.length - abs(x_p), blk.thickness, z_p, blk.height - z_p)
    if clearance < sizes.zone_radius:
        logger.warning(
            "the contact zone (radius %.3g m) reaches another face of the block (%.3g m from the "
            "impact point): those faces are tagged as usual (support / block surface)",
            sizes.zone_radius,
            clearance,
        )
    check_zone_fits("ball", sizes.ball_zone, R)
    return run_gmsh(lambda: _impact(blk, R, centre, contact_block, contact_ball, planes, sizes, generate))


def _impact(blk, R, centre, contact_block, contact_ball, planes, sizes, generate) -> ModelInfo:
    occ = gmsh.model.occ
    x_p, _, z_p = contact_block
    L, b, H = blk.length, blk.thickness, blk.height
    box = occ.addBox(-0.5 * L, -b, 0.0, L, b, H)
    ball = occ.addSphere(*centre, R)
    scale = max(L, b, H, 2 * R)
    lo, hi = (-L, -b - scale, -scale), (L, centre[1] + 2 * R + scale, H + scale)  # holds both bodies
    block_zone, block_region, v_block = split_body(
        box, contact_block, sizes.zone_radius, keep_box(planes, x_p, z_p, scale, lo, hi), "block"
    )
    ball_zone, ball_region, v_ball = split_body(
        ball, contact_ball, sizes.ball_zone, keep_box(planes, x_p, z_p, scale, lo, hi), "ball"
    )
    occ.synchronize()

    tol = 1e-9 * scale
    support_plane: tuple[int, float] = (2, 0.0) if blk.support == "base" else (1, -b)  # (axis, value m)

    def block_facet(s: int, in_zone: bool) -> int:
        sym = symmetry_tag(s, planes, x_p, z_p, tol)
        if sym:
            return sym
        if on_plane(s, *support_plane, tol):
            return SUPPORT
        if in_zone and on_plane(s, 1, 0.0, tol):
            return BLOCK_CONTACT
        return BLOCK_SURFACE

    def ball_facet(s: int, in_zone: bool) -> int:
        return symmetry_tag(s, planes, x_p, z_p, tol) or (BALL_CONTACT if in_zone else BALL_SURFACE)

    volumes = tag_groups(block_zone, block_region, ball_zone, ball_region, block_facet, ball_facet)
    info = ModelInfo(
        contact_block=contact_block,
        contact_ball=contact_ball,
        volumes=volumes,
        symmetry_planes=planes,
        sizes=sizes,
        contact_vertices=(v_block, v_ball),
        block_volumes=tuple(block_zone + block_region),
        ball_volumes=tuple(ball_zone + ball_region),
    )
    size_field([v_block, v_ball], sizes, ball=(centre, R))
    if generate:
        info = generate_mesh(info)
    return info
