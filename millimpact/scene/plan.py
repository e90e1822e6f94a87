"""The plan: what a scene needs, derived from its Hertz estimate (foundations.md section 5).

Every choice (symmetry, contact-zone radius, element sizes, initial gap, time steps, modal cutoff)
is computed here from the scene, can be overridden in ``scene.model`` / ``scene.time`` /
``scene.impact.gap``, and is reported with its reason by :meth:`Plan.table`.

The plan also carries the scene's derived numbers that the lower stages need, so that the scene
itself stops at the methods (the top of the flow): the ball and the struck body's materials, the
impact point, contact normal, arrival velocity and friction coefficient, and the places the
recorder probes (:class:`ProbeSpec`: the contact point and each gauge, mirrored into the kept part
of a symmetric model and nudged just inside the struck body, so that one cell holds each).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import SceneError
from ..theory.hertz import HertzImpact, effective_modulus, hertz_impact
from ..theory.thornton import plastic_zone_radius
from .liner_shape import vec3
from .schema import Ball, Material, Scene, Vec3

#: elements across the Hertz contact radius a_max: ~4 gives ~1 % on F_max (foundations.md section 3)
ELEMENTS_ACROSS_CONTACT = 4.0
#: contact-zone radius in units of a_max: the zone must hold the whole contact patch with margin
ZONE_RADIUS_FACTOR = 4.0
#: a plastic scene's contact zone reaches at least this many predicted plastic radii
#: (:func:`predict_plastic_radius`): the plastic region measured on the half-space (h = a_max / 3,
#: zone 5.5 a_max, threshold alpha 1e-6) over Y = 0.38-3 GPa at 3 m/s reached 0.69-1.33 of the
#: prediction (1.23 at Y 0.38 GPa, 1.33 at 1 GPa, 1.07 at 2 GPa, 0.69 at 3 GPa near the onset; the
#: rig with both steels plastic 1.32): 1.75 keeps the largest inside with a few elements to spare
PLASTIC_ZONE_MARGIN = 1.75
#: ... but at most this share of the zone-radius limit (:func:`zone_radius_limit`)
PLASTIC_ZONE_CAP = 0.98
#: initial gap in units of delta_max (the flight to contact is exact, so it only needs to be > 0)
GAP_FACTOR = 0.05
#: steps per contact duration while in contact
STEPS_PER_CONTACT = 100
#: modal cutoff in units of 1/t_c (foundations.md section 4: keep modes up to (3-5)/t_c)
F_CUT_FACTOR = 4.0
#: what the plan's degree, P1, gives (``--method full``): too stiff by a few percent whatever
#: h_contact (measured: hertz-halfspace F_max +3.0 %, t_c -3.0 % against Hertz, P2 +1.0 %; the rig
#: +2.8 % against P2 on the same mesh: docs/validation.md, benchmarks/full_hertz.py). P1 stays the
#: default: P2 on the same tetrahedra has ~7-8x the DOFs (a node on every edge as well), and
#: --method improved gives P2's accuracy at a fraction of its cost
P1_EXPECTED_ERROR = "F_max about +3 % and t_c about -3 % against the converged answer"
P2_REMEDY = "--degree 2 (model.degree = 2) or --method improved is within ~1 %"
#: a ball whose radius is at most this share of the struck body's smallest side is a *small ball*
#: (a hardness-test tip on a block, a 2.5 mm ball on hertz-halfspace's 100 mm block): its far
#: size R / 4 stays inside the ball, and the struck body's far size is its own side / 4, so the
#: block's cost follows the contact, not the ball (the 2.5 mm ball on the 100 mm block
#: meshed everything at R / 4 and passed 9 GB). Every built-in scene has a ball larger than this
#: (hertz-halfspace: 0.15 of its 100 mm block) and keeps its plan.
SMALL_BALL_SHARE = 0.1
#: a small ball's plan (:data:`SMALL_BALL_SHARE`) grows the element size by at most this much per
#: unit distance from the contact zone (the builders' Threshold field), so its block's element
#: count goes with log(block size / contact size) (int 4 pi r^2 dr / (g r)^3). Other plans keep
#: their growth over SIZE_GROWTH_ZONE_RADII zone radii (0.13-0.26 on the built-in scenes' full
#: plans, up to ~0.4 with the reduced methods' smaller zones), so their meshes are unchanged.
MAX_SIZE_GROWTH = 0.3
#: the size reaches h_far this many zone radii beyond fine_radius
SIZE_GROWTH_ZONE_RADII = 3.0


def size_growth_distance(h_contact: float, h_far: float, zone_radius: float, small_ball: bool) -> float:
    """The distance (m) beyond fine_radius over which the element size grows linearly from
    h_contact to h_far: SIZE_GROWTH_ZONE_RADII zone radii; for a ``small_ball`` plan (h_ball > 0)
    longer when needed, so that the growth rate (h_far - h_contact) / distance stays at most
    MAX_SIZE_GROWTH."""
    distance = SIZE_GROWTH_ZONE_RADII * zone_radius
    return max(distance, (h_far - h_contact) / MAX_SIZE_GROWTH) if small_ball else distance


#: elements per shear wavelength at f_cut in the far mesh of a liner with gauges: the phase error
#: of linear elements is ~(k h)^2 / 24 (k = 2 pi / wavelength), 0.4 % at 20 (Marfurt, Geophysics 49
#: (1984) 533-549, for the order of the error)
WAVE_ELEMENTS = 20.0


def wave_element_size(material: Material, f_cut: float) -> float:
    """The far element size (m) of :data:`WAVE_ELEMENTS` elements per shear wavelength
    c_s / f_cut, c_s = sqrt(G / rho) (m/s), f_cut in Hz."""
    return (material.shear_modulus / material.density) ** 0.5 / f_cut / WAVE_ELEMENTS


def scene_hertz(scene: Scene) -> HertzImpact:
    """Hertz values of a scene: the ball on a half-space of the block's material (the block is
    clamped, so the impacting mass is the ball's), with the normal component of the velocity."""
    e_star = effective_modulus(scene.ball.material, scene.target_material)
    return hertz_impact(scene.ball.radius, scene.ball.mass, scene.normal_speed, e_star, scene.target_material.poisson)


