"""Adaptive contact tables: the cases a DEM law needs, chosen by the law's own interpolation error.

A DEM code reads the table's law by bilinear interpolation in (ln speed, angle) over a grid of
speeds x angles, held at the nearest edge outside it (the Yade export's runtime,
:mod:`millimpact.dem.export.contact_law`). A grid fixed in advance computes cases the law does not
need and says nothing about the error between them. Here the grid grows where the law is wrong:

1. Start from ``start`` speeds (geometric between the range's ends) x ``start`` angles (linear).
2. Predict each cell's interpolation error from the grid's second differences around it: the
   error of linear interpolation at a cell's midpoint is |f''| h^2 / 8 along each direction, and
   (f_{i-1} - 2 f_i + f_{i+1}) / h^2 estimates f'' (in ln speed and in angle), so each cell gets
   the largest |second difference| / 4 of its edges' grid lines in each direction.
3. Compute the check case at the centre of the cells whose prediction is largest (a batch at a
   time, so that every rank has a case), and compare it with the law's bilinear value there:
   |e_n - law|, |e_t - law| against ``tolerance`` and |F_max / law - 1| against 2 ``tolerance``.
4. A cell that misses is split: a new speed (the geometric mean of its two) where its predicted
   error along speed is the larger, else a new angle (the mean); the new grid line's cases are
   computed, and the new cells are checked in turn. A cell that meets the tolerance is not
   checked again; the cells a split makes from a cell that met it inherit its check.
5. Stop when every cell has met the tolerance, or when the next batch would pass ``max_cases``
   (said, with the largest error checked).

Every case is one impact of the table engine (:mod:`millimpact.studies.table`), so the engine's
bands, reductions and case cache serve the grid and the checks alike; :func:`adaptive_table`
takes the engine as a ``compute`` function of a list of (speed, angle) points.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np

#: the quantities a law carries, and whether their error is absolute (e_n, e_t) or relative (F_max)
QUANTITIES = (("e_n", False), ("e_t", False), ("f_max", True))

Point = tuple[float, float]
Values = dict[str, float]


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

    @property
    def cases(self) -> int:
        return len(self.grid) + len(self.checks)

    def largest_error(self) -> Values:
        """The largest error of each quantity over the checks (0 without checks)."""
        return {q: max((c.errors[q] for c in self.checks), default=0.0) for q, _ in QUANTITIES}


def interpolate(
    speeds: Sequence[float], angles: Sequence[float], grid: dict[Point, Values], v: float, a: float
) -> Values:
    """The law's value at (v, a): bilinear in (ln speed, angle), held at the nearest edge outside."""
    out = {}
    lv = np.log(speeds)
    x = float(np.clip(math.log(v), lv[0], lv[-1]))
    y = float(np.clip(a, angles[0], angles[-1]))
    i = int(np.clip(np.searchsorted(lv, x) - 1, 0, max(len(speeds) - 2, 0)))
    j = int(np.clip(np.searchsorted(angles, y) - 1, 0, max(len(angles) - 2, 0)))
    i1, j1 = min(i + 1, len(speeds) - 1), min(j + 1, len(angles) - 1)
    tx = 0.0 if i1 == i else (x - lv[i]) / (lv[i1] - lv[i])
    ty = 0.0 if j1 == j else (y - angles[j]) / (angles[j1] - angles[j])
    for q, _ in QUANTITIES:
        f = [[grid[(speeds[ii], angles[jj])][q] for jj in (j, j1)] for ii in (i, i1)]
        out[q] = (1 - tx) * ((1 - ty) * f[0][0] + ty * f[0][1]) + tx * ((1 - ty) * f[1][0] + ty * f[1][1])
    return out


def _errors(values: Values, law: Values) -> Values:
    return {q: abs(values[q] / law[q] - 1.0) if rel and law[q] else abs(values[q] - law[q]) for q, rel in QUANTITIES}


def _passes(errors: Values, tolerance: float) -> bool:
    return all(errors[q] <= (2.0 * tolerance if rel else tolerance) for q, rel in QUANTITIES)


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

    def scale(q: str, rel: bool, value: float) -> float:
        return value / (2.0 * tolerance) if not rel else math.log(max(value, 1e-300)) / (2.0 * tolerance)

    along_v = np.zeros((len(sv), len(sa)))
    along_a = np.zeros((len(sv), len(sa)))
    for q, rel in QUANTITIES:
        table = np.array([[scale(q, rel, g[(v, a)][q]) for a in sa] for v in sv])
        for j in range(len(sa)):
            d = _scaled_second_differences(lv, table[:, j].__getitem__)
            along_v[:, j] = np.maximum(along_v[:, j], d)
        for i in range(len(sv)):
            d = _scaled_second_differences(sa, table[i, :].__getitem__)
            along_a[i, :] = np.maximum(along_a[i, :], d)
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
    start: int = 3,
    batch: int = 2,
    say: Callable[[str], None] = lambda s: None,
) -> AdaptiveResult:
    """Choose the table's cases (the module docstring); ``compute(points)`` returns each point's
    e_n, e_t and f_max."""
    v0, v1 = speed_range
    a0, a1 = angle_range
    speeds = [float(x) for x in np.geomspace(v0, v1, start)]
    angles = [float(x) for x in np.linspace(a0, a1, start)] if a1 > a0 else [float(a0)]
    result = AdaptiveResult(speeds, angles, {})
    passed: set[tuple[Point, Point]] = set()

    def fill_grid() -> None:
        todo = [(v, a) for v in result.speeds for a in result.angles if (v, a) not in result.grid]
        if todo:
            result.grid.update(compute(todo))

    fill_grid()
    while True:
        cells = _open_cells(result, passed, tolerance)
        if not cells:
            result.reached = True
            return result
        pick = cells[:batch]
        if result.cases + len(pick) > max_cases:
            result.stopped_by_budget = True
            return result
        centres = [_centre(c) for _, c, _ in pick]
        values = compute(centres)
        laws = [interpolate(result.speeds, result.angles, result.grid, *p) for p in centres]  # before any split
        split = False
        for (_, cell, (ev, ea)), p, law in zip(pick, centres, laws):
            errors = _errors(values[p], law)
            ok = _passes(errors, tolerance)
            result.checks.append(Check(p, cell, values[p], law, errors, ok))
            if ok:
                passed.add(cell)
            else:
                split = _split(result, cell, ev, ea) or split
        say(
            f"  adaptive: {len(result.speeds)} x {len(result.angles)} grid, {len(result.checks)} checks, "
            f"largest error {max(result.largest_error().values()):.3g}"
        )
        if split:
            if len(result.grid) + len(result.checks) + _new_cases(result) > max_cases:
                result.stopped_by_budget = True
                _drop_unfilled(result)
                return result
            fill_grid()


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
    return sum(1 for v in result.speeds for a in result.angles if (v, a) not in result.grid)


def _drop_unfilled(result: AdaptiveResult) -> None:
    """Back to the grid lines whose cases are computed (a split the budget could not pay for)."""
    result.speeds = [v for v in result.speeds if all((v, a) in result.grid for a in result.angles)]
    result.angles = [a for a in result.angles if all((v, a) in result.grid for v in result.speeds)]
