"""``millimpact table --tolerance``: the adaptive table through the command line.

The finite-element tables run on the coarse half-space of test_table.py (h_contact 0.58 mm, h_far
12 mm: ~2 s a case with improved); the Hertz tables (method hertz) cost nothing. Every tolerance's
source is at its assertion.
"""
from __future__ import annotations

import csv
import json
import math

import pytest

from conftest import run_cli

COARSE = ["--set", "model.h_contact=5.8e-4", "--set", "model.h_far=0.012"]
#: normal impacts at 2.3-3.3 m/s: one rung of the band ladder ([2.25, 3.375) m/s), one reduction;
#: 4 grid speeds and 3 checks, one batch, which meet 0.01 (measured: e_n 8e-5, F_max 0.19 % off the law)
RANGE = ["--velocity", "2.3,3.3", "--angle", "0", *COARSE]


def _doc(out):
    return json.loads((out / "contact_table.json").read_text())


def _checks(out):
    return list(csv.DictReader(line for line in (out / "checks.csv").read_text().splitlines() if not line.startswith("#")))


@pytest.fixture(scope="module")
def adaptive(tmp_path_factory):
    out = tmp_path_factory.mktemp("adaptive") / "t"
    r = run_cli("table", "hertz-halfspace", *RANGE, "--tolerance", "0.01", "--out", str(out))
    assert r.returncode == 0, r.stderr[-3000:]
    return out, r


def test_the_adaptive_table_files(adaptive):
    """4 grid speeds and their 3 checks reach 0.01: the rows' roles, checks.csv (units in its
    header), the summary, the figure; no warning."""
    out, r = adaptive
    assert "warning" not in r.stderr, r.stderr
    summary = _doc(out)["adaptive"]
    assert summary["reached"] and (summary["grid_cases"], summary["checks"], summary["cases"]) == (4, 3, 7)
    assert max(summary["largest_checked_error"].values()) <= 0.01
    rows = _doc(out)["rows"]
    assert sorted(row["role"] for row in rows) == ["check"] * 3 + ["grid"] * 4
    checks = _checks(out)
    assert len(checks) == 3 and all(c["passed"] == "1" for c in checks)
    assert "# error_peak_normal_force_N_rel [-]" in (out / "checks.csv").read_text()
    assert "reached" in (out / "contact_table.csv").read_text().splitlines()[2]
    assert (out / "adaptive_points.png").stat().st_size > 0


def test_a_budget_too_small_says_the_tolerance_is_not_reached(adaptive, tmp_path):
    """A tolerance of 1e-6, below the discretisation's scatter on this mesh (F_max varies ~1e-3
    about the law), and a budget of 7: the three checks miss, their cells split at the checks' own
    points (no new case), and the next checks would pass the budget. Exit 0, one warning line, the
    files say it with the error reached (the missed checks': the split cells are not checked).
    The cases are the fixture's (the same grid and checks): none is computed."""
    import shutil

    out0, _ = adaptive
    out = tmp_path / "t"
    shutil.copytree(out0, out)      # a rerun of the table's folder: its cases/ serve
    r = run_cli("table", "hertz-halfspace", *RANGE, "--tolerance", "1e-6", "--max-cases", "7", "--out", str(out))
    assert r.returncode == 0, r.stderr[-3000:]
    warnings = [line for line in r.stderr.splitlines() if "warning: tolerance" in line]
    assert len(warnings) == 1 and "not reached within --max-cases 7" in warnings[0], r.stderr
    summary = _doc(out)["adaptive"]
    assert not summary["reached"] and summary["stopped_by_budget"]
    assert (summary["grid_cases"], summary["checks"], summary["cases"]) == (7, 3, 7)
    worst = summary["largest_checked_error"]
    # the reached error is the missed checks' own: above the tolerance (F_max: 2e-6 relative)
    assert worst["restitution_normal"] > 1e-6 or worst["peak_normal_force_rel"] > 2e-6
    assert "NOT reached within 7 cases" in (out / "contact_table.csv").read_text().splitlines()[2]
    checks = _checks(out)
    assert len(checks) == 3 and all(c["passed"] == "0" and c["became_grid"] == "1" for c in checks)


