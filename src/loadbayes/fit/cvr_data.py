"""What a CVR fit does to the samples before any regression: glitches, the schedule, days.

* **Glitches** (:func:`find_glitches`): a spike is a sample that stands away from both
  its neighbours on the same side by more than ``SPIKE_K`` local noise sd (the local
  sd: 1.4826 times the rolling median of the absolute first differences over ``LOCAL``
  samples, so that a sunny noon's PV flicker is not a spike but a lone +6 MW is; a step
  or a ramp moves away from one neighbour only); a stuck value is a run of at least
  ``STUCK_RUN`` identical readings. Both are left out and counted.
* **The on/off schedule** (:func:`schedule_from_steps`): from a schedule column when
  given; otherwise from the voltage, by the package's step finder
  (:func:`loadbayes.measurements.steps.find_steps`) with a smallest step of
  ``min_step``: a step down switches the reduction on, a step up off, and each sample
  takes the state of the last step before it.
* **Days** (:func:`daily_table`): a day's energy is its mean power times 24 h (a gap
  does not read as a saving), its voltage the mean V, its weather and PV (or irradiance)
  their means; a day with under ``COVERAGE`` of
  its samples, or with the reduction on for part of it only, is left out and counted.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

__all__ = [
    "COVERAGE",
    "Days",
    "Glitches",
    "daily_table",
    "find_glitches",
    "read_telemetry",
    "relabel_days",
    "schedule_from_steps",
    "voltage_answers_to_load",
]

#: A spike: this many local noise sd from the median of its neighbours.
SPIKE_K = 10.0
#: Samples over which the local noise sd is taken.
LOCAL = 25
#: A stuck value: at least this many identical readings in a row.
STUCK_RUN = 6
#: A day counts when at least this share of its samples is there.
COVERAGE = 0.8


@dataclass
class Glitches:
    """Samples left out, by kind (boolean masks over the samples)."""

    spike_v: np.ndarray
    spike_p: np.ndarray
    stuck: np.ndarray

    @property
    def bad(self) -> np.ndarray:
        """Every sample left out."""
        return self.spike_v | self.spike_p | self.stuck

    def counts(self) -> dict[str, int]:
        """How many samples of each kind (a sample may be of two kinds)."""
        return {
            "spikes_v": int(self.spike_v.sum()),
            "spikes_p": int(self.spike_p.sum()),
            "stuck": int(self.stuck.sum()),
            "left_out": int(self.bad.sum()),
        }


def _rolling_median(y: np.ndarray, half: int) -> np.ndarray:
    from numpy.lib.stride_tricks import sliding_window_view

    pad = np.pad(y, half, mode="edge")
    return np.median(sliding_window_view(pad, 2 * half + 1), axis=-1)


def _spikes(y: np.ndarray) -> np.ndarray:
    if y.size < 2 * LOCAL:
        return np.zeros(y.size, dtype=bool)
    d = np.diff(y)
    a = np.r_[0.0, d]  # y_i - y_(i-1)
    b = np.r_[-d, 0.0]  # y_i - y_(i+1)
    local = 1.4826 * _rolling_median(np.abs(np.r_[d, d[-1]]), LOCAL // 2)
    floor = 1.4826 * float(np.median(np.abs(d))) * 0.2 + 1e-12
    # away from both neighbours on the same side: a step or a ramp is not a spike
    return (a * b > 0) & (np.minimum(np.abs(a), np.abs(b)) > SPIKE_K * np.maximum(local, floor))


def _stuck(y: np.ndarray) -> np.ndarray:
    out = np.zeros(y.size, dtype=bool)
    if y.size < STUCK_RUN:
        return out
    same = np.r_[False, y[1:] == y[:-1]]
    start = 0
    for i in range(1, y.size + 1):
        if i == y.size or not same[i]:
            if i - start >= STUCK_RUN:
                out[start:i] = True
            start = i
    return out


def find_glitches(v: np.ndarray, p: np.ndarray, q: np.ndarray | None = None) -> Glitches:
    """Spikes in V and P, and stuck V, P or Q (module notes)."""
    stuck = _stuck(v) | _stuck(p)
    if q is not None:
        stuck |= _stuck(q)
    return Glitches(_spikes(v), _spikes(p), stuck)


def schedule_from_steps(
    x: np.ndarray, p: np.ndarray, t: np.ndarray, *, min_step: float
) -> tuple[np.ndarray, dict[str, Any]]:
    """Each sample's state (1: reduction on) from the voltage's steps (module notes).

    Returns the states, what was seen (the steps used, their median size, and how many
    times two steps in a row went the same way: a switch missed, or a tap), and the
    samples in doubt (between two steps the same way).
    """
    from loadbayes.measurements.steps import find_steps

    steps, info = find_steps(x, p, t=t, min_step=min_step)
    state = np.zeros(x.size, dtype=np.int8)
    if not steps:
        return state, {"steps": 0, "repeats": 0, **info}, np.zeros(x.size, dtype=bool)
    idx = np.array([s.index for s in steps])
    down = np.array([s.dv < 0 for s in steps])
    state[: idx[0]] = 0 if down[0] else 1
    for j, i in enumerate(idx):
        end = idx[j + 1] if j + 1 < idx.size else x.size
        state[i:end] = 1 if down[j] else 0
    same = np.flatnonzero(down[1:] == down[:-1])
    # between two steps the same way a switch was missed: the samples there are in doubt
    doubt = np.zeros(x.size, dtype=bool)
    for j in same:
        doubt[idx[j] : idx[j + 1]] = True
    size = float(np.median(np.abs([s.dv for s in steps])))
    seen = {"steps": len(steps), "repeats": int(same.size), "median_step_pu": size, **info}
    return state, seen, doubt


def relabel_days(
    stamps: np.ndarray, x: np.ndarray, on: np.ndarray, good: np.ndarray, doubt: np.ndarray
):
    """Days in doubt whose mean voltage sits with the other state's days, relabelled whole.

    A switch the step finder cannot see (in a telemetry gap, or next to a tap) carries
    the wrong state on until the next one; the two steps around it then go the same
    way, and the samples between them are in ``doubt``. A day there labelled wholly on
    (off) whose mean V is nearer the median of the undoubted off (on) days is given the
    other state (only there: the daily voltage also moves with taps and the load, so a
    day's mean alone would mislabel days elsewhere). Returns the states and how many
    days were relabelled.
    """
    day = stamps.astype("datetime64[D]")
    _, inv = np.unique(day, return_inverse=True)
    w = good.astype(float)
    count = np.maximum(np.bincount(inv, weights=w), 1)
    v = np.bincount(inv, weights=w * x) / count
    share = np.bincount(inv, weights=w * on) / count
    in_doubt = np.bincount(inv, weights=doubt.astype(float)) > 0
    whole_on, whole_off = share >= 0.999, share <= 0.001
    sure_on, sure_off = whole_on & ~in_doubt, whole_off & ~in_doubt
    if sure_on.sum() < 2 or sure_off.sum() < 2 or not in_doubt.any():
        return on, 0
    m_on, m_off = np.median(v[sure_on]), np.median(v[sure_off])
    near_on = np.abs(v - m_on) < np.abs(v - m_off)
    flip = in_doubt & ((whole_on & ~near_on) | (whole_off & near_on))
    if not flip.any():
        return on, 0
    out = on.copy()
    rows = flip[inv]
    out[rows] = 1 - out[rows]
    return out, int(flip.sum())


@dataclass
class Days:
    """One row per day kept: energy, voltage, state, calendar, weather."""

    date: np.ndarray  # datetime64[D]
    energy: dict[str, np.ndarray]  # "p" (and "q"): mean power times 24 h
    v: np.ndarray
    on: np.ndarray
    weekday: np.ndarray
    holiday: np.ndarray
    weather: np.ndarray | None
    pv: np.ndarray | None = None
    instrument: np.ndarray | None = None
    dropped: dict[str, int] = field(default_factory=dict)

    def rows(self) -> list[dict[str, Any]]:
        """One dict per day (the JSON's days table)."""
        out = []
        for i in range(self.v.size):
            row = {"date": str(self.date[i]), "on": int(self.on[i]), "v_pu": float(self.v[i])}
            row.update({f"energy_{k}": float(e[i]) for k, e in self.energy.items()})
            if self.weather is not None:
                row["weather"] = float(self.weather[i])
            out.append(row)
        return out


def daily_table(
    stamps: np.ndarray,
    x: np.ndarray,
    chans: dict[str, np.ndarray],
    on: np.ndarray,
    *,
    good: np.ndarray,
    step_s: float,
    weather: np.ndarray | None = None,
    holiday: np.ndarray | None = None,
    pv: np.ndarray | None = None,
    instrument: np.ndarray | None = None,
) -> Days:
    """The days of the record (module notes); ``stamps`` are datetime64 per sample."""
    day = stamps.astype("datetime64[D]")
    uniq, inv = np.unique(day, return_inverse=True)
    n_days = uniq.size
    w = good.astype(float)
    count = np.bincount(inv, weights=w, minlength=n_days)
    expect = 86_400.0 / step_s
    share_on = np.bincount(inv, weights=w * on, minlength=n_days) / np.maximum(count, 1)
    cover = count / expect
    energy = {k: 24.0 * np.bincount(inv, weights=w * y, minlength=n_days) / np.maximum(count, 1)
              for k, y in chans.items()}  # fmt: skip
    v = np.bincount(inv, weights=w * x, minlength=n_days) / np.maximum(count, 1)
    short = cover < COVERAGE
    mixed = ~short & (share_on > 0.1) & (share_on < 0.9)
    nonpos = ~short & ~mixed & (energy["p"] <= 0)
    keep = ~(short | mixed | nonpos)

    def mean(y):
        if y is None:
            return None
        return (np.bincount(inv, weights=w * y, minlength=n_days) / np.maximum(count, 1))[keep]

    hol = np.zeros(n_days)
    if holiday is not None:
        hol = np.bincount(inv, weights=w * (holiday > 0), minlength=n_days) > 0.5 * np.maximum(
            count, 1
        )
    wd = ((uniq.astype("datetime64[D]").astype(np.int64) + 3) % 7).astype(int)  # Monday 0
    return Days(
        date=uniq[keep],
        energy={k: e[keep] for k, e in energy.items()},
        v=v[keep],
        on=(share_on[keep] >= 0.5).astype(int),
        weekday=wd[keep],
        holiday=np.asarray(hol, dtype=float)[keep],
        weather=mean(weather),
        pv=mean(pv),
        instrument=mean(instrument),
        dropped={
            "short": int(short.sum()),
            "mixed": int(mixed.sum()),
            "not_positive": int(nonpos.sum()),
            "days": int(n_days),
        },  # fmt: skip
    )


def voltage_answers_to_load(
    x: np.ndarray, p: np.ndarray, good: np.ndarray, steps_at: np.ndarray, *, lag: int = 1
) -> dict[str, float]:
    """How far V falls per unit of P at the head, from their joint moves between steps.

    Over ``lag`` samples, ``dV = -z dP + e``, leaving out every difference that spans a
    voltage step (``steps_at``: the first sample after each, from the step finder) or a
    left-out sample: what moves V there is the load through the source impedance. The
    slope's mean and 95% interval (least squares with a Student-t interval: a
    measurement, not a model of the load). ``z`` is in p.u. of V per unit of P (the
    units of the powers given).
    """
    from scipy.special import stdtrit  # stats.t.ppf's own; scipy.stats costs ~1.5 s to import

    n = x.size
    if n <= lag + 3:
        return {}
    dv = x[lag:] - x[:-lag]
    dp = p[lag:] - p[:-lag]
    ok = good[lag:] & good[:-lag]
    near = np.zeros(n, dtype=bool)
    for i in steps_at:
        near[max(int(i) - lag, 0) : int(i) + lag] = True
    ok &= ~near[lag:]
    ok &= ~near[:-lag]
    dv, dp = dv[ok], dp[ok]
    if dv.size < 30 or float(np.var(dp)) <= 0:
        return {}
    dpc, dvc = dp - dp.mean(), dv - dv.mean()
    slope = float(dpc @ dvc / (dpc @ dpc))
    resid = dvc - slope * dpc
    se = float(np.sqrt(resid @ resid / (dv.size - 2) / (dpc @ dpc)))
    tq = float(stdtrit(dv.size - 2, 0.975))
    z = -slope
    return {"z": z, "low": z - tq * se, "high": z + tq * se, "n": int(dv.size)}


def read_telemetry(data, *, t_col, v_col, p_col, q_col, q_req, v_base, s_base, extra, drop_invalid):
    """A file or table read for a CVR fit.

    Returns the name errors use, V, P (Q) in per unit, the named extra columns, the data
    rows kept (1-based), seconds, datetime64 stamps, and a note when the time holds no
    dates.
    """
    import pandas as pd

    from loadbayes.io.errors import DataError
    from loadbayes.measurements.frame import NAME, is_path, read_frame
    from loadbayes.measurements.times import check_increasing, parse_times, read_text_column

    extra = tuple(c for c in extra if c)
    if is_path(data):
        from loadbayes.measurements.columns import read_power_columns

        path = str(data)
        pc = read_power_columns(path, v_col=v_col, p_col=p_col, q_col=q_col,
                                q_required=q_req, extra=extra, v_base=v_base,
                                s_base=s_base, drop_invalid=drop_invalid)  # fmt: skip
        cols, rows, ext = pc.cols, pc.rows, pc.extra
        missing = [c for c in extra if c not in ext]
        if missing:
            raise DataError("not found in the file", path=path, column=missing[0])
        raw = read_text_column(path, t_col).iloc[rows - 1].reset_index(drop=True)
    else:
        path = NAME
        need = [v_col, p_col] + [c for c in ((q_col if q_req else None), *extra) if c]
        opt = [q_col] if q_col and not q_req else []
        tab = read_frame(data, need, optional=opt, positive=[v_col], drop_invalid=drop_invalid)
        rows = tab.rows
        cols = {"v": tab.data[v_col] / (v_base or 1.0), "p": tab.data[p_col] / (s_base or 1.0)}
        if q_col and q_col in tab.data:
            cols["q"] = tab.data[q_col] / (s_base or 1.0)
        ext = {c: tab.data[c] for c in extra}
        if t_col not in data.keys():
            raise DataError("not found in the table", path=path, column=t_col)
        raw = pd.Series(np.asarray(data[t_col])[rows - 1])
    secs = parse_times(raw, path=path, column=t_col, rows=rows)
    check_increasing(secs, rows, path=path, column=t_col)
    note = None
    text = raw.astype(str).str.strip()
    if pd.to_numeric(text, errors="coerce").notna().all():
        # seconds with no date: the calendar starts on a Monday, said in the result
        start = np.datetime64("2024-01-01T00:00:00")
        note = "the time column holds seconds, not dates: the first day is taken as a Monday"
    else:
        start = pd.Timestamp(pd.to_datetime(text.iloc[0], format="ISO8601")).tz_localize(None)
        start = np.datetime64(start.to_datetime64(), "ms")
    stamps = start + (secs * 1000.0).astype("timedelta64[ms]")
    return path, cols, ext, rows, secs, stamps, note
