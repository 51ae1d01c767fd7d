"""Which dynamic load model a record supports: leave-one-event-out prediction.

With two or more events of one load, each model is fitted to all events but one and
asked to predict the one left out from its recorded voltage alone (``zip+motor`` by
``validate.validate_event``, a model of parts by ``validate_parts.validate_parts_event``,
the feeder's loop solved). Each model's score is the held-out events' expected log
predictive density (ELPD: the sum over scored samples of the log of the mean over draws
of their likelihood), beside the RMS of P and Q on the held-out events and the band's
coverage. Two models' difference has a standard error from the pointwise differences
(``sqrt(n) sd``, as PSIS-LOO's; Vehtari, Gelman and Gabry 2017); a difference within
two of its standard errors is said to be one the data do not settle.

That standard error is the data's, given the draws. Where the fits of the two best
models have not converged (``r_hat``, the largest R-hat over each model's fits, not
below :data:`~loadbayes.diagnostics.RHAT_MAX`), their scores move with the chains: on
the shared real record at 4000 x 2 draws (R-hat 1.3-2.4), transformer #2's choice went
to ``slm`` "ahead by 367.7 (SE 164.2)" at seed 1 and to ``cmld-lite`` "ahead by 301.9
(SE 117.7)" at seed 2. The words then say that the runs do not settle the choice.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from loadbayes.core.settings import SamplerSettings
from loadbayes.diagnostics import RHAT_MAX
from loadbayes.fit.composite.driver import fit_composite
from loadbayes.fit.composite.validate import validate_event
from loadbayes.fit.composite.validate_parts import validate_parts_event
from loadbayes.measurements.record import EventRecord

__all__ = ["ModelChoice", "choose_model", "compare_models"]


@dataclass
class ModelChoice:
    """Each model's held-out score, the best one and what the difference means."""

    table: list[dict[str, Any]]
    best: str
    words: str
    pointwise: dict[str, np.ndarray] = field(repr=False, default_factory=dict)
    #: Each model's fits, one per left-out event (``fits[name][k]`` left out event k).
    fits: dict[str, list[Any]] = field(repr=False, default_factory=dict)
    #: Each model's score on each left-out event (``held_out[name][k]``).
    held_out: dict[str, list[Any]] = field(repr=False, default_factory=dict)

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready (the pointwise densities left out)."""
        return {"table": self.table, "best": self.best, "words": self.words}


def _worst_rhat(fits) -> float | None:
    """The largest R-hat over the scalar draws of a model's fits (None with one chain)."""
    from loadbayes.core.convergence import summarize

    worst = []
    for fit in fits:
        x = [np.asarray(v, dtype=float) for v in fit.posterior.draws.values()]
        x = [v for v in x if v.ndim == 2 and v.shape[0] >= 2 and np.ptp(v) > 0]
        if x:
            worst.append(np.nanmax(summarize(np.stack(x), tail=False)["r_hat"]))
    return float(np.nanmax(worst)) if worst and not np.all(np.isnan(worst)) else None


def _held_out(model, post, event, mask, seed):
    if getattr(model, "parts", None) is not None:
        return validate_parts_event(post, model, event, exclude=mask, seed=seed)
    return validate_event(post, event, exclude=mask, seed=seed)


def _words(rows: list[dict[str, Any]]) -> str:
    """What the scores say, best first (``rows`` sorted, with ``d_elpd`` and ``r_hat``)."""
    best = rows[0]["model"]
    words = f"{best} predicts the held-out events best (ELPD {rows[0]['elpd']:.1f})"
    if len(rows) > 1:
        second = rows[1]
        gap, se = -second["d_elpd"], second["se_d_elpd"]
        slow = [r for r in rows[:2] if (r.get("r_hat") or 0.0) >= RHAT_MAX]  # None: unjudged
        if slow:
            worst = max(r["r_hat"] for r in slow)
            names = " and ".join(r["model"] for r in slow)
            words += (f"; {second['model']} is behind by {gap:.1f} (SE {se:.1f}), but the "
                      f"chains of {names} have not converged (R-hat up to {worst:.2f}): the "
                      "scores move with the chains, and these runs do not settle the choice "
                      "(run longer: --draws, --burn)")  # fmt: skip
        elif gap > 2 * se:
            words += f", ahead of {second['model']} by {gap:.1f} (SE {se:.1f})"
        else:
            words += (f"; {second['model']} is within {gap:.1f} (SE {se:.1f}): the data do "
                      "not settle the choice between them")  # fmt: skip
    return words


