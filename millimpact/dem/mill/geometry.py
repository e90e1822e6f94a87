"""The cross-section of a mill's liner from a scene's liner description, for a DEM slice of the mill.

The scene's :class:`~millimpact.scene.schema.Liner` describes one segment of the shell liner
(:mod:`millimpact.scene.liner_shape`): the plate's inner face on a circle of radius R =
``mill_radius`` and lifters ``lifter_height`` h high with a ``lifter_top_width`` top and faces
inclined ``lifter_face_angle`` from the lifter's centre line, ``lifter_spacing`` s apart (arc length
on the plate's inner face). Round the whole shell that makes

    n = round(2 pi R / s)

lifters, evenly spaced in angle (2 pi / n apart: the spacing is rounded so that they close the
circle). Plate, bolts and backing under the plate's inner face do not matter to the charge.

The profile is the closed polygon the charge sees, in the mill's cross-section (x, y) with the
mill's axis on z through the origin: walking counter-clockwise (the direction the mill turns), the
plate's inner circle (as chords no more than :func:`plate_chord` long) up to a lifter's trailing
foot, up its trailing face, across its top, down its leading face (the face that lifts the charge
when the mill turns counter-clockwise), and on along the plate. Lifter k's centre line points from
the shell at angle theta_k = 2 pi k / n towards the axis; a face meets the plate where its line
crosses the circle of radius R (the lifter's foot, in :mod:`~millimpact.scene.liner_shape`, lies on
the tangent at theta_k: the two differ by ~ (base/2)^2 / (2 R), under 2 mm for the built-in liners).

Every segment carries its ``place`` (``plate``, ``lifter_face``, ``lifter_top``: the places of
:data:`millimpact.dem.impacts.PLACES`) and a ``part`` number: the plate between two lifters is one
part, each face and each top another, so a ball rolling from one chord of the plate onto the next
does not count as a new impact. A worn lifter's top corners may be cut by chamfers
(:func:`outline_profile`); a chamfer is a segment of its face's part.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

from ...errors import InputError
from ...scene.liner_shape import LinerShape

#: a plate chord's sagitta, at most this fraction of the ball radius: L <= sqrt(8 R r f)
CHORD_SAG_FRACTION = 0.01

Point2 = tuple[float, float]


@dataclass(frozen=True)
class ProfileSegment:
    """One straight segment of the mill's profile (m), its place, the lifter it belongs to (the
    lifter whose centre line is nearest for the plate) and its part number."""

    start: Point2
    end: Point2
    place: str
    lifter: int
    part: int

    @property
    def length(self) -> float:
        return math.dist(self.start, self.end)


@dataclass(frozen=True)
class MillProfile:
    """A mill's liner profile in its cross-section: the shell radius R (plate's inner face, m), the
    number of lifters n, their height (m) and the closed polygon of :class:`ProfileSegment`."""

    radius: float
    n_lifters: int
    lifter_height: float
    segments: tuple[ProfileSegment, ...]

    @property
    def diameter(self) -> float:
        """The mill's inside diameter D = 2 R (m), the D of the critical speed n_c = 42.3 / sqrt(D)."""
        return 2.0 * self.radius

    def lifter_angle(self, k: int) -> float:
        """Angle (rad) of lifter k's centre line, theta_k = 2 pi k / n."""
        return 2.0 * math.pi * k / self.n_lifters

    def arc_position(self, x: float, y: float) -> float:
        """Arc position (m) of the point (x, y) of the liner frame: R times its angle from the nearest
        lifter's centre line, positive towards that lifter's leading face (counter-clockwise)."""
        pitch = 2.0 * math.pi / self.n_lifters
        phi = math.atan2(y, x)
        d = (phi + 0.5 * pitch) % pitch - 0.5 * pitch
        return self.radius * d

    def unit_starts(self) -> tuple[list[float], float]:
        """The surface position (m) where each segment starts, measured along the profile from its
        lifter unit's start (the lifter's trailing foot: trailing face, top, leading face, then the
        plate to the next lifter), and the length of a unit (m). All units are alike."""
        return self._unit_starts

    @functools.cached_property
    def _unit_starts(self) -> tuple[list[float], float]:
        starts, s, part = [], 0.0, None
        for seg in self.segments:
            if seg.part % 4 == 0 and seg.part != part:  # a unit's first segment
                s = 0.0
            part = seg.part
            starts.append(s)
            s += seg.length
        return starts, s

    def surface_position(self, x: float, y: float, part: int) -> float:
        """Surface position (m, :meth:`unit_starts`) of the point (x, y) of the liner frame on the
        segment of ``part`` nearest to it."""
        starts, _ = self.unit_starts()
        best = (math.inf, 0.0)
        for k, seg in enumerate(self.segments):
            if seg.part != part:
                continue
            (ax, ay), (bx, by) = seg.start, seg.end
            L2 = (bx - ax) ** 2 + (by - ay) ** 2
            t = min(1.0, max(0.0, ((x - ax) * (bx - ax) + (y - ay) * (by - ay)) / L2))
            d = math.hypot(ax + t * (bx - ax) - x, ay + t * (by - ay) - y)
            if d < best[0]:
                best = (d, starts[k] + t * math.sqrt(L2))
        return best[1]

    def point_at(self, s: float) -> tuple[float, float]:
        """The point (m) of lifter 0's unit at surface position s (clamped to the unit)."""
        starts, total = self.unit_starts()
        s = min(max(s, 0.0), total)
        n = self.segments_per_unit
        for k in range(n):
            seg = self.segments[k]
            if s <= starts[k] + seg.length or k == n - 1:
                t = min(1.0, (s - starts[k]) / seg.length)
                return (seg.start[0] + t * (seg.end[0] - seg.start[0]), seg.start[1] + t * (seg.end[1] - seg.start[1]))
        raise AssertionError("unreachable")

    def unit_surfaces(self) -> list[list[float]]:
        """[start, end] (m) of the trailing face, top, leading face and plate along a lifter's unit
        (:meth:`unit_starts`)."""
        starts, total = self.unit_starts()
        n = self.segments_per_unit
        ends = [starts[k + 1] for k in range(n - 1) if self.segments[k + 1].part != self.segments[k].part][:3]
        ends.append(total)
        return [[0.0 if k == 0 else ends[k - 1], ends[k]] for k in range(4)]

    @property
    def segments_per_unit(self) -> int:
        return len(self.segments) // self.n_lifters

    def open_area(self) -> float:
        """Area (m^2) inside the profile (the shell's circle less the lifters): the shoelace sum."""
        a = 0.0
        for s in self.segments:
            a += s.start[0] * s.end[1] - s.end[0] * s.start[1]
        return 0.5 * abs(a)


