"""Find voltage sags and their recoveries in a long record; cut one file per event.

A sag starts when the voltage falls below ``threshold * v_ref`` and ends (recovers) when
it is back above ``(threshold + hysteresis) * v_ref``; ``v_ref`` is the median voltage
of the record unless given. The hysteresis keeps a voltage hovering around the threshold
from being cut into many short sags. Sags shorter than ``min_duration_s`` are dropped.
Each event is the sag with ``pre_s`` seconds before it and ``post_s`` after its
recovery (clipped to the record); events whose windows overlap are merged into one.

Each event table keeps the record's columns (``t_s, v, p, q[, f]``, per unit, f in Hz)
with ``t_s`` counted from the event's first sample, ready for ``loadbayes fit zip`` and
``loadbayes fit composite``.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import asdict, dataclass

import numpy as np

__all__ = ["SagWindow", "cut_events", "find_sags"]


@dataclass(frozen=True)
class SagWindow:
    """One sag and the window cut around it (where it lies in the record, not its samples).

    Parameters
    ----------
    index : int
        1-based event number.
    start, stop : int
        Sample indices of the window ``[start, stop)`` in the record.
    sag_start_s, recovery_s : float
        Record times when the voltage crossed the threshold down and recovered (NaN if
        the record ends before the voltage recovers).
    duration_s : float
        Time below the recovery threshold.
    v_min : float
        Lowest voltage in the sag (p.u.).
    depth : float
        ``1 - v_min / v_ref``.
    recovered : bool
        Whether the voltage recovered before the record ends.
    n_sags : int
        Sags merged into this window.
    """

    index: int
    start: int
    stop: int
    sag_start_s: float
    recovery_s: float
    duration_s: float
    v_min: float
    depth: float
    recovered: bool
    n_sags: int

    def as_row(self) -> dict:
        """The event as a flat dict (one row of the events table)."""
        return asdict(self)


def _runs(mask: np.ndarray) -> list[tuple[int, int]]:
    """[start, stop) of the runs of True."""
    edges = np.diff(np.concatenate([[0], mask.astype(np.int8), [0]]))
    return list(zip(np.flatnonzero(edges == 1), np.flatnonzero(edges == -1), strict=True))


def find_sags(
    t_s: np.ndarray,
    v: np.ndarray,
    *,
    threshold: float = 0.9,
    hysteresis: float = 0.02,
    min_duration_s: float = 0.02,
    pre_s: float = 0.5,
    post_s: float = 2.0,
    v_ref: float | None = None,
) -> list[SagWindow]:
    """Find the voltage sags of a record.

    Parameters
    ----------
    t_s : numpy.ndarray
        Increasing sample times (s).
    v : numpy.ndarray
        Voltage magnitude (p.u.).
    threshold : float, default 0.9
        A sag starts below ``threshold * v_ref`` (IEEE 1159 uses 0.9).
    hysteresis : float, default 0.02
        It ends above ``(threshold + hysteresis) * v_ref``.
    min_duration_s : float, default 0.02
        Shorter sags are ignored (one cycle at 50 Hz).
    pre_s, post_s : float
        Seconds kept before the sag and after its recovery.
    v_ref : float, optional
        Reference voltage; the record's median by default.

    Returns
    -------
    list of SagWindow
        In time order; overlapping windows merged.

    Raises
    ------
    ValueError
        If the settings are out of range or ``t_s`` is not increasing.
    """
    t = np.asarray(t_s, dtype=float)
    v = np.asarray(v, dtype=float)
    if t.shape != v.shape or t.ndim != 1:
        raise ValueError("t_s and v must be 1-D arrays of the same length")
    if not 0 < threshold < 1:
        raise ValueError(f"threshold must be in (0, 1), got {threshold}")
    if not 0 <= hysteresis < 1 - threshold:
        raise ValueError(f"hysteresis must be in [0, {1 - threshold:g}), got {hysteresis}")
    if min(min_duration_s, pre_s, post_s) < 0:
        raise ValueError("min_duration_s, pre_s and post_s must be >= 0")
    if t.size and np.any(np.diff(t) <= 0):
        raise ValueError("t_s must be strictly increasing")
    if t.size == 0:
        return []
    ref = float(np.median(v)) if v_ref is None else float(v_ref)
    if not ref > 0:
        raise ValueError(f"reference voltage must be > 0, got {ref}")
    enter, leave = threshold * ref, (threshold + hysteresis) * ref
    sags = []
    for a, b in _runs(v < leave):
        if not np.any(v[a:b] < enter):
            continue  # dipped under the recovery level only: not a sag
        first = a + int(np.argmax(v[a:b] < enter))
        recovered = b < v.size
        end_t = t[b] if recovered else t[-1]
        if end_t - t[first] < min_duration_s:
            continue
        sags.append((first, b, recovered))
    windows: list[list] = []
    for first, b, recovered in sags:
        lo = int(np.searchsorted(t, t[first] - pre_s, side="left"))
        hi_t = (t[b] if recovered else t[-1]) + post_s
        hi = int(np.searchsorted(t, hi_t, side="right"))
        if windows and lo < windows[-1][1]:
            windows[-1][1] = max(windows[-1][1], hi)
            windows[-1][2].append((first, b, recovered))
        else:
            windows.append([lo, hi, [(first, b, recovered)]])
    out = []
    for k, (lo, hi, group) in enumerate(windows, start=1):
        first, _, _ = group[0]
        _, b, recovered = group[-1]
        vmin = float(np.min(v[lo:hi]))
        out.append(
            SagWindow(
                index=k,
                start=lo,
                stop=hi,
                sag_start_s=float(t[first]),
                recovery_s=float(t[b]) if recovered else float("nan"),
                duration_s=float((t[b] if recovered else t[-1]) - t[first]),
                v_min=vmin,
                depth=1.0 - vmin / ref,
                recovered=recovered,
                n_sags=len(group),
            )
        )
    return out


def cut_events(
    data: Mapping[str, np.ndarray], events: list[SagWindow], *, t_col: str = "t_s"
) -> list[dict[str, np.ndarray]]:
    """Cut each event's window out of the record, its time counted from its first sample.

    Parameters
    ----------
    data : mapping of str to numpy.ndarray
        The record's columns, all the same length.
    events : list of SagWindow
        From :func:`find_sags`.
    t_col : str, default "t_s"
        The time column, rebased to 0 at each event's first sample.

    Returns
    -------
    list of dict
        One table (column -> array) per event.
    """
    out = []
    for ev in events:
        table = {k: np.asarray(col)[ev.start : ev.stop] for k, col in data.items()}
        table[t_col] = table[t_col] - table[t_col][0]
        out.append(table)
    return out
