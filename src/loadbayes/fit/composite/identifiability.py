"""The composite fit's plain-words identifiability report.

One idea needs these 404 lines: the composite fit's identifiability report in plain
words, for the motor's parameters, the torque shares and the static part.
Which motor parameters the events determine, which stay close to their prior, which lie
on a ridge, and what would help (:func:`identifiability`); whether estimated torque
shares were determined (:func:`torque_identifiability`); and the warning the fit prints
for the prior-driven ones (:func:`prior_driven_warning`). A quantity whose interval
reaches its prior's bound (f_m and the shares under bounded shares, :func:`at_bound`) is
said to be at its bound, never well determined. (A little over 400 lines: the one idea is
the words of the identifiability section, motor, torque and static part together.)
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
    "SHARE_SD",
    "STATIC_CORR",
    "at_bound",
    "short_window",
    "static_identifiability",
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
#: The ZIP shares of one channel are "not determined" when the posterior correlation of
#: the impedance and current shares is below ``STATIC_CORR``, when a share's sd exceeds
#: ``SHARE_SD``, or when it exceeds ``PRIOR_DRIVEN`` times the prior's sd of the share.
STATIC_CORR, SHARE_SD = -0.9, 0.3
#: An interval end closer to its support's bound than this share of the interval's width
#: "reaches the bound": the posterior is piled against it (f_m 0.947 [0.847, 1.000]).
BOUND_SHARE = 0.05
#: What is said of a quantity at its bound.
AT_BOUND = "at its bound (the prior's support), not determined by the data"


def at_bound(x: np.ndarray, prob: float = 0.95, support: tuple[float, float] = (0.0, 1.0)):
    """The central ``prob`` interval of ``x`` if it reaches a bound of ``support``, else None."""
    x = np.asarray(x, dtype=float).ravel()
    if x.size == 0 or not np.all(np.isfinite(x)):
        return None
    lo, hi = (float(v) for v in np.quantile(x, [(1 - prob) / 2, (1 + prob) / 2]))
    near = BOUND_SHARE * (hi - lo)
    return (lo, hi) if lo - support[0] <= near or support[1] - hi <= near else None


def identifiability(
    theta: np.ndarray,
    f_m: np.ndarray,
    prior: CompositePrior,
    n_events: int,
    *,
    span_s: float | None = None,
    bounded: bool = False,
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
    span_s : float, optional
        The longest event's span (s); under ``MIN_SPAN_S`` the summary says what so short
        a window can and cannot tell (:func:`short_window`).
    bounded : bool
        Bounded shares: f_m's support is [0, 1], and an interval reaching 0 or 1 is said
        to be at its bound (:func:`at_bound`), not well determined.

    Returns
    -------
    dict
        ``parameters`` (per coordinate: the sd ratio and a verdict), ``ridges``,
        ``motor_share``, ``short_window`` (a sentence or None) and ``summary`` /
        ``what_would_help`` sentences.
    """
    flat = theta.reshape(-1, SCALE_FREE_MATRIX.shape[1]) @ SCALE_FREE_MATRIX.T
    u = flat[:, : len(SCALE_FREE_NAMES)]
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
    for i in range(u.shape[1]):
        for j in range(i + 1, u.shape[1]):
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
    edge = at_bound(fm) if bounded else None
    fm_ok = fm_ok and edge is None
    weak = [PLAIN_NAMES[n] for n, p in params.items() if p["verdict"] == "prior-driven"]
    partly = [PLAIN_NAMES[n] for n, p in params.items() if p["verdict"] == "partly determined"]
    good = [PLAIN_NAMES[n] for n, p in params.items() if p["verdict"] == "determined by the data"]
    words = [
        f"The motor's share of the initial load is {'well' if fm_ok else 'poorly'} "
        f"determined (f_m = {np.mean(fm):.3f} +- {fm_sd:.3f})."
        if edge is None
        else f"The motor's share of the initial load is {AT_BOUND} (f_m = {np.mean(fm):.3f}, "
        f"95% interval {edge[0]:.3f} to {edge[1]:.3f})."
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
    short = None if span_s is None else short_window(span_s, theta)
    if short:
        words.append(short)
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
        "motor_share": {
            "sd": fm_sd,
            "well_determined": bool(fm_ok),
            **({} if edge is None else {"at_bound": [edge[0], edge[1]]}),
        },
        "short_window": short,
        "summary": " ".join(words),
        "what_would_help": help_,
        "thresholds": {
            "prior_driven_above": PRIOR_DRIVEN,
            "determined_below": DETERMINED,
            "ridge_correlation": RIDGE_CORR,
        },
    }


