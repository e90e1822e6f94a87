"""A SAG charge (balls and rock) in the mill slice, and the sliding work at the liner.

Exact references: a ball launched sliding (no spin) on a still plate slides until v = 5/7 v0 and
then rolls (rigid-body mechanics: friction is the only tangential force, so the angular momentum
about the contact point is kept), so friction turns m v0^2 / 7 into heat over a slip path of
v0^2 / (7 mu g); the energy balance of a whole run (the drive's work against the change of the
particles' energy and the dissipation by kind). The small mill of mill_scenes.py with Young's moduli
x 0.001 keeps each run to seconds of CPU."""

from __future__ import annotations

import csv
import json
import math

import numpy as np
import pytest

from millimpact.dem.impacts import read_impacts
from millimpact.dem.mill.run import SCRIPT, run_mill
from millimpact.dem.mill.power import model_inputs
from millimpact.dem.mill.setup import MillOptions, plan_mill
from millimpact.dem.yade import run_yade

from conftest import run_cli
from mill_scenes import needs_yade, small_mill_scene

SOFT = 0.001


def _sliding_input(v0: float, mu: float, r: float = 0.03) -> dict:
    """One ball (steel, E 2 GPa) resting on a flat plate segment (y = 0, 4 m long), launched along x
    at v0 without spin, gravity -y; the liner still (omega 0)."""
    rho = 7800.0
    m = 4.0 / 3.0 * math.pi * r**3 * rho
    e_star = 1.0 / (2.0 * (1.0 - 0.3**2) / 2e9)
    k_no = 4.0 / 3.0 * e_star * math.sqrt(2.0 * r / 3.0)  # Yade's facet: R* = 2 r / 3
    delta = (m * 9.81 / k_no) ** (2.0 / 3.0)  # the ball's static overlap
    dt = 2e-5
    return {
        "thickness_m": 4 * r,
        "gravity_m_s2": 9.81,
        "omega_rad_s": 0.0,
        "ball": {"radius_m": r, "young_Pa": 2e9, "poisson": 0.3, "density_kg_m3": rho},
        "liner": {"young_Pa": 2e9, "poisson": 0.3, "density_kg_m3": rho},
        "friction": mu,
        "en_yade": 0.5,
        "segments": [[-0.5, 0.0, 3.5, 0.0, 0]],
        "ball_positions": [[0.0, r - delta, 2 * r]],
        "ball_velocities": [[v0, 0.0, 0.0]],
        "rock": None,
        "v_max_m_s": 2 * v0,
        "arc": {"lifter_height_m": 0.0, "radius_m": 1.0, "bin_m": 0.01, "segment_s0_m": [0.0]},
        "dt_s": dt,
        "check_every": 3,
        "power_every": 3,
        "warmup_s": 0.0,
        "run_s": 3.0 * v0 / (7.0 * mu * 9.81) * 2 + 0.05,
        "snapshot_every_s": 0.05,
        "energy_samples": 5,
        "trace_balls": [],
        "trace_every": 0,
        "law": None,
    }


@needs_yade
def test_a_sliding_ball_does_friction_work_m_v0_squared_over_7(tmp_path):
    """abrasion_raw.csv's friction work of a ball launched at 1.5 m/s without spin on a still plate
    (mu 0.3): m v0^2 / 7 within 2 % (the sum is sampled every 3 steps with
    the normal force at the sample; the contact's bounce-free start keeps F_n = m g), and its slip
    path v0^2 / (7 mu g) within 2 %, so the friction work is mu m g times the path."""
    v0, mu, r = 1.5, 0.3, 0.03
    cfg = _sliding_input(v0, mu, r)
    (tmp_path / "input.json").write_text(json.dumps(cfg))
    run_yade(SCRIPT, tmp_path, ["input.json"], timeout=600)
    with open(tmp_path / "abrasion_raw.csv") as fh:
        rows = list(csv.DictReader(fh))
    work = sum(float(row["friction_work_J"]) for row in rows)
    slip = sum(float(row["slip_m"]) for row in rows)
    m = 4.0 / 3.0 * math.pi * r**3 * 7800.0
    assert work == pytest.approx(m * v0**2 / 7.0, rel=0.02)
    assert slip == pytest.approx(v0**2 / (7.0 * mu * 9.81), rel=0.02)
    # the same work seen by the whole run (energy.csv): the liner's share is all of Yade's friction
    with open(tmp_path / "energy.csv") as fh:
        last = list(csv.DictReader(fh))[-1]
    assert float(last["liner_friction_J"]) == pytest.approx(float(last["friction_J"]), rel=0.02)


def _sag_opts(**kw) -> MillOptions:
    base = dict(
        revolutions=0.5,
        charge="sag",
        fill=0.3,
        ball_fill=0.12,
        rock_top_size=0.06,
        rock_cutoff=0.03,
        stiffness_scale=SOFT,
        warmup=0.5,
    )
    return MillOptions(**{**base, **kw})


