"""``millimpact damage --bins-from adaptive``: a placed scene's bins read from the adaptive table
engine's grid of cases where it needs fewer cases than the bins (millimpact.damage.adaptive_bins).

References: a case runner whose every response is bilinear in the law's own coordinates (ln v_n,
angle), which bilinear interpolation must reproduce exactly (round-off), so any slip in the
coordinates, the weights or the rows' scalings shows; the per-bin cases themselves (the map with
``--bins-from cases``) on the real table engine; and, where the engine does not save cases, the
per-bin rows to the last bit.
"""
from __future__ import annotations

import json
import math

import numpy as np
import pytest

from conftest import run_cli
from millimpact.commandkit.store import PieceStore
from millimpact.damage.adaptive_bins import START
from millimpact.damage.damage_map import MapSettings, run_damage_map
from millimpact.errors import InputError
from test_damage_map import COARSE, GOOD, HEADER, MASS, SCENE, V_Y, FakeRunner, _impact, _spectrum, _write

#: the response quantities of a row the map reads or reports (bins.csv)
ROW_QUANTITIES = ("restitution_normal", "restitution_tangential", "peak_normal_force_N",
                  "table_plastic_dissipation_J", "residual_dent_depth_m")


def bilinear_response(vn: float, angle: float, curved: float = 0.0) -> dict:
    """A response bilinear in x = ln v_n and y = angle (deg) in the form the map interpolates each
    quantity: e_n, e_t, the energies' fractions of the kinetic energy and the impulses per unit
    normal speed themselves; F_max and the dent in their logarithm. ``curved``: e_t gains
    curved (y / 60)^2, which no bilinear law follows."""
    x, y = math.log(vn), angle

    def bl(c0, cx, cy, cxy):
        return c0 + cx * x + cy * y + cxy * x * y

    vt = vn * math.tan(math.radians(angle))
    t = 0.5 * MASS * (vn**2 + vt**2)
    return {"restitution_normal": bl(0.85, -0.06, 4e-4, -3e-4),
            "restitution_tangential": bl(-0.3, 0.02, 0.012, 1e-3) + curved * (y / 60) ** 2,
            "peak_normal_force_N": math.exp(bl(11.0, 1.2, 1e-3, -2e-3)),
            "plastic_dissipation_J": t * bl(0.2, 0.05, -1e-3, 2e-4), "friction_dissipation_J": t * bl(0.05, 0.0, 2e-3, 0.0),
            "energy_to_liner_J": t * bl(0.01, 2e-3, 0.0, 1e-4), "residual_dent_depth_m": math.exp(bl(-10.0, 0.9, 2e-3, 0.0)),
            "tangential_impulse_N_s": vn * bl(-0.1, 0.01, -1e-3, 0.0), "normal_impulse_N_s": vn * bl(3.0, -0.2, 0.0, 0.0),
            "normal_velocity_in_m_s": vn, "tangential_velocity_in_m_s": vt}


class BilinearRunner(FakeRunner):
    """Stores each case's :func:`bilinear_response` at its normal speed and angle; counts the cases."""

    def __init__(self, curved=0.0):
        super().__init__()
        self.curved = curved

    def __call__(self, todo, folder, say):
        for c in todo:
            v = np.asarray(c.scene.impact.velocity)
            n = np.asarray(c.scene.contact_normal)
            vn = float(-(v @ n))
            vt = float(np.linalg.norm(v + vn * n))
            row = {"case": c.index, "key": c.key, "impact_speed_m_s": c.speed, "impact_angle_deg": c.angle,
                   "status": "ok", **bilinear_response(vn, math.degrees(math.atan2(vt, vn)), self.curved)}
            PieceStore(folder).save(c.key, row)
            self.done.append(c.key)


def _spread(n=240, seed=7):
    """Face impacts, v_n log-uniform in [0.3, 4] m/s (above V_y ~0.12 m/s), angles 5-60 deg, and
    four sub-yield ones."""
    rng = np.random.default_rng(seed)
    out = []
    for _ in range(n):
        vn = float(np.exp(rng.uniform(np.log(0.3), np.log(4.0))))
        out.append(_impact(vn, vn * math.tan(math.radians(rng.uniform(5, 60)))))
    return out + [_impact(0.5 * V_Y, 0.2 * V_Y)] * 4