def short_window(span_s: float, theta: np.ndarray) -> str | None:
    """What a window shorter than ``MIN_SPAN_S`` can and cannot tell, or None.

    A fault recorder keeps 0.2-0.5 s around each fault. The first cycles after a voltage
    step fix the motor's share and its transient reactance X' (the current steps with
    the voltage before the flux moves); the flux decays with T', seen settling only when
    T' is well under the window; the speed (H) hardly changes in a few tenths of a second.
    """
    from loadbayes.measurements.events import MIN_SPAN_S

    if not span_s < MIN_SPAN_S:
        return None
    t_prime = float(np.exp(np.median(np.asarray(theta)[..., 3])))
    seen = (
        f"T' (median {t_prime:.3g} s) is well under it, so its decay is seen"
        if t_prime < span_s / 3
        else f"T' (median {t_prime:.3g} s) is not well under it, so T' is perhaps not determined"
    )
    return (
        f"The events are short (the longest spans {span_s:.3g} s, under {MIN_SPAN_S:g} s): "
        "such a window tells the motor's share f_m and its transient reactance X' (the "
        f"first cycles after the voltage moves); {seen}; H (the speed hardly changes in "
        f"{span_s:.2g} s) perhaps not: where the table calls them prior-driven, their "
        "values are the prior's."
    )


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


#: Per channel: the shares (impedance, current, power) and the words of the channel.
_STATIC = {"p": (("a1", "a2", "a3"), "P", "cp2"), "q": (("a4", "a5", "a6"), "Q", "cq2")}


def _interval(x: np.ndarray, prob: float) -> dict[str, float]:
    lo, hi = np.quantile(x, [(1 - prob) / 2, (1 + prob) / 2])
    return {"mean": float(x.mean()), "sd": float(x.std()), "low": float(lo), "high": float(hi)}


