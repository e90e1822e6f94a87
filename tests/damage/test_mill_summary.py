"""The damage map reads the mill's own summary.json beside its impacts.csv: the logged revolutions
(``clock.revolutions``) and the mill's lifter count, so `millimpact damage` chains onto
`millimpact mill` with no extra option; given options win."""
from __future__ import annotations

import argparse
import json

import pytest

from millimpact.damage.command import check_log_liner, lifters_of, revolutions_of
from millimpact.errors import InputError


def _args(**kw):
    return argparse.Namespace(**{"revolutions": None, "lifters": None, **kw})


def test_mill_summary_gives_revolutions_and_lifters(tmp_path):
    # the layout millimpact mill writes (dem/mill.py): clock.revolutions, mill.lifters
    (tmp_path / "summary.json").write_text(json.dumps({"clock": {"revolutions": 2.0}, "mill": {"lifters": 115}}))
    log = tmp_path / "impacts.csv"
    assert revolutions_of(_args(), log) == 2.0
    assert lifters_of(_args(), log) == 115
    assert revolutions_of(_args(revolutions=3.0), log) == 3.0
    assert lifters_of(_args(lifters=4), log) == 4


def test_without_a_summary_revolutions_must_be_given(tmp_path):
    log = tmp_path / "impacts.csv"
    assert lifters_of(_args(), log) == 1
    with pytest.raises(InputError, match="--revolutions"):
        revolutions_of(_args(), log)


def test_a_log_of_another_liners_mill_is_refused(tmp_path):
    """liner-segment's mill log (115 lifters 0.2 m high, D 11 m) mapped on liner-panel (77 lifters,
    0.18 m): its places and arc positions belong to the other liner (before: accepted without a
    word); on its own scene, or without a summary, it is taken."""
    from millimpact.scene.builtin import builtin_scene

    mill = {"diameter_m": 11.0, "lifters": 115, "lifter_height_m": 0.2}
    (tmp_path / "summary.json").write_text(json.dumps({"scene": "liner-segment", "mill": mill}))
    log = tmp_path / "impacts.csv"
    with pytest.raises(InputError, match="logged by millimpact mill on liner-segment .* not on the liner of "
                                         "liner-panel"):
        check_log_liner(builtin_scene("liner-panel"), log)
    check_log_liner(builtin_scene("liner-segment"), log)
    check_log_liner(builtin_scene("liner-panel"), tmp_path / "elsewhere" / "impacts.csv")
