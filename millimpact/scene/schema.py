"""Scenes: what the user describes (bodies, materials, impact, gauges, time span, outputs).

A scene is a frozen dataclass tree, validated on construction; every refusal is a
:class:`SceneError` naming the field, the value and the allowed range. Scenes load from and save
to TOML; built-in scenes are named (``paper-rig`` is the default).

Coordinates (SI units throughout, metres / seconds / pascals / kilograms):
the block occupies ``x in [-length/2, length/2]``, ``y in [-thickness, 0]``, ``z in [0, height]``;
the struck face is ``y = 0`` (the length x height face), so ``thickness`` (b) lies along the impact
direction. ``support = "base"`` clamps the ``z = 0`` face (the paper's rig), ``"back"`` clamps the
``y = -thickness`` face (a half-space-like block). The ball starts at
``(x_p, radius + gap, z_p)`` above the impact point ``(x_p, 0, z_p)`` and moves with ``velocity``.
"""

from __future__ import annotations

import dataclasses
import functools
import math
import tomllib
import types
import typing
from dataclasses import dataclass, field
from typing import Any

from ..errors import SceneError
from .liner_shape import IMPACT_PLACES, LinerShape, vec3
from .materials import named_material

Vec3 = tuple[float, float, float]
Vec2 = tuple[float, float]

#: densities the model takes, kg/m^3: engineering solids from polymers (~900) to the densest metal,
#: osmium (22,590; CRC Handbook of Chemistry and Physics), with margin
DENSITY_RANGE = (500.0, 25000.0)
#: shear moduli the model takes, Pa: from soft rubbers (~0.3 MPa) to diamond (~530 GPa; Ashby,
#: Materials Selection in Mechanical Design, 2011, chart 4.3), with margin
SHEAR_MODULUS_RANGE = (1.0e5, 1.0e12)


