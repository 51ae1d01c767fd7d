"""Figures of a composite-load fit: P and Q bands over the measured traces, motor pairs.

:func:`plot_composite_fit` (``fit composite --plot`` and the report) draws V(t), P(t),
Q(t) against each recording with the 95% bands and a zoom on each fault;
:func:`plot_composite` is the study's shorter figure (P, Q and the pairs). Axis labels
take their units from :data:`loadbayes.report.composite_names.QUANTITIES`.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from loadbayes.measurements.record import EventRecord
from loadbayes.plots.fit import pyplot
from loadbayes.posterior import Posterior

__all__ = ["plot_composite", "plot_composite_fit"]

_PAIRS = (("f_m", "t_prime_s"), ("x_prime", "h_s"), ("t_prime_s", "x_open"))
#: Axis labels with units (the motor's impedances are on its own base, docs/composite.md).
_LABELS = {
    "f_m": "motor share of P0, f_m",
    "t_prime_s": "T' (s)",
    "x_prime": "X' (p.u., motor base)",
    "h_s": "H (s, motor base)",
    "x_open": "X (p.u., motor base)",
}


def plot_composite(
    post: Posterior,
    events: Sequence[EventRecord],
    bands: Sequence[Mapping[str, np.ndarray]],
    *,
    baseline: Posterior | None = None,
    truth: Mapping[str, float] | None = None,
    max_events: int = 3,
) -> Any:
    """Measured P, Q with the posterior band of the model, and pairs of motor parameters.

    Parameters
    ----------
    post : Posterior
        The composite posterior.
    events : sequence of EventRecord
        The recordings fitted.
    bands : sequence of mapping
        From :func:`loadbayes.fit.composite.driver.predictive_band`, one per event.
    baseline : Posterior, optional
        The NLS baseline's Gaussian draws, shown beside the posterior in the pair plots.
    truth : mapping, optional
        True values (simulated events), marked in the pair plots.
    max_events : int
        Events drawn (the first ones).

    Returns
    -------
    matplotlib.figure.Figure
    """
    plt = pyplot()
    n_ev = min(len(events), max_events)
    n_pair = len(_PAIRS)
    # A grid fine enough for both rows: each event's traces and each pair plot span
    # equal widths, so no panel is left empty whatever the number of events.
    ncol = math.lcm(n_ev, n_pair)
    fig = plt.figure(figsize=(4.0 * max(n_ev, n_pair), 9.0))
    grid = fig.add_gridspec(3, ncol)
    w_ev, w_pair = ncol // n_ev, ncol // n_pair
    for k in range(n_ev):
        ev, band = events[k], bands[k]
        for row, ch in ((0, "p"), (1, "q")):
            ax = fig.add_subplot(grid[row, k * w_ev : (k + 1) * w_ev])
            ax.plot(ev.t, getattr(ev, ch), ".", ms=2.5, color="0.4", label="measured")
            tb = band.get("t", ev.t)
            ax.fill_between(tb, band[f"{ch}_lo"], band[f"{ch}_hi"], color="C0", alpha=0.35)
            ax.plot(tb, band[f"{ch}_mid"], color="C0", lw=1.0, label="posterior (95% band)")
            ax.set_xlabel("t (s)")
            ax.set_ylabel(f"{ch.upper()} (p.u.)")
            ax.set_title(ev.name[-40:], fontsize=8)
            if k == 0 and row == 0:
                ax.legend(fontsize=7)
    for k in range(len(_PAIRS)):
        ax = fig.add_subplot(grid[2, k * w_pair : (k + 1) * w_pair])
        _pair(ax, k, post, baseline, truth)
    fig.tight_layout()
    return fig


def _pair(ax, k: int, post: Posterior, baseline: Posterior | None, truth) -> None:
    a, b = _PAIRS[k]
    x, y = post.draws[a].ravel(), post.draws[b].ravel()
    step = max(1, x.size // 2000)
    ax.plot(x[::step], y[::step], ".", ms=1.5, alpha=0.4, color="C0", label="posterior")
    if baseline is not None:
        xb, yb = baseline.draws[a].ravel(), baseline.draws[b].ravel()
        sb = max(1, xb.size // 1000)
        ax.plot(xb[::sb], yb[::sb], ".", ms=1.5, alpha=0.3, color="C1", label="NLS (Gauss)")
    if truth is not None and a in truth and b in truth:
        ax.plot([truth[a]], [truth[b]], "k*", ms=10, label="truth")
    ax.set_xlabel(_LABELS.get(a, a))
    ax.set_ylabel(_LABELS.get(b, b))
    if k == 0:
        leg = ax.legend(fontsize=7)
        # Enlarge the scatter's dots in the legend only (a markerscale would also
        # blow up the truth's star).
        for handle in leg.legend_handles:
            if handle.get_marker() == ".":
                handle.set_markersize(8)


def _trace_label(ch: str) -> str:
    # The unit of the recording's V (that of v0) and of P, Q (that of p0, q0).
    from loadbayes.report.composite_names import QUANTITIES

    return f"{ch.upper()} ({QUANTITIES[ch + '0'][0]})"


def _trace(ax, ev: EventRecord, band, ch: str, window=None) -> None:
    t = ev.t
    sel = slice(None) if window is None else (t >= window[0]) & (t <= window[1])
    ax.plot(t[sel], getattr(ev, ch)[sel], ".", ms=3 if window else 2.5, color="0.3",
            label="recording", zorder=3)  # fmt: skip
    if ch == "v":
        ax.plot(t[sel], ev.v[sel], "-", lw=0.6, color="0.6", zorder=2)
    elif band is not None:
        # The band at its own times: the samples the fit read (a fit that leaves out the
        # samples inside a fault's edge gives them as band["t"]).
        tb = np.asarray(band.get("t", t))
        sb = slice(None) if window is None else (tb >= window[0]) & (tb <= window[1])
        if f"{ch}_pred_lo" in band:
            ax.fill_between(tb[sb], band[f"{ch}_pred_lo"][sb], band[f"{ch}_pred_hi"][sb],
                            color="C0", alpha=0.15, lw=0,
                            label="95% posterior predictive (noise included)")  # fmt: skip
        ax.fill_between(tb[sb], band[f"{ch}_lo"][sb], band[f"{ch}_hi"][sb], color="C0",
                        alpha=0.4, lw=0, label="95% band of the model")  # fmt: skip
        ax.plot(tb[sb], band[f"{ch}_mid"][sb], color="C0", lw=1.0, label="posterior median")
    ax.set_ylabel(_trace_label(ch), fontsize=8)
    ax.tick_params(labelsize=7)


def plot_composite_fit(
    post: Posterior,
    events: Sequence[EventRecord],
    bands: Sequence[Mapping[str, np.ndarray]] | None,
    faults: Sequence[Sequence[float]] | None = None,
    *,
    baseline: Posterior | None = None,
    truth: Mapping[str, float] | None = None,
    max_events: int = 3,
    max_zooms: int = 3,
    notes: Sequence[str] = (),
) -> Any:
    """V(t), P(t), Q(t) of each event against the recording, with a zoom on each fault.

    Per event three rows (V, P, Q): the whole recording, then one column a fault (the
    fitted step, or a fast voltage change) zoomed to a few samples either side. P and Q
    carry the 95% band of the model and, lighter, the 95% posterior-predictive band
    (noise included); the last row holds pairs of motor parameters.

    Parameters
    ----------
    post : Posterior
        The composite posterior.
    events : sequence of EventRecord
        The recordings fitted.
    bands : sequence of mapping, or None
        From :func:`loadbayes.fit.composite.predictive.predictive_band`, one per event
        (None: the recordings only).
    faults : sequence of sequence of float, optional
        Per event the instants to zoom on
        (:func:`loadbayes.fit.composite.predictive.fault_times`); default none.
    baseline, truth : optional
        As :func:`plot_composite` (pair plots).
    max_events, max_zooms : int
        Events drawn (the first ones) and zooms per event (the first faults).
    notes : sequence of str
        Paragraphs printed under the panels (what the events determine, the settings
        used), wrapped to the figure's width.

    Returns
    -------
    matplotlib.figure.Figure
    """
    plt = pyplot()
    n_ev = min(len(events), max_events)
    faults = [list(f)[:max_zooms] for f in (faults or [[] for _ in events])][:n_ev]
    n_zoom = max((len(f) for f in faults), default=0)
    import textwrap

    ncol = max(2 + n_zoom, len(_PAIRS))
    width_in = 3.0 * ncol
    wrapped = [textwrap.fill(n, width=int(width_in * 13)) for n in notes if n]
    text_lines = sum(w.count("\n") + 1 for w in wrapped)
    text_in = 0.16 * text_lines + (0.3 if wrapped else 0.0)
    fig = plt.figure(figsize=(width_in, 2.1 * (3 * n_ev + 1) + 0.6 + text_in))
    grid = fig.add_gridspec(3 * n_ev + 1, ncol)
    for k in range(n_ev):
        ev, band = events[k], None if bands is None else bands[k]
        dt = float(np.median(np.diff(ev.t)))
        half = max(0.1, 5 * dt)
        for row, ch in enumerate(("v", "p", "q")):
            r = 3 * k + row
            ax = fig.add_subplot(grid[r, : ncol - n_zoom])
            _trace(ax, ev, band, ch)
            for tf in faults[k]:
                ax.axvline(tf, color="C3", lw=0.6, ls=":")
            if row == 0:
                ax.set_title(f"event {k + 1}: {ev.name[-50:]}", fontsize=8, loc="left")
            if row == 1 and k == 0 and band is not None:
                ax.legend(fontsize=6, loc="lower right")
            if row == 2:
                ax.set_xlabel("t (s)", fontsize=8)
            for j, tf in enumerate(faults[k]):
                zx = fig.add_subplot(grid[r, ncol - n_zoom + j])
                _trace(zx, ev, band, ch, window=(tf - half, tf + half))
                zx.axvline(tf, color="C3", lw=0.6, ls=":")
                zx.set_xlim(tf - half, tf + half)
                zx.set_ylabel("")
                if row == 0:
                    zx.set_title(f"zoom: fault at {tf:.4g} s", fontsize=8)
                if row == 2:
                    zx.set_xlabel("t (s)", fontsize=8)
    w_pair = ncol // len(_PAIRS)
    for k in range(len(_PAIRS)):
        ax = fig.add_subplot(grid[3 * n_ev, k * w_pair : (k + 1) * w_pair])
        _pair(ax, k, post, baseline, truth)
    if wrapped:
        # The text in its own strip at the bottom; the panels keep the rest.
        bottom = text_in / fig.get_figheight()
        fig.tight_layout(rect=(0, bottom, 1, 1))
        fig.text(0.01, bottom - 0.3 / fig.get_figheight(), "\n".join(wrapped), fontsize=7.5,
                 va="top", ha="left", family="monospace")  # fmt: skip
    else:
        fig.tight_layout()
    return fig