def test_a_case_of_the_adaptive_table_is_the_case_of_a_fixed_table(adaptive, tmp_path):
    """A grid case (2.3 m/s) and a check case (the geometric mean of 2.3 and sqrt(2.3 x 3.3)) of the
    adaptive table, computed again in a fixed table of these two speeds alone: the same key and
    the same numbers to 1e-10 relative (each case's mesh, reduction and steps follow from the case
    alone, the band ladder; the same serial computation gives the same floating-point result, the
    margin being for the factorization's pivoting order, which does not vary here)."""
    out, _ = adaptive
    rows = _doc(out)["rows"]
    grid = min((row for row in rows if row["role"] == "grid"), key=lambda row: row["impact_speed_m_s"])
    check = min((row for row in rows if row["role"] == "check"), key=lambda row: row["impact_speed_m_s"])
    fixed = tmp_path / "fixed"
    speeds = f"{grid['impact_speed_m_s']!r},{check['impact_speed_m_s']!r}"
    r = run_cli("table", "hertz-halfspace", "--velocity", speeds, "--angle", "0", *COARSE, "-q", "--out", str(fixed))
    assert r.returncode == 0, r.stderr[-3000:]
    again = {row["impact_speed_m_s"]: row for row in _doc(fixed)["rows"]}
    for row in (grid, check):
        twin = again[row["impact_speed_m_s"]]
        assert twin["key"] == row["key"]
        for k in ("restitution_normal", "peak_normal_force_N", "normal_impulse_N_s", "max_approach_m"):
            assert twin[k] == pytest.approx(row[k], rel=1e-10), k


@pytest.mark.mpi
def test_mpi_adaptive_table_equals_serial(adaptive, tmp_path):
    """mpirun -n 2 (two groups of one rank; the grid and its checks one batch, as serial): the
    same cases chosen and the same rows to 1e-9 relative (each case is the same serial computation;
    test_table's MPI bound)."""
    out, _ = adaptive
    r = run_cli("table", "hertz-halfspace", *RANGE, "--tolerance", "0.01", "--out", str(tmp_path / "np2"), np=2)
    assert r.returncode == 0, r.stderr[-3000:]
    a, b = _doc(out)["rows"], _doc(tmp_path / "np2")["rows"]
    assert [(x["impact_speed_m_s"], x["role"]) for x in a] == [(x["impact_speed_m_s"], x["role"]) for x in b]
    for ra, rb in zip(a, b):
        for k in ("restitution_normal", "peak_normal_force_N", "normal_impulse_N_s"):
            assert rb[k] == pytest.approx(ra[k], rel=1e-9), k


def test_a_hertz_table_needs_the_starting_grid_only_and_its_error_is_exported(tmp_path):
    """Method hertz: e_n = 1 and F_max = Hertz's at every speed and angle, which the exported law
    (zeta = 0 and the materials' E* at every grid point, F_max from the point's own normal speed)
    reproduces exactly: the 4 x 3 grid and its 6 checks reach the tolerance, the errors at the
    law's own precision (its e(zeta) interpolant, ~1e-8: theory/hertz_dashpot.py). The export
    carries the largest checked error into its file's header."""
    out = tmp_path / "h"
    r = run_cli("table", "hertz-halfspace", "--method", "hertz", "--velocity", "0.5,10", "--angle", "0,60",
                "--tolerance", "0.01", "-q", "--out", str(out))
    assert r.returncode == 0 and "warning" not in r.stderr, r.stderr[-3000:]
    s = _doc(out)["adaptive"]
    assert s["reached"] and (s["grid_cases"], s["checks"]) == (12, 6)
    assert max(s["largest_checked_error"].values()) < 1e-8
    for c in _checks(out):
        # a check at the centre of its cell: the geometric mean of the speeds, the mean of the angles
        v0, v1 = map(float, c["cell_speeds_m_s"].split())
        assert float(c["impact_speed_m_s"]) == pytest.approx(math.sqrt(v0 * v1), rel=1e-15)
    r = run_cli("export", str(out), "--to", "yade", "-q", "--out", str(tmp_path / "y"))
    assert r.returncode == 0, r.stderr[-3000:]
    head = (tmp_path / "y" / "contact_law_yade.py").read_text().splitlines()[:12]
    line = [h for h in head if h.startswith("# Interpolation error checked at 6 of the table's cases")]
    assert len(line) == 1 and "tolerance 0.01 (F_max 2 %) reached" in line[0], head
    law = json.loads((tmp_path / "y" / "contact_law.json").read_text())
    assert law["interpolation_checked"]["reached"] and len(law["points"]) == 12      # the grid's points only


