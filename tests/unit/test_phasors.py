"""One-cycle DFT phasors on synthetic waveforms with a known answer."""

import math

import numpy as np
import pytest

from loadbayes.recordings.phasors import cycle_phasors, samples_per_cycle
from loadbayes.recordings.synth import zip_waveforms

FS = 3200.0  # 64 samples per 50 Hz cycle
VB = 230e3 / math.sqrt(3)
SB = 100e6
COEFS = (0.3, 0.2, 0.5, 0.6, 0.1, 0.3)


def _truth(x, p0=1.0, q0=0.4):
    a1, a2, a3, a4, a5, a6 = COEFS
    return p0 * (a1 * x**2 + a2 * x + a3), q0 * (a4 * x**2 + a5 * x + a6)


def _steady(f_hz, harmonics=(), v_pu=0.93, seconds=1.0):
    t = np.arange(int(seconds * FS)) / FS
    v, i = zip_waveforms(t, np.full(t.size, v_pu), COEFS, f_hz=f_hz, harmonics=harmonics)
    return cycle_phasors(t, v, i, f0=50.0, rate_hz=FS)


def test_nominal_frequency_with_harmonics_is_exact():
    c = _steady(50.0, harmonics=[(3, 0.05), (5, 0.05), (7, 0.03)])
    p, q = _truth(0.93)
    # Integer harmonics sit on the DFT's nulls at f0: only rounding is left.
    np.testing.assert_allclose(c["v"] / VB, 0.93, rtol=1e-12)
    np.testing.assert_allclose(c["p"] / SB, p, rtol=1e-11)
    np.testing.assert_allclose(c["q"] / SB, q, rtol=1e-11)
    np.testing.assert_allclose(c["f"], 50.0, atol=1e-9)


@pytest.mark.parametrize("f_hz", [49.5, 50.5])
def test_off_nominal_frequency_clean(f_hz):
    c = _steady(f_hz)
    p, q = _truth(0.93)
    # Balanced set: the leaked halves cancel in V1 and in sum V conj(I); the gain G is
    # divided out, and so is the |H|^2 conj(S) the leaked halves add to the power.
    np.testing.assert_allclose(c["v"] / VB, 0.93, rtol=1e-10)
    np.testing.assert_allclose(c["p"] / SB, p, atol=1e-10)
    np.testing.assert_allclose(c["q"] / SB, q, atol=1e-10)
    np.testing.assert_allclose(c["f"], f_hz, atol=1e-9)


@pytest.mark.parametrize("f_hz", [49.5, 50.5])
def test_off_nominal_frequency_with_harmonics_stated_accuracy(f_hz):
    c = _steady(f_hz, harmonics=[(5, 0.05), (7, 0.03)])
    p, q = _truth(0.93)
    s = math.hypot(p, q)
    # The accuracy stated in the phasors module docstring: off-nominal harmonics leak.
    assert np.max(np.abs(c["v"] / VB / 0.93 - 1)) < 1e-3
    assert np.max(np.abs(c["p"] / SB - p)) < 1e-3 * s
    assert np.max(np.abs(c["q"] / SB - q)) < 1e-3 * s
    assert np.max(np.abs(c["f"] - f_hz)) < 1e-3


def test_frequency_ramp_is_tracked():
    t = np.arange(int(2.0 * FS)) / FS
    f = 50.0 - 0.5 * t  # ROCOF -0.5 Hz/s
    v, i = zip_waveforms(t, np.ones(t.size), COEFS, f_hz=f)
    c = cycle_phasors(t, v, i, f0=50.0, rate_hz=FS)
    # Reported at the window centre; the first window takes its neighbour's estimate.
    true_f = np.interp(c["t_s"], t, f)
    assert np.max(np.abs(c["f"][1:-1] - true_f[1:-1])) < 1e-4


def test_sag_and_power_follow_the_voltage():
    t = np.arange(int(1.0 * FS)) / FS
    x = np.where((t > 0.3) & (t < 0.6), 0.7, 1.0)
    v, i = zip_waveforms(t, x, COEFS, f_hz=50.0)
    c = cycle_phasors(t, v, i, f0=50.0, rate_hz=FS)
    # Windows wholly inside the sag (cycles 16..28) see exactly the sag.
    inside = (c["t_s"] > 0.32) & (c["t_s"] < 0.58)
    p, q = _truth(0.7)
    np.testing.assert_allclose(c["v"][inside] / VB, 0.7, rtol=1e-12)
    np.testing.assert_allclose(c["p"][inside] / SB, p, rtol=1e-10)
    np.testing.assert_allclose(c["q"][inside] / SB, q, rtol=1e-10)


def test_bad_rates_and_shapes():
    with pytest.raises(ValueError, match="whole multiple"):
        samples_per_cycle(1000.0, 60.0)
    with pytest.raises(ValueError, match="whole multiple"):
        samples_per_cycle(200.0, 50.0)
    assert samples_per_cycle(3840.0, 60.0) == 64
    t = np.arange(10) / FS
    with pytest.raises(ValueError, match="shaped"):
        cycle_phasors(t, np.zeros((3, 9)), np.zeros((3, 9)), f0=50.0, rate_hz=FS)
    with pytest.raises(ValueError, match="at least 2"):
        cycle_phasors(t, np.zeros((3, 10)), np.zeros((3, 10)), f0=50.0, rate_hz=FS)
