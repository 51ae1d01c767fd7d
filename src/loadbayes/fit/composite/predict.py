"""What a fitted load of parts does in a fault it has not shown: a planner's prediction.

:func:`predict` plays posterior draws of an ``slm`` or ``cmld-lite`` fit through a fault
given by its voltage at the recorded bus (a sag built by ``predict_scope.sag_profile``
or a recorded profile), the feeder's loop solved (``models/parts_predict.py``), at the
fit's operating point (event 0's pre-fault P and Q at the recorded bus, as
``validate`` plays a held-out event). Motor D's stall voltage and time and the
electronics' trip voltages are sampled by the fit under their priors
(``models/part_priors.THRESHOLD_PRIORS``): a fitted event that stalls or trips them
determines them, one above them only rules out what would have stalled or tripped in it,
and each played draw carries its own (``predict_scope.fitted_thresholds``; a user's
prior reweights them; a fit that did not sample them takes them from their priors). It
returns the 95 % band of P(t), Q(t) and the current (the model's, and with the fit's
noise), the probability that motor D stalls (a Jeffreys interval over the draws played),
the share of the electronics tripped, the time for P and Q to come back within 10 % of
their pre-fault values, and, in words, where the fault lies beyond what the fitted
events covered (``predict_scope.covered``) and which priors then decide. :func:`sweep`
repeats it over sag depths.

A draw that does not play through the fault is an answer too
(``predict_outcome.py``): the shares of the draws that play, that collapse (the feeder
loop has no settled solution: counted as stalled) and that fail numerically (left out),
each with its interval, and in words where no draw plays ("every draw collapses at this
depth: no band"). Only a fit none of whose draws has a steady state at the operating
point, with no fault at all, is refused: the question is wrong there, not the load.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from loadbayes.fit.composite.predict_chains import judge
from loadbayes.fit.composite.predict_outcome import KINDS, after_stall, outcome, parts_why
from loadbayes.fit.composite.predict_scope import (
    MEANING,
    bands,
    covered,
    extrapolation,
    fitted_thresholds,
    left_to_prior,
    q_excess,
    recovery_time,
    sag_extent,
    static_q_terms,
)
from loadbayes.fit.composite.predict_scope import jeffreys as _jeffreys
from loadbayes.fit.composite.predict_scope import spread as _spread
from loadbayes.fit.composite.predictive import events_of
from loadbayes.fit.composite.validate import noise_precision, operating_point
from loadbayes.measurements.record import EventRecord
from loadbayes.models.part_priors import THRESHOLD_PRIORS, draw_thresholds
from loadbayes.models.parts_play import COLLAPSES, FAILS, NO_OPERATING_POINT, PLAYS, play_draws
from loadbayes.posterior import Posterior

__all__ = ["PRIOR_SOURCE", "Prediction", "load_result", "parse_priors", "predict", "sweep"]

#: Where the thresholds' default priors come from (``part_priors.THRESHOLD_PRIORS``).
PRIOR_SOURCE = (
    "centres: the WECC composite load model specification's typical values (WECC MVWG "
    "2015: Vstall 0.6 p.u., Tstall 0.033 s, Vd1 0.7, Vd2 0.5 p.u.); spreads: loadbayes' "
    "choice, wide enough that Vstall's 95% range (0.5-0.7 p.u.) spans the tested air "
    "conditioners of PNNL-17796 (Lu, Xie and Huang 2008)"
)
_PARTS_MODELS = ("slm", "cmld-lite")


@dataclass
class Prediction:
    """One fault played through a posterior (see the module docstring); ``to_dict`` is the JSON."""

    fault: dict[str, Any]
    operating_point: dict[str, float]
    draws: dict[str, int]
    thresholds: dict[str, Any]
    stall: dict[str, Any] | None
    electronics_tripped: dict[str, Any] | None
    recovery: dict[str, Any]
    coverage: dict[str, Any]
    extrapolation: dict[str, Any]
    band: dict[str, np.ndarray]
    prob: float
    warnings: list[str] = field(default_factory=list)
    #: Where some draw did not play: each outcome's share (``predict_outcome.outcome``);
    #: None where every draw plays (the JSON then has no ``outcome``). Where none plays,
    #: ``band`` holds the fault's ``t_s`` and ``v`` alone.
    outcome: dict[str, Any] | None = None
    #: Per draw played and kept: ``index`` (of the pooled draws), the planning outcome
    #: (``predict_scope.OUTCOME``), ``stalled``, and for a fit of parts its thresholds;
    #: per draw picked: ``picked`` (its index), ``why`` (``predict_outcome``: 0 plays, 1
    #: collapses, 2 fails, 3 no operating point), for a fit of parts ``low`` (the lowest
    #: |V_L| / |V| its sweeps reached) and ``picked_thresholds``.
    outcomes: dict[str, np.ndarray] | None = field(default=None, repr=False)
    #: Where the fit's chains have not converged or disagree about this fault
    #: (``predict_chains.judge``): each chain's outcomes, the R-hat, in words (also a
    #: warning); None otherwise (the JSON then has no ``chains``).
    chains: dict[str, Any] | None = None

    def to_dict(self, *, band: bool = True) -> dict[str, Any]:
        """JSON-ready numbers (``band=False``: the summary without the time series)."""
        out = {k: getattr(self, k) for k in ("fault", "operating_point", "draws", "prob",
               "thresholds", "stall", "electronics_tripped", "recovery", "coverage",
               "extrapolation", "warnings")}  # fmt: skip
        if self.outcome is not None:
            out["outcome"] = self.outcome
        if self.chains is not None:
            out["chains"] = self.chains
        if band:
            out["band"] = {k: [round(float(x), 7) for x in v] for k, v in self.band.items()}
        return out  # fmt: skip

    def summary_lines(self) -> list[str]:
        """What ``loadbayes predict`` prints: fault, stall, trip, thresholds, recovery, words."""
        f = self.fault
        out = [
            f"fault: {f['name']}, down to {f['v_min']:.3g} p.u. ({f['depth']:.0%} below "
            f"{f['v_pre']:.3g}) for {f['duration_s']:.3g} s; {self.draws['used']} draws"
        ]
        if self.outcome is not None:
            out.append(self.outcome["message"])
        if self.stall is not None:
            lo, hi = self.stall["interval"]
            if self.stall["probability"] is not None:
                c = " (a collapse counted as a stall)" if self.stall.get("n_collapsed") else ""
                out.append(f"{self.stall.get('part', 'motor D')} stalls with probability "
                           f"{self.stall['probability']:.2f} [{lo:.2f}, {hi:.2f}]{c}")  # fmt: skip
        e = self.electronics_tripped
        if e is not None and e["median"] is not None:
            out.append(f"electronics tripped: median {e['median']:.2f} "
                       f"[{e['interval'][0]:.2f}, {e['interval'][1]:.2f}]")  # fmt: skip
        for name, th in self.thresholds.items():
            if th.get("played"):
                lo, hi = th["played"]["interval"]
                how = "fitted" if th.get("fitted") else "from its prior"
                out.append(f"{name} played: median {th['played']['median']:.3g} "
                           f"[{lo:.3g}, {hi:.3g}] ({how})")  # fmt: skip
        for ch in ("p", "q") if self.draws["used"] else ():
            r = self.recovery[ch]
            med = "never" if r["median"] is None else f"median {r['median']:.3g} s"
            out.append(f"{ch.upper()} back within 10%: {med}; not within the window in "
                       f"{r['not_within_window']:.0%} of draws")  # fmt: skip
        out.append(self.extrapolation["message"])
        return out + [f"warning: {w}" for w in self.warnings]


def load_result(result: str | Path | Posterior) -> Posterior:
    """A fit's posterior: a :class:`Posterior`, its NetCDF, or its JSON with the NetCDF beside."""
    if isinstance(result, Posterior):
        return result
    path = Path(result)
    if path.suffix.lower() == ".json":
        beside = path.with_suffix(".nc")
        if not beside.is_file():
            raise ValueError(f"{path}: the JSON holds the summary of the draws, not the "
                             "draws; give the fit's NetCDF (fit composite --netcdf)")  # fmt: skip
        path = beside
    try:
        return Posterior.from_netcdf(path)
    except Exception as exc:  # xarray/netCDF raise many types for a bad file
        raise ValueError(f"{path}: not a loadbayes NetCDF posterior ({exc})") from None


