"""Scenes: TOML round trip, built-ins, validation with one line naming field and range."""
import dataclasses

import pytest

from millimpact.errors import SceneError
from millimpact.scene.plan import make_plan
from millimpact.scene.schema import Scene
from millimpact.scene.builtin import BUILTIN_SCENES, BUILTIN_STUDIES, builtin_scene, study_scene
from millimpact.scene.toml_io import dump_scene, load_scene, scene_from_dict


@pytest.mark.parametrize("name", list(BUILTIN_SCENES))
def test_toml_round_trip(name, tmp_path):
    scene = builtin_scene(name)
    path = tmp_path / "s.toml"
    path.write_text(dump_scene(scene))
    assert load_scene(path) == scene


def test_default_scene_is_the_paper_rig():
    s = builtin_scene("paper-rig")
    # foundations.md section 2 / paper Tables 1-2
    assert (s.block.length, s.block.thickness, s.block.height) == (0.042, 0.045, 0.080)
    assert s.ball.radius == 0.015 and s.impact.speed == 3.0
    assert s.block.material.youngs_modulus == pytest.approx(182e9)
    assert s.time.end == 0.040
    assert [g.name for g in s.gauges] == ["A", "B", "C"]


def test_studies_match_the_paper():
    # paper section 4: u = 0.5/1/1.5 (nu_block 0.3), v = 1/3/5, r = 15/20/25 mm, b = 30/40/50 mm
    nus = [study_scene(BUILTIN_STUDIES["poisson"], v).ball.material.poisson for v in BUILTIN_STUDIES["poisson"].values]
    assert [n / 0.3 for n in nus] == pytest.approx([0.5, 1.0, 1.5])
    vs = [study_scene(BUILTIN_STUDIES["velocity"], v).impact.velocity for v in (1.0, 3.0, 5.0)]
    assert vs == [(0.0, -1.0, 0.0), (0.0, -3.0, 0.0), (0.0, -5.0, 0.0)]
    rs = [study_scene(BUILTIN_STUDIES["radius"], v).ball.radius for v in BUILTIN_STUDIES["radius"].values]
    assert rs == [0.015, 0.020, 0.025]
    b = [study_scene(BUILTIN_STUDIES["thickness"], v).block.thickness for v in BUILTIN_STUDIES["thickness"].values]
    assert b == [0.030, 0.040, 0.050]
    base = builtin_scene("study-base")
    assert (base.ball.radius, base.block.thickness, base.impact.speed) == (0.020, 0.040, 3.0)


BAD = [
    ("ball.radius", -0.01, "ball.radius"),
    ("ball.radius", 0.0, "ball.radius"),
    ("block.thickness", -1.0, "block.thickness"),
    ("block.material.poisson", 0.5, "(-1, 0.5)"),
    ("ball.material.poisson", -1.0, "(-1, 0.5)"),
    ("block.material.density", 0.0, "block.material.density"),
    ("ball.material.shear_modulus", -70e9, "ball.material.shear_modulus"),
    ("impact.gap", -1e-5, "inside the block"),
    ("impact.velocity", [0.0, 3.0, 0.0], "towards the struck face"),
    ("impact.velocity", [3.0, 0.0, 0.0], "towards the struck face"),
    ("impact.point", [0.05, 0.04], "impact.point[0]"),
    ("time.end", 0.0, "time.end"),
    ("model.symmetry", "octant", "model.symmetry"),
]


@pytest.mark.parametrize("path,value,expect", BAD)
def test_bad_values_are_refused_naming_the_field(path, value, expect):
    with pytest.raises(SceneError) as exc:
        builtin_scene("paper-rig").with_value(path, value)
    msg = str(exc.value)
    assert "\n" not in msg and path.split(".")[-1] in msg and expect in msg


def test_gauge_off_the_body():
    data = {"gauges": [{"name": "A", "position": [0.0, 0.01, 0.04]}]}  # 10 mm in front of the face
    with pytest.raises(SceneError, match=r"gauges\[0\]\.position"):
        scene_from_dict(data)
    data = {"gauges": [{"name": "A", "position": [0.0, -0.01, 0.04]}]}  # inside, not on a face
    with pytest.raises(SceneError, match="surface"):
        scene_from_dict(data)


def test_unknown_key_and_wrong_type(tmp_path):
    p = tmp_path / "bad.toml"
    p.write_text("[ball]\nradius = 0.01\ncolour = 'red'\n")
    with pytest.raises(SceneError, match=r"ball\.colour.*unknown key"):
        load_scene(p)
    p.write_text("[ball]\nradius = 'big'\n")
    with pytest.raises(SceneError, match=r"ball\.radius.*number"):
        load_scene(p)
    p.write_text("[impact]\nvelocity = [0, -3]\n")
    with pytest.raises(SceneError, match=r"impact\.velocity.*3 components"):
        load_scene(p)
    p.write_text("[ball\n")
    with pytest.raises(SceneError, match="not valid TOML"):
        load_scene(p)


def test_plan_follows_the_scene():
    # foundations.md section 5: quarter only for a back-clamped block struck at mid-height; the rig's base
    # clamp leaves the x = 0 plane alone; an oblique velocity in x removes it
    assert make_plan(builtin_scene("hertz-halfspace")).symmetry == "quarter"
    rig = builtin_scene("paper-rig")
    assert make_plan(rig).symmetry_planes == ("x",)
    assert make_plan(rig.with_value("impact.velocity", [1.0, -3.0, 0.0])).symmetry == "full"
    p = make_plan(rig)
    assert p.h_contact == pytest.approx(p.hertz.a_max / 4)
    assert p.f_cut == pytest.approx(4 / p.hertz.contact_time)
    with pytest.raises(SceneError, match="model.symmetry"):
        make_plan(rig.with_value("model.symmetry", "quarter"))
    assert dataclasses.replace(rig) == rig


def test_an_incomplete_table_names_the_missing_field():
    """A gauge without its position: the line names the field (before: "Gauge.__init__() missing
    1 required positional argument: 'position'")."""
    from millimpact.scene.schema import Gauge, SceneError, from_table

    with pytest.raises(SceneError, match=r"gauges\[0\].*incomplete: give position \(required here: name, position\)") as exc:
        from_table(Gauge, {"name": "A"}, "gauges[0]")
    assert "__init__" not in str(exc.value)