def plate_chord(radius: float, ball_radius: float) -> float:
    """The longest plate chord (m): its sagitta L^2 / (8 R) stays below CHORD_SAG_FRACTION of the
    ball radius, so a ball rolling on the plate feels a circle."""
    return math.sqrt(8.0 * radius * ball_radius * CHORD_SAG_FRACTION)


def lifter_count(liner: LinerShape) -> int:
    """n = round(2 pi R / s): the lifters round the whole shell at the scene's spacing."""
    return max(1, round(2.0 * math.pi * liner.mill_radius / liner.lifter_spacing))


def _foot_on_circle(axis: float, radius: float, top: Point2, foot: Point2) -> Point2:
    """Where the face line from ``top`` through ``foot`` crosses the plate's circle (radius
    ``radius`` about the mill's axis, which lies at (zeta, eta) = (0, axis) in the lifter's local
    frame: zeta across, eta up from the new liner's plate along the lifter's centre line)."""
    # point p(t) = top + t (foot - top); distance from the axis (0, axis) equals radius
    (z0, e0), (z1, e1) = top, foot
    dz, de = z1 - z0, e1 - e0
    a = dz * dz + de * de
    b = 2.0 * (z0 * dz + (e0 - axis) * de)
    c = z0 * z0 + (e0 - axis) ** 2 - radius * radius
    disc = b * b - 4.0 * a * c
    t = (-b + math.sqrt(max(disc, 0.0))) / (2.0 * a)  # the crossing beyond the top (t > 0)
    return z0 + t * dz, e0 + t * de


def build_profile(liner: LinerShape, ball_radius: float) -> MillProfile:
    """The liner's closed profile round the whole mill (see the module docstring), plate chords no
    longer than :func:`plate_chord` for balls of ``ball_radius`` (m)."""
    R = float(liner.mill_radius)
    if not R > 0:
        raise InputError(
            f"liner.mill_radius = {liner.mill_radius!r}: a mill run needs a curved liner "
            "(mill_radius > 0 m, the shell's inner radius)"
        )
    h, ht = liner.lifter_height, 0.5 * liner.lifter_top_width
    hb = 0.5 * liner.lifter_base_width
    corners = ((-hb, 0.0), (-ht, h), (ht, h), (hb, 0.0))
    profile = outline_profile(R, R, lifter_count(liner), corners, ball_radius)
    if profile is None:
        raise InputError(
            f"liner.lifter_spacing = {liner.lifter_spacing!r}: {lifter_count(liner)} lifters round a shell of radius "
            f"{R:g} m overlap (each is {2 * hb:g} m wide at its foot)"
        )
    return profile


