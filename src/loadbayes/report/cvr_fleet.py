"""A fleet's CVR: the feeder-by-feeder table, the lines ``loadbayes cvr --by`` prints, the page.

The page (``loadbayes report cvr_fleet.parquet --out page.html``, the fleet report's
page layout, :mod:`loadbayes.report.page`): a summary, the feeders' energy CVR factors
and dP/dV with their intervals and flags in one table, a figure of both factors feeder by
feeder, the class rows when pooled, the flags counted, and the run's settings.
"""

from __future__ import annotations

import html
from typing import Any

import numpy as np
import pandas as pd

from loadbayes.core.display import fmt
from loadbayes.report.figures import png
from loadbayes.report.page import Page, table_html

__all__ = ["FLAG_LABELS", "cvr_fleet_lines", "cvr_fleet_page", "feeder_table"]

#: A flag's short label in the table, from the fixed start of its warning
#: (:data:`loadbayes.fleet.cvr.FLAGS`).
FLAG_LABELS = {
    "head voltage answers to the load": "head V answers to load",
    "reverse flow": "reverse flow",
    "glitches left out": "glitches",
}
PARAMS = ("cvr_p", "cvr_q", "dp_dv", "dq_dv")


def feeder_table(table: pd.DataFrame) -> pd.DataFrame:
    """One row per feeder: each factor's mean and interval, the flags, what went wrong."""
    bus = table[table["level"] == "bus"]
    rows = []
    for name, g in bus.groupby("bus", sort=True):
        r: dict[str, Any] = {"feeder": name, "class": g["class"].iloc[0]}
        for p in PARAMS:
            one = g[g["parameter"] == p]
            ok = len(one) == 1
            r[p] = float(one["mean"].iloc[0]) if ok else np.nan
            r[f"{p}_low"] = float(one["hdi_low"].iloc[0]) if ok else np.nan
            r[f"{p}_high"] = float(one["hdi_high"].iloc[0]) if ok else np.nan
        words = str(g["warnings"].iloc[0] or "")
        said = [w.strip() for w in words.split(" | ") if w.strip()]
        r["flags"] = ", ".join(lab for key, lab in FLAG_LABELS.items()
                               if any(w.startswith(key) for w in said))  # fmt: skip
        r["fitted"] = bool(g["parameter"].notna().any())
        r["warnings"] = words
        rows.append(r)
    return pd.DataFrame(rows)


def _iv(r, p: str) -> str:
    if not np.isfinite(r[p]):
        return "–"
    return f"{r[p]:.2f} [{r[p + '_low']:.2f}, {r[p + '_high']:.2f}]"


def cvr_fleet_lines(table: pd.DataFrame, settings: dict[str, Any]) -> list[str]:
    """The lines printed: a header, then one line per feeder, then the class rows."""
    wide = feeder_table(table)
    hp = 100 * settings.get("hdi_prob", 0.95)
    out = [f"feeder by feeder ({hp:.0f}% intervals): energy CVR factor P (%dE/%dV) | "
           "dP/dV at the steps' voltage | flags"]  # fmt: skip
    for _, r in wide.iterrows():
        if not r["fitted"]:
            out.append(f"  {r['feeder']}: not fitted: {r['warnings']}")
            continue
        out.append(f"  {r['feeder']}: {_iv(r, 'cvr_p')} | {_iv(r, 'dp_dv')} | "
                   f"{r['flags'] or 'none'}")  # fmt: skip
    cls = table[table["level"] == "class"]
    for name, g in cls.groupby("class", sort=True):
        parts = [f"{r['parameter']} {r['mean']:.2f} [{r['hdi_low']:.2f}, {r['hdi_high']:.2f}]"
                 for _, r in g.iterrows()]  # fmt: skip
        out.append(f"  class {name} ({int(g['n'].iloc[0])} feeders, pooled): " + "; ".join(parts))
    return out


