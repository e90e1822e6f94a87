"""Adaptive contact tables: the cases a DEM law needs, chosen by the law's own interpolation error.

A DEM code reads the table's law by bilinear interpolation in (ln speed, angle) over a grid of
speeds x angles, held at the nearest edge outside it (the Yade export's runtime,
:mod:`millimpact.theory.hertz_dashpot`, interpolates the Hertz-dashpot law's zeta and E*: the
``law`` the checks measure, :func:`millimpact.studies.table_adaptive.export_law`; by default here
e_n, e_t and F_max themselves, :func:`interpolate`). A grid fixed in advance computes cases the
law does not need and says nothing about the error between them. Here the grid grows where the
law is wrong:

1. Start from ``start`` speeds (geometric between the range's ends) x ``start`` angles (linear), or
   from (speeds, angles) counts apart.
2. Predict each cell's interpolation error from the grid's second differences around it: the
   error of linear interpolation at a cell's midpoint is |f''| h^2 / 8 along each direction, and
   the divided second difference estimates f'' (in ln speed and in angle), in units of the
   tolerance (F_max: relative to its value, in units of 2 ``tolerance``); each cell gets the
   largest of its edges' grid lines in each direction.
3. Compute the check at the centre of the open cells: with ``eager`` all in one batch (the start
   grid's with the grid) while the budget pays for them, one barrier and one reduction per band;
   else the largest predictions first, ``batch`` at a time. Compare ``|e_n - law|``, ``|e_t - law|``
   with ``tolerance`` and ``|F_max / law - 1|`` with 2 ``tolerance``, within ``CHECK_MARGIN`` (0.65)
   of them for the cases' own scatter (e_t not where the law has none: a normal-incidence corner).
4. A cell that misses is split: a new speed (the geometric mean of its two) where its predicted
   error along speed is the larger, else a new angle (the mean); the new grid line's cases are
   computed, and the new cells are checked in turn: their centres are computed in the same batch
   as the line (known before it is: a batch of two ranks' work instead of two batches that each
   wait for their slowest case), kept as spare cases until their cell's check takes them. A cell
   that meets the tolerance is not checked again; the cells a split makes from a cell that met it
   inherit its check.
5. After every new grid line, every earlier check is compared with the law as it now is
   (:func:`_recheck`): a check whose point the law now misses (its centre passed with the errors
   along speed and angle cancelling, and a split beside it uncovered one) gets the grid lines
   through its point, and the cells around it are checked again. So at the end every check
   meets the tolerance against the final law.
6. Stop when every cell has met the tolerance, or when the next batch or grid line would pass
   ``max_cases`` (a grid line the budget cannot pay for is dropped). The largest error is the
   checks' against the final law, and a missed check's own where its cell's parts are unchecked
   (:meth:`AdaptiveResult.largest_error`).

Every case is one impact of the table engine (:mod:`millimpact.studies.table`), so the engine's
bands, reductions and case cache serve the grid and the checks alike; :func:`adaptive_table`
takes the engine as a ``compute`` function of a list of (speed, angle) points.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np

#: a check passes within this fraction of the tolerance. A check measures the law against one
#: case, and every case carries its mesh's scatter: the plastic paper-rig table's 100 cases (10
#: speeds x 10 angles) depart from a smooth surface (degree 5 in ln v x 4 in angle, least squares)
#: by 0.0007 rms and 0.0025 at most in e_n, a quarter of a 0.01 tolerance; a check understating the
#: law's error by that, or a point beside it overstating it, is covered by the margin. Measured
#: (benchmarks/adaptive_table.py, the cell 2.24-10 m/s x 0-30 deg): a centre that passed at 0.0087
#: held points at 0.0123, and in a later run of the same code paths one at 0.0079 held 0.0114, both
#: ~1.44 times the centre's error; 1 / 1.44 = 0.69, less 5 % for the scatter between runs
CHECK_MARGIN = 0.65
#: the quantities a law carries, and whether their error is absolute (e_n, e_t) or relative (F_max)
QUANTITIES = (("e_n", False), ("e_t", False), ("f_max", True))

Point = tuple[float, float]
Values = dict[str, float]
#: a law: its values at (v, a) from the grid's speeds, angles and cases
Law = Callable[[Sequence[float], Sequence[float], dict[Point, Values], float, float], Values]


@dataclass
class Check:
    """One check case: its point, the cell it checked, its values, the law's, the errors."""

    point: Point
    cell: tuple[Point, Point]  # the cell's (low speed, low angle) and (high speed, high angle) corners
    values: Values
    law: Values
    errors: Values  # per quantity, absolute (relative for F_max)
    passed: bool