def _run(tmp_path, imps, runner, name, **kw):
    out = tmp_path / name
    out.mkdir()
    res = run_damage_map(SCENE, imps, out, MapSettings(revolutions=1.0, repeat_impacts=0, **kw), "synthetic",
                         case_runner=runner, quiet=True)
    return res, out


def test_a_bilinear_response_is_interpolated_exactly_from_fewer_cases(tmp_path):
    runner = BilinearRunner()
    res, out = _run(tmp_path, _spread(), runner, "a", max_bins=60, angle_bins=3, bins_from="adaptive")
    rep = res["bins_from"]
    (g,) = rep["groups"]
    # one placed scene: 3 angle bins x the speed bins above V_y for the engine, the sub-yield bins
    # their own cases (Thornton's kink at V_y)
    assert g["engine"] and g["reached"] and g["bins_covered"] > START * START
    own = [b for b in res["bins"] if b["response"] == "case"]
    assert own and all(b["below_yield"] for b in own)
    # (a) the engine's starting grid and one check per cell: the law is exact at every check
    assert g["cases"] == START * START + (START - 1) ** 2 < g["bins_covered"]
    assert len(set(runner.done)) == rep["cases"] == g["cases"] + len(own) < len(res["bins"])
    assert all(e < 1e-12 for e in g["largest_checked_error"].values())
    assert rep["largest_checked_error"] == g["largest_checked_error"]
    # (b) every interpolated bin's row is the response at its own (v_n, angle) to round-off
    for b in res["bins"]:
        want = bilinear_response(b["normal_speed_m_s"], b["angle_deg"])
        for q in ROW_QUANTITIES:
            col = "plastic_dissipation_J" if q == "table_plastic_dissipation_J" else q
            assert b[q] == pytest.approx(want[col], rel=1e-9, abs=1e-12), (b["bin"], q)
    assert all(b["case_key"] == "" for b in res["bins"] if b["response"] == "interpolated")
    # the report is damage.json's
    summary = json.loads((out / "damage.json").read_text())
    assert summary["bins_from"]["groups"][0]["cases"] == g["cases"] and summary["bins_from"]["mode"] == "adaptive"


def test_where_the_engine_saves_nothing_the_rows_are_the_per_bin_cases_to_the_last_bit(tmp_path):
    imps = _spectrum(300)
    # few bins per placed scene (the default budget of 30 bins: 8 above V_y per place): no engine
    small, _ = _run(tmp_path, imps, FakeRunner(), "small", bins_from="adaptive")
    assert small["bins_from"]["engine_cases"] == 0 and not any(g["engine"] for g in small["bins_from"]["groups"])
    cases, _ = _run(tmp_path, imps, FakeRunner(), "cases", bins_from="cases")
    assert small["bins"] == cases["bins"] and small["places"] == cases["places"]
    # a placed scene of sub-yield bins alone: nothing for the engine to cover
    slow = [_impact(v, v * math.tan(math.radians(a))) for v, a in zip(np.linspace(0.3, 0.95, 12) * V_Y,
                                                                      np.linspace(10, 50, 12))]
    alone, _ = _run(tmp_path, slow, FakeRunner(), "slow", bins_from="adaptive", angle_bins=3)
    (g,) = alone["bins_from"]["groups"]
    assert g["bins_covered"] == 0 and not g["engine"] and g["bins"] == len(alone["bins"]) > 1
    assert alone["bins"] == _run(tmp_path, slow, FakeRunner(), "slow_cases", angle_bins=3)[0]["bins"]
    # many bins, but the fake's e_t (Coulomb sliding floored at rolling: a kink along the angle)
    # cannot be met within the budget: the engine stops (its starting grid projects more cases than
    # the bins, or the budget is spent), its cases are spent and reported, the rows are the bins' own
    runner = FakeRunner()
    big, _ = _run(tmp_path, imps, runner, "big", max_bins=100, bins_from="adaptive")
    per_bin, _ = _run(tmp_path, imps, FakeRunner(), "per_bin", max_bins=100, bins_from="cases")
    rep = big["bins_from"]
    assert rep["groups"] and all(not g["engine"] for g in rep["groups"])
    assert all("projects" in g["note"] or g["stopped_by_budget"] for g in rep["groups"])
    assert all(START * START <= g["cases"] <= g["bins_covered"] for g in rep["groups"])
    assert rep["engine_cases_spent"] == rep["engine_cases"] > 0 and rep["bins_interpolated"] == 0
    assert rep["largest_checked_error"] == {"restitution_normal": None, "restitution_tangential": None,
                                           "peak_normal_force_rel": None}
    assert big["bins"] == per_bin["bins"] and big["places"] == per_bin["places"]
    assert len(set(runner.done)) == rep["cases"] > len(per_bin["bins"])


