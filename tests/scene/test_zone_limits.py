"""A struck body's contact zone may outgrow the ball's: a model.zone_radius above 0.45 of the ball's
radius is accepted up to 0.45 of the struck body's smallest side, the ball keeping a zone of its
own at 0.98 x 0.45 of its radius (scene/plan.py); above the body's limit it is refused naming the
field and the limit."""
from __future__ import annotations

import pytest

from millimpact.scene.builtin import builtin_scene
from millimpact.scene.plan import PLASTIC_ZONE_CAP, ZONE_SIZE_SHARE, make_plan
from millimpact.scene.schema import SceneError


def _mill(zone=None):
    s = builtin_scene("mill-hadfield")
    return s if zone is None else s.with_value("model.zone_radius", zone)


def test_a_block_zone_beyond_the_balls_cap_gives_the_ball_its_own_zone():
    scene = _mill()
    ball_cap = PLASTIC_ZONE_CAP * ZONE_SIZE_SHARE * scene.ball.radius  # 27.56 mm for the 125 mm ball
    block_limit = ZONE_SIZE_SHARE * scene.block.thickness  # 33.75 mm for the 75 mm plate
    assert ball_cap < 0.033 < block_limit
    plan = make_plan(_mill(0.033))
    assert plan.zone_radius == 0.033
    assert plan.ball_zone == pytest.approx(ball_cap, rel=1e-12)
    # below the ball's cap the ball shares the zone, as before
    small = make_plan(_mill(0.02))
    assert small.zone_radius == small.ball_zone == 0.02


def test_a_zone_beyond_the_struck_bodys_limit_is_refused():
    limit = ZONE_SIZE_SHARE * _mill().block.thickness
    with pytest.raises(SceneError, match=f"model.zone_radius.*smaller than {limit:g} m"):
        make_plan(_mill(1.01 * limit))
