"""Refusals name the field the user set and its allowed range (issue 35, rows 5, 17 and 22)."""
from __future__ import annotations

import re

import pytest

from conftest import run_cli
from millimpact.errors import SceneError
from millimpact.scene.builtin import builtin_scene
from millimpact.scene.plan import MAX_CONTACT_SHARE, make_plan


def one_error_line(*args: str) -> str:
    r = run_cli(*args)
    assert r.returncode == 2, r.stderr
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in r.stderr, r.stderr
    return lines[0]


@pytest.mark.parametrize("assignment,field,allowed", [
    ("ball.material.density=1e30", "ball.material.density", "[500, 25000] kg/m^3"),
    ("ball.material.shear_modulus=1", "ball.material.shear_modulus", "[100000, 1e+12] Pa"),
    ("block.material.density=0.001", "block.material.density", "[500, 25000] kg/m^3"),
])
def test_material_out_of_range_names_the_field_and_its_range(assignment, field, allowed, tmp_path):
    line = one_error_line("run", "--method", "hertz", "--set", assignment, "--out", str(tmp_path / "o"))
    assert f"error: {field} = " in line and allowed in line and "h_contact" not in line


def first_number_after(text: str, words: str) -> float:
    return float(re.search(re.escape(words) + r" ([0-9.e+-]+)", text).group(1))


def test_a_ball_too_large_for_the_block_names_the_radius_and_its_limit(tmp_path):
    # the documented maximum radius (1 m) on the rig's 42 mm block
    line = one_error_line("run", "--method", "hertz", "--set", "ball.radius=1", "--out", str(tmp_path / "o"))
    assert "error: ball.radius = 1.0: must be at most" in line and "block.length = 0.042 m" in line
    assert "h_contact" not in line
    r_max = first_number_after(line, "must be at most")
    # the stated limit is the plan's (printed to 3 digits: 1 % either side decides)
    rig = builtin_scene("paper-rig")
    make_plan(rig.with_value("ball.radius", 0.99 * r_max))
    with pytest.raises(SceneError) as exc:
        make_plan(rig.with_value("ball.radius", 1.01 * r_max))
    assert exc.value.field == "ball.radius"
    # a_max = R (5 pi rho v^2 / (4 E*))^(1/5) (Johnson 11.4): at the limit a_max = share x 42 mm
    e_star = 1 / (2 * (1 - 0.3**2) / (2 * 70e9 * 1.3))
    ratio = (5 * 3.141592653589793 * 7800 * 3.0**2 / (4 * e_star)) ** 0.2
    assert r_max == pytest.approx(MAX_CONTACT_SHARE * 0.042 / ratio, rel=2e-3)


def test_too_soft_materials_name_the_speed_and_its_limit():
    # a rubber-soft block (inside the material range): the contact would be as wide as the ball
    soft = builtin_scene("paper-rig").with_value("block.material.shear_modulus", 1e5)
    with pytest.raises(SceneError) as exc:
        make_plan(soft)
    assert exc.value.field == "impact.velocity" and "h_contact" not in str(exc.value)
    v_max = first_number_after(str(exc.value), "must be at most")
    make_plan(soft.with_value("impact.velocity", [0.0, -0.99 * v_max, 0.0]))
    with pytest.raises(SceneError):
        make_plan(soft.with_value("impact.velocity", [0.0, -1.01 * v_max, 0.0]))


def test_a_user_h_contact_or_zone_is_still_named():
    rig = builtin_scene("paper-rig")
    with pytest.raises(SceneError) as exc:
        make_plan(rig.with_value("model.h_contact", 0.01))
    assert exc.value.field == "model.h_contact"
    with pytest.raises(SceneError) as exc:
        make_plan(rig.with_value("model.zone_radius", 0.0003))
    assert exc.value.field == "model.zone_radius" and "at least" in str(exc.value)


def test_a_user_fine_radius_is_meshed_up_to_the_zone():
    """model.fine_radius replaces the plan's 1.5 a_max (a fast plastic impact's region outgrows it),
    up to the contact zone: beyond it one line names the field and the zone's radius."""
    rig = builtin_scene("paper-rig")
    plan = make_plan(rig)
    assert plan.fine_radius == pytest.approx(1.5 * plan.hertz.a_max)
    wider = make_plan(rig.with_value("model.fine_radius", plan.zone_radius))
    assert wider.fine_radius == plan.zone_radius and dict(wider.reasons)["fine_radius"] == "user"
    with pytest.raises(SceneError) as exc:
        make_plan(rig.with_value("model.fine_radius", 1.01 * plan.zone_radius))
    assert exc.value.field == "model.fine_radius" and "contact-zone radius" in str(exc.value)
    with pytest.raises(SceneError) as exc:
        rig.with_value("model.fine_radius", -1e-3)
    assert exc.value.field == "model.fine_radius"


