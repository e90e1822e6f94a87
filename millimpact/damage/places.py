"""A bin's place on the liner scene: the scene's impact moved to the lifter face, the lifter top or
the plate at the bin's arc position (``liner.impact_place`` / ``impact_arc``, :class:`millimpact.scene.schema.Liner`).

Arc positions follow impacts.csv (:mod:`millimpact.dem.impacts`): from the centre line of the
nearest lifter, positive towards its leading face, which is taken to be the scene's struck face
(``liner.impact_face``). So:

- ``lifter_face``: arc >= 0 strikes the scene's face, arc < 0 the other face of the lifter; the
  height on the face follows from the arc position along the inclined face, f = (b/2 - |s|) /
  (b/2 - t/2) (b the base and t the top width), and is the scene's ``impact_height`` when the
  face is radial (the arc position does not fix the height then);
- ``lifter_top``: the arc position across the top;
- ``plate``: the arc position along the plate.

A place the scene cannot hold (the ball would touch the plate beside a low face impact, or a
lifter beside a plate impact near its foot, or the arc lies off the top's edge) is moved to the
nearest position that it can, in steps of STEP_FRACTION of the ball radius, and the move is
reported (``extrapolated``); if no position is found the bin is refused with the scene's reason.
With a ``margin`` the position also keeps that distance from the place's free edges along the
surface (the room a bin's contact needs: :mod:`millimpact.damage.edges`).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

from ..errors import SceneError
from ..scene.schema import Impact as SceneImpact
from ..scene.schema import Liner, Scene

#: the step (a fraction of the ball radius) by which a place the scene cannot hold is moved
STEP_FRACTION = 0.05
#: the face heights (fractions of the lifter height) a face impact is kept within
FACE_HEIGHT_RANGE = (0.05, 0.95)
#: a plate impact is kept this many plate thicknesses inside the segment's side edge (beyond it the
#: impact is placed there: the plate's response away from the lifter is taken as the same)
PLATE_EDGE_MARGIN = 1.0
#: a top impact is kept this fraction of the half top width inside its edge
TOP_EDGE_MARGIN = 0.1


@dataclass(frozen=True)
class PlacedScene:
    """The liner scene with its impact at a bin's place (a normal unit velocity: the table sets
    the speed and angle), the position used and what was changed."""

    scene: Scene | None
    place: str
    arc_m: float  #: the arc position asked (m)
    arc_used_m: float  #: the arc position of the scene's impact (m)
    note: str = ""  #: why the position was moved ("" if not)
    refused: str = ""  #: why the bin cannot be computed ("" if it can)


def liner_of(scene: Scene) -> Liner:
    """The liner of a liner scene: the damage map's places are a liner's (the command refuses a
    block scene before any bin)."""
    if scene.liner is None:
        raise SceneError("liner", None, f"scene '{scene.name}' has no liner: the damage map needs a liner scene")
    return scene.liner


def _with_place(base: Scene, place: str, arc: float, face: str, height: float) -> Scene:
    ln = dataclasses.replace(
        liner_of(base), impact_place=place, impact_arc=float(arc), impact_face=face, impact_height=float(height)
    )
    # a normal unit velocity into the struck surface (the table gives each case its speed and angle)
    n = ln.impact_site(place, ln.impact_lifter, face, height, ln.impact_x, arc)[1]
    v = (round(-n[0], 15) + 0.0, round(-n[1], 15) + 0.0, round(-n[2], 15) + 0.0)
    return dataclasses.replace(base, liner=ln, impact=SceneImpact(velocity=v, point=None, gap=base.impact.gap))


def place_scene(base: Scene, place: str, arc: float, margin: float = 0.0) -> PlacedScene:
    """The scene ``base`` (a liner scene) with its impact at ``place`` and arc position ``arc`` (m)
    (module docstring); with ``margin`` (m) at least that far, along the struck surface, from its
    free edges (the contact's room: :mod:`millimpact.damage.edges`)."""
    ln = liner_of(base)
    hb, ht = 0.5 * ln.lifter_base_width, 0.5 * ln.lifter_top_width
    step = STEP_FRACTION * base.ball.radius
    flip = {"+z": "-z", "-z": "+z"}
    if margin >= 0.5 * ln.length - abs(ln.impact_x):
        return PlacedScene(
            None,
            place,
            arc,
            arc,
            refused=f"the segment is {ln.length * 1e3:.4g} mm long "
            f"(liner.length), less than twice the contact's {margin * 1e3:.3g} mm",
        )
    if place == "lifter_face":
        face = ln.impact_face if arc >= 0 else flip[ln.impact_face]
        if abs(hb - ht) > 1e-9 * ln.lifter_height:
            f = (hb - abs(arc)) / (hb - ht)
        else:
            f = ln.impact_height
        lo, hi = FACE_HEIGHT_RANGE
        kept = f"kept inside {FACE_HEIGHT_RANGE}"
        if 1.0 - margin / math.hypot(ln.lifter_height, hb - ht) < hi:
            hi = 1.0 - margin / math.hypot(ln.lifter_height, hb - ht)
            kept = f"the contact's {margin * 1e3:.3g} mm from the top corner"
        if hi < lo:
            return PlacedScene(
                None,
                place,
                arc,
                arc,
                refused=f"the face is shorter than the contact's {margin * 1e3:.3g} mm from its top corner",
            )
        tries = [min(max(f, lo), hi)]
        h_step = step / ln.lifter_height
        tries += [tries[0] + k * h_step for k in range(1, int((hi - tries[0]) / h_step) + 1)]
        tries += [tries[0] - k * h_step for k in range(1, int((tries[0] - lo) / h_step) + 1)]
        reason = ""
        for fh in tries:
            try:
                sc = _with_place(base, place, 0.0, face, fh)
            except SceneError as exc:
                reason = reason or str(exc)
                continue
            s_used = math.copysign(hb - fh * (hb - ht), arc if arc != 0 else 1.0)
            note = (
                ""
                if abs(fh - f) < 1e-12
                else (f"face height {f:.3g} of the lifter height moved to {fh:.3g} ({reason or kept})")
            )
            return PlacedScene(sc, place, arc, s_used, note)
        return PlacedScene(None, place, arc, arc, refused=reason or "no face height holds the ball")
    if place == "lifter_top":
        lim = min((1.0 - TOP_EDGE_MARGIN) * ht, ht - margin)
        if lim < 0:
            return PlacedScene(
                None,
                place,
                arc,
                arc,
                refused=f"the top is {2 * ht * 1e3:.4g} mm wide, narrower than "
                f"twice the contact's {margin * 1e3:.3g} mm",
            )
        a0 = min(max(arc, -lim), lim)
        sign = -1.0 if a0 > 0 else 1.0
        tries = [a0] + [a0 + sign * k * step for k in range(1, int(2 * lim / step) + 1)]
    elif place == "plate":
        # away from the nearest lifter, towards the middle of the plate between lifters
        sign = 1.0 if arc >= 0 else -1.0
        c = ln.lifter_centres()[ln.impact_lifter]
        edge = (ln.width - c if (sign > 0) == (ln.impact_face == "+z") else c) - max(
            PLATE_EDGE_MARGIN * ln.thickness, margin
        )
        a0 = sign * min(abs(arc), edge)  # a segment narrower than the mill's lifter spacing: its far plate
        if abs(a0) < abs(arc):
            sign = -sign  # then move back towards the lifter if needed
        tries = [a0] + [a0 + sign * k * step for k in range(1, int(ln.width / step) + 1)]
    else:
        return PlacedScene(None, place, arc, arc, refused=f"unknown place '{place}'")
    reason = ""
    for a in tries:
        try:
            sc = _with_place(base, place, a, ln.impact_face, ln.impact_height)
        except SceneError as exc:
            reason = reason or str(exc)
            continue
        why = reason or ("off the top edge" if place == "lifter_top" else "beyond the segment's plate")
        note = "" if abs(a - arc) < 1e-12 else f"arc position {arc:.4g} m moved to {a:.4g} m ({why})"
        return PlacedScene(sc, place, arc, a, note)
    return PlacedScene(None, place, arc, arc, refused=reason or "no position on this place holds the ball")
