"""The built-in scenes (``paper-rig`` the default, ``paper-rig-plastic``, ``hertz-halfspace``, ``study-base``,
``liner-segment``, ``liner-panel``, ``mill-crmo``, ``mill-hadfield``, ``leeb-d``) and the paper's
parameter studies; :func:`resolve_scene` takes a built-in name or a TOML file.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from pathlib import Path
from typing import TypedDict

from ..errors import SceneError
from ..theory.rubber import compression_modulus, sheet_shape_factor, shore_a_modulus
from .liner_shape import vec3
from .schema import (
    Ball,
    Block,
    ContactOptions,
    Gauge,
    Impact,
    Liner,
    Material,
    Outputs,
    Scene,
    TimeSpan,
    Vec3,
    coerce_value,
)
from .toml_io import load_scene


class _BlockSizes(TypedDict):
    """A block's sizes (m) and support, the :class:`Block` fields a family of scenes shares."""

    length: float
    thickness: float
    height: float
    support: str


# --- built-in scenes -------------------------------------------------------------------------
def _default_gauges(block: Block, radius: float) -> tuple[Gauge, ...]:
    """Gauges A, B, C on the struck face near the impact (an assumption: the paper's Figure 4 with
    their exact places is not available). A and B above the impact point along z, C beside it
    along x, each measuring the in-plane normal stress along its direction."""
    zc = 0.5 * block.height
    d = 0.5 * radius
    return (
        Gauge("A", (0.0, 0.0, zc + d), (0.0, 0.0, 1.0)),
        Gauge("B", (0.0, 0.0, zc + 2 * d), (0.0, 0.0, 1.0)),
        Gauge("C", (min(d, 0.45 * block.length), 0.0, zc), (1.0, 0.0, 0.0)),
    )


def _paper_rig() -> Scene:
    block = Block()
    return Scene(
        name="paper-rig",
        description="The paper's test rig (Liu et al. 2022, Tables 1-2): r = 15 mm steel ball at 3 m/s "
        "normal to the 42 x 80 mm face of a 45 mm thick block clamped at its base; 40 ms.",
        block=block,
        gauges=_default_gauges(block, 0.015),
        outputs=Outputs(field_times=(0.0, 45e-6, 90e-6, 1e-3)),
    )


def _paper_rig_plastic() -> Scene:
    """The rig with real steels: both bodies yield at 3 m/s (Hertz p0 4.9 GPa > 1.6 Y)."""
    rig = _paper_rig()
    ball = Ball(radius=0.015, material=coerce_value(Material, "forged-ball-60hrc", "ball.material"))
    block = dataclasses.replace(rig.block, material=coerce_value(Material, "cr-mo-liner", "block.material"))
    return dataclasses.replace(
        rig,
        name="paper-rig-plastic",
        ball=ball,
        block=block,
        description="The paper's rig with real steels (elastic-plastic, J2): a forged 60 HRC ball (Y 1.9 GPa) on a "
        "Cr-Mo liner-steel block (Y 0.95 GPa), 3 m/s; Hertz p0 4.9 GPa is 3x the block's first-yield "
        "pressure 1.6 Y. Material values and sources: scene/materials.toml. 40 ms as the rig (the reduced methods continue "
        "the free vibration about the residual state in closed form; full FE steps it: --set time.end=2e-3 "
        "for the impact and the first ringing).",
    )


def _hertz_halfspace() -> Scene:
    block = Block(length=0.100, thickness=0.100, height=0.100, support="back")
    return Scene(
        name="hertz-halfspace",
        description="The default ball on a large block clamped at its back face: a half-space-like "
        "target whose impact Hertz theory describes (restitution ~0.99).",
        block=block,
        gauges=_default_gauges(block, 0.015),
        time=TimeSpan(end=0.3e-3),
    )


def _study_base() -> Scene:
    """The base of the paper's parameter studies (section 4): r = 20 mm, v = 3 m/s, b = 40 mm, u = 1."""
    block = Block(thickness=0.040)
    return Scene(
        name="study-base",
        description="Base case of the paper's parameter studies (section 4): r = 20 mm, v = 3 m/s, "
        "b = 40 mm, u = nu_ball / nu_block = 1.0; other values as the rig.",
        ball=Ball(radius=0.020),
        block=block,
        gauges=_default_gauges(block, 0.020),
    )


#: the mill-regime block scenes: a 125 mm ball, a liner-thick block backed by the shell
MILL_BALL_RADIUS = 0.0625
MILL_BLOCK = _BlockSizes(length=0.250, thickness=0.075, height=0.250, support="back")