def parse_priors(specs: Sequence[str] | Mapping | None) -> dict[str, tuple[str, float, float]]:
    """The thresholds' priors: the defaults with the user's ``name=centre,spread`` over them."""
    out = dict(THRESHOLD_PRIORS)
    if specs is None:
        return out
    items = specs.items() if isinstance(specs, Mapping) else [s.split("=", 1) for s in specs]
    for item in items:
        if len(item) != 2:
            raise ValueError(f"--prior {item[0]!r}: give name=centre,spread (vstall=0.55,0.05)")
        name, value = item
        name = name.strip().lower()
        if name not in THRESHOLD_PRIORS:
            raise ValueError(f"--prior {name!r}: one of {', '.join(THRESHOLD_PRIORS)}")
        try:
            centre, spread = (float(x) for x in (value.split(",") if isinstance(value, str)
                                                 else value))  # fmt: skip
        except (TypeError, ValueError):
            raise ValueError(f"--prior {name}={value}: give centre,spread (two numbers)") from None
        if not (math.isfinite(centre) and math.isfinite(spread) and centre > 0 and spread >= 0):
            raise ValueError(f"--prior {name}={value}: a positive centre and a spread >= 0")
        out[name] = (THRESHOLD_PRIORS[name][0], centre, spread)
    return out