def smallest_size(scene: Scene) -> float:
    """The smallest body size of a scene (m): the ball radius, the block's sides, or the liner's
    length, plate thickness and lifter top."""
    if scene.liner is not None:
        ln = scene.liner
        body = (ln.length, ln.thickness, ln.lifter_top_width)
    else:
        body = (scene.block.length, scene.block.thickness, scene.block.height)
    return min(scene.ball.radius, *body)


def smallest_body_side(scene: Scene) -> tuple[str, float]:
    """The struck body's smallest size (m) and the scene field that sets it."""
    if scene.liner is not None:
        ln = scene.liner
        sides = {
            "liner.length": ln.length,
            "liner.thickness": ln.thickness,
            "liner.lifter_top_width": ln.lifter_top_width,
        }
    else:
        sides = {
            "block.length": scene.block.length,
            "block.thickness": scene.block.thickness,
            "block.height": scene.block.height,
        }
    return min(sides.items(), key=lambda kv: kv[1])


#: a zone sphere reaches at most this share of its body's smallest size (the far side stays out)
ZONE_SIZE_SHARE = 0.45


def is_small_ball(scene: Scene) -> bool:
    """True when the ball's radius is at most :data:`SMALL_BALL_SHARE` of the struck body's
    smallest side: its far size and its contact zone are the ball's own (:func:`make_plan`)."""
    return scene.ball.radius <= SMALL_BALL_SHARE * smallest_body_side(scene)[1]


def zone_radius_limit(scene: Scene) -> float:
    """The contact zone must stay below this radius (m): 0.45 of the smallest body size, so the
    zone sphere does not reach the far side of the ball or the body. The ball's zone is capped on
    its own (:attr:`Plan.ball_zone_radius`) for a small ball, and where ``model.zone_radius`` asks
    for more than the ball allows (a struck body whose plastic region outgrows the ball's zone,
    repeated impacts): the limit is then the struck body's."""
    own = is_small_ball(scene) or scene.model.zone_radius is not None
    return ZONE_SIZE_SHARE * (smallest_body_side(scene)[1] if own else smallest_size(scene))


#: ``model.strain = "auto"`` takes finite strain where Thornton's largest contact radius a_p
#: (:func:`millimpact.theory.thornton.plastic_zone_radius`) passes this share of the effective
#: radius: Tabor's representative strain 0.2 a/R is then 0.03, and the largest equivalent plastic
#: strain measured on the perfectly plastic sphere, 3-4 times Tabor's (docs: plasticity,
#: "Restitution against V / V_y"), passes the small-strain limit of 0.1 (between 100 and 183 V_y)
FINITE_STRAIN_CONTACT_SHARE = 0.15


#: a plastic body whose predicted plastic radius (Johnson's cavity c) passes this share of its
#: contact zone's radius is plastic in every cell (the full method's region cells, the reduced
#: methods' whole body kept unreduced in the zone): on
#: the perfectly plastic sphere (docs: plasticity) the plastic region reached the 6.6 mm zone's
#: boundary at 300 V_y (c = 0.97 of the zone) and stayed 1.1 mm inside it at 183 V_y (c = 0.70)
WHOLE_BODY_SHARE = 0.85


def whole_plastic_bodies(scene: Scene, h: HertzImpact, zone: float, ball_zone: float, reasons: dict[str, str]):
    """The bodies ("ball", "struck") whose predicted plastic region does not fit their contact zone
    (c > WHOLE_BODY_SHARE x its radius): every cell of them is made plastic (the reduced methods keep
    such a body whole, unreduced, in the zone). A zone the
    scene gives (``model.zone_radius``) is the user's: kept, and a run warns if plasticity reaches
    its boundary."""
    if scene.model.zone_radius is not None:
        return ()
    out = []
    for body, mat, z in (("ball", scene.ball.material, ball_zone or zone), ("struck", scene.target_material, zone)):
        if (y := mat.initial_yield_stress) is None:
            continue
        c = plastic_zone_radius(h.radius, h.mass, h.speed, h.e_star, y, mat.poisson)[1]
        if c > WHOLE_BODY_SHARE * z:
            out.append(body)
            reasons[f"plastic_whole_{body}"] = (
                f"predicted plastic radius {c * 1e3:.3g} mm > {WHOLE_BODY_SHARE:g} x its zone ({z * 1e3:.3g} mm): "
                f"every cell of the {'ball' if body == 'ball' else 'struck body'} is plastic"
            )
    return tuple(out)


