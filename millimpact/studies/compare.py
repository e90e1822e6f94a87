"""``millimpact compare REFERENCE OTHER.csv``: score another implementation's histories against a
reference run (``millimpact run --reference``).

For every column the two files share (contact force, contact-point displacement / velocity /
acceleration / stress, gauge stresses, ...) it reports, with y_r(t) the reference on its own time
grid t_r and y_o(t) the other, linearly interpolated:

- peak error: s (P_o - P_r) / |P_r|, where P is the extreme sample of s y (s = +1: the maximum, s = -1:
  the minimum) within the window both series cover; s is set per column by its physics
  (:data:`PEAK_SIGN`: +1 for a force, -1 for the compressive contact stress) or else is the sign
  of the reference's largest |value| there. Positive: the other's peak is stronger;
- time-of-peak error: t_peak,o - t_peak,r (s), each time refined below one sample by the vertex of
  the parabola through the extreme sample and its two neighbours;
- L2 error: sqrt(int (y_o - y_r)^2 dt / int y_r^2 dt) on the reference grid (trapezoidal rule),
  over the part of the reference's span the other covers (the other is never extrapolated);
  ``coverage`` = the share of int y_r^2 dt lying in that part (1.0 when the other spans it all);
- shift tau: the lag maximising the cross-correlation c(tau) = sum_i y_r(g_i) y_o(g_i + tau) on a
  uniform grid g over the reference's span (step: the reference's smallest step; the other taken as
  0 outside its own span), searched over |tau| <= --max-shift, refined below one step by the
  parabola through the best lag and its neighbours. tau > 0: the other lags the reference;
- L2 error after the shift: as above with y_o(t + tau).
"""

from __future__ import annotations

import argparse
import csv
import json
import math
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import TYPE_CHECKING

from ..console import say, world_rank
from ..errors import InputError
from ..results.output_folder import FORCE_HELP, OUT_HELP, claim_output, default_out

if TYPE_CHECKING:  # numpy and the time series are imported where compare computes (`--help` stays fast)
    import numpy as np

    from ..results.timeseries import TimeSeries

HELP = "score another implementation's CSV histories against a reference run (peak, L2, time shift)"

DESCRIPTION = """\
Score OTHER.csv (time_s plus any of contact_force_N, contact_point_displacement_m,
contact_point_velocity_m_s, contact_point_acceleration_m_s2, contact_point_stress_Pa,
gauge_<name>_stress_Pa, ... in SI units; '#' lines are comments) against REFERENCE
(reference.h5 / reference.csv from 'millimpact run --reference', or a run folder).

Per shared column: peak error (relative), time-of-peak error, L2-in-time relative error over
the reference's span (where OTHER covers it), the time shift that best aligns the two
(cross-correlation, sub-step parabolic refinement) and the L2 error after removing it.
Writes DIR/compare.json, DIR/compare.csv and DIR/compare.png (overlaid histories).

  millimpact run hertz-halfspace --reference --out out/ref
  millimpact compare out/ref/reference.h5 my_dem.csv --out out/cmp
"""

#: the largest uniform grid the cross-correlation resamples onto (memory bound: ~16 MB a series)
MAX_GRID = 2**21


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("reference", help="reference.h5 / reference.csv (millimpact run --reference) or a run folder")
    p.add_argument("other", help="the other implementation's CSV: time_s and any of the reference's columns")
    p.add_argument("--out", help=OUT_HELP.format(default="out/compare-OTHER"))
    p.add_argument("--force", action="store_true", help=FORCE_HELP)
    p.add_argument(
        "--time-offset",
        type=float,
        default=0.0,
        metavar="SECONDS",
        help="added to OTHER's time_s before comparing, e.g. the reference's first_contact_s when "
        "OTHER starts at first contact (default 0)",
    )
    p.add_argument(
        "--max-shift",
        type=float,
        metavar="SECONDS",
        help="largest time shift (either sign) searched (default: the reference's contact duration, or a "
        "quarter of its span without a contact force)",
    )
    p.add_argument("--no-plots", action="store_true", help="skip compare.png")


