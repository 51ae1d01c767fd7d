"""Phasors by least squares over sliding one-cycle windows, with the decaying DC removed.

Why not the one-cycle DFT of :mod:`~loadbayes.recordings.phasors`: after every voltage
step a motor's (and a line's) current carries a decaying DC offset. The DFT's kernel is
not orthogonal to a decaying exponential, so the offset leaks into the phasor; on
synthetic three-phase recordings of a composite load it put P off by up to 4% of the
load in the cycle after a step, and alone moved a fitted motor share from 0.40 to 0.33.

Method. In each window of one nominal cycle ``T = 1 / f0``, centred at ``c``, every
channel is fitted by least squares with::

    x(t) = sqrt(2) Re{X exp(j (w0 c + w (t - c)))}          fundamental at w = 2 pi f
         + d0 + sum_h (a_h cos(h w t) + b_h sin(h w t)),  h = 2..H   offset, harmonics

``X`` is the RMS phasor at the window's centre in the frame that rotates at the nominal
frequency (the angle convention of the composite fit's ``angle_rad``), at any sample
times (non-uniform stamps need no resampling). On whole cycles of evenly spaced samples
at ``f0`` this is the one-cycle DFT exactly (the offset and the harmonics are orthogonal
to the fundamental). ``w`` is the segment's frequency, the median of a first pass at
``f0``, so an off-nominal system (59.98 Hz) does not turn every phasor by
``2 pi (f - f0) t``.

A decaying offset is not orthogonal to the fundamental over one cycle; nor, with
harmonics present, can it be fitted there without a large cost: a ramp over one cycle is
almost in the span of the harmonics' sines (its Fourier series), so decay columns in the
window multiply the phasor's noise by 10-30 (measured: 1% white noise, 5% third and 3%
fifth harmonic). The estimator therefore tests each channel's window for a decaying
offset over the window's cycle and the next (an F-test of an offset ramp and curvature,
false-alarm rate :data:`DECAY_ALPHA`: :mod:`~loadbayes.recordings.phasor_offset`) and,
where one is found, fits the offset over those two cycles: in a three-phase set's space
vector, a non-rotating exponential ``D exp(-t / tau)`` (``tau`` the best of 0.5, 1, 2,
4 and 8 cycles) beside a positive-sequence phasor that moves (a quadratic in
``t``), a constant negative sequence and the harmonics. Over two cycles the harmonics
repeat and the offset does not, and the phasor turns while the offset stands still, so
the three are told apart at little cost (measured: the cleaned rows' noise is the plain
rows'). The time constant is the one that explains the most over the run of windows
the offset is found in. The offset is taken out of the window's samples and the row is the
plain fit of what is left: a moving phasor stays its one-cycle window mean. The offset
found right after a step is followed into the next windows while a test of the same
model (without the fast exponentials of the detection's null) still finds it.

Before, a found offset sent the window through a *mimic filter* (``y = x + tau
dx/dt``), which ``--dc on`` still applies to every window. On a moving phasor ``X(t)``
the filter returns ``X + tau X' / (1 + j w tau)``, about ``X' / (j w)`` off: after a
sag a motor's current recovers (``T' X' / X``, tens of ms) and the filter turned that
into P errors of 9-26 noise sd in the three rows after each step of issue 35's
recorder chain (tests/integration/test_recorder_chain.py), and the fitted motor's
``T'`` to a quarter of the truth. Measured there now: those rows within 3 noise sd.

Windows advance by ``T / per_cycle``: with ``per_cycle > 1`` neighbouring estimates share
samples, so their noise is correlated (two windows overlapping by a fraction ``r`` of a
cycle have noise correlation about ``r`` for white noise), which a likelihood that
treats them as independent must allow for.

The offset's test and estimate are in :mod:`~loadbayes.recordings.phasor_offset`.
A window that straddles a step fits badly: its residual (RMS of the misfit over the RMS
of the signal, the worst voltage channel) is returned, so that such samples can be left
out or flagged.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from loadbayes.recordings.phasor_offset import (
    DECAY_ALPHA,
    DECAY_MIN_SHARE,
    OFFSET_CYCLES,
    STEP_LIMIT,
    lstsq,
    max_harmonic,
    offset_test,
)

__all__ = ["DECAY_ALPHA", "PhasorFit", "fit_phasors", "max_harmonic"]

#: Change of a voltage channel's phasor between its window's two half cycles, relative to
#: the window's phasor, above which the window straddles a step. A fault's inception near
#: a voltage zero crossing steps the amplitude where the waveform itself is continuous:
#: the constant and the even harmonics of the plain fit take up the change (misfit under
#: 1%), yet the phasor is the mean of both levels (P 10% of P0 off the nearer one on a
#: phase-to-ground fault of 40%). Odd harmonics are half-wave symmetric, so they leave
#: the two half-cycle phasors equal; a steady voltage's even harmonics (about 1%) and a
#: 0.5% noise keep the change well under this limit (the step to be caught is ~0.4).
HALF_STEP_LIMIT = 0.03


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
    decay : numpy.ndarray
        Where a decaying offset was found and taken out (``dc="auto"``) or the mimic
        filter used (``dc="on"``), shape (channels, m).
    share : numpy.ndarray
        The fundamental's share of the window's mean square, shape (channels, m): about 1
        for a waveform, about 0 for samples that are not one (magnitudes).
    half_step : numpy.ndarray
        Where a voltage channel (the first ``step_channels``) changes between the
        window's two half cycles by more than :data:`HALF_STEP_LIMIT`, shape (m,): a step
        inside the window that the plain fit's misfit does not show.
    """

    t_s: np.ndarray
    x: np.ndarray
    residual: np.ndarray
    f_hz: float
    decay: np.ndarray
    share: np.ndarray
    half_step: np.ndarray | None = None