def test_a_user_ball_zone_is_the_balls_own_up_to_the_zone():
    """model.ball_zone_radius gives the ball a smaller contact zone than the struck body's (a
    repeated-impact sequence, millimpact/repeat/sequence.py); the mesh the plan asks for changes
    with it, and beyond the zone one line names the field and the zone's radius."""
    from millimpact.geometry.mesh import mesh_parameters

    rig = builtin_scene("paper-rig")
    plan = make_plan(rig)
    assert plan.ball_zone == plan.zone_radius
    own = rig.with_value("model.ball_zone_radius", 0.8 * plan.zone_radius)
    smaller = make_plan(own)
    assert smaller.ball_zone == pytest.approx(0.8 * plan.zone_radius) and smaller.zone_radius == plan.zone_radius
    assert dict(smaller.reasons)["ball_zone_radius"] == "user"
    assert mesh_parameters(own, smaller) != mesh_parameters(rig, plan)
    with pytest.raises(SceneError) as exc:
        make_plan(rig.with_value("model.ball_zone_radius", 1.01 * plan.zone_radius))
    assert exc.value.field == "model.ball_zone_radius" and "contact zone" in str(exc.value)
    with pytest.raises(SceneError) as exc:
        rig.with_value("model.ball_zone_radius", 0.0)
    assert exc.value.field == "model.ball_zone_radius"


# --- row 17: settings that would be silently ignored ---------------------------------------------
def test_block_fields_on_a_liner_scene_are_refused(tmp_path):
    line = one_error_line("run", "liner-segment", "--method", "hertz", "--set", "block.thickness=0.02",
                          "--out", str(tmp_path / "o"))
    assert "error: block.thickness = 0.02: is not used by a liner scene" in line


@pytest.mark.parametrize("fields", [
    {"hardening_modulus": 1e9},                                                  # elastic: no yield
    {"hardening_modulus": 1e9, "flow_curve": [[0.0, 4e8], [0.1, 6e8]]},           # the curve has its own
])
def test_hardening_modulus_that_would_be_ignored_is_refused(fields):
    with pytest.raises(SceneError) as exc:
        builtin_scene("paper-rig").with_value("block.material", fields)
    assert exc.value.field == "block.material.hardening_modulus"
    # with a yield stress it is the linear hardening and is taken
    m = builtin_scene("paper-rig").with_value("block.material", {"yield_stress": 1e9, "hardening_modulus": 1e9})
    assert m.block.material.hardening_modulus == 1e9


def test_a_material_named_with_set_name_as_the_note_says(tmp_path):
    # the elastic-limit note tells the user to set [block.material] name = "cr-mo-liner"; a field
    # overriding the named material's value wins whatever the order of the --set options
    out = tmp_path / "o"
    r = run_cli("run", "--method", "hertz", "-q", "--set", "block.material.yield_stress=1.1e9",
                "--set", "block.material.name=cr-mo-liner", "--out", str(out))
    assert r.returncode == 0, r.stderr
    import tomllib

    m = tomllib.loads((out / "scene.toml").read_text())["block"]["material"]
    assert m["yield_stress"] == 1.1e9 and m["shear_modulus"] == 80.8e9 and m["hardening_modulus"] == 2.5e9
    line = one_error_line("run", "--method", "hertz", "--set", "block.material.name=nosuch",
                          "--out", str(tmp_path / "n"))
    assert "block.material.name = 'nosuch': unknown material" in line


# --- row 22: --set values validated together ---------------------------------------------------------
SHRINK = ["block.length=0.025", "block.thickness=0.025", "block.height=0.025"]


@pytest.mark.parametrize("order", ["shrink first", "gauges first"])
def test_set_values_are_validated_together(order, tmp_path):
    # the 100 mm block's gauges lie off a 25 mm block: dropping them with the shrink is one change
    sets = SHRINK + ["gauges=[]"] if order == "shrink first" else ["gauges=[]"] + SHRINK
    out = tmp_path / "o"
    r = run_cli("run", "hertz-halfspace", "--method", "hertz", "-q", *[a for s in sets for a in ("--set", s)],
                "--out", str(out))
    assert r.returncode == 0, r.stderr
    import tomllib

    scene = tomllib.loads((out / "scene.toml").read_text())
    assert scene["block"]["length"] == scene["block"]["height"] == 0.025 and not scene.get("gauges")


def test_set_values_together_still_refuse_a_bad_result():
    # validated once at the end: a gauge left off the shrunk block is still refused, naming it
    hh = builtin_scene("hertz-halfspace")
    with pytest.raises(SceneError) as exc:
        hh.with_values([("block.length", 0.025), ("block.thickness", 0.025), ("block.height", 0.025)])
    assert exc.value.field.startswith("gauges[")
