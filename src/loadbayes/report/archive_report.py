"""The report of an archive's catalog: ``loadbayes report archive.db --out archive.html``.

The same page as a fit's (:mod:`loadbayes.report.page`: summary first, contents,
numbered figures inline, no script): the stations and their bays (files, events found,
usable, fitted), the events per month, each station's composition over the year with its
95 % bands, and everything that failed with its reason (broken files and bays, events
not usable, fits failed) and the files whose bays had no dip.

The composition is :func:`loadbayes.archive.pool`'s: run here on the catalog's fits with
modest draws (:data:`POOL_DRAWS` per chain, :data:`POOL_CHAINS` chains, seed 0), or read
from the JSON ``archive pool --out`` wrote (``pool=``); the page says which.
"""

from __future__ import annotations

import html
import json
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from loadbayes.report.page import Page, table_html

__all__ = ["POOL_CHAINS", "POOL_DRAWS", "archive_report", "is_catalog", "write_archive_report"]

#: The pool the report runs when none is given: kept draws per chain and chains.
POOL_DRAWS, POOL_CHAINS = 500, 4
#: Failures listed at most (the rest counted).
MAX_LISTED = 200
SQLITE_HEADER = b"SQLite format 3\x00"
SUFFIXES = (".db", ".sqlite", ".sqlite3")


def is_catalog(path: str | os.PathLike[str]) -> bool:
    """Whether ``path`` is an SQLite file (by its header) or is named as one."""
    p = Path(path)
    if p.suffix.lower() in SUFFIXES:
        return True
    try:
        with open(p, "rb") as fh:
            return fh.read(16) == SQLITE_HEADER
    except OSError:
        return False


@dataclass
class _Part:
    part: str
    units: list[tuple[str, str]]
    monthly: pd.DataFrame
    alike: pd.DataFrame
    groups: list[list[str]]
    diagnostics: dict[str, Any]


@dataclass
class _Pool:
    """A pool read back from its JSON: what the figure and the tables need."""

    parts: dict[str, _Part]
    left_out: dict[str, int]
    warnings: list[str]
    notes: list[str]
    settings: dict[str, Any]
    events: dict[str, int]


def read_pool_json(path: str | os.PathLike[str]) -> _Pool:
    """The JSON of ``archive pool --out`` as the report reads it.

    Raises
    ------
    DataError
        Not JSON, or not an archive pool's (no ``parts`` with ``monthly`` rows).
    """
    from loadbayes.io.errors import DataError

    try:
        d = json.loads(Path(path).read_text(encoding="utf-8"))
        parts = {}
        for name, p in d["parts"].items():
            units = [(u["station"], u["bay"]) for u in p["units"]]
            monthly = pd.DataFrame(p["monthly"])
            need = {"station", "bay", "month", "mean", "low", "high", "events"}
            if not need <= set(monthly.columns):
                raise KeyError(sorted(need - set(monthly.columns))[0])
            parts[name] = _Part(name, units, monthly, pd.DataFrame(p.get("alike", [])),
                                p.get("groups", []), p.get("diagnostics", {}))  # fmt: skip
    except (OSError, UnicodeDecodeError) as exc:
        raise DataError(f"cannot read the pool ({exc})", os.fspath(path)) from None
    except (ValueError, KeyError, TypeError, AttributeError) as exc:
        raise DataError(f"not the JSON of loadbayes archive pool --out (no {exc})",
                        os.fspath(path)) from None  # fmt: skip
    return _Pool(parts, d.get("left_out", {}), d.get("warnings", []), d.get("notes", []),
                 d.get("settings", {}), d.get("events", {}))  # fmt: skip


def _run_pool(fits: pd.DataFrame, db: str):
    """The pool on the catalog's fits (the most fitted model's), or why there is none."""
    from loadbayes.archive import pool
    from loadbayes.io.errors import DataError

    if fits.empty:
        return None, "no event has been fitted yet (run loadbayes archive fit)"
    model = fits.groupby("model")["event_id"].nunique().idxmax()
    try:
        res = pool(fits[fits["model"] == model], draws=POOL_DRAWS, chains=POOL_CHAINS, seed=0,
                   source=db)  # fmt: skip
    except DataError as exc:
        return None, str(exc)
    return res, (f"pooled here from the catalog's {model} fits: {POOL_DRAWS} draws x "
                 f"{POOL_CHAINS} chains after {POOL_DRAWS // 2} of burn-in, seed 0 (give "
                 "--pool pool.json for a pool run with more)")  # fmt: skip


