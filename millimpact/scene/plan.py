"""The plan: what a scene needs, derived from its Hertz estimate (DESIGN.md section 5).

Every choice (symmetry, contact-zone radius, element sizes, initial gap, time steps, modal cutoff)
is computed here from the scene, can be overridden in ``scene.model`` / ``scene.time`` /
``scene.impact.gap``, and is reported with its reason by :meth:`Plan.table`.
"""
from __future__ import annotations

from dataclasses import dataclass

from ..errors import SceneError
from ..theory.hertz import HertzImpact, effective_modulus, hertz_impact
from .schema import Scene

#: elements across the Hertz contact radius a_max: ~4 gives ~1 % on F_max (DESIGN.md section 3)
ELEMENTS_ACROSS_CONTACT = 4.0
#: contact-zone radius in units of a_max: the zone must hold the whole contact patch with margin
ZONE_RADIUS_FACTOR = 4.0
#: initial gap in units of delta_max (the flight to contact is exact, so it only needs to be > 0)
GAP_FACTOR = 0.05
#: steps per contact duration while in contact
STEPS_PER_CONTACT = 100
#: modal cutoff in units of 1/t_c (DESIGN.md section 4: keep modes up to (3-5)/t_c)
F_CUT_FACTOR = 4.0


def scene_hertz(scene: Scene) -> HertzImpact:
    """Hertz values of a scene: the ball on a half-space of the block's material (the block is
    clamped, so the impacting mass is the ball's), with the normal component of the velocity."""
    e_star = effective_modulus(scene.ball.material, scene.target_material)
    return hertz_impact(scene.ball.radius, scene.ball.mass, scene.normal_speed, e_star,
                        scene.target_material.poisson)


@dataclass(frozen=True)
class Plan:
    """Modelling choices for a scene, all in SI units."""

    hertz: HertzImpact
    symmetry: str                 #: full | half | quarter
    symmetry_planes: tuple[str, ...]  #: subset of ("x", "z"): x = x_p and z = z_p planes are cut
    h_contact: float              #: element size at the contact point, m
    h_far: float                  #: element size far from it, m
    zone_radius: float            #: contact-zone radius around the contact point (both bodies), m
    fine_radius: float            #: radius within which the size is h_contact, m
    gap: float                    #: initial gap between ball and face, m
    dt_contact: float             #: step while in contact, s
    dt_free: float                #: step in free vibration, s
    f_cut: float                  #: modal cutoff frequency, Hz
    degree: int                   #: Lagrange degree of the full model
    reasons: tuple[tuple[str, str], ...] = ()

    def table(self) -> list[tuple[str, str, str]]:
        """(name, value with unit, reason) rows for printing."""
        why = dict(self.reasons)
        rows = [
            ("symmetry", f"{self.symmetry} (cut planes: {', '.join(self.symmetry_planes) or 'none'})", why.get("symmetry", "")),
            ("h_contact", f"{self.h_contact*1e3:.4g} mm", why.get("h_contact", "")),
            ("h_far", f"{self.h_far*1e3:.4g} mm", why.get("h_far", "")),
            ("zone_radius", f"{self.zone_radius*1e3:.4g} mm", why.get("zone_radius", "")),
            ("fine_radius", f"{self.fine_radius*1e3:.4g} mm", why.get("fine_radius", "")),
            ("gap", f"{self.gap*1e6:.4g} um", why.get("gap", "")),
            ("dt_contact", f"{self.dt_contact*1e6:.4g} us", why.get("dt_contact", "")),
            ("dt_free", f"{self.dt_free*1e6:.4g} us", why.get("dt_free", "")),
            ("f_cut", f"{self.f_cut/1e3:.4g} kHz", why.get("f_cut", "")),
            ("degree", f"P{self.degree}", why.get("degree", "")),
        ]
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
        planes.append("x")   # a liner is prismatic along x and symmetric about x = 0 as well
    if scene.liner is None and (scene.block.support == "back" and abs(z_p - 0.5 * scene.block.height) < 1e-9
            and abs(vz) <= tol * scene.impact.speed):
        planes.append("z")
    allowed = {0: "full", 1: "half", 2: "quarter"}[len(planes)]
    req = scene.model.symmetry
    if req == "auto":
        reason = f"{allowed}: " + ("; ".join(
            {"x": ("velocity in the plane of incidence x = 0 (liner: prismatic along x)" if scene.liner is not None
                   else "normal velocity in the x = 0 mid-plane"), "z": "back-clamped block struck at mid-height"}[p]
            for p in planes) or "no symmetry plane (oblique or off-centre impact)")
        return allowed, tuple(planes), reason
    order = ["full", "half", "quarter"]
    if order.index(req) > order.index(allowed):
        raise SceneError("model.symmetry", req, f"the scene allows at most '{allowed}' (planes: {planes or 'none'})")
    if req == "full":
        planes = []
    elif req == "half":
        planes = planes[:1]
    return req, tuple(planes), "user choice"


