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
    from loadbayes.fit.composite.predict_outcome import no_band

    plt = pyplot()
    b = pred.band
    t = np.asarray(b["t_s"])
    fig, ax = plt.subplots(4, 1, figsize=(7, 9), sharex=True)
    ax[0].plot(t, b["v"], color="k", lw=1)
    ax[0].set_ylabel("V (p.u.)")
    pct = f"{pred.prob:.0%}"
    for a, ch, name in ((ax[1], "p", "P"), (ax[2], "q", "Q"), (ax[3], "i", "|I|")):
        if f"{ch}_mid" not in b:  # no draw plays: no band, said where it would be
            a.text(0.5, 0.5, no_band(pred.outcome), ha="center", va="center",
                   transform=a.transAxes, fontsize=8, wrap=True)  # fmt: skip
            a.set_ylabel(f"{name} (p.u.)")
            continue
        if f"{ch}_pred_lo" in b:
            a.fill_between(t, b[f"{ch}_pred_lo"], b[f"{ch}_pred_hi"], color="C0", alpha=0.15,
                           lw=0, label=f"{pct} with the fit's noise")  # fmt: skip
        a.fill_between(t, b[f"{ch}_lo"], b[f"{ch}_hi"], color="C0", alpha=0.35, lw=0,
                       label=f"{pct} of the model")  # fmt: skip
        a.plot(t, b[f"{ch}_mid"], color="C0", lw=1, label="median")
        a.set_ylabel(f"{name} (p.u.)")
    if "p_mid" in b:
        ax[1].legend(fontsize=7, loc="best")
    ax[3].set_xlabel("t (s)")
    words = []
    if pred.outcome is not None:
        o = pred.outcome
        words.append(f"plays {o['plays']['share']:.0%}, collapses {o['collapses']['share']:.0%}, "
                     f"fails numerically {o['fails_numerically']['share']:.0%}")  # fmt: skip
    if pred.stall is not None and pred.stall["probability"] is not None:
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
    """Stall probability (and its interval) and the electronics tripped against sag depth.

    Where some draws did not play: the share that collapses (and that fails numerically)
    per depth, and "no band" over a depth where none plays.
    """
    plt = pyplot()
    x = np.asarray(depths, dtype=float)
    fig, ax = plt.subplots(1, 1, figsize=(6, 4))
    nan = float("nan")  # a depth with no stall probability (every draw failed numerically)
    if all(p.stall is not None for p in preds):
        prob = [nan if p.stall["probability"] is None else p.stall["probability"] for p in preds]
        lo = [p.stall["interval"][0] for p in preds]
        hi = [p.stall["interval"][1] for p in preds]
        ax.fill_between(x, lo, hi, color="C3", alpha=0.25, lw=0)
        part = preds[0].stall.get("part", "motor D")
        ax.plot(x, prob, "o-", color="C3", label=f"P({part} stalls)")
    if all(p.electronics_tripped is not None for p in preds):
        el = [p.electronics_tripped for p in preds]
        med = [nan if e["median"] is None else e["median"] for e in el]
        lo = [nan if e["median"] is None else e["interval"][0] for e in el]
        hi = [nan if e["median"] is None else e["interval"][1] for e in el]
        ax.fill_between(x, lo, hi, color="C2", alpha=0.15, lw=0)
        ax.plot(x, med, "s--", color="C2", label="electronics tripped (median)")
    if any(p.outcome is not None for p in preds):  # the draws that did not play, per depth
        share = {k: [0.0 if p.outcome is None else p.outcome[k]["share"] for p in preds]
                 for k in ("collapses", "fails_numerically")}  # fmt: skip
        ax.plot(x, share["collapses"], "v-", color="k", label="collapses (no band)"
                if any("p_mid" not in p.band for p in preds) else "collapses")  # fmt: skip
        if any(share["fails_numerically"]):
            ax.plot(x, share["fails_numerically"], "x:", color="0.5", label="fails numerically")
        for d, p in zip(x, preds, strict=True):
            if "p_mid" not in p.band:
                ax.annotate("no band", (d, 1.0), fontsize=7, ha="center", va="bottom")
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
