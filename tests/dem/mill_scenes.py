"""A small mill for the DEM tests: 0.8 m across, 17 lifters 50 mm high, 60 mm balls."""
from __future__ import annotations

import dataclasses
import shutil

import pytest

from millimpact.scene.builtin import resolve_scene

needs_yade = pytest.mark.skipif(shutil.which("yade") is None, reason="Yade is not installed (apt-get install yade)")


def small_mill_scene(friction: float = 0.3):
    """liner-segment's materials on a 0.4 m mill radius: lifters 50 mm high, 30 mm top, 20 deg faces,
    150 mm apart (17 round the shell); balls of 30 mm radius."""
    base = resolve_scene("liner-segment")
    liner = dataclasses.replace(base.liner, width=0.3, thickness=0.04, lifter_height=0.05, lifter_top_width=0.03,
                                lifter_spacing=0.15, mill_radius=0.4)
    ball = dataclasses.replace(base.ball, radius=0.03)
    contact = dataclasses.replace(base.contact, friction=friction)
    return dataclasses.replace(base, name="small-mill", liner=liner, ball=ball, contact=contact)
