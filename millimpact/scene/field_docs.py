"""Unit, allowed range and meaning of every scene field: the docs' scene table (``docs/_ext/
scene_fields.py``) is generated from the schema's dataclasses and these, and a test checks that
both list the same fields (tests/scene/test_field_docs.py), so the table cannot drift.

Ranges are those the schema enforces (``millimpact/scene/schema.py``, ``liner_shape.py``); a
``-`` unit is dimensionless; ``(plan)`` means "derived by the plan when absent" (scene/plan.py).
"""

from __future__ import annotations

import dataclasses
import typing
from collections.abc import Iterator

#: the fields of each body's material table (``ball.material``, ``block.material``, ``liner.material``)
MATERIAL_DOCS: dict[str, tuple[str, str, str]] = {
    "name": ("", "a name in scene/materials.toml", "named material whose values the other fields override"),
    "density": ("kg/m^3", "[500, 25000]", "mass density"),
    "shear_modulus": ("Pa", "[1e5, 1e12]", "shear modulus G (E = 2 G (1 + nu))"),
    "poisson": ("-", "(-1, 0.5)", "Poisson's ratio nu"),
    "yield_stress": ("Pa", "> 0; absent = elastic", "initial von Mises yield stress Y (J2 plasticity)"),
    "hardening_modulus": (
        "Pa",
        ">= 0; only with yield_stress",
        "linear isotropic hardening modulus H (0: perfectly plastic)",
    ),
    "flow_curve": (
        "-, Pa",
        "[[0, Y], ...] strain increasing, stress not decreasing",
        "tabulated flow stress against equivalent plastic strain (instead of Y and H)",
    ),
    "voce": (
        "Pa, -",
        "[Q >= 0, b > 0], with yield_stress",
        "Voce hardening, sigma_y = Y + Q (1 - exp(-b eps_p)) (instead of H or a flow curve)",
    ),
    "swift": (
        "Pa, -, -",
        "[K > 0, 0 < eps0 <= 1, 0 <= n < 1]",
        "Swift hardening, sigma_y = K (eps0 + eps_p)^n, yield at K eps0^n (instead of Y, H or a flow curve)",
    ),
    "johnson_cook_rate": (
        "-, 1/s",
        "[0 < C <= 0.5, 0 < rate0 <= 1e6], with a plastic law",
        "strain-rate factor 1 + C ln(rate / rate0) on the flow stress above rate0 (Johnson-Cook)",
    ),
    "source": ("", "text", "where the values come from (paper, standard or datasheet)"),
}