def _month_counts(events: pd.DataFrame) -> tuple[list[str], list[list[str]]]:
    from loadbayes.archive.pool import MONTHS

    rows = []
    ev = events.dropna(subset=["time"])
    for station, g in ev.groupby("station", sort=True):
        c = g["time"].dt.month.value_counts()
        u = g[g["usable"] == 1]["time"].dt.month.value_counts()
        cells = [f"{int(c.get(m, 0))} ({int(u.get(m, 0))})" for m in range(1, 13)]
        rows.append([str(station), *cells, f"{len(g)} ({int(g['usable'].sum())})"])
    years = sorted(ev["time"].dt.year.unique()) if len(ev) else []
    head = ["station"] + list(MONTHS) + ["year" if len(years) <= 1 else "all"]
    return head, rows


def archive_report(
    db: str | os.PathLike[str],
    *,
    pool: str | os.PathLike[str] | None = None,
    title: str | None = None,
) -> str:
    """The HTML report of an archive's catalog.

    Parameters
    ----------
    db : str or os.PathLike
        The catalog of ``loadbayes archive scan`` (and ``archive fit``).
    pool : str or os.PathLike, optional
        The JSON of ``archive pool --out``; without it the pool is run here with
        :data:`POOL_DRAWS` draws x :data:`POOL_CHAINS` chains.
    title : str, optional
        The page's title.

    Returns
    -------
    str
        A self-contained HTML page.
    """
    from loadbayes._version import __version__
    from loadbayes.archive import events_frame, failures_frame, fits_frame, units_frame
    from loadbayes.report.figures import png

    e = html.escape
    name = Path(db).name
    units, events = units_frame(db), events_frame(db)
    fails, fits = failures_frame(db), fits_frame(db)
    if pool is not None:
        res, how = read_pool_json(pool), f"read from {Path(pool).name} (archive pool --out)"
    else:
        res, how = _run_pool(fits, os.fspath(db))
    page = Page(title or f"Archive {name}", f"Report of {name}, with loadbayes {__version__}.")

    # ------------------------------------------------------------ summary
    loads = units[units["status"] == "ok"]
    stations = sorted(loads["station"].dropna().unique())
    files = fails[fails["what"] == "file"]
    n_fit_bad = int((fails["what"] == "fit").sum())
    summary = [
        f"<p>{len(stations)} station(s), {len(loads)} load bay(s); {len(events):,} event(s) "
        f"found, {int(events['usable'].sum()):,} usable, {int(loads['fitted'].sum()):,} "
        f"fitted ({n_fit_bad} fit(s) failed); {len(files)} file(s) could not be read.</p>",
        f"<p>The composition over the year: {e(how)}.</p>" if res is not None else
        f"<p class='warn'>No composition over the year: {e(how)}.</p>",
    ]  # fmt: skip
    if fits is not None and len(fits):
        bad = fits[fits["status"] != "ok"]
        if len(bad):
            why = ", ".join(f"{k} {v}" for k, v in bad["status"].value_counts().items())
            summary.append(
                f"<p class='warn'>{len(bad)} of {len(fits)} fitted share(s) are left out of "
                f"the pool ({e(why)}): "
                "an event whose chains did not mix (R-hat 1.05 or more, or bulk ESS under 100) "
                "says little yet (a fit is kept once done: more --draws need a fresh "
                "catalog).</p>"
            )  # fmt: skip
    if res is not None:
        for w in res.warnings:
            summary.append(f"<p class='warn'>{e(w)}</p>")
    page.summary("".join(summary))

    # ------------------------------------------------------------ stations and bays
    sec = page.section("Stations and bays")
    rows = [[str(r.station), str(r.bay), str(r.kind), str(r.status), f"{r.files:,}",
             f"{r.events:,}", f"{r.usable:,}", f"{r.fitted:,}", f"{r.fit_failed:,}"]
            for r in units.itertuples()]  # fmt: skip
    sec.add(table_html(["station", "bay", "kind", "status", "files", "events", "usable",
                        "fitted", "fits failed"], rows, text_cols=(0, 1, 2, 3)))  # fmt: skip
    sec.text("Each bay as the records name it, with the kind the name rules gave it (a "
             "'skipped' bay is not a load by the rules); events are the dips the trigger "
             "found, usable those the fit can take (the voltage recovered, the bay draws "
             "power before the dip).")  # fmt: skip

    # ------------------------------------------------------------ events per month
    sec = page.section("Events per month")
    head, rows = _month_counts(events)
    if rows:
        sec.add(table_html(head, rows, wide=True))
        sec.text("Events found per station and month of their recorder's clock, usable in "
                 "brackets (every bay of a record counts its own).")  # fmt: skip
    else:
        sec.text("No event found.")

    # ------------------------------------------------------------ composition
    sec = page.section("Composition over the year")
    if res is None:
        sec.text(f"Not drawn: {how}.")
    else:
        from loadbayes.plots.archive_pool import names_drawn, plot_pool

        names = [n for p in res.parts.values() for u in p.units for n in u]
        with names_drawn(names) as boxes:
            image = png(plot_pool(res))
        sec.figure(image,
                   "Each station's share by month (the median event's, per bay) with its 95% "
                   "band; dashed: the stations pooled."
                   + (" No installed font has the ideographs of some names: they are drawn "
                      "as boxes (the tables name them)." if boxes else ""),
                   alt="monthly shares per station and bay with bands")  # fmt: skip
        sec.text(f"The pool: {how}.")
        for part in res.parts.values():
            sec.add(_monthly_table(part))
            if len(part.alike):
                rows = [[str(r["a"]), str(r["b"]), f"{r['prob_alike']:.2f}",
                         _apart_cell(r), f"{r['max_diff_median']:.2f}", str(r["verdict"])]
                        for _, r in part.alike.iterrows()]  # fmt: skip
                sec.add(table_html(["unit", "unit", "P(alike)", "P(apart)",
                                    "largest gap (median)", "verdict"], rows,
                                   text_cols=(0, 1, 5),
                                   caption=f"{part.part}: which bays are alike"))  # fmt: skip
        left = [f"{k}: {v}" for k, v in res.left_out.items() if v]
        if n_fit_bad:
            left.append(f"no fit (it failed; see below): {n_fit_bad}")
        counts = getattr(res, "events", None) or {}
        pooled = (f"{counts['pooled']} of {counts['rows']} fitted event shares pooled. "
                  if {"pooled", "rows"} <= set(counts) else "")  # fmt: skip
        sec.text(f"{pooled}Events left out of the pool: {', '.join(left) or 'none'}.")
        for n in res.notes:
            sec.text(n)

    # ------------------------------------------------------------ failures
    sec = page.section("What failed, and why")
    if fails.empty:
        sec.text("Every file was read, every event was usable and every fit finished.")
    else:
        shown = fails.head(MAX_LISTED)
        rows = [[str(r.what), _short(r.path), _text(r.station), _text(r.bay), _text(r.reason)]
                for r in shown.itertuples()]  # fmt: skip
        sec.add(table_html(["what", "file", "station", "bay", "reason"], rows,
                           text_cols=(0, 1, 2, 3, 4), wide=True))  # fmt: skip
        if len(fails) > MAX_LISTED:
            sec.text(f"... and {len(fails) - MAX_LISTED:,} more (loadbayes.archive."
                     "failures_frame has them all).")  # fmt: skip
    quiet = events_less(db)
    if quiet:
        sec.text(f"{len(quiet)} file(s) were read but no bay had a dip (a trigger for another "
                 "reason): " + ", ".join(_short(p) for p in quiet[:20])
                 + (" ..." if len(quiet) > 20 else "") + ".")  # fmt: skip
    return page.render()


