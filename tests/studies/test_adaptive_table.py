"""The adaptive table's choice of cases (millimpact.studies.adaptive), on laws with known answers:
a law bilinear in (ln speed, angle) needs only the start grid and its checks; a law with a kink in
speed gets its new speeds at the kink; a budget too small stops with the error it reached."""
from __future__ import annotations

import math

import numpy as np
import pytest

from millimpact.studies.adaptive import adaptive_table, interpolate


def _compute(f):
    calls = []

    def compute(points):
        calls.append(list(points))
        return {p: f(*p) for p in points}

    return compute, calls


def test_a_law_the_interpolation_holds_exactly_needs_the_start_grid_only():
    """e_n, e_t and F_max linear in ln v and in the angle: the bilinear law is exact, every cell's check
    passes (errors at rounding), 9 + 4 cases."""
    def law(v, a):
        return {"e_n": 0.9 - 0.05 * math.log(v), "e_t": 0.5 + 0.001 * a, "f_max": 1e4 * (2 + math.log(v))}

    compute, _ = _compute(law)
    res = adaptive_table(compute, (0.5, 10.0), (0.0, 60.0), tolerance=0.01, max_cases=40)
    assert res.reached and not res.stopped_by_budget
    assert (len(res.speeds), len(res.angles), len(res.checks)) == (3, 3, 4)
    assert max(res.largest_error().values()) < 1e-12


def test_the_grid_grows_at_a_kink():
    """e_n flat to V_y = 2 m/s, then falling as 0.25 ln(v / 2) (a plastic scene's restitution across
    V_y): the speeds added lie at the kink (each split halves the cell holding it in ln v), the
    tolerance is reached, and the law then meets it at 200 random points of the plane within the
    tolerance, the checks having sampled the interpolation error where it is largest."""
    def law(v, a):
        return {"e_n": 0.9 - 0.25 * max(math.log(v / 2.0), 0.0), "e_t": 0.6, "f_max": 1e4 * (3 + math.log(v))}

    compute, _ = _compute(law)
    res = adaptive_table(compute, (0.5, 10.0), (0.0, 60.0), tolerance=0.01, max_cases=200)
    assert res.reached
    added = sorted(set(res.speeds) - set(np.geomspace(0.5, 10.0, 3)))
    near = [v for v in added if abs(math.log(v / 2.0)) < math.log(2.0)]
    assert len(near) >= len(added) - 1 and len(near) >= 3, res.speeds
    rng = np.random.default_rng(1)
    for v, a in zip(np.exp(rng.uniform(math.log(0.5), math.log(10.0), 200)), rng.uniform(0, 60, 200)):
        assert abs(interpolate(res.speeds, res.angles, res.grid, v, a)["e_n"] - law(v, a)["e_n"]) <= 0.01 + 1e-12


def test_a_budget_too_small_stops_and_reports_the_error_it_reached():
    def law(v, a):
        return {"e_n": 0.9 - 0.25 * max(math.log(v / 2.0), 0.0), "e_t": 0.6, "f_max": 1e4 * (3 + math.log(v))}

    compute, _ = _compute(law)
    res = adaptive_table(compute, (0.5, 10.0), (0.0, 60.0), tolerance=0.01, max_cases=15)
    assert res.stopped_by_budget and not res.reached
    assert res.cases <= 15
    assert res.largest_error()["e_n"] > 0.01
    # every grid line left has all its cases: the law can be built
    assert all((v, a) in res.grid for v in res.speeds for a in res.angles)


def test_interpolation_is_held_at_the_edges():
    grid = {(v, a): {"e_n": v + a, "e_t": 0.0, "f_max": 1.0} for v in (1.0, 4.0) for a in (0.0, 10.0)}
    assert interpolate([1.0, 4.0], [0.0, 10.0], grid, 2.0, 5.0)["e_n"] == pytest.approx(0.5 * (1 + 4) + 5.0)
    assert interpolate([1.0, 4.0], [0.0, 10.0], grid, 100.0, 50.0)["e_n"] == pytest.approx(14.0)


def test_a_power_law_force_is_refined_along_speed():
    """F_max = 1e4 v^1.2 (Hertz), e_n and e_t constant: the law interpolates F_max itself, convex in
    ln v (F'' / F = 1.44), so its error is along speed alone: every line added is a speed."""
    def law(v, a):
        return {"e_n": 0.8, "e_t": 0.5, "f_max": 1e4 * v**1.2}

    compute, _ = _compute(law)
    res = adaptive_table(compute, (0.5, 10.0), (0.0, 60.0), tolerance=0.01, max_cases=200)
    assert res.reached and len(res.angles) == 3 and len(res.speeds) > 3


def test_checks_hold_on_the_final_law_where_errors_cancel_at_a_cell_centre():
    """F_max = 1e4 (v cos a)^1.2: convex in ln v, concave in the angle, so a cell's centre can pass
    with the two errors cancelling there; a split beside it then uncovers the angle error at that
    centre. Every check is held against the final law: each meets the tolerance there."""
    def law(v, a):
        return {"e_n": 0.8, "e_t": 0.5, "f_max": 1e4 * (v * math.cos(math.radians(a))) ** 1.2}

    compute, _ = _compute(law)
    res = adaptive_table(compute, (0.5, 10.0), (0.0, 60.0), tolerance=0.01, max_cases=400)
    assert res.reached
    assert all(res.law_errors(c)["f_max"] <= 0.02 for c in res.checks)
    assert res.largest_error()["f_max"] <= 0.02


