"""A mill slice in Yade checked against physics that needs no DEM: Yade's restitution, centrifuging
above the critical speed, a ball's free flight from a lifter, the charge's energy balance.

The small mill of mill_scenes.py (0.8 m across, 17 lifters, 60 mm balls) with Young's moduli x 0.001
(--stiffness-scale): none of these checks depends on the contact stiffness, and it keeps each run
to a few seconds of CPU."""
from __future__ import annotations

import csv
import dataclasses
import math

import numpy as np
import pytest

from millimpact.dem.impacts import read_impacts
from millimpact.dem.mill.run import run_mill
from millimpact.dem.mill.setup import MillOptions, plan_mill
from millimpact.dem.yade import run_yade

from mill_scenes import needs_yade, small_mill_scene

pytestmark = needs_yade

SOFT = 0.001

RESTITUTION_SCRIPT = """
import sys
from yade import utils
en, damping = float(sys.argv[1]), float(sys.argv[2])
O.materials.append(FrictMat(young=200e9, poisson=0.3, density=7800, frictionAngle=0))
R = 0.015
O.bodies.append(utils.facet([(-1, -1, 0), (1, -1, 0), (0, 1, 0)], fixed=True))
b = O.bodies.append(utils.sphere((0, 0, R * 1.001), R))
O.bodies[b].state.vel = (0, 0, -3.0)
O.engines = [ForceResetter(), InsertionSortCollider([Bo1_Sphere_Aabb(), Bo1_Facet_Aabb()]),
             InteractionLoop([Ig2_Facet_Sphere_ScGeom()],
                             [Ip2_FrictMat_FrictMat_MindlinPhys(en=MatchMaker(algo='val', val=en))],
                             [Law2_ScGeom_MindlinPhys_Mindlin()]),
             NewtonIntegrator(gravity=(0, 0, 0), damping=damping)]
O.dt = 1e-8
for i in range(100000):
    O.step()
    if O.bodies[b].state.vel[2] > 0 and O.interactions.countReal() == 0:
        break
print("RESULT", O.bodies[b].state.vel[2] / 3.0)
"""


def _yade_rebound(tmp_path, en, damping):
    script = tmp_path / "rebound.py"
    script.write_text(RESTITUTION_SCRIPT)
    out = run_yade(script, tmp_path, [en, damping], timeout=300)
    return float([l for l in out.splitlines() if l.startswith("RESULT")][0].split()[1])


def test_yade_rebounds_at_en_with_its_numerical_damping_off(tmp_path):
    """The mill script passes the wanted e to Yade as en with NewtonIntegrator(damping=0): Yade
    itself (a 15 mm steel ball at 3 m/s on a facet) gives e = en to 0.005 at 0.5 and 0.8; with
    Yade's default damping 0.2 it loses 0.1 more (the e = 0.65 at en = 0.8 of yade_drop.py)."""
    for en in (0.5, 0.8):
        assert _yade_rebound(tmp_path, en, 0.0) == pytest.approx(en, abs=0.005)
    assert _yade_rebound(tmp_path, 0.8, 0.2) < 0.7


def _run(tmp_path, name, opts, **setup_changes):
    scene = small_mill_scene()
    setup = dataclasses.replace(plan_mill(scene, opts), **setup_changes)
    stage = tmp_path / name
    stage.mkdir()
    return setup, run_mill(scene, opts, stage, plots=False, setup=setup, timeout=900), stage


def _fast_face_impacts(stage, setup):
    """Lifter-face impacts per revolution faster (normal speed) than a centrifuged ball can reach:
    pinned to the shell, it can only roll across its pocket between two lifters, gaining at most
    sqrt(2 g s) over the pocket's free length s (gravity's pull along the shell <= g)."""
    p = setup.profile
    pitch = 2 * math.pi * (p.radius - setup.ball_radius) / p.n_lifters
    top = [s for s in p.segments if s.place == "lifter_top"][0]
    s_free = pitch - top.length - 2 * setup.ball_radius
    v_bound = math.sqrt(2 * 9.81 * s_free)
    with open(stage / "impacts.csv") as fh:
        rows = [r for r in csv.DictReader(fh) if r["place"] == "lifter_face"]
    return sum(float(r["normal_speed_m_s"]) > v_bound for r in rows) / setup.revolutions, v_bound


