"""The liner-segment scene: validation, meshing, an oblique impact on a lifter face (serial and
``mpirun -n 2``), against Hertz (normal part) and the Maw-Barber-Fawcett friction regimes.

Coarse mesh for the tests: h_contact = 4 mm (a_max = 6.75 mm: ~1.7 elements across the contact
radius, so F_max is only good to ~10 %), h_far = 40 mm; ~2.6k dofs, half model (the plane of
incidence x = 0 is a symmetry plane).
"""
from __future__ import annotations

import json

import numpy as np
import pytest

from conftest import run_cli
from millimpact.errors import SceneError
from millimpact.scene.plan import make_plan
from millimpact.results.timeseries import TimeSeries
from millimpact.scene.builtin import builtin_scene

#: elastic (the paper's steel): the scene is plastic by default, these tests check the elastic
#: contact and friction laws against Hertz and Maw-Barber-Fawcett
COARSE = {"model.h_far": 0.04, "model.h_contact": 0.004, "time.end": 3.2e-4,
          "ball.material": "paper-steel", "liner.material": "paper-steel"}
SETS = [a for k, v in COARSE.items() for a in ("--set", f"{k}={v}")]


def _scene(**extra):
    s = builtin_scene("liner-segment")
    for k, v in {**COARSE, **extra}.items():
        s = s.with_value(k, v)
    return s


def test_scene_geometry_and_plan():
    s = builtin_scene("liner-segment")
    n = np.array(s.contact_normal)
    # the face of a 20 deg lifter: its normal is tilted 20 deg from +z towards +y (the mill's inside)
    assert n == pytest.approx([0.0, np.sin(np.radians(20)), np.cos(np.radians(20))])
    v = np.array(s.impact.velocity)
    # 8 m/s at 30 deg from the face's inward normal
    assert np.linalg.norm(v) == pytest.approx(8.0)
    assert -v @ n == pytest.approx(8.0 * np.cos(np.radians(30))) == s.normal_speed
    c = np.array(s.ball_centre(0.0))
    assert np.linalg.norm(c - np.array(s.impact_point)) == pytest.approx(s.ball.radius)
    plan = make_plan(s)
    assert plan.symmetry == "half" and plan.symmetry_planes == ("x",)
    # Hertz (normal component): a_max ~ 6.75 mm for a 125 mm ball of the paper's steel at 6.93 m/s
    paper = s.with_value("ball.material", "paper-steel").with_value("liner.material", "paper-steel")
    assert make_plan(paper).hertz.a_max == pytest.approx(6.75e-3, rel=0.01)
    # the default is plastic: a Cr-Mo liner under a forged ball, whose plastic region sizes the zone
    assert s.liner.material.plastic and s.ball.material.plastic
    assert plan.plastic_radius > plan.hertz.a_max and plan.zone_radius >= 1.75 * plan.plastic_radius


@pytest.mark.parametrize("field, value, words", [
    ("liner.impact_height", 1.2, "(0, 1)"),
    ("liner.impact_height", 0.05, "touch the plate"),
    ("liner.impact_face", "top", "'+z' or '-z'"),
    ("liner.lifter_face_angle", 95.0, "90"),
    ("liner.impact_lifter", 1, "0 .. 0"),
    ("liner.thickness", -0.01, "> 0"),
    ("impact.velocity", [0.0, -1.0, 5.0], "into the struck lifter face"),
    ("contact.friction", -0.1, "[0, 2]"),
])
def test_bad_liner_input_names_the_field(field, value, words):
    with pytest.raises(SceneError) as e:
        builtin_scene("liner-segment").with_value(field, value)
    assert field in str(e.value) and words in str(e.value)


def test_cli_refuses_bad_liner_value():
    r = run_cli("run", "liner-segment", "--set", "liner.impact_height=0", "-q", "--out", "/tmp/never-written")
    assert r.returncode == 2 and "liner.impact_height" in r.stderr and "Traceback" not in r.stderr


@pytest.fixture(scope="module")
def liner_runs(tmp_path_factory):
    base = tmp_path_factory.mktemp("liner")
    args = ["run", "liner-segment", "--method", "full", *SETS, "-q"]
    r1 = run_cli(*args, "--out", str(base / "np1"))
    assert r1.returncode == 0, r1.stderr[-2000:]
    r2 = run_cli(*args, "--out", str(base / "np2"), np=2)
    assert r2.returncode == 0, r2.stderr[-2000:]
    return [(json.loads((base / d / "summary.json").read_text()), TimeSeries.read_csv(base / d / "timeseries.csv"),
             base / d) for d in ("np1", "np2")]


