"""Edge impacts: whether a bin's contact fits on its place, decided for every bin before any bin
is computed.

The contact rows of a run tie each ball node within the candidate radius r_c of the contact axis
to the struck face point below it (:func:`millimpact.fem.contact.create_contact`); a point with no
face below it (past the lifter's top corner, the top's edge, the segment's side or end) stops the
run ("N contact points have no block face below them"). And a contact patch that reaches an edge is
a corner impact, whose response is not the face's. So a bin is computed at a position whose
distance to the struck surface's nearest free (convex) edge, measured along the surface, is at
least its contact margin

    m = max(r_c, a_p) + h_contact

with r_c the method's candidate radius for the bin's band (the band's fastest case: reduced
methods 1.75 a_max, at most zone - 2 h_contact, :func:`millimpact.methods.reduced.reduced_plan`;
the full method min(2.5 a_max, 0.95 zone) or ``-candidate_radius``), a_p Thornton's plastic
contact radius (R delta_max)^(1/2) at the normal speed of the band's fastest case
(:func:`millimpact.theory.thornton.plastic_zone_radius`; Thornton 1997), and one contact element
h_contact so that the outermost point lies inside a face cell. Concave corners (a lifter's foot on
the plate) hold the face below them and are not edges here; the ball's clearance from them is the
scene's check (:mod:`millimpact.damage.places`).

A bin that does not fit is moved inward to the nearest position that does (its place's search,
:func:`millimpact.damage.places.place_scene` with the margin), when the move is at most
MAX_EDGE_SHIFT_SHARE of the place's extent along the profile (a face's slant length, the top's
width, the plate between lifters: :func:`millimpact.damage.accumulate.place_extent`): the
representative then still lies among the impacts a bin of the place stands for (one arc bin spans
the place by default), and the response of a face impact changes little with its position on the
face (the arc position only moves the impact on the same kind of surface: the bins' docstring).
The move is a warning and is kept per bin (``edge_shift_m``, ``contact_margin_m`` in bins.csv) and
per place (damage.csv). A larger move, or a place narrower than two margins (a fast impact on a
narrow top), would compute a different impact than the bin's: the bin is refused with the reason,
and its impacts are counted in ``impacts_left_out_per_rev`` (the sums are then lower bounds).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Sequence

from ..errors import InputError, SceneError
from ..scene.schema import Scene
from ..theory.hertz import effective_modulus
from ..theory.thornton import plastic_zone_radius
from .accumulate import place_extent
from .bins import Bin
from .places import PlacedScene, liner_of, place_scene
from .responses import BinCase, define_bin_cases

#: the largest inward move of a bin's representative, as a share of its place's extent along the
#: profile, that is a clamp; beyond it the bin is refused (module docstring)
MAX_EDGE_SHIFT_SHARE = 0.25
#: contact elements added to the margin: the outermost contact point inside a face cell
EDGE_ELEMENTS = 1.0


def face_slant(liner) -> float:
    """A lifter face's length from the plate to the top corner along the face (m)."""
    return math.hypot(liner.lifter_height, 0.5 * (liner.lifter_base_width - liner.lifter_top_width))


def edge_room(scene: Scene) -> tuple[float, str]:
    """The distance (m) along the struck surface from the scene's impact point to its nearest free
    (convex) edge, and that edge: a lifter face's top corner, the top's edges, the plate's side
    edge of the segment, the segment's ends along the axis (the liner's length)."""
    ln = liner_of(scene)
    axial = (0.5 * ln.length - abs(ln.impact_x), "the segment's end (liner.length)")
    if ln.impact_place == "lifter_face":
        room = ((1.0 - ln.impact_height) * face_slant(ln), "the lifter's top corner")
    elif ln.impact_place == "lifter_top":
        room = (0.5 * ln.lifter_top_width - abs(ln.impact_arc), "the lifter top's edge")
    else:
        c = ln.lifter_centres()[ln.impact_lifter]
        s = c + (1.0 if ln.impact_face == "+z" else -1.0) * ln.impact_arc
        room = (min(s, ln.width - s), "the segment's side edge (liner.width)")
    return min(room, axial)


def contact_margin(bc: BinCase, method: str, options: dict) -> float:
    """The bin's contact margin m (m, module docstring): the room its contact needs from an edge."""
    from ..fem.contact import CANDIDATE_RADIUS_FACTOR
    from ..methods.options import peek
    from ..methods.reduced import REDUCED_METHODS, reduced_plan
    from ..scene.plan import make_plan

    case = bc.case
    assert case is not None  # a refused bin has no contact to fit
    if method in REDUCED_METHODS:
        band = case.band_scene or case.scene
        plan = make_plan(band)
        _, plan, r_c, _ = reduced_plan(band, plan)
    else:
        plan = make_plan(case.scene)
        given = peek(options, "candidate_radius")
        r_c = (
            float(given)
            if given not in (None, "")
            else min(CANDIDATE_RADIUS_FACTOR * plan.hertz.a_max, 0.95 * plan.zone_radius)
        )
    # the band's fastest case (a_p grows with the speed): every bin of a band gets one margin, so a
    # band moved off an edge stays one placed scene, one mesh and one reduction
    sc = case.band_scene or case.scene
    m = sc.ball.mass
    e_star = effective_modulus(sc.ball.material, sc.target_material)
    ys = [
        mat.initial_yield_stress
        for mat in (sc.ball.material, sc.target_material)
        if mat.plastic and mat.initial_yield_stress is not None
    ]
    a_p = plastic_zone_radius(sc.ball.radius, m, sc.normal_speed, e_star, min(ys))[0] if ys else 0.0
    return max(r_c, a_p) + EDGE_ELEMENTS * plan.h_contact