@dataclass(frozen=True)
class Material:
    """Isotropic steel: density (kg/m^3), shear modulus (Pa), Poisson's ratio; optionally J2
    plasticity with isotropic hardening: ``yield_stress`` (Pa; None = elastic), linear
    ``hardening_modulus`` (Pa, 0 = perfectly plastic) or a tabulated ``flow_curve`` of
    [equivalent plastic strain, flow stress (Pa)] pairs (from strain 0, increasing). A scene names
    one of :data:`NAMED_MATERIALS` with ``material = "NAME"`` (or ``name = "NAME"`` in the table,
    other keys overriding); ``source`` says where the values come from. Nonlinear hardening laws
    beside the table: ``voce = [Q, b]`` with ``yield_stress`` Y, sigma_y = Y + Q (1 - exp(-b eps_p))
    (E. Voce, J. Inst. Metals 74 (1948) 537), or ``swift = [K, eps0, n]``, sigma_y = K (eps0 +
    eps_p)^n (H. W. Swift, J. Mech. Phys. Solids 1 (1952) 1), its yield stress K eps0^n
    (:mod:`millimpact.fem.hardening` tabulates them for the return map). A strain-rate factor:
    ``johnson_cook_rate = [C, rate0]``, the flow stress times 1 + C ln(rate / rate0) above the
    reference rate rate0 (1/s; G. R. Johnson and W. H. Cook, 7th Int. Symp. Ballistics, 1983)."""

    density: float = 7800.0
    shear_modulus: float = 70.0e9
    poisson: float = 0.3
    yield_stress: float | None = None
    hardening_modulus: float = 0.0
    flow_curve: tuple[tuple[float, float], ...] | None = None
    voce: tuple[float, float] | None = None
    swift: tuple[float, float, float] | None = None
    johnson_cook_rate: tuple[float, float] | None = None
    source: str = ""

    def validate(self, where: str) -> None:
        _in_range(f"{where}.density", self.density, DENSITY_RANGE, "kg/m^3 (solids: polymers to osmium)")
        _in_range(f"{where}.shear_modulus", self.shear_modulus, SHEAR_MODULUS_RANGE, "Pa (soft rubber to diamond)")
        if not (-1.0 < self.poisson < 0.5):
            raise SceneError(f"{where}.poisson", self.poisson, "must lie in (-1, 0.5)")
        if self.yield_stress is not None:
            _positive(f"{where}.yield_stress", self.yield_stress, "Pa (leave it out for an elastic material)")
        _finite(f"{where}.hardening_modulus", self.hardening_modulus, "Pa")
        if self.hardening_modulus < 0:
            raise SceneError(
                f"{where}.hardening_modulus", self.hardening_modulus, "must be >= 0 Pa (0: perfectly plastic)"
            )
        if self.hardening_modulus != 0 and (self.yield_stress is None or self.flow_curve is not None):
            # it would be ignored: linear hardening needs a yield stress, a flow curve has its own slopes
            raise SceneError(
                f"{where}.hardening_modulus",
                self.hardening_modulus,
                "applies with yield_stress only (linear hardening): "
                + (
                    "the flow curve gives the hardening; leave it out"
                    if self.flow_curve is not None
                    else "give yield_stress too, or leave it out for an elastic material"
                ),
            )
        self._validate_laws(where)
        if self.flow_curve is not None:
            pts = self.flow_curve
            if len(pts) < 2:
                raise SceneError(
                    f"{where}.flow_curve", [list(p) for p in pts], "must have at least two [strain, stress] pairs"
                )
            if pts[0][0] != 0.0 or any(b[0] <= a[0] for a, b in zip(pts, pts[1:])):
                raise SceneError(
                    f"{where}.flow_curve",
                    [list(p) for p in pts],
                    "plastic strains must start at 0 and increase strictly",
                )
            if pts[0][1] <= 0 or any(b[1] < a[1] for a, b in zip(pts, pts[1:])):
                raise SceneError(
                    f"{where}.flow_curve", [list(p) for p in pts], "flow stresses must be > 0 Pa and must not decrease"
                )
            if self.yield_stress is not None and self.yield_stress != pts[0][1]:
                raise SceneError(
                    f"{where}.yield_stress",
                    self.yield_stress,
                    f"must equal the flow curve's first stress {pts[0][1]:g} Pa (or be left out)",
                )

    def _validate_laws(self, where: str) -> None:
        """At most one hardening description; Voce's and Swift's parameters in range."""
        given = [
            n for n, v in (("flow_curve", self.flow_curve), ("voce", self.voce), ("swift", self.swift)) if v is not None
        ]
        if len(given) > 1 or (given and given[0] != "flow_curve" and self.hardening_modulus != 0):
            names = given + (["hardening_modulus"] if self.hardening_modulus != 0 else [])
            raise SceneError(f"{where}.{names[-1]}", getattr(self, names[-1]), f"give one of {', '.join(names)}")
        if self.voce is not None:
            q, b = (float(x) for x in self.voce)
            if self.yield_stress is None:
                raise SceneError(
                    f"{where}.voce", list(self.voce), "needs yield_stress (Y of Y + Q (1 - exp(-b eps_p)))"
                )
            if not (math.isfinite(q) and q >= 0 and math.isfinite(b) and b > 0):
                raise SceneError(f"{where}.voce", list(self.voce), "must be [Q >= 0 Pa, b > 0]")
        if self.johnson_cook_rate is not None:
            c, rate0 = (float(x) for x in self.johnson_cook_rate)
            if not self.plastic:
                raise SceneError(f"{where}.johnson_cook_rate", list(self.johnson_cook_rate), "needs a plastic material")
            if not (math.isfinite(c) and 0 < c <= 0.5 and math.isfinite(rate0) and 0 < rate0 <= 1e6):
                raise SceneError(
                    f"{where}.johnson_cook_rate",
                    list(self.johnson_cook_rate),
                    "must be [0 < C <= 0.5, 0 < rate0 <= 1e6 1/s]",
                )
        if self.swift is not None:
            k, e0, n = (float(x) for x in self.swift)
            if not (math.isfinite(k) and k > 0 and 0 < e0 <= 1 and 0 <= n < 1):
                raise SceneError(f"{where}.swift", list(self.swift), "must be [K > 0 Pa, 0 < eps0 <= 1, 0 <= n < 1]")
            if self.yield_stress is not None and not math.isclose(self.yield_stress, k * e0**n, rel_tol=1e-9):
                raise SceneError(
                    f"{where}.yield_stress",
                    self.yield_stress,
                    f"must equal Swift's K eps0^n = {k * e0**n:g} Pa (or be left out)",
                )

    @property
    def plastic(self) -> bool:
        """True when the material yields (a yield stress, a flow curve or a Swift law is given)."""
        return self.yield_stress is not None or self.flow_curve is not None or self.swift is not None

    @property
    def initial_yield_stress(self) -> float | None:
        """The stress at which yielding starts (Pa), None for an elastic material."""
        if self.flow_curve is not None:
            return self.flow_curve[0][1]
        if self.swift is not None:
            k, e0, n = self.swift
            return float(k * e0**n)
        return self.yield_stress

    @property
    def youngs_modulus(self) -> float:
        """E = 2 G (1 + nu), Pa."""
        return 2.0 * self.shear_modulus * (1.0 + self.poisson)

    @property
    def lame_lambda(self) -> float:
        """First Lame parameter, Pa."""
        return 2.0 * self.shear_modulus * self.poisson / (1.0 - 2.0 * self.poisson)

    @property
    def wave_speed_p(self) -> float:
        """Dilatational wave speed sqrt((lambda + 2 mu) / rho), m/s."""
        return math.sqrt((self.lame_lambda + 2.0 * self.shear_modulus) / self.density)

    @property
    def bar_wave_speed(self) -> float:
        """One-dimensional bar wave speed sqrt(E / rho), m/s."""
        return math.sqrt(self.youngs_modulus / self.density)