def _centres(t: np.ndarray, period: float, per_cycle: int) -> np.ndarray:
    # A window of one cycle holds the samples in [c - T/2, c + T/2): the last sample
    # stands for the interval up to the next one, so the last whole window ends one
    # sample step after it (as the one-cycle DFT's last whole cycle does).
    step = float(np.median(np.diff(t)))
    first, last = t[0] + 0.5 * period, t[-1] + step - 0.5 * period
    if last < first - 1e-12 * period:
        return np.empty(0)
    hop = period / per_cycle
    count = np.floor((last - first) / hop + 1e-9) + 1
    # Bounded by the samples before allocating (red-team H1): with at least 8 samples
    # per cycle (checked first) there are at most per_cycle windows per 8 samples.
    if not count <= per_cycle * (t.size / 4 + 2):
        raise ValueError(
            f"{count:.3g} windows for {t.size} samples: the sample times are implausible"
        )
    return first + hop * np.arange(int(count))


def _mimic(t: np.ndarray, x: np.ndarray, tau: float, w0: float) -> tuple[np.ndarray, complex]:
    """The mimic filter and its gain at the fundamental (divided out of the phasor).

    ``y[n] = (1 + k) x[n] - k x[n-1]``, ``k = tau / dt``: a decaying offset of time
    constant ``tau`` is removed exactly, others mostly.
    """
    dt = np.diff(t)
    k = tau / dt
    y = np.empty_like(x)
    y[:, 1:] = (1.0 + k) * x[:, 1:] - k * x[:, :-1]
    y[:, 0] = y[:, 1]
    kd = tau / float(np.median(dt))
    return y, complex((1.0 + kd) - kd * np.exp(-1j * w0 * float(np.median(dt))))


