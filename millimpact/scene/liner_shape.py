"""The shape of a liner segment: plate, lifters, and the point and normal of a lifter face.

Pure geometry (no gmsh): the scene validates a liner and places the impact with it, and the
gmsh builder (:mod:`millimpact.geometry.liner`) draws the same shape. All lengths in m, angles in
degrees.

The plate spans ``x in [-length/2, length/2]`` (along the mill axis) and ``y in [-thickness, 0]``
at ``z = width/2``; its inner face ``y = 0`` looks into the mill (``y > 0``). ``n_lifters`` bars
run along x on the inner face, centred ``lifter_spacing`` apart about ``z = width/2``; each is
``lifter_height`` high (from the plate's inner face, on its centre line) with a
``lifter_top_width`` top and faces inclined ``lifter_face_angle`` from the plate normal (base width
``top + 2 height tan(angle)``; a negative angle undercuts the bar). ``mill_radius`` > 0 curves the
plate about an axis along x at ``(y, z) = (mill_radius, width/2)`` (the inner face has radius
``mill_radius``, ``width`` is its arc length); 0 keeps it flat (``z in [0, width]``).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

from ..errors import SceneError

Vec3 = tuple[float, float, float]


def _size(name: str, value: object) -> None:
    if not (isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value) and value > 0):
        raise SceneError(name, value, "must be a finite number > 0 m")


@dataclass(frozen=True)
class LinerShape:
    """Plate and lifter sizes of a liner segment (m, degrees; see the module docstring)."""

    length: float = 0.40
    width: float = 0.50
    thickness: float = 0.075
    n_lifters: int = 1
    lifter_height: float = 0.20
    lifter_top_width: float = 0.10
    lifter_face_angle: float = 20.0
    lifter_spacing: float = 0.30
    mill_radius: float = 0.0

    @property
    def lifter_base_width(self) -> float:
        """Width of a lifter where it meets the plate, m."""
        return self.lifter_top_width + 2.0 * self.lifter_height * math.tan(math.radians(self.lifter_face_angle))

    def lifter_centres(self) -> list[float]:
        """Arc-length positions (z for a flat plate) of the lifter centre lines, m."""
        n = self.n_lifters
        return [0.5 * self.width + (i - 0.5 * (n - 1)) * self.lifter_spacing for i in range(n)]

    @property
    def foot_depth(self) -> float:
        """How deep (m) the lifters' feet reach into the plate in the builder (a robust overlap for
        the fuse): half the thickness, or on a curved plate half the depth of the back face under
        the foot's corners, sqrt((R + t)^2 - (base/2)^2) - R."""
        t, R = self.thickness, self.mill_radius
        if R == 0:
            return 0.5 * t
        return 0.5 * (math.sqrt(max((R + t) ** 2 - (0.5 * self.lifter_base_width) ** 2, 0.0)) - R)

    def validate_shape(self) -> None:
        """Refuse impossible shapes with a :class:`SceneError` naming ``liner.<field>`` and its range."""
        for name in ("length", "width", "thickness"):
            _size(f"liner.{name}", getattr(self, name))
        n = self.n_lifters
        if isinstance(n, bool) or not isinstance(n, int) or n < 1:
            raise SceneError("liner.n_lifters", n, "must be an integer >= 1 (the ball strikes a lifter)")
        _size("liner.lifter_height", self.lifter_height)
        _size("liner.lifter_top_width", self.lifter_top_width)
        a = self.lifter_face_angle
        lo = -math.degrees(math.atan(self.lifter_top_width / (2.0 * self.lifter_height)))
        if not (isinstance(a, (int, float)) and math.isfinite(a) and lo < a < 90.0):
            raise SceneError("liner.lifter_face_angle", a, f"must lie in ({lo:.4g}, 90) deg "
                             "(a smaller angle makes the lifter's base width negative)")
        widest = max(self.lifter_base_width, self.lifter_top_width)
        if n > 1:
            s = self.lifter_spacing
            if not (isinstance(s, (int, float)) and math.isfinite(s) and s > widest):
                raise SceneError("liner.lifter_spacing", s, f"must exceed the lifter's widest section "
                                 f"{widest:g} m, else neighbouring lifters overlap")
        span = (n - 1) * (self.lifter_spacing if n > 1 else 0.0) + widest
        if span >= self.width:
            raise SceneError("liner.width", self.width, f"must exceed the lifters' span {span:g} m "
                             f"({n} lifters, spacing {self.lifter_spacing:g} m, widest section {widest:g} m)")
        r = self.mill_radius
        if not (isinstance(r, (int, float)) and math.isfinite(r) and r >= 0):
            raise SceneError("liner.mill_radius", r, "must be 0 (flat) or > 0 m")
        if r > 0:
            r_min = max(self.width / (0.5 * math.pi), 4.0 * self.lifter_height)
            if r < r_min:
                raise SceneError("liner.mill_radius", r, f"must be 0 (flat) or >= {r_min:g} m (the plate spans "
                                 "at most 90 degrees of arc and lifters reach at most a quarter of the way "
                                 "to the axis)")
            if self.foot_depth <= 0:
                raise SceneError("liner.thickness", self.thickness, f"too thin for lifters "
                                 f"{self.lifter_base_width:g} m wide on a plate curved to mill_radius {r:g} m "
                                 "(the back face would pass under the lifter's foot corners)")

    def lifter_rotate(self, c: float, eta: float, zeta: float) -> tuple[float, float]:
        """Rotate a local vector of the lifter centred at arc position ``c`` (eta along its centre
        line, zeta across) to global (y, z)."""
        if self.mill_radius == 0:
            return eta, zeta
        phi = (c - 0.5 * self.width) / self.mill_radius
        # up (eta) points to the axis: (cos phi, -sin phi); across (zeta) is the tangent (sin phi, cos phi)
        return eta * math.cos(phi) + zeta * math.sin(phi), -eta * math.sin(phi) + zeta * math.cos(phi)

    def lifter_to_global(self, c: float, zeta: float, eta: float) -> tuple[float, float]:
        """Global (y, z) of the local point (zeta across from the centre line, eta up) of the
        lifter centred at arc position ``c``, m."""
        if self.mill_radius == 0:
            return eta, c + zeta
        R = self.mill_radius
        phi = (c - 0.5 * self.width) / R
        # the lifter's foot (eta = 0, zeta = 0) sits on the inner face at angle phi about the axis
        # (y, z) = (R, width/2); eta points to the axis
        dy, dz = self.lifter_rotate(c, eta, zeta)
        return R - R * math.cos(phi) + dy, 0.5 * self.width + R * math.sin(phi) + dz

    def lifter_face_point(self, lifter: int = 0, face: str = "+z", height_fraction: float = 0.5,
                          x: float = 0.0) -> tuple[Vec3, Vec3]:
        """A point on a lifter face and the face's outward unit normal: ((x, y, z), (nx, ny, nz)), m.

        ``lifter`` indexes :meth:`lifter_centres`; ``face`` is ``"+z"`` or ``"-z"`` (the side the
        face looks to); ``height_fraction`` in (0, 1) the point's height over the lifter's height
        (along the lifter's centre line from the plate's inner face); ``x`` in m.
        """
        if not (0 <= lifter < self.n_lifters):
            raise SceneError("liner.impact_lifter", lifter, f"must index a lifter: 0 .. {self.n_lifters - 1}")
        if face not in ("+z", "-z"):
            raise SceneError("liner.impact_face", face, "must be '+z' or '-z'")
        if not (0.0 < height_fraction < 1.0):
            raise SceneError("liner.impact_height", height_fraction, "must lie in (0, 1) (a fraction of the lifter height)")
        if not (-0.5 * self.length < x < 0.5 * self.length):
            raise SceneError("liner.impact_x", x, f"must lie in (-{self.length / 2:g}, {self.length / 2:g}) m")
        sign = 1.0 if face == "+z" else -1.0
        hb, ht, h = 0.5 * self.lifter_base_width, 0.5 * self.lifter_top_width, self.lifter_height
        eta = height_fraction * h
        zeta = sign * (hb + (ht - hb) * height_fraction)      # local, from the lifter's centre line
        n_zeta, n_eta = sign * h, hb - ht                       # outward normal of the face (local)
        nn = math.hypot(n_zeta, n_eta)
        c = self.lifter_centres()[lifter]
        (y, z), (ny, nz) = self.lifter_to_global(c, zeta, eta), self.lifter_rotate(c, n_eta / nn, n_zeta / nn)
        return (float(x), y, z), (0.0, ny, nz)