#: balls the model covers, m: lab test spheres from 0.1 mm to SAG-mill grinding balls (<= 150 mm) with margin
BALL_RADIUS_RANGE = (1e-4, 1.0)
#: impact speeds the model covers, m/s: mill impacts are below ~15 m/s; beyond ~100 m/s small-strain
#: contact (and the quasi-static Hertz sizing of the plan) no longer describes the impact
MAX_IMPACT_SPEED = 100.0


#: a ball's ``body_mass`` may be up to this many times its sphere's own mass: the sphere carries the
#: body's mass as a uniformly denser sphere (a Leeb D tip, 3 mm tungsten carbide on a 5.5 g body:
#: ~25x), whose own lowest vibration period grows with the square root of the ratio (at 1000x,
#: ~30 x the sphere's wave transit time R / c)
BODY_MASS_RATIO_MAX = 1000.0


@dataclass(frozen=True)
class Ball:
    """The grinding ball: a sphere of ``radius`` (m). ``body_mass`` (kg; None: the sphere's own
    mass) is the mass of a heavier body whose tip the ball is (a hardness tester's impact body):
    the model's sphere carries it as a uniformly denser sphere, its stiffness the material's."""

    radius: float = 0.015
    material: Material = field(default_factory=Material)
    body_mass: float | None = None

    def validate(self) -> None:
        _positive("ball.radius", self.radius, "m")
        if not (BALL_RADIUS_RANGE[0] <= self.radius <= BALL_RADIUS_RANGE[1]):
            raise SceneError(
                "ball.radius",
                self.radius,
                f"must lie in [{BALL_RADIUS_RANGE[0]:g}, {BALL_RADIUS_RANGE[1]:g}] m "
                "(test and grinding balls; a small-contact impact model)",
            )
        self.material.validate("ball.material")
        if self.body_mass is not None:
            own = self.sphere_mass
            lo, hi = own, BODY_MASS_RATIO_MAX * own
            _finite("ball.body_mass", self.body_mass, "kg")
            if not (lo * (1 - 1e-12) <= self.body_mass <= hi):
                raise SceneError(
                    "ball.body_mass",
                    self.body_mass,
                    f"must lie in [{lo:.4g}, {hi:.4g}] kg: at least the sphere's own mass and at most "
                    f"{BODY_MASS_RATIO_MAX:g} x it (or leave it out: the sphere's mass)",
                )

    @property
    def sphere_mass(self) -> float:
        """The sphere's own mass 4/3 pi R^3 rho, kg."""
        return 4.0 / 3.0 * math.pi * self.radius**3 * self.material.density

    @property
    def mass(self) -> float:
        """The impacting mass, kg: ``body_mass`` if given, else the sphere's."""
        return self.sphere_mass if self.body_mass is None else self.body_mass

    @property
    def effective_density(self) -> float:
        """The density of a sphere of this radius and :attr:`mass`, kg/m^3 (Thornton's V_y)."""
        return self.mass / (4.0 / 3.0 * math.pi * self.radius**3)


@dataclass(frozen=True)
class Block:
    """The struck body: a rectangular block (the paper's liner sample), sizes in m.

    ``length`` l2 along x, ``thickness`` b along y (the impact direction), ``height`` l3 along z.
    """

    length: float = 0.042
    thickness: float = 0.045
    height: float = 0.080
    support: str = "base"
    material: Material = field(default_factory=Material)

    def validate(self) -> None:
        _positive("block.length", self.length, "m")
        _positive("block.thickness", self.thickness, "m")
        _positive("block.height", self.height, "m")
        if self.support not in ("base", "back"):
            raise SceneError(
                "block.support", self.support, "must be 'base' (z = 0 face) or 'back' (y = -thickness face)"
            )
        self.material.validate("block.material")


