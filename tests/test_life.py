"""Liner life (millimpact.life): the worn profile's geometry against exact offsets, the wear law's
arithmetic, a calibration that reproduces its figure, bad input, and the loop that runs the mill
again on the worn profile."""
from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from millimpact.life.calibration import DEFAULT_LAW, initial_height_rate
from millimpact.life.profile import LifterProfile, worn_profile
from millimpact.life.wear import MillRecord, WearLaw, depth_rates, surface_depths

from conftest import run_cli


def _lifter(angle=20.0):
    return LifterProfile(mill_radius=5.5, n_lifters=77, height=0.18, top_width=0.10, top_centre=0.0,
                         trailing_angle_deg=angle, leading_angle_deg=angle, plate_thickness=0.075)


def _uniform(lp, d):
    z = np.linspace(0.0, 0.1, 5)
    return {s: (z, np.full(5, d)) for s in ("trailing_face", "top", "leading_face", "plate")}


def test_uniform_wear_offsets_every_surface_by_its_depth():
    """Every surface worn by d: the top falls by d and the plate by d (the height above the plate
    is kept), the angles stay, and the top narrows as two lines offset by d meet the lowered top:
    w' = w + 2 d (tan a - 1 / cos a) (exact plane geometry)."""
    lp, d = _lifter(), 0.01
    new = worn_profile(lp, _uniform(lp, d))
    a = math.radians(20.0)
    assert new.height == pytest.approx(0.18 - d, abs=1e-12)
    assert new.height_above_plate == pytest.approx(0.18, abs=1e-12)
    assert new.plate_left == pytest.approx(0.075 - d, abs=1e-12)
    assert new.trailing_angle_deg == pytest.approx(20.0, abs=1e-9)
    assert new.leading_angle_deg == pytest.approx(20.0, abs=1e-9)
    assert new.top_width == pytest.approx(0.10 + 2 * d * (math.tan(a) - 1 / math.cos(a)), abs=1e-12)


def test_a_face_worn_more_at_its_top_turns_by_atan_of_the_difference():
    """The leading face worn d0 at its top corner falling linearly to 0 at its foot (positions from
    the top corner, as the profile runs): its angle grows by atan(d0 / L), L the face's length; the
    other surfaces do not move."""
    lp, d0 = _lifter(), 0.02
    L = 0.18 / math.cos(math.radians(20.0))
    u = np.linspace(0.0, L, 11)
    new = worn_profile(lp, {"leading_face": (u, d0 * (1 - u / L))})
    assert new.leading_angle_deg == pytest.approx(20.0 + math.degrees(math.atan(d0 / L)), abs=1e-9)
    assert new.trailing_angle_deg == pytest.approx(20.0, abs=1e-12)
    assert new.height == pytest.approx(0.18, abs=1e-12)
    # and the mill's profile is built from it (asymmetric faces)
    assert new.mill_profile(0.0625).n_lifters == 77


def test_wear_rates_are_volume_over_area_times_revolutions():
    """One bin: Archard 2 N m and 3 J absorbed a revolution; k_a 1e-3, k_i 2e-3, H 3 GPa; a 10 mm bin
    of a 0.25 m slice round 77 lifters at 10 rpm: depth per 1000 h = V / (b L n) x 600,000 rev."""
    law = WearLaw(abrasion=1e-3, impact=2e-3, hardness_Pa=3e9, density_kg_m3=7850.0)
    rec = MillRecord(folder=Path("."), surface=np.array(["top"]), position=np.array([0.2]),
                     archard=np.array([2.0]), absorbed=np.array([3.0]), bin_m=0.01, slice_m=0.25, n_lifters=77,
                     rpm=10.0, summary={}, surfaces=[[0, 0.1], [0.1, 0.3], [0.3, 0.4], [0.4, 1.0]])
    r = depth_rates(rec, law)
    revs = 10 * 60 * 1000
    area = 0.01 * 0.25 * 77
    assert r["abrasion_mm_per_1000h"][0] == pytest.approx(1e3 * 1e-3 * 2 / 3e9 / area * revs, rel=1e-12)
    assert r["impact_mm_per_1000h"][0] == pytest.approx(1e3 * 2e-3 * 3 / 3e9 / area * revs, rel=1e-12)
    assert r["mass_kg_per_1000h"][0] == pytest.approx((2e-3 + 6e-3) / 3e9 * 7850 * revs, rel=1e-12)


