"""The damage map's bins: a mill's impacts grouped by place, position along the arc, normal speed
and angle, so that each bin's response is resolved by one impact computed at its representative.

Speed edges (per place). The bin's response is read at one normal speed, so the restitution must
vary little across the bin. Thornton's e(V) (Thornton 1997, :mod:`millimpact.theory.thornton`)
is the estimate: the edges v_0 < v_1 < ... are placed so that e(v_k) - e(v_k+1) <= ``tolerance``
(0.02 by default) from the yield-onset speed V_y (Thornton 1997, eq. 13) up, and V_y is an edge
itself (the edges above it do not depend on the slowest impact), so no bin holds both sub-yield
impacts (no plastic work) and yielding ones. Below V_y Thornton's e is 1: the sub-yield impacts
form one bin. At high speed e ~ V^(-1/4), so the edges are nearly log-spaced, de/d ln V = -e/4:
a ratio ~exp(0.08 / e) (1.14 at e = 0.6). An elastic liner (no V_y) gets log-spaced edges a
factor ELASTIC_SPEED_RATIO apart.

Angle and arc edges (per place): equal-count (quantile) edges over the place's impacts,
``angle_bins`` and ``arc_bins`` of them. The arc position only moves the impact on the same kind
of surface, and friction is the angle's only effect on the normal response (a frictionless
oblique impact is the normal impact of its normal speed), so both get few bins.

Budget. Only occupied bins are computed. When they exceed ``max_bins``, the angle bins are cut
first, then the arc bins, then the restitution tolerance is widened (x 1.25 at a time); the
choice made and the restitution spread it reaches are reported (:meth:`BinChoice.report`).

Representative (per bin): the root-mean-square normal and tangential speeds of its impacts
(so the bin's representative kinetic energy is its impacts' mean), their angle atan(v_t / v_n),
and the median arc position of its arc bin (all the place's impacts in that arc range: the bins of
an arc bin share one placed scene, hence one mesh).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from ..dem.impacts import PLACES, Impact, impact_column
from ..errors import InputError
from ..theory.thornton import restitution_thornton

#: speed ratio of the bins of an elastic liner (no yield-onset speed): its restitution is ~1 and
#: varies only through the liner's vibration, which grows slowly with speed (Hunter 1957)
ELASTIC_SPEED_RATIO = 2.0
#: the restitution spread a bin may have across its speeds, by default (docs/damage.md)
DEFAULT_TOLERANCE = 0.02


@dataclass(frozen=True)
class Bin:
    """One bin: its place, edges (m, m/s, deg), its impacts (indices into the impact list) and
    its representative impact."""

    index: int
    place: str
    arc_range_m: tuple[float, float]
    normal_speed_range_m_s: tuple[float, float]
    angle_range_deg: tuple[float, float]
    impacts: tuple[int, ...]
    normal_speed_m_s: float  #: RMS normal speed of its impacts
    tangential_speed_m_s: float  #: RMS tangential speed of its impacts
    arc_m: float  #: median arc position of its arc bin's impacts (m)
    below_yield: bool  #: the bin's upper speed edge is at or below V_y

    @property
    def speed_m_s(self) -> float:
        """The representative impact speed |v| = (v_n^2 + v_t^2)^(1/2), m/s."""
        return math.hypot(self.normal_speed_m_s, self.tangential_speed_m_s)

    @property
    def angle_deg(self) -> float:
        """The representative angle from the surface normal, atan(v_t / v_n), deg."""
        return math.degrees(math.atan2(self.tangential_speed_m_s, self.normal_speed_m_s))


@dataclass(frozen=True)
class BinChoice:
    """The bins and how they were chosen."""

    bins: tuple[Bin, ...]
    v_y_m_s: float  #: Thornton's yield-onset speed (inf for an elastic liner)
    tolerance: float  #: the restitution spread asked per bin
    tolerance_used: float  #: the spread the speed edges were built for (>= tolerance on a tight budget)
    widest_spread: float  #: the largest Thornton spread e(lo) - e(hi) over the occupied bins
    angle_bins: int
    arc_bins: int
    max_bins: int
    speed_edges: dict = field(default_factory=dict)  #: place -> edges (m/s)
    notes: tuple[str, ...] = ()

    def report(self) -> dict:
        """The choice as JSON-able data (written to the summary)."""
        return {
            "bins": len(self.bins),
            "max_bins": self.max_bins,
            "yield_onset_speed_m_s": self.v_y_m_s,
            "restitution_tolerance": self.tolerance,
            "restitution_tolerance_used": self.tolerance_used,
            "widest_thornton_restitution_spread": self.widest_spread,
            "angle_bins": self.angle_bins,
            "arc_bins": self.arc_bins,
            "speed_edges_m_s": {p: list(e) for p, e in self.speed_edges.items()},
            "resolved": self.widest_spread <= self.tolerance * (1 + 1e-9),
            "notes": list(self.notes),
        }


def speed_edges(v_lo: float, v_hi: float, v_y: float, tolerance: float) -> list[float]:
    """Normal-speed edges covering [v_lo, v_hi] (m/s): V_y an edge when inside, one bin below it,
    and above it edges where Thornton's e drops by ``tolerance`` (module docstring)."""
    hi = v_hi * (1 + 1e-12) + 1e-300
    if not math.isfinite(v_y):
        ratio = ELASTIC_SPEED_RATIO ** (tolerance / DEFAULT_TOLERANCE)
        n = max(1, math.ceil(math.log(hi / max(v_lo, 1e-300)) / math.log(ratio))) if v_lo > 0 else 1
        return list(np.geomspace(max(v_lo, 1e-12), hi, n + 1)) if v_lo > 0 else [0.0, hi]
    if v_hi <= v_y:
        return [v_lo, hi]
    # anchored at V_y whatever the slowest impact: the bins above V_y do not depend on which
    # sub-yield impacts the log holds (empty bins are not computed)
    edges = [min(v_lo, v_y), v_y] if v_lo < v_y else [v_y]
    cur = v_y
    while cur < hi * (1 - 1e-12):
        target = restitution_thornton(max(cur, v_y), v_y) - tolerance
        if restitution_thornton(hi, v_y) >= target:
            edges.append(hi)
            break
        a, b = math.log(max(cur, v_y)), math.log(hi)
        for _ in range(60):  # bisection on ln V: e is monotone decreasing above V_y
            m = 0.5 * (a + b)
            a, b = (m, b) if restitution_thornton(math.exp(m), v_y) > target else (a, m)
        cur = math.exp(b)
        edges.append(cur)
    return edges