def test_liner_impact_against_hertz_and_energy(liner_runs):
    s, ts, folder = liner_runs[0]
    h = s["hertz"]
    # coarse mesh (1.7 elements across a_max, foundations.md section 3: ~4 give 1 %): 10 % on F_max and t_c
    assert s["peak_contact_force_N"] == pytest.approx(h["F_max_N"], rel=0.10)
    assert s["contact_duration_s"] == pytest.approx(h["t_c_s"], rel=0.10)
    # energy: total + friction dissipation is conserved by Newmark with mass redistribution
    # (Khenous et al. 2008; 0.5 %: the O(dt) impact/release error measured on the rig is ~0.02 %)
    e = ts["total_energy_J"] + ts["friction_dissipation_J"]
    assert np.max(np.abs(e - e[0])) < 5e-3 * e[0]
    assert ts["friction_dissipation_J"][-1] > 0
    # the liner's contact point is pushed in along the face normal
    assert ts["contact_point_displacement_m"].max() > 0
    assert s["model"]["symmetry"] == "half"
    assert (folder / "friction.png").stat().st_size > 0 and (folder / "contact_force.png").stat().st_size > 0


@pytest.mark.mpi
def test_liner_mpi_equals_serial(liner_runs):
    (s1, a, _), (s2, b, _) = liner_runs
    assert s2["model"]["mpi_ranks"] == 2
    assert len(a.time) == len(b.time)
    # same numbers to solver tolerance (direct factorizations: round-off only), 1e-6 relative
    for col, ref in (("contact_force_N", a["contact_force_N"].max()), ("tangential_force_N", a["contact_force_N"].max()),
                     ("total_energy_J", a["total_energy_J"][0]),
                     ("ball_tangential_velocity_m_s", np.abs(a["ball_tangential_velocity_m_s"]).max())):
        assert np.max(np.abs(a[col] - b[col])) < 1e-6 * ref, col


def _impulses(mu: float):
    from millimpact.methods.run import compute

    out, _ = compute(_scene(**{"contact.friction": mu, "outputs.xdmf": False}), "full", {}, False)
    ts = out.series
    t, fn, ft = ts.time, ts["contact_force_N"], ts["tangential_force_N"]
    return np.trapz(fn, t), np.trapz(ft, t), ts, out


def test_maw_barber_fawcett_gross_sliding():
    # tan(alpha) = v_t / v_n = 0.577; rigid-body sliding throughout needs tan(alpha) > 7/2 mu (1 + e)
    # ~ 7 mu: mu = 0.03 gives 0.21, well inside MBF's gross-sliding regime. There the tangential
    # force is -mu times the normal force at every instant, so J_t = -mu J_n, and the ball's
    # tangential velocity drops by mu J_n / m.
    mu = 0.03
    jn, jt, ts, out = _impulses(mu)
    assert jt / jn == pytest.approx(-mu, rel=1e-3)    # slip directions in the plane of incidence
    on = ts["contact_force_N"] > 0.02 * ts["contact_force_N"].max()
    assert np.allclose(ts["tangential_force_N"][on] / ts["contact_force_N"][on], -mu, rtol=1e-3)
    m = _scene().ball.mass
    dv = ts["ball_tangential_velocity_m_s"][-1] - ts["ball_tangential_velocity_m_s"][0]
    assert dv == pytest.approx(jt / m, rel=1e-3)        # momentum of the free ball


def test_maw_barber_fawcett_sticking():
    # small tan(alpha) / mu (0.577 / 0.5 << 7): MBF's regime where the contact sticks over most of
    # the impact and the tangential force reverses (the elastic tangential spring gives back its
    # energy): |J_t| well below mu J_n, and both signs of the tangential force occur
    mu = 0.5
    jn, jt, ts, out = _impulses(mu)
    ft = ts["tangential_force_N"]
    assert abs(jt) < 0.5 * mu * jn
    assert ft.min() < -0.05 * mu * ts["contact_force_N"].max() and ft.max() > 0.05 * mu * ts["contact_force_N"].max()
