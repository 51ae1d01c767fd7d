"""What the archive's pool reads: fits checked, temperatures matched, shares as logits.

:func:`check_fits` checks the catalog's rows (one-line errors naming the column and row),
:func:`event_temperatures` gives each event its station's temperature, and
:func:`working` turns each event's share into a measurement on the logit scale.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from loadbayes.archive.catalog import ESS_OK, RHAT_OK
from loadbayes.io.errors import DataError

__all__ = ["COLUMNS", "ESS_EVENT", "RHAT_EVENT", "check_fits", "event_temperatures", "usable",
           "working"]  # fmt: skip

#: The columns of ``catalog.fits_frame`` the pool reads (and ``ess`` when it is there).
COLUMNS = ("station", "bay", "event_id", "time", "part", "mean", "sd", "rhat", "status")
#: What the pool asks of an event is asked of its share alone (the share's own R-hat and
#: bulk ESS, not those of T' or the motor's other coordinates, which a shallow dip leaves
#: open and the pool does not read): the chains agree on it (R-hat under RHAT_EVENT) and
#: its mean and sd rest on ESS_EVENT effective draws or more (the mean's Monte Carlo error
#: a tenth of its sd, the sd known to about 7%). ``catalog.fits_frame`` marks a share
#: ``ok`` by the same two numbers. Looser than a single fit's R-hat 1.01 and ESS 400
#: (``loadbayes.diagnostics``): the pool reads only a mean and an sd. Not looser still:
#: on the tests' archive the 98 shares with ESS 50-100 held their truth in 99% of their
#: intervals but leaned +0.45 sd (the others +0.26), and pooled with them (their mean's
#: Monte Carlo error added to their variance) the monthly bands held the truth in 63 of
#: 72 months, against 65 without.
RHAT_EVENT = RHAT_OK
ESS_EVENT = ESS_OK
#: The temperature reading an event takes: its station's nearest within this.
TEMPERATURE_WINDOW = pd.Timedelta(hours=3)


def check_fits(frame: pd.DataFrame, source: str | None) -> pd.DataFrame:
    """The fits with numeric mean, sd, rhat and times; a bad ``ok`` row is a DataError."""
    missing = [c for c in COLUMNS if c not in frame.columns]
    if missing:
        raise DataError(f"the catalog's fits have no column {missing[0]!r}", source, missing[0])
    f = frame.reset_index(drop=True)
    times = pd.to_datetime(f["time"], errors="coerce")
    ok = f["status"].astype(str) == "ok"
    for col in ("mean", "sd", "rhat"):
        v = pd.to_numeric(f[col], errors="coerce")
        # a missing R-hat (one chain) is left out and counted; text there is an error
        bad = ok & (v.isna() if col != "sd" else ~(v > 0))
        if col == "rhat":
            bad = ok & v.isna() & f[col].notna()
        if col == "mean":
            bad |= ok & ((v < 0) | (v > 1))
        if bad.any():
            i = int(np.flatnonzero(bad)[0])
            what = {"mean": "a share in [0, 1]", "sd": "a positive sd", "rhat": "a number"}[col]
            raise DataError(f"event {f['event_id'][i]!r}: {f[col][i]!r} is not {what}",
                            source, col, i + 1)  # fmt: skip
        f[col] = v
    if times.isna().any():
        i = int(np.flatnonzero(times.isna())[0])
        raise DataError(f"event {f['event_id'][i]!r}: no time", source, "time", i + 1)
    f["time"] = times
    return f


def usable(f: pd.DataFrame) -> tuple[pd.DataFrame, dict[str, int]]:
    """The rows the pool reads, and the others counted by why they are left out.

    A row's own ``status`` says a failed fit (anything but ``ok``, ``unconverged`` and
    ``unphysical``) and an unphysical share; convergence is judged here from the share's
    ``rhat`` and ``ess`` (RHAT_EVENT, ESS_EVENT), whatever the status says of it.
    """
    status = f["status"].astype(str)
    rhat = f["rhat"].to_numpy(float)
    ess = pd.to_numeric(f["ess"], errors="coerce").to_numpy(float) if "ess" in f else None
    failed = ~status.isin(["ok", "unconverged", "unphysical"]).to_numpy()
    unphysical = (status == "unphysical").to_numpy() & ~failed
    rest = ~failed & ~unphysical
    no_rhat = rest & np.isnan(rhat)
    disagree = rest & ~no_rhat & ~(rhat < RHAT_EVENT)
    few = np.zeros(len(f), bool)
    if ess is not None:
        few = rest & ~no_rhat & ~disagree & ~(ess >= ESS_EVENT)
    keep = rest & ~no_rhat & ~disagree & ~few
    left = {
        "fit failed": int(failed.sum()),
        "share outside [0, 1]": int(unphysical.sum()),
        f"chains disagree on the share (R-hat >= {RHAT_EVENT:g})": int(disagree.sum()),
        f"too few effective draws of the share (ESS < {ESS_EVENT:g})": int(few.sum()),
        "no R-hat recorded": int(no_rhat.sum()),
    }
    return f[keep].reset_index(drop=True), left


def event_temperatures(f: pd.DataFrame, table: pd.DataFrame, name: str):
    """Each event's temperature (the station's nearest reading within 3 h), or NaN."""
    for col in ("station", "time", "temperature"):
        if col not in table.columns:
            raise DataError(f"no column {col!r} (needs station, time, temperature)", name, col)
    t = table.reset_index(drop=True)
    when = pd.to_datetime(t["time"], errors="coerce")
    temp = pd.to_numeric(t["temperature"], errors="coerce")
    for col, bad in (("time", when.isna()), ("temperature", temp.isna())):
        if bad.any():
            i = int(np.flatnonzero(bad)[0])
            raise DataError(f"{t[col][i]!r} is not a {col}", name, col, i + 1)
    t = pd.DataFrame({"station": t["station"].astype(str), "time": when, "temperature": temp})
    t = t.sort_values("time")
    ev = f[["station", "time"]].assign(station=f["station"].astype(str), _i=np.arange(len(f)))
    m = pd.merge_asof(ev.sort_values("time"), t, on="time", by="station",
                      direction="nearest", tolerance=TEMPERATURE_WINDOW)  # fmt: skip
    out = np.full(len(f), np.nan)
    out[m["_i"].to_numpy()] = m["temperature"].to_numpy()
    return out, t


def working(x, unit, units, m, sd, ridge_sd, rounds: int = 3):
    """A rough curve per unit (the start) and each event's logit linearised around it.

    ``y = logit(c) + (m - c) / (c (1 - c))``, ``s = sd / (c (1 - c))`` with ``c`` the
    unit's rough curve at the event (weighted least squares, ridged toward all units'
    curve), as iteratively reweighted least squares' working response. Taken at the
    event's own ``m`` instead, a share measured low got a larger ``s`` and less weight,
    and low shares' curves came out high (measured: +0.3 band sd on average at shares
    0.1-0.4 with sd 0.01-0.05).
    """
    c = m.copy()
    start = np.zeros((units, x.shape[1]))
    for _ in range(rounds):
        g = c * (1 - c)
        y, s = np.log(c / (1 - c)) + (m - c) / g, sd / g
        w = 1 / (s**2 + 0.04)
        xw = x * w[:, None]
        every = np.linalg.solve(xw.T @ x + 1e-6 * np.eye(x.shape[1]), xw.T @ y)
        for u in range(units):
            k = unit == u
            a = xw[k].T @ x[k] + np.diag(1 / ridge_sd**2)
            start[u] = every + np.linalg.solve(a, xw[k].T @ (y[k] - x[k] @ every))
        c = (1 / (1 + np.exp(-np.einsum("ep,ep->e", x, start[unit])))).clip(1e-3, 1 - 1e-3)
    g = c * (1 - c)
    return start, np.log(c / (1 - c)) + (m - c) / g, sd / g