def test_a_sag_charge_fills_what_the_options_say():
    """Balls and rock at the fills asked (J 0.30, J_B 0.12 within 2 %: whole particles), rock sizes
    between the cut-off and the top size, no two particles overlapping at the start."""
    setup = plan_mill(small_mill_scene(), _sag_opts())
    m = model_inputs(setup)
    assert m["fill"] == pytest.approx(0.30, rel=0.02)
    assert m["ball_fill"] == pytest.approx(0.12, rel=0.05)  # 35 balls: one ball is 3 % of them
    d = 2 * np.array(setup.rock_radii)
    assert d.min() >= 0.03 and d.max() <= 0.06 and setup.n_rocks > 3 * setup.n_balls
    p = np.array(setup.positions)
    radii = np.array([setup.particle_radius(k) for k in range(setup.n_particles)])
    gap = np.linalg.norm(p[:, None] - p[None], axis=2) - (radii[:, None] + radii[None])
    np.fill_diagonal(gap, 1.0)
    assert gap.min() > 0


@needs_yade
def test_a_sag_run_balances_its_energy_and_logs_rock_and_abrasion(tmp_path):
    """The drive's work equals the particles' energy change plus the dissipation by kind (impact
    damping, friction at the liner, friction in the bed, the rock's rolling resistance) within 5 %
    (the mill's energy test's bound); impacts.csv holds the rock's impacts with kind and mass, which
    the damage map's reader takes; abrasion.csv holds both kinds."""
    scene = small_mill_scene()
    opts = _sag_opts()
    setup = plan_mill(scene, opts)
    stage = tmp_path / "sag"
    stage.mkdir()
    summary = run_mill(scene, opts, stage, plots=False, setup=setup, timeout=900)
    b = summary["energy_balance"]
    kinds = b["dissipated_by_kind_J"]
    assert min(kinds.values()) > 0
    assert sum(kinds.values()) == pytest.approx(b["dissipated_J"], rel=1e-9)
    assert abs(b["relative_error"]) < 0.05, b
    impacts = read_impacts(stage / "impacts.csv")
    kind = impacts.column("kind")
    assert set(kind) == {"ball", "rock"}
    mass = impacts.column("mass_kg")
    assert np.allclose(mass[kind == "ball"], setup.ball_mass)
    assert (mass[kind == "rock"] < setup.ball_mass).all()
    with open(stage / "abrasion.csv") as fh:
        rows = list(csv.DictReader(fh))
    assert {r["kind"] for r in rows} == {"ball", "rock"}
    total = sum(float(r["friction_work_J_per_revolution"]) for r in rows) * opts.revolutions
    assert 0 < total < kinds["friction_at_liner"]  # the log's window is part of the whole run
    share = summary["charge"]["ball_contacts_on_rock_share"]
    assert 0.3 < share < 1.0  # most of the charge is rock: most of a ball's contacts are with rock


@pytest.mark.parametrize(
    "args, words",
    [
        (["--charge", "sag", "--ball-fill", "0.3"], "--ball-fill 0.3: must lie in (0, --fill = 0.28]"),
        (["--charge", "sag", "--fill", "0.6"], "--fill 0.6: must lie in [0.05, 0.5]"),
        (["--charge", "sag", "--rock-cutoff", "0.2"], "--rock-cutoff 0.2 m: must lie in (0, --rock-top-size = 0.2 m)"),
        (["--charge", "sag", "--rock-top-size", "3"], "--rock-top-size 3 m: must be below half the mill's radius"),
        (["--charge", "sag", "--rock-top-size", "0.3"], "--rock-top-size 0.3 m: must be at most the slice's thickness"),
        (["--charge", "sag", "--rolling-resistance", "1.5"], "--rolling-resistance 1.5: must lie in [0, 1]"),
        (["--charge", "sag", "--slurry-density", "500"], "--slurry-density 500 kg/m^3: must be 0 (a dry charge) or"),
        (["--slurry-density", "1800"], "--slurry-density: a rock option; give --charge sag"),
        (["--rock-cutoff", "0.05"], "--rock-cutoff: a rock option; give --charge sag"),
        (["--charge", "sag", "--balls", "10"], "--balls: with --charge sag give --fill and --ball-fill"),
        (["--charge", "gravel"], "--charge"),
    ],
)
def test_bad_sag_input_is_one_line_and_exit_2_and_no_folder(tmp_path, args, words):
    out = tmp_path / "mill"
    res = run_cli("mill", "liner-panel", *args, "--revolutions", "1", "--out", str(out), timeout=120)
    assert res.returncode == 2, res.stderr
    lines = res.stderr.strip().splitlines()
    assert lines and words in lines[-1], res.stderr
    assert "Traceback" not in res.stderr
    assert not out.exists() and not list(tmp_path.iterdir())