def test_first_order_decay_rate():
    """152 -> 58 mm in 4000 h: tau = 4000 / ln(152/58) = 4152 h, the new lifter's rate 152 / tau."""
    tau = 4000 / math.log(152 / 58)
    assert initial_height_rate(152, 58, 4000) == pytest.approx(152 / tau * 1000, rel=1e-12)
    assert DEFAULT_LAW.hardness_Pa == pytest.approx(325 * 9.807e6)


@pytest.mark.parametrize("args, words", [
    (["--hours", "0"], "--hours 0.0: must lie in (0"),
    (["--cycles", "0"], "--cycles 0: must be an integer in [1, 100]"),
    (["--spread", "1.5"], "--spread 1.5: must lie in [0, 1)"),
    (["--max-step-depth", "0"], "--max-step-depth 0.0: must lie in (0, 1]"),
    (["--calibrate-height", "58:152:4000"], "needs H0 > H1 > 0 mm"),
    (["--calibrate-mass", "2.6", "--calibrate-height", "152:58:4000"], "give one of them"),
    (["--calibrate-life", "152:58:4000", "--hours", "1000"], "runs the life to its figure's 4000 h"),
    (["--calibrate-life", "152:58"], "--calibrate-life '152:58': give H0:H1:HOURS"),
    (["--calibrate-life", "152:58:4000", "--max-step-depth", "1"], "not with --calibrate-life"),
])
def test_bad_life_input_is_one_line_and_exit_2_and_no_folder(tmp_path, args, words):
    mill = tmp_path / "mill"
    mill.mkdir()
    out = tmp_path / "life"
    res = run_cli("life", "liner-panel", "--mill", str(mill), *args, "--out", str(out), timeout=120)
    assert res.returncode == 2, res.stderr
    lines = res.stderr.strip().splitlines()
    assert len(lines) == 1 and words in lines[0], res.stderr
    assert not out.exists()


def test_a_folder_that_is_no_mill_run_is_one_line(tmp_path):
    res = run_cli("life", "liner-panel", "--mill", str(tmp_path), "--out", str(tmp_path / "life"), timeout=120)
    assert res.returncode == 2 and "not a mill run with abrasion" in res.stderr
    assert not (tmp_path / "life").exists()