@dataclass(frozen=True)
class Liner(LinerShape):
    """A SAG-mill liner segment: a shell plate with lifter bars, struck on a lifter face. When a
    scene has a ``liner``, it replaces the block (whose fields are then unused).

    Shape (m, degrees): the fields of :class:`millimpact.scene.liner_shape.LinerShape` (plate
    ``length``, ``width``, ``thickness``; ``n_lifters`` lifters ``lifter_height`` high with a
    ``lifter_top_width`` top, ``lifter_face_angle``, ``lifter_spacing``; ``mill_radius``; bolt holes
    ``bolt_hole_diameter`` at ``bolt_x`` x ``bolt_arc``, clamped). The back face lies on the mill
    shell: clamped (``backing = "clamped"``, the default) or on a rubber backing sheet
    (``backing = "rubber"``): a Winkler layer of normal stiffness k_n = ``backing_modulus`` /
    ``backing_thickness`` (Pa/m), the modulus being the sheet's compression modulus (with the
    confinement of a thin sheet: :func:`millimpact.theory.rubber.compression_modulus`).

    Impact placement: the ball first touches lifter ``impact_lifter`` (index from the lowest z) on
    its ``impact_face`` (``"+z"`` or ``"-z"``, the side the face looks to) at ``impact_height`` (a
    fraction in (0, 1) of the lifter height, measured along its centre line from the plate) and at
    ``x = impact_x`` (m). The contact normal is that face's outward normal; the impact velocity
    (``impact.velocity``, global x, y, z) must point into the face.

    ``impact_place`` moves the impact off the face (the damage map's places, foundations.md section 12):
    ``"lifter_face"`` (the default, as above), ``"lifter_top"`` or ``"plate"``, these two at
    ``impact_arc`` (m) from the struck lifter's centre line along the liner's profile, positive
    towards its ``impact_face`` (:meth:`millimpact.scene.liner_shape.LinerShape.impact_site`); the contact normal is the top's
    or the plate's, and the ball must clear every lifter.
    """

    #: the placement fields added with the places, and their defaults: a liner that keeps them
    #: writes (and hashes) as it did before them
    PLACE_DEFAULTS = {"impact_place": "lifter_face", "impact_arc": 0.0}

    material: Material = field(default_factory=Material)
    impact_lifter: int = 0
    impact_face: str = "+z"
    impact_height: float = 0.5
    impact_x: float = 0.0
    backing_modulus: float = 1.0e9
    backing_thickness: float = 0.006
    impact_place: str = "lifter_face"
    impact_arc: float = 0.0

    @property
    def backing_stiffness(self) -> float:
        """Normal stiffness per area of the backing, k_n = E_c / t (Pa/m); 0 when the back face is clamped."""
        return self.backing_modulus / self.backing_thickness if self.backing == "rubber" else 0.0

    def face_point(self) -> tuple[Vec3, Vec3]:
        """The impact point (on the lifter face, or on the ``impact_place``) and the struck
        surface's outward unit normal (m)."""
        if self.impact_place == "lifter_face":
            return self.lifter_face_point(self.impact_lifter, self.impact_face, self.impact_height, self.impact_x)
        return self.impact_site(
            self.impact_place, self.impact_lifter, self.impact_face, self.impact_height, self.impact_x, self.impact_arc
        )

    def validate(self) -> None:
        self.material.validate("liner.material")
        self.validate_shape()
        _finite("liner.impact_height", self.impact_height, "fraction of the lifter height")
        _finite("liner.impact_x", self.impact_x, "m")
        if self.impact_place not in IMPACT_PLACES:
            raise SceneError("liner.impact_place", self.impact_place, f"must be one of {', '.join(IMPACT_PLACES)}")
        _finite("liner.impact_arc", self.impact_arc, "m from the struck lifter's centre line")
        self.face_point()  # refuses a lifter, face, height or x off the liner
        _positive("liner.backing_modulus", self.backing_modulus, "Pa (compression modulus of the rubber backing)")
        _positive("liner.backing_thickness", self.backing_thickness, "m (thickness of the rubber backing)")


@dataclass(frozen=True)
class ContactOptions:
    """Contact law. ``friction``: Coulomb coefficient mu >= 0 between ball and block/liner (0:
    frictionless, the default; see :mod:`millimpact.integration.friction` for the formulation)."""

    friction: float = 0.0

    def validate(self) -> None:
        _finite("contact.friction", self.friction, "dimensionless")
        if not (0.0 <= self.friction <= 2.0):
            raise SceneError("contact.friction", self.friction, "must lie in [0, 2] (Coulomb coefficient)")


@dataclass(frozen=True)
class Impact:
    """Arrival state of the ball.

    ``velocity`` (m/s) at first contact; ``point`` (x, z) on the struck face y = 0 (m), ``None``
    for the face centre; ``gap`` (m) between ball and face at the start, ``None`` for the plan's
    choice (a small fraction of the Hertz approach).
    """

    velocity: Vec3 = (0.0, -3.0, 0.0)
    point: Vec2 | None = None
    gap: float | None = None

    @property
    def speed(self) -> float:
        return math.sqrt(sum(c * c for c in self.velocity))

    @property
    def normal_speed(self) -> float:
        """Speed towards the struck face (m/s); positive when approaching."""
        return -self.velocity[1]


@dataclass(frozen=True)
class Gauge:
    """A strain gauge on the block: reports sigma = E * (direction . eps . direction), Pa."""

    name: str
    position: Vec3
    direction: Vec3 = (0.0, 0.0, 1.0)


@dataclass(frozen=True)
class TimeSpan:
    """Simulated time ``end`` (s); steps ``dt_contact`` in contact and ``dt_free`` otherwise (s),
    ``None`` for the plan's choice (from the Hertz contact time)."""

    end: float = 0.040
    dt_contact: float | None = None
    dt_free: float | None = None