#: every other field, by its dotted name
FIELD_DOCS: dict[str, tuple[str, str, str]] = {
    "name": ("", "text", "the scene's name (output folder default)"),
    "description": ("", "text", "what the scene is, with its sources"),
    "ball.radius": ("m", "[1e-4, 1]", "ball radius R"),
    "ball.body_mass": (
        "kg",
        "[sphere's mass, 1000 x it]; absent = the sphere's",
        "impacting mass when the ball is the tip of a heavier body (a Leeb probe)",
    ),
    "block.length": ("m", "> 0", "block size along x (the struck face is length x height)"),
    "block.thickness": ("m", "> 0", "block size along the impact direction (-y)"),
    "block.height": ("m", "> 0", "block size along z"),
    "block.support": ("", "base | back", "clamped face: base (z = 0, the paper's rig) or back (y = -thickness)"),
    "impact.velocity": ("m/s", "|v| <= 100, into the struck face", "the ball's velocity at the start"),
    "impact.point": ("m", "on the struck face", "(x, z) of the first contact point on the face y = 0 (block)"),
    "impact.gap": ("m", "[0, ball radius]; (plan)", "initial gap between ball and face (0.05 delta_max)"),
    "gauges": (
        "m, -",
        "unique names, on the block (a liner: inside it, just under its surface)",
        "strain gauges: name, position, direction (stress E d.eps.d)",
    ),
    "time.end": ("s", "> 0", "simulated time"),
    "time.dt_contact": ("s", "> 0; (plan)", "time step while in contact (t_c / 100)"),
    "time.dt_free": ("s", "> 0; (plan)", "time step in free vibration (1 / (10 f_cut))"),
    "model.h_contact": ("m", "> 0, <= zone_radius / 2; (plan)", "element size at the contact point (a_max / 4)"),
    "model.h_far": ("m", ">= h_contact; (plan)", "element size far from the contact (smallest body size / 4)"),
    "model.zone_radius": (
        "m",
        "< 0.45 x the smallest body size; (plan)",
        "contact-zone radius (full: 4 a_max; reduced: 2.5 a_max; plastic: 1.75 x the plastic radius)",
    ),
    "model.fine_radius": (
        "m",
        "> 0, <= zone_radius; (plan)",
        "radius about the contact point within which the size is h_contact (1.5 a_max)",
    ),
    "model.ball_zone_radius": (
        "m",
        "> 0, <= the zone radius; (plan)",
        "the ball's contact-zone radius (the zone radius; a small ball's: 0.9 x 0.45 its radius)",
    ),
    "model.strain": (
        "",
        "auto | small | finite",
        "plastic zone's kinematics (auto: finite where the predicted plastic strain passes 0.1)",
    ),
    "model.symmetry": ("", "auto | full | half | quarter", "symmetry planes used (auto: all the scene allows)"),
    "model.degree": ("", "1 | 2", "Lagrange degree of the full FE model (reduced methods use their own)"),
    "model.f_cut": ("Hz", "> 0; (plan)", "modal cutoff of the reduction (4 / t_c)"),
    "model.modes": ("", ">= 1; absent = by f_cut", "fixed-interface modes kept per body (wins over f_cut)"),
    "outputs.field_times": ("s", ">= 0 each", "times of the XDMF displacement (and plastic) fields"),
    "outputs.figures": ("", "true | false", "write the PNG figures"),
    "outputs.xdmf": ("", "true | false", "write fields.xdmf for ParaView"),
    "outputs.hdf5": ("", "true | false", "write timeseries.h5"),
    "liner.length": ("m", "> 0", "liner plate length along the mill axis (x)"),
    "liner.width": ("m", "> the lifters' span", "plate width along the arc"),
    "liner.thickness": ("m", "> 0, thick enough for the lifters", "shell plate thickness"),
    "liner.n_lifters": ("", ">= 1", "number of lifter bars"),
    "liner.lifter_height": ("m", "> 0", "lifter height above the plate"),
    "liner.lifter_top_width": ("m", "> 0", "width of the lifter's top"),
    "liner.lifter_face_angle": (
        "deg",
        "(lower bound from the shape, 90)",
        "lifter face angle from the radial direction",
    ),
    "liner.lifter_spacing": ("m", "> the lifter's widest section", "distance between lifter centre lines"),
    "liner.mill_radius": ("m", "0 (flat) or >= the plate's span", "mill radius the plate is curved to"),
    "liner.bolt_hole_diameter": (
        "m",
        "0 (no holes) or > 0",
        "diameter of the bolt holes through the plate (clamped: the bolts)",
    ),
    "liner.bolt_x": ("m", "inside the plate, > a diameter apart", "axial positions of the bolt holes"),
    "liner.bolt_arc": (
        "m",
        "on the shell plate between lifters, > a diameter apart",
        "arc positions of the bolt holes (every bolt_x x bolt_arc pair is a hole)",
    ),
    "liner.backing": (
        "",
        "clamped | rubber (rubber needs bolt holes)",
        "what holds the back face: clamped (rigid shell) or a rubber backing (Winkler layer)",
    ),
    "liner.backing_modulus": ("Pa", "> 0", "compression modulus E_c of the rubber backing sheet (k_n = E_c / t)"),
    "liner.backing_thickness": ("m", "> 0", "thickness t of the rubber backing sheet"),
    "liner.impact_lifter": ("", "0 .. n_lifters - 1", "the struck lifter"),
    "liner.impact_face": ("", "+z | -z", "the struck face of that lifter"),
    "liner.impact_height": ("-", "(0, 1)", "impact height as a fraction of the lifter height"),
    "liner.impact_x": ("m", "(-length/2, length/2)", "impact position along the mill axis"),
    "liner.impact_place": ("", "lifter_face | lifter_top | plate", "the struck place (the damage map's places)"),
    "liner.impact_arc": (
        "m",
        "on the top or the plate, the ball clear of the lifters",
        "lifter_top / plate: position along the profile from the struck lifter's centre line, "
        "positive towards impact_face",
    ),
    "contact.friction": ("-", "[0, 2]", "Coulomb friction coefficient mu between ball and struck body"),
}


def scene_field_rows() -> Iterator[tuple[str, str, str, str, str, str]]:
    """(dotted name, type, default, unit, allowed, meaning) of every scene field, walking the
    schema's dataclasses (a material table's fields from :data:`MATERIAL_DOCS`)."""
    from .schema import Scene

    yield from _rows(Scene, "")


def _rows(cls, prefix: str):
    from .schema import Material

    if cls is Material:  # a material table's `name` is read by the loader, not a dataclass field
        yield (f"{prefix}name", "str", "(none)", *MATERIAL_DOCS["name"])
    hints = typing.get_type_hints(cls)
    for f in dataclasses.fields(cls):
        tp = hints[f.name]
        inner = [a for a in typing.get_args(tp) if a is not type(None)]
        target = inner[0] if inner else tp
        if dataclasses.is_dataclass(target) and f.name != "gauges":
            yield from _rows(target, f"{prefix}{f.name}.")
            continue
        if f.default is not dataclasses.MISSING:
            default = repr(f.default)
        elif f.default_factory is not dataclasses.MISSING:
            default = repr(f.default_factory())
        else:
            default = "(required)"
        name = f"{prefix}{f.name}"
        doc = MATERIAL_DOCS.get(f.name) if cls is Material else None
        unit, allowed, meaning = doc or FIELD_DOCS.get(name, ("", "", ""))
        yield (name, getattr(tp, "__name__", str(tp)).replace("typing.", ""), default, unit, allowed, meaning)
