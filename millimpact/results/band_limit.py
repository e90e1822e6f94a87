"""Band-limiting a sampled history to the frequencies a model resolves (zero phase).

The contact point's velocity and acceleration (:class:`millimpact.results.recorder.Recorder`) carry,
besides the impact's response, content at the time-step scale: the contact zone's mesh modes
(MHz on the rig) that an implicit step of ~1 us can neither resolve nor damp (Newmark's average
acceleration keeps them undamped). That content changes with dt and h and is not physics; the
response below the band the model is built to resolve (f_cut = 4 / t_c, foundations.md section 4)
converges. A Gaussian kernel is used:

    y_f(t_i) = sum_j w_ij y_j dt_j / sum_j w_ij dt_j,   w_ij = exp(-(t_j - t_i)^2 / (2 sigma^2)),

with dt_j the local sample spacing (so uneven grids, the contact and free steps, weigh by time),
truncated at 4 sigma. Its transfer function exp(-2 pi^2 sigma^2 f^2) is real (no phase shift, so
peak times are kept) and has no overshoot (a step stays monotone); it is 1/2 at
f_half = sqrt(ln 2 / 2) / (pi sigma) ~ 0.187 / sigma, so sigma = 0.187 / f_half.

A zero-phase kernel is not causal: it spreads the response sigma-wide backwards in time, before the
impact, where the struck body is at rest (on the rig sigma ~ 0.05 t_c, longer than the flight to
contact: v(0) read 0.29 m/s with F = 0). Samples before ``rest_until`` (the first contact) are
therefore kept as they are, and the motion from the last sample at rest t_r on is filtered as
the odd extension y(t_r - s) = -y(t_r + s): the kernel is symmetric, so the filtered motion is 0
at t_r and rises from rest continuously (keeping the raw zeros before and the plainly filtered
series after made a step of 0.25 of the peak velocity at the first contact).
"""

from __future__ import annotations

import math

import numpy as np

#: sigma f_half of the Gaussian: its transfer function is 1/2 at f_half (module docstring)
SIGMA_TIMES_F_HALF = math.sqrt(math.log(2.0) / 2.0) / math.pi


def gaussian_low_pass(t: np.ndarray, y: np.ndarray, f_half: float, rest_until: float | None = None) -> np.ndarray:
    """``y`` (sampled at increasing times ``t``, s) band-limited by the zero-phase Gaussian whose
    transfer function is 1/2 at ``f_half`` (Hz); the samples before ``rest_until`` (s; the first
    contact, before which the body is at rest) are kept as they are. See the module docstring."""
    t = np.asarray(t, dtype=float)
    y = np.asarray(y, dtype=float)
    if len(t) < 3 or not f_half > 0:
        return y.copy()
    if rest_until is not None and t[0] < rest_until <= t[-1]:
        r = int(np.searchsorted(t, rest_until)) - 1  # the last sample at rest
        ta, ya = t[r:] - t[r], y[r:] - y[r]
        near = ta[1:][ta[1:] <= 4.0 * SIGMA_TIMES_F_HALF / f_half][::-1]
        ext_t = np.concatenate([-near, ta])
        ext_y = np.concatenate([-ya[1 : 1 + len(near)][::-1], ya])
        out = y.copy()  # t_r itself stays as recorded
        out[r + 1 :] = gaussian_low_pass(ext_t, ext_y, f_half)[len(near) + 1 :] + y[r]
        return out
    sigma = SIGMA_TIMES_F_HALF / f_half
    dt = np.gradient(t)
    lo = np.searchsorted(t, t - 4.0 * sigma)
    hi = np.searchsorted(t, t + 4.0 * sigma, side="right")
    out = np.empty_like(y)
    for i in range(len(t)):
        s = slice(lo[i], hi[i])
        w = np.exp(-0.5 * ((t[s] - t[i]) / sigma) ** 2) * dt[s]
        out[i] = float(w @ y[s]) / float(w.sum())
    return out