def choose_strain(scene: Scene, h: HertzImpact, reasons: dict[str, str]) -> str:
    """``small`` or ``finite``: ``model.strain`` unless it is auto, else finite where a plastic
    material's predicted contact radius passes FINITE_STRAIN_CONTACT_SHARE of the radius."""
    asked = scene.model.strain
    if asked != "auto":
        reasons["strain"] = "user"
        return asked
    shares = [
        plastic_zone_radius(h.radius, h.mass, h.speed, h.e_star, y, m.poisson)[0] / h.radius
        for m in (scene.ball.material, scene.target_material)
        if (y := m.initial_yield_stress) is not None
    ]
    share = max(shares, default=0.0)
    if share > FINITE_STRAIN_CONTACT_SHARE:
        reasons["strain"] = (
            f"contact radius {share:.3g} R > {FINITE_STRAIN_CONTACT_SHARE:g} R: plastic strains past 0.1 "
            "(logarithmic-strain J2)"
        )
        return "finite"
    reasons["strain"] = (
        f"contact radius {share:.3g} R <= {FINITE_STRAIN_CONTACT_SHARE:g} R: small-strain J2"
        if shares
        else "elastic materials"
    )
    return "small"


def predict_plastic_radius(h: HertzImpact, materials: tuple[Material, ...]) -> float:
    """The radius (m) of the plastic region an impact ``h`` leaves about the impact point: the
    largest of Johnson's expanding-cavity radius c over the plastic ``materials`` (each with its
    initial yield stress; :func:`millimpact.theory.thornton.plastic_zone_radius` on Thornton's
    contact radius); 0 when none yields."""
    # a material is plastic exactly when it has an initial yield stress
    radii = [
        plastic_zone_radius(h.radius, h.mass, h.speed, h.e_star, y, m.poisson)[1]
        for m in materials
        if (y := m.initial_yield_stress) is not None
    ]
    return max(radii, default=0.0)


@dataclass(frozen=True)
class GaugePlace:
    """A strain gauge where the model holds it: ``point`` (m) just inside the struck body's kept
    part (mirrored into it on a symmetric model), unit ``direction`` (mirrored with it); the
    gauge reports sigma = E d.eps.d (Pa)."""

    name: str
    point: Vec3
    direction: Vec3


@dataclass(frozen=True)
class ProbeSpec:
    """What a recorder observes of an impact, in the model's coordinates (SI units).

    ``contact_point`` the impact point nudged just inside the struck body (and off the symmetry
    planes); ``gauges`` the gauges' places; ``material`` the struck body's elastic constants
    (stresses from strains); ``liner`` True when the struck body is a liner (normal quantities
    along the contact normal n rather than -y); ``slide_direction`` the unit tangential
    direction of the arrival velocity (None for a normal impact: the contact's first tangent
    is used); ``gap`` the initial gap (m), subtracted from the ball's travel to give the approach;
    ``patch_radius`` (m) the radius of the material patch under the contact point whose centre of
    mass gives the contact point's velocity and acceleration (the Hertz a_max; 0: the surface
    node's values); ``band_limit_hz`` the frequency at which those two are band-limited
    (:mod:`millimpact.results.band_limit`: F_CUT_FACTOR / t_c, the band the models resolve; 0: raw).
    """

    contact_point: Vec3
    gauges: tuple[GaugePlace, ...]
    material: Material
    liner: bool
    slide_direction: Vec3 | None
    gap: float
    patch_radius: float = 0.0
    band_limit_hz: float = 0.0

    @property
    def gauge_names(self) -> tuple[str, ...]:
        return tuple(g.name for g in self.gauges)


