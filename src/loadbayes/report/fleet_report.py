"""The report of a fleet: ``loadbayes report fleet.parquet --out fleet.html``.

The same page as a single fit's (:mod:`loadbayes.report.page`: summary first, contents,
numbered figures inline, no script): the class mixes with their intervals, the shrinkage
of the buses towards their classes, the buses flagged (not fitted, unconverged, few
effective draws, thin, flat voltage) in a table, dP/dV and dQ/dV per bus (a map when
coordinates exist), the other warnings grouped, and the run's settings. What the table
does not hold is said in so many words ("not in this file").
"""

from __future__ import annotations

import html
import re
from collections import Counter
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from loadbayes.core.display import DESCRIPTIONS, fmt, fmt_like, precision_sd
from loadbayes.report.fleet_table import (
    ESS_LIMIT,
    RHAT_LIMIT,
    THIN_ROWS,
    FleetTable,
    load_fleet,
    read_coords,
    table_coords,
)
from loadbayes.report.page import Page, table_html

__all__ = ["fleet_report", "write_fleet_report"]

#: Flagged buses listed in the table at most (the rest counted).
MAX_LISTED = 200
NOT_IN_FILE = "not in this file"


def _interval(r: pd.Series) -> str:
    if not np.isfinite(r["hdi_low"]):
        return "–"
    digits = precision_sd(r["sd"], r["hdi_low"], r["hdi_high"])
    return f"{fmt_like(r['hdi_low'], digits)} to {fmt_like(r['hdi_high'], digits)}"


def _class_table(ft: FleetTable, pct: str) -> tuple[list[str], list[list[str]], list[bool]]:
    rows, flags = [], []
    for _, r in ft.class_rows.dropna(subset=["parameter"]).iterrows():
        p = str(r["parameter"])
        what = DESCRIPTIONS.get(p) or (
            f"spread of {p[3:]} within the class" if p.startswith("sd_") else ""
        )
        bad = (np.isfinite(r["r_hat"]) and r["r_hat"] > RHAT_LIMIT) or (
            np.isfinite(r["ess_bulk"]) and r["ess_bulk"] < ESS_LIMIT
        )
        rows.append([r["class"], p, what, fmt_like(r["mean"], r["sd"]), _interval(r),
                     "–" if not np.isfinite(r["r_hat"]) else f"{r['r_hat']:.3f}",
                     "–" if not np.isfinite(r["ess_bulk"]) else f"{r['ess_bulk']:,.0f}",
                     r["warnings"]])  # fmt: skip
        flags.append(bool(bad))
    head = ["class", "parameter", "meaning", "mean", f"{pct} interval", "R-hat", "ESS",
            "warnings"]  # fmt: skip
    return head, rows, flags


def _grouped_warnings(ft: FleetTable) -> list[tuple[str, int]]:
    """Distinct bus warnings with their counts, numbers replaced by '#'."""
    counts: Counter[str] = Counter()
    number = re.compile(r"(?<![A-Za-z_\d])-?\d+(\.\d+)?(e[-+]?\d+)?")
    per_bus = ft.bus_rows.groupby("bus", sort=False)["warnings"].first()
    for text in per_bus:
        for w in set(number.sub("#", t) for t in text.split(" | ")):
            if w:
                counts[w] += 1
    return counts.most_common()


