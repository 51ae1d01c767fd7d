"""Figures of a composite-load fit: P and Q bands over the measured traces, motor pairs."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from loadbayes.models.composite import Event
from loadbayes.plots import pyplot
from loadbayes.posterior import Posterior

__all__ = ["plot_composite"]

_PAIRS = (("f_m", "t_prime_s"), ("x_prime", "h_s"), ("t_prime_s", "x_open"))


def plot_composite(
    post: Posterior,
    events: Sequence[Event],
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
    events : sequence of Event
        The recordings fitted.
    bands : sequence of mapping
        From :func:`loadbayes.fit.composite.predictive_band`, one per event.
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
    ncol = max(n_ev, len(_PAIRS))
    fig, axes = plt.subplots(3, ncol, figsize=(4.0 * ncol, 9.0), squeeze=False)
    for k in range(n_ev):
        ev, band = events[k], bands[k]
        for row, ch in ((0, "p"), (1, "q")):
            ax = axes[row, k]
            ax.plot(ev.t, getattr(ev, ch), ".", ms=2.5, color="0.4", label="measured")
            ax.fill_between(ev.t, band[f"{ch}_lo"], band[f"{ch}_hi"], color="C0", alpha=0.35)
            ax.plot(ev.t, band[f"{ch}_mid"], color="C0", lw=1.0, label="posterior (95% band)")
            ax.set_xlabel("t (s)")
            ax.set_ylabel(f"{ch.upper()} (p.u.)")
            ax.set_title(ev.name[-40:], fontsize=8)
            if k == 0 and row == 0:
                ax.legend(fontsize=7)
    for k in range(n_ev, ncol):
        axes[0, k].axis("off")
        axes[1, k].axis("off")
    for k, (a, b) in enumerate(_PAIRS):
        ax = axes[2, k]
        x, y = post.draws[a].ravel(), post.draws[b].ravel()
        step = max(1, x.size // 2000)
        ax.plot(x[::step], y[::step], ".", ms=1.5, alpha=0.4, color="C0", label="posterior")
        if baseline is not None:
            xb, yb = baseline.draws[a].ravel(), baseline.draws[b].ravel()
            sb = max(1, xb.size // 1000)
            ax.plot(xb[::sb], yb[::sb], ".", ms=1.5, alpha=0.3, color="C1", label="NLS (Gauss)")
        if truth is not None and a in truth and b in truth:
            ax.plot([truth[a]], [truth[b]], "k*", ms=10, label="truth")
        ax.set_xlabel(a)
        ax.set_ylabel(b)
        if k == 0:
            ax.legend(fontsize=7, markerscale=4)
    for k in range(len(_PAIRS), ncol):
        axes[2, k].axis("off")
    fig.tight_layout()
    return fig
