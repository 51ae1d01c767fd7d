"""Figure of a composite fit on held-out events: V, P, Q against the predictive band."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

from loadbayes.plots.fit import pyplot

__all__ = ["plot_validation"]


def plot_validation(scores: Sequence[Any], *, prob: float = 0.95, titles=None) -> Any:
    """One column per event: recorded V, and P, Q over the posterior-predictive band.

    Parameters
    ----------
    scores : sequence of EventValidation
        From :func:`loadbayes.fit.composite.validate.validate_events`.
    prob : float
        The band's probability (for the legend).
    titles : sequence of str, optional
        Column titles (default: the event's file and its RMS and coverage).

    Returns
    -------
    matplotlib.figure.Figure
    """
    plt = pyplot()
    n = len(scores)
    fig, axes = plt.subplots(3, n, figsize=(4.2 * n, 7.5), sharex="col", squeeze=False)
    for k, s in enumerate(scores):
        ev, band, ok = s.event, s.band, s.scored
        t = ev.t - ev.t[0]
        ax = axes[0, k]
        ax.plot(t, ev.v, ".-", ms=2.5, lw=0.6, color="0.3", label="recorded")
        ax.set_ylabel("V (p.u.)")
        title = (
            titles[k]
            if titles
            else f"{s.file[-36:]}\nrms P {100 * s.rms_p:.1f}%, Q {100 * s.rms_q:.1f}% of P0; "
            f"in band {100 * s.coverage_p:.0f}%, {100 * s.coverage_q:.0f}%"
        )
        ax.set_title(title, fontsize=8)
        for row, ch in ((1, "p"), (2, "q")):
            ax = axes[row, k]
            ax.fill_between(t, band[f"{ch}_lo"], band[f"{ch}_hi"], color="C0", alpha=0.3,
                            label=f"{prob:.0%} predictive band")  # fmt: skip
            ax.plot(t, band[f"{ch}_mean"], color="C0", lw=1.0, label="posterior mean")
            y = getattr(ev, ch)
            ax.plot(t[ok], y[ok], ".", ms=3, color="0.2", label="recorded")
            if (~ok).any():
                ax.plot(t[~ok], y[~ok], "x", ms=4, color="C3", label="recorded, not scored")
            ax.set_ylabel(f"{ch.upper()} (p.u.)")
        axes[2, k].set_xlabel("t from the event's first sample (s)")
    axes[1, 0].legend(fontsize=7)
    axes[0, 0].legend(fontsize=7)
    fig.tight_layout()
    return fig
