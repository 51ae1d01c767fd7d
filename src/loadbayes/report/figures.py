"""A fit's figures for the report, as PNG bytes with their captions and alt texts.

Each function returns a :class:`Figure` (or None when the fit has nothing to show), drawn
with the panels of :mod:`loadbayes.plots.fit`, so the report and ``--plot`` agree.
"""

from __future__ import annotations

import io
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

__all__ = [
    "Figure",
    "composite_fit_figure",
    "curves_figure",
    "marginals_figure",
    "pairs_figure",
    "png",
    "traces_figure",
]

#: Pixels per inch of the report's figures: 1100 px wide at 11 in.
DPI = 100


@dataclass
class Figure:
    """One figure of the report."""

    title: str
    png: bytes
    caption: str
    alt: str


def png(fig: Any) -> bytes:
    """The figure as PNG bytes (and closed)."""
    from loadbayes.plots.fit import pyplot

    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=DPI, bbox_inches="tight")
    pyplot().close(fig)
    return buf.getvalue()


def curves_figure(post: Any, *, hdi_prob: float = 0.95) -> Figure | None:
    """P(V) and Q(V) in the data's units, with the data and both bands."""
    from loadbayes.plots.fit import draw_curve, pyplot
    from loadbayes.predictive import data_units, model_of

    chans = [c for c in ("p", "q") if c in post.observed and f"tau_{c}" in post.draws]
    if model_of(post) is None or "v" not in post.observed or not chans:
        return None
    plt = pyplot()
    fig, axes = plt.subplots(1, len(chans), figsize=(5.5 * len(chans), 4.0), squeeze=False,
                             layout="constrained")  # fmt: skip
    for ax, ch in zip(axes[0], chans, strict=True):
        draw_curve(ax, post, ch, hdi_prob=hdi_prob)
        ax.set_title(f"{ch.upper()}(V)", fontsize=10)
    u = data_units(post)
    what = " and ".join(f"{c.upper()}(V)" for c in chans)
    return Figure(
        "Load curves",
        png(fig),
        f"{what} in the data's units (V in {u['v']}, powers in {u['p']}). Grey dots: the "
        f"measurements (at most 4,000 shown); dark band: {hdi_prob:.0%} interval of the load "
        f"curve itself; light band: {hdi_prob:.0%} interval of a new measurement (curve plus "
        "noise); line: posterior mean. About 1 in 20 measurements should fall outside the "
        "light band if the model and its noise are right.",
        f"Scatter of measured {what} against voltage with the fitted curve and its bands.",
    )


def marginals_figure(
    post: Any,
    *,
    hdi_prob: float = 0.95,
    truth: Mapping[str, float] | None = None,
    names: Any = None,
) -> Figure | None:
    """The marginal posterior of every coefficient (derived ones included), or of ``names``."""
    from loadbayes.plots.fit import draw_marginal, pyplot

    names = [n for n in (post.coefficients if names is None else names) if n in post.draws]
    if not names:
        return None
    plt = pyplot()
    ncol = min(4, len(names))
    nrow = int(np.ceil(len(names) / ncol))
    fig, axes = plt.subplots(nrow, ncol, figsize=(2.75 * ncol + 0.5, 2.4 * nrow), squeeze=False,
                             layout="constrained")  # fmt: skip
    for ax, name in zip(axes.flat, names, strict=False):
        draw_marginal(ax, post, name, hdi_prob=hdi_prob, truth=(truth or {}).get(name))
    for ax in axes.flat[len(names) :]:
        ax.axis("off")
    extra = " Red dashed line: the true value given to the report." if truth else ""
    return Figure(
        "Marginal posteriors",
        png(fig),
        f"Posterior of each coefficient: histogram of the draws, black line at the mean, "
        f"shaded {hdi_prob:.0%} highest-density interval." + extra,
        "Histograms of the posterior draws of " + ", ".join(names) + ".",
    )