@dataclass
class AdaptiveResult:
    """The grid the law is built on, its cases' values, the checks, and whether the tolerance held."""

    speeds: list[float]
    angles: list[float]
    grid: dict[Point, Values]
    checks: list[Check] = field(default_factory=list)
    reached: bool = False
    stopped_by_budget: bool = False
    #: the cells (corners) whose check met the tolerance; a cell inside one needs no check
    passed: set[tuple[Point, Point]] = field(default_factory=set)
    #: the law the checks measure (default :func:`interpolate`)
    law: Law = field(default=lambda *args: interpolate(*args), repr=False)
    #: cases computed ahead with a grid line, the centres of the cells it made (step 4), not yet a check
    spare: dict[Point, Values] = field(default_factory=dict)
    #: a check passes within this fraction of the tolerance (:data:`CHECK_MARGIN`)
    margin: float = CHECK_MARGIN

    @property
    def cases(self) -> int:
        """The cases computed: the grid's, the checks' (a check a split made a grid point once) and
        the spare centres'."""
        return len(set(self.grid) | {c.point for c in self.checks} | set(self.spare))

    def law_errors(self, check: Check) -> Values:
        """The check's errors against the law of the grid as it is now (a later split may have put a
        grid line through its point or next to it): what the exported law's error is there."""
        return _errors(check.values, self.law(self.speeds, self.angles, self.grid, *check.point))

    def largest_error(self) -> Values:
        """The largest error of each quantity the checks measured on the law as it is now (0 without
        checks; a quantity the law does not define at a check, NaN, is left out): each check's
        error against the law now, and a missed check's own error while a cell inside its cell is
        still unchecked (a budget stop: the split law there is not verified, the miss stands)."""
        open_cells = [cell for _, cell, _ in _open_cells(self, self.passed, 1.0)] if not self.reached else []
        errors = []
        for c in self.checks:
            e = self.law_errors(c)
            if not c.passed and any(_inside(o, c.cell) for o in open_cells):
                e = {q: float(np.fmax(e[q], c.errors[q])) for q in e}
            errors.append(e)
        return {q: max((e[q] for e in errors if math.isfinite(e[q])), default=0.0) for q, _ in QUANTITIES}


def bilinear_weights(speeds: Sequence[float], angles: Sequence[float], v: float, a: float) -> list[tuple[Point, float]]:
    """The grid points around (v, a) and their weights of bilinear interpolation in (ln speed,
    angle), (v, a) held at the nearest edge outside the grid (the Yade export's runtime)."""
    lv = np.log(speeds)
    x = float(np.clip(math.log(v), lv[0], lv[-1]))
    y = float(np.clip(a, angles[0], angles[-1]))
    i = int(np.clip(np.searchsorted(lv, x) - 1, 0, max(len(speeds) - 2, 0)))
    j = int(np.clip(np.searchsorted(angles, y) - 1, 0, max(len(angles) - 2, 0)))
    i1, j1 = min(i + 1, len(speeds) - 1), min(j + 1, len(angles) - 1)
    tx = 0.0 if i1 == i else (x - lv[i]) / (lv[i1] - lv[i])
    ty = 0.0 if j1 == j else (y - angles[j]) / (angles[j1] - angles[j])
    return [
        ((speeds[i], angles[j]), (1 - tx) * (1 - ty)),
        ((speeds[i], angles[j1]), (1 - tx) * ty),
        ((speeds[i1], angles[j]), tx * (1 - ty)),
        ((speeds[i1], angles[j1]), tx * ty),
    ]


def interpolate(
    speeds: Sequence[float], angles: Sequence[float], grid: dict[Point, Values], v: float, a: float
) -> Values:
    """The law's value at (v, a): e_n, e_t and F_max bilinear in (ln speed, angle), held at the
    nearest edge outside."""
    w = bilinear_weights(speeds, angles, v, a)
    return {q: sum(wk * grid[p][q] for p, wk in w if wk != 0.0) for q, _ in QUANTITIES}


