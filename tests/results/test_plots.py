"""Figure units (issue 18): chosen by the data's span so ticks read 0.1-1000, the same rule in every
figure; no duplicate gauge panel on a short run."""
from __future__ import annotations

import numpy as np
import pytest

from millimpact.results import plots
from millimpact.results.timeseries import TimeSeries


@pytest.mark.parametrize("span, unit", [(90e-6, "\u00b5s"), (0.9e-3, "\u00b5s"), (2e-3, "ms"), (0.04, "ms"), (3.0, "s")])
def test_time_unit_by_span(span, unit):
    factor, u = plots.time_unit(span)
    assert u == unit and 0.1 <= span * factor < 1000


@pytest.mark.parametrize("column, peak, unit", [("contact_force_N", 13.4e3, "kN"), ("contact_force_N", 657e3, "kN"),
                                                ("contact_point_displacement_m", 8.9e-5, "\u00b5m"),
                                                ("contact_point_stress_Pa", 4.9e9, "GPa"), ("gauge_A_stress_Pa", 2.4e7, "MPa"),
                                                ("contact_point_acceleration_m_s2", 1.1e6, "Mm/s\u00b2"),
                                                ("total_energy_J", 0.79, "mJ")])
def test_value_unit_by_magnitude(column, peak, unit):
    factor, u = plots.value_unit(column, np.array([0.0, -peak, 0.5 * peak]))
    assert u == unit and 1 <= peak * factor < 1000


def _series(t_end):
    t = np.linspace(0.0, t_end, 2001)
    f = np.where((t > 1e-5) & (t < 1e-4), 1e4 * np.sin(np.pi * (t - 1e-5) / 9e-5), 0.0)
    return TimeSeries({"time_s": t, "contact_force_N": f, "gauge_A_stress_Pa": 1e7 * np.sin(2e4 * t)})


def test_gauge_figure_has_one_panel_on_a_short_run(tmp_path, monkeypatch):
    plt = plots.pyplot()
    made, orig = [], plt.subplots

    def subplots(*a, **k):
        made.append(a[:2])
        return orig(*a, **k)

    monkeypatch.setattr(plt, "subplots", subplots)
    assert plots.plot_gauges(_series(2e-4), tmp_path / "short.png")   # impact window ~ the whole run
    assert plots.plot_gauges(_series(4e-2), tmp_path / "long.png")    # 40 ms of ringing: two panels
    assert made == [(1, 1), (1, 2)]