def pairs_figure(post: Any, *, k: int = 3) -> Figure | None:
    """Joint draws of the ``k`` most correlated pairs of free coefficients."""
    from loadbayes.plots.fit import correlated_pairs, draw_pair, pyplot

    # The most correlated pair always; others only when they are correlated at all.
    pairs = [pr for i, pr in enumerate(correlated_pairs(post, k)) if i == 0 or abs(pr[2]) > 0.3]
    if not pairs:
        return None
    plt = pyplot()
    fig, axes = plt.subplots(1, len(pairs), figsize=(3.7 * len(pairs), 3.4), squeeze=False,
                             layout="constrained")  # fmt: skip
    for ax, (a, b, _) in zip(axes[0], pairs, strict=True):
        draw_pair(ax, post, a, b)
    text = "; ".join(f"{a}-{b} {r:+.3f}" for a, b, r in pairs)
    return Figure(
        "Pair plots",
        png(fig),
        f"Joint draws of the most correlated pairs of coefficients (correlations: {text}). A "
        "thin ridge means the data fix a combination of the two but not each one alone.",
        "Scatter plots of joint posterior draws for " + text + ".",
    )


def traces_figure(post: Any, *, max_params: int = 6) -> Figure | None:
    """Thinned traces of the free coefficients, one line per chain."""
    from loadbayes.plots.fit import draw_trace, pyplot

    names = [n for n in (post.free or post.coefficients) if n in post.draws][:max_params]
    if not names:
        return None
    plt = pyplot()
    ncol = min(3, len(names))
    nrow = int(np.ceil(len(names) / ncol))
    fig, axes = plt.subplots(nrow, ncol, figsize=(3.8 * ncol, 2.6 * nrow), squeeze=False,
                             layout="constrained")  # fmt: skip
    step = 1
    for ax, name in zip(axes.flat, names, strict=False):
        step = draw_trace(ax, post, name)
    for ax in axes.flat[len(names) :]:
        ax.axis("off")
    if post.n_chains > 1:
        axes.flat[0].legend(fontsize=7, loc="upper right", framealpha=0.85)
    thin = f" (every {step}th kept draw shown)" if step > 1 else ""
    return Figure(
        "Traces",
        png(fig),
        f"Draws of each free coefficient against the iteration, one colour a chain{thin}. "
        "Chains that overlap with no trend or stuck stretch have mixed; R-hat and ESS in the "
        "parameter table say the same in numbers.",
        "Trace plots of " + ", ".join(names) + f" for {post.n_chains} chains.",
    )


def composite_fit_figure(post: Any, *, hdi_prob: float = 0.95, seed: int = 0) -> Figure | None:
    """A composite fit's V(t), P(t), Q(t) against the recordings, with a zoom on each fault.

    None when the result keeps no recordings (written before they were kept).
    """
    from loadbayes.fit.composite.predictive import events_of, fault_times, predictive_band
    from loadbayes.plots.composite import plot_composite_fit

    events = events_of(post)
    if not events:
        return None
    torque = post.settings.get("torque", [1.0, 0.0, 0.0])
    f_hz = float(post.settings.get("f_hz", 60.0))
    # Estimated shares are in the draws (predictive_band reads them there).
    fixed = (1.0, 0.0, 0.0) if isinstance(torque, str) else tuple(torque)
    bands = predictive_band(post, events, f_hz=f_hz, torque=fixed, prob=hdi_prob, seed=seed)
    faults = fault_times(post, events)
    fig = plot_composite_fit(post, events, bands, faults)
    shown = min(len(events), 3)
    pct = f"{hdi_prob:.0%}"
    return Figure(
        "Fit to the recordings",
        png(fig),
        f"Each event's V(t), P(t), Q(t) (V in p.u., P and Q in p.u. of the system base; t in "
        f"s), {shown} of {len(events)} event(s), with a zoom on each fault (dotted line: a "
        "fitted step or a place where the voltage starts or stops moving). Dots: the "
        f"recording; dark band: {pct} interval of the model's P, Q over 200 posterior "
        f"draws; light band: {pct} posterior-predictive interval (each draw's noise "
        "added), where about 1 in 20 samples should fall outside if the model and its noise "
        "are right; line: posterior median. Bottom row: pairs of motor parameters.",
        "Measured voltage, active and reactive power of each event over time, with the "
        "fitted composite load's bands and zooms on the faults.",
    )