@pytest.mark.slow
def test_the_loop_runs_the_mill_again_on_the_worn_profile(tmp_path, monkeypatch, capsys):
    """A short SAG run of the small mill (moduli x 0.001), then life over 2 cycles: the second mill
    run is made on the worn profile (its lifters as high as the first step left them, within the
    plate's chord sagitta), profiles.csv holds the three profiles, the calibration reproduces its
    figure (the new lifter's height loss rate, first-order decay of 50 -> 30 mm in 2000 h); then
    what its kept re-runs give a rerun and an interrupted one (_rerun_keeps_and_resumes)."""
    import shutil

    if shutil.which("yade") is None:
        pytest.skip("Yade is not installed (apt-get install yade)")
    sets = ["--set", "liner.width=0.3", "--set", "liner.thickness=0.04", "--set", "liner.lifter_height=0.05",
            "--set", "liner.lifter_top_width=0.03", "--set", "liner.lifter_spacing=0.15", "--set",
            "liner.mill_radius=0.4", "--set", "ball.radius=0.03", "--set", "contact.friction=0.3"]
    mill = tmp_path / "mill"
    res = run_cli("mill", "liner-segment", *sets, "--charge", "sag", "--rock-top-size", "0.06", "--rock-cutoff",
                  "0.03", "--stiffness-scale", "0.001", "--revolutions", "0.2", "--warmup", "0.2", "--no-plots",
                  "--out", str(mill), timeout=900)
    assert res.returncode == 0, res.stderr
    life = tmp_path / "life"
    res = run_cli("life", "liner-segment", *sets, "--mill", str(mill), "--calibrate-height", "50:30:2000",
                  "--hours", "400", "--cycles", "2", "--reline-height", "5", "--out", str(life), timeout=900)
    assert res.returncode == 0, res.stderr
    s = json.loads((life / "summary.json").read_text())
    rows = s["profiles"]
    assert len(rows) == 3 and rows[0]["hours"] == 0 and rows[2]["hours"] == 400
    # the calibrated constants give back the figure on the first run: top less plate
    first = s["rates"][0]
    assert first["top"]["mean_mm_per_1000h"] - first["plate"]["mean_mm_per_1000h"] == pytest.approx(
        initial_height_rate(50, 30, 2000), rel=1e-9)
    second = json.loads((life / "mills" / "cycle-1" / "summary.json").read_text())
    assert second["mill"]["lifter_height_m"] * 1e3 == pytest.approx(rows[1]["lifter_height_mm"], rel=1e-9)
    assert rows[1]["net_power_kW_m"] > 0
    # the stage times: the re-run's lap holds its Yade run (Yade's own clock, in the re-run's summary)
    t, laps = s["wall_time_s"], s["wall_time_s_per_cycle"]
    assert len(laps["mill_reruns"]) == 1 and laps["mill_reruns"][0] >= second["yade"]["wall_s"]
    assert t["mill_reruns"] == pytest.approx(sum(laps["mill_reruns"]), rel=1e-12)
    assert sum(v for k, v in t.items() if k != "total") == pytest.approx(t["total"], rel=1e-12)
    # every bin of every surface is in the record, the ones nothing touched as zero, so a surface's
    # mean is over its whole length (a plate touched on a third of its bins is not worn three times
    # as deep): the bins' centres tile each surface at the bin width
    from millimpact.life.profile import LifterProfile
    from millimpact.life.wear import read_mill_record
    from millimpact.scene.builtin import resolve_scene

    scene = resolve_scene("liner-segment").with_values(
        [(sets[k + 1].split("=")[0], float(sets[k + 1].split("=")[1])) for k in range(0, len(sets), 2)])
    rec = read_mill_record(mill, LifterProfile.from_liner(scene.liner).mill_profile(scene.ball.radius))
    for name, (a, b) in zip(("trailing_face", "top", "leading_face", "plate"), rec.surfaces):
        centres = np.sort(rec.position[rec.surface == name])
        expected = [x for x in (np.arange(int(b / rec.bin_m) + 2) + 0.5) * rec.bin_m if a <= x < b]
        assert set(np.round(expected, 9)) <= set(np.round(centres, 9)), name
    assert np.count_nonzero(rec.archard + rec.absorbed == 0) > 0  # some bins are untouched
    # --calibrate-life with one cycle holds the first run's rates; the life ends H1 high at HOURS
    held = tmp_path / "life-held"
    res = run_cli("life", "liner-segment", *sets, "--mill", str(mill), "--calibrate-life", "50:30:2000",
                  "--reline-height", "5", "--no-plots", "--out", str(held), timeout=300)
    assert res.returncode == 0, res.stderr
    h = json.loads((held / "summary.json").read_text())
    assert h["profiles"][-1]["hours"] == pytest.approx(2000, rel=1e-12)
    assert h["profiles"][-1]["lifter_height_mm"] == pytest.approx(30, rel=1e-9)
    assert json.loads((held / "calibration.json").read_text())["calibrated_on"]["target"] == 30
    _rerun_keeps_and_resumes(life, [*sets, "--mill", str(mill), "--calibrate-height", "50:30:2000",
                                    "--reline-height", "5", "-q", "--out", str(life)], s, monkeypatch, capsys)


