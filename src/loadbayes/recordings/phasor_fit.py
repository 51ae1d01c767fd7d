"""Phasors by least squares over sliding one-cycle windows, with the decaying DC removed.

Why not the one-cycle DFT of :mod:`~loadbayes.recordings.phasors`: after every voltage
step a motor's (and a line's) current carries a decaying DC offset. The DFT's kernel is
not orthogonal to a decaying exponential, so the offset leaks into the phasor; on
synthetic three-phase recordings of a composite load it put P off by up to 4% of the
load in the cycle after a step, and alone moved a fitted motor share from 0.40 to 0.33.

Method. In each window of one nominal cycle ``T = 1 / f0``, centred at ``c``, every
channel is fitted by least squares with::

    x(t) = sqrt(2) Re{X exp(j (w0 c + w (t - c)))}          fundamental at w = 2 pi f
         + d0 + d1 u + d2 u^2,  u = (t - c) / T             offset and its decay
         + sum_h (a_h cos(h w t) + b_h sin(h w t)),  h = 2..H   harmonics

``X`` is then the RMS phasor at the window's centre in the frame that rotates at the
nominal frequency (the angle convention of the composite fit's ``angle_rad``), at any
sample times (non-uniform stamps need no resampling). The quadratic in ``u`` takes a
decaying exponential to within ``(T/tau)^3 / 48`` of its size over the window
(tau = 20 ms: 2%, 50 ms: 0.1% of the offset); the harmonic columns (up to the 7th, fewer
when the window holds few samples) keep harmonics out of the DC terms. ``w`` is the
segment's frequency, the median of a first pass at ``f0``, so an off-nominal system
(59.98 Hz) does not turn every phasor by ``2 pi (f - f0) t``.

Windows advance by ``T / per_cycle``: with ``per_cycle > 1`` neighbouring estimates share
samples, so their noise is correlated (two windows overlapping by a fraction ``r`` of a
cycle have noise correlation about ``r`` for white noise), which a likelihood that
treats them as independent must allow for.

A window that straddles a step fits badly: its residual (RMS of the misfit over the RMS
of the signal, the worst voltage channel) is returned, so that such samples can be left
out or flagged.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["PhasorFit", "fit_phasors", "max_harmonic"]

#: Highest harmonic modelled in a window (fewer when the window holds few samples).
HARMONICS = 7


@dataclass(frozen=True)
class PhasorFit:
    """Phasors of several channels at the window centres.

    Parameters
    ----------
    t_s : numpy.ndarray
        Window centres (s), shape (m,).
    x : numpy.ndarray
        Complex RMS phasors, shape (channels, m), in the nominal-frequency frame.
    residual : numpy.ndarray
        Relative RMS misfit per channel and window, shape (channels, m).
    f_hz : float
        The frequency the fundamental was fitted at.
    """

    t_s: np.ndarray
    x: np.ndarray
    residual: np.ndarray
    f_hz: float


def max_harmonic(samples: int) -> int:
    """Highest harmonic a window of ``samples`` points can carry beside 5 other columns."""
    return max(1, min(HARMONICS, (samples - 8) // 2 + 1))


def _centres(t: np.ndarray, period: float, per_cycle: int) -> np.ndarray:
    first, last = t[0] + 0.5 * period, t[-1] - 0.5 * period
    if last < first - 1e-12 * period:
        return np.empty(0)
    hop = period / per_cycle
    return first + hop * np.arange(int(np.floor((last - first) / hop + 1e-9)) + 1)


def _one_pass(t, x, centres, period, w, w0, dc, skew):
    k = x.shape[0]
    out = np.empty((k, centres.size), dtype=complex)
    res = np.empty((k, centres.size))
    dt = np.median(np.diff(t))
    for j, c in enumerate(centres):
        lo = np.searchsorted(t, c - 0.5 * period - 1e-6 * dt)
        hi = np.searchsorted(t, c + 0.5 * period - 1e-6 * dt)
        tt, xx = t[lo:hi], x[:, lo:hi]
        m = tt.size
        phase = w0 * c + w * (tt - c)
        cols = [np.cos(phase), np.sin(phase)]
        if dc:
            u = (tt - c) / period
            cols += [np.ones(m), u, u * u]
        for h in range(2, max_harmonic(m) + 1):
            cols += [np.cos(h * w * tt), np.sin(h * w * tt)]
        a = np.column_stack(cols)
        coef, *_ = np.linalg.lstsq(a, xx.T, rcond=None)
        fit = a @ coef
        rms = np.sqrt(np.mean(xx * xx, axis=1))
        with np.errstate(invalid="ignore", divide="ignore"):
            res[:, j] = np.sqrt(np.mean((xx - fit.T) ** 2, axis=1)) / rms
        # x = sqrt(2) Re{X e^{j phase}} = sqrt(2) (Re X cos - Im X sin)
        out[:, j] = (coef[0] - 1j * coef[1]) / np.sqrt(2.0)
    if skew is not None:
        out *= np.exp(-1j * w0 * np.asarray(skew, dtype=float))[:, None]
    return out, np.nan_to_num(res, nan=0.0)


def fit_phasors(
    t_s: np.ndarray,
    x: np.ndarray,
    *,
    f0: float,
    per_cycle: int = 1,
    dc: bool = True,
    skew_s: np.ndarray | None = None,
    reference: int = 0,
) -> PhasorFit:
    """RMS phasors of every channel over sliding one-cycle windows.

    Parameters
    ----------
    t_s : numpy.ndarray
        Sample times (s), increasing (not necessarily evenly spaced), shape (n,).
    x : numpy.ndarray
        Waveforms, shape (channels, n).
    f0 : float
        Nominal frequency (Hz).
    per_cycle : int, default 1
        Estimates per nominal cycle (windows advance by ``1 / (f0 per_cycle)``).
    dc : bool, default True
        Fit and remove an offset with a quadratic decay in each window.
    skew_s : numpy.ndarray, optional
        Per-channel time skews (s): channel k was sampled ``skew_s[k]`` after the stamp.
    reference : int, default 0
        Channel whose phasor's turn gives the segment's frequency.

    Returns
    -------
    PhasorFit

    Raises
    ------
    ValueError
        If the samples are sparser than 8 per nominal cycle, the record is shorter than
        one cycle, or ``per_cycle`` < 1.
    """
    t = np.asarray(t_s, dtype=float)
    x = np.atleast_2d(np.asarray(x, dtype=float))
    if per_cycle < 1:
        raise ValueError(f"per_cycle must be >= 1, got {per_cycle}")
    if x.shape[-1] != t.size:
        raise ValueError(f"x has {x.shape[-1]} samples, t_s {t.size}")
    period = 1.0 / f0
    if t.size < 2 or np.max(np.diff(t)) * f0 > 1 / 8 + 1e-9:
        raise ValueError(f"fewer than 8 samples per {f0:g} Hz cycle: too sparse for phasors")
    centres = _centres(t, period, per_cycle)
    if centres.size == 0:
        raise ValueError(f"the record is shorter than one {f0:g} Hz cycle")
    w0 = 2.0 * np.pi * f0
    first, res_first = _one_pass(t, x, centres, period, w0, w0, dc, None)
    w = w0
    if centres.size >= 3:
        turn = np.angle(first[reference, 1:] * np.conj(first[reference, :-1]))
        f_est = f0 + turn / (2.0 * np.pi * np.diff(centres))
        f_med = float(np.median(f_est))
        if abs(f_med - f0) < 0.05 * f0:  # a plausible system frequency
            w = 2.0 * np.pi * f_med
    if w == w0 and skew_s is None:
        return PhasorFit(centres, first, res_first, f0)
    out, res = _one_pass(t, x, centres, period, w, w0, dc, skew_s)
    return PhasorFit(centres, out, res, w / (2.0 * np.pi))
