"""A lifter's profile as it wears: the lifter's outline and the plate, moved by the wear depths.

A lifter is described in its local frame (zeta across, positive towards the leading face, the one
that lifts the charge; eta up from the new plate along its centre line): its top at height h with
corners at zeta_c -/+ w/2, its trailing and leading faces inclined alpha_t and alpha_l from the
centre line (the scene's ``lifter_face_angle`` for a new liner), and the plate worn by d_p below the
new plate (its radius R + d_p about the mill's axis). A worn lifter's height above the plate is
h + d_p.

Wear moves each surface inward along its normal (:func:`worn_profile`): the top by its mean depth;
each face by a depth that varies linearly along it, the least-squares line of its bins' depths
against the position along the face, so a face that wears more near its top turns: its new line
passes through the top corner moved by d_top and the root moved by d_root, and its angle grows by
atan((d_top - d_root) / L) for a face of length L; the plate by its mean depth. This is the
measured shape of worn SAG lifters: the leading face's angle grows as the lifter loses height
(Yahyaei & Banisi, Minerals Eng. 23 (2010) 1213-1219: 14 to 47 degrees while the height fell from
152 to 58 mm in 4000 h).

The top corners: the charge strikes and slides over a lifter's top edges far more than over its
faces (a sharp edge's bin wears 1.4-11 times its face's mean, benchmarks/liner_life_corners.py), so
the bins at a corner (the chamfer's and, on each side, the one next to it) are left out of the
lines and the top's mean: they cut the corner instead. A corner's cut is a chamfer of equal legs c
along the face and the top from the sharp corner where the new lines meet (area c^2 cos(alpha) / 2
for a face at alpha); the two chamfers together take what the lines did not (the lifter's area
lost equals the wear integrated over its bins), shared in proportion to each corner's old chamfer
area plus its bins' wear. Fed to the mill, a chamfer is a segment of its face.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from ..dem.mill.geometry import MillProfile, chamfer_ends, lifter_count, outline_profile
from ..errors import InputError

#: the least top width a worn lifter keeps (m): faces that would meet leave a ridge this wide
MIN_TOP_WIDTH = 0.005


@dataclass(frozen=True)
class LifterProfile:
    """A lifter and its plate (m, degrees; the module docstring's frame)."""

    mill_radius: float  #: the new plate's inner radius R (m)
    n_lifters: int
    height: float  #: h: the top above the new plate
    top_width: float
    top_centre: float  #: zeta_c
    trailing_angle_deg: float
    leading_angle_deg: float
    plate_thickness: float  #: the new plate's thickness (m)
    plate_wear: float = 0.0  #: d_p (m)
    trailing_chamfer: float = 0.0  #: the leg (m) of the cut at the trailing top corner (0: sharp)
    leading_chamfer: float = 0.0  #: the leg (m) of the cut at the leading top corner

    @classmethod
    def from_liner(cls, liner) -> LifterProfile:
        """The new liner of a scene's ``[liner]``."""
        return cls(
            mill_radius=float(liner.mill_radius),
            n_lifters=lifter_count(liner),
            height=float(liner.lifter_height),
            top_width=float(liner.lifter_top_width),
            top_centre=0.0,
            trailing_angle_deg=float(liner.lifter_face_angle),
            leading_angle_deg=float(liner.lifter_face_angle),
            plate_thickness=float(liner.thickness),
        )

    @property
    def height_above_plate(self) -> float:
        return self.height + self.plate_wear

    @property
    def plate_left(self) -> float:
        """The plate's remaining thickness (m)."""
        return self.plate_thickness - self.plate_wear

    def corners(self) -> tuple[tuple[float, float], ...]:
        """(a point of the trailing face at eta = 0, the trailing top corner, the leading top
        corner, a point of the leading face at eta = 0), in the local frame."""
        h, zc, w = self.height, self.top_centre, self.top_width
        tt, tl = (zc - 0.5 * w, h), (zc + 0.5 * w, h)
        bt = (tt[0] - h * math.tan(math.radians(self.trailing_angle_deg)), 0.0)
        bl = (tl[0] + h * math.tan(math.radians(self.leading_angle_deg)), 0.0)
        return bt, tt, tl, bl

    def mill_profile(self, ball_radius: float) -> MillProfile:
        """The mill's profile of this lifter round the shell (InputError when the feet overlap)."""
        p = outline_profile(
            self.mill_radius,
            self.mill_radius + self.plate_wear,
            self.n_lifters,
            self.corners(),
            ball_radius,
            (self.trailing_chamfer, self.leading_chamfer),
        )
        if p is None:
            raise InputError("the worn lifters' feet overlap: the profile cannot be built")
        return p

    def outline(self) -> list[tuple[float, float]]:
        """The lifter's outline (m, local frame) from the trailing face's point at eta = 0 to the
        leading face's, through the chamfers' ends where a corner is cut."""
        bt, tt, tl, bl = self.corners()
        pts = [bt]
        for corner, foot, other, c in ((tt, bt, tl, self.trailing_chamfer), (tl, bl, tt, self.leading_chamfer)):
            if c > 0:
                ends = list(chamfer_ends(corner, foot, other, c))
                pts += ends if corner is tt else ends[::-1]
            else:
                pts.append(corner)
        return pts + [bl]

    def chamfer_area(self) -> float:
        """The steel the two chamfers cut from the sharp outline (m^2 per metre of lifter)."""
        return 0.5 * (
            self.trailing_chamfer**2 * math.cos(math.radians(self.trailing_angle_deg))
            + self.leading_chamfer**2 * math.cos(math.radians(self.leading_angle_deg))
        )

    def record(self) -> dict:
        """profiles.csv's columns of this profile (mm, degrees): the top's width is its flat part,
        between the chamfers."""
        return {
            "lifter_height_mm": 1e3 * self.height_above_plate,
            "top_width_mm": 1e3 * (self.top_width - self.trailing_chamfer - self.leading_chamfer),
            "trailing_face_angle_deg": self.trailing_angle_deg,
            "leading_face_angle_deg": self.leading_angle_deg,
            "plate_thickness_mm": 1e3 * self.plate_left,
            "top_centre_mm": 1e3 * self.top_centre,
            "trailing_chamfer_mm": 1e3 * self.trailing_chamfer,
            "leading_chamfer_mm": 1e3 * self.leading_chamfer,
        }

    @classmethod
    def from_record(cls, p: dict) -> LifterProfile:
        """The outline of a profiles.csv row (mill radius, lifters and plate left at 1 and 0)."""
        ct, cl = 1e-3 * p.get("trailing_chamfer_mm", 0.0), 1e-3 * p.get("leading_chamfer_mm", 0.0)
        return cls(
            1.0,
            1,
            1e-3 * p["lifter_height_mm"],
            1e-3 * p["top_width_mm"] + ct + cl,
            1e-3 * p["top_centre_mm"],
            p["trailing_face_angle_deg"],
            p["leading_face_angle_deg"],
            1.0,
            trailing_chamfer=ct,
            leading_chamfer=cl,
        )


def _area(pts: list[tuple[float, float]]) -> float:
    """A closed polygon's area (m^2, shoelace)."""
    return 0.5 * abs(sum(a[0] * b[1] - b[0] * a[1] for a, b in zip(pts, pts[1:] + pts[:1])))


def _face_fit(u: np.ndarray, d: np.ndarray, length: float) -> tuple[float, float]:
    """(depth at the root u = 0, depth at the top u = length) of the least-squares line d(u); the
    mean at both ends when fewer than two positions hold wear; never below 0."""
    if u.size == 0:
        return 0.0, 0.0
    if u.size < 2 or np.ptp(u) == 0:
        m = float(np.mean(d))
        return max(m, 0.0), max(m, 0.0)
    slope, icept = np.polyfit(u, d, 1)
    return max(float(icept), 0.0), max(float(icept + slope * length), 0.0)


def _line_at_height(p: tuple[float, float], q: tuple[float, float], eta: float) -> float:
    """zeta where the line through p and q crosses the height eta (p's zeta for a line that has
    turned flat: a step far too long for its rates, which only a search for a step's hours meets)."""
    if abs(q[1] - p[1]) < 1e-12:
        return p[0]
    return p[0] + (eta - p[1]) * (q[0] - p[0]) / (q[1] - p[1])


def _bin_width(depth: dict) -> float:
    """The bins' width (m): the least spacing of positions on one surface."""
    gaps = [float(np.min(np.diff(np.sort(u)))) for u, _ in depth.values() if np.size(u) > 1]
    gaps = [g for g in gaps if g > 0]
    return min(gaps) if gaps else 0.0


@dataclass(frozen=True)
class CornerBins:
    """A lifter's bins split at its top corners (:func:`corner_bins`): each face's bins off its
    corner as (position from the face's root for the trailing face, from its sharp top corner for
    the leading face (m), depth), the top's depths off both corners, and the sum of the depths
    on each corner (trailing, leading: the chamfer's bins and the one beside it on each side) and
    how many bins each holds."""

    trailing_face: tuple[np.ndarray, np.ndarray]
    leading_face: tuple[np.ndarray, np.ndarray]
    top: np.ndarray
    corners: tuple[float, float]
    corner_bins: tuple[int, int]


def corner_bins(lp: LifterProfile, depth: dict, w: float, lengths: tuple[float, float]) -> CornerBins:
    """``depth`` (:func:`worn_profile`'s) split at the corners of ``lp``, bins ``w`` wide, its faces
    ``lengths`` (trailing, leading; m) long from the plate to the sharp corner."""
    empty = (np.zeros(0), np.zeros(0))
    (lt, _), ct, cl = lengths, lp.trailing_chamfer, lp.leading_chamfer
    chord_l = 2.0 * cl * math.sin(0.5 * (0.5 * math.pi + math.radians(lp.leading_angle_deg)))
    u, d = (np.asarray(x, float) for x in depth.get("trailing_face", empty))
    at_t = u > lt - ct - w  # the trailing face from its foot, its chamfer beyond lt - ct
    face_t, sum_t = (u[~at_t], d[~at_t]), float(d[at_t].sum())
    u, d = (np.asarray(x, float) for x in depth.get("top", empty))
    u = u + ct  # from the trailing sharp corner
    top_at_t, top_at_l = u < ct + w, (u > lp.top_width - cl - w) & ~(u < ct + w)
    middle = ~(top_at_t | top_at_l)
    top = d[middle] if np.any(middle) else d
    sum_t += float(d[top_at_t].sum())
    sum_l = float(d[top_at_l].sum())
    u, d = (np.asarray(x, float) for x in depth.get("leading_face", empty))
    on_face = u >= chord_l  # the leading face's part starts with its chamfer
    u = np.where(on_face, u - chord_l + cl, 0.0)  # from the leading sharp corner
    at_l = ~on_face | (u < cl + w)
    counts = (
        int(np.count_nonzero(at_t) + np.count_nonzero(top_at_t)),
        int(np.count_nonzero(top_at_l) + np.count_nonzero(at_l)),
    )
    return CornerBins(face_t, (u[~at_l], d[~at_l]), top, (sum_t, sum_l + float(d[at_l].sum())), counts)


def worn_profile(
    lp: LifterProfile, depth: dict[str, tuple[np.ndarray, np.ndarray]], bin_m: float | None = None
) -> LifterProfile:
    """The profile after wear: ``depth[surface] = (positions along the surface from its start in the
    direction of the profile (m), depths there (m))`` for the surfaces ``trailing_face``, ``top``,
    ``leading_face``, ``plate`` (the module docstring), as the mill's profile of ``lp`` runs: a
    chamfer is part of its face. ``bin_m``: the bins' width (default: the positions' spacing)."""
    empty = (np.zeros(0), np.zeros(0))
    w = bin_m or _bin_width(depth)
    _, tt, tl, _ = lp.corners()
    h = lp.height
    a_t, a_l = math.radians(lp.trailing_angle_deg), math.radians(lp.leading_angle_deg)
    # the faces' feet on the worn plate (eta = -d_p, the plate's curvature across a foot neglected)
    drop = h + lp.plate_wear
    bt = (tt[0] - drop * math.tan(a_t), -lp.plate_wear)
    bl = (tl[0] + drop * math.tan(a_l), -lp.plate_wear)
    lt, ll = math.dist(bt, tt), math.dist(tl, bl)
    ct, cl = lp.trailing_chamfer, lp.leading_chamfer
    bins = corner_bins(lp, depth, w, (lt, ll))
    removed = w * sum(float(np.sum(depth.get(k, empty)[1])) for k in ("trailing_face", "top", "leading_face"))
    grown = (w * bins.corners[0], w * bins.corners[1])
    d_top = max(float(np.mean(bins.top)), 0.0) if bins.top.size else 0.0
    plate = depth.get("plate", empty)[1]
    d_plate = max(float(np.mean(plate)), 0.0) if np.size(plate) else 0.0
    root_t, top_t = _face_fit(*bins.trailing_face, lt)
    top_l, root_l = _face_fit(*bins.leading_face, ll)
    n_t, n_l = (-math.cos(a_t), math.sin(a_t)), (math.cos(a_l), math.sin(a_l))  # outward normals

    def moved(p, n, dist):
        return (p[0] - dist * n[0], p[1] - dist * n[1])

    pt, qt = moved(bt, n_t, root_t), moved(tt, n_t, top_t)
    pl, ql = moved(bl, n_l, root_l), moved(tl, n_l, top_l)
    ang_t = math.degrees(math.atan2(qt[0] - pt[0], qt[1] - pt[1]))
    ang_l = math.degrees(math.atan2(pl[0] - ql[0], ql[1] - pl[1]))
    old_area = _area([bt, tt, tl, bl]) - lp.chamfer_area()
    base = -lp.plate_wear
    new_h = h - d_top
    for _ in range(20):  # the chamfers must fit on the top and the faces; else the top falls more
        z_t, z_l = _line_at_height(pt, qt, new_h), _line_at_height(pl, ql, new_h)
        if z_l - z_t < MIN_TOP_WIDTH:
            mid = 0.5 * (z_t + z_l)
            z_t, z_l = mid - 0.5 * MIN_TOP_WIDTH, mid + 0.5 * MIN_TOP_WIDTH
        sharp = [
            (_line_at_height(pt, qt, base), base),
            (z_t, new_h),
            (z_l, new_h),
            (_line_at_height(pl, ql, base), base),
        ]
        cut = _area(sharp) - (old_area - removed)
        share = (0.5 * ct**2 * math.cos(a_t) + grown[0], 0.5 * cl**2 * math.cos(a_l) + grown[1])
        total = sum(share)
        if cut <= 0 or total <= 0:
            legs = (0.0, 0.0)
            break
        # a face turned past 90 degrees (a step far too long) still gives a cut
        cos_t, cos_l = (max(math.cos(math.radians(a)), 1e-6) for a in (ang_t, ang_l))
        legs = (math.sqrt(2 * cut * share[0] / total / cos_t), math.sqrt(2 * cut * share[1] / total / cos_l))
        room = z_l - z_t - MIN_TOP_WIDTH
        if legs[0] + legs[1] <= room:
            break
        # the chamfers would meet: the corners' steel lowers the top instead (area over the top's width)
        fit = max(room, 0.0) / (legs[0] + legs[1])
        new_h -= (cut * (1.0 - fit**2)) / max(z_l - z_t, MIN_TOP_WIDTH)
    if legs[0] + legs[1] > max(z_l - z_t - MIN_TOP_WIDTH, 0.0):  # still too wide after the falls
        fit = max(z_l - z_t - MIN_TOP_WIDTH, 0.0) / (legs[0] + legs[1])
        legs = (legs[0] * fit, legs[1] * fit)
    return replace(
        lp,
        height=new_h,
        top_width=z_l - z_t,
        top_centre=0.5 * (z_t + z_l),
        trailing_angle_deg=ang_t,
        leading_angle_deg=ang_l,
        plate_wear=lp.plate_wear + d_plate,
        trailing_chamfer=legs[0],
        leading_chamfer=legs[1],
    )