def _rerun_keeps_and_resumes(life, args, first, monkeypatch, capsys):
    """The mill re-runs a life keeps (mills/cycle-K/, keyed by scene, options, profile and version):
    the same command again runs no mill and gives the same profiles; a 3-cycle life over 600 h (its
    first step the 200 h of the 2-cycle one: the same profile) takes cycle-1 and, interrupted (Ctrl-C)
    in cycle 2's run, writes no summary.json and says what it kept; run again it runs cycle 2 alone;
    the 2-cycle life after it runs none and drops cycle-2; a kept run whose key differs (another
    profile's) is run again. The re-runs here are a stand-in that copies cycle-1's files: what is
    tested is which runs are made and kept, not the DEM (the test above runs it)."""
    import shutil

    from millimpact import cli
    from millimpact.dem.mill import run as mill_run

    calls, stop = [], [0]
    made = life / "made-by-the-stand-in"
    shutil.copytree(life / "mills" / "cycle-1", made)
    summary = json.loads((made / "summary.json").read_text())

    def counted(scene, opts, stage, **k):
        calls.append(stage.name)
        if len(calls) == stop[0]:
            raise KeyboardInterrupt
        shutil.copytree(made, stage, dirs_exist_ok=True)
        return {k: v for k, v in summary.items() if k != "life_key"}

    monkeypatch.setattr(mill_run, "run_mill", counted)
    two, three = ["life", "liner-segment", *args], ["life", "liner-segment", *args, "--hours", "600", "--cycles", "3"]
    two += ["--hours", "400", "--cycles", "2"]
    assert cli.main(two) == 0 and calls == []
    assert json.loads((life / "summary.json").read_text())["profiles"] == first["profiles"]
    stop[0] = 1
    assert cli.main(three) == 130 and calls == [".cycle-2.partial"]
    assert "1 finished mill re-run(s) kept in" in capsys.readouterr().err
    assert json.loads((life / "summary.json").read_text())["profiles"] == first["profiles"]  # not replaced
    calls.clear()
    stop[0] = 0
    assert cli.main(three) == 0 and calls == [".cycle-2.partial"]
    assert [r["hours"] for r in json.loads((life / "summary.json").read_text())["profiles"]] == [0, 200, 400, 600]
    calls.clear()
    assert cli.main(two) == 0 and calls == []
    assert sorted(p.name for p in (life / "mills").iterdir()) == ["cycle-1"]
    kept = life / "mills" / "cycle-1" / "summary.json"
    kept.write_text(kept.read_text().replace('"life_key": "', '"life_key": "x'))
    stop[0] = 1
    assert cli.main(two) == 130 and calls == [".cycle-1.partial"]


def _record(tmp_path, power_W_m=2.0e5):
    """One bin on each surface, Archard 2 N m and 3 J absorbed a revolution each; 10 rpm, 77 lifters."""
    surf = np.array(["trailing_face", "top", "leading_face", "plate"])
    return MillRecord(folder=tmp_path, surface=surf, position=np.array([0.05, 0.2, 0.35, 0.6]),
                      archard=np.full(4, 2.0), absorbed=np.full(4, 3.0), bin_m=0.01, slice_m=0.25, n_lifters=77,
                      rpm=10.0, summary={"power": {"measured": {"net_per_metre_W_m": power_W_m}}},
                      surfaces=[[0, 0.1], [0.1, 0.3], [0.3, 0.4], [0.4, 1.0]])


def test_a_mass_calibration_gives_its_g_per_kwh_back(tmp_path):
    """--calibrate-mass 2.6: the calibrated law's mass per metre of mill over the net power per metre
    is 2.6 g/kWh (the calibration scales both constants, their ratio held)."""
    import argparse

    from millimpact.life.command import calibrate
    from millimpact.life.wear import place_rates

    rec = _record(tmp_path)
    args = argparse.Namespace(calibration=None, calibrate_height=None, calibrate_mass=2.6, impact_ratio=0.5,
                              spread=None)
    cal = calibrate(args, rec, {"yield_stress_Pa": 9.5e8})
    assert cal.law.impact == pytest.approx(0.5 * cal.law.abrasion, rel=1e-12)
    kg_per_1000h_per_m = sum(r["mass_kg_per_1000h_per_metre"] for r in place_rates(rec, depth_rates(rec, cal.law)).values())
    kwh_per_1000h_per_m = 2.0e5 / 1e3 * 1000
    assert 1e3 * kg_per_1000h_per_m / kwh_per_1000h_per_m == pytest.approx(2.6, rel=1e-12)


def test_a_calibration_made_on_another_steel_is_refused(tmp_path):
    """A calibration made on liner-segment's Cr-Mo liner serves it and is refused, one line naming
    both steels, for the same scene with a Hadfield liner (the constants are the steel's); a file
    that does not say which steel (an older one) is taken as it is."""
    import argparse

    from millimpact.errors import InputError
    from millimpact.life.calibration import liner_steel
    from millimpact.life.command import calibrate
    from millimpact.scene.builtin import builtin_scene

    crmo = liner_steel(builtin_scene("liner-segment").liner.material)
    hadfield = liner_steel(builtin_scene("liner-segment").with_value("liner.material", "hadfield-mn-liner").liner.material)
    rec = _record(tmp_path)
    made = calibrate(argparse.Namespace(calibration=None, calibrate_height=None, calibrate_mass=2.6, impact_ratio=1.0,
                                        spread=None), rec, crmo)
    path = tmp_path / "calibration.json"
    path.write_text(made.to_json())
    use = argparse.Namespace(calibration=str(path), calibrate_height=None, calibrate_mass=None, spread=None)
    assert calibrate(use, rec, crmo).law == made.law
    with pytest.raises(InputError, match="another liner steel, Cr-Mo liner steel of yield 950 MPa, than this scene's, Hadfield .* of yield 380 MPa"):
        calibrate(use, rec, hadfield)
    older = json.loads(path.read_text())
    del older["calibrated_on"]["liner_steel"]
    path.write_text(json.dumps(older))
    assert calibrate(use, rec, hadfield).law == made.law