def fit_contacts(
    base: Scene,
    bins: Sequence[Bin],
    placed: dict[int, PlacedScene],
    bcs: list[BinCase],
    method: str,
    options: dict,
    warn: Callable[[str], None],
) -> tuple[dict[int, PlacedScene], list[BinCase], dict[int, dict]]:
    """Check every computable bin's contact against its place's edges and clamp or refuse the ones
    that do not fit (module docstring). Returns the placed scenes, the bin cases (redefined where
    a place moved) and per bin {"contact_margin_m", "edge_room_m", "edge_shift_m"}."""
    info: dict[int, dict] = {}
    need: dict[int, float] = {}
    refuse: dict[int, str] = {}
    for bc in bcs:
        if bc.case is None:
            continue
        try:
            margin = contact_margin(bc, method, options)
        except (InputError, SceneError) as exc:
            refuse[bc.bin.index] = f"its contact does not fit the scene: {exc}"
            continue
        room, _ = edge_room(bc.case.scene)
        info[bc.bin.index] = {"contact_margin_m": margin, "edge_room_m": room, "edge_shift_m": 0.0}
        if room < margin * (1 - 1e-9):
            need[bc.bin.index] = margin
    for i, why in refuse.items():
        warn(f"bin {i} refused: {why}")
    bcs = [BinCase(c.bin, c.placed, None, refuse[c.bin.index]) if c.bin.index in refuse else c for c in bcs]
    if not need:
        return placed, bcs, info
    placed = dict(placed)
    by_index = {b.index: b for b in bins}
    cache: dict[tuple, PlacedScene] = {}
    for idx, margin in need.items():
        b, old = by_index[idx], placed[idx]
        assert old.scene is not None  # only placed bins need room
        room0, edge = edge_room(old.scene)
        key = (b.place, b.arc_m, margin)
        if key not in cache:
            extent = place_extent(base.liner, b.place)
            new = place_scene(base, b.place, b.arc_m, margin=margin)
            shift = edge_room(new.scene)[0] - room0 if new.scene is not None else math.inf
            what = (
                f"its contact (radius + one element: {margin * 1e3:.3g} mm) needs that room from {edge}, "
                f"which is {room0 * 1e3:.3g} mm away"
            )
            if new.scene is None:
                new = dataclasses.replace(
                    old,
                    scene=None,
                    refused=f"edge impact: {what}, and no position on the "
                    f"{b.place.replace('_', ' ')} gives it ({new.refused})",
                )
            elif shift > MAX_EDGE_SHIFT_SHARE * extent:
                new = dataclasses.replace(
                    old,
                    scene=None,
                    refused=(
                        f"edge impact: {what}; the nearest position that gives it is {shift * 1e3:.3g} mm inward, more "
                        f"than {MAX_EDGE_SHIFT_SHARE:g} of the place's extent {extent * 1e3:.3g} mm"
                    ),
                )
            else:
                new = dataclasses.replace(
                    new,
                    note=(
                        f"moved {shift * 1e3:.3g} mm inward from {edge}: {what}" + (f"; {new.note}" if new.note else "")
                    ),
                )
            cache[key] = new
            if new.refused:
                warn(f"{b.place} at arc {b.arc_m:.4g} m refused: {new.refused}")
            else:
                warn(f"{b.place} at arc {b.arc_m:.4g} m clamped: {new.note}")
        placed[idx] = cache[key]
    bcs = define_bin_cases(bins, placed, method, options)
    bcs = [BinCase(c.bin, c.placed, None, refuse[c.bin.index]) if c.bin.index in refuse else c for c in bcs]
    for bc in bcs:
        i = bc.bin.index
        if i not in need:
            continue
        if bc.case is None:
            info.pop(i, None)
            continue
        # the moved bins' bands are the same bins: the same margin; checked, not assumed
        margin = contact_margin(bc, method, options)
        room, edge = edge_room(bc.case.scene)
        info[i] = {"contact_margin_m": margin, "edge_room_m": room, "edge_shift_m": room - info[i]["edge_room_m"]}
        if room < margin * (1 - 1e-9):
            why = (
                f"edge impact: its contact needs {margin * 1e3:.3g} mm from {edge}, {room * 1e3:.3g} mm after the move"
            )
            bcs = [BinCase(c.bin, c.placed, None, why) if c.bin.index == i else c for c in bcs]
            info.pop(i, None)
            warn(f"bin {i} refused: {why}")
    return placed, bcs, info
