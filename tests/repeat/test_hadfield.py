"""Hadfield steel (a Voce law) under repeated impacts: the coarse version of the 50-impact
benchmark (benchmarks/hadfield_repeat.py): a 125 mm ball at 6 m/s, five times at one spot on the
manganese liner steel, very coarse (h_contact 4 mm ~ a_max / 1.6, h_far 30 mm; ~5 s an impact)."""
from __future__ import annotations

import numpy as np
import pytest

from millimpact.repeat.sequence import HB_PER_PA, ImpactSpec, run_sequence
from millimpact.scene.builtin import resolve_scene

pytestmark = pytest.mark.slow

#: the Voce law of hadfield-mn-liner-voce (scene/materials.toml): Y, Q, b
Y, Q, B = 380e6, 1.42e9, 2.5


@pytest.fixture(scope="module")
def hadfield():
    scene = resolve_scene("mill-hadfield").with_values([
        ("block.material", "hadfield-mn-liner-voce"), ("model.h_contact", 4e-3), ("model.h_far", 0.03)])
    return run_sequence(scene, [ImpactSpec(6.0)] * 5)


def test_hadfield_surface_hardens_towards_the_voce_saturation(hadfield):
    """The surface hardness 3 sigma_y at the impact point starts above the annealed steel's
    (3 Y = 116 HB: the point under the ball yields in the first impact), rises with every impact
    by less each time (the law saturates and the residual stress shields later impacts), and stays
    below the law's saturation 3 (Y + Q) = 551 HB."""
    hb = np.array([o.surface_flow_stress_Pa for o in hadfield]) * HB_PER_PA
    assert hb[0] > Y * HB_PER_PA * 1.01
    rise = np.diff(np.concatenate([[Y * HB_PER_PA], hb]))
    assert np.all(rise > 0), hb
    assert np.all(np.diff(rise) < 0), rise
    assert hb[-1] < (Y + Q) * HB_PER_PA


def test_hadfield_dent_spreads_and_deepens_by_less_each_impact(hadfield):
    """The dent deepens and widens with every impact (the steel keeps flowing: the lateral spread
    of a Hadfield liner), by less each time, and the restitution rises as the surface hardens."""
    depth = np.array([o.residual_dent_depth_m for o in hadfield])
    width = np.array([o.residual_dent_radius_m for o in hadfield])
    e = np.array([o.restitution_normal for o in hadfield])
    assert np.all(np.diff(depth) > 0) and np.all(np.diff(np.diff(depth)) < 0), depth
    assert np.all(np.diff(width) > 0), width
    assert np.all(np.diff(e) > 0), e