@dataclass(frozen=True)
class Plan:
    """Modelling choices for a scene, all in SI units; below ``degree``, the scene's derived
    numbers that the lower stages need (not printed by :meth:`table`)."""

    hertz: HertzImpact
    symmetry: str  #: full | half | quarter
    symmetry_planes: tuple[str, ...]  #: subset of ("x", "z"): x = x_p and z = z_p planes are cut
    h_contact: float  #: element size at the contact point, m
    h_far: float  #: element size far from it, m
    zone_radius: float  #: contact-zone radius around the contact point (both bodies), m
    fine_radius: float  #: radius within which the size is h_contact, m
    gap: float  #: initial gap between ball and face, m
    dt_contact: float  #: step while in contact, s
    dt_free: float  #: step in free vibration, s
    f_cut: float  #: modal cutoff frequency, Hz
    degree: int  #: Lagrange degree of the full model
    ball: Ball  #: the ball: radius (m), material; its mass ``ball.mass`` (kg)
    target: Material  #: the struck body's material (the block's or the liner's)
    impact_point: Vec3  #: point p of first contact on the struck face, m
    contact_normal: Vec3  #: outward unit normal n of the struck face at p
    velocity: Vec3  #: the ball's arrival velocity, m/s
    friction: float  #: Coulomb coefficient between ball and struck body
    probes: ProbeSpec  #: what a recorder observes, and where
    reasons: tuple[tuple[str, str], ...] = ()
    #: predicted radius of the plastic region about the impact point (m; 0 if the materials are
    #: elastic or the impact stays below the yield onset): :func:`predict_plastic_radius`
    plastic_radius: float = 0.0
    #: normal stiffness per area (Pa/m) of a liner's rubber backing on its back face (a Winkler
    #: layer, :mod:`millimpact.fem.model`); 0: the back face is clamped (or not a liner)
    backing_stiffness: float = 0.0
    #: the ball's far element size (m) when it differs from h_far (a small ball:
    #: :data:`SMALL_BALL_SHARE`); 0: h_far in both bodies
    h_ball: float = 0.0
    #: the contact zone's radius in the ball (m) when smaller than zone_radius (a small ball whose
    #: zone in the block is larger than the ball allows); 0: zone_radius in both bodies
    ball_zone_radius: float = 0.0
    #: the plastic zone's kinematics: ``small`` or ``finite`` strain (:func:`choose_strain`)
    strain: str = "small"
    #: the bodies ("ball", "struck") plastic in every cell, not in their zone alone: their plastic
    #: region does not fit the zone (:func:`whole_plastic_bodies`)
    plastic_whole: tuple[str, ...] = ()

    @property
    def ball_zone(self) -> float:
        """The contact zone's radius in the ball, m."""
        return self.ball_zone_radius or self.zone_radius

    @property
    def normal_speed(self) -> float:
        """Speed towards the struck face, -v . n (m/s): the Hertz estimate's speed."""
        return self.hertz.speed

    def table(self) -> list[tuple[str, str, str]]:
        """(name, value with unit, reason) rows for printing."""
        why = dict(self.reasons)
        rows = [
            (
                "symmetry",
                f"{self.symmetry} (cut planes: {', '.join(self.symmetry_planes) or 'none'})",
                why.get("symmetry", ""),
            ),
            ("h_contact", f"{self.h_contact * 1e3:.4g} mm", why.get("h_contact", "")),
            ("h_far", f"{self.h_far * 1e3:.4g} mm", why.get("h_far", "")),
            *([("h_ball", f"{self.h_ball * 1e3:.4g} mm", why.get("h_ball", ""))] if self.h_ball > 0 else []),
            ("zone_radius", f"{self.zone_radius * 1e3:.4g} mm", why.get("zone_radius", "")),
            *(
                [("ball_zone_radius", f"{self.ball_zone_radius * 1e3:.4g} mm", why.get("ball_zone_radius", ""))]
                if self.ball_zone_radius > 0
                else []
            ),
            ("fine_radius", f"{self.fine_radius * 1e3:.4g} mm", why.get("fine_radius", "")),
            ("gap", f"{self.gap * 1e6:.4g} um", why.get("gap", "")),
            ("dt_contact", f"{self.dt_contact * 1e6:.4g} us", why.get("dt_contact", "")),
            ("dt_free", f"{self.dt_free * 1e6:.4g} us", why.get("dt_free", "")),
            ("f_cut", f"{self.f_cut / 1e3:.4g} kHz", why.get("f_cut", "")),
            ("degree", f"P{self.degree}", why.get("degree", "")),
        ]
        if self.plastic_radius > 0 or self.strain == "finite":
            rows.append(("strain", self.strain, why.get("strain", "")))
        for body in self.plastic_whole:
            value = "ball" if body == "ball" else "struck body"
            rows.append(("plastic_whole", value, why.get(f"plastic_whole_{body}", "")))
        if self.plastic_radius > 0:
            rows.insert(
                4 if self.h_ball > 0 else 3,
                (
                    "plastic_radius",
                    f"{self.plastic_radius * 1e3:.4g} mm ({self.plastic_radius / self.hertz.a_max:.3g} a_max)",
                    why.get("plastic_radius", ""),
                ),
            )
        return rows


def decide_symmetry(scene: Scene) -> tuple[str, tuple[str, ...], str]:
    """Which symmetry planes the scene allows.

    The plane x = x_p is a symmetry plane if the impact point is at x = 0 (the block is symmetric
    about x = 0) and the velocity has no x component. The plane z = z_p needs the block and its
    support symmetric about it: only with ``support = "back"``, the point at mid-height and no z
    velocity. The ball is symmetric about any plane through its centre.
    """
    x_p, _, z_p = scene.impact_point
    vx, _, vz = scene.impact.velocity
    tol = 1e-12
    planes = []
    if abs(x_p) < 1e-9 and abs(vx) <= tol * scene.impact.speed:
        planes.append("x")  # a liner is prismatic along x and symmetric about x = 0 as well
    if scene.liner is None and (
        scene.block.support == "back"
        and abs(z_p - 0.5 * scene.block.height) < 1e-9
        and abs(vz) <= tol * scene.impact.speed
    ):
        planes.append("z")
    allowed = {0: "full", 1: "half", 2: "quarter"}[len(planes)]
    req = scene.model.symmetry
    if req == "auto":
        reason = f"{allowed}: " + (
            "; ".join(
                {
                    "x": (
                        "velocity in the plane of incidence x = 0 (liner: prismatic along x)"
                        if scene.liner is not None
                        else "normal velocity in the x = 0 mid-plane"
                    ),
                    "z": "back-clamped block struck at mid-height",
                }[p]
                for p in planes
            )
            or "no symmetry plane (oblique or off-centre impact)"
        )
        return allowed, tuple(planes), reason
    order = ["full", "half", "quarter"]
    if order.index(req) > order.index(allowed):
        raise SceneError("model.symmetry", req, f"the scene allows at most '{allowed}' (planes: {planes or 'none'})")
    if req == "full":
        planes = []
    elif req == "half":
        planes = planes[:1]
    return req, tuple(planes), "user choice"