def test_a_starting_grid_that_projects_more_cases_than_bins_stops_the_engine(tmp_path):
    # e_t = ... + 10 (angle / 60 deg)^2: the bins' representatives span 13-54 deg, where the
    # starting grid's cells (20.7 deg) miss by f'' h^2 / 8 = 0.30, 15 tolerances: 4 parts a cell
    # (error ~ h^2), 9 angle lines x 3 speeds and their checks, 83 cases for 42 bins
    runner = BilinearRunner(curved=10.0)
    ada, _ = _run(tmp_path, _spread(), runner, "a", max_bins=60, angle_bins=3, bins_from="adaptive")
    ref, _ = _run(tmp_path, _spread(), BilinearRunner(curved=10.0), "c", max_bins=60, angle_bins=3, bins_from="cases")
    (g,) = ada["bins_from"]["groups"]
    assert not g["engine"] and "projects" in g["note"] and g["cases"] == START * START < g["bins_covered"]
    assert ada["bins_from"]["engine_cases_spent"] == START * START
    assert len(set(runner.done)) == ada["bins_from"]["cases"] == START * START + len(ref["bins"])
    assert ada["bins"] == ref["bins"] and ada["places"] == ref["places"]


@pytest.mark.parametrize("k_t, k_n, k_f", [(0.0, 0.0, 0.0), (0.2, 0.05, 0.05), (0.5, 0.0, 0.0), (0.0, 0.0, 0.2),
                                           (1.0, 0.1, 0.1)])
def test_the_projection_from_the_starting_grid_never_exceeds_what_the_engine_needs(k_t, k_n, k_f):
    """Quadratic responses in x = ln v and y = angle / 60 deg: the projection from the engine's
    starting grid (its own second-difference prediction) against the cases the engine then takes
    to reach the tolerance: equal where the starting grid and its 4 checks suffice, below it where
    cells split (a split cell's check comes on top of its parts'), so a projection above the budget
    stops only an engine that could not have saved cases."""
    from millimpact.damage.adaptive_bins import BINS_CHECK_MARGIN, map_law, projected_cases
    from millimpact.studies.adaptive import adaptive_table

    def response(v, a):
        x, y = math.log(v), a / 60.0
        return {"e_n": 0.8 + k_n * x * x, "e_t": -0.3 + k_t * y * y, "f_max": 1e5 * math.exp(1.2 * x + k_f * x * x)}

    start = {}

    def compute(points):
        out = {p: response(*p) for p in points}
        start.update(out if not start else {})
        return out

    engine = adaptive_table(compute, (0.5, 4.0), (0.0, 60.0), 0.02, 1000, START, 2, law=map_law, margin=BINS_CHECK_MARGIN)
    projected = projected_cases(start, 0.02)
    assert engine.reached and projected <= engine.cases
    if engine.cases == START * START + (START - 1) ** 2:
        assert projected == engine.cases
    else:
        assert projected > START * START + (START - 1) ** 2     # it sees the splits coming


