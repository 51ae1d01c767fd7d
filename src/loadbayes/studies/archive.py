"""The demo's archive section: a generated year of three stations, scanned, fitted, pooled.

The records of ``loadbayes example archive`` (:mod:`loadbayes.cases.archive_example`: a
ZIP part and the library's motor behind each bay, the motor's share following each
station's seasonal curve with event-to-event noise, COMTRADE in three encodings and two
data formats, two files broken) go through what a user runs: :func:`loadbayes.archive.scan`
into a catalog, :func:`loadbayes.archive.fit` (``zip+motor``, the default one-cycle phasor
window, fixed draws), :func:`loadbayes.archive.pool`. The section sets each station's
pooled monthly share beside the truth (the seasonal curve averaged over the month's days),
each event's fitted share beside its own, and lists the files that failed with their
reasons.

Quick (the demo): 3 stations x 1 bay (the transformer) x 6 records, ``archive fit``'s
defaults per event (6,000 draws a chain after 4,000, 4 chains), the pool 500 x 4; full:
3 x 2 x 24, the same per event, the pool 1,000 x 4. The records are the example's (its
seed, 38); ``seed`` seeds the fits and the pool.
"""

from __future__ import annotations

import io
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from loadbayes.archive.fit import BURN, CHAINS, DRAWS

__all__ = ["ArchiveStudy", "html_section", "monthly_truth", "run"]

#: (records per station, bays, draws, burn, chains, pool draws) of the quick and the full
#: run: each event at ``archive fit``'s defaults. The quick run's 1,500 after 500 x 2
#: chains left 15 of its 18 events unconverged, out of the pool (3 pooled).
QUICK = (6, 1, DRAWS, BURN, CHAINS, 500)
FULL = (24, 2, DRAWS, BURN, CHAINS, 1000)
#: The same for ``smoke`` (a check of the pipeline, not a result): one record a station,
#: 3 events, of which 2 pass the pool's convergence check at seed 0 (at 3 a station, 1 of
#: 9 did, for 4 s more of the tests' ``reproduce all --smoke``). The pool needs one; the
#: draws stay at 1,500: at 800, none of the 9 passed.
SMOKE = (1, 1, 1500, 500, 2, 300)
YEAR = 2025


@dataclass
class ArchiveStudy:
    """The pool, its monthly table against the truth, the events, the failures, the sizes."""

    pool: Any
    monthly: pd.DataFrame
    events: pd.DataFrame
    failures: pd.DataFrame
    truth: dict[tuple[str, str], np.ndarray]
    sizes: dict[str, Any]
    seconds: dict[str, float]


def monthly_truth(station: int, bay: int, year: int = YEAR) -> np.ndarray:
    """The example's true share of a bay averaged over each month's days (12 values)."""
    from loadbayes.cases.archive_example import seasonal_share

    days = pd.date_range(f"{year}-01-01", f"{year}-12-31", freq="D")
    share = np.array([seasonal_share(station, bay, d.dayofyear - 0.5) for d in days])
    return pd.Series(share).groupby(days.month).mean().to_numpy()