def _quantile_edges(values: np.ndarray, n: int) -> list[float]:
    """At most ``n`` equal-count bins' edges over ``values`` (the last edge just above the largest)."""
    top = float(values.max())
    top = top + max(abs(top), 1.0) * 1e-9
    if n <= 1 or np.ptp(values) == 0:
        return [float(values.min()), top]
    inner = np.unique(np.quantile(values, np.linspace(0, 1, n + 1)[1:-1]))
    inner = [float(q) for q in inner if values.min() < q < top]
    return [float(values.min()), *inner, top]


def _index(values: np.ndarray, edges: Sequence[float]) -> np.ndarray:
    """The bin index of each value (edges[k] <= v < edges[k+1]; the last bin closed)."""
    return np.clip(np.searchsorted(np.asarray(edges), values, side="right") - 1, 0, len(edges) - 2)


def _make_bins(
    impacts: Sequence[Impact],
    v_y: float,
    tolerance: float,
    n_angle: int,
    n_arc: int,
    columns: dict | None = None,
    count_only: bool = False,
) -> tuple[list[Bin], dict, float]:
    """The occupied bins (as arrays: one key per impact, grouped by sorting); ``count_only``: the
    bins' number alone (a list of that many Nones), for the budget's search."""
    c = columns if columns is not None else _columns(impacts)
    vn, vt, ang, arc, place = c["vn"], c["vt"], c["ang"], c["arc"], c["place"]
    bins: list = []
    edges_of: dict = {}
    spread = 0.0
    for p in PLACES:
        sel = np.flatnonzero(place == p)
        if sel.size == 0:
            continue
        se = speed_edges(float(vn[sel].min()), float(vn[sel].max()), v_y, tolerance)
        ae = _quantile_edges(ang[sel], n_angle)
        ce = _quantile_edges(arc[sel], n_arc)
        edges_of[p] = se
        ci, si, ai = _index(arc[sel], ce), _index(vn[sel], se), _index(ang[sel], ae)
        key = (ci * (len(se) - 1) + si) * (len(ae) - 1) + ai  # sorted as (arc, speed, angle)
        keys, first, counts = np.unique(key, return_index=True, return_counts=True)
        if count_only:
            bins += [None] * len(keys)
            continue
        order = np.argsort(key, kind="stable")
        groups = np.split(sel[order], np.cumsum(counts)[:-1])
        # one position per arc bin (its impacts' median), so the bins of an arc bin share a placed scene
        arc_rep = {int(k): float(np.median(arc[sel][ci == k])) for k in np.unique(ci)}
        for j, members in zip(first, groups):
            cj, sj, aj = int(ci[j]), int(si[j]), int(ai[j])
            lo, hi = se[sj], se[sj + 1]
            below = math.isfinite(v_y) and hi <= v_y * (1 + 1e-12)
            if math.isfinite(v_y) and not below:
                spread = max(spread, restitution_thornton(max(lo, v_y), v_y) - restitution_thornton(hi, v_y))
            bins.append(
                Bin(
                    len(bins),
                    p,
                    (ce[cj], ce[cj + 1]),
                    (lo, hi),
                    (ae[aj], ae[aj + 1]),
                    tuple(members.tolist()),
                    float(np.sqrt(np.mean(vn[members] ** 2))),
                    float(np.sqrt(np.mean(vt[members] ** 2))),
                    arc_rep[cj],
                    below,
                )
            )
    return bins, edges_of, spread


