"""The plan's kinematics (small or finite strain) and its whole-body plasticity.

The configuration of docs/plasticity.md's restitution study: a perfectly plastic 15 mm steel
ball (Y = 1 GPa) on the hertz-halfspace block made 10x stiffer, at multiples of Thornton's V_y.
Thornton's contact radius a_p passes 0.15 R between 100 V_y (0.118 R) and 183 V_y (0.160 R), and
Johnson's cavity radius passes 0.85 of the 6.6 mm zone between 183 V_y (4.7 mm) and 300 V_y
(6.4 mm): the plan's thresholds (scene/plan.py) put each of these on a known side.
"""
from __future__ import annotations

import pytest

from millimpact.errors import SceneError
from millimpact.repeat.sequence import small_strain_plan
from millimpact.scene.builtin import builtin_scene
from millimpact.scene.plan import make_plan
from millimpact.theory.hertz import effective_modulus
from millimpact.theory.thornton import yield_onset_velocity

Y = 1e9


def _sphere(ratio: float, **fields):
    base = builtin_scene("hertz-halfspace")
    stiff = base.with_value("block.material.shear_modulus", 10 * base.block.material.shear_modulus)
    vy = yield_onset_velocity(Y, effective_modulus(stiff.ball.material, stiff.block.material), stiff.ball.material.density)
    scene = stiff.with_value("impact.velocity", [0.0, -ratio * vy, 0.0]).with_value("ball.material.yield_stress", Y)
    for key, value in fields.items():
        scene = scene.with_value(key, value)
    return scene


@pytest.mark.parametrize(("ratio", "strain", "whole"), [(30, "small", ()), (100, "small", ()),
                                                        (183, "finite", ()), (300, "finite", ("ball",)),
                                                        (1000, "finite", ("ball",))])
def test_the_plan_chooses_the_kinematics_and_the_plastic_bodies(ratio, strain, whole):
    plan = make_plan(_sphere(ratio))
    assert plan.strain == strain
    assert plan.plastic_whole == whole
    rows = {name: (value, why) for name, value, why in plan.table()}
    assert rows["strain"][0] == strain and "contact radius" in rows["strain"][1]
    assert ("plastic_whole" in rows) == bool(whole)
    if whole:
        assert rows["plastic_whole"][0] == "ball" and "every cell of the ball" in rows["plastic_whole"][1]


def test_the_scene_overrides_the_kinematics():
    plan = make_plan(_sphere(1000, **{"model.strain": "small"}))
    assert plan.strain == "small" and dict(plan.reasons)["strain"] == "user"
    assert make_plan(_sphere(30, **{"model.strain": "finite"})).strain == "finite"


def test_an_elastic_scene_stays_small_strain():
    plan = make_plan(builtin_scene("hertz-halfspace"))
    assert plan.strain == "small" and plan.plastic_whole == ()
    assert "strain" not in {name for name, _, _ in plan.table()}


def test_a_bad_strain_is_refused_naming_the_field():
    with pytest.raises(SceneError) as err:
        _sphere(30, **{"model.strain": "large"})
    assert "model.strain" in str(err.value) and "auto, small, finite" in str(err.value)


def test_repeated_impacts_run_small_strain_in_the_zones():
    """A sequence carries its plastic state through linear residual states: its plan is small
    strain with plasticity in the zones, and the reason says so."""
    plan = small_strain_plan(make_plan(_sphere(1000)))
    assert plan.strain == "small" and plan.plastic_whole == ()
    assert "repeated impacts" in dict(plan.reasons)["strain"]