@dataclass(frozen=True)
class Score:
    """The comparison of one history (values in the column's unit, times in s, errors relative)."""

    quantity: str
    unit: str
    peak_reference: float
    peak_other: float
    peak_error: float | None
    time_of_peak_reference_s: float
    time_of_peak_other_s: float
    time_of_peak_error_s: float | None
    l2_error: float | None
    coverage: float
    shift_s: float | None
    shift_at_limit: bool
    l2_error_shifted: float | None


# --- the measures -------------------------------------------------------------------------------
def _vertex(x: np.ndarray, y: np.ndarray, i: int) -> tuple[float, float]:
    """Position and value of the maximum of the parabola through samples i-1, i, i+1 (any spacing);
    the sample itself at an end or when the three points do not bend down."""
    if i <= 0 or i >= len(y) - 1:
        return float(x[i]), float(y[i])
    h1, h2 = x[i] - x[i - 1], x[i + 1] - x[i]
    dm, dp = y[i - 1] - y[i], y[i + 1] - y[i]
    # y = a s^2 + b s + y_i with s = x - x_i through (-h1, dm) and (h2, dp)
    a = (dp * h1 + dm * h2) / (h1 * h2 * (h1 + h2))
    b = (dp * h1 * h1 - dm * h2 * h2) / (h1 * h2 * (h1 + h2))
    if not a < 0:
        return float(x[i]), float(y[i])
    s = min(max(-b / (2 * a), -h1), h2)
    return float(x[i] + s), float(y[i] + b * s + a * s * s)


def peak(t: np.ndarray, y: np.ndarray, sign: float) -> tuple[float, float]:
    """(time, value) of the extremum of ``sign * y`` (sign +1: maximum, -1: minimum): the extreme
    sample's value (never overshoots a staircase such as the contact radius) at the time of the
    vertex of the parabola through that sample and its two neighbours (sub-step, within them);
    on a plateau (neighbours equal to the extreme within 1e-9 of it) the plateau's middle."""
    import numpy as np

    sy = sign * y
    i = int(np.argmax(sy))
    level = sy[i] - 1e-9 * abs(sy[i])
    j0 = j1 = i
    while j0 > 0 and sy[j0 - 1] >= level:
        j0 -= 1
    while j1 + 1 < len(sy) and sy[j1 + 1] >= level:
        j1 += 1
    if j1 > j0:
        return 0.5 * float(t[j0] + t[j1]), float(y[i])
    tp, _ = _vertex(t, sy / abs(sy[i]) if sy[i] != 0 else sy, i)  # the vertex's time: any scale (no overflow)
    return tp, float(y[i])


#: the physical sense of each column's peak (+1 maximum, -1 minimum); others: the sign of the
#: reference's largest |value| in the compared window
#: The contact point's acceleration peaks negative: the deceleration while the ball is pushed back
#: (-share F / m in Hertz, the patch's deceleration in FE runs).
PEAK_SIGN = {
    "contact_force_N": 1.0,
    "approach_m": 1.0,
    "contact_radius_m": 1.0,
    "contact_point_displacement_m": 1.0,
    "contact_point_stress_Pa": -1.0,
    "contact_point_von_mises_Pa": 1.0,
    "strain_energy_J": 1.0,
    "contact_point_acceleration_m_s2": -1.0,
}

#: a reference history varying by less than this share of its largest |value| in the window is
#: "flat" (energies, a constant velocity): it has no time of peak or shift to report
FLAT = 0.01


