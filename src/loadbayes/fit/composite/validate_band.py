"""The held-out band with the model error the fitted events' own playback shows.

A fit's noise (``tau_p``, ``tau_q``) is what its likelihood left unexplained, on the path
the fit reads (for ``zip+motor``, with the steps' instants and the straddling rows it
fits). A prediction plays the voltage through a different path (no step instants: the
voltage read linearly between samples), and where that path misses the fitted events
themselves by more than the fit's noise, a band of model + fit noise is falsely narrow on
any held-out event.

:func:`playback_error` plays the fitted events back through their own fit as the held-out
scoring does (``validate.validate_event``, ``validate_parts.validate_parts_event``) and
fits, per channel, the stated error model of ``fit/composite/model_error.py`` on what it
misses: recorded = model + d (AR(1), the model's form) + e (white: the recorder's noise,
half the variance of the steady pre-fault rows' differences). :func:`honest_band` then
gives each held-out event, per channel, the wider of two bands:

- the fit's noise band (each draw plus its own noise, percentiles over the draws) when
  the playback shows no more error than the fit's noise: the playback's mean square not
  above the fit's mean noise variance by more than chance allows (one-sided chi-square
  at :data:`ALPHA`, the residuals white under a true model), or the stated model's
  ``s_d^2 + s_e^2`` not above it: the model reads its own events as its fit did;
- else ``model_error.discrepancy_band``: the posterior-mean prediction
  +- z sqrt(spread^2 + s_d^2 + s_e^2).

``coverage_p``, ``coverage_q`` are then the chosen band's; the fit-noise band's coverage
is kept beside it (``coverage_fit_noise_p``, ``coverage_fit_noise_q``), and the event
says which band it used and what the playback missed (``playback``).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import replace
from typing import Any

import numpy as np

from loadbayes.fit.composite.model_error import (
    discrepancy_band,
    fit_discrepancy,
    noise_floor,
)
from loadbayes.fit.composite.validate import EventValidation, noise_precision
from loadbayes.posterior import Posterior

__all__ = [
    "BAND_FIT_NOISE", "BAND_MODEL_ERROR", "fitted_masks", "honest_band", "honest_bands",
    "playback_error",
]  # fmt: skip

BAND_FIT_NOISE = "fit noise"
BAND_MODEL_ERROR = "model error (AR(1), fitted on the fitted events' playback) + noise"

#: False-alarm rate of "the playback shows more error than the fit's noise" when the
#: model is true (the playback's residuals then white with the fit's noise variance).
ALPHA = 0.01

#: Time between fitted events in the joint AR(1) fit, in sample intervals: rho ** GAP is 0,
#: so each event's model error is its own series with the same sd and rho.
GAP = 10**6


def fit_noise_sd(post: Posterior, channel: str) -> float:
    """The fit's noise sd of one sample: sqrt of the draws' mean of ``1 / precision``."""
    d = {k: np.asarray(v, dtype=float).reshape(-1) for k, v in post.draws.items()
         if k in (f"tau_{channel}", f"rho_{channel}")}  # fmt: skip
    n = d[f"tau_{channel}"].size
    return math.sqrt(float(np.mean([1.0 / noise_precision(d, channel, i) for i in range(n)])))


def _steady(v: EventValidation) -> np.ndarray:
    """The scored rows before the voltage first moves or the first unscored row."""
    from loadbayes.measurements.events import STEADY_DV

    ev, sc = v.event, np.asarray(v.scored, bool)
    moved = np.flatnonzero((np.abs(ev.v / ev.v0 - 1.0) > STEADY_DV) | ~sc)
    k = int(moved[0]) if moved.size else ev.n
    return sc & (np.arange(ev.n) < k)


def playback_error(post: Posterior, fitted: Sequence[EventValidation]) -> dict[str, dict]:
    """Per channel, the model error of the fitted events played back through their fit.

    ``fitted``: each fitted event scored against its own fit (the held-out path). Returns
    ``{"p": {...}, "q": {...}}`` with ``disc`` (:class:`~model_error.Discrepancy`: one sd
    and rho for every event, each event its own series), ``rms`` (recorded minus the
    posterior-mean prediction over the scored rows, per unit of the fitted P0) and
    ``sd_fit_noise`` (:func:`fit_noise_sd`, per unit), ``n`` (the rows) and ``scale``.
    """
    out = {}
    for ch in ("p", "q"):
        resid, times, floors, weights, offset = [], [], [], [], 0.0
        for v in fitted:
            sc = np.asarray(v.scored, bool)
            x = getattr(v.event, ch)
            t = v.event.t[sc] - v.event.t[sc][0]
            dt = float(np.median(np.diff(t))) if t.size > 1 else 1.0
            resid.append((x - v.band[f"{ch}_mean"])[sc])
            times.append(t + offset)
            offset += float(t[-1]) + GAP * dt
            steady = _steady(v)
            if steady.sum() > 2:
                floors.append(noise_floor(x[steady]))
                weights.append(int(steady.sum()))
        r = np.concatenate(resid)
        var_e = float(np.average(floors, weights=weights)) if floors else 0.0
        disc = fit_discrepancy(r, np.concatenate(times), var_e)
        out[ch] = {"disc": disc, "rms": float(np.sqrt(np.mean(r**2))) / fitted[0].scale,
                   "sd_fit_noise": fit_noise_sd(post, ch), "n": int(r.size),
                   "scale": fitted[0].scale}  # fmt: skip
    return out


def _wider(e: dict) -> bool:
    """Whether the playback shows more error than the fit's noise (and a wider band).

    One-sided at :data:`ALPHA`: the model true, the playback's ``n`` residuals are the
    noise, white, and ``n rms^2 / sd^2`` is chi-square on ``n`` degrees of freedom.
    """
    from scipy.stats import chi2

    disc, sd = e["disc"], e["sd_fit_noise"] / e["scale"]
    more = e["rms"] ** 2 > sd**2 * chi2.ppf(1 - ALPHA, e["n"]) / e["n"]
    return bool(more and disc.sd_d**2 + disc.sd_e**2 > e["sd_fit_noise"] ** 2)


def honest_band(held: EventValidation, error: dict[str, dict],
                prob: float = 0.95) -> EventValidation:  # fmt: skip
    """``held`` with each channel's band the wider of the fit-noise and model-error bands.

    ``error``: :func:`playback_error`'s. The fit-noise band's coverage stays in
    ``coverage_fit_noise_p``, ``coverage_fit_noise_q``; ``band_p``, ``band_q`` name the
    band used; ``playback`` holds the fitted events' playback error (per unit of the
    fitted P0).
    """
    band, cover, kind, info = dict(held.band), {}, {}, {}
    sc = np.asarray(held.scored, bool)
    for ch in ("p", "q"):
        e = error[ch]
        disc, x = e["disc"], getattr(held.event, ch)
        cover[ch] = getattr(held, f"coverage_{ch}")
        kind[ch] = BAND_FIT_NOISE
        if _wider(e):
            lo, hi = discrepancy_band(band[f"{ch}_mean"], band[f"{ch}_spread"], disc, prob)
            band[f"{ch}_lo"], band[f"{ch}_hi"] = lo, hi
            cover[ch] = float(np.mean((x[sc] >= lo[sc]) & (x[sc] <= hi[sc])))
            kind[ch] = BAND_MODEL_ERROR
        s = held.scale
        info[ch] = {"rms": e["rms"], "model_error_sd": disc.sd_d / s, "model_error_rho": disc.rho,
                    "noise_sd": disc.sd_e / s, "fit_noise_sd": e["sd_fit_noise"] / s,
                    "band": kind[ch]}  # fmt: skip
    return replace(
        held, band=band, coverage_p=cover["p"], coverage_q=cover["q"],
        coverage_fit_noise_p=held.coverage_p, coverage_fit_noise_q=held.coverage_q,
        band_p=kind["p"], band_q=kind["q"], playback=info,
    )  # fmt: skip


def honest_bands(post: Posterior, held: Sequence[EventValidation],
                 fitted: Sequence[EventValidation], prob: float = 0.95) -> list[Any]:  # fmt: skip
    """:func:`honest_band` of each held-out event, the error read from ``fitted``."""
    error = playback_error(post, fitted)
    return [honest_band(h, error, prob) for h in held]


def fitted_masks(events: Sequence[Any], window_s: float) -> list[np.ndarray]:
    """Per fitted event, the rows its playback does not score.

    The event's own ``straddle`` flags where its reader set them; else the rows inside
    each edge ``models/composite_steps.FitSamples`` finds (those whose window straddles a
    step, and with point samples those on a step's ramp). There the fit reads the step at
    its fitted instant and the playback reads the voltage linearly between samples: a
    miss of a row or two that is the reading's, not the load's, and that a held-out
    event's straddle flags leave out of its scores too.
    """
    from loadbayes.models.composite_steps import FitSamples

    out = []
    for e in events:
        if getattr(e, "straddle", None) is not None:
            out.append(np.asarray(e.straddle, bool))
            continue
        found = FitSamples.find([e.t], [e.v], window_s=window_s, detect=True)
        mask = ~np.isin(np.arange(e.n), found.keep[0])
        for k0, k1 in found.edges[0]:
            mask[k0 + 1 : k1] = True
        out.append(mask)
    return out