def _model_of(post: Posterior):
    """The fit's model of parts rebuilt; None for a ``zip+motor`` fit (``predict_zm.py``)."""
    from loadbayes.export.partsload import rebuild_model

    name = post.settings.get("model")
    if name in (None, "zip+motor"):
        return None
    if name not in _PARTS_MODELS:
        raise ValueError(f"a {name} fit: predict plays zip+motor, "
                         f"{', '.join(_PARTS_MODELS)} fits")  # fmt: skip
    return rebuild_model(post.settings)


def predict(
    result: str | Path | Posterior,
    *,
    sag: float | None = None,
    duration: float | None = None,
    recovery: float = 0.0,
    angle: float = 0.0,
    voltage: str | Path | EventRecord | None = None,
    draws: int = 300,
    prior: Sequence[str] | Mapping | None = None,
    prob: float = 0.95,
    seed: int = 0,
    rate_hz: float = 240.0,
) -> Prediction:
    """Play a fault through a fit of parts' posterior (see the module docstring).

    Parameters
    ----------
    result : path or Posterior
        The fit's NetCDF (or its JSON with the NetCDF of the same name beside it).
    sag, duration, recovery, angle : float
        The fault as a sag: depth (share of the pre-fault voltage), seconds at the bottom,
        seconds of a linear recovery, the phase jump in degrees. Or ``voltage``:
    voltage : path or EventRecord
        A recorded profile (CSV of ``t_s, v``, optionally ``angle_rad`` and ``v2_re,
        v2_im``: the negative sequence, which brakes the motors of a model of parts).
    draws : int
        Posterior draws played (each with its own thresholds).
    prior : sequence of ``"name=centre,spread"`` or mapping, optional
        Priors of ``vstall, tstall, vd1, vd2`` over the defaults (:data:`PRIOR_SOURCE`).
    """
    from loadbayes.fit.composite.predict_scope import read_profile, sag_profile

    post = load_result(result)
    model = _model_of(post)
    if (voltage is None) == (sag is None):
        raise ValueError("give the fault as --sag DEPTH --duration S, or as --voltage PROFILE.csv "
                         "(one of them)")  # fmt: skip
    if not 20 <= int(draws) <= 20000:
        raise ValueError(f"--draws {draws}: 20 to 20000")
    priors = parse_priors(prior)
    events = events_of(post)
    if not events:
        raise ValueError("the result keeps no recordings of its events (written before they "
                         "were kept): its operating point and what it covered are unknown; "
                         "fit again")  # fmt: skip
    p0, q0 = operating_point(events[0])
    v0 = float(events[0].v0)
    if voltage is not None:
        event = voltage if isinstance(voltage, EventRecord) else read_profile(voltage)
        kind = "profile"
    else:
        if duration is None:
            raise ValueError("--sag needs --duration S (the seconds the fault lasts)")
        event = sag_profile(sag, duration, recovery=recovery, angle_deg=angle, v0=v0,
                            rate_hz=rate_hz)  # fmt: skip
        kind = "sag"
    ext = sag_extent(event.t, event.v)
    fault = {"kind": kind, "name": event.name, "n": event.n, "t_end_s": float(event.t[-1]),
             **ext} | ({"sag": sag, "duration": duration, "recovery": recovery,
                        "angle_deg": angle} if kind == "sag" else {})  # fmt: skip
    if event.v2 is not None:  # the motors of a model of parts brake with it (parts_play)
        fault["v2_max"] = float(np.max(np.abs(event.v2)))
    cover = covered(events)
    if model is None:  # a zip+motor fit: no feeder, no motor D, no thresholds
        from loadbayes.fit.composite.predict_zm import play_zip_motor

        return Prediction(**play_zip_motor(post, event, fault, cover, priors, p0, q0, v0,
                                           draws, prob, seed))  # fmt: skip
    return _play(post, model, event, fault, cover, priors, p0, q0, v0, draws, prob, seed)