def _errors(values: Values, law: Values) -> Values:
    """Each quantity's error: absolute, relative for F_max; NaN where the case or the law has no
    value (e_t of a normal impact, and so of the law on a cell with a normal-incidence corner)."""
    return {q: abs(values[q] / law[q] - 1.0) if rel and law[q] else abs(values[q] - law[q]) for q, rel in QUANTITIES}


def _passes(errors: Values, tolerance: float, margin: float) -> bool:
    """Within ``margin`` times the tolerance (2 ``tolerance`` relative for F_max); a NaN error is
    not checked."""
    limit = margin * tolerance
    return not any(errors[q] > (2.0 * limit if rel else limit) for q, rel in QUANTITIES)


def _scaled_second_differences(xs: Sequence[float], column: Callable[[int], float]) -> list[float]:
    """|f_{k-1} - 2 f_k + f_{k+1}| / 4 at each interior line k (0 at the ends), each quantity
    normalised by its tolerance scale beforehand (``column`` gives it)."""
    out = [0.0] * len(xs)
    for k in range(1, len(xs) - 1):
        h0, h1 = xs[k] - xs[k - 1], xs[k + 1] - xs[k]
        # the divided second difference times the cell's half-width squared, for uneven spacing
        d2 = 2.0 * ((column(k + 1) - column(k)) / h1 - (column(k) - column(k - 1)) / h0) / (h0 + h1)
        out[k] = abs(d2) * (0.5 * max(h0, h1)) ** 2 / 2.0
    return out


def predicted_errors(result: AdaptiveResult, tolerance: float) -> dict[tuple[int, int], tuple[float, float]]:
    """Per cell (i, j): its predicted interpolation error along speed and along angle, in units of
    the tolerance (the module docstring, step 2)."""
    sv, sa, g = result.speeds, result.angles, result.grid
    lv = [math.log(v) for v in sv]

    along_v = np.zeros((len(sv), len(sa)))
    along_a = np.zeros((len(sv), len(sa)))
    for q, rel in QUANTITIES:
        raw = np.array([[g[(v, a)][q] for a in sa] for v in sv])
        # e_n, e_t in units of the tolerance; F_max relative to its value at the line, in units of
        # 2 tolerance: the law interpolates F_max itself (not ln F_max), so a power law F ~ v^1.2,
        # straight in (ln v, ln F), is curved for it (F'' / F = 1.2^2 in ln v)
        table = raw / (2.0 * tolerance if rel else tolerance)
        for j in range(len(sa)):
            d = np.array(_scaled_second_differences(lv, table[:, j].__getitem__))
            d = d / np.abs(raw[:, j]) if rel else d
            along_v[:, j] = np.fmax(along_v[:, j], d)  # fmax: a NaN (undefined e_t) predicts nothing
        for i in range(len(sv)):
            d = np.array(_scaled_second_differences(sa, table[i, :].__getitem__))
            d = d / np.abs(raw[i, :]) if rel else d
            along_a[i, :] = np.fmax(along_a[i, :], d)
    out = {}
    for i in range(len(sv) - 1):
        for j in range(max(len(sa) - 1, 1)):
            jj = [j, min(j + 1, len(sa) - 1)]
            out[(i, j)] = (
                float(max(along_v[i, jj].max(), along_v[i + 1, jj].max())),
                float(max(along_a[i, jj].max(), along_a[i + 1, jj].max())) if len(sa) > 1 else 0.0,
            )
    return out