def l2_error(
    t_r: np.ndarray, y_r: np.ndarray, t_o: np.ndarray, y_o: np.ndarray, shift: float = 0.0
) -> tuple[float | None, float]:
    """Relative L2-in-time error of y_o(t + shift) against y_r(t) on the reference grid, over the
    part of the reference's span where t + shift lies in the other's span; and that part's share
    of int y_r^2 dt (the coverage). The error is None when the reference is zero there.

    Each integral of a square is taken of the values over their largest magnitude, and the
    magnitudes put back outside the square root (values near 1e308 do not overflow)."""
    import numpy as np

    def square_integral(y, t) -> tuple[float, float]:
        """(m, I): int y^2 dt = m^2 I, m the largest |y| (1 for a zero y)."""
        m = float(np.max(np.abs(y))) if len(y) else 0.0
        m = m if m > 0 else 1.0
        return m, float(np.trapz((y / m) ** 2, t))

    mask = (t_r + shift >= t_o[0]) & (t_r + shift <= t_o[-1])
    m_total, total = square_integral(y_r, t_r)
    if mask.sum() < 2:
        return None, 0.0
    tr, yr = t_r[mask], y_r[mask]
    m_den, den = square_integral(yr, tr)
    coverage = den * (m_den / m_total) ** 2 / total if total > 0 else 1.0
    if den <= 0:
        return None, coverage
    m_o = float(np.max(np.abs(y_o))) or 1.0
    yo = np.interp(tr + shift, t_o, y_o / m_o)  # over its largest magnitude (the slopes would overflow)
    big = max(m_o, m_den)
    m_d, num = square_integral(yo * (m_o / big) - yr / big, tr)  # int (y_o - y_r)^2 dt = (big m_d)^2 num
    return big * m_d / m_den * math.sqrt(num / den), coverage


def _corr(o: np.ndarray, r: np.ndarray, j: int) -> float:
    """sum_n o[n + j] r[n], summed exactly rounded (fsum), so that the correlation of identical
    shapes is exactly symmetric about their lag."""
    return math.fsum(o[j : j + len(r)] * r)


def time_shift(
    t_r: np.ndarray, y_r: np.ndarray, t_o: np.ndarray, y_o: np.ndarray, max_shift: float
) -> tuple[float, bool]:
    """The lag tau (s) maximising the cross-correlation of y_r(t) and y_o(t + tau) within
    |tau| <= max_shift, refined below one grid step by a parabola; and whether it hit the limit.

    Both are resampled on one uniform grid (step: the reference's smallest step): the reference
    over its span, the other over that span widened by max_shift on each side, zero outside its
    own span. So a shifted copy of a finite signal correlates as its zero-padded autocorrelation,
    which is symmetric about the true lag.
    """
    import numpy as np
    from scipy.signal import correlate

    span = t_r[-1] - t_r[0]
    dt = max(float(np.min(np.diff(t_r))), span / (MAX_GRID - 1))
    n = int(math.floor(span / dt + 1e-9)) + 1
    kmax = min(int(math.floor(max_shift / dt + 1e-9)), n - 1)
    g = t_r[0] + dt * np.arange(n)
    # each over its largest magnitude: the lag does not depend on the scales, and the interpolation's
    # slopes of values near 1e308 would overflow
    r = np.interp(g, t_r, y_r / (np.max(np.abs(y_r)) or 1.0))
    o = np.interp(
        t_r[0] + dt * np.arange(-kmax, n + kmax), t_o, y_o / (np.max(np.abs(y_o)) or 1.0), left=0.0, right=0.0
    )
    if not np.any(r) or not np.any(o):
        return 0.0, False
    c = correlate(o, r, mode="valid")  # c[j] = sum_n o[n + j] r[n], lag j - kmax
    j = int(np.argmax(c))
    if j == 0 or j == 2 * kmax:
        return (j - kmax) * dt, kmax > 0
    cm, c0, cp = _corr(o, r, j - 1), _corr(o, r, j), _corr(o, r, j + 1)
    denom = cm - 2 * c0 + cp
    delta = 0.5 * (cm - cp) / denom if denom < 0 else 0.0
    return (j - kmax + min(max(delta, -0.5), 0.5)) * dt, False


