"""How big a scene's mesh will be, from its plan, before meshing: vertices, edges, DOFs.

The mesh follows the size field of :mod:`millimpact.geometry.builders` (h_contact within
fine_radius of the contact points, linear growth to h_far over
:func:`millimpact.scene.plan.size_growth_distance`; a small ball's own far size h_ball inside it;
on a liner's bolt holes pi d / 16 growing to h_far one diameter away from their edges: a tube
about each hole here). A tetrahedral mesh of local
size h(x) has about ``int dV / (c h^3)`` vertices; the number of edges is about
:data:`EDGES_PER_VERTEX` times the vertices, so the DOFs are 3 V (P1) and 3 (V + E) (P2).

The constants were fitted to gmsh meshes of the liner panel, the liner segment and the rig
(``benchmarks/panel_mesh_count.py``; docs/scenes.md, "liner-panel"): the estimate is within
~15 % of the measured counts there. It is an estimate for sizing and memory, not a mesh.
"""

from __future__ import annotations

import math
from typing import NamedTuple

from .plan import Plan, size_growth_distance, smallest_size
from .schema import Scene

#: vertices per int dV / h^3 of a Delaunay tetrahedral mesh in the bulk, and the boundary's extra
#: vertices, growing with x = h_far / the smallest body size (:func:`millimpact.scene.plan.smallest_size`):
#: V = (VERTICES_PER_UNIT + SURFACE_VERTICES x) int dV / h^3 (fitted, module docstring)
VERTICES_PER_UNIT = 0.621
SURFACE_VERTICES = 1.457
#: edges per vertex: EDGES_PER_VERTEX - SURFACE_EDGES x (6.9 in the bulk, fewer on the boundary; fitted)
EDGES_PER_VERTEX = 6.88
SURFACE_EDGES = 2.275
#: elements around a bolt hole (builders.HOLE_ELEMENTS_AROUND)
HOLE_ELEMENTS_AROUND = 16


class MeshEstimate(NamedTuple):
    """Estimated counts of a scene's mesh (the model's part: a symmetric model is cut)."""

    vertices: int
    edges: int
    volume: float  #: m^3 of the model (both bodies)

    def dofs(self, degree: int) -> int:
        """Displacement DOFs of the vector Lagrange space of ``degree`` (1 or 2)."""
        return 3 * self.vertices if degree == 1 else 3 * (self.vertices + self.edges)


def body_volume(scene: Scene) -> float:
    """Volume (m^3) of the full struck body: the block, or the liner's plate (curved: an annular
    sector), lifters (prisms of the trapezoid section) less the bolt holes."""
    if scene.liner is None:
        b = scene.block
        return b.length * b.thickness * b.height
    ln = scene.liner
    R, t, w, L = ln.mill_radius, ln.thickness, ln.width, ln.length
    plate = L * w * t if R == 0 else L * (w / R) * 0.5 * ((R + t) ** 2 - R**2)
    lifters = ln.n_lifters * L * 0.5 * (ln.lifter_base_width + ln.lifter_top_width) * ln.lifter_height
    holes = len(ln.bolt_holes()) * math.pi * 0.25 * ln.bolt_hole_diameter**2 * t
    return plate + lifters - holes


def _graded(h0: float, h1: float, r0: float, r1: float, weight, n: int = 400) -> float:
    """int_0^r1 weight(r) (1/h(r)^3 - 1/h1^3) dr for h = h0 below r0, linear to h1 at r1 (midpoint rule)."""
    total, dr = 0.0, r1 / n
    for i in range(n):
        r = (i + 0.5) * dr
        h = h0 if r <= r0 else h0 + (h1 - h0) * (r - r0) / (r1 - r0)
        total += weight(r) * (1.0 / h**3 - 1.0 / h1**3) * dr
    return total


def estimate_mesh(scene: Scene, plan: Plan) -> MeshEstimate:
    """The plan's mesh of ``scene``, estimated (module docstring): counts of the model (a half or
    quarter model holds that share of the bodies)."""
    share = 0.5 ** len(plan.symmetry_planes)
    ball_volume = 4.0 / 3.0 * math.pi * scene.ball.radius**3
    volume = share * (body_volume(scene) + ball_volume)
    h_far = plan.h_far
    small = plan.h_ball > 0
    r1 = plan.fine_radius + size_growth_distance(plan.h_contact, h_far, plan.zone_radius, small)
    if plan.h_ball > 0:
        # a small ball: the body (half a sphere about the contact) grows to h_far, the ball to h_ball
        h_b = plan.h_ball
        integral = share * (body_volume(scene) / h_far**3 + ball_volume / h_b**3)
        integral += share * _graded(plan.h_contact, h_far, plan.fine_radius, r1, lambda r: 2.0 * math.pi * r * r)
        r1_b = plan.fine_radius + size_growth_distance(plan.h_contact, h_b, plan.zone_radius, small)
        integral += share * _graded(plan.h_contact, h_b, plan.fine_radius, r1_b, lambda r: 2.0 * math.pi * r * r)
    else:
        integral = volume / h_far**3
        # about the contact point each body holds about half of a sphere of radius r (both: all of it)
        integral += share * _graded(plan.h_contact, h_far, plan.fine_radius, r1, lambda r: 4.0 * math.pi * r * r)
    ln = scene.liner
    if ln is not None and ln.bolt_holes():
        d = ln.bolt_hole_diameter
        h_hole = min(h_far, math.pi * d / HOLE_ELEMENTS_AROUND)
        kept = sum(1 for x, _ in ln.bolt_holes() if "x" not in plan.symmetry_planes or x >= plan.impact_point[0])
        # a tube about each hole, through the plate: the size grows from h_hole on the wall to h_far one d away
        integral += kept * _graded(h_hole, h_far, 0.0, d, lambda r: 2.0 * math.pi * (0.5 * d + r) * ln.thickness)
    # the fit's range: x <= 0.8 (a small ball: the block's far size against its side)
    x = min(h_far / (smallest_size(scene) if plan.h_ball == 0 else 4.0 * h_far), 1.0)
    vertices = (VERTICES_PER_UNIT + SURFACE_VERTICES * x) * integral
    return MeshEstimate(int(round(vertices)), int(round((EDGES_PER_VERTEX - SURFACE_EDGES * x) * vertices)), volume)