def adaptive_table(
    compute: Callable[[list[Point]], dict[Point, Values]],
    speed_range: tuple[float, float],
    angle_range: tuple[float, float],
    tolerance: float,
    max_cases: int,
    start: int | tuple[int, int] = 3,
    batch: int = 2,
    say: Callable[[str], None] = lambda s: None,
    law: Law = interpolate,
    margin: float = CHECK_MARGIN,
    eager: bool = False,
) -> AdaptiveResult:
    """Choose the table's cases (the module docstring); ``compute(points)`` returns each point's
    e_n, e_t and f_max; ``law`` is the law the checks measure (the exported law's own
    interpolation: :func:`interpolate` of e_n, e_t, F_max by default); a check passes within
    ``margin`` of the tolerance; ``eager``: every open cell's check in one batch when the budget
    pays for them all (step 3)."""
    v0, v1 = speed_range
    a0, a1 = angle_range
    n_v, n_a = (start, start) if isinstance(start, int) else start
    speeds = [float(x) for x in np.geomspace(v0, v1, n_v)]
    angles = [float(x) for x in np.linspace(a0, a1, n_a)] if a1 > a0 else [float(a0)]
    result = AdaptiveResult(speeds, angles, {}, law=law, margin=margin)
    passed = result.passed

    def fill_grid(ahead: Sequence[Point] = ()) -> None:
        # a check on the new line (the centre of the cell it split) is a grid case already computed;
        # ``ahead``: the centres of the cells the line makes, computed in the same batch (spare)
        known = {**result.spare, **{c.point: c.values for c in result.checks}}
        todo = [(v, a) for v in result.speeds for a in result.angles if (v, a) not in result.grid]
        result.grid.update({p: known[p] for p in todo if p in known})
        for p in todo:
            result.spare.pop(p, None)
        extra = [p for p in ahead if p not in known and p not in todo]
        todo = [p for p in todo if p not in known]
        if todo or extra:
            values = compute(todo + extra)
            result.grid.update({p: values[p] for p in todo})
            result.spare.update({p: values[p] for p in extra})

    first = [_centre(c) for c in _all_cells(result)]
    fill_grid(first if eager and len(speeds) * len(angles) + len(first) <= max_cases else ())
    while True:
        if _recheck(result, tolerance):
            if result.cases + _new_cases(result) > max_cases:
                result.stopped_by_budget = True
                _drop_unfilled(result)
                return result
            fill_grid()
            continue
        cells = _open_cells(result, passed, tolerance)
        if not cells:
            result.reached = True
            return result
        paid = sum(_centre(c) not in result.spare for _, c, _ in cells)
        pick = _batch(cells, paid if eager and result.cases + paid <= max_cases else batch, result.spare)
        centres = [_centre(c) for _, c, _ in pick]
        needed = [p for p in centres if p not in result.spare]
        if result.cases + len(needed) > max_cases:
            result.stopped_by_budget = True
            return result
        values = compute(needed) if needed else {}
        values.update({p: result.spare.pop(p) for p in centres if p in result.spare})
        laws = [law(result.speeds, result.angles, result.grid, *p) for p in centres]  # before any split
        missed = []
        for (_, cell, (ev, ea)), p, at in zip(pick, centres, laws):
            errors = _errors(values[p], at)
            ok = _passes(errors, tolerance, result.margin)
            result.checks.append(Check(p, cell, values[p], at, errors, ok))
            if ok:
                passed.add(cell)
            elif _split(result, cell, ev, ea):
                missed.append(cell)
        if missed:
            line = _new_cases(result)
            if result.cases + line > max_cases:
                result.stopped_by_budget = True
                _drop_unfilled(result)
                return result
            ahead = [_centre(c) for m in missed for c in _cells_within(result, m)]
            fill_grid(ahead if result.cases + line + len(ahead) <= max_cases else ())
        worst = result.largest_error()
        say(
            f"  adaptive: {len(result.speeds)} x {len(result.angles)} grid, {len(result.checks)} checks "
            f"({sum(not c.passed for c in result.checks)} missed); the law's largest error at the checks: e_n "
            f"{worst['e_n']:.3g}, e_t {worst['e_t']:.3g}, F_max {worst['f_max']:.2%}"
        )


def _recheck(result: AdaptiveResult, tolerance: float) -> bool:
    """Every check against the law as it now is (step 5 of the module docstring): a split changes
    the law at earlier check points, where the values are known, and a cell's check at its centre
    can pass where the errors along speed and along angle cancel there (F_max convex in ln v and
    concave in the angle) and the split of a neighbour then uncovers one of them. A check the law
    now misses gets the grid line(s) through its point (its speed, else its angle: the point
    becomes a grid case, exact) and the cells that had passed around it are checked again.
    Returns whether a line was added."""
    added = False
    missed = [
        c for c in result.checks if not _passes(result.law_errors(c), tolerance, result.margin)
    ]  # before adding lines
    for c in missed:
        v, a = c.point
        if v not in result.speeds:
            result.speeds = sorted([*result.speeds, v])
        elif a not in result.angles:
            result.angles = sorted([*result.angles, a])
        else:
            continue  # a grid case already: exact once its line is filled
        added = True
        for cell in [p for p in result.passed if _inside(((v, a), (v, a)), p)]:
            result.passed.discard(cell)
    return added