def mirror_into_model(
    point: np.ndarray, direction: np.ndarray, planes: tuple[str, ...], impact_point: Vec3
) -> tuple[np.ndarray, np.ndarray]:
    """Map a point (and a direction) on the full body into the kept part of a symmetric model
    (cut by the x = x_p and z = z_p ``planes`` through the impact point)."""
    x_p, _, z_p = impact_point
    p, d = np.array(point, float), np.array(direction, float)
    if "x" in planes and p[0] < x_p:
        p[0], d[0] = 2 * x_p - p[0], -d[0]
    if "z" in planes and p[2] < z_p:
        p[2], d[2] = 2 * z_p - p[2], -d[2]
    return p, d


def inward_point(point: np.ndarray, scene: Scene, planes: tuple[str, ...], h_contact: float) -> np.ndarray:
    """A point nudged just inside the struck body (and off the symmetry ``planes``) by 1e-6
    ``h_contact`` (m), so that one cell holds it."""
    eps = 1e-6 * h_contact
    p = np.array(point, float)
    if scene.liner is not None:  # the liner's contact point: along -n into the lifter
        p = p - eps * np.asarray(scene.contact_normal)
        if "x" in planes:
            p[0] = max(p[0], scene.impact_point[0] + eps)
        return p
    blk = scene.block
    p[1] = min(p[1], -eps)
    p[1] = max(p[1], -blk.thickness + eps)
    p[0] = np.clip(p[0], -blk.length / 2 + eps, blk.length / 2 - eps)
    p[2] = np.clip(p[2], eps, blk.height - eps)
    x_p, _, z_p = scene.impact_point
    if "x" in planes:
        p[0] = max(p[0], x_p + eps)
    if "z" in planes:
        p[2] = max(p[2], z_p + eps)
    return p


def slide_direction(velocity: Vec3, normal: Vec3) -> Vec3 | None:
    """The unit tangential direction of ``velocity`` on the plane of unit ``normal``; None when
    the velocity is normal to it (tangential part below 1e-12 of the speed)."""
    v, n = np.array(velocity), np.array(normal)
    vt = v - (v @ n) * n
    if np.linalg.norm(vt) > 1e-12 * np.linalg.norm(v):
        return vec3(vt / np.linalg.norm(vt))
    return None


def make_probe_spec(
    scene: Scene,
    planes: tuple[str, ...],
    h_contact: float,
    gap: float,
    patch_radius: float = 0.0,
    band_limit_hz: float = 0.0,
) -> ProbeSpec:
    """Where a model of ``scene`` (cut by the symmetry ``planes``, contact element size
    ``h_contact``) is probed: the contact point and each gauge, inside the struck body's kept
    part; ``patch_radius``: see :class:`ProbeSpec`."""
    contact_point = inward_point(np.array(scene.impact_point), scene, planes, h_contact)
    gauges = []
    for g in scene.gauges:
        p, d = mirror_into_model(np.array(g.position), np.array(g.direction), planes, scene.impact_point)
        gauges.append(GaugePlace(g.name, vec3(inward_point(p, scene, planes, h_contact)), vec3(d / np.linalg.norm(d))))
    return ProbeSpec(
        vec3(contact_point),
        tuple(gauges),
        scene.target_material,
        scene.liner is not None,
        slide_direction(scene.impact.velocity, scene.contact_normal),
        gap,
        patch_radius,
        band_limit_hz,
    )


@dataclass(frozen=True)
class _ElementSizes:
    """The plan's element sizes (m): ``h_contact`` at the contact point, ``h_far`` far from it in
    the struck body (and in the ball unless ``h_ball`` > 0, a small ball's own far size)."""

    h_contact: float
    h_far: float
    h_ball: float


@dataclass(frozen=True)
class _Zones:
    """The plan's contact zones (m): ``zone`` about the contact point in both bodies,
    ``ball_zone`` the ball's own when smaller (0: ``zone``), ``fine`` the radius meshed at
    h_contact; ``plastic_radius`` the predicted plastic region's radius (0: elastic)."""

    zone: float
    ball_zone: float
    fine: float
    plastic_radius: float


@dataclass(frozen=True)
class _TimeSteps:
    """The plan's initial gap (m), contact and free-vibration steps (s) and modal cutoff (Hz)."""

    gap: float
    dt_contact: float
    dt_free: float
    f_cut: float


def _element_sizes(scene: Scene, h: HertzImpact, reasons: dict[str, str]) -> _ElementSizes:
    """The element sizes (m): h_contact = a_max / ELEMENTS_ACROSS_CONTACT, h_far = the smallest
    body size / 4 (a small ball: the struck body's smallest side / 4, the ball's radius / 4 inside
    the ball; a liner with gauges: at most :func:`wave_element_size` at the planned f_cut), unless
    ``scene.model`` gives them; each choice's reason goes into ``reasons``."""
    m = scene.model
    h_c = m.h_contact if m.h_contact is not None else h.a_max / ELEMENTS_ACROSS_CONTACT
    reasons["h_contact"] = "user" if m.h_contact is not None else f"a_max / {ELEMENTS_ACROSS_CONTACT:g} (~1 % on F_max)"
    smallest = smallest_size(scene)
    h_far = m.h_far if m.h_far is not None else smallest / 4.0
    reasons["h_far"] = "user" if m.h_far is not None else "smallest body size / 4"
    side_field, side = smallest_body_side(scene)
    h_ball = 0.0
    if m.h_far is None and is_small_ball(scene):
        # a small ball on a large body: the body far from the contact carries only the static
        # compliance and the low modes, which its own size sets; the contact's stress field decays
        # within a few contact radii, which the growth from h_contact resolves
        h_far, h_ball = side / 4.0, scene.ball.radius / 4.0
        reasons["h_far"] = (
            f"{side_field} / 4: a small ball (radius <= {SMALL_BALL_SHARE:g} x the body's smallest "
            f"side), the size grows from the contact at <= {MAX_SIZE_GROWTH:g} per unit distance: "
            "the cost follows the contact, not the block"
        )
        reasons["h_ball"] = "ball radius / 4 inside the ball (small ball)"
    f_cut_plan = m.f_cut if m.f_cut is not None else F_CUT_FACTOR / h.contact_time
    h_wave = wave_element_size(scene.target_material, f_cut_plan)
    if m.h_far is None and scene.liner is not None and scene.gauges and h_wave < h_far:
        # a liner's gauges sit away from the impact (a bolt hole, a lifter root): the waves that
        # reach them are the answer there, so the far mesh resolves them up to the cutoff
        h_far = h_wave
        reasons["h_far"] = (
            f"shear wavelength at f_cut / {WAVE_ELEMENTS:g} (gauges away from the impact; "
            "P1 phase error (k h)^2 / 24 ~ 0.4 %)"
        )
    if h_ball >= h_far:  # the wave size above took the body's far size below the ball's
        h_ball = 0.0
        reasons.pop("h_ball", None)
    return _ElementSizes(h_c, h_far, h_ball)