@needs_yade
def test_a_rolling_rock_stops_where_its_rolling_resistance_says(tmp_path):
    """A rock (the SAG charge's contact: rolling resistance mu_r, M <= mu_r R F_n) rolling without
    slip on a still plate at v0: once the moment has reached its limit it decelerates at
    a = M R / (I + m R^2) = (5/7) mu_r g (rigid-body mechanics about the contact point), so it stops
    after 7 v0^2 / (10 mu_r g); within 5 % (the spring's elastic start, ~k_r-limited, and the contact's
    overlap, 0.1 % of R, shorten it a little). Without rolling resistance it rolls on."""
    v0, r, mu_r = 0.5, 0.03, 0.2
    stops, rolled = {}, {}
    for eta in (mu_r, 0.0):
        cfg = _sliding_input(v0, 0.6, r)
        m = 4.0 / 3.0 * math.pi * r**3 * 2700.0
        e_star = 1.0 / (2.0 * (1.0 - 0.29**2) / 6.2e8)
        delta = (m * 9.81 / (4.0 / 3.0 * e_star * math.sqrt(2.0 * r / 3.0))) ** (2.0 / 3.0)
        cfg["ball_positions"], cfg["ball_velocities"] = [], []
        cfg["rock"] = {
            "positions": [[0.0, r - delta, 2 * r]],
            "radii": [r],
            "young_Pa": 6.2e8,
            "poisson": 0.29,
            "density_kg_m3": 2700.0,
            "en_yade": 0.3,
            "friction": 0.6,
            "eta": eta,
            "krot": 2.25 * mu_r**2 * r**2 * 1e6,
            "velocities": [[v0, 0.0, 0.0]],
            "angular_velocities": [[0.0, 0.0, -v0 / r]],
        }
        cfg["run_s"] = 2.0 * 7 * v0 / (5 * mu_r * 9.81)
        cfg["trace_balls"], cfg["trace_every"] = [0], 50
        work = tmp_path / f"eta{eta}"
        work.mkdir()
        (work / "input.json").write_text(json.dumps(cfg))
        run_yade(SCRIPT, work, ["input.json"], timeout=600)
        with open(work / "trace.csv") as fh:
            x = [float(row["x_m"]) for row in csv.DictReader(fh)]
        stops[eta] = x[-1] - x[0]
        with open(work / "energy.csv") as fh:
            rows = list(csv.DictReader(fh))
        rolled[eta] = float(rows[-1]["rolling_J"]) - float(rows[0]["rolling_J"])
    assert stops[mu_r] == pytest.approx(7 * v0**2 / (10 * mu_r * 9.81), rel=0.05)
    # the rolling moments' work is the rock's whole kinetic energy, (1/2) m v0^2 (1 + 2/5), less the
    # moment's stored energy M^2 / (2 k_r) at rest (1e-4 of it): 1 % bounds the sampled sum
    assert rolled[mu_r] == pytest.approx(0.7 * m * v0**2, rel=0.01)
    assert rolled[0.0] == 0.0
    assert stops[0.0] > 2 * stops[mu_r]


@needs_yade
def test_the_pair_pass_every_second_check_misses_no_contact(tmp_path):
    """The pass over the contacts between particles runs every PAIR_EVERY_CHECKS checks (2: 6
    steps, inside the shortest contact's STEPS_PER_CONTACT = 25). Without rolling resistance the
    pass only reads the charge, so a run passing every check is the exact reference: the same
    impacts and energies to the digit, and every new contact between particles counted (each
    still exists at the next pass). (The counts at >= 1 m/s are too few in this small, slow mill
    to compare: 13 and 11 rock-rock contacts.)"""
    from millimpact.dem.mill.setup import PAIR_EVERY_CHECKS

    assert PAIR_EVERY_CHECKS * 3 < 25
    setup = plan_mill(small_mill_scene(), _sag_opts(rolling_resistance=0.0, revolutions=0.2, warmup=0.2))
    runs = {}
    for every in (1, PAIR_EVERY_CHECKS):
        work = tmp_path / f"pairs-{every}"
        work.mkdir()
        cfg = dict(setup.yade_input(), pair_every=every)
        (work / "input.json").write_text(json.dumps(cfg))
        run_yade(SCRIPT, work, ["input.json"], timeout=600)
        runs[every] = work
    one, two = runs[1], runs[PAIR_EVERY_CHECKS]
    for name in ("impacts_raw.csv", "energy.csv"):
        assert (one / name).read_text() == (two / name).read_text(), name
    c1 = json.loads((one / "run.json").read_text())["particle_contacts_after_warmup"]
    c2 = json.loads((two / "run.json").read_text())["particle_contacts_after_warmup"]
    assert c1.keys() == c2.keys() and len(c1) == 3
    for pair in c1:
        assert c2[pair]["all"] == c1[pair]["all"] > 100, pair