def _mill_block(name: str, liner_material: str, what: str) -> Scene:
    """A 125 mm forged ball at 8 m/s normal to a 75 mm liner plate of ``liner_material`` backed by
    the shell (the back face clamped): the mill's regime on a block, for repeated impacts."""
    block = Block(**MILL_BLOCK, material=coerce_value(Material, liner_material, "block.material"))
    return Scene(
        name=name,
        description=(
            f"A 125 mm forged 60 HRC ball (Y 1.9 GPa) at 8 m/s normal to a 75 mm {what} liner plate, "
            "250 x 250 mm, clamped at its back (the shell). Balls of 100-150 mm strike SAG liners at "
            "3-13 m/s (100-580 J for 125 mm; docs: foundations, section 10); the plate thickness is the liner-segment "
            "scene's shell plate (Royston 2007: 75-100 mm). Material values and sources: "
            "scene/materials.toml. Impact only (0.6 ms)."
        ),
        ball=Ball(radius=MILL_BALL_RADIUS, material=coerce_value(Material, "forged-ball-60hrc", "ball.material")),
        block=block,
        impact=Impact(velocity=(0.0, -8.0, 0.0)),
        gauges=_default_gauges(block, MILL_BALL_RADIUS),
        time=TimeSpan(end=0.6e-3),
    )


#: the liner-segment scene's impact: speed (m/s) and angle (deg) between the velocity and the lifter
#: face's inward normal, in the plane of incidence x = 0 (the ball comes down along the face)
LINER_IMPACT_SPEED = 8.0
LINER_IMPACT_ANGLE = 30.0


def _oblique_velocity(liner: Liner) -> Vec3:
    """The liner scenes' arrival velocity: LINER_IMPACT_SPEED at LINER_IMPACT_ANGLE from the struck
    face's inward normal -n, tilted towards the plate (down the face): v = V (-cos(a) n - sin(a) s),
    s the face's up-slope direction in the y-z plane."""
    _, n = liner.face_point()
    up = (0.0, n[2], -n[1]) if n[2] > 0 else (0.0, -n[2], n[1])  # in-face, pointing away from the plate
    a = math.radians(LINER_IMPACT_ANGLE)
    return vec3(round(LINER_IMPACT_SPEED * (-math.cos(a) * nc - math.sin(a) * uc), 12) + 0.0 for nc, uc in zip(n, up))


def _liner_segment() -> Scene:
    """A large ball striking a SAG liner's lifter face obliquely (sizes and sources in the description)."""
    liner = Liner(
        length=0.40,
        width=0.50,
        thickness=0.075,
        n_lifters=1,
        lifter_height=0.20,
        lifter_top_width=0.10,
        lifter_face_angle=20.0,
        lifter_spacing=0.30,
        mill_radius=5.5,
        impact_lifter=0,
        impact_face="+z",
        impact_height=0.5,
        impact_x=0.0,
        material=coerce_value(Material, "cr-mo-liner", "liner.material"),
    )
    v = _oblique_velocity(liner)
    return Scene(
        name="liner-segment",
        description=(
            "A 125 mm steel ball at 8 m/s striking a lifter face of a SAG-mill liner segment 30 deg off the "
            "face normal (towards the plate), Coulomb friction mu = 0.2 (steel on wet steel). Sizes of a "
            "36-40 ft (11-12 m) SAG mill, typical values of the liner-design literature (e.g. D. Royston, "
            "SAG mill liner design and development, Min. Metall. Process. 24 (2007) 121-132): shell plate "
            "75 mm thick (typical 75-100 mm), lifter 200 mm high (150-250 mm), 100 mm top, 20 deg face angle "
            "(15-30 deg), plate curved to the mill's 5.5 m radius, 400 mm along the axis x 500 mm of arc; balls "
            "100-150 mm thrown at up to ~10 m/s. Real steels, elastic-plastic (J2): a Cr-Mo liner steel (Y 0.95 "
            "GPa) and a forged 60 HRC ball (Y 1.9 GPa), values and sources in scene/materials.toml; Hertz p0 "
            "~6.9 GPa is 4.5x the liner's first-yield pressure. The elastic case (the paper's steel in both "
            "bodies): --set ball.material=paper-steel --set liner.material=paper-steel. "
            "Half model: the plane of incidence x = 0 is a symmetry plane."
        ),
        ball=Ball(radius=0.0625, material=coerce_value(Material, "forged-ball-60hrc", "ball.material")),
        liner=liner,
        impact=Impact(velocity=v),
        contact=ContactOptions(friction=0.2),
        time=TimeSpan(end=0.6e-3),
        outputs=Outputs(field_times=(0.0, 2.0e-4, 4.0e-4)),
    )