def _zone_radius(scene: Scene, h: HertzImpact, c_p: float, reasons: dict[str, str]) -> float:
    """The contact zone's radius (m): ZONE_RADIUS_FACTOR a_max or PLASTIC_ZONE_MARGIN times the
    predicted plastic radius ``c_p`` (m), whichever is larger, capped at PLASTIC_ZONE_CAP of
    :func:`zone_radius_limit`, unless ``model.zone_radius`` gives it; refuses a zone that reaches
    the limit (SceneError on model.zone_radius)."""
    m = scene.model
    zone = m.zone_radius if m.zone_radius is not None else max(ZONE_RADIUS_FACTOR * h.a_max, PLASTIC_ZONE_MARGIN * c_p)
    reasons["zone_radius"] = (
        "user"
        if m.zone_radius is not None
        else f"{ZONE_RADIUS_FACTOR:g} a_max (holds the contact patch)"
        if zone == ZONE_RADIUS_FACTOR * h.a_max
        else f"{PLASTIC_ZONE_MARGIN:g} plastic_radius (holds the plastic region)"
    )
    limit = zone_radius_limit(scene)
    if m.zone_radius is None and zone > PLASTIC_ZONE_CAP * limit:
        # the margins ask for more than the bodies allow (a fast impact of a small ball): take what
        # they allow; the contact candidates need 1.2 a_max + 2 h_contact (checked by the
        # methods), and a plastic run's zone-boundary check says whether the plastic region stayed
        # inside
        zone = PLASTIC_ZONE_CAP * limit
        reasons["zone_radius"] = (
            f"{zone / h.a_max:.3g} a_max: capped by the bodies' size (0.45 x the smallest, {limit:g} m)"
        )
    if zone >= limit:
        raise SceneError("model.zone_radius", zone, f"the contact zone must be smaller than {limit:g} m for this scene")
    return zone


def _ball_zone_radius(scene: Scene, zone: float, reasons: dict[str, str]) -> float:
    """The ball's own contact-zone radius (m; 0: the zone's radius ``zone``): a small ball's is
    capped at PLASTIC_ZONE_CAP x ZONE_SIZE_SHARE of its radius, ``model.ball_zone_radius`` sets
    it (refused above that cap or above ``zone``)."""
    m = scene.model
    ball_zone = 0.0
    ball_limit = PLASTIC_ZONE_CAP * ZONE_SIZE_SHARE * scene.ball.radius
    own = is_small_ball(scene) or (m.zone_radius is not None and m.zone_radius > ball_limit)
    if own and zone > ball_limit:
        # the block's plastic region is larger than the ball allows: the ball's zone stays inside
        # it and holds the contact patch (the candidates need 1.2 a_max + 2 h_contact)
        ball_zone = ball_limit
        reasons["ball_zone_radius"] = (
            f"{PLASTIC_ZONE_CAP:g} x {ZONE_SIZE_SHARE:g} ball radius: the ball's own zone (the struck body's is larger)"
        )
    if m.ball_zone_radius is not None:
        # the ball's own zone (a repeated-impact sequence: the liner's plastic region grows, the
        # ball's stays small), no larger than the zone and than the ball allows
        top = min(zone, ball_limit) if own else zone
        if m.ball_zone_radius > top:
            raise SceneError(
                "model.ball_zone_radius",
                m.ball_zone_radius,
                f"must be at most {top:g} m (the contact zone's radius"
                + (f", and {PLASTIC_ZONE_CAP:g} x {ZONE_SIZE_SHARE:g} the ball radius)" if top < zone else ")"),
            )
        ball_zone = m.ball_zone_radius if m.ball_zone_radius < zone else 0.0
        reasons["ball_zone_radius"] = "user"
    return ball_zone


