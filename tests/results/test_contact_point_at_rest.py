"""The contact point is at rest before the first contact (issue 35, row 20): the zero-phase
band limit (results.band_limit) must not smear the impact back into it (v(0) read 0.29 m/s with
F = 0 on the rig)."""
import math

import numpy as np

from millimpact.results.band_limit import gaussian_low_pass
from millimpact.results.recorder import band_limit_contact_point
from millimpact.results.timeseries import TimeSeries


def impact_series(t0: float = 2e-6, tc: float = 80e-6) -> TimeSeries:
    """A struck point at rest until first contact at ``t0``, then a half-sine velocity over ``tc``
    (a Hertz-like pulse) sampled at t_c / 100, the rig's contact step; the flight to contact is
    shorter than the filter's sigma (0.187 / f_half = 0.047 t_c at f_half = 4 / t_c)."""
    t = np.arange(0.0, 3 * tc, tc / 100)
    on = (t >= t0) & (t <= t0 + tc)
    v = np.where(on, 0.5 * np.sin(math.pi * (t - t0) / tc), 0.0)
    a = np.where(on, 0.5 * math.pi / tc * np.cos(math.pi * (t - t0) / tc), 0.0)
    f = np.where(on, 1e4 * np.clip(np.sin(math.pi * (t - t0) / tc), 0.0, None) ** 1.5, 0.0)
    return TimeSeries({"time_s": t, "contact_force_N": f, "contact_point_velocity_m_s": v,
                       "contact_point_acceleration_m_s2": a})


def test_no_motion_before_the_first_contact():
    ts = impact_series()
    t, f_half = ts.time, 4 / 80e-6
    leaky = gaussian_low_pass(t, ts["contact_point_velocity_m_s"], f_half)
    before = t < t[np.nonzero(ts["contact_force_N"] > 0)[0][0]]
    assert np.max(np.abs(leaky[before])) > 1e-3          # the plain zero-phase filter leaks backwards
    raw = {n: ts[n].copy() for n in ("contact_point_velocity_m_s", "contact_point_acceleration_m_s2")}
    band_limit_contact_point(ts, f_half)
    sigma = 0.187 / f_half
    t1 = t[~before][0]
    for name, y in raw.items():
        assert np.all(ts[name][before] == 0.0), name     # at rest: exactly the recorded zeros
        # past 4 sigma after the first contact the kernel no longer reaches the rest: the plain filter
        far = t > t1 + 4 * sigma
        assert np.allclose(ts[name][far], gaussian_low_pass(t, y, f_half)[far], rtol=0, atol=1e-12 * np.abs(y).max()), name
    # and the motion starts from rest continuously: no step at the first contact larger than the
    # raw pulse's own largest step (0.5 sin sampled at t_c / 100: pi / 100 of its peak); keeping the
    # zeros before and the plainly filtered series after stepped by the leak, 0.25 of the peak on the rig
    v, v_raw = ts["contact_point_velocity_m_s"], raw["contact_point_velocity_m_s"]
    assert np.abs(np.diff(v)).max() <= np.abs(np.diff(v_raw)).max() * 1.0001
