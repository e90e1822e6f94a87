"""compare.png follows the run figures' unit rule (issue 35, row 9): time in µs or ms, values with
an SI prefix (kN, µm, MPa, m/s²) in brackets, and no offset or exponent text above an axis."""
import math

import numpy as np

from millimpact.results.plots import time_unit, value_unit
from millimpact.results.timeseries import TimeSeries
from millimpact.studies.compare import compare_figure, compare_series


def pulse_series(scale: float = 1.0) -> TimeSeries:
    """A Hertz-like impact over 300 µs: force ~14 kN, approach ~85 µm, acceleration ~1e5 m/s²,
    and a gauge stress of 200 MPa with a 1 kPa ripple (an axis matplotlib would give an offset)."""
    t = np.linspace(0.0, 300e-6, 601)
    pulse = np.clip(np.sin(math.pi * (t - 50e-6) / 85e-6), 0.0, None) * ((t > 50e-6) & (t < 135e-6))
    return TimeSeries({"time_s": t, "contact_force_N": 13.85e3 * scale * pulse ** 1.5,
                       "approach_m": 85e-6 * scale * pulse,
                       "contact_point_acceleration_m_s2": 1.2e5 * scale * np.cos(math.pi * (t - 50e-6) / 85e-6) * pulse,
                       "gauge_A_stress_Pa": 2e8 + 1e3 * scale * np.sin(2 * math.pi * t / 1e-4)})


def test_compare_axes_follow_the_unit_rule_without_offsets():
    ref, other = pulse_series(), pulse_series(1.02)
    scores = compare_series(ref, other)
    fig = compare_figure(ref, other, scores, "ref", "other")
    fig.canvas.draw()          # offsets are decided when drawn
    labels = {}
    for ax in fig.axes:
        if not ax.get_visible():
            continue
        labels[ax.get_title()] = ax.get_ylabel()
        assert ax.get_xlabel() == f"time [{time_unit(300e-6)[1]}]" == "time [\u00b5s]"
        for axis in (ax.xaxis, ax.yaxis):
            assert axis.get_offset_text().get_text() == "", (ax.get_title(), axis.get_offset_text().get_text())
    assert labels == {"contact force": "contact force [kN]", "approach": "approach [\u00b5m]",
                      "contact point acceleration": "contact point acceleration [km/s\u00b2]",
                      "gauge A stress": "gauge A stress [MPa]"}
    # the plotted values are the scaled ones (kN: ~13.85 at the peak)
    force_ax = next(ax for ax in fig.axes if ax.get_title() == "contact force")
    kilo = value_unit("contact_force_N", ref["contact_force_N"])[0]
    assert kilo == 1e-3 and max(force_ax.lines[0].get_ydata()) == np.max(ref["contact_force_N"]) * kilo
