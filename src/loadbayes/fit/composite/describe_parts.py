"""What a fit of a model built from parts says in words beside its draws.

For a :class:`~loadbayes.models.parts_model.PartsModel` fit (``slm``, ``cmld-lite``):

- **physical**: the shares are on their simplex by construction; each motor's Rs and H
  on its own base are checked against the physical region a planner can use (Rs <= 0.1,
  H >= 0.05 s, X' 0.04 to 0.65, :data:`PHYSICAL`), on the posterior's median and interval;
- **left to the prior**: a motor, feeder or threshold parameter whose posterior spread
  (of the log, where its prior is log-normal) is more than :data:`PRIOR_DRIVEN` of the
  prior's was not determined by the events, and is said to be the prior's (its
  interval is the published range it came from);
- **the negative sequence**: which events it entered (rows, their |V2|), or why not, and
  the motors' ratings it speaks to.

The words go into the posterior's warnings and ``extra_json["parts"]`` (the JSON).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from loadbayes.models.part_priors import (
    FEEDER_X,
    MOTOR_CLASSES,
    THRESHOLD_PRIORS,
    X_PRIME_RANGE,
)
from loadbayes.models.parts_model import NEG_SEQ_MIN

__all__ = ["PHYSICAL", "PRIOR_DRIVEN", "describe_parts", "parts_residuals", "prior_driven"]

#: The physical region of a motor on its own base: Rs at most 0.1, H at least 0.05 s,
#: X' in the range published locked-rotor currents allow (``part_priors.X_PRIME_RANGE``).
PHYSICAL = {"rs": (None, 0.1), "h_s": (0.05, None), "x_prime": X_PRIME_RANGE}
#: Posterior sd of a log-parameter over the prior's above which it is the prior's.
PRIOR_DRIVEN = 0.7


def _interval(x: np.ndarray, prob: float) -> tuple[float, float]:
    lo, hi = np.quantile(x, [(1 - prob) / 2, (1 + prob) / 2])
    return float(lo), float(hi)


def prior_driven(model: Any, draws: dict[str, np.ndarray],
                 hdi_prob: float = 0.95) -> list[tuple[str, tuple[float, float]]]:  # fmt: skip
    """The motor, feeder and threshold parameters whose posterior keeps their prior's spread.

    ``(name, interval)`` of each whose posterior sd (of the log, for the log-normal
    priors) is above :data:`PRIOR_DRIVEN` of the prior's (the events did not determine
    it); the sampled thresholds (motor D's stall voltage and time, the electronics' trip
    voltages) are judged the same way.
    """
    prior_of = {}
    for m, t in zip(model.motors, model._tags, strict=True):
        for k, (median, sd) in MOTOR_CLASSES[m]["prior"].items():
            prior_of[k + t] = model.priors.get(k + t, (median, sd))
    if model.feeder:
        prior_of["x_fd"] = model.priors.get("x_fd", FEEDER_X)
    logs = set(prior_of)
    for name in getattr(model, "thresholds", ()):
        kind, centre, sd = THRESHOLD_PRIORS[name]
        prior_of[name] = model.priors.get(name, (centre, sd))
        if kind == "lognormal":
            logs.add(name)
    out = []
    for name, (_median, sd) in prior_of.items():
        if name not in draws or not sd > 0:
            continue
        x = np.asarray(draws[name], dtype=float).ravel()
        if float(np.std(np.log(x) if name in logs else x)) / sd > PRIOR_DRIVEN:
            out.append((name, _interval(x, hdi_prob)))
    return out


#: A median AR(1) coefficient above which the noise is said to be nearly a random walk.
RHO_RANDOM_WALK = 0.95


def parts_residuals(problem: Any, blocks: Any, n_draws: int = 20) -> dict[str, float]:
    """Lag-1 autocorrelation of P's and Q's residuals, over a few posterior draws.

    Each draw's residuals ``y - Z beta`` of every event (its kept samples, in time
    order), the lag-1 autocorrelation of each channel, averaged over the draws and the
    events weighted by their samples.
    """
    theta = blocks.theta.reshape(-1, blocks.theta.shape[-1])
    betas = blocks.betas.reshape(-1, *blocks.betas.shape[-2:])
    pick = np.linspace(0, theta.shape[0] - 1, min(n_draws, theta.shape[0])).astype(int)
    acc, weight = np.zeros(2), 0.0
    for i in pick:
        for ev, b in zip(problem.events, betas[i], strict=True):
            ch = problem.model.channels(ev, theta[i])
            if ch is None:
                continue
            for g in range(2):
                z, y = ch[g]
                e = y - z @ b
                e = e - e.mean()
                den = float(e @ e)
                acc[g] += (float(e[1:] @ e[:-1]) / den if den > 0 else 0.0) * y.size
            weight += ch[0][1].size
    lag = acc / weight if weight else np.zeros(2)
    return {"lag1_p": float(lag[0]), "lag1_q": float(lag[1])}


def describe_parts(post: Any, draws: dict[str, np.ndarray], model: Any, events: list,
                   hdi_prob: float = 0.95,
                   residuals: dict[str, float] | None = None) -> None:  # fmt: skip
    """Add the words of a parts model's fit to ``post`` (warnings and ``extra_json``)."""
    words: dict[str, Any] = {"model": model.name, "parts": list(model.parts) + ["static"]}
    if residuals:
        # Residuals that run in stretches are model form, not noise: a white residual has
        # lag-1 autocorrelation about 0; one part white noise and one part a misfit whose
        # own lag-1 is rho has lag-1 = (the misfit's share) x rho, so with rho <= 1 the
        # lag-1 is a lower bound of the misfit's share (equal for a smooth misfit).
        share = {k: max(v, 0.0) for k, v in residuals.items()}
        words["residuals"] = {**residuals, "model_form_share_p": share["lag1_p"],
                              "model_form_share_q": share["lag1_q"]}  # fmt: skip
        ar = getattr(model, "noise", "white") == "ar1" and "rho_p" in draws
        if ar:  # the share is modelled: said with the coefficients, not warned of
            rho = {g: float(np.median(draws[f"rho_{g}"])) for g in ("p", "q")}
            words["residuals"]["rho_p"], words["residuals"]["rho_q"] = rho["p"], rho["q"]
            words["residuals"]["noise"] = (
                f"AR(1) noise (rho {rho['p']:.2f} for P, {rho['q']:.2f} for Q, medians) "
                "takes the residuals' stretches as correlated error: the intervals widen "
                "for the model's form instead of biasing"
            )
            top = float(getattr(model, "rho_max", 0.999))
            hi = {g: float(np.quantile(draws[f"rho_{g}"], 0.975)) for g in ("p", "q")}
            at = [g.upper() for g in ("p", "q") if top < 0.999 and hi[g] > top - 0.01]
            if at:
                post.warnings.append(
                    f"rho of {' and '.join(at)} sits at its bound {top:g} (rho_max, --rho-max): "
                    "the bound, not the data, sets how correlated the noise is, and so how "
                    "wide the intervals are"
                )
            near = {g: r for g, r in rho.items() if r > RHO_RANDOM_WALK}
            if near:
                said = ", ".join(f"{r:.3f} for {g.upper()}" for g, r in near.items())
                post.warnings.append(
                    f"the AR(1) noise is nearly a random walk (rho {said}): it takes up the "
                    "slow part of the response the parts would explain, and the parts' values "
                    "rest on the rows' differences alone; do not use them without comparing "
                    "the white-noise fit (--noise white) and a held-out event"
                )
        elif max(share.values()) > 0.3:
            post.warnings.append(
                f"the residuals run in stretches (lag-1 autocorrelation {residuals['lag1_p']:.2f} "
                f"for P, {residuals['lag1_q']:.2f} for Q): at least {share['lag1_p']:.0%} and "
                f"{share['lag1_q']:.0%} of the error is the model's form, not noise, and the "
                "white-noise likelihood does not widen the intervals for it"
            )
    driven = [f"{name} [{lo:.3g}, {hi:.3g}]" for name, (lo, hi) in
              prior_driven(model, draws, hdi_prob)]  # fmt: skip
    unphysical = []
    at_limit = []
    # The model's own limits (a user may move them), each side checked where it has one.
    region = {"rs": (None, model.rs_max), "h_s": (model.h_min, None),
              "x_prime": (model.x_prime_min, model.x_prime_max)}  # fmt: skip
    for t in model._tags:
        for key, (low, high) in PHYSICAL.items():
            x = np.asarray(draws[key + t], dtype=float).ravel()
            med = float(np.median(x))
            if (low is not None and med < low) or (high is not None and med > high):
                unphysical.append(f"{key + t} {med:.3g} (median)")
            lo, hi = _interval(x, hdi_prob)
            for limit, near in ((region[key][1], hi > 0.97 * (region[key][1] or 0)),
                                (region[key][0], lo < 1.03 * (region[key][0] or 0))):  # fmt: skip
                if model.physical_region and limit is not None and near:
                    at_limit.append(f"{key + t} [{lo:.3g}, {hi:.3g}] against {limit:g}")
    words["prior_driven"] = driven
    words["at_physical_limit"] = at_limit
    if at_limit:
        post.warnings.append(
            "at the physical region's limit (held there by the prior: the data pull past "
            "it, so the model lacks something this load has): " + ", ".join(at_limit)
        )
    words["unphysical"] = unphysical
    if driven:
        post.warnings.append(
            "left to the prior (the events did not determine them; their intervals are the "
            "published ranges the priors hold, models/part_priors.py): " + ", ".join(driven)
        )
    if unphysical:
        post.warnings.append(
            "outside the physical region of a motor (Rs <= 0.1, H >= 0.05 s, X' "
            f"{X_PRIME_RANGE[0]:g} to {X_PRIME_RANGE[1]:g} on its base): " + ", ".join(unphysical)
        )
    used = []
    for k, ev in enumerate(events):
        if model.negative_sequence != "off" and model.uses_negative_sequence(ev):
            keep = model.kept(ev)  # the rows the likelihood read (not those across a step)
            rows = int(np.sum(np.abs(np.asarray(ev.v2)[keep]) >= NEG_SEQ_MIN))
            used.append({"event": k, "name": ev.name, "rows": rows,
                         "v2_max": float(np.max(np.abs(ev.v2)))})  # fmt: skip
    words["negative_sequence"] = {"events": used, "threshold_v2_pu": NEG_SEQ_MIN}
    if used:
        words["negative_sequence"]["summary"] = (
            f"the negative sequence entered the fit at {sum(u['rows'] for u in used)} "
            f"rows of {len(used)} event(s) (|V2| >= {NEG_SEQ_MIN} p.u.): it measures the "
            "motors' rating over their X' (S / X')"
        )
    else:
        words["negative_sequence"]["summary"] = (
            "no negative sequence in the fit: "
            + (
                "it is off"
                if model.negative_sequence == "off"
                else f"no event has v2, i2 columns with |V2| >= {NEG_SEQ_MIN} p.u."
            )  # fmt: skip
        )
    ratings = {}
    for name in draws:
        if name.startswith("mva") and "_e" not in name:
            lo, hi = _interval(np.asarray(draws[name]).ravel(), hdi_prob)
            ratings[name] = {"median": float(np.median(draws[name])), "interval": [lo, hi]}
    words["ratings"] = ratings
    post.extra_json["parts"] = words
    post.extra_json["identifiability"] = {
        "summary": words["negative_sequence"]["summary"]
        + (f"; left to the prior: {len(driven)} parameter(s)" if driven else "")
    }
