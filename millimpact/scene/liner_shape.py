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

Bolt holes (optional; ``bolt_hole_diameter`` 0, the default, means none): a hole of that diameter
through the plate, normal to it (radial on a curved plate), at every pair of an axial position in
``bolt_x`` and an arc position in ``bolt_arc`` (measured like :meth:`LinerShape.lifter_centres`).
``backing`` says what holds the back face: ``"clamped"`` (rigid, u = 0: the default) or
``"rubber"`` (an elastic Winkler layer; its stiffness is a scene field of
:class:`millimpact.scene.schema.Liner`); the holes' surfaces are clamped (the bolts).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from ..errors import SceneError

Vec3 = tuple[float, float, float]


def vec3(values) -> Vec3:
    """The three components of a point or vector (any sequence or array of three numbers) as
    floats; a sequence of another length raises ValueError."""
    x, y, z = values
    return (float(x), float(y), float(z))


#: where on a liner a ball can strike (the places of impacts.csv, millimpact.dem.impacts.PLACES)
IMPACT_PLACES = ("lifter_face", "lifter_top", "plate")


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
    bolt_hole_diameter: float = 0.0
    bolt_x: tuple[float, ...] = ()
    bolt_arc: tuple[float, ...] = ()
    backing: str = "clamped"

    #: the fields added with the bolt holes and the backing, and their defaults (no holes, the back
    #: face clamped): a liner that keeps them has the mesh (and cache key) it had before them
    OPTIONAL_DEFAULTS = {"bolt_hole_diameter": 0.0, "bolt_x": (), "bolt_arc": (), "backing": "clamped"}

    def bolt_holes(self) -> list[tuple[float, float]]:
        """(x, arc position) of every bolt hole's axis, m; empty without holes."""
        if self.bolt_hole_diameter == 0:
            return []
        return [(float(x), float(s)) for x in self.bolt_x for s in self.bolt_arc]

    def hole_axis(self, x: float, s: float) -> tuple[Vec3, Vec3]:
        """A point of the axis of the hole at (x, arc s) on the plate's inner face and the axis'
        unit direction pointing out of the mill (into the plate), m."""
        if self.mill_radius == 0:
            return (x, 0.0, s), (0.0, -1.0, 0.0)
        R = self.mill_radius
        phi = (s - 0.5 * self.width) / R
        return (x, R - R * math.cos(phi), 0.5 * self.width + R * math.sin(phi)), (0.0, -math.cos(phi), math.sin(phi))

    def hole_distance(self, p: Vec3, x: float, s: float) -> float:
        """Distance (m) of point ``p`` from the axis of the hole at (x, arc s)."""
        a, e = self.hole_axis(x, s)
        d = [pc - ac for pc, ac in zip(p, a)]
        along = sum(dc * ec for dc, ec in zip(d, e))
        return math.sqrt(max(sum(dc * dc for dc in d) - along * along, 0.0))

    def contains(self, p: Vec3, tol: float = 1e-9) -> bool:
        """Whether point ``p`` (m) lies in the liner (plate or a lifter, not in a bolt hole), with
        ``tol`` (m) of slack on every face."""
        x, y, z = p
        if abs(x) > 0.5 * self.length + tol:
            return False
        R, w, t = self.mill_radius, self.width, self.thickness
        if R == 0:
            r, s = -y, z  # depth below the inner face, arc position
        else:
            r = math.hypot(y - R, z - 0.5 * w) - R
            s = 0.5 * w + R * math.atan2(z - 0.5 * w, R - y)
        in_plate = -tol <= r <= t + tol and -tol <= s <= w + tol
        if in_plate and any(
            self.hole_distance(p, hx, hs) < 0.5 * self.bolt_hole_diameter - tol for hx, hs in self.bolt_holes()
        ):
            return False
        if in_plate:
            return True
        hb, ht, h = 0.5 * self.lifter_base_width, 0.5 * self.lifter_top_width, self.lifter_height
        for c in self.lifter_centres():
            dy, dz = (
                (y, z - c)
                if R == 0
                else (y - (R - R * math.cos((c - 0.5 * w) / R)), z - (0.5 * w + R * math.sin((c - 0.5 * w) / R)))
            )
            phi = 0.0 if R == 0 else (c - 0.5 * w) / R
            eta = dy * math.cos(phi) - dz * math.sin(phi)
            zeta = dy * math.sin(phi) + dz * math.cos(phi)
            if -tol <= eta <= h + tol and abs(zeta) <= hb + (ht - hb) * max(eta, 0.0) / h + tol:
                return True
        return False

    def validate_bolts(self) -> None:
        """Refuse bolt holes off the plate, under a lifter's foot or overlapping, and an unknown
        backing, with a :class:`SceneError` naming the field."""
        if self.backing not in ("clamped", "rubber"):
            raise SceneError(
                "liner.backing",
                self.backing,
                "must be 'clamped' (rigid shell) or 'rubber' "
                "(a Winkler layer: liner.backing_modulus / liner.backing_thickness)",
            )
        d = self.bolt_hole_diameter
        if self.backing == "rubber" and not (isinstance(d, (int, float)) and d > 0):
            raise SceneError(
                "liner.backing",
                self.backing,
                "a rubber backing needs bolt holes (liner.bolt_hole_diameter "
                "> 0): the bolts hold the liner along the shell, the backing only across it",
            )
        if not (isinstance(d, (int, float)) and not isinstance(d, bool) and math.isfinite(d) and d >= 0):
            raise SceneError("liner.bolt_hole_diameter", d, "must be 0 (no holes) or a finite number > 0 m")
        if d == 0:
            if self.bolt_x or self.bolt_arc:
                raise SceneError("liner.bolt_hole_diameter", d, "must be > 0 m when bolt_x / bolt_arc place holes")
            return
        if not self.bolt_x or not self.bolt_arc:
            raise SceneError(
                "liner.bolt_x" if not self.bolt_x else "liner.bolt_arc",
                list(self.bolt_x if not self.bolt_x else self.bolt_arc),
                "must list at least one position (m) when bolt_hole_diameter > 0",
            )
        half = 0.5 * d
        lim = 0.5 * self.length - half
        for i, x in enumerate(self.bolt_x):
            if not (math.isfinite(x) and -lim < x < lim):
                raise SceneError(
                    f"liner.bolt_x[{i}]", x, f"must lie in ({-lim:g}, {lim:g}) m (the hole inside the plate)"
                )
        xs = sorted(self.bolt_x)
        if any(b - a <= d for a, b in zip(xs, xs[1:])):
            raise SceneError("liner.bolt_x", list(self.bolt_x), f"holes must be more than a diameter ({d:g} m) apart")
        ss = sorted(self.bolt_arc)
        if any(b - a <= d for a, b in zip(ss, ss[1:])):
            raise SceneError(
                "liner.bolt_arc", list(self.bolt_arc), f"holes must be more than a diameter ({d:g} m) apart"
            )
        hb = 0.5 * max(self.lifter_base_width, self.lifter_top_width)
        for i, s in enumerate(self.bolt_arc):
            if not (math.isfinite(s) and half < s < self.width - half):
                raise SceneError(
                    f"liner.bolt_arc[{i}]",
                    s,
                    f"must lie in ({half:g}, {self.width - half:g}) m (the hole inside the plate)",
                )
            for c in self.lifter_centres():
                if abs(s - c) < hb + half:
                    raise SceneError(
                        f"liner.bolt_arc[{i}]",
                        s,
                        f"the hole meets the foot of the lifter at arc "
                        f"{c:g} m: keep it {hb + half:g} m or more from a lifter centre line "
                        "(holes go through the shell plate between lifters)",
                    )

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
            raise SceneError(
                "liner.lifter_face_angle",
                a,
                f"must lie in ({lo:.4g}, 90) deg (a smaller angle makes the lifter's base width negative)",
            )
        widest = max(self.lifter_base_width, self.lifter_top_width)
        if n > 1:
            s = self.lifter_spacing
            if not (isinstance(s, (int, float)) and math.isfinite(s) and s > widest):
                raise SceneError(
                    "liner.lifter_spacing",
                    s,
                    f"must exceed the lifter's widest section {widest:g} m, else neighbouring lifters overlap",
                )
        span = (n - 1) * (self.lifter_spacing if n > 1 else 0.0) + widest
        if span >= self.width:
            raise SceneError(
                "liner.width",
                self.width,
                f"must exceed the lifters' span {span:g} m "
                f"({n} lifters, spacing {self.lifter_spacing:g} m, widest section {widest:g} m)",
            )
        r = self.mill_radius
        if not (isinstance(r, (int, float)) and math.isfinite(r) and r >= 0):
            raise SceneError("liner.mill_radius", r, "must be 0 (flat) or > 0 m")
        if r > 0:
            r_min = max(self.width / (0.5 * math.pi), 4.0 * self.lifter_height)
            if r < r_min:
                raise SceneError(
                    "liner.mill_radius",
                    r,
                    f"must be 0 (flat) or >= {r_min:g} m (the plate spans "
                    "at most 90 degrees of arc and lifters reach at most a quarter of the way "
                    "to the axis)",
                )
            if self.foot_depth <= 0:
                raise SceneError(
                    "liner.thickness",
                    self.thickness,
                    f"too thin for lifters "
                    f"{self.lifter_base_width:g} m wide on a plate curved to mill_radius {r:g} m "
                    "(the back face would pass under the lifter's foot corners)",
                )
        self.validate_bolts()

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

    def lifter_face_point(
        self, lifter: int = 0, face: str = "+z", height_fraction: float = 0.5, x: float = 0.0
    ) -> tuple[Vec3, Vec3]:
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
            raise SceneError(
                "liner.impact_height", height_fraction, "must lie in (0, 1) (a fraction of the lifter height)"
            )
        if not (-0.5 * self.length < x < 0.5 * self.length):
            raise SceneError("liner.impact_x", x, f"must lie in (-{self.length / 2:g}, {self.length / 2:g}) m")
        sign = 1.0 if face == "+z" else -1.0
        hb, ht, h = 0.5 * self.lifter_base_width, 0.5 * self.lifter_top_width, self.lifter_height
        eta = height_fraction * h
        zeta = sign * (hb + (ht - hb) * height_fraction)  # local, from the lifter's centre line
        n_zeta, n_eta = sign * h, hb - ht  # outward normal of the face (local)
        nn = math.hypot(n_zeta, n_eta)
        c = self.lifter_centres()[lifter]
        (y, z), (ny, nz) = self.lifter_to_global(c, zeta, eta), self.lifter_rotate(c, n_eta / nn, n_zeta / nn)
        return (float(x), y, z), (0.0, ny, nz)

    def lifter_top_point(
        self, lifter: int = 0, face: str = "+z", arc: float = 0.0, x: float = 0.0
    ) -> tuple[Vec3, Vec3]:
        """A point on a lifter's top and the top's outward unit normal (towards the mill axis):
        ((x, y, z), (nx, ny, nz)), m. ``arc`` (m) is measured across the top from the lifter's
        centre line, positive towards ``face``; it must lie in (-top/2, top/2)."""
        if not (0 <= lifter < self.n_lifters):
            raise SceneError("liner.impact_lifter", lifter, f"must index a lifter: 0 .. {self.n_lifters - 1}")
        if face not in ("+z", "-z"):
            raise SceneError("liner.impact_face", face, "must be '+z' or '-z'")
        ht = 0.5 * self.lifter_top_width
        if not (isinstance(arc, (int, float)) and math.isfinite(arc) and -ht < arc < ht):
            raise SceneError(
                "liner.impact_arc",
                arc,
                f"must lie in ({-ht:g}, {ht:g}) m on the lifter top "
                "(from its centre line, positive towards liner.impact_face)",
            )
        if not (-0.5 * self.length < x < 0.5 * self.length):
            raise SceneError("liner.impact_x", x, f"must lie in (-{self.length / 2:g}, {self.length / 2:g}) m")
        c = self.lifter_centres()[lifter]
        zeta = (1.0 if face == "+z" else -1.0) * arc
        (y, z), (ny, nz) = self.lifter_to_global(c, zeta, self.lifter_height), self.lifter_rotate(c, 1.0, 0.0)
        return (float(x), y, z), (0.0, ny, nz)

    def plate_point(self, lifter: int = 0, face: str = "+z", arc: float = 0.0, x: float = 0.0) -> tuple[Vec3, Vec3]:
        """A point on the plate's inner face and its outward unit normal (towards the mill axis):
        ((x, y, z), (nx, ny, nz)), m. ``arc`` (m) is the arc length along the inner face from the
        centre line of ``lifter``, positive towards its ``face``; the point must lie on the plate
        and not under a lifter's foot (the ball's clearance from the lifters is the scene's check)."""
        if not (0 <= lifter < self.n_lifters):
            raise SceneError("liner.impact_lifter", lifter, f"must index a lifter: 0 .. {self.n_lifters - 1}")
        if face not in ("+z", "-z"):
            raise SceneError("liner.impact_face", face, "must be '+z' or '-z'")
        if not (-0.5 * self.length < x < 0.5 * self.length):
            raise SceneError("liner.impact_x", x, f"must lie in (-{self.length / 2:g}, {self.length / 2:g}) m")
        c = self.lifter_centres()[lifter]
        s = c + (1.0 if face == "+z" else -1.0) * arc if isinstance(arc, (int, float)) else math.nan
        hb = 0.5 * max(self.lifter_base_width, self.lifter_top_width)
        lo, hi = -c, self.width - c
        if face == "-z":
            lo, hi = c - self.width, c
        if not (math.isfinite(s) and 0.0 < s < self.width):
            raise SceneError(
                "liner.impact_arc",
                arc,
                f"must lie on the plate: ({lo:g}, {hi:g}) m from lifter "
                f"{lifter}'s centre line (positive towards liner.impact_face)",
            )
        if any(abs(s - cc) <= hb for cc in self.lifter_centres()):
            raise SceneError(
                "liner.impact_arc",
                arc,
                f"lies under a lifter's foot: keep it more than {hb:g} m from a lifter's centre line",
            )
        if any(
            self.hole_distance((x, *self._plate_yz(s)), hx, hs) <= 0.5 * self.bolt_hole_diameter
            for hx, hs in self.bolt_holes()
        ):
            raise SceneError("liner.impact_arc", arc, "lies in a bolt hole")
        R = self.mill_radius
        if R == 0:
            return (float(x), 0.0, float(s)), (0.0, 1.0, 0.0)
        phi = (s - 0.5 * self.width) / R
        y, z = self._plate_yz(s)
        return (float(x), y, z), (0.0, math.cos(phi), -math.sin(phi))

    def _plate_yz(self, s: float) -> tuple[float, float]:
        """(y, z) of the inner face at arc position ``s`` (m, from the plate's edge)."""
        R = self.mill_radius
        if R == 0:
            return 0.0, s
        phi = (s - 0.5 * self.width) / R
        return R - R * math.cos(phi), 0.5 * self.width + R * math.sin(phi)

    def impact_site(
        self,
        place: str = "lifter_face",
        lifter: int = 0,
        face: str = "+z",
        height_fraction: float = 0.5,
        x: float = 0.0,
        arc: float = 0.0,
    ) -> tuple[Vec3, Vec3]:
        """The first-contact point and outward unit normal of an impact on ``place``: a lifter face
        (:meth:`lifter_face_point`: ``height_fraction``), a lifter top (:meth:`lifter_top_point`) or
        the plate (:meth:`plate_point`), these two at ``arc`` (m) from the lifter's centre line."""
        if place == "lifter_face":
            return self.lifter_face_point(lifter, face, height_fraction, x)
        if place == "lifter_top":
            return self.lifter_top_point(lifter, face, arc, x)
        if place == "plate":
            return self.plate_point(lifter, face, arc, x)
        raise SceneError("liner.impact_place", place, f"must be one of {', '.join(IMPACT_PLACES)}")
