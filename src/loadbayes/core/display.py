"""Numbers as a reader wants them, a fit's summary rows, and its notebook view.

:func:`fmt` is the one number format of the terminal table, the notebook view and the
HTML report (3 significant digits, no exponent between 0.001 and 100,000; thousands
grouped); :func:`fmt_like` prints a mean and its interval to the precision of its sd
(two digits of the sd; :func:`precision_sd` takes the interval's width instead where a
heavy tail makes the sd far wider than the interval); :func:`summary_rows` formats a
fit's summary, row by row, and :func:`summary_html` is a
:class:`~loadbayes.posterior.Posterior`'s view in a notebook. They sit below
``posterior.py`` (which shows itself with them) and ``report/`` (whose table,
:func:`loadbayes.report.text.summary_table`, and pages print with them); a fit is taken
as any object with ``summary()``, ``settings``, ``warnings`` and the chain counts.
"""

from __future__ import annotations

import html
import math
from collections.abc import Callable
from typing import Any

import numpy as np

__all__ = [
    "DESCRIPTIONS",
    "fmt",
    "fmt_like",
    "precision_sd",
    "headline",
    "summary_html",
    "summary_rows",
]

#: What each parameter is, in words (the report's and the notebook's tables).
DESCRIPTIONS = {
    "a1": "P: impedance share",
    "a2": "P: current share",
    "a3": "P: constant-power share",
    "a4": "Q: impedance share",
    "a5": "Q: current share",
    "a6": "Q: constant-power share",
    "p0": "nominal P at V = v0",
    "q0": "nominal Q at V = v0",
    "np": "exponent of P",
    "nq": "exponent of Q",
    "kpf": "frequency coefficient of P",
    "kqf": "frequency coefficient of Q",
    "drift_p": "sd of the P level's change in 1 h",
    "drift_q": "sd of the Q level's change in 1 h",
    "dP/dV": "dP/dV at v0 (pu of P0/pu V)",
    "dQ/dV": "dQ/dV at v0 (pu of Q0/pu V)",
    "tau_p": "noise precision of P",
    "tau_q": "noise precision of Q",
    "b1": "flux coefficient b1",
    "b2": "flux coefficient b2",
    "b3": "speed coefficient b3",
    "ab": "current coefficient ab",
    "ac": "current coefficient ac",
    "tau_e": "noise precision, flux equations",
    "tau_w": "noise precision, speed equation",
    "tau_i": "noise precision, current equations",
    "rs": "stator resistance Rs",
    "xp": "transient reactance X'",
    "x": "open-circuit reactance X",
    "tp_s": "transient time constant T'",
    "h_s": "inertia constant H",
    "xs": "stator leakage reactance",
    "xm": "magnetising reactance",
    "xr": "rotor leakage reactance",
    "rr": "rotor resistance",
}


def fmt(x: Any, sig: int = 3) -> str:
    """``x`` to ``sig`` significant digits, fixed-point from 1e-3 to 1e5, else scientific.

    Examples
    --------
    >>> [fmt(v) for v in (0.25012, -1.119, 15370.2, 3.2e-7, 1, float("nan"))]
    ['0.250', '-1.12', '15,400', '3.20e-07', '1.00', '–']
    """
    try:
        x = float(x)
    except (TypeError, ValueError):
        return str(x)
    if not math.isfinite(x):
        return "–" if math.isnan(x) else ("∞" if x > 0 else "-∞")
    if x == 0:
        return "0"
    mag = math.floor(math.log10(abs(x)))
    if not -3 <= mag < 5:
        return f"{x:.{sig - 1}e}"
    decimals = max(sig - 1 - mag, 0)
    r = round(x, decimals if decimals else sig - 1 - mag)
    return f"{r:,.{decimals}f}"


def fmt_like(x: Any, sd: Any) -> str:
    """``x`` to the precision its posterior sd warrants: the sd's first two digits.

    A mean, and the ends of its interval, print with the same decimals, so that a tight
    interval never reads ``13.4 to 13.4``; without a usable sd, :func:`fmt`.

    Examples
    --------
    >>> fmt_like(-11.44051, 0.0050), fmt_like(0.26812, 0.037), fmt_like(39512.3, 1471.2)
    ('-11.4405', '0.268', '39,500')
    """
    try:
        x, sd = float(x), float(sd)
    except (TypeError, ValueError):
        return fmt(x)
    if not (math.isfinite(x) and math.isfinite(sd) and sd > 0) or x == 0:
        return fmt(x)
    if not -3 <= math.floor(math.log10(abs(x))) < 5:
        return fmt(x)
    decimals = 1 - math.floor(math.log10(sd))
    if decimals > 8:
        return fmt(x, 9)
    if decimals >= 0:
        return f"{round(x, decimals):,.{decimals}f}"
    return f"{round(x, decimals):,.0f}"


