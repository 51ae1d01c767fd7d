"""A fitted model of parts checked on an event it was not fitted to, and scored for choice.

:func:`validate_parts_event` plays the held-out event's recorded voltage (magnitude and
angle, at the recorded bus) through posterior draws of a ``slm`` or ``cmld-lite`` fit,
the feeder's loop solved (``models/parts_predict.py``), at the event's own operating
point (``validate.operating_point``), with each draw's noise added for the band, as
``fit/composite/validate.py`` does for ``zip+motor``. Its result is the same
:class:`~loadbayes.fit.composite.validate.EventValidation`, plus the held-out event's
log predictive density (``elpd``: the log of the mean over draws of each sample's
Gaussian likelihood, summed over the scored samples of P and Q), which
:mod:`loadbayes.fit.composite.choice` compares between models.
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from loadbayes.fit.composite.validate import (
    N_DRAWS,
    EventValidation,
    band_scores,
    gaussian_logl,
    noise_precision,
    operating_point,
    pointwise_lpd,
)
from loadbayes.measurements.record import EventRecord
from loadbayes.models.parts_predict import predict_parts
from loadbayes.posterior import Posterior

__all__ = ["validate_parts_event"]


def validate_parts_event(
    post: Posterior,
    model,
    event: EventRecord,
    *,
    exclude: np.ndarray | None = None,
    n_draws: int = N_DRAWS,
    prob: float = 0.95,
    seed: int = 0,
) -> EventValidation:
    """Play one event's voltage through a parts model's posterior; score P and Q."""
    d = {n: np.asarray(v, dtype=float).reshape(-1) for n, v in post.draws.items()}
    missing = [n for n in (*model.theta_names, "cq2", "tau_p", "tau_q") if n not in d]
    if missing:
        raise ValueError(f"the posterior holds no draws of {', '.join(missing)}: not a "
                         f"{model.name} fit")  # fmt: skip
    rng = np.random.default_rng(seed)
    total = d["tau_p"].size
    pick = rng.choice(total, size=min(n_draws, total), replace=False)
    scored = np.ones(event.n, dtype=bool) if exclude is None else ~np.asarray(exclude, bool)
    if not scored.any():
        raise ValueError(f"{event.name or 'the event'}: every sample is excluded: nothing to score")
    p0n, q0n = operating_point(event, scored)
    n_out = int(event.n - scored.sum())
    full = replace(event, straddle=~scored) if n_out else event
    rows = scored
    if n_out:  # the rows straddling a step left out: the motors step across the gap
        event = event.take(scored)
        scored = np.ones(event.n, dtype=bool)
    theta = np.stack([d[n] for n in model.theta_names], -1)
    cq = np.stack([d["cq2"], d["cq1"], d["cq0"]], -1)
    means_p, means_q, noisy_p, noisy_q, logl = [], [], [], [], []
    for i in pick:
        share = cq[i] / cq[i].sum() if abs(cq[i].sum()) > 1e-9 else np.array([0.0, 0.0, 1.0])
        out = predict_parts(model, full, theta[i], p0n, q0n, share)
        if out is None:
            continue
        mp, mq, _ = out
        if mp.size != event.n:  # point samples (window_s 0): every row predicted, so pick
            mp, mq = mp[rows], mq[rows]
        tau_p, tau_q = noise_precision(d, "p", i), noise_precision(d, "q", i)
        sp, sq = 1 / math.sqrt(tau_p), 1 / math.sqrt(tau_q)
        means_p.append(mp)
        means_q.append(mq)
        noisy_p.append(mp + sp * rng.standard_normal(event.n))
        noisy_q.append(mq + sq * rng.standard_normal(event.n))
        logl.append(gaussian_logl(event, mp, mq, tau_p, tau_q))
    if not means_p:
        raise ValueError(f"{event.name or 'the event'}: no posterior draw has a steady state at "
                         f"its first voltage ({event.v0:.4g} p.u.)")  # fmt: skip
    scale = float(np.mean(d["p0"]))
    band, scores = band_scores(event, scored, (noisy_p, noisy_q), (means_p, means_q), scale,
                               prob)  # fmt: skip
    return EventValidation(
        file=event.name, n=event.n + n_out, n_excluded=n_out, event=event,
        scored=scored, band=band, p0=p0n, q0=q0n, draws_used=len(means_p), scale=scale,
        lpd=pointwise_lpd(logl, scored), **scores,
    )  # fmt: skip
