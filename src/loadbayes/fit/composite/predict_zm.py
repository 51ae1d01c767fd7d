"""A ``zip+motor`` fit played through a fault it has not shown (``loadbayes predict``).

A ``zip+motor`` fit has no feeder, no motor D and no electronics: the fault's voltage at
the recorded bus drives every posterior draw's induction motor (``THETA_NAMES``, its
torque shares ``a, b, c``) and static part (``f_m``, ``a1..a6`` of event 0) directly, at
the fit's operating point (event 0's pre-fault P and Q at the recorded bus, as
``predict`` does for a fit of parts and ``validate.py`` plays a held-out event at its
own), and the fit's noise (``tau_p``, ``tau_q``) gives the band with noise. The motor is
integrated at the sample instants (``models/motor_kernel.integrate``, whose states give
its speed): a prediction is of the load's own P and Q, not of a recorder's window means.

**Stall.** A draw's motor stalls when, at the record's end, its slip is above its
pull-out slip (the slip of the largest electrical torque on its steady-state torque
curve, :func:`pull_out_slip`: a motor still past it when the record ends runs on the
falling side of its torque curve, where it has not come back), or its slip is still
rising faster than :data:`RISING_PER_S` over the last :data:`RISING_OVER_S` s (it was
still slowing down when the record ended). The
probability is the share of draws that stall, with its Jeffreys interval. The
thresholds of a fit of parts (motor D's stall voltage and time, the electronics' trip
voltages) have no place here: they are listed with ``"used": false``.

A draw whose motor's integration fails in the fault fails numerically, or has no
operating point where it fails with no fault too (``predict_outcome.py``); with no
feeder, nothing here collapses: a motor that does not come back is a stall.
"""

from __future__ import annotations

import math
from types import SimpleNamespace
from typing import Any

import numpy as np

from loadbayes.fit.composite.predict_outcome import outcome
from loadbayes.fit.composite.predict_scope import (
    MEANING,
    bands,
    extrapolation,
    jeffreys,
    q_excess,
    recovery_time,
    spread,
)
from loadbayes.models.composite import THETA_NAMES, design
from loadbayes.models.motor_kernel import integrate
from loadbayes.models.part_priors import THRESHOLD_PRIORS
from loadbayes.posterior import Posterior

__all__ = ["RISING_OVER_S", "RISING_PER_S", "STALL_RULE", "play_zip_motor", "pull_out_slip"]

#: A slip still rising at the record's end: by more than this per second ...
RISING_PER_S = 0.02
#: ... over the record's last seconds.
RISING_OVER_S = 0.1
STALL_RULE = (
    "the induction motor stalls when, at the record's end, its slip is above its pull-out "
    "slip (the slip of the largest electrical torque on its steady-state torque curve: "
    "past it the motor runs on the curve's falling side) or still rising by more than "
    f"{RISING_PER_S:g} per second over the last {RISING_OVER_S:g} s"
)
#: What stands in for ``model`` in ``predict_scope.extrapolation``: no motor D, no electronics.
_MODEL = SimpleNamespace(name="zip+motor", motor_d=False, electronics=False)


def pull_out_slip(rs: float, xp: float, dx: float, tp_s: float, f_hz: float) -> float:
    """The slip of the largest steady-state electrical torque (the breakdown slip).

    The torque at slip ``s`` is ``Re(E' conj(I))`` with ``E' = j D V / (Z (1 + j wb T' s)
    + j D)``, ``I = (V - E') / Z``, ``Z = Rs + j X'``, ``D = X - X'`` (the steady flux of
    ``models/motor_kernel.py``); it scales with ``V^2``, so its peak's slip does not
    depend on the voltage. Found on a grid and refined by a bounded scalar search.
    """
    from scipy.optimize import minimize_scalar

    wb = 2 * math.pi * f_hz
    z = complex(rs, xp)

    def te(s):
        e = 1j * dx / (z * (1.0 + 1j * wb * tp_s * s) + 1j * dx)
        return np.real(e * np.conj((1.0 - e) / z))

    grid = np.geomspace(1e-5, 1.0, 400)
    k = int(np.argmax(te(grid)))
    lo, hi = grid[max(k - 1, 0)], grid[min(k + 1, grid.size - 1)]
    return float(minimize_scalar(lambda s: -te(s), bounds=(lo, hi), method="bounded",
                                 options={"xatol": 1e-9 * hi}).x)  # fmt: skip