def fleet_report(
    ft: FleetTable,
    *,
    unpooled: FleetTable | None = None,
    coords: pd.DataFrame | None = None,
    coord_names: tuple[str, str] = ("x", "y"),
    title: str | None = None,
    source: str | None = None,
) -> str:
    """The HTML report of a fleet table.

    Parameters
    ----------
    ft : FleetTable
        From :func:`~loadbayes.report.fleet_table.load_fleet`.
    unpooled : FleetTable, optional
        A ``--pool none`` run of the same buses: each bus's own estimate, for the
        shrinkage figure of a pooled run.
    coords : DataFrame, optional
        Bus coordinates (index: bus id as text; columns ``x``, ``y``), from
        :func:`~loadbayes.report.fleet_table.read_coords`; else those in the table.
    coord_names : (str, str)
        The coordinates' column names, for the axes.
    title, source : str, optional
        Page title; the result file, named in the page.

    Returns
    -------
    str
        A self-contained HTML page.
    """
    from loadbayes._version import __version__
    from loadbayes.report.fleet_figures import (
        class_mix_figure,
        sensitivity_figure,
        shrinkage_figure,
    )

    e = html.escape
    st = ft.settings
    hdi = float(st.get("hdi_prob", 0.95))
    pct = f"{hdi:.0%}"
    buses = ft.bus_rows["bus"].nunique()
    fitted = ft.bus_rows.dropna(subset=["parameter"])["bus"].nunique()
    classes = sorted(set(ft.bus_rows["class"]))
    flagged = ft.flagged()
    data = st.get("data")
    page = Page(
        title or f"Fleet of {buses:,} buses" + (f": {data}" if data else ""),
        "Report" + (f" of {source}" if source else "")
        + (f", fitted with loadbayes {st['loadbayes_version']}" if st.get("loadbayes_version")
           else "")
        + f", reported with {__version__}.",
    )  # fmt: skip

    # ------------------------------------------------------------ summary
    how = (
        "pooled within classes (hierarchical model)"
        if ft.pooled
        else "each bus on its own (no pooling)"
    )
    summary = [
        f"<p>ZIP load models of {buses:,} buses in {len(classes)} "
        f"class{'es' if len(classes) != 1 else ''} ({e(', '.join(classes))}), fitted {how}; "
        f"{fitted:,} fitted, {buses - fitted:,} not.</p>"
    ]
    if ft.pooled:
        mix = ft.class_rows[ft.class_rows["parameter"].isin(["a1", "a2", "a3"])]
        rows = []
        for c in sorted(set(mix["class"])):
            r = mix[mix["class"] == c].set_index("parameter")
            rows.append([c, f"{int(r['n'].max()):,}"] + [
                f"{fmt_like(r.loc[p, 'mean'], r.loc[p, 'sd'])} ({_interval(r.loc[p])})"
                if p in r.index else NOT_IN_FILE for p in ("a1", "a2", "a3")])  # fmt: skip
        if rows:
            cap = f"Class mean shares of P, {pct} intervals"
            head = ["class", "buses", "a1 (Z)", "a2 (I)", "a3 (P)"]
            summary.append(table_html(head, rows, caption=cap))
        rh = ft.class_rows["r_hat"].max(skipna=True)
        ess = ft.class_rows["ess_bulk"].min(skipna=True)
        cr = ft.class_rows
        bad = (cr["r_hat"] > RHAT_LIMIT) | (cr["ess_bulk"] < ESS_LIMIT)
        if "converged" in cr.columns:
            bad |= cr["converged"].map(lambda v: False if pd.isna(v) else not bool(v))
        bad_cls = cr[bad.astype(bool)]
        if np.isfinite(rh):
            ok = bad_cls.empty
            names = ", ".join(sorted(set(bad_cls["class"])))
            text = (
                f"Class-level chains agree: largest R-hat {rh:.3f}, smallest ESS {ess:,.0f}."
                if ok
                else f"Class-level chains may not have converged in {names}: largest R-hat "
                f"{rh:.3f} (limit {RHAT_LIMIT}), smallest ESS {ess:,.0f} (at least "
                f"{ESS_LIMIT} wanted). Run longer (--draws) before using these numbers."
            )
            summary.append(f"<p class='{'ok' if ok else 'warn'}'>{e(text)}</p>")
    else:
        summary.append(
            "<p>No pooling: there are no class estimates in this file; the class mixes "
            "section shows how the buses' own estimates spread in each class.</p>"
        )
    kinds = Counter(k.split(":")[0].split(" (")[0] for rs in flagged["reasons"] for k in rs)
    if len(flagged):
        listed = "; ".join(f"{n:,} {k}" for k, n in kinds.most_common(6))
        summary.append(
            f"<div class='warn'><b>{len(flagged):,} of {buses:,} buses flagged</b> ({e(listed)})"
            ": see <a href='#buses-flagged'>Buses flagged</a>.</div>"
        )
    else:
        summary.append("<p class='ok'>No bus flagged.</p>")
    run_warn = st.get("warnings") or []
    if isinstance(run_warn, str):
        run_warn = [run_warn]
    if st.get("stop"):
        stop = str(st["stop"])  # run_fleet writes "stopped after N sweeps per chain: why"
        words = (
            "The chains " + stop if stop.startswith("stopped ") else "The chains stopped: " + stop
        )
        summary.append(f"<p>{e(words)}</p>")
    if run_warn:
        items = "".join(f"<li>{e(str(w))}</li>" for w in run_warn)
        summary.append(f"<div class='warn'><b>Run warnings</b><ul>{items}</ul></div>")
    cls_warn = [w for w in ft.class_rows["warnings"].unique() if w]
    if cls_warn:
        items = "".join(f"<li>{e(w)}</li>" for w in cls_warn)
        summary.append(f"<div class='warn'><b>Class warnings</b><ul>{items}</ul></div>")
    page.summary("".join(summary))

    # ------------------------------------------------------------ class mixes
    sec = page.section("Class mixes")
    fig = class_mix_figure(ft, hdi_prob=hdi)
    if fig is not None:
        sec.figure(fig.png, fig.caption, alt=fig.alt, title=fig.title)
    if ft.pooled:
        head, rows, flags = _class_table(ft, pct)
        sec.add(table_html(head, rows, text_cols=(0, 1, 2, 7), flags=flags, wide=True))
        has_spread = ft.class_rows["parameter"].astype(str).str.startswith("sd_").any()
        sec.text(
            f"Each class's mean shares (a1..a6) with their {pct} intervals, R-hat and bulk "
            "ESS; rows in red have R-hat above "
            f"{RHAT_LIMIT} or ESS below {ESS_LIMIT}. "
            + ("sd_a1.. are the spreads of the buses' shares within the class."
               if has_spread else f"Within-class spreads (sd_a1..): {NOT_IN_FILE}.")
        )  # fmt: skip

    # ------------------------------------------------------------ shrinkage
    sec = page.section("Shrinkage")
    own, own_src = ft.unpooled(unpooled)
    fig = shrinkage_figure(ft, own, own_src)
    if not ft.pooled:
        sec.text("No pooling in this run: every bus keeps its own estimate (no shrinkage).")
    else:
        if fig is not None:
            sec.figure(fig.png, fig.caption, alt=fig.alt, title=fig.title)
        if own is None:
            sec.text(
                f"The buses' own (unpooled) estimates: {NOT_IN_FILE}. Give a --pool none run "
                "of the same data (loadbayes report fleet.parquet --unpooled none.parquet) "
                "to draw each bus's pooled estimate against its own."
            )
        if "shrinkage" in ft.table.columns and ft.bus_rows["shrinkage"].notna().any():
            s = ft.bus_rows.groupby("bus", sort=False).agg(
                cls=("class", "first"), s=("shrinkage", "first")
            )
            rows = [[c, f"{len(g):,}", fmt(g['s'].median(), 2), fmt((g['s'] > 0.5).mean(), 2)]
                    for c, g in s.dropna().groupby("cls")]  # fmt: skip
            sec.add(table_html(["class", "buses", "median shrinkage", "share above 0.5"], rows))
        else:
            sec.text(f"Shrinkage per bus: {NOT_IN_FILE}.")

    # ------------------------------------------------------------ flagged
    sec = page.section("Buses flagged")
    sec.text(
        f"A bus is flagged when it was not fitted, when its chains disagree (R-hat above "
        f"{RHAT_LIMIT} on any parameter), when its draws are few (bulk ESS below "
        f"{ESS_LIMIT}), when it is thin (fewer than {THIN_ROWS} rows) or when its voltage "
        "hardly moved (flat: its shares then come mostly from its class, or are not "
        "identified), or when its data do not tell a1 from a2 (a4 from a5) along the "
        "curvature a1 - 2 a2 + a3 (the split of its shares is then its class's; its dP/dV "
        "and dQ/dV are what its data fix)."
    )
    if len(flagged):
        shown = flagged.head(MAX_LISTED)
        rows = [[str(r["bus"]), str(r["class"]), f"{r['n']:,}", "; ".join(r["reasons"])]
                for _, r in shown.iterrows()]  # fmt: skip
        sec.add(table_html(["bus", "class", "rows", "why"], rows, text_cols=(0, 1, 3),
                           wide=True))  # fmt: skip
        if len(flagged) > MAX_LISTED:
            sec.text(f"... and {len(flagged) - MAX_LISTED:,} more (the table's 'warnings' "
                     "column has them all).")  # fmt: skip
    else:
        sec.text("No bus is flagged.")
    grouped = _grouped_warnings(ft)
    if grouped:
        rows = [[w, f"{n:,}"] for w, n in grouped[:12]]
        sec.add(table_html(["warning (numbers shown as #)", "buses"], rows, text_cols=(0,),
                           wide=True))  # fmt: skip
        sec.text("Every distinct warning of the bus rows, with how many buses carry it.")

    # ------------------------------------------------------------ sensitivity
    sec = page.section("Voltage sensitivity")
    sens, where, unit = {}, {}, {}
    for k in ("dp_dv", "dq_dv"):
        sens[k], where[k], unit[k] = ft.sensitivity(k)
    if coords is None:
        coords, coord_names = table_coords(ft)
    fig = sensitivity_figure(ft, sens, unit, coords, coord_names, set(flagged["bus"].astype(str)))
    if fig is not None:
        sec.figure(fig.png, fig.caption, alt=fig.alt, title=fig.title)
    for k, lab in (("dp_dv", "dP/dV"), ("dq_dv", "dQ/dV")):
        if sens[k] is None:
            sec.text(f"{lab}: {NOT_IN_FILE}.")
        else:
            s = sens[k]["mean"]
            ivl = "with intervals" if sens[k]["hdi_low"].notna().any() else "no intervals"
            sec.text(
                f"{lab} from {where[k]} ({ivl}): median {fmt(s.median())}, 5% to 95% of the "
                f"buses {fmt(s.quantile(0.05))} to {fmt(s.quantile(0.95))} ({unit[k]})."
            )
    if coords is None:
        sec.text(
            "No coordinates (x/y or lat/lon) in this file: give --coords FILE, a CSV or "
            "Parquet table with the bus column and x, y or lat, lon (the fleet's input will "
            "do), for a map."
        )
    else:
        missing = sorted(set(ft.bus_rows["bus"].astype(str)) - set(coords.index))
        if missing:
            sec.text(f"{len(missing):,} buses have no coordinates and are not on the map, "
                     f"e.g. {missing[0]}.")  # fmt: skip

    # ------------------------------------------------------------ settings
    _settings_section(page, ft)
    return page.render()