#: a block of yield stress 3.4 GPa: Thornton's V_y 3.86 m/s, so that the table's elastic part starts
#: at 1 m/s, where the coarse mesh's F_max scatters by ~1 % (below ~0.8 m/s the contact spans ~1
#: element and F_max scatters by up to 3.6 %, which a tolerance of 0.01 would chase)
YIELD_STRESS = 3.4e9
#: 1-10 m/s at 0 deg: the start grid 1, 3.16, 10 m/s (--start-grid 3x3); its upper cell holds V_y
#: (0.82-2.59 V_y). The default 4 speeds (1, 2.15, 4.64, 10) cut the kink's curvature into cells that
#: each pass (measured: e_n 0.0007, 0.0046, 0.0006 at their centres against 0.65 x 0.01)
KINK_RANGE = ["--velocity", "1,10", "--angle", "0", *COARSE, "--tolerance", "0.01", "--max-cases", "12",
              "--start-grid", "3x3"]


@pytest.mark.slow
def test_an_elastic_plastic_table_refines_where_the_block_yields(tmp_path):
    """The law across Thornton's yield-onset speed V_y (theory/thornton.py): below it the block's
    vibration alone takes energy (e_n 0.997-0.989, nearly linear in ln v), above it e_n falls by a
    further ~0.031 ln(v / V_y)^2 (measured against the elastic block at 1.46-2.59 V_y), a kink in
    its curvature at V_y. The engine adds speeds in the start cell that holds V_y, within a factor 1.5
    of it, because e_n misses there (not F_max's scatter); the elastic cell's check passes; the
    final law meets every check. The same table on the elastic block adds no speed, and its cases
    below V_y are the plastic block's (no yield there): the refinement is the yield's."""
    from millimpact.scene.builtin import builtin_scene
    from millimpact.theory.hertz import effective_modulus
    from millimpact.theory.thornton import yield_onset_velocity

    scene = builtin_scene("hertz-halfspace")
    v_y = yield_onset_velocity(YIELD_STRESS, effective_modulus(scene.ball.material, scene.block.material),
                               scene.ball.effective_density)
    start = [1.0, math.sqrt(10.0), 10.0]
    assert start[1] < v_y < start[2]      # V_y inside the upper start cell: the kink is in a cell, not on a line
    tol = 0.01
    runs = {}
    for name, extra in (("plastic", ["--set", f"block.material.yield_stress={YIELD_STRESS!r}"]), ("elastic", [])):
        out = tmp_path / name
        r = run_cli("table", "hertz-halfspace", *KINK_RANGE, *extra, "-q", "--out", str(out))
        assert r.returncode == 0 and "warning" not in r.stderr, r.stderr[-3000:]
        runs[name] = out
    summary = _doc(runs["plastic"])["adaptive"]
    added = [v for v in summary["speeds_m_s"] if min(abs(math.log(v / s)) for s in start) > 1e-9]
    # the kink cell's centre misses in e_n (measured 0.0117 against 0.8 tol = 0.008: the parabola above
    # V_y predicts 0.0097 there, the elastic part's curvature ~0.0008 more) and is split there, 1.46 V_y;
    # its halves pass (0.0019, 0.0014). A split in the elastic cell (its centre 0.46 V_y) or at the
    # centre of the upper half (1.95 V_y: what F_max's scatter makes at a tolerance of 0.004) fails.
    assert summary["reached"] and added, summary["speeds_m_s"]
    assert all(start[1] < v < start[2] and abs(math.log(v / v_y)) < math.log(1.5) for v in added), (v_y, added)
    checks = _checks(runs["plastic"])
    missed = [c for c in checks if c["passed"] == "0"]
    assert missed and all(float(c["error_restitution_normal"]) > 0.8 * tol for c in missed), missed
    # F_max is not what split: the coarse mesh's scatter gives check errors <= 0.93 % here, under 1.6 %
    assert all(float(c["error_peak_normal_force_N_rel"]) <= 1.6 * tol for c in missed)
    assert all(float(c["cell_speeds_m_s"].split()[1]) > v_y for c in missed)   # only the cell holding V_y
    # the final law meets every check (the engine's margin: 0.8 tol in e_n, 1.6 tol in F_max)
    for c in checks:
        assert float(c["error_restitution_normal_final"]) <= 0.8 * tol, c
        assert float(c["error_peak_normal_force_N_final_rel"]) <= 1.6 * tol, c
    elastic = _doc(runs["elastic"])
    assert elastic["adaptive"]["reached"] and len(elastic["adaptive"]["speeds_m_s"]) == 3
    plastic_rows = {row["impact_speed_m_s"]: row for row in _doc(runs["plastic"])["rows"]}
    for row in elastic["rows"]:
        twin = plastic_rows[row["impact_speed_m_s"]]
        if row["impact_speed_m_s"] < v_y:
            # no yield below V_y on this mesh either: the same computation, to the last bit
            assert twin["plastic_dissipation_J"] == 0.0
            assert twin["restitution_normal"] == pytest.approx(row["restitution_normal"], rel=1e-12)
        else:
            # above V_y the block yields: e_n below the elastic block's by more than the tolerance at
            # 10 m/s (measured 0.004 at 1.46 V_y, 0.029 at 2.59 V_y)
            assert twin["restitution_normal"] < row["restitution_normal"] - 1e-3


