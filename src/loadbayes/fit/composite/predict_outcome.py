"""What became of each draw a prediction played: it plays through, collapses, or fails.

A planner asks what a load does at a depth it has never shown; a load that does not come
back there is an answer, not an error. Each draw played through a fault
(``predict.py``, ``predict_zm.py``) ends one of four ways:

- **plays**: the fault is played to the record's end (a model of parts: its feeder loop
  converged, ``models/parts_play.PLAYS``); its P, Q and current enter the bands, its
  stall (motor D's, or the induction motor's by its torque curve) the stall probability;
- **collapses**: a model of parts whose feeder loop does not settle in the fault (plain
  sweeps, then damped at 0.5 for up to 200, then each sample's load bus solved on its
  P-V curve, plain and damped; or they leave the finite numbers) after a sweep drove its
  load bus below ``parts_play.COLLAPSE_RATIO`` (0.2) of the recorded bus's voltage, or
  with some sample's P-V equation left without a root (``parts_loop.pv_root``: the
  load's nose below the feeder's), while the same draw settles with no fault: what the
  load draws through the feeder has no voltage to settle at, the model's voltage collapse
  (``parts_play.COLLAPSES``). Measured on the tests' stalling load at a 44 % sag (a
  draw traced), the load bus ran away at the sag's bottom (to 0.07 p.u. under a
  recorded 0.56) under damping 0.5, 0.25 and 0.1 alike, the record's end settled with
  motor D stalled;
  with the cmld-lite fit of ``tests/feeder_generator.py``'s 15 % sag at a 50 % sag, the
  draws given six times the feeder all collapse and the others all play. A collapse
  counts as a stall in the stall probability (the load does not come back);
- **fails numerically**: a loop that does not settle (or leaves the finite numbers) with
  its load bus held above that share (``parts_play.FAILS``: sweeps bouncing between two
  trajectories, say), or a ``zip+motor`` motor's integration that fails, though the draw
  has an operating point. Not a collapse: it says nothing about the load, and is left
  out of every share but its own;
- **no operating point**: a motor of the draw has no steady state at the fit's operating
  point with no fault at all (found by playing the same draw through a fault-free
  record, :func:`fault_free`): a defect of the draw, not an answer about the fault. When
  no draw has one the question itself is wrong and ``predict`` refuses it.

:func:`outcome` counts them with Jeffreys intervals and says them in words; it is in the
JSON only where some draw did not play (where every draw plays the JSON is as it was).
"""

from __future__ import annotations

from dataclasses import replace
from typing import Any

import numpy as np

from loadbayes.fit.composite.predict_scope import jeffreys
from loadbayes.measurements.record import EventRecord
from loadbayes.models.parts_play import NO_OPERATING_POINT, PLAYS, play_draws

__all__ = ["KINDS", "after_stall", "fault_free", "no_band", "outcome", "parts_why"]

#: The outcomes in ``outcome``'s order: the JSON's keys and their words.
KINDS = {
    "plays": "play through",
    "collapses": "collapse (the feeder loop has no voltage to settle at: the load does "
                  "not come back)",
    "fails_numerically": "fail numerically (not a collapse: left out)",
    "no_operating_point": "have no steady state at the operating point (a defect of the "
                          "draw, left out)",
}  # fmt: skip


def fault_free(event: EventRecord) -> EventRecord:
    """The fault's record with its first sample's voltage throughout: no sag, no jump, no V2."""
    flat = np.full(event.n, float(event.v[0]))
    return replace(event, v=flat, delta=None if event.delta is None else np.zeros(event.n),
                   v2=None, name=f"{event.name} (no fault)")  # fmt: skip


def outcome(counts: dict[str, int], prob: float) -> dict[str, Any] | None:
    """Each outcome's count, share and Jeffreys interval, in words; None when all play.

    ``counts`` has the keys of :data:`KINDS`; the shares are of every draw played.
    """
    n = sum(counts.values())
    if n == 0 or counts["plays"] == n:
        return None
    out: dict[str, Any] = {"n": n}
    for kind in KINDS:
        k = int(counts.get(kind, 0))
        out[kind] = {"n": k, "share": k / n, "interval": jeffreys(k, n, prob)}
    out["interval_is"] = "Jeffreys interval of the share of the draws played"
    out["message"] = _words(out)
    return out