@dataclass(frozen=True)
class ModelOptions:
    """Overrides of the plan's modelling choices; ``None`` leaves the choice to the plan.

    ``h_contact`` element size at the contact point (m), ``h_far`` far from it (m),
    ``zone_radius`` contact-zone radius (m), ``fine_radius`` radius within which the size is
    ``h_contact`` (m, at most ``zone_radius``), ``symmetry`` one of auto/full/half/quarter,
    ``degree`` Lagrange degree of the full model, ``f_cut`` modal cutoff (Hz), ``modes`` a fixed
    mode count per body, ``ball_zone_radius`` the ball's own contact-zone radius (m, at most
    ``zone_radius``; a repeated-impact sequence's ball, whose plastic region grows less than the
    liner's), ``strain`` the plastic zone's kinematics: auto (the plan's choice from the predicted
    plastic strain), small or finite.
    """

    h_contact: float | None = None
    h_far: float | None = None
    zone_radius: float | None = None
    symmetry: str = "auto"
    degree: int = 1
    f_cut: float | None = None
    modes: int | None = None
    fine_radius: float | None = None
    ball_zone_radius: float | None = None
    strain: str = "auto"


@dataclass(frozen=True)
class Outputs:
    """What a run writes: XDMF fields at ``field_times`` (s; those after ``time.end`` are skipped),
    PNG figures, HDF5 time series."""

    field_times: tuple[float, ...] = ()
    figures: bool = True
    xdmf: bool = True
    hdf5: bool = True