def _settings_section(page: Page, ft: FleetTable) -> None:
    sec = page.section("Settings")
    st = ft.settings
    params = [str(p) for p in ft.bus_rows["parameter"].dropna().unique()]
    known = {
        "rows in the table": f"{len(ft.table):,}",
        "pooling": "class (hierarchical)" if ft.pooled else "none",
        "bus parameters": ", ".join(params),
        "columns": ", ".join(map(str, ft.table.columns)),
    }
    for k, v in st.items():
        if v is not None and k not in ("loadbayes_version", "warnings"):
            known[k.replace("_", " ")] = _plain(v)
    items = "".join(f"<dt>{html.escape(k)}</dt><dd>{html.escape(str(v))}</dd>"
                    for k, v in known.items())  # fmt: skip
    sec.add(f"<dl class='settings'>{items}</dl>")
    if not st:
        sec.text(f"The run's settings (data, columns, sampler, seed): {NOT_IN_FILE} (written "
                 "by an older loadbayes, or from Python without them).")  # fmt: skip


def _plain(v: Any) -> str:
    if isinstance(v, dict):
        return ", ".join(f"{k} = {_plain(w)}" for k, w in v.items() if w is not None)
    if isinstance(v, list | tuple):
        return "; ".join(_plain(w) for w in v)
    if isinstance(v, float) and np.isfinite(v):
        return fmt(v)
    return str(v)