def score(name: str, t_r: np.ndarray, y_r: np.ndarray, t_o: np.ndarray, y_o: np.ndarray, max_shift: float) -> Score:
    """All measures of one history (see the module docstring)."""
    import numpy as np

    from ..results.timeseries import unit_of

    lo, hi = max(t_r[0], t_o[0]), min(t_r[-1], t_o[-1])
    wr = (t_r >= lo) & (t_r <= hi)
    wo = (t_o >= lo) & (t_o <= hi)
    if not wr.any() or not wo.any():  # the spans barely touch: the nearest samples
        wr = wr | (np.arange(len(t_r)) == int(np.argmin(np.abs(t_r - lo))))
        wo = wo | (np.arange(len(t_o)) == int(np.argmin(np.abs(t_o - lo))))
    yr_w = y_r[wr]
    sign = PEAK_SIGN.get(name, -1.0 if yr_w[int(np.argmax(np.abs(yr_w)))] < 0 else 1.0)
    tp_r, p_r = peak(t_r[wr], yr_w, sign)
    tp_o, p_o = peak(t_o[wo], y_o[wo], sign)
    flat = float(np.ptp(yr_w)) <= FLAT * float(np.max(np.abs(yr_w)))
    l2, coverage = l2_error(t_r, y_r, t_o, y_o)
    if flat:
        dt_peak, shift, at_limit, l2s = None, None, False, None
    else:
        dt_peak = tp_o - tp_r
        shift, at_limit = time_shift(t_r, y_r, t_o, y_o, max_shift)
        l2s, _ = l2_error(t_r, y_r, t_o, y_o, shift)
    # (p_o - p_r) / |p_r| as p_o / |p_r| - sign(p_r): no overflow of the difference near 1e308
    error = sign * (float(p_o) / abs(float(p_r)) - math.copysign(1.0, p_r)) if p_r != 0 else None
    return Score(name, unit_of(name), p_r, p_o, error, tp_r, tp_o, dt_peak, l2, coverage, shift, at_limit, l2s)


def time_unit_hint(ref: TimeSeries, other: TimeSeries) -> str | None:
    """A warning when the other's time span is 100x the reference's or more (or 1/100 or less):
    its time_s is likely in ms or µs (scored as seconds, a pulse 1000x too long leaves the
    reference's window nearly empty: peak -100 %). None otherwise."""
    span_r = float(ref.time[-1] - ref.time[0])
    span_o = float(other.time[-1] - other.time[0])
    if not (span_r > 0 and span_o > 0):
        return None
    ratio = span_o / span_r
    if 1e-2 < ratio < 1e2:
        return None
    likely = {3: " (in ms?)", 6: " (in \u00b5s?)"}.get(round(math.log10(ratio) / 3) * 3, "") if ratio > 1 else ""
    return (
        f"the other's time_s spans {span_o:.3g}, {ratio:.3g}x the reference's {span_r:.3g} s{likely}: "
        "time_s must be in seconds (scale the column, or see --time-offset for a shifted start)"
    )


def default_max_shift(ref: TimeSeries) -> float:
    """The reference's contact duration, or a quarter of its span without a contact force."""
    from ..results.timeseries import contact_metrics

    if "contact_force_N" in ref:
        d = contact_metrics(ref).get("contact_duration_s", 0.0)
        if d > 0:
            return d
    return 0.25 * float(ref.time[-1] - ref.time[0])


def match_columns(ref: TimeSeries, other: TimeSeries) -> tuple[list[str], dict[str, list[str]]]:
    """The columns to score (the reference's order) and the other's columns ignored, by reason."""
    from ..results.reference import is_known_column

    common = [n for n in ref.columns if n != "time_s" and n in other]
    extra = [n for n in other.columns if n != "time_s" and n not in ref]
    ignored = {
        "not in the reference": [n for n in extra if is_known_column(n)],
        "unknown column": [n for n in extra if not is_known_column(n)],
    }
    return common, {k: v for k, v in ignored.items() if v}


def not_modelled(ref: TimeSeries, other: TimeSeries, names: list[str]) -> list[str]:
    """The shared columns the other does not model: identically zero where the reference's are not
    (a model without that quantity writes zeros): flagged, not scored (a "-100 %" peak error there
    says nothing about the model)."""
    import numpy as np

    return [n for n in names if not np.any(other[n]) and np.any(ref[n])]


#: columns whose meaning follows the method's contact-point kinematics (registry.MethodEntry)
KINEMATICS_COLUMNS = ("contact_point_velocity_m_s", "contact_point_acceleration_m_s2")


def method_of(path: Path, meta: dict | None = None) -> str | None:
    """The millimpact method that wrote ``path``: from its metadata (a reference file's), else the
    ``summary.json`` of the run folder that holds it; None for a file from elsewhere."""
    if meta and meta.get("method"):
        return str(meta["method"])
    side = Path(path).parent / "summary.json"
    try:
        return str(json.loads(side.read_text())["method"])
    except (OSError, ValueError, KeyError, TypeError):
        return None