def _columns(impacts: Sequence[Impact]) -> dict:
    """The columns the bins are made of: normal and tangential speed, angle, arc position, place."""
    vn = impact_column(impacts, "normal_speed_m_s")
    vt = impact_column(impacts, "tangential_speed_m_s")
    return {
        "vn": vn,
        "vt": vt,
        "ang": np.degrees(np.arctan2(vt, vn)),  # Impact.angle_deg
        "arc": impact_column(impacts, "arc_position_m"),
        "place": impact_column(impacts, "place"),
    }


def choose_bins(
    impacts: Sequence[Impact],
    v_y: float,
    max_bins: int = 30,
    tolerance: float = DEFAULT_TOLERANCE,
    angle_bins: int = 2,
    arc_bins: int = 1,
) -> BinChoice:
    """The bins of ``impacts`` (module docstring); ``v_y`` Thornton's yield-onset speed (m/s, inf
    for an elastic liner). InputError when even the coarsest choice needs more than ``max_bins``."""
    if max_bins < 1:
        raise InputError(f"--max-bins {max_bins}: must be >= 1")
    if not (0 < tolerance < 1):
        raise InputError(f"--restitution-tolerance {tolerance:g}: must lie in (0, 1)")
    notes: list[str] = []
    tol = tolerance
    columns = _columns(impacts)
    for _ in range(60):
        for na in range(angle_bins, 0, -1):
            for nc in range(arc_bins, 0, -1):
                bins, _, _ = _make_bins(impacts, v_y, tol, na, nc, columns, count_only=True)
                if len(bins) <= max_bins:
                    bins, edges, spread = _make_bins(impacts, v_y, tol, na, nc, columns)
                    if na < angle_bins:
                        notes.append(f"angle bins cut from {angle_bins} to {na} to stay within {max_bins} bins")
                    if nc < arc_bins:
                        notes.append(f"arc bins cut from {arc_bins} to {nc} to stay within {max_bins} bins")
                    if tol > tolerance:
                        notes.append(
                            f"restitution tolerance widened from {tolerance:g} to {tol:.3g} to stay "
                            f"within {max_bins} bins"
                        )
                    return BinChoice(tuple(bins), v_y, tolerance, tol, spread, na, nc, max_bins, edges, tuple(notes))
        if tol >= 1.0:
            break
        tol = min(1.0, tol * 1.25)
    raise InputError(
        f"--max-bins {max_bins}: the impacts need at least {len(bins)} bins (one per place and "
        "speed range either side of the yield-onset speed)"
    )


def yield_onset_speed(scene) -> float:
    """Thornton's V_y (m/s) of the scene's ball on its liner: the softer yielding body's initial
    yield stress, the contact modulus E* of the pair and the ball's density (Thornton 1997, eq. 13);
    inf when neither body yields."""
    from ..theory.hertz import effective_modulus
    from ..theory.thornton import yield_onset_velocity

    ys = [m.initial_yield_stress for m in (scene.ball.material, scene.target_material) if m.plastic]
    if not ys:
        return math.inf
    e_star = effective_modulus(scene.ball.material, scene.target_material)
    return yield_onset_velocity(min(ys), e_star, scene.ball.effective_density)


def describe(choice: BinChoice, counts: dict | None = None) -> str:
    """One line saying how the bins were chosen."""
    vy = "none (elastic)" if not math.isfinite(choice.v_y_m_s) else f"{choice.v_y_m_s:.3g} m/s"
    return (
        f"{len(choice.bins)} bins (at most {choice.max_bins}): V_y {vy}; speed edges for a Thornton restitution "
        f"spread <= {choice.tolerance_used:.3g} (widest {choice.widest_spread:.3g}); {choice.angle_bins} angle and "
        f"{choice.arc_bins} arc bin(s) per place"
    )
