"""Edge impacts (issue 34): a bin whose contact would reach past its place's edge (a lifter's top
corner, the top's edge) is moved inward by the room its contact needs, or refused with the reason,
before anything is computed; the map's energy accounting still holds.

The room a bin needs is the contact's own (the method's candidate radius, Thornton's plastic
contact radius, one contact element: millimpact.damage.edges); the checks below are against the
geometry of the placed scene (its distance to the edge, measured along the surface from the
liner's construction), the energy balance of the real table engine's case and, with the fake
runner of test_damage_map, the sum over impacts with each impact's own restitutions.
"""
from __future__ import annotations

import json
import math

import pytest

from millimpact.damage.bins import choose_bins, yield_onset_speed
from millimpact.damage.damage_map import MapSettings, run_damage_map
from millimpact.damage.edges import MAX_EDGE_SHIFT_SHARE, edge_room, face_slant, fit_contacts
from millimpact.damage.places import place_scene
from millimpact.damage.responses import define_bin_cases
from millimpact.scene.toml_io import dump_scene
from test_damage_map import SCENE, SETS, FakeRunner, _impact, _map, _truth, map_through_cli

TOP_HALF = 0.5 * SCENE.liner.lifter_top_width     # 50 mm on liner-segment
#: the face's arc position 1 mm below the top corner: hb - s = f (hb - ht) (places.py)
FACE_CORNER_ARC = 0.5 * SCENE.liner.lifter_top_width + 0.001


def _corner_impacts():
    """Impacts on the top 1 mm from its edge and on the face 1 mm (of arc) below its top corner,
    from 0.5 to 8 m/s normal: the slow ones fit at the scene's own edge rule, the fast ones not."""
    out = []
    for v in (0.5, 1.0, 2.0, 4.0, 8.0):
        out += [_impact(v, 0.3 * v, "lifter_top", TOP_HALF - 0.001), _impact(v, 0.3 * v, "lifter_face", FACE_CORNER_ARC)]
    return out


def test_corner_bins_are_moved_inward_by_their_contacts_room(tmp_path):
    imps = _corner_impacts()
    res, out = _map(tmp_path, imps, repeat=0)
    bins = res["bins"]
    assert all(b["status"] == "ok" for b in bins)        # nothing refused, nothing failed
    moved = [b for b in bins if b["edge_shift_m"] > 0]
    assert moved and len(moved) < len(bins)              # the fast bins only
    for b in bins:
        # the placed scene's distance to its edge (the liner's own geometry) against the room the
        # bin's contact needs: at least it, and exactly it where the bin was moved (the nearest fit)
        arc = TOP_HALF - 0.001 if b["place"] == "lifter_top" else FACE_CORNER_ARC
        ps = place_scene(SCENE, b["place"], arc, margin=b["contact_margin_m"] if b["edge_shift_m"] > 0 else 0.0)
        room = edge_room(ps.scene)[0]
        assert room >= b["contact_margin_m"] * (1 - 1e-9)
        if b["edge_shift_m"] > 0:
            assert room == pytest.approx(b["contact_margin_m"], rel=1e-9) and "inward" in b["note"]
            assert b["edge_shift_m"] <= MAX_EDGE_SHIFT_SHARE * (SCENE.liner.lifter_top_width if b["place"] == "lifter_top"
                                                                else face_slant(SCENE.liner))
    # the margin grows with the speed (a_max ~ v^(2/5)): the fastest moved the most
    top = sorted((b for b in bins if b["place"] == "lifter_top"), key=lambda b: b["normal_speed_m_s"])
    assert [b["edge_shift_m"] for b in top] == sorted(b["edge_shift_m"] for b in top)
    assert any("clamped" in w for w in res["warnings"])
    # the moves are in damage.csv per place and the energy accounting still holds (1 %: the bins'
    # restitution spread, test_damage_map)
    for p in ("lifter_top", "lifter_face"):
        t = res["places"][p]
        assert t["impacts_left_out_per_rev"] == 0
        assert t["impacts_edge_clamped_per_rev"] == sum(b["impacts"] for b in moved if b["place"] == p)
        assert t["largest_edge_shift_m"] == max(b["edge_shift_m"] for b in moved if b["place"] == p)
    assert "impacts_edge_clamped_per_rev" in (out / "damage.csv").read_text()
    total = sum(t["energy_absorbed_J_per_rev"] for t in res["places"].values())
    assert total == pytest.approx(_truth(imps), rel=0.01)