def test_a_budget_stop_after_an_angle_split_keeps_the_computed_grid():
    """e_n curved in the angle only: the first checks miss and split along angle, which the budget
    (9 + 2 checks) cannot pay for; the grid goes back to its computed 3 x 3 lines."""
    def law(v, a):
        return {"e_n": 0.9 - 1e-4 * a**2, "e_t": 0.6, "f_max": 1e4}

    compute, _ = _compute(law)
    res = adaptive_table(compute, (0.5, 10.0), (0.0, 60.0), tolerance=0.01, max_cases=11)
    assert res.stopped_by_budget and (len(res.speeds), len(res.angles)) == (3, 3)
    assert res.largest_error()["e_n"] > 0.01


def test_a_new_lines_cells_are_checked_from_the_batch_that_computed_it():
    """The kink law of test_the_grid_grows_at_a_kink: a split's grid line is computed with the centres
    of the cells it makes (one batch: the ranks busy on both instead of two batches each waiting for
    its slowest case). Every such centre is then either a check or a grid point (a later split through
    it) or left as a spare case, counted in the cases; every compute call after the start grid that
    carries a grid line carries cell centres with it."""
    def law(v, a):
        return {"e_n": 0.9 - 0.25 * max(math.log(v / 2.0), 0.0), "e_t": 0.6, "f_max": 1e4 * (3 + math.log(v))}

    compute, calls = _compute(law)
    res = adaptive_table(compute, (0.5, 10.0), (0.0, 60.0), tolerance=0.01, max_cases=200)
    assert res.reached
    computed = [p for c in calls for p in c]
    assert len(computed) == len(set(computed)) == res.cases  # no case computed twice, every one counted
    used = set(res.grid) | {c.point for c in res.checks}
    assert set(computed) == used | set(res.spare)
    assert len(res.spare) <= 2  # the centres computed ahead are nearly all used
    # fewer batches than cases: the lines' batches carry their cells' centres
    line_batches = [c for c in calls[1:] if any(p in res.grid for p in c)]
    assert line_batches and all(any(p not in res.grid for p in c) for c in line_batches)


#: the laws above: a kink in speed, errors that cancel at a cell's centre, a curve in the angle
LAWS = {
    "kink": lambda v, a: {"e_n": 0.9 - 0.25 * max(math.log(v / 2.0), 0.0), "e_t": 0.6, "f_max": 1e4 * (3 + math.log(v))},
    "cancelling": lambda v, a: {"e_n": 0.8, "e_t": 0.5, "f_max": 1e4 * (v * math.cos(math.radians(a))) ** 1.2},
    "angle": lambda v, a: {"e_n": 0.9 - 1e-4 * a**2, "e_t": 0.6, "f_max": 1e4},
}


@pytest.mark.parametrize("name", sorted(LAWS))
@pytest.mark.parametrize("start", [3, (4, 3)])
def test_eager_batches_check_every_open_cell_at_once_and_meet_the_tolerance(name, start):
    """eager (the table's mode): the start grid and its cells' centres are one batch, and each later
    batch checks every open cell the budget pays for. It reaches the tolerance as the pairwise order
    does, every check holds against the final law, no case is computed twice, in fewer batches.
    It may compute more cases (a check a split through its centre would have made needless: on
    these laws from a 3 x 3 start 41, 197, 34 cases against 41, 164, 25), which is what one
    barrier a batch costs."""
    runs = {}
    for eager in (False, True):
        compute, calls = _compute(LAWS[name])
        res = adaptive_table(compute, (0.5, 10.0), (0.0, 60.0), tolerance=0.01, max_cases=400, start=start,
                             eager=eager)
        runs[eager] = (res, calls)
        assert res.reached
        n_v, n_a = (start, start) if isinstance(start, int) else start
        assert (len(set(res.speeds) & set(np.geomspace(0.5, 10.0, n_v))), len(res.angles) >= n_a) == (n_v, True)
        assert all(max(res.law_errors(c)["e_n"], res.law_errors(c)["e_t"]) <= 0.01 for c in res.checks)
        assert all(res.law_errors(c)["f_max"] <= 0.02 for c in res.checks)
        computed = [p for c in calls for p in c]
        assert len(computed) == len(set(computed)) == res.cases
    eager_calls = runs[True][1]
    assert len(eager_calls[0]) == n_v * n_a + (n_v - 1) * (n_a - 1)
    assert len(eager_calls) < len(runs[False][1])


def test_eager_batches_fall_back_to_pairs_on_a_short_budget():
    """A budget of 11 cannot pay for the 3 x 3 grid's 4 checks with it: eager computes the grid alone
    and then a batch of two checks, the pairwise order (the budget test above)."""
    compute, calls = _compute(LAWS["angle"])
    res = adaptive_table(compute, (0.5, 10.0), (0.0, 60.0), tolerance=0.01, max_cases=11, eager=True)
    assert res.stopped_by_budget and [len(c) for c in calls] == [9, 2]