def compare_models(
    models: Sequence[Any],
    events: Sequence[EventRecord],
    *,
    sampler: SamplerSettings,
    exclude: Sequence[np.ndarray | None] | None = None,
) -> ModelChoice:
    """Score each model by leave-one-event-out prediction (see the module docstring)."""
    events = list(events)
    if len(events) < 2:
        raise ValueError("choosing a model by held-out prediction needs two or more events")
    masks = list(exclude) if exclude is not None else [None] * len(events)
    rows, pointwise, fits, held = [], {}, {}, {}
    for model in models:
        lpd, rms_p, rms_q, cov_p, cov_q = [], [], [], [], []
        fits[model.name], held[model.name] = [], []
        parts = getattr(model, "parts", None) is not None
        for k, ev in enumerate(events):
            # A model of parts is told which rows straddle a step (the scoring's masks): it
            # leaves them out and steps across (models/parts.step_knots); zip+motor finds
            # its own edges.
            train = [replace(e, straddle=np.asarray(masks[j], bool))
                     if parts and masks[j] is not None else e
                     for j, e in enumerate(events) if j != k]  # fmt: skip
            fit = fit_composite(model, train, sampler=sampler)
            v = _held_out(model, fit.posterior, ev, masks[k], sampler.seed)
            fits[model.name].append(fit)
            held[model.name].append(v)
            lpd.append(v.lpd)
            rms_p.append(v.rms_p)
            rms_q.append(v.rms_q)
            cov_p.append(v.coverage_p)
            cov_q.append(v.coverage_q)
        pw = np.concatenate(lpd)
        pointwise[model.name] = pw
        rows.append({
            "model": model.name, "elpd": float(pw.sum()),
            "rms_p": float(np.mean(rms_p)), "rms_q": float(np.mean(rms_q)),
            "coverage_p": float(np.mean(cov_p)), "coverage_q": float(np.mean(cov_q)),
            "r_hat": _worst_rhat(fits[model.name]),
        })  # fmt: skip
    rows.sort(key=lambda r: -r["elpd"])
    best = rows[0]["model"]
    for r in rows:
        diff = pointwise[r["model"]] - pointwise[best]
        r["d_elpd"] = float(diff.sum())
        r["se_d_elpd"] = float(math.sqrt(diff.size) * np.std(diff)) if diff.size > 1 else 0.0
    return ModelChoice(rows, best, _words(rows), pointwise, fits, held)


def choose_model(events: Sequence[EventRecord], *, f_hz: float, sampler: SamplerSettings,
                 negative_sequence: str = "auto") -> tuple[Any, dict[str, Any]]:  # fmt: skip
    """``--model auto``: ``zip+motor``, ``slm`` and ``cmld-lite`` compared, the best returned.

    Each fitted to all events but one at ``sampler``'s draws (not run on to convergence)
    and scored on the one left out; returns the model of the best ELPD and the
    comparison's record (:meth:`ModelChoice.to_dict`).
    """
    from loadbayes.io.errors import OptionError
    from loadbayes.models.dynamic import dynamic_model

    if len(events) < 2:
        raise OptionError("--model auto needs two or more events: it scores each model by "
                          "predicting each event from the others")  # fmt: skip
    ns = negative_sequence
    models = [dynamic_model("zip+motor", f_hz=f_hz),
              dynamic_model("slm", f_hz=f_hz, negative_sequence=ns),
              dynamic_model("cmld-lite", f_hz=f_hz, negative_sequence=ns)]  # fmt: skip
    ch = compare_models(models, events, sampler=sampler.with_(until_converged=False))
    return next(m for m in models if m.name == ch.best), ch.to_dict()