def _figure(wide: pd.DataFrame) -> bytes | None:
    from loadbayes.plots.fit import pyplot

    ok = wide[wide["fitted"]]
    if ok.empty:
        return None
    plt = pyplot()
    k = len(ok)
    fig, axes = plt.subplots(1, 2, figsize=(10, 0.9 + 0.28 * k), sharey=True)
    y = np.arange(k)[::-1]
    panels = ((axes[0], "cvr_p", "energy CVR factor, P (%dE/%dV)"),
              (axes[1], "dp_dv", "dP/dV at the steps' voltage (p.u./p.u.)"))  # fmt: skip
    for ax, p, label in panels:
        m = ok[p].to_numpy()
        lo, hi = ok[f"{p}_low"].to_numpy(), ok[f"{p}_high"].to_numpy()
        flag = ok["flags"].str.len().to_numpy() > 0
        for sel, col in ((~flag, "C0"), (flag, "C3")):
            ax.errorbar(m[sel], y[sel], xerr=[m[sel] - lo[sel], hi[sel] - m[sel]], fmt="o",
                        color=col, ms=4, capsize=2)  # fmt: skip
        ax.axvline(0.0, color="0.6", lw=0.8)
        ax.set_xlabel(label)
    axes[0].set_yticks(y)
    axes[0].set_yticklabels(ok["feeder"].astype(str).tolist(), fontsize=7)
    return png(fig)


def cvr_fleet_page(
    table: pd.DataFrame, settings: dict[str, Any], *, title: str | None = None, source: str = ""
) -> str:
    """The HTML page of a fleet's CVR table (module notes)."""
    wide = feeder_table(table)
    hp = 100 * settings.get("hdi_prob", 0.95)
    page = Page(title or "CVR factors of a fleet of feeders", source)
    fitted = wide[wide["fitted"]]
    counts = {lab: int(fitted["flags"].str.contains(lab, regex=False).sum())
              for lab in FLAG_LABELS.values()}  # fmt: skip
    med = float(np.nanmedian(fitted["cvr_p"])) if len(fitted) else float("nan")
    summary = (f"{len(fitted)} of {len(wide)} feeders fitted ({settings.get('pool', 'none')} "
               f"pooling); median energy CVR factor {fmt(med)}; flags: "
               + ", ".join(f"{lab} on {n}" for lab, n in counts.items()))  # fmt: skip
    page.summary(f"<p>{html.escape(summary)}</p>")
    sec = page.section("Feeder by feeder")
    rows = [[str(r["feeder"]), str(r["class"] if r["class"] is not None else "–"),
             _iv(r, "cvr_p"), _iv(r, "cvr_q"), _iv(r, "dp_dv"), _iv(r, "dq_dv"),
             r["flags"] or ("not fitted" if not r["fitted"] else "")]
            for _, r in wide.iterrows()]  # fmt: skip
    sec.add(table_html(["feeder", "class", "CVR P", "CVR Q", "dP/dV", "dQ/dV", "flags"], rows,
                       text_cols=(0, 1, 6), flags=[bool(r[6]) for r in rows], wide=True,
                       caption=f"means and {hp:.0f}% intervals; energy factors in %dE/%dV, "
                       "dP/dV per unit of the level at the steps' median voltage"))  # fmt: skip
    fig = _figure(wide)
    if fig is not None:
        cap = f"Each feeder's energy CVR factor and dP/dV, {hp:.0f}% intervals; red: flagged."
        sec.figure(fig, cap, alt="feeder-by-feeder intervals")
    cls = table[table["level"] == "class"]
    if len(cls):
        s = page.section("Classes (pooled)")
        s.text(
            "Each class's mean and the spread between its feeders (normal-normal pooling of "
            "each feeder's posterior); the feeders' rows above are then their pooled values."
        )
        s.add(table_html(["class", "parameter", "mean", "interval"],
                         [[str(r["class"]), str(r["parameter"]), fmt(r["mean"]),
                           f"{fmt(r['hdi_low'])} to {fmt(r['hdi_high'])}"]
                          for _, r in cls.iterrows()], text_cols=(0, 1)))  # fmt: skip
    s = page.section("Flags and warnings")
    s.text(
        "A head voltage that answers to the load: the factors are then fitted from the "
        "on/off switching and the voltage steps only (outside causes of V), never from every "
        "move of V. Reverse flow: the factors are per unit of the net load at the head."
    )
    for _, r in wide[wide["warnings"] != ""].iterrows():
        s.text(f"{r['feeder']}: {r['warnings']}")
    s = page.section("Settings")
    keep = {k: v for k, v in settings.items() if k != "feeders"}
    s.add(table_html(["setting", "value"], [[k, str(v)] for k, v in keep.items()]))
    return page.render()
