"""Figures of a composite-load fit: P and Q bands over the measured traces, motor pairs."""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from loadbayes.models.composite import EventRecord
from loadbayes.plots.fit import pyplot
from loadbayes.posterior import Posterior

__all__ = ["plot_composite"]

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
    for k, (a, b) in enumerate(_PAIRS):
        ax = fig.add_subplot(grid[2, k * w_pair : (k + 1) * w_pair])
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
    fig.tight_layout()
    return fig
