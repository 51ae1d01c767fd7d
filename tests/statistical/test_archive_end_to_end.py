"""Issue 38's check end to end: the tests' archive scanned, fitted and pooled, against its truth.

The records are tests/archive_generator.py's (not the package's simulator): 3 stations x 2
bays, a SciPy ZIP + third-order motor behind each bay, the motor's share seasonal per
station with event-to-event noise (sd 0.03), COMTRADE 1991/1999/2013 in ASCII, BINARY,
BINARY32 and FLOAT32, names in GB18030, ASCII and Latin-1; and the special files: a record
with no dip, a malformed .cfg, a .dat cut short, a .cfg without its .dat. They go through
``archive scan`` -> ``archive fit`` (zip+motor) -> ``archive pool`` as a user runs them.

The check (issue 38): the pooled monthly 95% bands cover the truth (the station's seasonal
curve averaged over the month's days) at 90% or more of the (bay, month) cells, and the
broken files are listed with their reasons.

- Full size (``make validate``, LOADBAYES_VALIDATE=1): 50 records a station (150 records,
  300 bay events), 3,000 draws after 1,000 x 2 chains per event, the pool 1,000 x 4;
  with the default one-cycle phasor window and with ``window_s=0`` (point samples).
- Measured (seed 38, 2026-11-29), after the generator's motor got the load torque the
  fit assumes (``T0 w^2``; it had a constant torque, and that alone read the motor share
  1.06-1.07 times high: bisected on exact point samples, exact window means and the
  COMTRADE chain alike, see tests/archive_generator.py):
  default window: 300 of 300 fitted, 153 shares pooled (107 left out for an ESS of the
  share under 100, 40 for its R-hat 1.05 or more), fitted/true share 1.018 (median of
  the pooled; 1.014-1.026 per bay; 1.07 on 4-10% dips, 1.01 on 20-30%), each event's
  95% interval holding its truth in 96% of them, the pooled bands the truth in 65 of 72
  cells (90.3%): passes, at the edge (seed fixed: the same draws every run; on archives
  of the pool's own generator, 0 of 15 missed the 90%, tests/statistical/
  test_archive_pool_coverage.py, which states its false-alarm rate). ``window_s=0``:
  214 pooled, ratio 1.009, events covered 62% (one-cycle phasors read as point samples
  misfit: intervals too narrow), cells 70 of 72 (97%): the pool's event-to-event spread
  takes up the misfit.
  15 and 5 minutes of fitting on 2 shared cores (22 and 13 at a load of 12-16); the
  two tests 20.5 minutes under pytest. Before the torque fix:
  1.066 and 45 of 72 cells (default), 1.045 and 38 of 72 (``window_s=0``, measured
  before the smeared-edge rule).
- The suite's lean version: one record a station (6 events), 300 draws per event: the
  pipeline runs end to end on these files, every usable event is fitted, the broken ones
  are listed with reasons, and the fitted shares rank the events as their truth does.
"""

from __future__ import annotations

import json
import os
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from archive_generator import STATIONS, motor_share, write_archive  # noqa: E402
from loadbayes.archive import events_frame, failures_frame, fit, fits_frame, pool, scan  # noqa: E402

VALIDATE = os.environ.get("LOADBAYES_VALIDATE") == "1"
_MONTH_START = np.cumsum([0, 31, 28, 31, 30, 31, 30, 31, 31, 30, 31, 30])
_MONTH_DAYS = np.diff(np.append(_MONTH_START, 365))


def monthly_truth(station: str, bay: str) -> np.ndarray:
    """The generator's mean share averaged over each month's days (12 values)."""
    st = next(s for s in STATIONS if s.name == station)
    b = st.bays.index(bay)
    return np.array([np.mean([motor_share(st, b, d + 0.5) for d in range(s, s + n)])
                     for s, n in zip(_MONTH_START, _MONTH_DAYS, strict=True)])  # fmt: skip


