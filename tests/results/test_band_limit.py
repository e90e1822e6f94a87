"""The zero-phase Gaussian low-pass (results.band_limit) against its exact transfer function."""
import math

import numpy as np
import pytest

from millimpact.results.band_limit import gaussian_low_pass


@pytest.mark.parametrize("ratio, gain", [(1.0, 0.5), (0.25, 2 ** (-1 / 16)), (2.0, 2 ** -4)])
def test_a_sinusoid_is_scaled_by_the_transfer_function(ratio, gain):
    """H(f) = exp(-2 pi^2 sigma^2 f^2) = 2^(-(f / f_half)^2): 1/2 at f_half. Checked away from the
    ends (the kernel is truncated there); the discrete sum over 40 samples per period differs from
    the integral by ~1e-6 (the 4-sigma truncation: exp(-8) of the weight)."""
    f_half = 1e4
    f = ratio * f_half
    t = np.linspace(0.0, 20.0 / f, 801)
    y = np.sin(2 * math.pi * f * t)
    yf = gaussian_low_pass(t, y, f_half)
    mid = slice(200, 601)
    assert np.max(np.abs(yf[mid] - gain * y[mid])) < 2e-3


def test_uneven_grid_and_zero_phase():
    """A constant stays itself on any grid; a symmetric pulse keeps its peak time (zero phase) on a
    grid of two step sizes (the contact and free steps), and its area (the kernel's weights are
    normalised by time, not by sample count)."""
    t = np.concatenate([np.arange(0.0, 50e-6, 2e-6), np.arange(50e-6, 150e-6, 0.5e-6), np.arange(150e-6, 200e-6, 2e-6)])
    assert np.allclose(gaussian_low_pass(t, np.full_like(t, 3.0), 4e4), 3.0, rtol=1e-12)
    y = np.where(np.abs(t - 100e-6) < 40e-6, np.cos(math.pi * (t - 100e-6) / 80e-6) ** 2, 0.0)
    yf = gaussian_low_pass(t, y, 4e4)
    assert t[np.argmax(yf)] == pytest.approx(100e-6, abs=0.5e-6)
    assert np.trapz(yf, t) == pytest.approx(np.trapz(y, t), rel=1e-3)