def write_fleet_report(
    result: str | Path,
    out: str | Path,
    *,
    unpooled: str | Path | None = None,
    coords: str | Path | None = None,
    title: str | None = None,
    force: bool = False,
) -> Path:
    """Read a fleet table (and optional files) and write its report atomically.

    Raises
    ------
    DataError
        A file that cannot be read or is not what it should be (file, column, row), or
        ``out`` exists and ``force`` is False.
    """
    from loadbayes.io.atomic import atomic_write
    from loadbayes.io.errors import DataError

    ft = load_fleet(result)
    if ft.settings.get("kind") == "cvr-fleet":  # loadbayes cvr --by: its own page
        from loadbayes.report.cvr_fleet import cvr_fleet_page

        text = cvr_fleet_page(ft.table, ft.settings, title=title, source=Path(result).name)
        with atomic_write(Path(out), force=force) as tmp:
            Path(tmp).write_text(text, encoding="utf-8")
        return Path(out)
    other = load_fleet(unpooled) if unpooled else None
    if other is not None:  # the figure calls them each bus's own, unpooled estimates
        if other.settings.get("pool") == "class" or (other.table["level"] == "class").any():
            raise DataError(
                "a pooled fit (--pool class); --unpooled wants a --pool none table", str(unpooled)
            )
        if not set(ft.bus_rows["bus"]) & set(other.bus_rows["bus"]):
            raise DataError(f"none of the buses of {Path(result).name} (--unpooled)", str(unpooled))
    xy, names = (None, ("x", "y"))
    if coords:
        xy, names = read_coords(coords, by=ft.settings.get("by"))
    text = fleet_report(ft, unpooled=other, coords=xy, coord_names=names, title=title,
                        source=Path(result).name)  # fmt: skip
    out = Path(out)
    with atomic_write(out, force=force) as tmp:
        Path(tmp).write_text(text, encoding="utf-8")
    return out