def _open_cells(result: AdaptiveResult, passed: set, tolerance: float) -> list:
    """The cells not yet known to meet the tolerance, largest prediction first: (prediction, cell
    corners, (along speed, along angle))."""
    pred = predicted_errors(result, tolerance)
    sv, sa = result.speeds, result.angles
    out = []
    for (i, j), (ev, ea) in pred.items():
        cell = ((sv[i], sa[j]), (sv[i + 1], sa[min(j + 1, len(sa) - 1)]))
        if not any(_inside(cell, p) for p in passed):
            out.append((max(ev, ea), cell, (ev, ea)))
    out.sort(key=lambda c: -c[0])
    return out


def _batch(cells: list, batch: int, spare: dict[Point, Values]) -> list:
    """The open cells (largest prediction first) a batch checks: the first ``batch`` whose centre
    must be computed, and every open cell whose centre was computed ahead (no case to pay)."""
    pick, paid = [], 0
    for c in cells:
        free = _centre(c[1]) in spare
        if free or paid < batch:
            pick.append(c)
            paid += not free
    return pick


def _all_cells(result: AdaptiveResult) -> list[tuple[Point, Point]]:
    """Every cell of the grid as it now is."""
    sv, sa = result.speeds, result.angles
    return _cells_within(result, ((sv[0], sa[0]), (sv[-1], sa[-1])))


def _cells_within(result: AdaptiveResult, cell: tuple[Point, Point]) -> list[tuple[Point, Point]]:
    """The cells of the grid as it now is inside ``cell`` (a split cell's parts)."""
    (v0, a0), (v1, a1) = cell
    sv = [v for v in result.speeds if v0 <= v <= v1]
    sa = [a for a in result.angles if a0 <= a <= a1]
    if len(sa) == 1:
        return [((sv[i], sa[0]), (sv[i + 1], sa[0])) for i in range(len(sv) - 1)]
    return [((sv[i], sa[j]), (sv[i + 1], sa[j + 1])) for i in range(len(sv) - 1) for j in range(len(sa) - 1)]


def _inside(cell: tuple[Point, Point], parent: tuple[Point, Point]) -> bool:
    """Whether ``cell`` lies within ``parent`` (a cell that met the tolerance)."""
    (v0, a0), (v1, a1) = cell
    (p0, q0), (p1, q1) = parent
    eps = 1e-12
    return p0 * (1 - eps) <= v0 and v1 <= p1 * (1 + eps) and q0 - eps <= a0 and a1 <= q1 + eps


def _centre(cell: tuple[Point, Point]) -> Point:
    (v0, a0), (v1, a1) = cell
    return (math.sqrt(v0 * v1), 0.5 * (a0 + a1))


def _split(result: AdaptiveResult, cell, ev: float, ea: float) -> bool:
    """Add the cell's new speed (or angle, where its predicted error along angle is larger)."""
    (v0, a0), (v1, a1) = cell
    if ea > ev and a1 > a0:
        new = 0.5 * (a0 + a1)
        if new not in result.angles:
            result.angles = sorted([*result.angles, new])
            return True
    new = math.sqrt(v0 * v1)
    if new not in result.speeds:
        result.speeds = sorted([*result.speeds, new])
        return True
    return False


def _new_cases(result: AdaptiveResult) -> int:
    """The cases the grid's new lines need (a check or a spare case on them is computed already)."""
    checked = {c.point for c in result.checks} | set(result.spare)
    return sum(1 for v in result.speeds for a in result.angles if (v, a) not in result.grid and (v, a) not in checked)


def _drop_unfilled(result: AdaptiveResult) -> None:
    """Back to the grid lines whose cases are computed (a split the budget could not pay for): a
    grid line is filled at once or not at all, so the lines to drop are those without a case."""
    speeds = [v for v in result.speeds if any((v, a) in result.grid for a in result.angles)]
    angles = [a for a in result.angles if any((v, a) in result.grid for v in result.speeds)]
    result.speeds, result.angles = speeds, angles