@pytest.mark.parametrize("args, said", [
    (["--tolerance", "0"], "--tolerance 0: outside (0, 0.5)"),
    (["--tolerance", "0.5"], "--tolerance 0.5: outside (0, 0.5)"),
    (["--tolerance", "nan"], "--tolerance nan: outside (0, 0.5)"),
    (["--tolerance", "0.01", "--max-cases", "11"], "--max-cases 11: outside [12, 10000] (the starting grid is 4 speeds x 3 angles)"),
    (["--tolerance", "0.01", "--angle", "0", "--max-cases", "3"], "--max-cases 3: outside [4, 10000] (the starting grid is 4 speeds)"),
    (["--max-cases", "20"], "--max-cases: only with --tolerance"),
    (["--start-grid", "3x3"], "--start-grid: only with --tolerance"),
    (["--tolerance", "0.01", "--start-grid", "1x3"], "--start-grid '1x3': N and M must lie in [2, 20]"),
    (["--tolerance", "0.01", "--start-grid", "4by3"], "--start-grid '4by3': give NxM"),
    (["--tolerance", "0.01", "--start-grid", "5x5", "--max-cases", "24"],
     "--max-cases 24: outside [25, 10000] (the starting grid is 5 speeds x 5 angles)"),
    (["--tolerance", "0.01", "--velocity", "1"], "--velocity '1': with --tolerance, the range's ends"),
    (["--tolerance", "0.01", "--velocity", "3,1"], "--velocity '3,1': with --tolerance, the range's ends"),
])
def test_bad_adaptive_input_is_one_line_and_no_folder(args, said, tmp_path):
    base = ["--velocity", "0.5,10", "--angle", "0,60"]
    # the later --velocity / --angle win (argparse): each case changes one field of a valid command
    r = run_cli("table", "hertz-halfspace", "--method", "hertz", *base, *args, "--out", str(tmp_path / "x"))
    lines = r.stderr.strip().splitlines()
    assert r.returncode == 2 and len(lines) == 1 and said in lines[0], r.stderr
    assert not (tmp_path / "x").exists()