def _one_pass(t, x, centres, period, w, w0, dc, skew, tau, steps=0, sets=(), progress=None):
    """Phasors of every window, windows with the same sample offsets fitted together.

    Each window's columns are written in the time ``u = t - c`` from its centre: the
    harmonics' span is the same as in absolute time, and the fundamental's coefficients
    are those of ``cos(w0 c + w u)`` turned by ``w0 c``. Evenly spaced samples give every
    window the same offsets, so one pseudo-inverse serves all of them (a recorder's own
    time stamps may give each window its own: then each is its own group).
    """
    k = x.shape[0]
    out = np.empty((k, centres.size), dtype=complex)
    res = np.empty((k, centres.size))
    share = np.empty((k, centres.size))
    decay = np.zeros((k, centres.size), dtype=bool)
    halves = np.zeros(centres.size, dtype=bool)
    dt = np.median(np.diff(t))
    if dc == "on":
        y, gain = _mimic(t, x, tau, w)
    los = np.searchsorted(t, centres - 0.5 * period - 1e-6 * dt)
    his = np.searchsorted(t, centres + 0.5 * period - 1e-6 * dt)
    # The decay test reads the window's cycle and the one after it: windows are grouped
    # by the offsets of both, whatever ``dc`` (so every setting fits a window in the same
    # group, and a window read without the filter is the same to the last bit).
    his2 = np.searchsorted(t, centres + 1.5 * period - 1e-6 * dt)
    groups: dict[tuple, list[int]] = {}
    for j in range(centres.size):
        u = t[los[j] : his2[j]] - centres[j]
        key = (int(his[j] - los[j]), np.round(u / dt, 6).tobytes())
        groups.setdefault(key, []).append(j)
    if dc == "auto":  # filled per window, resolved in time order after the loop
        taus = len(OFFSET_CYCLES)
        clean = np.zeros((*out.shape, taus), dtype=complex)
        first = np.zeros_like(decay)
        then = np.zeros((*decay.shape, taus), dtype=bool)
        choice = np.zeros(decay.shape, dtype=int)
        scores = np.zeros(then.shape)
        rss_off = np.zeros_like(res)
        stepped = np.zeros_like(halves)
    mean_sq = np.empty_like(res)
    sum_sq = np.empty_like(res)
    for js in groups.values():
        js = np.asarray(js)
        if progress is not None:
            progress(int(js.size))
        lo = los[js]
        m = int(his[js[0]] - lo[0])
        idx = lo[:, None] + np.arange(m)
        u = t[idx[0]] - centres[js[0]]
        cols = [np.cos(w * u), np.sin(w * u), np.ones(m)]
        for h in range(2, max_harmonic(m) + 1):
            cols += [np.cos(h * w * u), np.sin(h * w * u)]
        a = np.column_stack(cols)
        xx = x[:, idx]  # (k, g, m)
        ssq = np.sum(xx * xx, axis=2)
        pinv = np.linalg.pinv(a)
        coef = np.einsum("pm,kgm->kgp", pinv, xx)
        rss = np.sum((xx - np.einsum("kgp,mp->kgm", coef, a)) ** 2, axis=2)
        turn = np.exp(-1j * w0 * centres[js])
        phasor = (coef[..., 0] - 1j * coef[..., 1]) / np.sqrt(2.0) * turn
        if steps > 0:
            halves[js] = _half_step(u, xx[:steps], w, np.abs(phasor[:steps]))
        if dc != "off":
            # A window across a step of the voltage (its plain fit poor) is no place for
            # an offset: the decay columns would "explain" the step. Voltages carry no
            # decaying offset to speak of, so their misfit tells a step from a current's
            # offset.
            across = (
                np.any(rss[:steps] > STEP_LIMIT**2 * ssq[:steps], axis=0)
                if steps > 0
                else np.zeros(js.size, dtype=bool)
            )
            ok = (lo > 0) & ~across & ~halves[js]
            r = u / period
            # A window with an offset has the residual of its ramp and curvature over the
            # window's own cycle (where they are needed: they cost a fit).
            ramp = np.column_stack([a, r, r * r])
        if dc == "on":
            use = np.ones_like(rss, dtype=bool) & ok[None, :]
            if use.any():
                # The window's first filtered sample is made with the sample before
                # the window, which may lie across a step: it is left out.
                yy = y[:, idx[:, 1:]]
                coef_m = np.einsum("pm,kgm->kgp", np.linalg.pinv(a[1:]), yy)
                mimic = (coef_m[..., 0] - 1j * coef_m[..., 1]) / np.sqrt(2.0) / gain * turn
                phasor = np.where(use, mimic, phasor)
                rss = np.where(use, np.minimum(rss, lstsq(ramp, xx)[1]), rss)
            decay[:, js] = use
        elif dc == "auto":
            m2 = int(his2[js[0]] - lo[0])
            idx2 = lo[:, None] + np.arange(m2)
            # The offset fitted over two cycles, taken out of the window's samples: the
            # phasor of the cleaned samples is the plain one less the offset's share.
            use, follow, best, score, across2, off = offset_test(
                t[idx2[0]] - centres[js[0]], x[:, idx2], period, w, steps, sets,
                (pinv[0] - 1j * pinv[1]) / np.sqrt(2.0),
            )  # fmt: skip
            ok &= ~across2
            cleaned = phasor[..., None] - off * turn[:, None]  # (k, g, time constants)
            at_best = np.take_along_axis(cleaned, best[..., None], axis=2)[..., 0]
            matters = np.ones_like(use)
            for chans in sets:
                idx_s = list(chans)
                moved = np.abs(at_best[idx_s] - phasor[idx_s]) > DECAY_MIN_SHARE * np.abs(
                    phasor[idx_s]
                )
                matters[idx_s] = moved.any(axis=0)[None, :]
            first[:, js] = use & ok & matters
            then[:, js] = follow & ok[None, :, None]
            choice[:, js] = best
            scores[:, js] = score
            stepped[js] = across | halves[js]
            clean[:, js] = cleaned
            need = np.flatnonzero((first[:, js] | then[:, js].any(axis=2)).any(axis=0))
            if need.size:
                rss_off[:, js[need]] = lstsq(ramp, xx[:, need])[1]
        res[:, js] = rss
        sum_sq[:, js] = ssq
        mean_sq[:, js] = ssq / m
        out[:, js] = phasor
    if dc == "auto":
        # An offset found right after a step (where the test allows for a fast-moving
        # phasor) is followed while it lasts: each next window where the plainer test
        # (a slowly moving phasor) still finds it is cleaned too.
        # The offset is fitted over two cycles: none may hold a step. A step on the
        # cycles' boundary at a voltage zero crossing misfits neither cycle's window nor
        # (by much) the two cycles' fit, but moves the voltage's phasor between them.
        hop = round(period / (centres[1] - centres[0])) if centres.size > 1 else 1
        for j in range(centres.size):
            nxt = min(j + hop, centres.size - 1)
            if steps > 0:
                # (the nominal frame's turn at the segment's frequency taken out first)
                v0 = out[:steps, j]
                v1 = out[:steps, nxt] * np.exp(-1j * (w - w0) * (centres[nxt] - centres[j]))
                if stepped[j : nxt + 1].any() or np.any(
                    np.abs(v1 - v0) > HALF_STEP_LIMIT * np.abs(v0)
                ):
                    continue
            own = then[np.arange(k), j, choice[:, j]]
            decay[:, j] = first[:, j] | (own & (decay[:, j - 1] if j else False))
        # One offset, one time constant: the one that explains the most over the run of
        # windows it was found in (chosen in each window alone, where the offset is
        # small, noise turned rows 8 sd off). Only where voltage channels tell the steps:
        # without them a run can start in windows whose two cycles hold the step, which
        # a short time constant fits best and would outweigh the rest.
        for c in range(k if steps > 0 else 0):
            runs = np.flatnonzero(np.diff(np.r_[0, decay[c].astype(int), 0]))
            for a, b in zip(runs[::2], runs[1::2], strict=True):
                choice[c, a:b] = np.argmax(scores[c, a:b].sum(axis=0))
        picked = np.take_along_axis(clean, choice[..., None], axis=2)[..., 0]
        out = np.where(decay, picked, out)
        res = np.where(decay, np.minimum(res, rss_off), res)
    with np.errstate(invalid="ignore", divide="ignore"):
        res = np.sqrt(res / sum_sq)
        share = np.abs(out) ** 2 / mean_sq
    if skew is not None:
        out *= np.exp(-1j * w0 * np.asarray(skew, dtype=float))[:, None]
    return out, np.nan_to_num(res, nan=0.0), decay, np.nan_to_num(share, nan=0.0), halves