def test_a_bins_from_outside_its_choices_is_one_line(tmp_path):
    path = _write(tmp_path / "impacts.csv", HEADER, [GOOD])
    out = tmp_path / "out"
    r = run_cli("damage", "liner-segment", "--impacts", str(path), "--revolutions", "1", "--bins-from", "grid",
                "--out", str(out))
    lines = r.stderr.strip().splitlines()
    assert r.returncode == 2 and len(lines) == 1 and "--bins-from" in lines[0] and "adaptive" in lines[0], r.stderr
    assert not out.exists()
    with pytest.raises(InputError, match="--bins-from grid: must be one of adaptive, cases"):
        _run(tmp_path, [_impact(3.0, 1.0)], FakeRunner(), "api", bins_from="grid")


@pytest.mark.slow
def test_the_real_engine_reads_one_angles_bins_from_fewer_cases_within_the_tolerance(tmp_path):
    """Face impacts at 20 deg, v_n 1.02-1.45 m/s (one band of the table's ladder, [1, 1.5) m/s: one
    mesh and reduction), on the coarse liner-segment of the suite, --restitution-tolerance 0.01:
    6 speed bins, each computed as its own case and read from the engine's grid."""
    tol = 0.01
    imps = [_impact(v, v * math.tan(math.radians(20.0))) for v in np.geomspace(1.02, 1.45, 40)]
    coarse = SCENE
    for k, v in COARSE.items():
        coarse = coarse.with_value(k, v)
    res = {}
    for mode in ("adaptive", "cases"):
        out = tmp_path / mode
        out.mkdir()
        st = MapSettings(revolutions=1.0, repeat_impacts=0, bins_from=mode, tolerance=tol, angle_bins=1)
        res[mode] = run_damage_map(coarse, imps, out, st, "synthetic", quiet=True)
        res[mode]["stored"] = len(list((out / "cases").glob("*.json")))
    ada, ref = res["adaptive"], res["cases"]
    (g,) = ada["bins_from"]["groups"]
    # (a) 3 speeds at one angle and 2 checks for the 6 bins
    assert g["engine"] and g["reached"] and len(g["angles_deg"]) == 1
    assert ada["stored"] == g["cases"] == ada["bins_from"]["cases"] < len(ada["bins"]) == ref["stored"]
    assert all(b["response"] == "interpolated" for b in ada["bins"])
    # (b) against each bin's own case: e_n and e_t within the tolerance and F_max within 2 x it,
    # relative (the engine's: checked at each cell's centre, where linear interpolation of a smooth
    # response misses most, |f''| h^2 / 8, within 0.8 of it to leave the cases' scatter room)
    worst = ada["bins_from"]["largest_checked_error"]
    assert worst["restitution_normal"] <= 0.8 * tol and worst["peak_normal_force_rel"] <= 1.6 * tol
    for a, c in zip(ada["bins"], ref["bins"]):
        assert c["response"] == "case" and c["status"] == "ok" and a["bin"] == c["bin"]
        assert abs(a["restitution_normal"] - c["restitution_normal"]) <= tol
        assert abs(a["restitution_tangential"] - c["restitution_tangential"]) <= tol
        assert abs(a["peak_normal_force_N"] / c["peak_normal_force_N"] - 1) <= 2 * tol
        # the plastic work as a fraction of the impact's kinetic energy T: a loss like 1 - e_n^2,
        # whose error from e_n's is 2 e_n de_n <= 2 tol; the dent, interpolated in ln like F_max, 2 tol
        t = 0.5 * MASS * a["speed_m_s"] ** 2
        assert abs(a["table_plastic_dissipation_J"] - c["table_plastic_dissipation_J"]) / t <= 2 * tol
        assert abs(a["residual_dent_depth_m"] / c["residual_dent_depth_m"] - 1) <= 2 * tol
        # the absorbed energy (1 - e_n^2) T_n + (1 - e_t^2) (2/7) T_t per impact: its change from
        # errors de_n, de_t <= tol is at most 2 |e| tol (+ tol^2) of each term
        t_n = t * math.cos(math.radians(a["angle_deg"])) ** 2 * a["impacts"]
        t_t = (t * a["impacts"] - t_n) * 2 / 7
        bound = (2 * c["restitution_normal"] + tol) * tol * t_n + (2 * abs(c["restitution_tangential"]) + tol) * tol * t_t
        assert abs(a["energy_absorbed_J_per_rev"] - c["energy_absorbed_J_per_rev"]) <= bound