def _words(out: dict[str, Any]) -> str:
    n = out["n"]
    parts = [f"{out[k]['share']:.0%} {KINDS[k].split(' (')[0]} "
             f"[{out[k]['interval'][0]:.2f}, {out[k]['interval'][1]:.2f}]"
             for k in KINDS if out[k]["n"] or k in ("plays", "collapses")]  # fmt: skip
    head = f"of {n} draws: " + "; ".join(parts)
    if out["plays"]["n"]:
        return head + ". The band is of the draws that play."
    return head + ". " + no_band(out)


def no_band(out: dict[str, Any]) -> str:
    """The words for a depth where no draw plays (so there is no band)."""
    n = out["n"] - out["no_operating_point"]["n"]  # the draws with an operating point
    if out["collapses"]["n"] == n:
        return "every draw collapses at this depth: no band"
    if out["fails_numerically"]["n"] == n:
        return "every draw fails numerically at this depth: no band (not a collapse)"
    return (f"no draw plays through at this depth ({out['collapses']['n']} collapse, "
            f"{out['fails_numerically']['n']} fail numerically, "
            f"{out['no_operating_point']['n']} have no operating point): no band")  # fmt: skip


def parts_why(model, event, theta, p0, q0, shares, th, played) -> np.ndarray:
    """Each draw's ``parts_play`` outcome, those that fail played again with no fault.

    A draw that fails the fault-free record too has no operating point
    (``predict_outcome``'s module docstring); one that plays it collapses or fails
    numerically in the fault, as its loop said.
    """
    why = np.array(played.why, dtype=np.int64)
    bad = np.flatnonzero(why != PLAYS)
    if bad.size:
        flat = play_draws(model, fault_free(event), theta[bad], p0, q0, shares[bad],
                          {k: np.asarray(v)[bad] for k, v in th.items()})  # fmt: skip
        why[bad[~flat.ok]] = NO_OPERATING_POINT
    return why


def after_stall(extrapolation: dict[str, Any], model, stall: dict | None) -> dict[str, Any]:
    """``extrapolation`` with, where some draw stalls, what then decides P and Q: an assumption.

    Once motor D stalls, its P and Q after the clearing are set by its restart constants
    (``frst, vrst, trst``: models/parts.MOTOR_D_DEFAULTS, the WECC composite load model's
    typical data, or the model's ``motor_d_params``), which no fit estimates; the units
    that do not restart stay stalled to the record's end (no thermal trip). A load or a
    simulator whose stalled units come back at the clearing draws far less there: measured
    on GridDyn 0.13.0's CMLD at a 46 % sag, motor D stays stalled at Vstall 0.58 and 0.60
    and comes back within 0.15 s at 0.545, 0.62 and 0.684 (f_d 0.15), and the band from a
    13 % and a 25 % fit, its draws stalled to the end, held 14-45 % of such a fault's Q.
    The restart constants decide it, not the draws: on GridDyn's drawn load 105 (f_d 0.243,
    Vstall 0.684) Q's coverage stays 0.14 with Frst = 1 (the stalled units' current
    through the fitted feeder holds the load bus below Vrst 0.95: none restarts), is 0.82
    with Vrst 0.7 and 0.95 with Vrst 0.7 and Trst 0.05 s as well; no source gives those.
    Unchanged where no draw stalls (or the model has no motor D).
    """
    if not model.motor_d or not stall or not stall.get("probability"):
        return extrapolation
    from loadbayes.models.parts import MOTOR_D_DEFAULTS

    kw = {**MOTOR_D_DEFAULTS, **getattr(model, "motor_d_params", {})}
    assumed = {k: float(kw[k]) for k in ("frst", "vrst", "trst")}
    words = (f"After a stall, P and Q once the fault clears rest on an assumption, not on "
             f"the data: a share frst {assumed['frst']:.2g} of the stalled air conditioners "
             f"restarts after trst {assumed['trst']:.2g} s above vrst {assumed['vrst']:.2g} "
             "p.u. and the rest stay stalled to the record's end (the WECC composite load "
             "model's typical data; no fit estimates them, no thermal trip is modelled); "
             "where they come back at the clearing the load draws far less P and Q than "
             "this band after it.")  # fmt: skip
    return extrapolation | {
        "after_stall": {"assumed": assumed, "source": "WECC composite load model, "
                        "typical data (models/parts.MOTOR_D_DEFAULTS)", "message": words},
        "message": f"{extrapolation['message']} {words}",
    }  # fmt: skip
