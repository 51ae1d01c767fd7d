"""A model of parts' likelihood sums at ``theta``: each event's parts solved once per state.

The Python side of ``parts_kernel``: its arguments at ``theta`` (the event's arrays, the
parts' constants, each kept on the model), and each event's solved parts
(``parts_kernel.event_parts``: the load bus, every dynamic part's response) kept too, so
that the sums at given shares (:func:`model_sums`) and the shares' basis
(:func:`model_basis`) read one solve.

**Which states share a solve.** The parts' responses do not depend on the shares (the
load bus comes from the recorded current). Nor, to the bit, on a threshold pair the
event's load bus never reaches: where every kept row's ``|V_L|`` lies above motor D's
``vstall`` (and ``tstall > 0``), no row counts towards a stall and motor D runs on its
curves; where it lies above the electronics' ``vd1`` (with ``vd2 < vd1``), their
connected share is 1.0 at every row. So each solve is kept under ``theta`` without its
shares and thresholds, with the thresholds it was solved at and its lowest ``|V_L|``
(the kernel's own), and serves any thresholds that are the same or, pair by pair, reached
at neither (:func:`_entry`). The block move's proposal solves the parts; the shares'
steps after it (their basis at the state: ``fit/composite/shares.py``) and the
thresholds' steps that move a pair an event does not reach read that solve again, where
each solved them anew before (on ``cmld-lite``'s two GridDyn events, 2,000 iterations x
2 chains: 9,976 solves against 20,263). The arithmetic of every sum is the kernel's as
before: the draws are the same, bit for bit.
"""

from __future__ import annotations

import math

import numpy as np

from loadbayes.core.kept import token
from loadbayes.models.composite import SCALE_FREE_MATRIX
from loadbayes.models.part_priors import MOTOR_CLASSES, THRESHOLD_COORDS
from loadbayes.models.parts import MOTOR_D_DEFAULTS, NEG_SEQ_MIN, gaps_of
from loadbayes.models.parts_kernel import event_basis, event_parts, event_sums
from loadbayes.models.parts_state import K_NAMES, feeder_of, parts_constants, shares_of

__all__ = ["event_arrays", "model_basis", "model_constants", "model_sums"]

#: Keys (an event and theta without shares or thresholds) kept per model before the
#: store is emptied, and solves kept per key (at different thresholds).
KEEP = 256
PER_KEY = 4

_MISSING = object()


def model_sums(model, event, theta, ar=False):
    """``event_sums`` for a ``PartsModel`` at ``theta``: ``(ztz, zty, yty, n)`` or None.

    With ``ar``, ``((ztz, zty, yty, n), (mzz, mzy, myy, segments))``: P's and Q's AR(1)
    sums beside them (``inference.ar1.ar_moments``' stacks, one per channel).
    """
    theta = np.asarray(theta, dtype=float)
    fixed, parts, ns_on = _arguments(model, event, theta)
    solved = _entry(model, event, theta, fixed, parts)[2]
    if solved is None:
        return None
    f, a_p = _shares_of(model, theta)
    g = len(model.channel_names)
    ztz, zty, yty, nn = np.empty((g, 4, 4)), np.empty((g, 4)), np.empty(g), np.empty(g)
    moments = ((np.empty((2, 4, 4, 4)), np.empty((2, 4, 4)), np.empty((2, 4))) if ar
               else _NO_MOMENTS)  # fmt: skip
    r, x, motors, _, d_on = parts[:5]
    ok = event_sums(solved, fixed[6], fixed[8], fixed[9], fixed[10], r, x, motors.shape[0],
                    d_on, f, a_p, ns_on,
                    ztz, zty, yty, nn, ar, *moments)  # fmt: skip
    return _result(ok, (ztz, zty, yty, nn), moments, fixed, ar)


def model_basis(model, event, theta, ar=False):
    """``event_basis`` for a ``PartsModel`` at ``theta`` (its shares not read).

    ``(bb, by, yy, n)`` or None, as :func:`model_sums` returns; with ``ar`` their AR(1)
    stacks and segment count beside them. Kept with the solve it reads (the same arrays
    for every caller: read them, do not write them).
    """
    theta = np.asarray(theta, dtype=float)
    fixed, parts, ns_on = _arguments(model, event, theta)
    entry = _entry(model, event, theta, fixed, parts)
    got = entry[3].get(ar, _MISSING)
    if got is not _MISSING:
        return got
    got, solved = None, entry[2]
    if solved is not None:
        g = len(model.channel_names)
        m = len(model.parts) + 6
        bb, by, yy, nn = np.empty((g, m, m)), np.empty((g, m)), np.empty(g), np.empty(g)
        moments = (np.empty((2, 4, m, m)), np.empty((2, 4, m)), np.empty((2, 4)))
        r, x, motors, _, d_on = parts[:5]
        ok = event_basis(solved, fixed[6], fixed[8], fixed[9], fixed[10], r, x,
                         motors.shape[0], d_on, ns_on, bb, by, yy, nn, ar,
                         *moments)  # fmt: skip
        got = _result(ok, (bb, by, yy, nn), moments, fixed, ar)
    entry[3][ar] = got
    return got