#: the liner-panel scene's rubber backing: a 65 Shore A, 6 mm mill-backing sheet (Reglin Rubber,
#: "Mill Backing Lining Rubber" data sheet: 65 +- 5 Shore A, sold 6 mm thick, bonded behind liner plates)
PANEL_BACKING_SHORE_A = 65.0
PANEL_BACKING_THICKNESS = 0.006
#: a gauge sits this far (m) under the liner surface: its probe needs a cell that holds it
GAUGE_DEPTH = 1.0e-4


def _panel_gauges(liner: Liner) -> tuple[Gauge, ...]:
    """Gauge ``bolt`` on the plate's inner face beside the bolt hole nearest the impact (3 mm from
    the hole's edge on its side towards the plane of incidence, along the arc: the hoop stress at
    the hole's edge under the plate's bending across the lifters) and gauge ``root`` on the struck
    lifter face 5 % of its height above the plate (along the face, up the slope: the lifter's
    bending at its root). Both GAUGE_DEPTH under the surface."""
    p, n = liner.face_point()
    c = liner.lifter_centres()[liner.impact_lifter]
    # the nearest hole in the kept half (x >= the impact's x), on the struck face's side preferred
    hx, hs = min(
        liner.bolt_holes(),
        key=lambda h: (h[0] < p[0], (h[1] > c) != (liner.impact_face == "+z"), (h[0] - p[0]) ** 2 + (h[1] - c) ** 2),
    )
    R, w = liner.mill_radius, liner.width
    phi = (hs - 0.5 * w) / R
    r = R + GAUGE_DEPTH
    x_g = hx - math.copysign(0.5 * liner.bolt_hole_diameter + 3e-3, hx - p[0])
    bolt = Gauge("bolt", (x_g, R - r * math.cos(phi), 0.5 * w + r * math.sin(phi)), (0.0, math.sin(phi), math.cos(phi)))
    q, m = liner.lifter_face_point(liner.impact_lifter, liner.impact_face, 0.05, p[0])
    up = (0.0, m[2], -m[1]) if m[2] > 0 else (0.0, -m[2], m[1])
    root = Gauge("root", vec3(qc - GAUGE_DEPTH * mc for qc, mc in zip(q, m)), up)
    return (bolt, root)


def _liner_panel() -> Scene:
    """A panel of a SAG mill's shell liner: three lifters, bolt holes, rubber backing (sources in the description)."""
    length, width, height, spacing, base = 1.0, 1.2, 0.18, 0.45, 0.1 + 2 * 0.18 * math.tan(math.radians(20.0))
    # the backing's compression modulus: the sheet under one lifter's foot (base x length) bonded, Gent and Lindley
    e_c = compression_modulus(
        shore_a_modulus(PANEL_BACKING_SHORE_A), sheet_shape_factor(base, length, PANEL_BACKING_THICKNESS)
    )
    liner = Liner(
        length=length,
        width=width,
        thickness=0.075,
        n_lifters=3,
        lifter_height=height,
        lifter_top_width=0.10,
        lifter_face_angle=20.0,
        lifter_spacing=spacing,
        mill_radius=5.5,
        bolt_hole_diameter=0.042,
        bolt_x=(-0.25, 0.25),
        bolt_arc=(0.375, 0.825),
        backing="rubber",
        backing_modulus=round(e_c, -6),
        backing_thickness=PANEL_BACKING_THICKNESS,
        impact_lifter=1,
        impact_face="+z",
        impact_height=0.5,
        impact_x=0.0,
        material=coerce_value(Material, "cr-mo-liner", "liner.material"),
    )
    # the ball, friction, run time and outputs are liner-segment's (the description says so)
    return dataclasses.replace(
        _liner_segment(),
        name="liner-panel",
        description=(
            "A panel of the shell liner of a 36-40 ft (11-12 m) SAG mill: 1.0 m along the axis x 1.2 m of arc, "
            "three lifters on a 75 mm shell plate curved to the mill's 5.5 m radius, bolted to the shell through "
            "42 mm holes and lying on a rubber backing; a 125 mm ball at 8 m/s strikes the middle lifter's face "
            "30 deg off its normal (towards the plate), Coulomb friction mu = 0.2, as liner-segment. "
            "Sources: plate 75 mm (typical 75-100 mm), lifter 180 mm high (150-250 mm), 100 mm top, 20 deg face "
            "angle (15-30 deg), balls 100-150 mm at up to ~10 m/s: D. Royston, SAG mill liner design and "
            "development, Min. Metall. Process. 24 (2007) 121-132. Lifter spacing 450 mm: a spacing-to-height "
            "ratio of 2.5, the low end of the 2.5-5 that maximizes throughput (911 Metallurgist, SAG mill liner "
            "design, after Royston). Bolts: 1 1/2 in (38.1 mm), the largest liner bolt of Unicast's liner-bolt "
            "torque table (1 - 1 1/2 in UNF), in 42 mm holes (ISO 273 medium clearance for M39); two bolts "
            "along each shell plate (liner plates are held by two or three bolts: FLSmidth, Ball mills 70000375-1, "
            "bolted-on lining plates), at x = -0.25, 0.25 m, midway between lifters. Backing: a 6 mm, 65 Shore A "
            "mill-backing rubber sheet (Reglin Rubber data sheet), Young's modulus 4.4 MPa (Gent 1958), "
            "compression modulus of the sheet under a lifter's foot ~1.0 GPa (Gent and Lindley 1959, bulk "
            "modulus 2 GPa: Lindley, Engineering design with natural rubber, MRPRA 1978): a Winkler layer "
            "k_n = E_c / t on the back face (docs/scenes.md, liner-panel); the bolt holes' surfaces clamped. "
            "Steels as liner-segment (cr-mo-liner, forged-ball-60hrc; scene/materials.toml), elastic-plastic. "
            "Gauges: 'bolt' beside the bolt hole nearest the impact, 'root' at the struck lifter's root. "
            "Half model: the plane of incidence x = 0 is a symmetry plane."
        ),
        liner=liner,
        impact=Impact(velocity=_oblique_velocity(liner)),
        gauges=_panel_gauges(liner),
    )