def run(*, quick: bool = True, seed: int = 0, smoke: bool = False) -> ArchiveStudy:
    """Write the example's records, scan, fit and pool them; compare with the truth."""
    from loadbayes.archive import failures_frame, fit, fits_frame, pool, scan
    from loadbayes.cases.archive_example import ARCHIVE_STATIONS, archive_files

    records, bays, draws, burn, chains, pool_draws = (SMOKE if smoke else QUICK if quick
                                                      else FULL)  # fmt: skip
    seconds = {}
    with tempfile.TemporaryDirectory(prefix="loadbayes-archive-") as tmp:
        folder, db = Path(tmp) / "records", Path(tmp) / "archive.db"
        t0 = time.perf_counter()
        files = archive_files(records=records, bays=bays, year=YEAR)
        folder.mkdir()
        for name, content in files.items():
            (folder / name).write_bytes(content)
        seconds["write"] = time.perf_counter() - t0
        t0 = time.perf_counter()
        scanned = scan(folder, db)
        seconds["scan"] = time.perf_counter() - t0
        t0 = time.perf_counter()
        fitted = fit(db, draws=draws, burn=burn, chains=chains, seed=seed)
        seconds["fit"] = time.perf_counter() - t0
        fits, failures = fits_frame(db), failures_frame(db)
    failures["path"] = failures["path"].map(lambda p: Path(p).name)
    t0 = time.perf_counter()
    res = pool(fits, draws=pool_draws, chains=4, seed=seed)
    seconds["pool"] = time.perf_counter() - t0
    truth = {(st.name, st.bays[b]): monthly_truth(i, b)
             for i, st in enumerate(ARCHIVE_STATIONS) for b in range(bays)}  # fmt: skip
    mo = res.parts["f_m"].monthly
    mo = mo[mo["station"] != "(all)"].copy()
    mo["truth"] = [truth[(s, b)][m - 1] for s, b, m in zip(mo["station"], mo["bay"], mo["month"],
                                                           strict=True)]  # fmt: skip
    mo["covered"] = (mo["low"] <= mo["truth"]) & (mo["truth"] <= mo["high"])
    events = _events(fits, pd.read_csv(io.BytesIO(files["truth.csv"])))
    sizes = {"stations": len(ARCHIVE_STATIONS), "bays": bays, "records": records,
             "files": scanned.new, "broken": scanned.broken, "events": scanned.events,
             "usable": scanned.usable, "fitted": fitted.done, "fit_failed": fitted.failed,
             "pooled": int(sum(p.events.sum() for p in res.parts.values())),
             "draws": draws, "burn": burn, "chains": chains, "pool_draws": pool_draws,
             "seed": seed,
             "quick": quick}  # fmt: skip
    return ArchiveStudy(res, mo, events, failures, truth, sizes, seconds)


def _events(fits: pd.DataFrame, truth: pd.DataFrame) -> pd.DataFrame:
    """Each fitted event beside its true share (matched by station, bay and time)."""
    t = truth.assign(time=pd.to_datetime(truth["time"])).sort_values("time")
    f = fits.sort_values("time")
    m = pd.merge_asof(f, t[["station", "bay", "time", "f_m"]].rename(columns={"f_m": "true"}),
                      on="time", by=["station", "bay"], tolerance=pd.Timedelta("1s"),
                      direction="nearest")  # fmt: skip
    m["covered"] = (m["lo"] <= m["true"]) & (m["true"] <= m["hi"])
    return m


def _misses(ok: pd.DataFrame) -> str:
    """The events whose interval misses their truth, in words (empty when none does)."""
    miss = ok[~ok["covered"]]
    n, high = len(miss), int((miss["mean"] > miss["true"]).sum())
    if n == 0:
        return ""
    if n == 1:
        who = f"the one that misses it ({'above' if high else 'below'}) is"
    else:
        side = ("all above" if high == n else "all below" if high == 0
                else f"{high} above, {n - high} below")  # fmt: skip
        who = f"the {n} that miss it ({side}) are"
    own = "its own" if n == 1 else "each one's"
    why = ("a bias of the fit on these records (the median ratio above)" if high in (0, n)
           else "more scatter between events than their intervals allow")  # fmt: skip
    return (f"; {who} read further from it than {own} noise allows: {why}, which the pool's "
            "event-to-event spread (tau) takes up")  # fmt: skip