@dataclass(frozen=True)
class Scene:
    """A complete impact scene. Validated on construction."""

    name: str = "custom"
    description: str = ""
    ball: Ball = field(default_factory=Ball)
    block: Block = field(default_factory=Block)
    impact: Impact = field(default_factory=Impact)
    gauges: tuple[Gauge, ...] = ()
    time: TimeSpan = field(default_factory=TimeSpan)
    model: ModelOptions = field(default_factory=ModelOptions)
    outputs: Outputs = field(default_factory=Outputs)
    liner: Liner | None = None
    contact: ContactOptions = field(default_factory=ContactOptions)

    def __post_init__(self) -> None:
        if _VALIDATE_ON_CONSTRUCTION[0]:
            self.validate()

    # --- derived geometry -------------------------------------------------------------------
    @property
    def impact_point(self) -> Vec3:
        """Point of first contact on the struck face (m): on y = 0 for a block, on the lifter face
        for a liner."""
        if self.liner is not None:
            return vec3(self.liner.face_point()[0])
        if self.impact.point is None:
            return (0.0, 0.0, 0.5 * self.block.height)
        return (float(self.impact.point[0]), 0.0, float(self.impact.point[1]))

    @property
    def contact_normal(self) -> Vec3:
        """Outward unit normal of the struck face at the impact point: +y for a block, the lifter
        face's normal for a liner."""
        if self.liner is not None:
            return vec3(self.liner.face_point()[1])
        return (0.0, 1.0, 0.0)

    @property
    def normal_speed(self) -> float:
        """Speed towards the struck face, -v . n (m/s); positive when approaching."""
        if self.liner is None:
            return self.impact.normal_speed
        return -sum(v * n for v, n in zip(self.impact.velocity, self.contact_normal))

    @property
    def target_material(self) -> Material:
        """The struck body's material (the liner's or the block's)."""
        return self.liner.material if self.liner is not None else self.block.material

    def ball_centre(self, gap: float) -> Vec3:
        """Initial ball centre for a given gap (m): ``radius + gap`` off the impact point along
        the contact normal."""
        if self.liner is not None:
            p, n = self.liner.face_point()
            return vec3(pc + (self.ball.radius + gap) * nc for pc, nc in zip(p, n))
        x, _, z = self.impact_point
        return (x, self.ball.radius + gap, z)

    # --- validation ---------------------------------------------------------------------------
    def validate(self) -> None:
        """Refuse a scene with any field out of its range (SceneError naming the first one, in this
        order): the bodies, the impact, the gauges, the time span and the model options."""
        self._validate_bodies()
        self._validate_impact()
        self._validate_gauges()
        self._validate_time_and_model()

    def _validate_bodies(self) -> None:
        """The ball and the block; on a liner scene, no block field changed from its default."""
        self.ball.validate()
        self.block.validate()
        if self.liner is not None and self.block != Block():
            # a liner replaces the block: a block field set on a liner scene would be ignored
            changed = [
                f"block.{f.name}"
                for f in dataclasses.fields(Block)
                if getattr(self.block, f.name) != getattr(Block(), f.name)
            ]
            raise SceneError(
                changed[0],
                getattr(self.block, changed[0].split(".", 1)[1]),
                "is not used by a liner scene (its [liner] replaces the block): set the liner's "
                "fields (liner.thickness, liner.material, ...) instead",
            )

    def _validate_impact(self) -> None:
        """The arrival: a finite velocity (m/s) of speed at most MAX_IMPACT_SPEED towards the struck
        face, the contact law, the liner and its placement (:meth:`_validate_liner`), an impact
        point on a block's face and a gap (m) in [0, ball radius]."""
        imp, blk = self.impact, self.block
        for i, c in enumerate(imp.velocity):
            _finite(f"impact.velocity[{i}]", c, "m/s")
        if imp.speed > MAX_IMPACT_SPEED:
            raise SceneError(
                "impact.velocity",
                list(imp.velocity),
                f"its speed {imp.speed:g} m/s must be at most "
                f"{MAX_IMPACT_SPEED:g} m/s (small-strain contact; mill impacts are below ~15 m/s)",
            )
        self.contact.validate()
        if self.liner is not None:
            self._validate_liner(self.liner)
        elif imp.normal_speed <= 0.0:
            raise SceneError(
                "impact.velocity",
                list(imp.velocity),
                "its y component must be negative (towards the struck face y = 0)",
            )
        if imp.point is not None and self.liner is None:
            x, z = imp.point
            if not (-blk.length / 2 < x < blk.length / 2):
                raise SceneError(
                    "impact.point[0]", x, f"must lie on the face: (-{blk.length / 2:g}, {blk.length / 2:g}) m"
                )
            if not (0.0 < z < blk.height):
                raise SceneError("impact.point[1]", z, f"must lie on the face: (0, {blk.height:g}) m")
        if imp.gap is not None:
            if not (math.isfinite(imp.gap) and imp.gap >= 0.0):
                raise SceneError(
                    "impact.gap", imp.gap, "must be >= 0 m (a negative gap puts the ball inside the block)"
                )
            if imp.gap > self.ball.radius:
                raise SceneError(
                    "impact.gap",
                    imp.gap,
                    f"must be at most the ball radius ({self.ball.radius:g} m): "
                    "the simulation starts just before contact",
                )

    def _validate_gauges(self) -> None:
        """The gauges: unique names, a position in the liner (a hair under its surface) or on the
        block's surface (within 1e-6 m of a face), a non-zero direction."""
        names = set()
        for i, g in enumerate(self.gauges):
            where = f"gauges[{i}]"
            if g.name in names:
                raise SceneError(f"{where}.name", g.name, "must be unique")
            names.add(g.name)
            if self.liner is not None:
                # a gauge on a liner sits a hair under its surface (the probe needs a cell holding it)
                if not self.liner.contains(vec3(g.position), tol=1e-9):
                    raise SceneError(
                        f"{where}.position",
                        list(g.position),
                        "must lie in the liner (plate or a "
                        "lifter, not in a bolt hole): place it a fraction of a mm under the surface",
                    )
            else:
                self._check_block_gauge(g, where)
            if not math.sqrt(sum(c * c for c in g.direction)) > 0:
                raise SceneError(f"{where}.direction", list(g.direction), "must be a non-zero vector")

    def _check_block_gauge(self, g: Gauge, where: str) -> None:
        """Refuse a gauge ``g`` (field prefix ``where``) off the block's surface: inside the block
        (1e-9 m tolerance) with one coordinate within 1e-6 m of a face."""
        blk = self.block
        x, y, z = g.position
        tol = 1e-9
        inside = (
            -blk.length / 2 - tol <= x <= blk.length / 2 + tol
            and -blk.thickness - tol <= y <= tol
            and -tol <= z <= blk.height + tol
        )
        on_surface = (
            inside
            and min(
                abs(x - blk.length / 2),
                abs(x + blk.length / 2),
                abs(y),
                abs(y + blk.thickness),
                abs(z),
                abs(z - blk.height),
            )
            <= 1e-6
        )
        if not on_surface:
            raise SceneError(
                f"{where}.position",
                list(g.position),
                f"must lie on the block's surface: x in [{-blk.length / 2:g}, {blk.length / 2:g}], "
                f"y in [{-blk.thickness:g}, 0], z in [0, {blk.height:g}] m with one coordinate on a face",
            )

    def _validate_time_and_model(self) -> None:
        """The time span (s, > 0), the model options (sizes in m and f_cut in Hz > 0, a block's
        zone below half its struck face, symmetry, degree 1 or 2, modes >= 1) and the output
        times (s, >= 0)."""
        blk = self.block
        t = self.time
        _positive("time.end", t.end, "s")
        if t.dt_contact is not None:
            _positive("time.dt_contact", t.dt_contact, "s")
        if t.dt_free is not None:
            _positive("time.dt_free", t.dt_free, "s")
        m = self.model
        for name in ("h_contact", "h_far", "zone_radius", "fine_radius", "ball_zone_radius", "f_cut"):
            v = getattr(m, name)
            if v is not None:
                _positive(f"model.{name}", v, "Hz" if name == "f_cut" else "m")
        if m.zone_radius is not None and self.liner is None and m.zone_radius >= min(blk.length, blk.height) / 2:
            raise SceneError(
                "model.zone_radius",
                m.zone_radius,
                f"must be smaller than half the struck face ({min(blk.length, blk.height) / 2:g} m)",
            )
        if m.strain not in ("auto", "small", "finite"):
            raise SceneError("model.strain", m.strain, "must be one of auto, small, finite")
        if m.symmetry not in ("auto", "full", "half", "quarter"):
            raise SceneError("model.symmetry", m.symmetry, "must be one of auto, full, half, quarter")
        if m.degree not in (1, 2):
            raise SceneError("model.degree", m.degree, "must be 1 or 2")
        if m.modes is not None and m.modes < 1:
            raise SceneError("model.modes", m.modes, "must be >= 1")
        for i, ft in enumerate(self.outputs.field_times):
            if not (math.isfinite(ft) and ft >= 0.0):
                raise SceneError(f"outputs.field_times[{i}]", ft, "must be >= 0 s (times after time.end are skipped)")

    def _validate_liner(self, ln: Liner) -> None:
        """Liner scenes (``ln`` the scene's liner): the geometry, the placement, an approaching
        velocity, a ball clear of the plate."""
        imp = self.impact
        ln.validate()
        if imp.point is not None:
            raise SceneError(
                "impact.point",
                list(imp.point),
                "is not used with a liner: place the impact with "
                "liner.impact_lifter / impact_face / impact_height / impact_x",
            )
        p, n = ln.face_point()
        vn = sum(v * c for v, c in zip(imp.velocity, n))
        if not vn < 0.0:
            raise SceneError(
                "impact.velocity",
                list(imp.velocity),
                f"must point into the struck lifter face (v . n < 0 with its outward normal n = "
                f"({n[0]:.4g}, {n[1]:.4g}, {n[2]:.4g}))",
            )
        c = self.ball_centre(0.0 if imp.gap is None else imp.gap)
        if ln.impact_place != "lifter_face":
            self._check_ball_clear(ln, c)
            return
        Rm = ln.mill_radius
        # clearance of the ball from the plate's inner face (y = 0, or the cylinder of radius Rm)
        clear = (
            c[1] - self.ball.radius
            if Rm == 0.0
            else Rm - math.hypot(c[1] - Rm, c[2] - 0.5 * ln.width) - self.ball.radius
        )
        if clear <= 0.0:
            raise SceneError(
                "liner.impact_height",
                ln.impact_height,
                f"too low for a ball of radius {self.ball.radius:g} m: the ball would touch the "
                f"plate ({-clear:.4g} m into it); choose a higher point",
            )

    def _check_ball_clear(self, ln: Liner, centre: Vec3) -> None:
        """Refuse a ball (at ``centre``, m) that would overlap the liner ``ln`` away from the impact
        point: a lifter beside a plate impact, or the plate or lifter edge beside a top impact."""
        hit = _ball_overlap(ln, self.ball.radius, vec3(centre))
        if hit is not None:
            raise SceneError(
                "liner.impact_arc",
                ln.impact_arc,
                f"a ball of radius {self.ball.radius:g} m striking the {ln.impact_place.replace('_', ' ')} "
                f"here would touch the liner elsewhere (at (y, z) = ({hit[0]:.4g}, {hit[1]:.4g}) m); "
                "move the impact away from the lifter",
            )

    def with_value(self, path: str, value: Any) -> Scene:
        """A copy with the dotted field ``path`` (e.g. ``ball.radius``) set to ``value`` (validated)."""
        return self.with_values([(path, value)])

    def with_values(self, assignments: typing.Sequence[tuple[str, Any]]) -> Scene:
        """A copy with every ``(path, value)`` set, validated once all are set (so their order does
        not matter: shrinking a block and dropping its gauges is one change). A material named
        (``block.material = "NAME"`` or ``block.material.name = "NAME"``) is set before the
        fields that override its values; otherwise a later value of one field wins."""
        named_first = sorted(assignments, key=lambda pv: not _names_a_material(pv[0], pv[1]))
        _VALIDATE_ON_CONSTRUCTION[0] = False
        try:
            scene = self
            for path, value in named_first:
                scene = _replace_path(scene, path.split("."), value, path)
        finally:
            _VALIDATE_ON_CONSTRUCTION[0] = True
        scene.validate()
        return scene