def events_less(db: str | os.PathLike[str]) -> list[str]:
    """The files read (``ok``) with no event in any bay."""
    from loadbayes.archive.catalog import connect

    with connect(db) as conn:
        rows = conn.execute(
            "SELECT path FROM files f WHERE status = 'ok' AND NOT EXISTS "
            "(SELECT 1 FROM events e WHERE e.file_id = f.file_id) ORDER BY path"
        ).fetchall()
    return [r[0] for r in rows]


def _monthly_table(part: Any) -> str:
    from loadbayes.archive.pool import MONTHS

    rows = []
    for (station, bay), g in part.monthly.groupby(["station", "bay"], sort=False):
        g = g.sort_values("month")
        who = f"{station} / {bay}" if station != "(all)" else "all stations" + (
            "" if bay == "(all)" else f" / {bay}")  # fmt: skip
        rows.append([who, f"{int(g['events'].iloc[0])}"] + [
            f"{m:.2f} [{lo:.2f}, {hi:.2f}]"
            for m, lo, hi in zip(g["mean"], g["low"], g["high"], strict=True)])  # fmt: skip
    return table_html(["station / bay", "events", *MONTHS], rows, wide=True,
                      caption=f"{part.part} by month: mean [95% band]")  # fmt: skip


def _apart_cell(row: Any) -> str:
    """P(apart) of a pair, or a dash for a pool written before it was kept."""
    v = row.get("prob_apart")
    return "-" if v is None or pd.isna(v) else f"{v:.2f}"


def _text(v: Any) -> str:
    return "" if v is None or (isinstance(v, float) and np.isnan(v)) else str(v)


def _short(path: Any) -> str:
    """The path's last two parts (the folder and the file), which say where it is."""
    p = Path(_text(path))
    return str(Path(*p.parts[-2:])) if len(p.parts) > 1 else str(p)


def write_archive_report(
    db: str | os.PathLike[str],
    out: str | os.PathLike[str],
    *,
    pool: str | os.PathLike[str] | None = None,
    title: str | None = None,
    force: bool = False,
) -> Path:
    """Write the catalog's report atomically (nothing written if anything fails)."""
    from loadbayes.io.atomic import atomic_write

    text = archive_report(db, pool=pool, title=title)
    out = Path(out)
    with atomic_write(out, force=force) as tmp:
        Path(tmp).write_text(text, encoding="utf-8")
    return out