def html_section(study: ArchiveStudy) -> str:
    """The archive section of the report (an HTML ``<section>``)."""
    from loadbayes.plots.archive_pool import names_drawn, plot_pool
    from loadbayes.studies.report import bullet_list, escape, figure_html, frame_html

    s, sec, res = study.sizes, study.seconds, study.pool
    mo = study.monthly
    ev = study.events
    ok = ev[ev["status"] == "ok"]
    ratio = (ok["mean"] / ok["true"]).median() if len(ok) else float("nan")
    gaps = mo.assign(gap=np.maximum(mo["low"] - mo["truth"], mo["truth"] - mo["high"]).clip(0))
    per_unit = (
        gaps.groupby(["station", "bay"], sort=False)
        .agg(events=("events", "first"), months_covered=("covered", "sum"),
             largest_gap=("gap", "max"))
        .reset_index()
        .round({"largest_gap": 3})
    )  # fmt: skip
    columns = {"months_covered": "months covered (of 12)", "largest_gap": "largest miss"}
    names = [n for k in study.truth for n in k]
    with names_drawn(names) as boxes:
        fig = figure_html(
            plot_pool(res, truth=study.truth),
            "Each station's motor share by month (the median event's) with its 95% band; "
            "circles: the truth (the seasonal curve averaged over the month); dashed: the "
            "stations pooled." + (" Names in a script no installed font has are drawn as "
                                  "boxes." if boxes else ""),
        )  # fmt: skip
    fails = study.failures[["what", "path", "station", "bay", "reason"]].fillna("")
    # fits_frame's status: ok, unconverged (R-hat >= 1.05 or ESS < 100), unphysical
    out = ev[ev["status"] != "ok"]["status"].value_counts()
    left = ", ".join(f"{v} {k}" for k, v in out.items()) or "none"
    words = [escape(w) for w in res.warnings + res.notes]
    parts = [
        '<section id="archive">',
        "<h2>A recorder archive: each station's composition over the year</h2>",
        f"<p>The records of <code>loadbayes example archive --records {s['records']} --bays "
        f"{s['bays']}</code>: {s['stations']} stations x {s['bays']} bay(s) x {s['records']} "
        "fault records over 2025 (COMTRADE 1999 in GB18030, ASCII and Latin-1, ASCII and "
        "BINARY data, two files broken), the motor's share of each bay seasonal (highest in "
        "summer) with event-to-event noise (sd 0.03). Run as a user would: <code>archive "
        f"scan</code> ({s['files']} files, {s['broken']} broken, {s['events']} events, "
        f"{s['usable']} usable; {sec['scan']:.0f} s), <code>archive fit</code> (zip+motor, "
        f"the one-cycle phasor window, {s['draws']:,} draws after {s['burn']:,} x "
        f"{s['chains']} chains "
        f"per event: {s['fitted']} fitted, {s['fit_failed']} failed; {sec['fit']:.0f} s), "
        f"<code>archive pool</code> ({s['pool_draws']:,} draws x 4 chains, "
        f"{sec['pool']:.0f} s); the records written in {sec['write']:.0f} s. Left out of the "
        f"pool: {escape(left)} at these draws (R-hat 1.05 or more, or bulk ESS under 100); "
        f"{s['pooled']} events pooled.</p>",
        f"<p>The pooled monthly bands cover the truth in {int(mo['covered'].sum())} of "
        f"{len(mo)} station-months ({mo['covered'].mean():.0%}; issue 38 asks 90%). Each "
        f"event's own fit: median fitted/true motor share {ratio:.2f}, its 95% interval "
        f"holding the event's true share in {int(ok['covered'].sum())} of {len(ok)} events"
        f"{_misses(ok)}. With a few events a "
        "station the bands are wide enough to hold a bias in every event's share; with "
        "many they are not: on the tests' own archive (150 records, 45 events a bay; "
        "tests/statistical/test_archive_end_to_end.py under make validate), whose motors "
        "have the load torque the fit assumes, the per-event fit reads the motor share "
        "1.018 times the truth at this phasor window and the pooled bands hold it in 65 of "
        "72 months; with a constant-torque motor it read 1.066 times high and held 45.</p>",
        fig,
        frame_html(
            per_unit.rename(columns=columns), caption="Each station's bands against the truth"
        ),
        frame_html(fails, caption="Files, bays, events and fits that failed, and why"),
        bullet_list(words) if words else "",
        "</section>",
    ]
    return "\n".join(p for p in parts if p)