def _entry(model, event, theta, fixed, parts) -> list:
    # The event's solve that holds at theta: [thresholds, lowest |V_L|, the solved parts
    # (None where a motor has no steady state), its basis by ar]. Kept per event under
    # theta without its shares and thresholds, a few per key (module docstring).
    pairs = model._threshold_pairs
    rest = theta[: model._n_gauss].copy()
    thr = []
    for key_v, other, _ in pairs:
        thr += [float(theta[key_v]), float(theta[other])]
        rest[key_v] = rest[other] = 0.0
    key = (token(event), rest.tobytes())
    entries = model._solved.get(key)
    if entries is None:
        entries = model._solved.keep(key, [])
    for entry in entries:
        if entry[2] is None or _holds(entry, thr, pairs):
            return entry
    ok, *arrays = event_parts(*fixed[:10], *parts)
    entry = [thr, float(arrays[0].min()), tuple(arrays) if ok else None, {}]
    entries.append(entry)
    if len(entries) > PER_KEY:
        del entries[0]
    return entry


def _holds(entry, thr, pairs) -> bool:
    # Whether a solve at the entry's thresholds is the solve at thr: each pair the same,
    # or reached by no row at either (the module docstring).
    if entry[0] == thr:
        return True
    low = entry[1]
    for k, (_, _, positive) in enumerate(pairs):
        old, new = entry[0][2 * k : 2 * k + 2], thr[2 * k : 2 * k + 2]
        if old != new and not (_unreached(old, low, positive) and _unreached(new, low, positive)):
            return False
    return True


def _unreached(pair, low: float, positive: bool) -> bool:
    # Motor D: no row below vstall, tstall = exp(log_tstall) > 0 (below 0 stalls at once);
    # the electronics: no row below vd1, and vd2 < vd1.
    key_v, other = pair
    return key_v < low and (other > -700.0 if positive else other < key_v)


def threshold_pairs(model) -> tuple[tuple[int, int, bool], ...]:
    """``(key voltage, other, positive)`` indices in ``theta`` of each sampled threshold pair.

    Motor D's ``(vstall, log_tstall)`` (``positive``: the stall time's log), the
    electronics' ``(vd1, vd2)``.
    """
    names = model.theta_names
    out = []
    for a, b, positive in (("vstall", "tstall", True), ("vd1", "vd2", False)):
        if a in model.thresholds and b in model.thresholds:
            ia, ib = (names.index(THRESHOLD_COORDS[n]) for n in (a, b))
            out.append((ia, ib, positive))
    return tuple(out)


def model_constants(model) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """``(k, inv_sf, torques, d_base)``: the arrays ``parts_state.parts_constants`` reads.

    ``k`` (``parts_state.K_NAMES``): the feeder (1/0), ``wb``, the motors' count, each threshold's
    coordinate in ``theta`` (-1: held) and held value, where ``vstall, tstall`` sit in
    ``d_base`` (motor D's constants in ``parts.MOTOR_D_DEFAULTS``' order, the model's
    own over them), the Gaussian coordinates' and the parts' counts; ``inv_sf`` the
    inverse of the motors' scale-free map; ``torques`` each motor's ``(A, B, C)``.
    """
    params = {**MOTOR_D_DEFAULTS, **model.motor_d_params}
    held = {"vstall": params["vstall"], "tstall": params["tstall"], "vd1": model.vd1,
            "vd2": model.vd2}  # fmt: skip
    index = {n: (model.theta_names.index(THRESHOLD_COORDS[n]) if n in model.thresholds else -1)
             for n in held}  # fmt: skip
    keys = list(MOTOR_D_DEFAULTS)
    values = {"feeder": float(model.feeder), "wb": 2.0 * math.pi * model.f_hz,
              "n_motors": len(model.motors), "d_vstall": keys.index("vstall"),
              "d_tstall": keys.index("tstall"), "n_gauss": model._n_gauss,
              "n_parts": len(model.parts),
              **{f"i_{n}": index[n] for n in held}, **held}  # fmt: skip
    k = np.array([float(values[n]) for n in K_NAMES])
    torques = np.array([MOTOR_CLASSES[m]["torque"] for m in model.motors], dtype=float)
    d_base = np.array([float(params[n]) for n in keys])
    inv_sf = np.linalg.inv(SCALE_FREE_MATRIX)  # as PartsModel._split's
    return k, np.ascontiguousarray(inv_sf), torques.reshape(-1, 3), d_base