def _play(post, model, event, fault, cover, priors, p0, q0, v0, n_draws, prob, seed):
    d = {n: np.asarray(v, dtype=float).reshape(-1) for n, v in post.draws.items()}
    missing = [n for n in (*model.theta_names, "cq2", "cq1", "cq0", "tau_p", "tau_q")
               if n not in d]  # fmt: skip
    if missing:
        raise ValueError(f"the posterior holds no draws of {', '.join(missing)}: not a "
                         f"{model.name} fit")  # fmt: skip
    rng = np.random.default_rng(seed)
    total = d["tau_p"].size
    pick = rng.choice(total, size=min(int(n_draws), total), replace=False)
    th = draw_thresholds(rng, pick.size, priors)
    th["vd1"] = np.clip(th["vd1"], 0.06, 1.2)
    th["vd2"] = np.clip(th["vd2"], 0.0, th["vd1"] - 0.05)
    th["tstall"] = np.maximum(th["tstall"], 0.0)
    pick, th, notes = fitted_thresholds(model, d, pick, th, priors, left_to_prior(model, d),
                                        rng)  # fmt: skip
    theta = np.stack([d[n] for n in model.theta_names], -1)
    cq, _ = static_q_terms(d, cover)  # the deepest fitted event's: the least extrapolated
    v = event.v * np.exp(1j * (0 if event.delta is None else event.delta - event.delta[0]))
    t = event.t
    ps, qs, cur, noisy_p, noisy_q = [], [], [], [], []
    stalled, tripped, rec_p, rec_q = [], [], [], []
    kept, excess = [], []
    failed = 0
    # Every draw's feeder loop solved in compiled calls, in threads (models/parts_play.py;
    # models/parts_predict.predict_parts is the same arithmetic, one draw in NumPy).
    shares = np.array([cq[i] / cq[i].sum() if abs(cq[i].sum()) > 1e-9 else [0.0, 0.0, 1.0]
                       for i in pick])  # fmt: skip
    played = play_draws(model, event, theta[pick], p0, q0, shares, th)
    why = parts_why(model, event, theta[pick], p0, q0, shares, th, played)
    for j, i in enumerate(pick):
        if not played.ok[j]:
            failed += 1
            continue
        mp, mq = played.p[j], played.q[j]
        ps.append(mp)
        qs.append(mq)
        cur.append(np.abs(np.conj((mp + 1j * mq) / v)))
        sp, sq = (1 / math.sqrt(noise_precision(d, ch, i)) for ch in ("p", "q"))
        noisy_p.append(mp + sp * rng.standard_normal(event.n))
        noisy_q.append(mq + sq * rng.standard_normal(event.n))
        rec_p.append(recovery_time(t, mp, fault["t_clear_s"]))
        rec_q.append(recovery_time(t, mq, fault["t_clear_s"]))
        kept.append(j)
        excess.append(q_excess(t, mq, fault["t_clear_s"]))
        # Read off the load bus's voltage the parts saw (the recorded one less the drop).
        if model.motor_d:
            stalled.append(bool(played.stalled[j]))
        if model.electronics:
            tripped.append(float(played.tripped[j]))
    used = len(ps)
    codes = (PLAYS, COLLAPSES, FAILS, NO_OPERATING_POINT)
    counts = {k: int(np.sum(why == c)) for k, c in zip(KINDS, codes, strict=True)}
    if counts["no_operating_point"] == pick.size:
        raise ValueError(f"no posterior draw has a steady state at the operating point "
                         f"(P {p0:.4g}, Q {q0:.4g} at {v0:.4g} p.u.), even with no fault: "
                         "a defect of the fit, not an answer about this fault")  # fmt: skip
    out = outcome(counts, prob)
    lo, hi = 50 * (1 - prob), 50 * (1 + prob)
    band = (bands(t, event.v, {"p": ps, "q": qs, "i": cur}, {"p": noisy_p, "q": noisy_q}, prob)
            if used else {"t_s": t, "v": event.v})  # fmt: skip
    warnings = list(notes)  # what did not play is said in ``outcome`` (its message)
    chains = judge(post, model, pick, why, played.ok & played.stalled, prob)  # chains agree?
    if chains is not None:
        warnings.append(chains["message"])
    stall = None
    if model.motor_d:  # a collapse is a stall for good; a numerical failure is left out
        n_c = counts["collapses"]
        k, n = int(np.sum(stalled)) + n_c, used + n_c
        stall = {"probability": k / n if n else None,
                 "interval": _jeffreys(k, n, prob) if n else [0.0, 1.0],
                 "n_stalled": k, "n": n,
                 "interval_is": "Jeffreys interval of the share of draws that stall"}  # fmt: skip
        if n_c:
            stall["n_collapsed"] = n_c
            stall["collapse"] = "counted as stalled: the load does not come back"
    el = None
    if model.electronics:
        x = np.array(tripped)
        el = ({"median": float(np.median(x)),
               "interval": [float(v) for v in np.percentile(x, [lo, hi])]} if used
              else {"median": None, "interval": None, "note": "no draw plays"})  # fmt: skip
    recovery = {"p": _spread(np.array(rec_p), prob), "q": _spread(np.array(rec_q), prob),
                "rule": "seconds after the clearing (the last sample below half the sag's "
                        "depth) from which the model's P (Q) stays within 10% of its "
                        "pre-fault value; not_within_window: share of draws still outside "
                        f"at the record's end ({fault['t_end_s']:.3g} s)"}  # fmt: skip
    if not used:
        recovery["note"] = "no draw plays: nothing recovers"
    thresholds = {}
    for name, (kind, c, s) in priors.items():
        user = (kind, c, s) != THRESHOLD_PRIORS[name]
        thresholds[name] = {"meaning": MEANING[name], "prior": [kind, c, s],
                            "source": "given by the user (--prior)" if user else PRIOR_SOURCE,
                            "used": name in ("vstall", "tstall") and model.motor_d
                            or name in ("vd1", "vd2") and model.electronics,
                            "fitted": name in getattr(model, "thresholds", ())}  # fmt: skip
        if thresholds[name]["used"]:
            x = np.asarray(th[name], dtype=float)
            thresholds[name]["played"] = {
                "median": float(np.median(x)),
                "interval": [float(v) for v in np.percentile(x, [lo, hi])]}  # fmt: skip
    return Prediction(
        fault=fault,
        operating_point={"p0": p0, "q0": q0, "v0": v0,
                         "from": "event 0's pre-fault P, Q at the recorded bus"},  # fmt: skip
        draws={"asked": int(n_draws), "played": int(pick.size), "used": used, "failed": failed},
        thresholds=thresholds, stall=stall, electronics_tripped=el, recovery=recovery,
        coverage=cover, band=band,
        extrapolation=after_stall(extrapolation(model, fault, cover, priors,
                                                left_to_prior(model, post.draws)), model, stall),
        prob=prob, warnings=warnings, outcome=out,
        outcomes={"index": pick[kept], "q_excess_pu_s": np.array(excess),
                  "stalled": np.array(stalled if model.motor_d else [False] * used),
                  **{k: np.asarray(v)[kept] for k, v in th.items()},
                  "picked": pick, "why": why, "low": played.low,
                  "picked_thresholds": th},
        chains=chains,
    )  # fmt: skip


def sweep(result, depths: Sequence[float], *, duration: float, **kw) -> list[Prediction]:
    """:func:`predict` at each sag depth (the same draws' seed each time)."""
    post = load_result(result)
    return [predict(post, sag=float(x), duration=duration, **kw) for x in depths]