#: the Leeb D impact device (ASTM A956-12; ISO 16859-1; PCE Instruments PCE-2800 manual, Table 3):
#: a 5.5 g impact body with a 3 mm tungsten-carbide ball tip, impact energy 11 mJ (N mm)
LEEB_D_BODY_MASS = 5.5e-3
LEEB_D_TIP_RADIUS = 1.5e-3
LEEB_D_ENERGY = 11.0e-3
#: the speed of that energy, sqrt(2 E / m) = 2.0 m/s
LEEB_D_SPEED = math.sqrt(2.0 * LEEB_D_ENERGY / LEEB_D_BODY_MASS)
#: the test block: 25 mm thick (the D probe's least uncoupled sample thickness, Proceq Equotip 3
#: manual 2012, 2.3), 40 x 40 mm, clamped at its back (a sample coupled to a solid base)
LEEB_BLOCK = _BlockSizes(length=0.040, thickness=0.025, height=0.040, support="back")


def _leeb_d() -> Scene:
    """The Leeb D rebound hardness test on a steel block (sources in the description)."""
    block = Block(**LEEB_BLOCK, material=coerce_value(Material, "steel-400hb", "block.material"))
    return Scene(
        name="leeb-d",
        description=(
            "The Leeb rebound hardness test, D impact device (ASTM A956; ISO 16859-1): a 5.5 g impact body "
            "with a 3 mm tungsten-carbide ball tip strikes the steel at 2.0 m/s (11 mJ; PCE-2800 manual, "
            "Table 3); HLD = 1000 v_rebound / v_impact, the restitution x 1000. The tip is the ball (wc-co-tip: "
            "E 630 GPa, nu 0.24) carrying the body's mass (ball.body_mass); the block 40 x 40 x 25 mm clamped "
            "at its back, of a steel of known hardness, perfectly plastic at Tabor's flow stress Y = 9.807 HB / "
            "2.8 MPa (steel-400hb, ~600 HLD; steel-108hb, steel-551hb: --set block.material=NAME; sources "
            "in scene/materials.toml). A small ball: the mesh grows from the contact and the block's far size "
            "is its own (scene/plan.py). Impact only (0.25 ms). benchmarks/leeb_rebound.py compares e with "
            "HLD / 1000."
        ),
        ball=Ball(
            radius=LEEB_D_TIP_RADIUS,
            material=coerce_value(Material, "wc-co-tip", "ball.material"),
            body_mass=LEEB_D_BODY_MASS,
        ),
        block=block,
        impact=Impact(velocity=(0.0, -round(LEEB_D_SPEED, 12), 0.0)),
        time=TimeSpan(end=0.25e-3),
    )