def make_plan(scene: Scene) -> Plan:
    """Derive the modelling choices of a scene from its Hertz estimate (DESIGN.md section 5)."""
    h = scene_hertz(scene)
    m = scene.model
    sym, planes, sym_reason = decide_symmetry(scene)
    reasons = {"symmetry": sym_reason}

    h_c = m.h_contact if m.h_contact is not None else h.a_max / ELEMENTS_ACROSS_CONTACT
    reasons["h_contact"] = "user" if m.h_contact is not None else f"a_max / {ELEMENTS_ACROSS_CONTACT:g} (~1 % on F_max)"
    if scene.liner is not None:   # the liner's smallest sizes: plate thickness, lifter top, length
        ln = scene.liner
        body = (ln.length, ln.thickness, ln.lifter_top_width)
    else:
        body = (scene.block.length, scene.block.thickness, scene.block.height)
    smallest = min(scene.ball.radius, *body)
    h_far = m.h_far if m.h_far is not None else smallest / 4.0
    reasons["h_far"] = "user" if m.h_far is not None else "smallest body size / 4"
    zone = m.zone_radius if m.zone_radius is not None else ZONE_RADIUS_FACTOR * h.a_max
    reasons["zone_radius"] = "user" if m.zone_radius is not None else f"{ZONE_RADIUS_FACTOR:g} a_max (holds the contact patch)"
    limit = 0.45 * smallest
    if zone >= limit:
        raise SceneError("model.zone_radius", zone, f"the contact zone must be smaller than {limit:g} m for this scene")
    fine = min(1.5 * h.a_max, zone)
    reasons["fine_radius"] = "1.5 a_max: h_contact over the whole contact patch"
    if h_c > zone / 2:
        raise SceneError("model.h_contact", h_c, f"must be at most half the contact-zone radius ({zone/2:g} m)")
    gap = scene.impact.gap if scene.impact.gap is not None else GAP_FACTOR * h.delta_max
    reasons["gap"] = "user" if scene.impact.gap is not None else f"{GAP_FACTOR:g} delta_max (flight before contact is exact)"
    t = scene.time
    dt_c = t.dt_contact if t.dt_contact is not None else h.contact_time / STEPS_PER_CONTACT
    reasons["dt_contact"] = "user" if t.dt_contact is not None else f"t_c / {STEPS_PER_CONTACT}"
    f_cut = m.f_cut if m.f_cut is not None else F_CUT_FACTOR / h.contact_time
    reasons["f_cut"] = "user" if m.f_cut is not None else f"{F_CUT_FACTOR:g} / t_c (DESIGN.md section 4)"
    # free vibration: resolve the kept band (10 steps per period of f_cut)
    dt_f = t.dt_free if t.dt_free is not None else max(dt_c, 1.0 / (10.0 * f_cut))
    reasons["dt_free"] = "user" if t.dt_free is not None else "1 / (10 f_cut): ten steps per period of the highest kept mode"
    reasons["degree"] = "user" if m.degree != 1 else "P1 (default)"
    if dt_c > t.end:
        raise SceneError("time.end", t.end, f"must exceed the contact step ({dt_c:g} s)")
    return Plan(h, sym, planes, h_c, h_far, zone, fine, gap, dt_c, dt_f, f_cut, m.degree, tuple(reasons.items()))