def kinematics_differ(ref_method: str | None, other_method: str | None) -> bool:
    """True when one file's contact-point velocity and acceleration are the FE patch's centre of
    mass and the other's the Hertz surface point (different quantities: not scored)."""
    from ..methods.registry import METHODS

    kind = {m.name: m.contact_point_kinematics for m in METHODS}
    a, b = kind.get(ref_method or ""), kind.get(other_method or "")
    return a is not None and b is not None and a != b


def compare_series(
    ref: TimeSeries, other: TimeSeries, max_shift: float | None = None, skip: tuple[str, ...] = ()
) -> list[Score]:
    """Score every column ``other`` shares with ``ref`` and models (:func:`not_modelled`), except
    those in ``skip``."""
    common, _ = match_columns(ref, other)
    skipped = set(not_modelled(ref, other, common)) | set(skip)
    ms = default_max_shift(ref) if max_shift is None else max_shift
    return [score(n, ref.time, ref[n], other.time, other[n], ms) for n in common if n not in skipped]


# --- output -------------------------------------------------------------------------------------
_FIELDS = [f.name for f in Score.__dataclass_fields__.values()]


def _pct(x: float | None) -> str:
    return "     -" if x is None or not math.isfinite(x) else f"{100 * x:+7.2f}"


def format_table(scores: list[Score]) -> str:
    """The stdout table: peak (reference, other, error), time-of-peak error, L2, shift, L2 shifted."""
    head = (
        f"{'quantity':<34s} {'unit':<6s} {'peak ref':>11s} {'peak other':>11s} {'peak %':>7s} "
        f"{'dt_peak us':>10s} {'L2 %':>7s} {'shift us':>9s} {'L2 sh %':>7s} {'cover':>6s}"
    )
    lines = [head, "-" * len(head)]
    for s in scores:
        l2 = "     -" if s.l2_error is None else f"{100 * s.l2_error:7.2f}"
        l2s = "     -" if s.l2_error_shifted is None else f"{100 * s.l2_error_shifted:7.2f}"
        lim = "*" if s.shift_at_limit else " "
        dtp = f"{'-':>10s}" if s.time_of_peak_error_s is None else f"{1e6 * s.time_of_peak_error_s:10.4g}"
        sh = f"{'-':>8s}" if s.shift_s is None else f"{1e6 * s.shift_s:8.4g}"
        lines.append(
            f"{s.quantity:<34s} {s.unit:<6s} {s.peak_reference:11.4g} {s.peak_other:11.4g} "
            f"{_pct(s.peak_error)} {dtp} {l2} {sh}{lim} {l2s} {s.coverage:6.3f}"
        )
    if any(s.shift_s is None for s in scores):
        lines.append(f"- flat (varies by < {100 * FLAT:g} % of its size): no time of peak or shift")
    if any(s.shift_at_limit for s in scores):
        lines.append("* shift at the search limit (--max-shift): the best alignment may lie beyond it")
    return "\n".join(lines)


