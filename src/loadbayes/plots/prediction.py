"""Figures of a prediction: V, P, Q and the current against their bands; a sweep's stall curve."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from loadbayes.plots.fit import pyplot

__all__ = ["plot_prediction", "plot_sweep"]


def plot_prediction(pred: Any, *, title: str = "") -> Any:
    """Four panels: the fault's voltage, and P, Q, |I| with the model's and the noisy band.

    ``pred`` is a :class:`loadbayes.fit.composite.predict.Prediction`.
    """
    plt = pyplot()
    b = pred.band
    t = np.asarray(b["t_s"])
    fig, ax = plt.subplots(4, 1, figsize=(7, 9), sharex=True)
    ax[0].plot(t, b["v"], color="k", lw=1)
    ax[0].set_ylabel("V (p.u.)")
    pct = f"{pred.prob:.0%}"
    for a, ch, name in ((ax[1], "p", "P"), (ax[2], "q", "Q"), (ax[3], "i", "|I|")):
        if f"{ch}_pred_lo" in b:
            a.fill_between(t, b[f"{ch}_pred_lo"], b[f"{ch}_pred_hi"], color="C0", alpha=0.15,
                           lw=0, label=f"{pct} with the fit's noise")  # fmt: skip
        a.fill_between(t, b[f"{ch}_lo"], b[f"{ch}_hi"], color="C0", alpha=0.35, lw=0,
                       label=f"{pct} of the model")  # fmt: skip
        a.plot(t, b[f"{ch}_mid"], color="C0", lw=1, label="median")
        a.set_ylabel(f"{name} (p.u.)")
    ax[1].legend(fontsize=7, loc="best")
    ax[3].set_xlabel("t (s)")
    words = []
    if pred.stall is not None:
        lo, hi = pred.stall["interval"]
        words.append(
            f"{pred.stall.get('part', 'motor D')} stalls: "
            f"{pred.stall['probability']:.2f} [{lo:.2f}, {hi:.2f}]"
        )
    if pred.extrapolation["extrapolated"]:
        words.append("EXTRAPOLATED beyond the fitted events")
    ax[0].set_title("\n".join([title or pred.fault["name"], "; ".join(words)]), fontsize=9)
    fig.tight_layout()
    return fig


def plot_sweep(preds: Sequence[Any], depths: Sequence[float], *, title: str = "") -> Any:
    """Stall probability (and its interval) and the electronics tripped against sag depth."""
    plt = pyplot()
    x = np.asarray(depths, dtype=float)
    fig, ax = plt.subplots(1, 1, figsize=(6, 4))
    if all(p.stall is not None for p in preds):
        prob = [p.stall["probability"] for p in preds]
        lo = [p.stall["interval"][0] for p in preds]
        hi = [p.stall["interval"][1] for p in preds]
        ax.fill_between(x, lo, hi, color="C3", alpha=0.25, lw=0)
        part = preds[0].stall.get("part", "motor D")
        ax.plot(x, prob, "o-", color="C3", label=f"P({part} stalls)")
    if all(p.electronics_tripped is not None for p in preds):
        med = [p.electronics_tripped["median"] for p in preds]
        lo = [p.electronics_tripped["interval"][0] for p in preds]
        hi = [p.electronics_tripped["interval"][1] for p in preds]
        ax.fill_between(x, lo, hi, color="C2", alpha=0.15, lw=0)
        ax.plot(x, med, "s--", color="C2", label="electronics tripped (median)")
    covered = preds[0].coverage.get("depth_max")
    if covered is not None:
        ax.axvline(covered, color="k", ls=":", lw=1, label="deepest fitted event")
    ax.set_xlabel("sag depth (share of the pre-fault voltage)")
    ax.set_ylabel("probability / share")
    ax.set_ylim(-0.02, 1.02)
    ax.legend(fontsize=8, loc="best")
    ax.set_title(title or "what the load does as the sag deepens", fontsize=9)
    fig.tight_layout()
    return fig
