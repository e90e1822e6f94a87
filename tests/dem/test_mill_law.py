"""``millimpact mill --law DIR``: the mill's ball-liner contacts run the exported contact law.

The table: paper-rig as in test_export.py (2 speeds 1, 3 m/s x 2 angles 0, 40 deg; e_n 0.91-0.93;
its 15 mm ball), exported for Yade. The mill: the small mill of mill_scenes.py with the table's
15 mm balls. The reference is the table itself (millimpact's finite-element impacts), read from
the table's folder, not from the exported law.
"""
from __future__ import annotations

import csv
import dataclasses
import json
import math

import numpy as np
import pytest

from conftest import run_cli
from millimpact.dem.mill.run import run_mill
from millimpact.dem.mill.setup import MillOptions, plan_mill
from millimpact.dem.export.table_input import read_table

from mill_scenes import needs_yade, small_mill_scene

#: the small mill's liner on the command line (mill_scenes.small_mill_scene) with the table's 15 mm balls
SMALL_MILL = ["--set", "ball.radius=0.015",
              "--set", "liner.width=0.3", "--set", "liner.thickness=0.04", "--set", "liner.lifter_height=0.05",
              "--set", "liner.lifter_top_width=0.03", "--set", "liner.lifter_spacing=0.15",
              "--set", "liner.mill_radius=0.4"]


@pytest.fixture(scope="module")
def exported(tmp_path_factory, rig_contact_table):
    """(table folder, Yade export folder): the table is conftest's (test_export.py's too: its ~20 s
    of finite elements computed once)."""
    table = rig_contact_table
    law = tmp_path_factory.mktemp("millaw") / "law"
    r = run_cli("export", str(table), "--to", "yade", "--out", str(law), "-q")
    assert r.returncode == 0, r.stderr[-3000:]
    return table, law


def _law_scene():
    scene = small_mill_scene()
    return dataclasses.replace(scene, ball=dataclasses.replace(scene.ball, radius=0.015))


def _fake_export(folder, code, radius=0.015):
    """A folder shaped like an export (the checks read contact_law.json's code and the law's data)."""
    folder.mkdir()
    (folder / "contact_law.json").write_text(json.dumps({"code": code}))
    law = {"speeds_m_s": [1.0], "angles_deg": [0.0], "zeta": [[0.06]], "e_star_Pa": [[1e11]],
           "restitution_normal_table": [[0.92]], "friction": 0.2, "ball_radius_m": radius,
           "yade": {"young_Pa": 2e11, "poisson": 0.3, "ball_material": "millimpact_ball",
                    "liner_material": "millimpact_liner"}}
    runtime = "def millimpact_update():\n    pass\n"
    (folder / "contact_law_yade.py").write_text(f"MILLIMPACT_LAW = {json.dumps(law)}\n\n{runtime}")
    return folder


def test_bad_law_is_one_line_exit_2_and_no_folder(tmp_path):
    """Not an export (an empty folder), a LIGGGHTS export, a missing folder, a law whose table is for
    another ball, --law with --restitution or --friction: one line naming --law, exit 2, no folder."""
    (tmp_path / "table").mkdir()
    liggghts = _fake_export(tmp_path / "liggghts", "liggghts")
    yade = _fake_export(tmp_path / "yade", "yade")
    mill = SMALL_MILL[2:]                                 # all but the ball's radius
    r15 = ["--set", "ball.radius=0.015"]
    cases = [([str(tmp_path / "table"), *r15], "has no contact_law.json"),
             ([str(liggghts), *r15], "an export for 'liggghts'"),
             ([str(tmp_path / "nowhere"), *r15], "not a folder"),
             ([str(yade), "--set", "ball.radius=0.03"], "radius 0.015 m"),
             ([str(yade), *r15, "--restitution", "0.8"], "--law and --restitution"),
             ([str(yade), *r15, "--friction", "0.3"], "--law and --friction")]
    for (folder, *extra), words in cases:
        out = tmp_path / "mill"
        res = run_cli("mill", "liner-segment", *extra[:2], *mill, *extra[2:], "--law", folder, "--revolutions", "1",
                      "--balls", "5", "--out", str(out), timeout=120)
        assert res.returncode == 2, res.stderr
        lines = res.stderr.strip().splitlines()
        assert len(lines) == 1 and words in lines[0] and "--law" in lines[0], res.stderr
        assert not out.exists()


@pytest.mark.slow
@needs_yade
def test_mill_with_the_law_logs_impacts(tmp_path, exported):
    """The command with --law: 12 balls for 0.3 revolutions log impacts, the summary names the law."""
    _, yade = exported
    out = tmp_path / "mill"
    res = run_cli("mill", "liner-segment", *SMALL_MILL, "--law", str(yade), "--balls", "12", "--revolutions", "0.3",
                  "--warmup", "0", "--stiffness-scale", "0.001", "--no-plots", "--out", str(out), timeout=600)
    assert res.returncode == 0, res.stderr[-3000:]
    with open(out / "impacts.csv") as fh:
        rows = list(csv.DictReader(fh))
    assert len(rows) > 10
    summary = json.loads((out / "summary.json").read_text())
    assert str(yade.resolve()) in summary["contact"]["law"]
    assert summary["contact"]["friction"] == pytest.approx(0.2)
    assert (out / "yade" / "contact_law_yade.py").is_file()


