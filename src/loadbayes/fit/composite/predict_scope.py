"""The fault a prediction plays, and what the fitted events covered of such faults.

:func:`sag_profile` builds a voltage sag at the recorded bus (depth, duration, a linear
recovery, a phase jump); :func:`read_profile` reads one from a CSV (``t_s, v`` and
optionally ``angle_rad`` and the negative sequence ``v2_re, v2_im``, which brakes the
motors of a model of parts, ``models/motor_kernel.brake_torque``). :func:`sag_extent`
measures any voltage the same way, fitted or asked: its depth below the pre-fault
voltage (the first sample) and its duration, the time the voltage stays below half that
depth (a rectangular sag's own duration; a sag with a ramp's duration to the ramp's
middle). :func:`covered` is the range the
fitted events span (read from the recordings a fit keeps, ``predictive.events_of``), and
:func:`recovery_time` the time after the fault's clearing (the last sample below half
the depth) from which P or Q stays within 10 % of its pre-fault value.
:func:`fitted_thresholds` gives each played draw its thresholds (motor D's stall, the
electronics' trip): the posterior's where the fit sampled them, reweighted for a prior
the user gives. :func:`q_excess`
is the planning outcome (``export --planning`` orders the draws by it); :func:`jeffreys`
and :func:`spread` summarise the draws' answers.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from loadbayes.fit.composite.describe_parts import prior_driven
from loadbayes.io.errors import DataError
from loadbayes.measurements.record import EventRecord
from loadbayes.models.part_priors import THRESHOLD_PRIORS, VD_GAP

__all__ = [
    "MEANING",
    "MIN_ESS",
    "bands",
    "OUTCOME",
    "OUTCOME_RULE",
    "covered",
    "extrapolation",
    "fitted_thresholds",
    "jeffreys",
    "left_to_prior",
    "q_excess",
    "read_profile",
    "recovery_time",
    "sag_extent",
    "sag_profile",
    "spread",
    "static_q_terms",
]

#: What each threshold is (the thresholds of ``part_priors.THRESHOLD_PRIORS``).
MEANING = {"vstall": "motor D's stall voltage (p.u.)", "tstall": "motor D's stall time (s)",
           "vd1": "the electronics' voltage where tripping starts (p.u.)",
           "vd2": "the electronics' voltage where all have tripped (p.u.)"}  # fmt: skip

#: The planning outcome of each draw played (``Prediction.outcomes``): how hard the load
#: pulls on the voltage after the fault, the quantity a planner's ensemble must span.
OUTCOME = "q_excess_pu_s"
OUTCOME_RULE = (
    "the load's reactive energy above its pre-fault Q from the fault's clearing to the "
    "record's end: the integral of max(Q(t) - Q(0), 0) dt, system p.u. times s. A motor "
    "that reaccelerates slowly draws it for longer and one that stalls draws its locked "
    "rotor's Q to the end, so it orders the draws by stall severity (fault-induced "
    "delayed voltage recovery)"
)

#: Seconds of steady voltage before a built sag, and after its recovery.
PRE_S, POST_S = 0.2, 1.5


def sag_profile(depth: float, duration: float, *, recovery: float = 0.0,
                angle_deg: float = 0.0, v0: float = 1.0, rate_hz: float = 240.0,
                post_s: float = POST_S) -> EventRecord:  # fmt: skip
    """A sag of ``depth`` (share of ``v0``) for ``duration`` s, then a linear recovery.

    The voltage steps down at ``PRE_S`` and holds ``v0 (1 - depth)`` for ``duration``;
    it returns to ``v0`` linearly over ``recovery`` s (a step when 0) and the record
    runs ``post_s`` s more. The angle jumps by ``angle_deg`` with the fault and returns
    with the voltage. P and Q are zeros (a prediction does not read them).
    """
    if not (math.isfinite(depth) and 0 < depth < 1):
        raise ValueError(f"--sag {depth!r}: a depth between 0 and 1 (0.45 for a 45% sag)")
    if not (math.isfinite(duration) and 0 < duration <= 10):
        raise ValueError(f"--duration {duration!r}: seconds, above 0 and at most 10")
    if not (math.isfinite(recovery) and 0 <= recovery <= 30):
        raise ValueError(f"--recovery {recovery!r}: seconds, 0 to 30")
    if not (math.isfinite(angle_deg) and abs(angle_deg) <= 90):
        raise ValueError(f"--angle {angle_deg!r}: degrees, -90 to 90")
    dt = 1.0 / rate_hz
    end = PRE_S + duration + recovery + post_s
    t = np.arange(0.0, end + dt / 2, dt)
    t_f, t_c = PRE_S, PRE_S + duration
    share = np.where((t >= t_f) & (t < t_c), 1.0, 0.0)
    if recovery > 0:
        ramp = (t >= t_c) & (t < t_c + recovery)
        share[ramp] = 1.0 - (t[ramp] - t_c) / recovery
    v = v0 * (1.0 - depth * share)
    delta = math.radians(angle_deg) * share
    zeros = np.zeros(t.size)
    return EventRecord(t, v, zeros, zeros, delta, f"sag {depth:g} for {duration:g} s")


def read_profile(path: str | Path) -> EventRecord:
    """A voltage profile from a CSV: ``t_s``, ``v`` (p.u.), optionally ``angle_rad``.

    And optionally ``v2_re, v2_im`` (both or neither): the negative-sequence voltage per
    unit as ``v`` (docs/formats.md), the event's ``v2`` (its ``i2`` None).
    """
    name = str(path)
    try:
        frame = pd.read_csv(path)
    except (OSError, UnicodeDecodeError, pd.errors.ParserError, pd.errors.EmptyDataError) as exc:
        raise DataError(f"not a CSV of t_s, v ({str(exc).splitlines()[0]})", name) from None
    cols = {}
    v2_cols = [c for c in ("v2_re", "v2_im") if c in frame.columns]
    if len(v2_cols) == 1:
        other = ({"v2_re", "v2_im"} - set(v2_cols)).pop()
        raise DataError(f"{v2_cols[0]!r} without {other!r} (the negative sequence needs "
                        "both)", name)  # fmt: skip
    for col in ("t_s", "v", "angle_rad", *v2_cols):
        if col not in frame.columns:
            if col == "angle_rad":
                continue
            raise DataError(f"no column {col!r} (a profile holds t_s, v and optionally "
                            "angle_rad, v2_re, v2_im)", name)  # fmt: skip
        x = pd.to_numeric(frame[col], errors="coerce").to_numpy(dtype=float)
        bad = np.flatnonzero(~np.isfinite(x))
        if bad.size:
            raise DataError(f"not a finite number ({frame[col].iloc[bad[0]]!r})", name, col,
                            int(bad[0]) + 2)  # fmt: skip
        cols[col] = x
    t, v = cols["t_s"], cols["v"]
    if t.size < 10:
        raise DataError(f"{t.size} rows: a profile needs at least 10", name)
    back = np.flatnonzero(np.diff(t) <= 0)
    if back.size:
        raise DataError("time does not increase", name, "t_s", int(back[0]) + 3)
    low = np.flatnonzero((v <= 0.0) | (v > 2.0))
    if low.size:
        raise DataError(f"{v[low[0]]:g} p.u.: a voltage per unit in (0, 2]", name, "v",
                        int(low[0]) + 2)  # fmt: skip
    zeros = np.zeros(t.size)
    v2 = cols["v2_re"] + 1j * cols["v2_im"] if v2_cols else None
    return EventRecord(t - t[0], v, zeros, zeros, cols.get("angle_rad"), Path(name).name, v2=v2)


def sag_extent(t: np.ndarray, v: np.ndarray) -> dict[str, float]:
    """Depth (share of the first sample's voltage), lowest V, duration and clearing time."""
    v_pre = float(v[0])
    v_min = float(np.min(v))
    depth = 1.0 - v_min / v_pre
    below = v < v_pre - 0.5 * (v_pre - v_min)
    if depth < 1e-3 or not below.any():
        return {"v_pre": v_pre, "v_min": v_min, "depth": max(depth, 0.0), "duration_s": 0.0,
                "t_clear_s": float(t[0])}  # fmt: skip
    dt = np.diff(t, append=t[-1] + (t[-1] - t[-2]))
    last = int(np.flatnonzero(below)[-1])
    return {"v_pre": v_pre, "v_min": v_min, "depth": depth,
            "duration_s": float(np.sum(dt[below])),
            "t_clear_s": float(t[min(last + 1, t.size - 1)])}  # fmt: skip


def covered(events: Sequence[EventRecord]) -> dict:
    """The voltages and durations the fitted events span (for extrapolation's words)."""
    each = []
    for ev in events:
        ext = sag_extent(ev.t, ev.v)
        each.append({"event": ev.name, "v_min": ext["v_min"], "depth": ext["depth"],
                     "duration_s": ext["duration_s"]})  # fmt: skip
    if not each:
        return {"events": [], "v_min": None, "depth_max": None, "duration_max_s": None}
    return {
        "events": each,
        "v_min": min(e["v_min"] for e in each),
        "depth_max": max(e["depth"] for e in each),
        "duration_max_s": max(e["duration_s"] for e in each),
    }


def static_q_terms(draws: Mapping[str, np.ndarray], cover: dict) -> tuple[np.ndarray, str]:
    """The static Q's terms ``(cq2, cq1, cq0)`` per draw, of the fitted event that went lowest.

    A fit estimates them for each event (``cq2`` for event 0, ``cq2_e1``... for the
    others); over a shallow event their split among x^2, x and 1 is barely determined,
    and played through a deeper fault it extrapolates (measured: a 15 % sag's terms gave
    Q -0.48 p.u. at a 38 % sag where the load drew +0.31, which lifted the load bus above
    the recorded one and hid motor D's stall). The event that reached the lowest voltage
    spans the widest range of it. Returns ``(terms (n, 3), its event's name)``.
    """
    each = cover.get("events") or []
    k = int(np.argmin([e["v_min"] for e in each])) if each else 0
    sfx = f"_e{k}" if k else ""
    if f"cq2{sfx}" not in draws:  # a posterior thinned to event 0's names
        sfx, k = "", 0
    terms = np.stack([np.asarray(draws[n + sfx], dtype=float).reshape(-1)
                      for n in ("cq2", "cq1", "cq0")], -1)  # fmt: skip
    return terms, (each[k]["event"] if each else "event 0")


def recovery_time(t: np.ndarray, x: np.ndarray, t_clear: float, share: float = 0.1) -> float:
    """Seconds after ``t_clear`` from which ``x`` stays within ``share`` of ``x[0]``.

    NaN when the last sample is still outside (not recovered within the window).
    """
    tol = share * abs(float(x[0]))
    out = np.abs(x - x[0]) > tol
    after = t >= t_clear
    bad = np.flatnonzero(out & after)
    if bad.size == 0:
        return 0.0
    if bad[-1] == t.size - 1:
        return math.nan
    return float(t[bad[-1] + 1] - t_clear)


def left_to_prior(model, draws: Mapping[str, np.ndarray]) -> list[str]:
    """The motor and feeder parameters the fit left to their priors (``describe_parts``)."""
    return [name for name, _ in prior_driven(model, draws)]


def extrapolation(model, fault: dict, cover: dict, priors: Mapping,
                  left: Sequence[str] = ()) -> dict[str, Any]:  # fmt: skip
    """Where the fault lies beyond the fitted events, and which priors then decide."""
    why: list[str] = []
    if cover["v_min"] is None:
        why.append("the result keeps no recordings of its events: what they covered is unknown")
    else:
        if fault["depth"] > cover["depth_max"] + 0.02:
            why.append(f"the sag reaches {fault['v_min']:.3g} p.u. ({fault['depth']:.0%}), "
                       f"deeper than any fitted event (the deepest {cover['depth_max']:.0%}, "
                       f"down to {cover['v_min']:.3g} p.u.)")  # fmt: skip
        if fault["duration_s"] > 1.25 * cover["duration_max_s"] + 0.02:
            why.append(f"it lasts {fault['duration_s']:.3g} s, longer than any fitted event "
                       f"({cover['duration_max_s']:.3g} s at most)")  # fmt: skip
    decide = []
    v_seen = cover["v_min"] if cover["v_min"] is not None else 1.0
    fitted = set(getattr(model, "thresholds", ()))
    reached = []  # the thresholds this fault's voltage comes near
    if model.motor_d:
        kind, c, s = priors["vstall"]
        if fault["v_min"] < c + 2 * s + 0.05:
            reached += ["vstall", "tstall"]
    if model.electronics:
        kind, c, s = priors["vd1"]
        if fault["v_min"] < c + 2 * s + 0.05:
            reached += ["vd1", "vd2"]
    # A sampled threshold the fitted events determined (a stall or a trip in them) is
    # the data's; one whose posterior keeps its prior's spread is still the prior's.
    decide = [d for d in reached if d not in fitted or d in left]
    motor_left = [n for n in left if n not in MEANING]
    words = []
    if why:
        words.append("Extrapolation: " + "; ".join(why) + ".")
        if motor_left:
            words.append(
                "The fit left " + ", ".join(motor_left) + " to their priors "
                "(models/part_priors.py: the WECC composite load model's typical data and "
                "PNNL's LMDT records): beyond the fitted events they shape the answer as "
                "much as the data do."
            )
    if decide:
        seen = (f"no fitted event went below {v_seen:.3g} p.u." if v_seen > 0.7 else
                f"the fitted events went down to {v_seen:.3g} p.u.")  # fmt: skip
        how = ("the fit does not estimate them" if not fitted & set(decide) else
               "the fitted events did not determine them (their posteriors keep the "
               "priors' spread, less what the events rule out)")  # fmt: skip
        words.append(
            f"The answer is decided by the priors of {', '.join(decide)} ("
            + "; ".join(MEANING[d] for d in decide)
            + f"): {how} and {seen}; each draw carries its own, from that prior "
            "(see thresholds, with the source)."
        )
    learned = [d for d in reached if d not in decide]
    if learned:
        words.append("The fitted events narrowed " + ", ".join(learned) + " ("
                     + "; ".join(MEANING[d] for d in learned) + "): each draw carries "
                     "the posterior's value.")  # fmt: skip
    absent = [w for w, on in (("motor D (air conditioners that stall)", model.motor_d),
                              ("electronics that trip", model.electronics)) if not on]  # fmt: skip
    if why and absent and fault["v_min"] < 0.8:
        words.append(f"The {model.name} model has no {' and no '.join(absent)}: what they "
                     "would do in this fault cannot appear in the answer (fit cmld-lite for "
                     "them).")  # fmt: skip
    return {"extrapolated": bool(why), "why": why, "decided_by_prior": decide,
            "determined_by_the_fit": learned,
            "left_to_prior_by_the_fit": list(left),
            "message": " ".join(words) or "Within what the fitted events covered."}  # fmt: skip


#: Effective draws below which a user's prior over a sampled threshold does not reweight
#: the posterior (importance resampling) but replaces it (see :func:`fitted_thresholds`).
MIN_ESS = 50.0


def _log_prior(x: np.ndarray, prior) -> np.ndarray:
    kind, centre, spread = prior
    if kind == "lognormal":
        return -0.5 * ((np.log(x) - math.log(centre)) / spread) ** 2 - np.log(x)
    return -0.5 * ((x - centre) / spread) ** 2


def fitted_thresholds(model, d, pick, th, priors, left, rng):
    """Each played draw's thresholds: the posterior's, where the fit sampled them.

    ``th`` holds prior draws (an older fit, or ``fit_thresholds`` off, samples none); a
    threshold the fit sampled is replaced by the picked draws' own. A user's prior
    (``--prior``) over a sampled threshold reweights the posterior's draws by the ratio
    of the two priors (importance resampling, with replacement). Where that leaves fewer
    than :data:`MIN_ESS` effective draws: a threshold the fit left to its prior is drawn
    from the user's prior instead (what the fitted events rule out is then not applied:
    said), and one the fitted events determined is refused (the prior and the data
    disagree). Returns ``(pick, th, notes)``.
    """
    fitted = [n for n in getattr(model, "thresholds", ()) if n in d]
    if not fitted:
        return pick, th, []
    notes = []
    own = {n: (THRESHOLD_PRIORS[n][0], *model.priors.get(n, THRESHOLD_PRIORS[n][1:]))
           for n in fitted}  # fmt: skip
    changed = [n for n in fitted if tuple(priors[n]) != tuple(own[n])]
    replaced: list[str] = []
    if changed:
        ess = 0.0
        if all(priors[n][2] > 0 for n in changed):
            logw = sum(_log_prior(d[n], priors[n]) - _log_prior(d[n], own[n]) for n in changed)
            w = np.exp(logw - np.max(logw))
            w /= w.sum()
            ess = float(1.0 / np.sum(w * w))
        names = ", ".join(changed)
        if ess >= MIN_ESS:
            pick = rng.choice(w.size, size=pick.size, replace=True, p=w)
            notes.append(f"the prior given for {names} reweights the posterior's draws "
                         f"(importance resampling: {ess:.0f} effective draws)")  # fmt: skip
        else:
            hard = [n for n in changed if n not in left]
            if hard:
                x = d[hard[0]]
                raise ValueError(
                    f"--prior {hard[0]}: the fitted events determine it (95% of the posterior "
                    f"in [{np.percentile(x, 2.5):.3g}, {np.percentile(x, 97.5):.3g}]) and the "
                    f"prior given puts almost no mass there ({ess:.1f} effective draws): the "
                    "prior and the data disagree"
                )
            replaced = changed
            notes.append(f"the prior given for {names} lies where the posterior has few draws "
                         f"({ess:.1f} effective); the fitted events left {names} to the "
                         "prior, so each draw takes them from the prior given (what the "
                         "fitted events rule out is not applied)")  # fmt: skip
    for n in fitted:
        if n not in replaced:
            th[n] = np.asarray(d[n], dtype=float)[pick]
    if "vd1" in th and "vd2" in th:
        th["vd2"] = np.minimum(th["vd2"], th["vd1"] - VD_GAP)
    return pick, th, notes


def q_excess(t: np.ndarray, q: np.ndarray, t_clear: float) -> float:
    """:data:`OUTCOME`: the integral of ``max(Q - Q(0), 0)`` from ``t_clear`` to the end."""
    from scipy.integrate import trapezoid

    after = t >= t_clear
    if after.sum() < 2:
        return 0.0
    return float(trapezoid(np.maximum(q[after] - q[0], 0.0), t[after]))


def jeffreys(k: int, n: int, prob: float) -> list[float]:
    """The Jeffreys interval (``prob``) of a share ``k / n`` (0 and 1 at the ends).

    ``betaincinv`` is the function ``scipy.stats.beta.ppf`` calls (equal on 40,000
    arguments, checked); importing ``scipy.stats`` cost a ``predict`` about 0.6 s.
    """
    from scipy.special import betaincinv

    a = (1 - prob) / 2
    lo = 0.0 if k == 0 else float(betaincinv(k + 0.5, n - k + 0.5, a))
    hi = 1.0 if k == n else float(betaincinv(k + 0.5, n - k + 0.5, 1 - a))
    return [lo, hi]


def spread(x: np.ndarray, prob: float) -> dict[str, Any]:
    """Median and central ``prob`` interval of the finite ``x``; the share not finite."""
    lo, hi = 50 * (1 - prob), 50 * (1 + prob)
    done = x[np.isfinite(x)]
    out: dict[str, Any] = {"not_within_window": float(np.mean(~np.isfinite(x))) if x.size else 0.0}
    if done.size:
        out |= {"median": float(np.median(done)),
                "interval": [float(v) for v in np.percentile(done, [lo, hi])]}  # fmt: skip
    else:
        out |= {"median": None, "interval": None}
    return out


def bands(t: np.ndarray, v: np.ndarray, model: Mapping[str, list], noisy: Mapping[str, list],
          prob: float) -> dict[str, np.ndarray]:  # fmt: skip
    """A prediction's bands, from the draws played and the same with the fit's noise.

    Each channel of ``model`` gets ``lo, mid, hi``; each of ``noisy`` ``pred_lo, pred_hi``.
    """
    lo, hi = 50 * (1 - prob), 50 * (1 + prob)
    band: dict[str, np.ndarray] = {"t_s": t, "v": v}
    for ch, arr in model.items():
        band[f"{ch}_lo"], band[f"{ch}_mid"], band[f"{ch}_hi"] = np.percentile(
            np.array(arr), [lo, 50, hi], axis=0)  # fmt: skip
    for ch, arr in noisy.items():
        band[f"{ch}_pred_lo"], band[f"{ch}_pred_hi"] = np.percentile(np.array(arr), [lo, hi],
                                                                     axis=0)  # fmt: skip
    return band