def test_a_move_too_large_for_the_place_refuses_the_bin_and_the_sums_say_so(tmp_path):
    # a 40 mm top struck 1 mm from its edge: the 4 m/s contact needs ~11 mm of room (a move of
    # ~9 mm, under a quarter of the top), the 8 m/s one ~14 mm (a move of ~12 mm, over it)
    narrow = SCENE.with_value("liner.lifter_top_width", 0.04)
    clamped = [_impact(4.0, 1.2, "lifter_top", 0.019)] * 3
    refused = [_impact(8.0, 2.4, "lifter_top", 0.019)] * 2
    res = {}
    for name, imps in (("all", clamped + refused), ("clamped", clamped)):
        out = tmp_path / name
        out.mkdir()
        res[name] = run_damage_map(narrow, imps, out, MapSettings(revolutions=1.0, repeat_impacts=0), "synthetic",
                                   case_runner=FakeRunner(), quiet=True)
    by_speed = {round(b["normal_speed_m_s"]): b for b in res["all"]["bins"]}
    assert by_speed[4]["status"] == "ok" and 0 < by_speed[4]["edge_shift_m"] <= MAX_EDGE_SHIFT_SHARE * 0.04
    assert by_speed[8]["status"] == "refused" and "edge impact" in by_speed[8]["note"]
    assert f"more than {MAX_EDGE_SHIFT_SHARE:g} of the place's extent" in by_speed[8]["note"]
    assert any("refused: edge impact" in w for w in res["all"]["warnings"])
    t = res["all"]["places"]["lifter_top"]
    assert t["impacts_left_out_per_rev"] == 2 and t["impacts_edge_clamped_per_rev"] == 3
    # the refused bin adds nothing: the sums are those of the computed impacts (a lower bound)
    for q in ("energy_absorbed_J_per_rev", "plastic_work_J_per_rev"):
        assert t[q] == res["clamped"]["places"]["lifter_top"][q] > 0


def test_a_band_moved_off_an_edge_stays_one_band_and_a_refused_bin_does_not_split_it():
    # the coarse mesh (h_contact 4 mm) cannot hold the slow bin's contact zone: refused; the two
    # fast bins (normal speeds on one rung of the table's band ladder, [2.25, 3.375) m/s) keep one
    # band, one margin, one place
    coarse = SCENE.with_value("model.h_far", 0.04).with_value("model.h_contact", 0.004)
    imps = [_impact(0.2, 0.1, "lifter_top", TOP_HALF - 0.001), _impact(2.6, 0.9, "lifter_top", TOP_HALF - 0.001),
            _impact(3.1, 0.9, "lifter_top", TOP_HALF - 0.001)]
    choice = choose_bins(imps, yield_onset_speed(coarse), 30)
    assert len(choice.bins) == 3
    placed = {b.index: place_scene(coarse, b.place, b.arc_m) for b in choice.bins}
    bcs = define_bin_cases(choice.bins, placed, "improved", {})
    warned = []
    _, bcs, info = fit_contacts(coarse, choice.bins, placed, bcs, "improved", {}, warned.append)
    slow, *fast = sorted(bcs, key=lambda bc: bc.bin.normal_speed_m_s)
    assert slow.case is None and "h_contact" in slow.refused
    assert fast[0].case.band == fast[1].case.band and fast[0].case.band_scene == fast[1].case.band_scene
    assert dump_scene(fast[0].placed.scene) == dump_scene(fast[1].placed.scene)
    assert info[fast[0].bin.index] == info[fast[1].bin.index] and info[fast[0].bin.index]["edge_shift_m"] > 0
    assert len(warned) == 1 and "clamped" in warned[0]


@pytest.mark.slow
def test_corner_impacts_on_the_real_table_engine(tmp_path):
    """Fast impacts 1 mm from the top's edge and below the face's top corner on the coarse
    liner-segment, through the CLI: without the move their contact points would have no face below
    them (the run used to stop there); moved, each bin computes and its absorbed energy equals its
    case's own energy balance, plastic + friction + energy left in the liner."""
    imps = [_impact(4.0, 1.0, "lifter_top", TOP_HALF - 0.001), _impact(4.0, 1.0, "lifter_face", FACE_CORNER_ARC)]
    out, res = map_through_cli(tmp_path, imps, revolutions=1)
    assert len(res["bins"]) == 2
    for b in res["bins"]:
        row = json.loads((out / "cases" / f"{b['case_key']}.json").read_text())
        assert row["status"] == "ok" and b["edge_shift_m"] > 0 and "inward" in b["note"]
        per_impact = row["plastic_dissipation_J"] + row["friction_dissipation_J"] + row["energy_to_liner_J"]
        assert b["energy_absorbed_J_per_rev"] == pytest.approx(b["impacts"] * per_impact, rel=1e-9)
        assert math.isfinite(row["restitution_normal"]) and 0 < row["restitution_normal"] < 1
    assert all(t["impacts_left_out_per_rev"] == 0 for t in res["places"].values())