def write_csv(scores: list[Score], path: Path) -> None:
    """compare.csv: one row per quantity; times in s, errors relative (0.01 = 1 %)."""
    with open(path, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(_FIELDS)
        for s in scores:
            w.writerow(["" if v is None else (f"{v:.10g}" if isinstance(v, float) else v) for v in asdict(s).values()])


def _title(column: str) -> str:
    """``contact_point_acceleration_m_s2`` -> ``contact point acceleration``."""
    for suffix in ("_m_s2", "_m_s", "_Pa", "_N", "_J", "_m", "_s"):
        if column.endswith(suffix):
            column = column[: -len(suffix)]
            break
    return column.replace("_", " ")


def plot_compare(
    ref: TimeSeries, other: TimeSeries, scores: list[Score], path: Path, ref_label: str, other_label: str
) -> None:
    """One panel per quantity: reference and other overlaid over the span they share, the error
    figures in the legend (:func:`compare_figure`), written to ``path``."""
    import matplotlib.pyplot as plt

    fig = compare_figure(ref, other, scores, ref_label, other_label)
    fig.savefig(path, dpi=110)
    plt.close(fig)


def compare_figure(ref: TimeSeries, other: TimeSeries, scores: list[Score], ref_label: str, other_label: str):
    """The figure of :func:`plot_compare`. Axes follow the run figures' unit rule
    (:func:`millimpact.results.plots.time_unit`, :func:`~millimpact.results.plots.value_unit`: µs
    or ms, kN, MPa, m/s², µm, ... in brackets) and carry no offset or exponent above the axis."""
    from ..results.plots import pyplot

    plt = pyplot()
    import numpy as np

    from ..results.plots import time_unit, value_unit

    n = len(scores)
    ncol = 1 if n == 1 else 2
    nrow = (n + ncol - 1) // ncol
    fig, axes = plt.subplots(nrow, ncol, figsize=(6.4 * ncol, 3.0 * nrow + 0.6), squeeze=False)
    t0 = max(ref.time[0], other.time[0])
    t1 = min(ref.time[-1], other.time[-1])
    if t1 <= t0:
        t0, t1 = ref.time[0], ref.time[-1]
    scale, tunit = time_unit(t1 - t0)
    for ax, s in zip(axes.flat, scores):
        mr = (ref.time >= t0) & (ref.time <= t1)
        mo = (other.time >= t0) & (other.time <= t1)
        shown = np.concatenate([ref[s.quantity][mr], other[s.quantity][mo]])
        vscale, vunit = value_unit(s.quantity, shown[np.isfinite(shown)])
        ax.plot(scale * ref.time[mr], vscale * ref[s.quantity][mr], "k-", lw=1.6, label=f"reference ({ref_label})")

        def fmt(x):
            return "-" if x is None else f"{100 * x:.2f} %"

        ax.plot(
            scale * other.time[mo],
            vscale * other[s.quantity][mo],
            "C3--",
            lw=1.3,
            label=(
                f"{other_label}\npeak {fmt(s.peak_error)}, L2 {fmt(s.l2_error)}"
                + (
                    ""
                    if s.shift_s is None
                    else f"\nshift {scale * s.shift_s:.3g} {tunit}, L2 after shift {fmt(s.l2_error_shifted)}"
                )
            ),
        )
        ax.set_title(_title(s.quantity), fontsize=10)
        ax.set_xlabel(f"time [{tunit}]")
        ax.set_ylabel(f"{_title(s.quantity)} [{vunit}]" if vunit else _title(s.quantity))
        # the units carry the scale: no "1e-5" or "+1.38e4" above an axis (values the SI prefixes
        # cannot bring below 1e6, such as a history of 1e300, keep matplotlib's exponent)
        plain = not len(shown) or float(np.nanmax(np.abs(vscale * shown[np.isfinite(shown)]), initial=0.0)) < 1e6
        ax.ticklabel_format(axis="both", style="plain" if plain else "sci", useOffset=False)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7, loc="best")
    for ax in list(axes.flat)[n:]:
        ax.set_visible(False)
    fig.suptitle(f"{other_label} against the reference {ref_label}", fontsize=11)
    fig.tight_layout(rect=(0, 0, 1, 0.98 if nrow > 2 else 0.94))
    return fig