def _zones(scene: Scene, h: HertzImpact, h_c: float, reasons: dict[str, str]) -> _Zones:
    """The contact zones of a scene with Hertz values ``h`` and contact element size ``h_c`` (m):
    the predicted plastic radius, the zone (:func:`_zone_radius`), the ball's zone
    (:func:`_ball_zone_radius`) and the fine radius 1.5 a_max (or ``model.fine_radius``, at most
    the zone); refuses an h_contact over half the zone, naming the field to change."""
    m = scene.model
    c_p = predict_plastic_radius(h, (scene.ball.material, scene.target_material))
    reasons["plastic_radius"] = "Johnson's cavity model on Thornton's contact radius (theory/thornton.py)"
    zone = _zone_radius(scene, h, c_p, reasons)
    ball_zone = _ball_zone_radius(scene, zone, reasons)
    fine = min(1.5 * h.a_max, ball_zone or zone)
    reasons["fine_radius"] = "1.5 a_max: h_contact over the whole contact patch"
    if m.fine_radius is not None:
        # a fast plastic impact's plastic region (and contact) outgrows 1.5 a_max: the user can
        # mesh the whole region at h_contact (benchmarks/plastic_restitution.py)
        if m.fine_radius > (ball_zone or zone):
            raise SceneError(
                "model.fine_radius", m.fine_radius, f"must be at most the contact-zone radius ({ball_zone or zone:g} m)"
            )
        fine, reasons["fine_radius"] = m.fine_radius, "user"
    if h_c > (ball_zone or zone) / 2:
        if m.h_contact is not None:
            raise SceneError("model.h_contact", h_c, f"must be at most half the contact-zone radius ({zone / 2:g} m)")
        if m.zone_radius is not None:
            raise SceneError(
                "model.zone_radius",
                zone,
                f"must be at least 2 h_contact = {2 * h_c:.4g} m "
                f"(h_contact = a_max / {ELEMENTS_ACROSS_CONTACT:g} of this impact)",
            )
        raise contact_too_large(scene, h)
    return _Zones(zone, ball_zone, fine, c_p)


def _time_steps(scene: Scene, h: HertzImpact, reasons: dict[str, str]) -> _TimeSteps:
    """The initial gap GAP_FACTOR delta_max (m), the contact step t_c / STEPS_PER_CONTACT (s), the
    cutoff F_CUT_FACTOR / t_c (Hz) and the free step 1 / (10 f_cut) (s, at least the contact
    step), each unless the scene gives it; refuses a time.end shorter than the contact step."""
    m, t = scene.model, scene.time
    gap = scene.impact.gap if scene.impact.gap is not None else GAP_FACTOR * h.delta_max
    reasons["gap"] = (
        "user" if scene.impact.gap is not None else f"{GAP_FACTOR:g} delta_max (flight before contact is exact)"
    )
    dt_c = t.dt_contact if t.dt_contact is not None else h.contact_time / STEPS_PER_CONTACT
    reasons["dt_contact"] = "user" if t.dt_contact is not None else f"t_c / {STEPS_PER_CONTACT}"
    f_cut = m.f_cut if m.f_cut is not None else F_CUT_FACTOR / h.contact_time
    reasons["f_cut"] = "user" if m.f_cut is not None else f"{F_CUT_FACTOR:g} / t_c (docs: foundations, section 4)"
    # free vibration: resolve the kept band (10 steps per period of f_cut)
    dt_f = t.dt_free if t.dt_free is not None else max(dt_c, 1.0 / (10.0 * f_cut))
    reasons["dt_free"] = (
        "user" if t.dt_free is not None else "1 / (10 f_cut): ten steps per period of the highest kept mode"
    )
    reasons["degree"] = "user" if m.degree != 1 else f"P1 (default): expect {P1_EXPECTED_ERROR}; {P2_REMEDY}"
    if dt_c > t.end:
        raise SceneError("time.end", t.end, f"must exceed the contact step ({dt_c:g} s)")
    return _TimeSteps(gap, dt_c, dt_f, f_cut)


def make_plan(scene: Scene) -> Plan:
    """Derive the modelling choices of a scene from its Hertz estimate (foundations.md section 5): the
    symmetry (:func:`decide_symmetry`), the element sizes, the contact zones and the time steps,
    each with its reason, and the probes' places."""
    h = scene_hertz(scene)
    sym, planes, sym_reason = decide_symmetry(scene)
    reasons = {"symmetry": sym_reason}
    sizes = _element_sizes(scene, h, reasons)
    zones = _zones(scene, h, sizes.h_contact, reasons)
    steps = _time_steps(scene, h, reasons)
    strain = choose_strain(scene, h, reasons)
    whole = whole_plastic_bodies(scene, h, zones.zone, zones.ball_zone, reasons)
    return Plan(
        h,
        sym,
        planes,
        sizes.h_contact,
        sizes.h_far,
        zones.zone,
        zones.fine,
        steps.gap,
        steps.dt_contact,
        steps.dt_free,
        steps.f_cut,
        scene.model.degree,
        ball=scene.ball,
        target=scene.target_material,
        impact_point=scene.impact_point,
        contact_normal=scene.contact_normal,
        velocity=scene.impact.velocity,
        friction=scene.contact.friction,
        probes=make_probe_spec(scene, planes, sizes.h_contact, steps.gap, h.a_max, F_CUT_FACTOR / h.contact_time),
        reasons=tuple(reasons.items()),
        plastic_radius=zones.plastic_radius,
        backing_stiffness=scene.liner.backing_stiffness if scene.liner is not None else 0.0,
        h_ball=sizes.h_ball,
        ball_zone_radius=zones.ball_zone,
        strain=strain,
        plastic_whole=whole,
    )