def _half_step(u: np.ndarray, xx: np.ndarray, w: float, size: np.ndarray) -> np.ndarray:
    """Windows (g,) where a voltage channel's phasor differs between the two half cycles.

    Each half is fitted with a constant and the fundamental (three columns: at 8 samples
    per cycle a half holds four); ``size`` (k, g) is the window's phasor magnitude.
    """
    first = u < 0
    if min(first.sum(), (~first).sum()) < 4:
        return np.zeros(xx.shape[1], dtype=bool)
    ph = []
    for half in (first, ~first):
        uh = u[half]
        a = np.column_stack([np.ones(uh.size), np.cos(w * uh), np.sin(w * uh)])
        coef, _ = lstsq(a, xx[..., half])
        ph.append(coef[..., 1] - 1j * coef[..., 2])
    with np.errstate(invalid="ignore", divide="ignore"):
        change = np.abs(ph[1] - ph[0]) / np.sqrt(2.0) / size
    return np.any(np.nan_to_num(change, nan=0.0) > HALF_STEP_LIMIT, axis=0)


def fit_phasors(
    t_s: np.ndarray,
    x: np.ndarray,
    *,
    f0: float,
    per_cycle: int = 1,
    dc: str = "auto",
    skew_s: np.ndarray | None = None,
    reference: int = 0,
    mimic_tau_s: float | None = None,
    step_channels: int = 0,
    phase_sets: Sequence[Sequence[int]] = (),
    progress: Callable[[int], None] | None = None,
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
    dc : {"auto", "on", "off"}
        A decaying offset: fitted over two cycles and taken out where an F-test finds
        one (false-alarm rate :data:`DECAY_ALPHA` per channel and window), and in the
        windows that follow while it lasts; ``"on"``: the mimic filter in every window
        but a segment's first (off by about ``X' / (j w)`` where the phasor moves);
        ``"off"``: never (a constant offset is always fitted: being orthogonal to the
        fundamental over a whole cycle, it costs nothing).
    skew_s : numpy.ndarray, optional
        Per-channel time skews (s): channel k was sampled ``skew_s[k]`` after the stamp.
    reference : int, default 0
        Channel whose phasor's turn gives the segment's frequency.
    mimic_tau_s : float, optional
        Time constant of the mimic filter of ``dc="on"`` (s); one nominal cycle by
        default.
    step_channels : int, default 0
        The first ``step_channels`` channels are voltages: a window where one of them
        misfits by more than :data:`STEP_LIMIT` straddles a step, and keeps its plain
        phasors (no offset taken out in any channel).
    phase_sets : sequence of (int, int, int), optional
        Channel triples that are the phases a, b, c of one three-phase quantity: their
        decay test is made on the space vector, which tells an offset from a phasor that
        moves within the window (see
        :func:`~loadbayes.recordings.phasor_offset.offset_test`); each set is cleaned as
        one.
    progress : callable, optional
        Called with the number of windows fitted, as they are (twice per window: a first
        pass at ``f0``, a second at the segment's frequency).

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
    if dc not in ("auto", "on", "off"):
        raise ValueError(f"dc must be 'auto', 'on' or 'off', got {dc!r}")
    tau = period if mimic_tau_s is None else float(mimic_tau_s)
    first, res_first, dec_first, share_first, half_first = _one_pass(
        t, x, centres, period, w0, w0, dc, None, tau, step_channels, phase_sets, progress
    )
    w = w0
    if centres.size >= 3:
        turn = np.angle(first[reference, 1:] * np.conj(first[reference, :-1]))
        f_est = f0 + turn / (2.0 * np.pi * np.diff(centres))
        f_med = float(np.median(f_est))
        if abs(f_med - f0) < 0.05 * f0:  # a plausible system frequency
            w = 2.0 * np.pi * f_med
    if w == w0 and skew_s is None:
        return PhasorFit(centres, first, res_first, f0, dec_first, share_first, half_first)
    out, res, dec, share, half = _one_pass(
        t, x, centres, period, w, w0, dc, skew_s, tau, step_channels, phase_sets, progress
    )
    return PhasorFit(centres, out, res, w / (2.0 * np.pi), dec, share, half)