def _stalled(t: np.ndarray, slip: np.ndarray, s_pull_out: float) -> bool:
    if not np.all(np.isfinite(slip)) or slip[-1] > s_pull_out:
        return True
    back = int(np.searchsorted(t, t[-1] - RISING_OVER_S))
    span = t[-1] - t[back]
    return bool(span > 0 and (slip[-1] - slip[back]) / span > RISING_PER_S)


def _draws(post: Posterior) -> dict[str, np.ndarray]:
    need = [*THETA_NAMES, "f_m", "a1", "a2", "a3", "a4", "a5", "a6", "tau_p", "tau_q"]
    missing = [n for n in need if n not in post.draws]
    if missing:
        raise ValueError(f"the posterior holds no draws of {', '.join(missing)}: not a "
                         "zip+motor fit")  # fmt: skip
    return {n: np.asarray(v, dtype=float).reshape(-1) for n, v in post.draws.items()}


def _left_to_prior(post: Posterior) -> list[str]:
    """The motor's coordinates the fit called prior-driven (its identifiability report)."""
    params = post.extra_json.get("identifiability", {}).get("parameters", {})
    return [n for n, p in params.items() if isinstance(p, dict)
            and p.get("verdict") == "prior-driven"]  # fmt: skip


def _extrapolation(fault, cover, priors, left: list[str]) -> dict[str, Any]:
    """``predict_scope.extrapolation``'s words, with the motor's prior-driven parameters."""
    from loadbayes.fit.composite.identifiability import PLAIN_NAMES

    out = extrapolation(_MODEL, fault, cover, priors)
    out["left_to_prior_by_the_fit"] = left
    if out["extrapolated"] and left:
        words = ", ".join(PLAIN_NAMES.get(n, n) for n in left)
        out["message"] += (f" The fit left the motor's {words} to their priors "
                           "(models/composite_prior.py): beyond the fitted events they shape "
                           "the answer as much as the data do.")  # fmt: skip
    return out