def test_metal_flow_is_the_dent_growth_over_1000_hours(tmp_path):
    """A damage map's dent growth of 1e-9 m per revolution at a spot, at 10 rpm: 600,000 revolutions
    in 1000 h, 0.6 mm; reported beside the wear (never added to it)."""
    from millimpact.life.report import metal_flow

    (tmp_path / "damage.csv").write_text(
        "# a comment line\nplace,dent_growth_m_per_rev,repeat_verdict\nlifter_face,1e-09,ratcheting\nplate,nan,shakedown\n")
    flow = metal_flow(str(tmp_path), rpm=10.0)
    assert flow["lifter_face"]["dent_growth_mm_per_1000h"] == pytest.approx(0.6, rel=1e-12)
    assert flow["plate"]["dent_growth_mm_per_1000h"] is None
    assert "never added" in flow["is"]


def _unit_record(lp: LifterProfile, bin_m: float = 0.002, plate: float = 1.0) -> MillRecord:
    """Bins of ``bin_m`` along one lifter unit of ``lp`` (trailing face from its foot, top, leading
    face from its top corner, the plate to the next lifter; the plate's curvature neglected, as
    worn_profile does): Archard's integral linear along each face (more at the top corner, as the
    charge wears it), uniform on the top and ``plate`` times that on the plate; no impacts."""
    bt, tt, tl, bl = lp.corners()
    pitch = 2.0 * math.pi * lp.mill_radius / lp.n_lifters
    lengths = {"trailing_face": math.dist(bt, tt), "top": lp.top_width, "leading_face": math.dist(tl, bl),
               "plate": pitch - (bl[0] - bt[0])}
    surface, position, archard, bounds, s0 = [], [], [], [], 0.0
    for name, length in lengths.items():
        n = int(round(length / bin_m))
        u = (np.arange(n) + 0.5) * length / n
        along = {"trailing_face": u / length, "leading_face": 1.0 - u / length}.get(name, np.full(n, 0.5))
        surface += [name] * n
        position += list(s0 + u)
        archard += list((1.0 + 2.0 * along) * (plate if name == "plate" else 1.0))
        bounds.append([s0, s0 + length])
        s0 += length
    return MillRecord(folder=Path("."), surface=np.array(surface), position=np.array(position),
                      archard=np.array(archard) * (bin_m / 0.002), absorbed=np.zeros(len(surface)), bin_m=bin_m,
                      slice_m=0.25, n_lifters=lp.n_lifters, rpm=10.0, summary={}, surfaces=bounds)


def _steel_area(lp: LifterProfile) -> float:
    """The steel of one unit's cross-section above the plate's back (m^2): the plate band of the
    pitch (flat) and the lifter down to the worn plate's face."""
    pitch = 2.0 * math.pi * lp.mill_radius / lp.n_lifters
    _, tt, tl, _ = lp.corners()
    drop = lp.height + lp.plate_wear
    foot_t = tt[0] - drop * math.tan(math.radians(lp.trailing_angle_deg))
    foot_l = tl[0] + drop * math.tan(math.radians(lp.leading_angle_deg))
    lifter = 0.5 * ((foot_l - foot_t) + (tl[0] - tt[0])) * drop - lp.chamfer_area()
    return pitch * lp.plate_left + lifter