#: False while :meth:`Scene.with_values` sets several fields: the scene is validated once, at the end
_VALIDATE_ON_CONSTRUCTION = [True]


def _names_a_material(path: str, value: Any) -> bool:
    """Whether ``path = value`` replaces a whole material by a named one."""
    return path.endswith(".material.name") or (path.endswith("material") and isinstance(value, str))


# --- helpers ---------------------------------------------------------------------------------
@functools.lru_cache(maxsize=256)
def _ball_overlap(liner: Liner, radius: float, centre: Vec3) -> tuple[float, float] | None:
    """A point (y, z) where a ball of ``radius`` at ``centre`` (m) lies inside the liner, or None.
    The liner is prismatic along x (bolt holes only take material away), so the ball overlaps it
    if its section through the centre, a disk, overlaps the profile: its circle is sampled at 720
    points (0.5 mm apart for a 62.5 mm ball) at 99.9 % of the radius, so the first-contact point
    itself does not count. Cached: a study's copies of one scene check the same ball."""
    r = 0.999 * radius
    x, y, z = centre
    for k in range(720):
        t = 2.0 * math.pi * k / 720
        p = (x, y + r * math.cos(t), z + r * math.sin(t))
        if liner.contains(p, tol=0.0):
            return p[1], p[2]
    return None