def test_balls_centrifuge_above_the_critical_speed(tmp_path):
    """At 110 % of n_c every ball stays at the shell turning with it (over the last revolution, after
    3 revolutions' warm-up) and no lifter face is struck harder than a ball rolling across its pocket
    can strike it; at 75 % none centrifuges and the faces are struck harder many times a revolution."""
    fast, slow = {}, {}
    for S, warm, box in ((1.1, 3.0, fast), (0.75, 1.0, slow)):
        opts = MillOptions(revolutions=1.0, balls=12, speed_fraction=S, stiffness_scale=SOFT, warmup=warm)
        setup, summary, stage = _run(tmp_path, f"s{S}", opts)
        box["summary"] = summary
        box["fast_faces"], v_bound = _fast_face_impacts(stage, setup)
    assert fast["summary"]["centrifuged_fraction"] >= 0.9
    assert fast["summary"]["shoulder_deg"] is None
    assert slow["summary"]["centrifuged_fraction"] <= 0.1
    # "almost no lifter-face impacts": at most 1 a revolution above the rolling bound, against >= 5 at 75 %
    assert fast["fast_faces"] <= 1.0, (fast["fast_faces"], v_bound)
    assert slow["fast_faces"] >= 5.0, (slow["fast_faces"], v_bound)


def _landing_on_profile(setup, t0, p0, v0, t_stop):
    """First time after t0 the parabola p0 + v0 (t - t0) - g (t - t0)^2 / 2 e_y brings the ball's
    centre within a ball radius of the liner's profile turned by omega t; returns (t, x, y) and the
    nearest point of the profile then (x, y, in the mill's fixed frame)."""
    segs = setup.profile.segments
    a = np.array([s.start for s in segs])
    b = np.array([s.end for s in segs])
    t = np.arange(t0, t_stop, 2e-5)
    x = p0[0] + v0[0] * (t - t0)
    y = p0[1] + v0[1] * (t - t0) - 0.5 * 9.81 * (t - t0) ** 2
    th = -setup.omega * t                                  # the centre in the liner's frame
    xl = np.cos(th) * x - np.sin(th) * y
    yl = np.sin(th) * x + np.cos(th) * y
    q = np.stack([xl, yl], axis=1)[:, None, :]
    ab = (b - a)[None, :, :]
    u = np.clip(np.einsum("tsk,tsk->ts", q - a[None], ab) / np.einsum("tsk,tsk->ts", ab, ab), 0.0, 1.0)
    near = a[None] + u[..., None] * ab
    d_all = np.linalg.norm(q - near, axis=2)
    dist = d_all.min(axis=1)
    k = int(np.argmax(dist <= setup.ball_radius))
    assert dist[k] <= setup.ball_radius, "the parabola never meets the liner"
    nx, ny = near[k, int(np.argmin(d_all[k]))]
    c, s = math.cos(-th[k]), math.sin(-th[k])
    return t[k], x[k], y[k], (c * nx - s * ny, s * nx + c * ny)


