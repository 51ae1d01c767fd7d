"""The composite fit's plain-words identifiability report.

Which motor parameters the events determine, which stay close to their prior, which lie
on a ridge, and what would help (:func:`identifiability`); whether estimated torque
shares were determined (:func:`torque_identifiability`); and the warning the fit prints
for the prior-driven ones (:func:`prior_driven_warning`).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from loadbayes.fit.composite.torque import PRIOR_SD
from loadbayes.models.composite import SCALE_FREE_MATRIX, SCALE_FREE_NAMES
from loadbayes.models.composite_prior import CompositePrior

__all__ = [
    "DETERMINED",
    "MOTOR_SHARE_SD",
    "PLAIN_NAMES",
    "PRIOR_DRIVEN",
    "RIDGE_CORR",
    "identifiability",
    "prior_driven_warning",
    "torque_identifiability",
]

#: Plain names of the sampled (scale-free) coordinates, for the identifiability section.
#: The rating is unknown, so impedances are read on the base of the motor's own initial
#: load torque (T0 = 1): that is what an event can determine.
PLAIN_NAMES = {
    "log_rs_t0": "stator resistance Rs",
    "log_x_prime_t0": "transient reactance X'",
    "log_dx_t0": "X - X' (open-circuit minus transient reactance)",
    "log_t_prime": "transient time constant T'",
    "log_h_over_t0": "inertia H",
}
#: Posterior sd / prior sd (on the log scale) above which a parameter is "prior-driven",
#: and below which it is "determined by the data".
PRIOR_DRIVEN, DETERMINED = 0.7, 0.3
#: |posterior correlation| above which two sampled parameters are said to form a ridge.
RIDGE_CORR = 0.9
#: Posterior sd of the motor share f_m below which it is "well determined".
MOTOR_SHARE_SD = 0.1


def identifiability(
    theta: np.ndarray, f_m: np.ndarray, prior: CompositePrior, n_events: int
) -> dict[str, Any]:
    """Plain-words identifiability of the motor from posterior draws against the prior.

    Judged on the scale-free coordinates (``SCALE_FREE_NAMES``: Rs, X', X - X', H on the
    base of the motor's load torque, and T'), the only ones the data can inform; the
    loading ``T0`` itself (equivalently the rating) is always the prior's.

    Parameters
    ----------
    theta : ndarray, shape (..., 6)
        Draws of the log motor parameters (``THETA_NAMES``).
    f_m : ndarray
        Draws of the motor share (event 0).
    prior : CompositePrior
        The prior the draws came from.
    n_events : int
        Number of events fitted.

    Returns
    -------
    dict
        ``parameters`` (per coordinate: the sd ratio and a verdict), ``ridges``,
        ``motor_share`` and ``summary`` / ``what_would_help`` sentences.
    """
    flat = theta.reshape(-1, 6) @ SCALE_FREE_MATRIX.T
    u = flat[:, :5]
    _, cov_u, _, _ = prior.scale_free()
    ratio = u.std(axis=0) / np.sqrt(np.diag(cov_u))
    params = {}
    for name, r in zip(SCALE_FREE_NAMES, ratio, strict=True):
        verdict = (
            "prior-driven"
            if r > PRIOR_DRIVEN
            else ("determined by the data" if r < DETERMINED else "partly determined")
        )
        params[name] = {"posterior_sd_over_prior_sd": float(r), "verdict": verdict}
    corr = np.corrcoef(u.T)
    ridges = []
    for i in range(5):
        for j in range(i + 1, 5):
            if abs(corr[i, j]) > RIDGE_CORR:
                a, b = SCALE_FREE_NAMES[i], SCALE_FREE_NAMES[j]
                ridges.append(
                    {
                        "pair": [a, b],
                        "correlation": float(corr[i, j]),
                        "words": f"{PLAIN_NAMES[a]} and {PLAIN_NAMES[b]} trade off (posterior "
                        f"correlation {corr[i, j]:+.2f}): the events fix a combination of "
                        "them, not each one.",
                    }
                )
    fm = f_m.reshape(-1)
    fm_sd = float(np.std(fm))
    fm_ok = fm_sd < MOTOR_SHARE_SD
    weak = [PLAIN_NAMES[n] for n, p in params.items() if p["verdict"] == "prior-driven"]
    partly = [PLAIN_NAMES[n] for n, p in params.items() if p["verdict"] == "partly determined"]
    good = [PLAIN_NAMES[n] for n, p in params.items() if p["verdict"] == "determined by the data"]
    words = [
        f"The motor's share of the initial load is {'well' if fm_ok else 'poorly'} "
        f"determined (f_m = {np.mean(fm):.3f} +- {fm_sd:.3f})."
    ]
    if good:
        words.append("Determined by the data: " + ", ".join(good) + ".")
    if partly:
        words.append("Partly determined (the prior still matters): " + ", ".join(partly) + ".")
    if weak:
        words.append(
            "The data say little about "
            + ", ".join(weak)
            + ": their posterior stays close to the prior, so their values are the prior's."
        )
    words.append(
        "The motor's rating (mva_m) and its loading T0 are never determined by terminal "
        "data, only their product: the per-unit impedances and H are reported on a base "
        "whose size comes from the prior of T0 (give it from nameplate data if known)."
    )
    help_ = []
    if weak or partly or not fm_ok or ridges:
        help_ = [
            "a deeper voltage event (a sag of 20-50% moves the motor's speed and flux "
            "far more than a shallow one)",
            f"more events of the same load fitted jointly (this fit used {n_events})",
            "a prior from nameplate data (rating, H, locked-rotor current) on the "
            "parameters marked prior-driven",
        ]
    return {
        "parameters": params,
        "ridges": ridges,
        "motor_share": {"sd": fm_sd, "well_determined": bool(fm_ok)},
        "summary": " ".join(words),
        "what_would_help": help_,
        "thresholds": {
            "prior_driven_above": PRIOR_DRIVEN,
            "determined_below": DETERMINED,
            "ridge_correlation": RIDGE_CORR,
        },
    }


def prior_driven_warning(ident: dict[str, Any]) -> str | None:
    """The warning naming the prior-driven motor parameters and what would help, or None."""
    weak = [n for n, p in ident["parameters"].items() if p["verdict"] == "prior-driven"]
    if not weak:
        return None
    return (
        "prior-driven (the events barely inform them): "
        + ", ".join(PLAIN_NAMES[n] for n in weak)
        + ". "
        + "; ".join(ident["what_would_help"])
        + " would help."
    )


def torque_identifiability(abc: np.ndarray) -> dict:
    """Whether the event determined the shares: posterior sd of each against the prior's.

    Parameters
    ----------
    abc : ndarray, shape (..., 3)
        Draws of ``A, B, C``.

    Returns
    -------
    dict
        Per share the sd ratio and a verdict, and a ``summary`` sentence.
    """
    flat = abc.reshape(-1, 3)
    out, words = {}, []
    for i, name in enumerate(("a", "b", "c")):
        r = float(flat[:, i].std() / PRIOR_SD)
        verdict = (
            "prior-driven"
            if r > PRIOR_DRIVEN
            else ("determined by the data" if r < DETERMINED else "partly")
        )
        out[name] = {
            "posterior_sd_over_prior_sd": r,
            "verdict": verdict,
            "mean": float(flat[:, i].mean()),
        }
    weak = [n.upper() for n, v in out.items() if v["verdict"] == "prior-driven"]
    if len(weak) == 3:
        words.append(
            "The event did not determine the load-torque shares A, B, C: their posterior is "
            "close to the uniform prior, so the reported values are the prior's. The torque's "
            "speed dependence shows only when the speed moves a lot (a deep, long sag)."
        )
    elif weak:
        words.append(
            "The torque shares are only partly determined: "
            + ", ".join(weak)
            + " stay close to their prior; A, B, C trade off against each other."
        )
    else:
        means = ", ".join(f"{n.upper()} = {v['mean']:.2f}" for n, v in out.items())
        words.append(f"The event informs the torque shares ({means}).")
    return {"shares": out, "prior": "Dirichlet(1, 1, 1)", "summary": " ".join(words)}
