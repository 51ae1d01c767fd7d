"""Voltage steps in a long record: tap changes, capacitor switching, CVR steps.

Over a day the load level follows the time of day while the voltage moves, so a fit of
``P(V)`` with one level confuses the two. A voltage step is the exception: V changes
within one sample, while the load level changes slowly, so the change of P across the
step (with the slow drift on either side removed) is the load's response to the
voltage alone: the field method of measuring the voltage dependence of a load.

A step, as found here (:func:`find_steps`):

* the means of V over the two samples after and the two before a sample differ by more
  than ``k`` noise sd of that difference and by more than ``min_step`` p.u. (the noise
  sd of V from the median absolute first difference, robust to the steps themselves;
  two samples rather than one halve the noise of the difference, and resolve steps
  three samples apart, as an LTC's consecutive taps may be);
* that difference is the largest of its neighbours (one sample per step: the first
  after it);
* the level is steady on both sides: V stays within ``k`` noise sd (and half the step)
  of a straight line through each window, so a ramp, a second step or a sag inside a
  window disqualifies it;
* the windows do not cross a telemetry gap (a time step over 1.5 times the median), and
  two steps closer than two windows share the samples between them (each window ends
  halfway; under MIN_SIDE samples on a side, the step is counted as too close).

Each step's dV, dP, dQ are the jumps of a straight line with a step (level, slope in
time, jump) fitted by least squares over its windows: a load that drifts linearly
during the windows does not enter the jump.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd

__all__ = ["Step", "find_steps", "jump", "steps_table", "window_bounds"]

#: Default half-window (samples each side), noise multiple and smallest step (p.u.).
WINDOW = 5
K_SD = 6.0
MIN_STEP = 0.004
#: Fewest samples on each side of a step.
MIN_SIDE = 2
#: Samples on each side of the difference that detects a step.
DETECT = 2


@dataclass(frozen=True)
class Step:
    """One voltage step: ``index`` is the first sample after it (0-based)."""

    index: int
    lo: int
    hi: int
    dv: float
    dp: float
    dq: float | None
    v_before: float
    p_before: float
    q_before: float | None


def noise_sd(v: np.ndarray) -> float:
    """The sd of white noise on ``v`` from its first differences (median absolute)."""
    d = np.diff(np.asarray(v, dtype=float))
    if d.size == 0:
        return 0.0
    return float(1.4826 * np.median(np.abs(d - np.median(d))) / np.sqrt(2.0))


def window_bounds(idx: np.ndarray, n: int, window: int, t: np.ndarray | None):
    """Each step's window ``[lo, hi)``, or None when a side is under MIN_SIDE.

    ``window`` samples each side, halved between neighbouring steps, cut at a gap.
    """
    if t is not None and t.size > 1:
        dt = np.diff(t)
        step = float(np.median(dt))
        gaps = np.flatnonzero(dt > 1.5 * step) + 1 if step > 0 else np.array([], int)
    else:
        gaps = np.array([], dtype=int)
    out = []
    for j, i in enumerate(idx):
        lo, hi = i - window, i + window
        if j > 0:
            lo = max(lo, (idx[j - 1] + i + 1) // 2)
        if j + 1 < idx.size:
            hi = min(hi, (i + idx[j + 1]) // 2)
        lo, hi = max(lo, 0), min(hi, n)
        before = gaps[(gaps > lo) & (gaps <= i)]
        after = gaps[(gaps > i) & (gaps < hi)]
        if before.size:
            lo = int(before.max())
        if after.size:
            hi = int(after.min())
        if i - lo < MIN_SIDE or hi - i < MIN_SIDE or (gaps == i).any():
            out.append(None)
        else:
            out.append((int(lo), int(hi)))
    return out


def jump(y: np.ndarray, tt: np.ndarray, after: np.ndarray) -> tuple[float, float, np.ndarray]:
    """Least squares ``y = level + slope t + jump [after]``.

    Returns the jump, the level before the step (at its time), and the residuals.
    """
    a = np.column_stack([np.ones_like(tt), tt, after.astype(float)])
    coef, *_ = np.linalg.lstsq(a, y, rcond=None)
    return float(coef[2]), float(coef[0]), y - a @ coef


def find_steps(
    v: np.ndarray,
    p: np.ndarray,
    q: np.ndarray | None = None,
    *,
    t: np.ndarray | None = None,
    window: int = WINDOW,
    k: float = K_SD,
    min_step: float = MIN_STEP,
) -> tuple[list[Step], dict[str, float | int]]:
    """Voltage steps in a record in time order (module notes).

    Parameters
    ----------
    v, p, q : ndarray
        Voltage (per unit) and powers, one sample per row, in time order.
    t : ndarray, optional
        Sample times in seconds (for gaps and the drift's slope); the row number if None.
    window : int
        Samples on each side of a step (the windows the fit uses).
    k : float
        A step exceeds ``k`` noise sd of the windowed difference, and the level on each
        side stays within ``k`` noise sd of a line.
    min_step : float
        Smallest step in p.u. of V.

    Returns
    -------
    (list of Step, dict)
        The steps, and what the search saw: ``noise_sd`` of V, ``candidates``,
        ``not_steady`` and ``too_close`` (rejected candidates).
    """
    v = np.asarray(v, dtype=float)
    p = np.asarray(p, dtype=float)
    n = v.size
    tt = np.arange(n, dtype=float) if t is None else np.asarray(t, dtype=float)
    sd = noise_sd(v)
    info: dict[str, float | int] = {"noise_sd": sd, "candidates": 0, "not_steady": 0,
                                    "too_close": 0}  # fmt: skip
    if n < 2 * MIN_SIDE + 1:
        return [], info
    w = int(window)
    c = np.concatenate([[0.0], np.cumsum(v)])
    i = np.arange(1, n)
    m_b = np.minimum(i, DETECT)
    m_a = np.minimum(n - i, DETECT)
    diff = (c[i + m_a] - c[i]) / m_a - (c[i] - c[i - m_b]) / m_b
    need = np.maximum(k * sd * np.sqrt(1.0 / m_a + 1.0 / m_b), min_step)
    big = np.abs(diff) > need
    cand = []
    for j in np.flatnonzero(big):
        lo, hi = max(j - 1, 0), min(j + 2, diff.size)
        if np.abs(diff[j]) >= np.abs(diff[lo:hi]).max():
            cand.append(int(i[j]))
    info["candidates"] = len(cand)
    idx = np.asarray(cand, dtype=int)
    bounds = window_bounds(idx, n, w, None if t is None else tt)
    steps = []
    for s, b in zip(idx, bounds, strict=True):
        if b is None:
            info["too_close"] = int(info["too_close"]) + 1
            continue
        lo, hi = b
        sl = slice(lo, hi)
        after = np.arange(lo, hi) >= s
        tw = tt[sl] - tt[s]
        dv, v_b, res = jump(v[sl], tw, after)
        if np.abs(res).max() > max(k * sd, 0.5 * abs(dv)) or abs(dv) < min_step:
            info["not_steady"] = int(info["not_steady"]) + 1
            continue
        dp, p_b, _ = jump(p[sl], tw, after)
        dq = q_b = None
        if q is not None:
            dq, q_b, _ = jump(np.asarray(q, dtype=float)[sl], tw, after)
        steps.append(Step(int(s), lo, hi, dv, dp, dq, v_b, p_b, q_b))
    return steps, info


def steps_table(steps: list[Step], *, time: np.ndarray | None = None) -> pd.DataFrame:
    """The steps as a table: time, row, V before, dV, dP, dQ, and the sensitivities.

    ``sens_p`` is ``(dP / P) / (dV / V)`` at the step: the load's dP/dV in per unit of
    its own level (1 for a constant-current load, 2 for constant impedance).
    """
    rows = []
    for s in steps:
        row = {
            "time": time[s.index] if time is not None else s.index,
            "index": s.index,
            "v_before": s.v_before,
            "dv": s.dv,
            "dp": s.dp,
            "dq": s.dq,
            "sens_p": (s.dp / s.p_before) / (s.dv / s.v_before),
            "sens_q": (
                (s.dq / s.q_before) / (s.dv / s.v_before)
                if s.dq is not None and s.q_before
                else None
            ),
            "samples": s.hi - s.lo,
        }
        rows.append(row)
    cols = ["time", "index", "v_before", "dv", "dp", "dq", "sens_p", "sens_q", "samples"]
    return pd.DataFrame(rows, columns=cols)