def test_the_profile_update_keeps_the_steel_the_wear_removed():
    """The wear integrated over the unit's surface, sum of depth x bin width, equals the steel the
    updated profile lost (its cross-section's area before less after) within 1 %: the faces move
    by their depth along their normals, the top and the plate by theirs, and the chamfers take the
    rest of the lifter's wear by construction; what differs is the plate's (its feet move down
    the faces) and the bins' ends against the surfaces' (here d ~ 1-3 mm on a 180 mm lifter:
    measured -0.09 %)."""
    lp = _lifter()
    rec = _unit_record(lp)
    law = WearLaw(abrasion=0.5, impact=0.0, hardness_Pa=3e9, density_kg_m3=7850.0)
    rates = depth_rates(rec, law)
    hours = 200.0
    depths = surface_depths(rec, rates, hours)
    assert 5e-4 < max(float(d.max()) for _, d in depths.values()) < 5e-3  # small against the lifter
    removed = sum(float(d.sum()) for _, d in depths.values()) * rec.bin_m
    new = worn_profile(lp, depths)
    assert _steel_area(lp) - _steel_area(new) == pytest.approx(removed, rel=0.01)
    # the same in mass: the rates' kg over the hours, per unit of the slice
    mass = float(rates["mass_kg_per_1000h"].sum()) * hours / 1000.0
    assert mass / (7850.0 * rec.slice_m * rec.n_lifters) == pytest.approx(removed, rel=1e-9)


def test_a_worn_top_edge_is_cut_and_does_not_turn_its_face():
    """The trailing face worn d everywhere and 20 d in its last bin at the top corner (as the
    charge strikes a sharp edge): its angle stays (the line is fitted off the corner), and a
    chamfer takes the corner's extra steel, its area c^2 cos(alpha) / 2 equal to the extra wear
    (19 d x the bin) less the sliver the face's offset leaves at the corner (O(d^2): 2 %)."""
    lp, d, w = _lifter(), 0.001, 0.005
    L = 0.18 / math.cos(math.radians(20.0))
    u = (np.arange(int(L / w)) + 0.5) * w
    dd = np.full(u.size, d)
    dd[-1] = 20 * d
    new = worn_profile(lp, {"trailing_face": (u, dd)}, w)
    assert new.trailing_angle_deg == pytest.approx(20.0, abs=1e-9) and new.leading_angle_deg == 20.0
    assert new.height == pytest.approx(0.18, abs=1e-12) and new.leading_chamfer == 0.0
    area = 0.5 * new.trailing_chamfer**2 * math.cos(math.radians(20.0))
    assert area == pytest.approx(19 * d * w, rel=0.02)
    # the steel: the outlines' areas differ by the wear integrated (exact by construction, 1e-9)
    from millimpact.life.profile import _area
    assert _area(lp.outline()) - _area(new.outline()) == pytest.approx(float(dd.sum()) * w, rel=1e-9)
    # and the mill's profile has the chamfer as a segment of the trailing face's part: one more
    # segment a unit, the trailing face the chamfer's chord longer
    old_p, new_p = lp.mill_profile(0.0625), new.mill_profile(0.0625)
    assert new_p.segments_per_unit == old_p.segments_per_unit + 1
    (a0, a1), (b0, b1) = old_p.unit_surfaces()[0], new_p.unit_surfaces()[0]
    chord = 2 * new.trailing_chamfer * math.sin(math.radians(55.0))
    assert b1 - b0 == pytest.approx(L - d - new.trailing_chamfer + chord, abs=1e-3)  # the face's foot moves
    assert [s.part % 4 for s in new_p.segments[:3]] == [0, 0, 1]


def test_twice_the_hours_wear_twice_the_depth_on_a_fixed_profile():
    """Without a profile update the depth is the rate times the hours: twice the hours, twice every
    bin's depth (exactly), and the top and plate move twice as far."""
    lp = _lifter()
    rec = _unit_record(lp)
    law = WearLaw(abrasion=1e-3, impact=0.0, hardness_Pa=3e9, density_kg_m3=7850.0)
    rates = depth_rates(rec, law)
    one, two = surface_depths(rec, rates, 100.0), surface_depths(rec, rates, 200.0)
    for surf in one:
        assert np.allclose(two[surf][1], 2.0 * one[surf][1], rtol=1e-12, atol=0)
    a, b = worn_profile(lp, one), worn_profile(lp, two)
    assert lp.height - b.height == pytest.approx(2.0 * (lp.height - a.height), rel=1e-12)
    assert b.plate_wear == pytest.approx(2.0 * a.plate_wear, rel=1e-12)