def parse_value(text: str):
    """The value of a ``FIELD=VALUE`` override: a TOML value (number, string, array, boolean), or
    the text itself when it is not one (a bare word such as ``base``)."""
    try:
        return tomllib.loads(f"v = {text}")["v"]
    except tomllib.TOMLDecodeError:
        return text


def _finite(name: str, value: Any, unit: str) -> None:
    if not isinstance(value, (int, float)) or isinstance(value, bool) or not math.isfinite(value):
        raise SceneError(name, value, f"must be a finite number ({unit})")


def _positive(name: str, value: Any, unit: str) -> None:
    _finite(name, value, unit)
    if value <= 0:
        raise SceneError(name, value, f"must be > 0 {unit}")


def _in_range(name: str, value: Any, bounds: tuple[float, float], unit: str) -> None:
    _finite(name, value, unit)
    if not bounds[0] <= value <= bounds[1]:
        raise SceneError(name, value, f"must lie in [{bounds[0]:g}, {bounds[1]:g}] {unit}")


def _replace_path(obj: Any, parts: list[str], value: Any, full: str) -> Any:
    if not dataclasses.is_dataclass(obj) or isinstance(obj, type):  # a field's value, never a class
        raise SceneError(full, value, "is not a scene field")
    if isinstance(obj, Material) and parts == ["name"]:  # block.material.name = "NAME": that material
        if not isinstance(value, str):
            raise SceneError(full, value, "must be the name of a material (scene/materials.toml)")
        return coerce_value(Material, value, full)
    names = {f.name for f in dataclasses.fields(obj)}
    if parts[0] not in names:
        raise SceneError(full, value, f"unknown field '{parts[0]}'; known: {', '.join(sorted(names))}")
    if len(parts) == 1:
        hints = typing.get_type_hints(type(obj))
        return dataclasses.replace(obj, **{parts[0]: coerce_value(hints[parts[0]], value, full)})
    child = _replace_path(getattr(obj, parts[0]), parts[1:], value, full)
    return dataclasses.replace(obj, **{parts[0]: child})


def coerce_value(tp: Any, value: Any, where: str) -> Any:
    """Convert a TOML value to the annotated type, refusing wrong types with the field name."""
    origin = typing.get_origin(tp)
    args = typing.get_args(tp)
    if origin is typing.Union or origin is types.UnionType:  # X | None (or Optional[X])
        if value is None:
            return None
        inner = [a for a in args if a is not type(None)]
        return coerce_value(inner[0], value, where)
    if tp is Material and isinstance(value, str):  # material = "NAME"
        return from_table(tp, named_material(value, where), where)
    if tp is Material and isinstance(value, dict) and "name" in value:  # name = "NAME" + overrides
        base = named_material(value["name"], f"{where}.name")
        return from_table(tp, {**base, **{k: v for k, v in value.items() if k != "name"}}, where)
    if isinstance(tp, type) and dataclasses.is_dataclass(tp):
        if not isinstance(value, dict):
            raise SceneError(where, value, f"must be a table of {tp.__name__} fields")
        return from_table(tp, value, where)
    if origin is tuple:
        if not isinstance(value, (list, tuple)):
            raise SceneError(where, value, "must be an array")
        if len(args) == 2 and args[1] is Ellipsis:
            return tuple(coerce_value(args[0], v, f"{where}[{i}]") for i, v in enumerate(value))
        if len(value) != len(args):
            raise SceneError(where, list(value), f"must have {len(args)} components")
        return tuple(coerce_value(a, v, f"{where}[{i}]") for i, (a, v) in enumerate(zip(args, value)))
    if tp is float:
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise SceneError(where, value, "must be a number")
        return float(value)
    if tp is int:
        if isinstance(value, bool) or not isinstance(value, int):
            raise SceneError(where, value, "must be an integer")
        return value
    if tp is bool:
        if not isinstance(value, bool):
            raise SceneError(where, value, "must be true or false")
        return value
    if tp is str:
        if not isinstance(value, str):
            raise SceneError(where, value, "must be a string")
        return value
    raise TypeError(f"unsupported field type {tp!r} at {where}")


def from_table(cls: type, data: dict, where: str) -> Any:
    hints = typing.get_type_hints(cls)
    names = [f.name for f in dataclasses.fields(cls)]
    kwargs = {}
    for key, value in data.items():
        path = f"{where}.{key}" if where else key
        if key not in names:
            raise SceneError(path, value, f"unknown key; allowed here: {', '.join(names)}")
        kwargs[key] = coerce_value(hints[key], value, path)
    required = [
        f.name
        for f in dataclasses.fields(cls)
        if f.default is dataclasses.MISSING and f.default_factory is dataclasses.MISSING
    ]
    missing = [n for n in required if n not in kwargs]
    if missing:
        raise SceneError(
            where or cls.__name__, data, f"incomplete: give {', '.join(missing)} (required here: {', '.join(required)})"
        )
    try:
        return cls(**kwargs)
    except TypeError as exc:  # a required field missing
        raise SceneError(where or cls.__name__, data, f"incomplete: {exc}") from None