BUILTIN_SCENES = {
    "paper-rig": _paper_rig,
    "paper-rig-plastic": _paper_rig_plastic,
    "hertz-halfspace": _hertz_halfspace,
    "study-base": _study_base,
    "liner-segment": _liner_segment,
    "liner-panel": _liner_panel,
    "mill-crmo": lambda: _mill_block("mill-crmo", "cr-mo-liner", "Cr-Mo steel (Y 0.95 GPa)"),
    "mill-hadfield": lambda: _mill_block(
        "mill-hadfield", "hadfield-mn-liner", "Hadfield manganese steel (Y 380 MPa, strong hardening)"
    ),
    "leeb-d": _leeb_d,
}
DEFAULT_SCENE = "paper-rig"


@dataclass(frozen=True)
class StudySpec:
    """A one-parameter sweep of the paper: ``param`` is a dotted scene field, ``values`` its values,
    ``label``/``display`` how the figure names each case (e.g. u = nu_ball / nu_block)."""

    name: str
    base: str
    param: str
    values: tuple[float, ...]
    label: str
    display: tuple[float, ...]
    unit: str
    paper_conclusion: str  #: "" for a study that is not the paper's


BUILTIN_STUDIES = {
    "poisson": StudySpec(
        "poisson",
        "study-base",
        "ball.material.poisson",
        (0.15, 0.30, 0.45),
        "u = nu_ball / nu_block",
        (0.5, 1.0, 1.5),
        "",
        "(2) Poisson ratio changes little the contact-point displacement, velocity and "
        "acceleration but changes the stress; above u = 1.0 the stress grows less.",
    ),
    "velocity": StudySpec(
        "velocity",
        "study-base",
        "impact.velocity",
        (1.0, 3.0, 5.0),
        "v",
        (1.0, 3.0, 5.0),
        "m/s",
        "(3) displacement, velocity, acceleration and stress grow with v; above 3 m/s they grow less.",
    ),
    "radius": StudySpec(
        "radius",
        "study-base",
        "ball.radius",
        (0.015, 0.020, 0.025),
        "r",
        (15.0, 20.0, 25.0),
        "mm",
        "(4) displacement, velocity and stress grow with r, acceleration changes little; "
        "above 20 mm the stress changes greatly and the peak acceleration comes earlier.",
    ),
    "velocity-plastic": StudySpec(
        "velocity-plastic",
        "paper-rig-plastic",
        "impact.velocity",
        (0.1, 0.3, 1.0, 3.0, 10.0),
        "v",
        (0.1, 0.3, 1.0, 3.0, 10.0),
        "m/s",
        "",
    ),
    "mill-crmo": StudySpec(
        "mill-crmo", "mill-crmo", "impact.velocity", (3.0, 5.0, 8.0, 13.0), "v", (3.0, 5.0, 8.0, 13.0), "m/s", ""
    ),
    "mill-hadfield": StudySpec(
        "mill-hadfield",
        "mill-hadfield",
        "impact.velocity",
        (3.0, 5.0, 8.0, 13.0),
        "v",
        (3.0, 5.0, 8.0, 13.0),
        "m/s",
        "",
    ),
    "thickness": StudySpec(
        "thickness",
        "study-base",
        "block.thickness",
        (0.030, 0.040, 0.050),
        "b",
        (30.0, 40.0, 50.0),
        "mm",
        "(5) displacement and acceleration grow with b, stress amplitude falls; above "
        "40 mm the time of peak acceleration hardly changes.",
    ),
}


def builtin_scene(name: str) -> Scene:
    """A built-in scene by name."""
    try:
        return BUILTIN_SCENES[name]()
    except KeyError:
        raise SceneError(
            "scene", name, f"unknown built-in scene; known: {', '.join(BUILTIN_SCENES)} (or give a .toml file)"
        ) from None


def resolve_scene(name_or_file: str | None) -> Scene:
    """A built-in scene by name, or a TOML file by path; ``None`` gives the default scene."""
    if name_or_file is None:
        return builtin_scene(DEFAULT_SCENE)
    if name_or_file in BUILTIN_SCENES:
        return builtin_scene(name_or_file)
    if name_or_file.endswith(".toml") or Path(name_or_file).exists():
        return load_scene(name_or_file)
    return builtin_scene(name_or_file)


def study_scene(spec: StudySpec, value: float) -> Scene:
    """The scene of one study case (velocity values are speeds along -y)."""
    base = builtin_scene(spec.base)
    if spec.param == "impact.velocity":
        v = base.impact.velocity
        n = base.impact.speed
        return base.with_value("impact.velocity", [c / n * value for c in v])
    return base.with_value(spec.param, value)
