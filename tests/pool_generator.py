"""A year of fitted events at a few stations, with a known seasonal motor share (issue 38).

Written for the tests of :mod:`loadbayes.archive.pool`, independently of the package:
the frame :func:`loadbayes.archive.catalog.fits_frame` gives (one row per event and
part), as if every event had been fitted.

Each unit (a station's bay) has a true curve on the share scale,
``base + amp cos(2 pi (d - peak) / 365.25)`` (one harmonic on the share scale: not the
model's form on the logit scale, so the fit is tested a little off its own model). An
event's true share is the curve's at its day with event-to-event noise on the logit
scale (``N(0, tau^2)``; the curve is then the median event's share, as the pool's curve
is); its "fit" is a posterior summary: mean = true share + ``N(0, sd^2)`` with ``sd``
drawn in [0.01, 0.05] and known. Some events failed (status, no mean) and some did not
converge (R-hat 1.08-1.3); they are counted in :func:`archive`'s second return.

Stations A and B share their curves bay by bay; C differs (its motors peak in winter on
T1, in summer on F2); D (when asked) has A's curves but only a few events.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

#: (base, amplitude, day of the peak) per station and bay.
CURVES = {
    ("A", "T1"): (0.35, 0.12, 200.0),
    ("A", "F2"): (0.20, 0.06, 20.0),
    ("B", "T1"): (0.35, 0.12, 200.0),
    ("B", "F2"): (0.20, 0.06, 20.0),
    ("C", "T1"): (0.30, 0.10, 20.0),
    ("C", "F2"): (0.40, 0.10, 200.0),
    ("D", "T1"): (0.35, 0.12, 200.0),
    ("D", "F2"): (0.20, 0.06, 20.0),
}
YEAR = pd.Timestamp("2025-01-01")
_MONTH_START = np.cumsum([0, 31, 28, 31, 30, 31, 30, 31, 31, 30, 31, 30])
_MONTH_DAYS = np.diff(np.append(_MONTH_START, 365))


def truth(station: str, bay: str, day: np.ndarray) -> np.ndarray:
    """The true (median event's) motor share on day-of-year ``day`` (0 = 1 January)."""
    base, amp, peak = CURVES[(station, bay)]
    return base + amp * np.cos(2 * np.pi * (np.asarray(day, float) - peak) / 365.25)


def monthly_truth(station: str, bay: str) -> np.ndarray:
    """The true share averaged over each month's days (12 values)."""
    return np.array([truth(station, bay, s + np.arange(n) + 0.5).mean()
                     for s, n in zip(_MONTH_START, _MONTH_DAYS, strict=True)])  # fmt: skip


def archive(
    seed: int,
    *,
    stations: tuple[str, ...] = ("A", "B", "C"),
    events: int = 30,
    few: dict[str, int] | None = None,
    tau: float = 0.15,
    failed: int = 4,
    unconverged: int = 3,
) -> tuple[pd.DataFrame, dict[str, int]]:
    """``events`` per unit (``few`` overrides a station's), plus the bad ones.

    Returns the frame and the counts of failed and unconverged rows added.
    """
    rng = np.random.default_rng(seed)
    rows = []
    for station, bay in CURVES:
        if station not in stations:
            continue
        n = (few or {}).get(station, events)
        day = rng.uniform(0, 365, n)
        share0 = truth(station, bay, day)
        logit = np.log(share0 / (1 - share0)) + rng.normal(0, tau, n)
        share = 1 / (1 + np.exp(-logit))
        sd = rng.uniform(0.01, 0.05, n)
        mean = np.clip(share + rng.normal(0, sd), 0.002, 0.998)
        for i in range(n):
            rows.append({"station": station, "bay": bay, "event_id": f"{station}{bay}-{i}",
                         "time": YEAR + pd.Timedelta(days=float(day[i])), "model": "zip+motor",
                         "part": "f_m", "mean": mean[i], "sd": sd[i], "lo": mean[i] - 2 * sd[i],
                         "hi": mean[i] + 2 * sd[i], "rhat": rng.uniform(1.0, 1.01),
                         "ess": rng.uniform(400, 2000), "status": "ok"})  # fmt: skip
    bad = []
    for k in range(failed + unconverged):
        row = dict(rows[int(rng.integers(len(rows)))], event_id=f"bad-{k}")
        if k < failed:
            row.update(status="failed: the motor did not start", mean=np.nan, sd=np.nan)
        else:  # a far-off share that must not pull the curve
            row.update(rhat=rng.uniform(1.08, 1.3), mean=0.95)
        bad.append(row)
    frame = pd.DataFrame(rows + bad)
    frame["time"] = pd.to_datetime(frame["time"])
    return frame, {"failed": failed, "unconverged": unconverged}