def _result(ok, sums, moments, fixed, ar):
    if not ok:
        return None
    if not ar:
        return sums
    segments = 1.0 + float(np.count_nonzero(fixed[6][:-1]))
    return sums, (*moments, segments)


def _arguments(model, event, theta) -> tuple:
    # The kernels' arguments at theta but the shares: the event's arrays, the parts'
    # constants, whether the negative sequence is read.
    fixed = _fixed_of(model, event)
    x_load, motors, d_params, vd1, vd2 = _of_theta(model, theta)
    x_fd = feeder_of(x_load, fixed[4][0], fixed[5][0])  # the first kept row's P, Q
    parts = (model.rx * x_fd, x_fd, motors, float(model.window_s), model.motor_d, d_params,
             model.electronics, vd1, vd2, float(model.frcel))  # fmt: skip
    ns_on = len(model.channel_names) == 3 and bool(fixed[10].any())
    return fixed, parts, ns_on


def _of_theta(model, theta) -> tuple:
    # The parts' constants at theta but its shares (parts_state.parts_constants): the
    # same for every event and every share, so kept on the model for the last few (a
    # fit's events each ask them in turn, the shares' steps at the block move's state).
    key = theta[: model._n_gauss].tobytes()
    got = model._of_theta.get(key)
    if got is None:
        got = model._of_theta.keep(key, parts_constants(theta, *model.constants))
    return got


def _shares_of(model, theta) -> tuple:
    # The parts' shares of P and the static P's split (parts_state.shares_of), kept by
    # theta's shares.
    key = theta[model._n_gauss :].tobytes()
    got = model._shares.get(key)
    if got is None:
        got = model._shares.keep(key, shares_of(theta, model._n_gauss, len(model.parts)))
    return got


#: The AR(1) sums' arguments of the white-noise kernel call (not read).
_NO_MOMENTS = (np.zeros((2, 4, 4, 4)), np.zeros((2, 4, 4)), np.zeros((2, 4)))


def event_arrays(model, event) -> tuple:
    """The event's arrays the kernels read, over its kept rows (kept on the model).

    ``(t, v, delta, has_angle, p, q, gap, steps, v2, i2, i2_rows)``.
    """
    return _fixed_of(model, event)


def _fixed_of(model, event) -> tuple:
    # The event's arrays the kernel reads, once per event (kept on the model).
    got = model._fixed.get(event)
    if got is None:
        held = event  # the key: the event as given, not its kept rows
        keep, steps = model.drive_of(event)
        if keep.size < event.n:  # as channels: the rows left out make a gap
            event = event.take(keep)
        n = event.n
        ns = model.negative_sequence != "off" and model.uses_negative_sequence(event)
        # V2 and I2 wherever the event has them (the motors brake with them, parts.brake_drive,
        # I2 channel or not: without I2 the feeder's drop of V2 is unknown, left out).
        has_v2 = getattr(event, "v2", None) is not None
        v2 = np.asarray(event.v2, dtype=complex) if has_v2 else np.zeros(n, complex)
        i2 = (np.asarray(event.i2, dtype=complex) if has_v2 and event.i2 is not None
              else np.zeros(n, complex))  # fmt: skip
        rows = (np.abs(v2) >= NEG_SEQ_MIN) if ns else np.zeros(n, dtype=bool)
        delta = np.zeros(n) if event.delta is None else np.asarray(event.delta, float)
        got = model._fixed.keep(held, (
            np.ascontiguousarray(event.t, float), np.ascontiguousarray(event.v, float),
            np.ascontiguousarray(delta), event.delta is not None,
            np.ascontiguousarray(event.p, float), np.ascontiguousarray(event.q, float),
            gaps_of(event.t, steps), np.ascontiguousarray(steps, float),
            np.ascontiguousarray(v2), np.ascontiguousarray(i2), rows,
        ))  # fmt: skip
    return got