#: the largest Hertz contact radius a_max the plan meshes, as a share of the smallest of the ball
#: radius and the struck body's sides: h_contact = a_max / 4 must be at most half the contact
#: zone, and the zone at most PLASTIC_ZONE_CAP x 0.45 of that size (:func:`zone_radius_limit`)
MAX_CONTACT_SHARE = 2.0 * PLASTIC_ZONE_CAP * 0.45 * 4.0 / ELEMENTS_ACROSS_CONTACT


def contact_too_large(scene: Scene, h: HertzImpact) -> SceneError:
    """The refusal of a scene whose Hertz contact is too large to mesh, naming the field to change.

    a_max = R (5 pi rho v^2 / (4 E*))^(1/5) (Johnson 1985, section 11.4, with m = 4/3 pi R^3 rho),
    so a_max / R does not depend on the radius. When a_max exceeds :data:`MAX_CONTACT_SHARE` of the
    ball radius, the materials and the speed are to blame (a contact as wide as the ball: Hertz's
    small-contact model no longer holds) and the speed limit is given (a_max ~ v^(2/5)); otherwise
    the ball is too large for the struck body and the radius limit is given."""
    share = MAX_CONTACT_SHARE
    ratio = h.a_max / scene.ball.radius
    side_field, side = smallest_body_side(scene)
    if ratio > share:
        v_max = h.speed * (share * min(scene.ball.radius, side) / h.a_max) ** 2.5
        return SceneError(
            "impact.velocity",
            list(scene.impact.velocity),
            f"with these materials (ball density {scene.ball.material.density:g} kg/m^3, contact "
            f"modulus E* {h.e_star:.3g} Pa) the Hertz contact radius a_max would be {ratio:.3g} x the "
            f"ball radius, more than the {share:.3g} the model meshes: the normal speed must be at most "
            f"{v_max:.3g} m/s (or the materials stiffer or lighter)",
        )
    r_max = scene.ball.radius * share * side / h.a_max
    return SceneError(
        "ball.radius",
        scene.ball.radius,
        f"must be at most {r_max:.3g} m on this {'liner' if scene.liner is not None else 'block'} "
        f"({side_field} = {side:g} m): its Hertz contact radius a_max = {h.a_max:.3g} m must stay "
        f"under {share:.3g} x the struck body's smallest side (or make the body's sides at least "
        f"{h.a_max / share:.3g} m)",
    )


#: first yield under a Hertz contact (von Mises, nu = 0.3): p0 = 1.60 Y on the axis at 0.48 a
#: (Johnson, Contact Mechanics, 1985, section 6.2)
FIRST_YIELD_PRESSURE_FACTOR = 1.60
#: the yield stress of a typical liner steel (Cr-Mo, ~350 HB; scene/materials.toml "cr-mo-liner"),
#: used to warn when an elastic scene's pressure would yield a real liner
TYPICAL_LINER_YIELD = 0.95e9


def elastic_limit_note(plan: Plan) -> str | None:
    """A note when an all-elastic scene's Hertz pressure exceeds first yield (p0 > 1.6 Y) of its
    materials' yield stresses (none given: of a typical liner steel), else None."""
    if plan.ball.material.plastic or plan.target.plastic:
        return None
    return _typical_steel_note(plan.hertz.p0)


def first_yield_notes(h: HertzImpact, ball: Material, target: Material, target_name: str) -> list[str]:
    """What the Hertz values ``h`` say about yielding: for each body with a yield stress Y, whether
    p0 exceeds its first-yield pressure 1.6 Y (Johnson 1985, section 6.2: von Mises, nu = 0.3);
    for an all-elastic scene, :func:`elastic_limit_note`'s comparison with a typical liner steel."""
    if not (ball.plastic or target.plastic):
        note = _typical_steel_note(h.p0)
        return [note] if note else []
    notes = []
    for body, m in (("ball", ball), (target_name, target)):
        if not m.plastic:
            continue
        y = m.initial_yield_stress
        assert y is not None, "a plastic material has an initial yield stress"
        limit = FIRST_YIELD_PRESSURE_FACTOR * y
        if h.p0 > limit:
            notes.append(
                f"beyond the elastic limit: p0 = {h.p0 / 1e9:.3g} GPa exceeds the {body}'s first-yield "
                f"pressure 1.6 Y = {limit / 1e9:.3g} GPa (Y {y / 1e9:.3g} GPa; Johnson 1985, 6.2): the "
                f"{body} yields, and these elastic values overestimate the peak force and the restitution "
                "(millimpact run with a plastic method gives the elastic-plastic answer)"
            )
        else:
            notes.append(
                f"within the elastic limit of the {body}: p0 = {h.p0 / 1e9:.3g} GPa <= 1.6 Y = "
                f"{limit / 1e9:.3g} GPa (Johnson 1985, 6.2)"
            )
    return notes


def _typical_steel_note(p0: float) -> str | None:
    """The elastic-limit note of an all-elastic scene (p0 in Pa), None below the limit."""
    limit = FIRST_YIELD_PRESSURE_FACTOR * TYPICAL_LINER_YIELD
    if p0 <= limit:
        return None
    return (
        f"elastic model beyond the elastic limit: Hertz p0 = {p0 / 1e9:.3g} GPa exceeds the first-yield pressure "
        f"1.6 Y = {limit / 1e9:.3g} GPa of a typical liner steel (Y {TYPICAL_LINER_YIELD / 1e9:g} GPa); real steels "
        f'yield here: set [block.material] / [liner.material] name = "cr-mo-liner" (or yield_stress) for the '
        f"elastic-plastic answer (methods improved, traditional, full; scene paper-rig-plastic is the rig so)"
    )