def _fake_mill(monkeypatch, loop, delay=0.0, plate=1.0):
    """(record, run_mill_on) of a fake mill for ``loop.run_life``: each run on a profile takes
    ``delay`` s and reads back as _unit_record of that profile (its summary a fixed mill state)."""
    import dataclasses
    import time

    summary = {"power": {"measured": {"net_per_metre_W_m": 1e5}}, "toe_deg": -30, "shoulder_deg": 130,
               "impacts_per_revolution": {"all": 1.0}, "energy_per_revolution_J": {"all": 1.0}}
    worn = {}

    def record(lp):
        return dataclasses.replace(_unit_record(lp, plate=plate), summary=summary)

    def run_mill_on(lp, cycle):
        time.sleep(delay)
        worn["lp"] = lp
        return Path(".")

    monkeypatch.setattr(loop, "read_mill_record", lambda folder, profile: record(worn["lp"]))
    return record, run_mill_on


def test_the_loop_times_each_cycle_and_each_mill_rerun(tmp_path, monkeypatch):
    """run_life over 3 cycles with a mill runner that sleeps 0.4 s: one lap of wear and profile
    update per cycle, one mill re-run (and one read of it) per cycle but the last; each re-run's lap
    at least its 0.4 s and less than 0.3 s over (the fake's own work is microseconds; room for a
    loaded machine); the clock's stages and other add up to its total (to round-off)."""

    from millimpact.commandkit.timing import StageClock
    from millimpact.life import loop

    record, run_mill_on = _fake_mill(monkeypatch, loop, delay=0.4)
    lp = _lifter()
    law = WearLaw(abrasion=1e-3, impact=0.0, hardness_Pa=3e9, density_kg_m3=7850.0)
    clock = StageClock()
    steps, _, why = loop.run_life(lp, record(lp), law, 300.0, 3, (1.0, 1.0), run_mill_on, 0.0625, clock=clock)
    assert why is None and len(steps) == 4
    assert len(clock.laps["wear_and_profile"]) == 3 and len(clock.laps["read"]) == 2
    assert len(clock.laps["mill_reruns"]) == 2 and all(0.4 <= t < 0.7 for t in clock.laps["mill_reruns"])
    t = clock.record()
    assert sum(v for k, v in t.items() if k != "total") == pytest.approx(t["total"], rel=1e-12)


def test_an_unworn_profile_is_the_scenes_own():
    """The life loop's profile of a new liner (LifterProfile.from_liner) builds the same mill
    profile as the mill run on the scene's liner, segment by segment (1e-12 m), so a mill run on an
    unworn profile is the scene's own run."""
    from millimpact.dem.mill.geometry import build_profile
    from millimpact.scene.builtin import resolve_scene

    for name in ("liner-segment", "liner-panel"):
        liner = resolve_scene(name).liner
        ours = LifterProfile.from_liner(liner).mill_profile(0.0625)
        theirs = build_profile(liner, 0.0625)
        assert len(ours.segments) == len(theirs.segments) and ours.n_lifters == theirs.n_lifters
        for p, q in zip(ours.segments, theirs.segments):
            assert (p.place, p.lifter, p.part) == (q.place, q.lifter, q.part)
            assert math.dist(p.start, q.start) < 1e-12 and math.dist(p.end, q.end) < 1e-12


def test_a_step_limit_keeps_each_bins_loss_below_its_share_of_the_lifter(monkeypatch):
    """--max-step-depth F: each step is the nominal hours / cycles, or shorter so that its largest
    bin depth is F of the lifter's height above the plate (to round-off: the depth is linear in the
    hours), never below a quarter of the nominal step; the steps still add up to the hours. The
    fake mill wears the top corner fastest (_unit_record); at an abrasion constant of 0.5 its
    2000 h step takes 15.5 mm there, more than F = 0.05 of the 180 mm lifter (9 mm): the limit
    binds."""

    from millimpact.life import loop

    record, run_mill_on = _fake_mill(monkeypatch, loop)
    lp = _lifter()
    law = WearLaw(abrasion=0.5, impact=0.0, hardness_Pa=3e9, density_kg_m3=7850.0)
    equal, _, _ = loop.run_life(lp, record(lp), law, 4000.0, 2, (1.0, 1.0), run_mill_on, 0.0625)
    share = 0.05
    steps, _, why = loop.run_life(lp, record(lp), law, 4000.0, 2, (1.0, 1.0), run_mill_on, 0.0625,
                                  max_step_share=share)
    assert why is None and steps[-1].hours == pytest.approx(4000.0, rel=1e-12)
    assert len(equal) == 3 and len(steps) > len(equal)  # the limit binds: more, shorter steps
    for before, after in zip(steps[:-1], steps[1:]):
        dt = after.hours - before.hours
        assert loop.MIN_STEP_SHARE * 2000.0 * (1 - 1e-12) <= dt <= 2000.0 * (1 + 1e-12) or after is steps[-1]
        limit = share * 1e3 * before.profile.height_above_plate
        assert before.largest_step_depth_mm <= limit * (1 + 1e-9) or dt == pytest.approx(loop.MIN_STEP_SHARE * 2000.0)
    assert max(s.largest_step_depth_mm for s in steps[:-1]) < max(s.largest_step_depth_mm for s in equal[:-1])