def _drop_position(setup, segment, s, z, v_n):
    """A ball's start that falls vertically onto the plate chord ``segment`` and first touches it at
    the fraction ``s`` along it, ``z`` along the axis, at vertical speed v_n / cos(tilt)."""
    (x0, y0), (x1, y1) = segment.start, segment.end
    tx, ty = (x1 - x0) / segment.length, (y1 - y0) / segment.length
    nx, ny = -ty, tx                                  # the chord's normal towards the axis
    if nx * (x0 + x1) + ny * (y0 + y1) > 0:
        nx, ny = -nx, -ny
    r = setup.ball_radius
    cx, cy = x0 + s * (x1 - x0) + r * nx, y0 + s * (y1 - y0) + r * ny
    v = v_n / ny                                      # vertical fall: normal component v ny
    return (cx, cy + v * v / (2 * 9.81), z)


@pytest.mark.slow
@needs_yade
def test_a_dropped_ball_rebounds_at_the_tables_restitution(tmp_path, exported):
    """Two balls dropped onto plate chords at the bottom of the (almost still: 0.1 % of n_c) mill
    with the law, one at 0.8 m/s (below the table's 1 m/s: the law holds the 1 m/s point), one at
    3.3 m/s (above 3 m/s: the 3 m/s point), impact angles 7 and 14 deg: the rebound's normal speed
    over the impact's, read from Yade's trajectory, is the table's e_n at that speed (0 deg) within
    0.02 (the issue's round-trip tolerance; the law's e_n moves by 0.003 from 0 to 14 deg, gravity's
    pull within the trace's 3 steps ~ 5e-4 m/s); the contact's Hertz coefficient is the exported
    point's k_no = (4/3) E* K r^(1/2) (K = --stiffness-scale) within 1 % (angle interpolation:
    E* changes by 2 % from 0 to 40 deg), not the median law every contact starts with."""
    table_dir, yade = exported
    table = read_table(table_dir)
    K = 0.01
    scene = _law_scene()
    opts = MillOptions(revolutions=1.0, balls=2, speed_fraction=0.001, stiffness_scale=K, warmup=0.0,
                       thickness=3.0, law=str(yade))
    setup = plan_mill(scene, opts)
    plates = [g for g in setup.profile.segments if g.place == "plate"]

    def chord_near(x):
        return min((g for g in plates if g.start[1] < 0), key=lambda g: abs(0.5 * (g.start[0] + g.end[0]) - x))

    # contact points 0.7 along the chord, 1 mm from the end wall: > 8 mm in the plane from the facet
    # pair's diagonal and > 6 mm from the chord's ends (the contact's reach is ~ sqrt(2 r delta) < 5 mm)
    z = setup.ball_radius + 1e-3
    chords = [chord_near(-0.047), chord_near(0.10)]
    speeds = [0.8, 3.3]
    starts = [_drop_position(setup, g, 0.7, z, v) for g, v in zip(chords, speeds)]
    run_s = math.sqrt(2 * (starts[1][1] - (chords[1].start[1] + setup.ball_radius)) / 9.81) + 0.03
    setup = dataclasses.replace(setup, positions=tuple(starts), run_s=run_s, revolutions=run_s / setup.period_s,
                                trace_balls=(0, 1), trace_every=setup.check_every)
    stage = tmp_path / "drop"
    stage.mkdir()
    run_mill(scene, opts, stage, plots=False, setup=setup, timeout=600)
    with open(stage / "yade" / "impacts_raw.csv") as fh:
        impacts = list(csv.DictReader(fh))
    with open(stage / "yade" / "trace.csv") as fh:
        trace = list(csv.DictReader(fh))
    law = json.loads((yade / "contact_law.json").read_text())
    for ball, (v_drop, i_speed) in enumerate(zip(speeds, (0, len(table.speeds) - 1))):
        first = next(row for row in impacts if int(row["particle"]) == ball)
        n = np.array([float(first[k]) for k in ("nx", "ny")])
        v_in = np.array([float(first[k]) for k in ("vx", "vy")])
        rows = [row for row in trace if int(row["particle"]) == ball]
        contacts = np.array([int(row["liner_contacts"]) for row in rows])
        k0 = int(np.argmax(contacts > 0))
        k1 = k0 + int(np.argmax(contacts[k0:] == 0))
        assert k1 > k0 and contacts[k0:k1].max() == 1          # one facet: not a pair's diagonal or an edge
        v_out = np.array([float(rows[k1][k]) for k in ("vx_m_s", "vy_m_s")])
        v_n_in = -float(v_in @ n)
        assert v_n_in == pytest.approx(v_drop, rel=0.01)
        e_mill = float(v_out @ n) / v_n_in
        e_table = float(table.e_n[i_speed, 0])
        assert e_mill == pytest.approx(e_table, abs=0.02), (ball, e_mill, e_table)
        point = next(p for p in law["points"] if p["impact_speed_m_s"] == table.speeds[i_speed]
                     and p["impact_angle_deg"] == 0.0)
        k_no = 4.0 / 3.0 * point["contact_modulus_E_star_Pa"] * K * math.sqrt(setup.ball_radius)
        assert float(first["kno"]) == pytest.approx(k_no, rel=0.01)
