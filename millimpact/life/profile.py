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
atan((d_top - d_root) / L) for a face of length L; the plate by its mean depth. The new top
corners are where the new faces meet the new top. This is the measured shape of worn SAG lifters:
the leading face's angle grows as the lifter loses height (Yahyaei & Banisi, Minerals Eng. 23
(2010) 1213-1219: 14 to 47 degrees while the height fell from 152 to 58 mm in 4000 h).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from ..dem.mill.geometry import MillProfile, lifter_count, outline_profile
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
            self.mill_radius, self.mill_radius + self.plate_wear, self.n_lifters, self.corners(), ball_radius
        )
        if p is None:
            raise InputError("the worn lifters' feet overlap: the profile cannot be built")
        return p

    def record(self) -> dict:
        """profiles.csv's columns of this profile (mm, degrees)."""
        return {
            "lifter_height_mm": 1e3 * self.height_above_plate,
            "top_width_mm": 1e3 * self.top_width,
            "trailing_face_angle_deg": self.trailing_angle_deg,
            "leading_face_angle_deg": self.leading_angle_deg,
            "plate_thickness_mm": 1e3 * self.plate_left,
            "top_centre_mm": 1e3 * self.top_centre,
        }


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
    """zeta where the line through p and q crosses the height eta."""
    return p[0] + (eta - p[1]) * (q[0] - p[0]) / (q[1] - p[1])


def worn_profile(lp: LifterProfile, depth: dict[str, tuple[np.ndarray, np.ndarray]]) -> LifterProfile:
    """The profile after wear: ``depth[surface] = (positions along the surface from its start in the
    direction of the profile (m), depths there (m))`` for the surfaces ``trailing_face``, ``top``,
    ``leading_face``, ``plate`` (the module docstring)."""
    _, tt, tl, _ = lp.corners()
    h = lp.height
    # the faces' feet on the worn plate (eta = -d_p, the plate's curvature across a foot neglected)
    drop = h + lp.plate_wear
    bt = (tt[0] - drop * math.tan(math.radians(lp.trailing_angle_deg)), -lp.plate_wear)
    bl = (tl[0] + drop * math.tan(math.radians(lp.leading_angle_deg)), -lp.plate_wear)
    top = depth.get("top", (np.zeros(0), np.zeros(0)))[1]
    d_top = max(float(np.mean(top)), 0.0) if top.size else 0.0
    plate = depth.get("plate", (np.zeros(0), np.zeros(0)))[1]
    d_plate = max(float(np.mean(plate)), 0.0) if plate.size else 0.0
    new_h = h - d_top
    # the trailing face runs from its foot up to its top corner, the leading one from its top corner down
    lt = math.dist(bt, tt)
    u, d = depth.get("trailing_face", (np.zeros(0), np.zeros(0)))
    root_t, top_t = _face_fit(u, d, lt)
    ll = math.dist(tl, bl)
    u, d = depth.get("leading_face", (np.zeros(0), np.zeros(0)))
    top_l, root_l = _face_fit(u, d, ll)
    a_t, a_l = math.radians(lp.trailing_angle_deg), math.radians(lp.leading_angle_deg)
    n_t, n_l = (-math.cos(a_t), math.sin(a_t)), (math.cos(a_l), math.sin(a_l))  # outward normals

    def moved(p, n, dist):
        return (p[0] - dist * n[0], p[1] - dist * n[1])

    pt, qt = moved(bt, n_t, root_t), moved(tt, n_t, top_t)
    pl, ql = moved(bl, n_l, root_l), moved(tl, n_l, top_l)
    z_t, z_l = _line_at_height(pt, qt, new_h), _line_at_height(pl, ql, new_h)
    if z_l - z_t < MIN_TOP_WIDTH:
        mid = 0.5 * (z_t + z_l)
        z_t, z_l = mid - 0.5 * MIN_TOP_WIDTH, mid + 0.5 * MIN_TOP_WIDTH
    ang_t = math.degrees(math.atan2(qt[0] - pt[0], qt[1] - pt[1]))
    ang_l = math.degrees(math.atan2(pl[0] - ql[0], ql[1] - pl[1]))
    return replace(
        lp,
        height=new_h,
        top_width=z_l - z_t,
        top_centre=0.5 * (z_t + z_l),
        trailing_angle_deg=ang_t,
        leading_angle_deg=ang_l,
        plate_wear=lp.plate_wear + d_plate,
    )
