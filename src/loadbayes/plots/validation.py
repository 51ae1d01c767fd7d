"""Figure of a composite fit on held-out events: V, P, Q against the predictive band."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

from loadbayes.plots.fit import pyplot

__all__ = ["plot_validation"]


def plot_validation(
    scores: Sequence[Any], *, prob: float = 0.95, titles=None, ncols: int | None = None
) -> Any:
    """Per event a column of three panels: recorded V, and P, Q over the predictive band.

    Parameters
    ----------
    scores : sequence of EventValidation
        From :func:`loadbayes.fit.composite.validate.validate_events`.
    prob : float
        The band's probability (for the legend).
    titles : sequence of str, optional
        Column titles (default: the event's file and its RMS and coverage).
    ncols : int, optional
        Events side by side (default all); more events wrap onto further rows of panels.

    Returns
    -------
    matplotlib.figure.Figure
    """
    plt = pyplot()
    n = len(scores)
    ncols = min(ncols or n, n)
    nblocks = -(-n // ncols)
    fig, grid = plt.subplots(3 * nblocks, ncols, figsize=(4.2 * ncols, 7.5 * nblocks),
                             squeeze=False)  # fmt: skip
    blocks = [grid[3 * (k // ncols) : 3 * (k // ncols) + 3, k % ncols] for k in range(n)]
    for k in range(n, nblocks * ncols):  # empty slots of the last row of events
        for ax in grid[3 * (nblocks - 1) :, k % ncols]:
            ax.set_visible(False)
    for k, s in enumerate(scores):
        ev, band, ok = s.event, s.band, s.scored
        t = ev.t - ev.t[0]
        axes = blocks[k]
        axes[0].sharex(axes[2])
        axes[1].sharex(axes[2])
        ax = axes[0]
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
            ax = axes[row]
            ax.fill_between(t, band[f"{ch}_lo"], band[f"{ch}_hi"], color="C0", alpha=0.3,
                            label=f"{prob:.0%} predictive band")  # fmt: skip
            ax.plot(t, band[f"{ch}_mean"], color="C0", lw=1.0, label="posterior mean")
            y = getattr(ev, ch)
            ax.plot(t[ok], y[ok], ".", ms=3, color="0.2", label="recorded")
            if (~ok).any():
                ax.plot(t[~ok], y[~ok], "x", ms=4, color="C3", label="recorded, not scored")
            ax.set_ylabel(f"{ch.upper()} (p.u.)")
        axes[2].set_xlabel("t from the event's first sample (s)")
    blocks[0][1].legend(fontsize=7)
    blocks[0][0].legend(fontsize=7)
    fig.tight_layout()
    return fig