def main(args: argparse.Namespace) -> int:
    """``millimpact compare``: read, score, print the table, write compare.json/.csv/.png."""
    from ..results.reference import read_history_csv, read_reference
    from ..results.timeseries import jsonable

    other_path = Path(args.other)
    out = args.out if args.out is not None else default_out(other_path.stem, prefix="compare-")
    target = claim_output(out, "compare", force=args.force)  # before reading: a typo costs nothing
    ref = read_reference(Path(args.reference))
    if other_path.is_dir() or not other_path.exists():
        raise InputError(f"other {other_path}: no such file (expected a CSV with a time_s column)")
    other_meta: dict = {}
    if other_path.suffix.lower() in (".h5", ".hdf5"):  # another millimpact reference
        other_ref = read_reference(other_path)
        other, other_meta = other_ref.series, other_ref.meta
    else:
        other = read_history_csv(other_path, "other")
        side = other_path.with_suffix(".json")
        if side.is_file():
            try:
                other_meta = json.loads(side.read_text())
            except (OSError, ValueError):
                other_meta = {}
    if not math.isfinite(args.time_offset):
        raise InputError(f"--time-offset = {args.time_offset}: must be a finite number of seconds")
    if args.time_offset:
        other.columns["time_s"] = other.time + args.time_offset
    if args.max_shift is not None and not (args.max_shift >= 0 and math.isfinite(args.max_shift)):
        raise InputError(f"--max-shift = {args.max_shift}: must be >= 0 seconds")
    common, ignored = match_columns(ref.series, other)
    zero = not_modelled(ref.series, other, common)
    if zero:
        ignored["not modelled by the other: all zero"] = zero
    differ: tuple[str, ...] = ()
    if kinematics_differ(method_of(ref.path, ref.meta), method_of(other_path, other_meta)):
        differ = tuple(n for n in KINEMATICS_COLUMNS if n in common)
        if differ:
            ignored["defined differently: FE centre of mass of the half-ball of radius a_max, Hertz surface point"] = (
                list(differ)
            )
    if not common:
        raise InputError(
            f"other {other_path}: no column in common with the reference (it has "
            f"{', '.join(n for n in ref.series.columns if n != 'time_s')})"
        )
    if other.time[-1] < ref.series.time[0] or other.time[0] > ref.series.time[-1]:
        raise InputError(
            f"other {other_path}: time_s {other.time[0]:g}..{other.time[-1]:g} s does not overlap the "
            f"reference's {ref.series.time[0]:g}..{ref.series.time[-1]:g} s (see --time-offset)"
        )
    max_shift = default_max_shift(ref.series) if args.max_shift is None else args.max_shift
    scores = compare_series(ref.series, other, max_shift, skip=differ)

    say(f"reference {ref.path} ({ref.label}), other {other_path}: {len(common)} histories compared")
    if not ref.is_reference_file:
        say(
            f"warning: {ref.path.name} is a run's time series, not a reference file: scored without the "
            "reference metadata (first contact, Hertz values); 'millimpact run SCENE --reference' writes one"
        )
    say(format_table(scores))
    for reason, names in ignored.items():
        say(f"ignored ({reason}): {', '.join(names)}")
    low = [s.quantity for s in scores if s.coverage < 0.999]
    if low:
        say(
            f"note: the other covers less than 99.9 % of the reference's int y^2 dt for {', '.join(low)}: "
            "their L2 errors are over the covered part only (column 'cover')"
        )
    hint = time_unit_hint(ref.series, other)
    if hint:
        say(f"warning: {hint}")
    if world_rank() != 0:
        return 0
    result = {
        "format": "millimpact-compare",
        "format_version": 1,
        "reference": str(ref.path),
        "reference_scene": ref.meta.get("scene"),
        "reference_method": ref.meta.get("method"),
        "other": str(other_path),
        "time_offset_s": args.time_offset,
        "max_shift_s": max_shift,
        "ignored_columns": ignored,
        "definitions": {
            "peak_error": "s (P_other - P_ref) / |P_ref|; P the extreme sample of s y in the common window, "
            "s = +1 (maximum) or -1 (minimum) by the column's physics or the reference's sign",
            "time_of_peak_error_s": "t_peak,other - t_peak,ref, times parabola-refined; null for a flat history",
            "l2_error": "sqrt(int (y_o - y_r)^2 dt / int y_r^2 dt) on the reference grid where the other covers it",
            "coverage": "share of the reference's int y_r^2 dt inside the other's time span",
            "shift_s": "lag maximising the cross-correlation (other later: positive), parabola-refined",
            "l2_error_shifted": "l2_error of y_o(t + shift_s)",
        },
        "scores": [asdict(s) for s in scores],
    }
    with target.staged(collective=False) as stage:
        (stage / "compare.json").write_text(json.dumps(jsonable(result), indent=2) + "\n")
        write_csv(scores, stage / "compare.csv")
        if not args.no_plots:
            plot_compare(ref.series, other, scores, stage / "compare.png", ref.label, other_path.name)
    say(
        f"results in {target.shown}/ (compare.json, compare.csv{', compare.png' if not args.no_plots else ''})"
        + target.replaced_note()
    )
    return 0