def test_a_ball_thrown_from_a_lifter_lands_where_the_parabola_meets_the_liner(tmp_path):
    """One ball at 85 % of n_c: its longest flight starts at a lifter's tip; Yade's landing point is
    within a ball radius of where the free-flight parabola from the release state meets the turning
    liner (the analytic landing, computed from the liner's profile alone)."""
    opts = MillOptions(revolutions=1.0, balls=1, speed_fraction=0.85, stiffness_scale=SOFT, warmup=0.0)
    setup = dataclasses.replace(plan_mill(small_mill_scene(), opts), trace_balls=(0,))
    setup = dataclasses.replace(setup, trace_every=setup.check_every)
    _, _, stage = _run(tmp_path, "flight", opts, trace_balls=setup.trace_balls, trace_every=setup.trace_every)
    with open(stage / "yade" / "trace.csv") as fh:
        rows = list(csv.DictReader(fh))
    c = np.array([int(r["liner_contacts"]) for r in rows])
    free = np.flatnonzero(c == 0)
    # the longest run of samples without a liner contact
    runs = np.split(free, np.flatnonzero(np.diff(free) > 1) + 1)
    flight = max(runs, key=len)
    k0, k1 = flight[0], flight[-1] + 1
    assert k1 < len(rows), "the flight did not end within the run"
    r0, r1 = rows[k0], rows[k1]
    t0, t1 = float(r0["time_s"]), float(r1["time_s"])
    p0 = (float(r0["x_m"]), float(r0["y_m"]))
    v0 = (float(r0["vx_m_s"]), float(r0["vy_m_s"]))
    p1 = (float(r1["x_m"]), float(r1["y_m"]))
    r = setup.ball_radius
    assert math.dist(p0, p1) > 5 * r                       # a flight, not a bounce
    # released at a lifter's tip: the centre within 1.5 r of a top corner (in the liner's frame)
    th = -setup.omega * t0
    xl, yl = math.cos(th) * p0[0] - math.sin(th) * p0[1], math.sin(th) * p0[0] + math.cos(th) * p0[1]
    corners = [pt for s in setup.profile.segments if s.place == "lifter_top" for pt in (s.start, s.end)]
    assert min(math.dist((xl, yl), q) for q in corners) < 1.5 * r
    t_an, x_an, y_an, touch = _landing_on_profile(setup, t0, p0, v0, t1 + 0.05)
    assert abs(t_an - t1) < 0.01
    assert math.dist((x_an, y_an), p1) < r
    # the log's normal speed of that landing: the parabola's velocity relative to the liner's
    # surface there, along the normal: within 3 % (the log takes the normal when the contact is found,
    # a check later; at an edge it turns as the ball rolls over it: 1.3 % here)
    v = (v0[0], v0[1] - 9.81 * (t_an - t0))
    v_rel = (v[0] + setup.omega * touch[1], v[1] - setup.omega * touch[0])
    n = (x_an - touch[0], y_an - touch[1])
    v_n = -(v_rel[0] * n[0] + v_rel[1] * n[1]) / math.hypot(*n)
    with open(stage / "impacts.csv") as fh:
        logged = [row for row in csv.DictReader(fh) if abs(float(row["time_s"]) - t1) < 3 * setup.check_every * setup.dt]
    assert len(logged) == 1
    assert float(logged[0]["normal_speed_m_s"]) == pytest.approx(v_n, rel=0.03)


def test_energy_balance_of_the_charge(tmp_path):
    """The drive's work (the charge's torque on the liner x omega, summed every step) equals the
    energy dissipated in the contacts plus the change of the balls' kinetic + potential energy (and of
    the contacts' stored energy), within 5 % (the issue's tolerance), over a warm-up and a revolution
    of 30 balls at 75 % of n_c."""
    opts = MillOptions(revolutions=1.0, balls=30, speed_fraction=0.75, stiffness_scale=SOFT, warmup=0.5)
    _, summary, stage = _run(tmp_path, "energy", opts, power_every=1)
    b = summary["energy_balance"]
    assert b["drive_work_J"] > 0 and b["dissipated_J"] > 0.5 * b["drive_work_J"]
    assert abs(b["relative_error"]) < 0.05, b
    # the log is one the damage map's checked reader takes, and the per-revolution counts are its rows
    impacts = read_impacts(stage / "impacts.csv")
    assert len(impacts) == pytest.approx(summary["impacts_per_revolution"]["all"] * opts.revolutions)
