"""The figure of ``archive pool``: each station's composition over the year, with bands."""

from __future__ import annotations

import warnings
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any

import numpy as np

__all__ = ["CJK_FONTS", "names_drawn", "plot_pool"]

#: Fonts with CJK ideographs, tried (when installed) for station and bay names.
CJK_FONTS = ("Noto Sans CJK SC", "Noto Sans SC", "Source Han Sans SC", "WenQuanYi Zen Hei",
             "WenQuanYi Micro Hei", "SimHei", "Microsoft YaHei", "PingFang SC",
             "Hiragino Sans GB", "AR PL UMing CN")  # fmt: skip


@contextmanager
def names_drawn(names: list[str]) -> Iterator[bool]:
    """While a figure with these names is drawn: CJK fonts as fallbacks where installed.

    Yields whether some name has ideographs no installed font has: those glyphs are drawn
    as boxes (matplotlib's warning for each is silenced; the caller says it in words).
    """
    import matplotlib as mpl
    from matplotlib import font_manager

    have = {f.name for f in font_manager.fontManager.ttflist}
    extra = [f for f in CJK_FONTS if f in have]
    cjk = any(0x2E80 <= ord(c) <= 0x9FFF or 0xF900 <= ord(c) <= 0xFAFF for n in names for c in n)
    rc = {"font.sans-serif": [*mpl.rcParams["font.sans-serif"], *extra]} if extra else {}
    with mpl.rc_context(rc), warnings.catch_warnings():
        warnings.filterwarnings("ignore", message="Glyph .* missing from font")
        yield cjk and not extra


def plot_pool(result: Any, *, truth: dict[tuple[str, str], np.ndarray] | None = None) -> Any:
    """One panel per station (a row per part): each bay's monthly share with its 95% band.

    ``result`` is :func:`loadbayes.archive.pool.pool`'s :class:`PoolResult`. The
    population's curve (the stations pooled; one per bay name with ``by_bay``) is drawn
    dashed in every panel. ``truth``
    (``{(station, bay): 12 monthly values}``) adds known curves as dots, for a generated
    archive.
    """
    from loadbayes.archive.pool import MONTHS
    from loadbayes.plots.fit import pyplot

    plt = pyplot()
    parts = list(result.parts.values())
    stations = sorted({s for p in parts for s, _ in p.units})
    ncol = max(len(stations), 1)
    fig, axes = plt.subplots(len(parts), ncol, figsize=(3.2 * ncol + 0.6, 2.9 * len(parts)),
                             sharex=True, sharey="row", squeeze=False)  # fmt: skip
    months = np.arange(1, 13)
    for r, part in enumerate(parts):
        table = part.monthly
        pops = table[table["station"] == "(all)"]
        bays = sorted({b for _, b in part.units})
        for c, station in enumerate(stations):
            ax = axes[r, c]
            one = pops[pops["bay"] == "(all)"].sort_values("month")
            if not one.empty:
                ax.plot(months, one["mean"], "--", color="0.5", lw=1, label="all stations")
            for k, bay in enumerate(bays):
                rows = table[(table["station"] == station) & (table["bay"] == bay)]
                if rows.empty:
                    continue
                rows = rows.sort_values("month")
                colour = f"C{k}"
                n = int(rows["events"].iloc[0])
                ax.fill_between(months, rows["low"], rows["high"], color=colour, alpha=0.25,
                                lw=0)  # fmt: skip
                ax.plot(months, rows["mean"], "-", color=colour, label=f"{bay} ({n} events)")
                pop = pops[pops["bay"] == bay].sort_values("month")
                if not pop.empty:
                    ax.plot(months, pop["mean"], "--", color=colour, lw=1)
                if truth and (station, bay) in truth:
                    ax.plot(months, truth[(station, bay)], "o", ms=3, color=colour, mfc="none")
            ax.set_title(f"{station}: {part.part}", fontsize=9)
            ax.legend(fontsize=7, loc="best")
            if c == 0:
                ax.set_ylabel(f"{part.part} (median event's share)")
            ax.set_xticks(months[::2], [MONTHS[i] for i in range(0, 12, 2)], fontsize=8)
    fig.suptitle("composition over the year, 95% bands", fontsize=10)
    fig.tight_layout()
    return fig