def run_end_to_end(root: Path, *, records: int, draws: int, burn: int, window_s=None,
                   pool_draws: int = 1000, seed: int = 38, workers=None) -> dict:  # fmt: skip
    """Write, scan, fit and pool; the coverage and what the scan and fit listed."""
    root = Path(root)
    truth = write_archive(root / "records", records=records, seed=seed)
    db = root / "archive.db"
    scanned = scan(root / "records", db)
    fitted = fit(db, draws=draws, burn=burn, chains=2, seed=0, window_s=window_s,
                 workers=workers)  # fmt: skip
    fits = fits_frame(db)
    out = {"records": int(truth[truth["special"] == ""]["file"].nunique()),
           "events": scanned.events, "usable": scanned.usable, "fitted": fitted.done,
           "fit_failed": fitted.failed, "fit_seconds": fitted.seconds,
           "fits_status": fits["status"].value_counts().to_dict(),
           "failures": failures_frame(db), "events_frame": events_frame(db),
           "window_s": window_s, "draws": draws, "burn": burn}  # fmt: skip
    t = truth[truth["special"] == ""].copy()
    t["time"] = pd.to_datetime(t["time"])
    m = pd.merge_asof(fits.sort_values("time"),
                      t.sort_values("time")[["station", "bay", "time", "f_m"]]
                      .rename(columns={"f_m": "true"}),
                      on="time", by=["station", "bay"], tolerance=pd.Timedelta("1s"),
                      direction="nearest")  # fmt: skip
    ok = m[m["status"] == "ok"]
    out["per_event"] = m
    out["ratio_median"] = float((ok["mean"] / ok["true"]).median()) if len(ok) else None
    out["event_covered"] = float(((ok["lo"] <= ok["true"]) & (ok["true"] <= ok["hi"])).mean())
    if len(ok) == 0:
        return out
    res = pool(fits, draws=pool_draws, chains=4, seed=0)
    mo = res.parts["f_m"].monthly
    mo = mo[mo["station"] != "(all)"].copy()
    keys = zip(mo["station"], mo["bay"], mo["month"], strict=True)
    mo["truth"] = [monthly_truth(s, b)[k - 1] for s, b, k in keys]
    mo["covered"] = (mo["low"] <= mo["truth"]) & (mo["truth"] <= mo["high"])
    out.update(monthly=mo, coverage=float(mo["covered"].mean()), cells=len(mo),
               pooled=int(res.parts["f_m"].events.sum()), pool_warnings=res.warnings,
               left_out=res.left_out)  # fmt: skip
    return out


def summary(out: dict) -> dict:
    """The run's numbers as plain JSON."""
    keep = ("records", "events", "usable", "fitted", "fit_failed", "fit_seconds", "fits_status",
            "window_s", "draws", "burn", "ratio_median", "event_covered", "coverage", "cells",
            "pooled", "pool_warnings", "left_out")  # fmt: skip
    return {k: out[k] for k in keep if k in out}


def _broken_listed(out: dict) -> None:
    f = out["failures"]
    files = f[f["what"] == "file"].assign(name=lambda d: d["path"].map(lambda p: Path(p).name))
    reasons = dict(zip(files["name"], files["reason"], strict=True))
    assert set(reasons) == {"bad_cfg.cfg", "short_dat.cfg", "no_dat.cfg"}, reasons
    assert "channel" in reasons["bad_cfg.cfg"] or "line" in reasons["bad_cfg.cfg"]
    assert "no_dat.dat not found" in reasons["no_dat.cfg"]
    assert reasons["short_dat.cfg"]  # the reader's own line: cut short
    ev = out["events_frame"]
    assert not ev["path"].str.endswith("no_dip.cfg").any()  # read, and no event in it


@pytest.mark.statistical
def test_lean_archive_goes_through_scan_fit_pool_and_lists_the_broken_files(tmp_path):
    # 6 events at 300 draws: short chains (their R-hat is not asked), the bookkeeping and
    # the fitted shares' order are. The generator's shares at these 6 events span 0.16
    # to 0.62; a fit that ranks them against the truth (Spearman < 0.6) has lost them.
    out = run_end_to_end(tmp_path, records=1, draws=300, burn=100, pool_draws=60)
    assert out["records"] == 3 and out["usable"] == 6
    assert (out["fitted"], out["fit_failed"]) == (6, 0)
    _broken_listed(out)
    m = out["per_event"]
    assert m["true"].notna().all()
    rho = m["mean"].rank().corr(m["true"].rank())
    assert rho >= 0.6, m[["station", "bay", "mean", "true"]]


def _full(tmp_path, window_s) -> dict:
    out = run_end_to_end(tmp_path, records=50, draws=3000, burn=1000, window_s=window_s)
    _broken_listed(out)
    target = Path("results/validation")
    target.mkdir(parents=True, exist_ok=True)
    name = "archive_end_to_end" + ("" if window_s is None else f"_window{window_s:g}")
    (target / f"{name}.json").write_text(json.dumps(summary(out), indent=2, default=str) + "\n")
    return out


@pytest.mark.statistical
@pytest.mark.skipif(not VALIDATE, reason="the full archive runs under make validate")
def test_full_archive_covers_the_seasonal_truth_with_the_default_window(tmp_path):
    out = _full(tmp_path, None)
    assert out["records"] >= 150
    assert out["coverage"] >= 0.9, summary(out)


@pytest.mark.statistical
@pytest.mark.skipif(not VALIDATE, reason="the full archive runs under make validate")
def test_full_archive_covers_the_seasonal_truth_with_point_samples(tmp_path):
    out = _full(tmp_path, 0.0)
    assert out["records"] >= 150
    assert out["coverage"] >= 0.9, summary(out)
