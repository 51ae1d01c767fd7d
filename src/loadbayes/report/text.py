"""The table ``loadbayes fit`` prints, and the derived quantities' lines under it.

:func:`summary_table` is the table (80 columns): the rows and the numbers' format are
:mod:`loadbayes.core.display`'s (:func:`~loadbayes.core.display.fmt`, the one number
format of the terminal table, the notebook view and the HTML report);
:func:`derived_lines` says each derived quantity (dP/dV at v0 ...) on one line.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from loadbayes.core.display import (
    DESCRIPTIONS,
    fmt,
    fmt_like,
    headline,
    precision_sd,
    summary_rows,
)

__all__ = ["derived_lines", "summary_table"]


def summary_table(
    post: Any,
    *,
    hdi_prob: float = 0.95,
    summary: Any = None,
    width: int = 80,
    describe: Callable[[str], str] | None = None,
    title: str | None = None,
    derived: bool = True,
) -> str:
    """The table ``loadbayes fit`` prints: one row a parameter, at most ``width`` columns.

    Parameters
    ----------
    post : Posterior
        The fit.
    hdi_prob : float
        Probability of the interval.
    summary : DataFrame, optional
        A :meth:`Posterior.summary` already computed (the costly part).
    width : int
        Longest line; the description column is cut to fit (a unit at its end, in
        square brackets, is kept whole).
    describe : callable, optional
        A name's meaning (default :data:`DESCRIPTIONS`).
    title : str, optional
        The first line (default :func:`headline`).
    derived : bool
        Add the rows of :attr:`Posterior.derived` (dP/dV ...) after the parameters.
    """
    rows = summary_rows(post, hdi_prob=hdi_prob, summary=summary, describe=describe)
    if derived:
        rows += _derived_rows(post, hdi_prob)
    pct = f"{hdi_prob:.0%}"
    head = {"name": "", "mean": "mean", "sd": "sd", "low": f"{pct} low", "high": f"{pct} high",
            "ess": "ESS", "r_hat": "R-hat"}  # fmt: skip
    keys = list(head)
    widths = {k: max(len(head[k]), *(len(r[k]) for r in rows)) for k in keys}
    lines = []

    def line(r: dict, what: str = "") -> str:
        cells = [r["name"].ljust(widths["name"])]
        cells += [r[k].rjust(widths[k]) for k in keys[1:]]
        text = "  ".join(cells)
        room = width - len(text) - 2
        if what and room >= 8:
            text += "  " + _cut(what, room)
        return text[:width]

    lines.append(_wrap(headline(post) if title is None else title, width))
    lines.append(line(head))
    lines.extend(line(r, r["what"]) for r in rows)
    return "\n".join(lines)


def _cut(what: str, room: int) -> str:
    # Cut the words, keep a trailing unit "[...]" whole when it fits.
    if len(what) <= room:
        return what
    words, sep, unit = what.rpartition(" [")
    if sep and len(unit) + 3 < room - 4:
        unit = sep + unit
        return words[: room - len(unit) - 1] + "…" + unit
    return what[: room - 1] + "…"


def derived_lines(post: Any, *, hdi_prob: float = 0.95) -> list[str]:
    """One line per derived quantity: ``dP/dV at v0 = 1.16 (95% 0.94 to 1.37; ...)``."""
    out = []
    pct = f"{hdi_prob:.0%}"
    for r in _derived_rows(post, hdi_prob):
        out.append(f"{r['name']} = {r['mean']} (sd {r['sd']}, {pct} {r['low']} to "
                   f"{r['high']}; ESS {r['ess']}, R-hat {r['r_hat']}): {r['what']}")  # fmt: skip
    return out


def _derived_rows(post: Any, hdi_prob: float) -> list[dict]:
    """The table's rows of the derived quantities (dP/dV at v0 ...), formatted as the rest."""
    if not getattr(post, "derived", None):
        return []
    rows = []
    for name, r in post.derived_summary(hdi_prob=hdi_prob).items():
        sd = r["sd"] if r["sd"] is not None else float("nan")
        digits = precision_sd(sd, r["hdi_low"], r["hdi_high"])
        rows.append(
            {
                "name": name,
                "mean": fmt_like(r["mean"], digits),
                "sd": fmt(sd, 2),
                "low": fmt_like(r["hdi_low"], digits),
                "high": fmt_like(r["hdi_high"], digits),
                "ess": f"{r['ess_bulk']:,.0f}" if r["ess_bulk"] is not None else "–",
                "r_hat": f"{r['r_hat']:.3f}" if r["r_hat"] is not None else "–",
                "what": DESCRIPTIONS.get(name, ""),
            }
        )
    return rows


def _wrap(text: str, width: int) -> str:
    import textwrap

    return "\n".join(textwrap.wrap(text, width)) or text