def chamfer_ends(corner: Point2, along_face: Point2, along_top: Point2, leg: float) -> tuple[Point2, Point2]:
    """The ends of a chamfer with legs ``leg`` (m) cut at ``corner``: one on the face (towards
    ``along_face``), one on the top (towards ``along_top``)."""

    def towards(q: Point2) -> Point2:
        d = math.dist(corner, q)
        return (corner[0] + leg * (q[0] - corner[0]) / d, corner[1] + leg * (q[1] - corner[1]) / d)

    return towards(along_face), towards(along_top)


def outline_profile(
    axis: float,
    radius: float,
    n: int,
    corners: tuple[Point2, ...],
    ball_radius: float,
    chamfers: tuple[float, float] = (0.0, 0.0),
) -> MillProfile | None:
    """The closed profile of n lifters of one outline round a plate of ``radius`` (m), in the
    lifter's local frame (zeta across, positive leading; eta up from the new plate, the mill's axis
    at (0, ``axis``)): ``corners`` = (a point of the trailing face, the trailing top corner, the
    leading top corner, a point of the leading face); each face runs from its top corner through
    its point to the plate. ``chamfers`` (m): the legs of a cut at the trailing and leading top
    corner, equal along the face and the top (none at 0); a chamfer's segment belongs to its face's
    part. None when the lifters' feet overlap. A worn liner's plate lies deeper than the new one's
    (radius > axis)."""
    R = radius
    h = max(corners[1][1], corners[2][1])
    pitch = 2.0 * math.pi / n
    foot_t = _foot_on_circle(axis, R, corners[1], corners[0])
    foot_l = _foot_on_circle(axis, R, corners[2], corners[3])
    # (point, the part offset of the segment that starts there): 0 trailing face, 1 top, 2 leading face
    outline: list[tuple[Point2, int]] = [(foot_t, 0)]
    if chamfers[0] > 0:
        on_face, on_top = chamfer_ends(corners[1], foot_t, corners[2], chamfers[0])
        outline += [(on_face, 0), (on_top, 1)]
    else:
        outline.append((corners[1], 1))
    if chamfers[1] > 0:
        on_face, on_top = chamfer_ends(corners[2], foot_l, corners[1], chamfers[1])
        outline += [(on_top, 2), (on_face, 2)]
    else:
        outline.append((corners[2], 2))
    outline.append((foot_l, 3))
    half_t = math.atan2(-foot_t[0], axis - foot_t[1])  # angles of the feet from the centre line
    half_l = math.atan2(foot_l[0], axis - foot_l[1])
    if half_t + half_l >= pitch:
        return None
    gap = pitch - half_t - half_l
    n_chords = max(1, math.ceil(R * gap / plate_chord(R, ball_radius)))

    def to_global(k: int, zeta: float, eta: float) -> Point2:
        th = k * pitch
        # centre line up = -e_r(th), across (leading) = e_theta(th)
        er, et = (math.cos(th), math.sin(th)), (-math.sin(th), math.cos(th))
        rho = axis - eta
        return (rho * er[0] + zeta * et[0], rho * er[1] + zeta * et[1])

    segments: list[ProfileSegment] = []
    part = 0
    for k in range(n):
        pts = [to_global(k, z, e) for (z, e), _ in outline]
        for (p, q), (_, off) in zip(zip(pts, pts[1:]), outline):
            segments.append(ProfileSegment(p, q, "lifter_top" if off == 1 else "lifter_face", k, part + off))
        part += 3
        # the plate from this lifter's leading foot to the next lifter's trailing foot
        a0 = k * pitch + half_l
        arc = [a0 + gap * i / n_chords for i in range(n_chords + 1)]
        ring = [pts[-1]] + [(R * math.cos(a), R * math.sin(a)) for a in arc[1:-1]] + [to_global(k + 1, *foot_t)]
        mid = a0 + 0.5 * gap
        for i, (p, q) in enumerate(zip(ring, ring[1:])):
            a_mid = a0 + gap * (i + 0.5) / n_chords
            owner = k if a_mid < mid else (k + 1) % n
            segments.append(ProfileSegment(p, q, "plate", owner, part))
        part += 1
    # the lifters stand h above the new plate, h + (R - axis) above a worn one
    return MillProfile(radius=R, n_lifters=n, lifter_height=h + (R - axis), segments=tuple(segments))