def play_zip_motor(post, event, fault, cover, priors, p0, q0, v0, n_draws, prob, seed
                   ) -> dict[str, Any]:  # fmt: skip
    """The fields of ``predict.Prediction`` for a ``zip+motor`` fit (the module docstring).

    ``event`` is the fault's voltage (``predict_scope``), ``fault`` its description,
    ``cover`` what the fitted events covered, ``priors`` the thresholds' priors (listed,
    not used), ``p0, q0, v0`` the operating point; ``n_draws`` draws are played, picked by
    ``seed``, which also draws the noise.
    """
    d = _draws(post)
    f_hz = float(d["f_hz"][0]) if "f_hz" in d else float(post.settings.get("f_hz", 60.0))
    rng = np.random.default_rng(seed)
    total = d["f_m"].size
    pick = rng.choice(total, size=min(int(n_draws), total), replace=False)
    theta = np.stack([d[n] for n in THETA_NAMES], -1)
    abc = (np.stack([d[n] for n in ("a", "b", "c")], -1) if all(n in d for n in "abc")
           else np.tile([1.0, 0.0, 0.0], (total, 1)))  # fmt: skip
    delta = None if event.delta is None else event.delta - event.delta[0]
    vc = event.v * np.exp(1j * (0 if delta is None else delta))
    t, t_clear = event.t, fault["t_clear_s"]
    ps, qs, cur, noisy_p, noisy_q = [], [], [], [], []
    stalled, rec_p, rec_q, kept, excess, slip_end = [], [], [], [], [], []
    failed = 0
    why = np.zeros(pick.size, dtype=int)  # 0 plays, 2 fails numerically, 3 no operating point
    for j, i in enumerate(pick):
        rs, xp, dx, tp, h, t0 = np.exp(theta[i])
        kw = dict(rs=rs, xp=xp, dx=dx, tp_s=tp, h_s=h, t0=t0, f_hz=f_hz, torque=tuple(abc[i]))
        out = integrate(t, event.v, delta, **kw)
        if out is None or not (np.all(np.isfinite(out[0])) and abs(out[0][0]) > 0):
            failed += 1
            flat = integrate(t, np.full(t.size, event.v[0]), None, **kw)  # with no fault
            why[j] = 3 if flat is None or not np.all(np.isfinite(flat[0])) else 2
            continue
        pm, qm, states = out
        zp, zq = design(event, pm, qm)
        pz = p0 * (1.0 - d["f_m"][i])
        beta = np.array([pz * d["a1"][i], pz * d["a2"][i], pz * d["a3"][i], q0 * d["a4"][i],
                         q0 * d["a5"][i], q0 * d["a6"][i], d["f_m"][i] * p0])  # fmt: skip
        mp, mq = zp @ beta, zq @ beta
        ps.append(mp)
        qs.append(mq)
        cur.append(np.abs(np.conj((mp + 1j * mq) / vc)))
        noisy_p.append(mp + rng.standard_normal(event.n) / math.sqrt(d["tau_p"][i]))
        noisy_q.append(mq + rng.standard_normal(event.n) / math.sqrt(d["tau_q"][i]))
        rec_p.append(recovery_time(t, mp, t_clear))
        rec_q.append(recovery_time(t, mq, t_clear))
        slip = 1.0 - states[2]
        stalled.append(_stalled(t, slip, pull_out_slip(rs, xp, dx, tp, f_hz)))
        slip_end.append(float(slip[-1]))
        kept.append(int(i))
        excess.append(q_excess(t, mq, t_clear))
    used = len(ps)
    counts = {"plays": used, "collapses": 0, "fails_numerically": int(np.sum(why == 2)),
              "no_operating_point": int(np.sum(why == 3))}  # fmt: skip
    if counts["no_operating_point"] == pick.size:
        raise ValueError(f"no posterior draw's motor has a steady state at the operating "
                         f"point ({v0:.4g} p.u.), even with no fault: a defect of the fit, "
                         "not an answer about this fault")  # fmt: skip
    band = (bands(t, event.v, {"p": ps, "q": qs, "i": cur}, {"p": noisy_p, "q": noisy_q}, prob)
            if used else {"t_s": t, "v": event.v})  # fmt: skip
    warnings = []  # what did not play is said in ``outcome`` (predict_outcome.py)
    user = [n for n, v in priors.items() if v != THRESHOLD_PRIORS[n]]
    if user:
        warnings.append(f"--prior {', '.join(user)}: not used, a zip+motor fit has no motor D "
                        "and no electronics")  # fmt: skip
    k = int(np.sum(stalled))
    stall = {"probability": k / used if used else None,
             "interval": jeffreys(k, used, prob) if used else [0.0, 1.0], "n_stalled": k,
             "n": used, "part": "the induction motor", "rule": STALL_RULE,
             "interval_is": "Jeffreys interval of the share of draws that stall"}  # fmt: skip
    recovery = {"p": spread(np.array(rec_p), prob), "q": spread(np.array(rec_q), prob),
                "rule": "seconds after the clearing (the last sample below half the sag's "
                        "depth) from which the model's P (Q) stays within 10% of its "
                        "pre-fault value; not_within_window: share of draws still outside "
                        f"at the record's end ({fault['t_end_s']:.3g} s)"}  # fmt: skip
    thresholds = {name: {"meaning": MEANING[name], "prior": list(priors[name]), "used": False,
                         "why": "a zip+motor fit has no motor D and no electronics"}
                  for name in priors}  # fmt: skip
    return {
        "fault": fault,
        "operating_point": {
            "p0": p0,
            "q0": q0,
            "v0": v0,
            "from": "event 0's pre-fault P, Q at the recorded bus",
        },  # fmt: skip
        "draws": {
            "asked": int(n_draws),
            "played": int(pick.size),
            "used": used,
            "failed": failed,
        },  # fmt: skip
        "thresholds": thresholds,
        "stall": stall,
        "electronics_tripped": None,
        "recovery": recovery,
        "coverage": cover,
        "extrapolation": _extrapolation(fault, cover, priors, _left_to_prior(post)),
        "band": band,
        "prob": prob,
        "warnings": warnings,
        "outcome": outcome(counts, prob),
        "outcomes": {
            "index": np.array(kept, dtype=int),
            "q_excess_pu_s": np.array(excess),
            "stalled": np.array(stalled),
            "slip_end": np.array(slip_end),
            "picked": pick,
            "why": why,
        },
    }