def static_identifiability(
    draws: dict[str, np.ndarray],
    events: Any,
    *,
    prior: CompositePrior | None = None,
    hdi_prob: float = 0.95,
    bounded: bool = False,
) -> dict[str, Any]:
    """Whether each event determined the ZIP shares of its static part, and what it did fix.

    One sag shows the static part at two voltages, its initial ``v0`` and the sag's
    lowest ``V_sag`` (and briefly in between): the shares ``a1, a2, a3`` of P (``a4, a5,
    a6`` of Q) then trade off along a line, and only combinations of them are fixed by
    the data: the slope ``2 a1 + a2`` (dP/dV of the static part at ``v0``, per unit of
    its initial P and of ``v0``; ``fit zip`` reports the same) and the static P at the
    sag's voltage, ``a1 x^2 + a2 x + a3`` with ``x = V_sag / v0`` (per unit of its
    initial P). Both are given with their central ``hdi_prob`` interval.

    Parameters
    ----------
    draws : dict of str to ndarray
        The named draws (``a1{sfx}`` ... ``a6{sfx}``, ``p0{sfx}``, ``f_m{sfx}``).
    events : sequence of EventRecord
        The events fitted (their lowest voltage).
    prior : CompositePrior, optional
        The fit's prior: a share whose sd exceeds ``PRIOR_DRIVEN`` times the prior's sd
        of that share is also "not determined".
    hdi_prob : float
        Probability of the intervals.
    bounded : bool
        Bounded shares (support [0, 1]): a share whose interval reaches 0 or 1 is said to
        be at its bound (:func:`at_bound`), and the shares are not called determined.

    Returns
    -------
    dict
        ``events`` (per event, per channel ``p``/``q``: ``determined``, the shares' mean
        and sd, their correlation and the ``combinations``), ``summary`` (words) and
        ``warning`` (a sentence, or None when every share is determined).
    """
    from loadbayes.fit.composite.naming import event_suffix

    out, words, weak, edges = [], [], [], []
    for k, ev in enumerate(events):
        sfx = event_suffix(k)
        x = float(np.min(ev.v) / ev.v0)
        row: dict[str, Any] = {"event": ev.name, "v_sag_over_v0": x}
        for ch, (names, upper, beta_name) in _STATIC.items():
            if any(f"{n}{sfx}" not in draws for n in names):
                continue
            a = [np.asarray(draws[f"{n}{sfx}"], dtype=float).ravel() for n in names]
            sds = [float(s.std()) for s in a]
            with np.errstate(invalid="ignore", divide="ignore"):
                r = float(np.corrcoef(a[0], a[1])[0, 1])
            prior_sd = None
            if prior is not None:
                from loadbayes.models.composite import BETA_NAMES

                # The share's prior sd: the coefficient's, over the static part's power.
                i = BETA_NAMES.index(beta_name)
                if ch == "p":
                    base = draws[f"p0{sfx}"] * (1 - draws[f"f_m{sfx}"])
                else:
                    base = draws[f"q0{sfx}"]
                scale = float(np.abs(np.mean(base)))
                prior_sd = float(prior.beta_sd[i]) / scale if scale > 0 else None
            undetermined = (
                (np.isfinite(r) and r < STATIC_CORR)
                or max(sds) > SHARE_SD
                or (prior_sd is not None and max(sds) > PRIOR_DRIVEN * prior_sd)
            )
            n1, n2, n3 = (f"{n}{sfx}" for n in names)
            slope = 2 * a[0] + a[1]
            level = a[0] * x * x + a[1] * x + a[2]
            combos = [
                {
                    "name": f"2 {n1} + {n2}",
                    "meaning": f"d{upper}/dV of the static {upper} at v0 (per unit of its "
                    f"initial {upper}, per unit of v0)",
                    **_interval(slope, hdi_prob),
                },
                {
                    "name": f"{n1} x^2 + {n2} x + {n3} at x = {x:.3f}",
                    "meaning": f"static {upper} at the sag's voltage {x:.3f} v0 (per unit "
                    f"of its initial {upper})",
                    **_interval(level, hdi_prob),
                },
            ]
            row[ch] = {
                "determined": not undetermined,
                "shares": {
                    f"{n}{sfx}": {"mean": float(s.mean()), "sd": sd}
                    for n, s, sd in zip(names, a, sds, strict=True)
                },
                "correlation": r if np.isfinite(r) else None,
                "prior_sd_of_share": prior_sd,
                "combinations": combos,
            }
            if bounded:
                ends = {f"{n}{sfx}": at_bound(v, hdi_prob) for n, v in zip(names, a, strict=True)}
                ends = {n: e for n, e in ends.items() if e is not None}
                if ends:
                    row[ch]["at_bound"] = {n: list(e) for n, e in ends.items()}
                    edges.append(
                        f"Event {k + 1}: "
                        + ", ".join(
                            f"{n} {float(np.mean(draws[n])):.3f} ({hdi_prob:.0%} interval "
                            f"{e[0]:.3f} to {e[1]:.3f})"
                            for n, e in ends.items()
                        )
                        + (
                            f" is {AT_BOUND}."
                            if len(ends) == 1
                            else f" are {AT_BOUND.replace('its', 'their')}."
                        )
                    )
            if undetermined:
                weak.append(f"{upper} of {ev.name or f'event {k + 1}'}")
                shares = ", ".join(
                    f"{n}{sfx} {s.mean():+.2f} +- {sd:.2f}"
                    for n, s, sd in zip(names, a, sds, strict=True)
                )
                pct = f"{hdi_prob:.0%}"
                fixed = "; ".join(
                    f"{c['name']} = {c['mean']:.3f} ({pct} interval {c['low']:.3f} to "
                    f"{c['high']:.3f}): {c['meaning']}"
                    for c in combos
                )
                words.append(
                    f"Event {k + 1}: the ZIP shares of the static {upper} are not determined "
                    f"({shares}; correlation of {n1} and {n2} {r:+.3f}). What the "
                    f"event does determine: {fixed}."
                )
        out.append(row)
    warning = None
    if weak:
        warning = (
            "the static (ZIP) part is not determined for "
            + ", ".join(weak)
            + ": one sag shows it at two voltages only, so its shares trade off along a line "
            "and the reported a1..a6 are not what the data determine (a point on that line, "
            "or the prior's); the combinations the data do fix are listed under "
            "identifiability.static_part (a deeper or second sag, or a prior on the shares, "
            "would separate them)"
        )
        summary = " ".join(words + edges)
    elif edges:
        summary = " ".join(edges)
    else:
        summary = "The ZIP shares of the static part are determined by the data."
    return {
        "events": out,
        "thresholds": {
            "correlation_below": STATIC_CORR,
            "share_sd_above": SHARE_SD,
            "share_sd_over_prior_sd_above": PRIOR_DRIVEN,
        },
        "summary": summary,
        "warning": warning,
        **({"at_bound": " ".join(edges)} if edges else {}),
    }