def precision_sd(sd: Any, low: Any, high: Any) -> Any:
    """The spread that sets a row's printed digits: its sd, or the interval's width / 3.92.

    The width is taken where a heavy tail makes the sd more than twice what its 95%
    interval implies (a few far draws on a ridge), so that the mean and the interval's
    ends are not rounded away (an sd of 41,000 beside an interval of -593 to 560 printed
    ``-0`` and ``-1,000 to 1,000``).

    Examples
    --------
    >>> precision_sd(0.05, 0.4, 0.6), round(precision_sd(41_000.0, -593.0, 560.0), 1)
    (0.05, 294.1)
    """
    try:
        s, w = float(sd), (float(high) - float(low)) / 3.92
    except (TypeError, ValueError):
        return sd
    if math.isfinite(s) and math.isfinite(w) and w > 0 and s > 2 * w:
        return w
    return sd


def summary_rows(
    post: Any,
    *,
    hdi_prob: float = 0.95,
    summary: Any = None,
    describe: Callable[[str], str] | None = None,
) -> list[dict]:
    """One dict per parameter: name, mean, sd, HDI, ESS, R-hat as formatted strings.

    ``describe`` gives a name's meaning (default :data:`DESCRIPTIONS`); the rows are
    those of ``summary`` (all parameters when it is None).
    """
    s = post.summary(hdi_prob=hdi_prob) if summary is None else summary
    what = describe or (lambda name: DESCRIPTIONS.get(name, ""))
    rows = []
    for name, r in s.iterrows():
        ess = r.get("ess_bulk", float("nan"))
        rhat = r.get("r_hat", float("nan"))
        digits = precision_sd(r["sd"], r["hdi_low"], r["hdi_high"])
        rows.append(
            {
                "name": str(name),
                "mean": fmt_like(r["mean"], digits),
                "sd": fmt(r["sd"], 2),
                "low": fmt_like(r["hdi_low"], digits),
                "high": fmt_like(r["hdi_high"], digits),
                "ess": f"{ess:,.0f}" if np.isfinite(ess) else "–",
                "r_hat": f"{rhat:.3f}" if np.isfinite(rhat) else "–",
                "what": what(str(name)),
            }
        )
    return rows


def headline(post: Any) -> str:
    """One line: model, method, samples, chains x kept draws."""
    n = post.settings.get("n")
    data = post.settings.get("data")
    src = f" from {data}" if data else ""
    return (
        f"{post.model} posterior{src}: {post.method}, n = {n if n is not None else '?'}, "
        f"{post.n_chains} chains x {post.n_draws:,} draws"
    )


def summary_html(post: Any, *, hdi_prob: float = 0.95) -> str:
    """An HTML fragment: headline, parameter table, warnings (the notebook view)."""
    rows = summary_rows(post, hdi_prob=hdi_prob)
    pct = f"{hdi_prob:.0%}"
    e = html.escape
    body = "".join(
        f"<tr><th scope='row'>{e(r['name'])}</th><td>{e(r['mean'])}</td><td>{e(r['sd'])}</td>"
        f"<td>{e(r['low'])} – {e(r['high'])}</td><td>{e(r['ess'])}</td>"
        f"<td>{e(r['r_hat'])}</td><td>{e(r['what'])}</td></tr>"
        for r in rows
    )
    warn = "".join(f"<li>{e(w)}</li>" for w in post.warnings)
    return (
        f"<div class='loadbayes-posterior'><p><b>{e(headline(post))}</b></p>"
        "<table><thead><tr><th scope='col'>parameter</th><th scope='col'>mean</th>"
        f"<th scope='col'>sd</th><th scope='col'>{pct} interval</th><th scope='col'>ESS</th>"
        "<th scope='col'>R-hat</th><th scope='col'>meaning</th></tr></thead>"
        f"<tbody>{body}</tbody></table>"
        + (f"<p>Warnings:</p><ul>{warn}</ul>" if warn else "")
        + "</div>"
    )