def test_a_life_calibration_reaches_its_height_at_its_hours(monkeypatch):
    """--calibrate-life: the life stepped at provisional constants until the lifter is H1 high
    (the last step cut there: the height falls linearly within a step), then the constants scaled
    so that this happens at HOURS. Checked independently of the loop: each rescaled step, redone
    by hand at the calibrated constants from its profile's own mill record, gives the next profile
    (to round-off: a factor on the constants only rescales the hours), and the last one is H1 high
    at HOURS. With the fake mill (its record follows the profile; its plate wears a quarter of its
    top's rate, so the lifter loses height) the rates change every step."""
    from millimpact.life import loop
    from millimpact.life.calibration import Calibration, through_life

    record, run_mill_on = _fake_mill(monkeypatch, loop, plate=0.25)
    lp = _lifter()
    law = WearLaw(abrasion=1.0, impact=0.0, hardness_Pa=3e9, density_kg_m3=7850.0)
    h1, hours = 0.120, 4000.0
    steps, rates, why = loop.run_life(lp, record(lp), law, hours, 4, (1.0, 1.0), run_mill_on, 0.0625,
                                      max_step_share=0.2, stop_height=h1)
    assert why is None and steps[-1].profile.height_above_plate == pytest.approx(h1, rel=1e-12)
    assert steps[-2].profile.height_above_plate > h1 and len(steps) > 2
    cal, factor = through_life(Calibration(law, {"h1_mm": 120.0}), steps[-1].hours, hours)
    steps, rescaled_rates = loop.rescaled(steps, rates, factor)
    assert steps[-1].hours == pytest.approx(hours, rel=1e-12) and cal.calibrated_on["target"] == 120.0
    assert cal.law.abrasion == pytest.approx(factor, rel=1e-15)
    for before, after in zip(steps[:-1], steps[1:]):
        rec = record(before.profile)
        depths = surface_depths(rec, depth_rates(rec, cal.law), after.hours - before.hours)
        mine = worn_profile(before.profile, depths, rec.bin_m)
        for f in ("height", "top_width", "top_centre", "trailing_angle_deg", "leading_angle_deg", "plate_wear"):
            assert getattr(mine, f) == pytest.approx(getattr(after.profile, f), rel=1e-9, abs=1e-12), f
    top = rescaled_rates[0]["top"]["mean_mm_per_1000h"]
    assert top == pytest.approx(factor * rates[0]["top"]["mean_mm_per_1000h"], rel=1e-15)


def test_a_life_calibration_out_of_reach_is_refused(monkeypatch):
    """A height the provisional constants do not reach within STOP_BOUND x HOURS: InputError naming
    the height (the fake mill wears 0.3 um per 1000 h at these constants); a relining limit reached
    before it: InputError naming the limit."""
    from millimpact.errors import InputError
    from millimpact.life import loop

    record, run_mill_on = _fake_mill(monkeypatch, loop)
    lp = _lifter()
    law = WearLaw(abrasion=1e-8, impact=0.0, hardness_Pa=3e9, density_kg_m3=7850.0)
    with pytest.raises(InputError, match="stay above 120 mm"):
        loop.run_life(lp, record(lp), law, 4000.0, 1, (1.0, 1.0), None, 0.0625, stop_height=0.120)
    # a relining limit met first (the plate's 75 mm at 74 mm) names the limit, not the height
    record, run_mill_on = _fake_mill(monkeypatch, loop, plate=0.25)
    law = WearLaw(abrasion=1.0, impact=0.0, hardness_Pa=3e9, density_kg_m3=7850.0)
    with pytest.raises(InputError, match=r"relining limit \(plate thickness\) before the lifters are 120 mm"):
        loop.run_life(lp, record(lp), law, 4000.0, 4, (1.0, 74.0), run_mill_on, 0.0625, stop_height=0.120)
