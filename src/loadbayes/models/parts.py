"""The parts a substation's load is built from: physics only, one function a part.

A load seen from a recorder at a substation is, in the WECC composite load model's
terms (WECC MVWG, "WECC Composite Load Model Specifications", 2015; its PSS/E record
CMLDBLU2), a series impedance (the substation transformer and the feeder) between the
recorded bus and a load bus, and behind it: three-phase induction motors (fast
compressors, fans and pumps), single-phase air conditioners (motor D, a performance
model that stalls), power electronics (constant power that trips when the voltage
falls), a static ZIP part and shunt capacitors. Each function here gives one part's
P, Q (or its negative-sequence admittance) on its own base from the voltage it sees;
:mod:`loadbayes.models.parts_model` assembles them into a
:class:`~loadbayes.models.base.DynamicLoadModel`.

The series impedance: the recorder measures ``V`` and the current ``I = conj(S / V)``
(``S = P + jQ``), so the load bus's voltage is ``V_L = V - Z I`` and the load draws
``S_L = S - Z |I|^2`` (:func:`load_bus`), for any ``Z = R + jX`` without an algebraic
loop. The recorded current carries the noise of P and Q into ``V_L``: ``|Z| dI``, for
a feeder of 0.1 p.u. and 0.5 % noise about 5e-4 p.u., beside the noise of P and Q
themselves; a prediction with no recorded current solves the loop instead
(``parts_model.PartsModel.predict``, waveform relaxation).

Motor D (:func:`motor_d`) is the WECC performance model of the single-phase air
conditioner compressor (PNNL-17796, Lu, Xie and Huang 2008, "Air conditioner compressor
performance model"; the WECC specification's motor D): running, its P and Q follow
two power laws on either side of a break voltage ``Vbrk``; below ``Vstall`` for
``Tstall`` it stalls and becomes the impedance ``Rstall + jXstall``; a fraction
``Frst`` restarts after the voltage has stayed above ``Vrst`` for ``Trst``. The
thermal relay, the contactors and the frequency terms are left out (they act over
seconds, beyond a fault record's window), and said so in ``docs/composite.md``.

The electronics (:func:`electronics_fraction`): constant P and Q; the share connected
falls linearly from 1 at ``Vd1`` to 0 at ``Vd2`` and does not come back, except a
fraction ``Frcel`` of what tripped (the WECC specification's electronic load).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numba
import numpy as np
from numpy.typing import NDArray

from loadbayes.measurements.record import EventRecord

__all__ = [
    "GAP",
    "MOTOR_D_DEFAULTS",
    "NEG_SEQ_MIN",
    "LoadBus",
    "brake_drive",
    "electronics_fraction",
    "gaps_of",
    "load_bus",
    "d_step",
    "motor_d",
    "motor_y2",
    "step_knots",
    "step_times",
]

#: A sample interval this many times the median one is a gap: rows were left out there
#: (their phasor window straddled a step), and the voltage steps at the gap's middle.
GAP = 1.5
#: |V2| (p.u.) above which a row's negative sequence is data: below it the current is
#: the recorder's noise and the load's own imbalance more than the fault's.
NEG_SEQ_MIN = 0.02
#: Motor D's constants (WECC composite load model specification, 2015, typical values;
#: the run curves are PNNL-17796's fit to 27 tested units): break voltage, the two run
#: curves' gains and exponents, the stall voltage, time and impedance (own base), the
#: restart, and the compressor's power factor.
MOTOR_D_DEFAULTS: dict[str, float] = {
    "vbrk": 0.86,
    "kp1": 0.0,
    "np1": 1.0,
    "kq1": 6.0,
    "nq1": 2.0,
    "kp2": 12.0,
    "np2": 3.2,
    "kq2": 11.0,
    "nq2": 2.5,
    "vstall": 0.60,
    "tstall": 0.033,
    "rstall": 0.10,
    "xstall": 0.10,
    "frst": 0.20,
    "vrst": 0.95,
    "trst": 0.30,
    "comp_pf": 0.98,
}


@dataclass(frozen=True)
class LoadBus:
    """What the load bus sees behind a series impedance, from the recorded bus's data.

    ``event`` is the load bus's own record (its V, angle, P, Q: the recorded ones less
    the impedance's drop and losses); ``loss_p, loss_q`` the impedance's ``R |I|^2`` and
    ``X |I|^2``; ``v2`` the negative-sequence voltage at the load bus (None without one).
    """

    event: EventRecord
    loss_p: NDArray[np.float64]
    loss_q: NDArray[np.float64]
    v2: NDArray[np.complex128] | None


def load_bus(event: EventRecord, r: float, x: float) -> LoadBus:
    """The load bus behind ``Z = r + jx`` (system p.u.) from the recorded bus's data.

    The angle is the recorded one plus the impedance's angle shift where the event has
    an angle; without one it stays None (the motors then see a constant frame, as at
    the recorded bus).
    """
    delta = np.zeros(event.n) if event.delta is None else event.delta
    v = event.v * np.exp(1j * delta)
    current = np.conj((event.p + 1j * event.q) / v)
    z = complex(r, x)
    vl = v - z * current
    i2 = np.abs(current) ** 2
    v2 = getattr(event, "v2", None)
    i2_neg = getattr(event, "i2", None)
    v2l = None
    if v2 is not None and i2_neg is not None:
        v2l = np.asarray(v2, dtype=complex) - z * np.asarray(i2_neg, dtype=complex)
    ev = EventRecord(
        event.t,
        np.abs(vl),
        event.p - r * i2,
        event.q - x * i2,
        None if event.delta is None else np.angle(vl),
        event.name,
        event.angle_from,
    )
    return LoadBus(ev, r * i2, x * i2, v2l)


@numba.njit(cache=True, nogil=True)
def d_step(dt, vk, st, dp, force):  # pragma: no cover - compiled
    """One sample of motor D (``_motor_d`` runs it sample by sample; so does the march).

    Its P, Q on its own base at ``|V_L| = vk``, ``dt`` after the last sample, from
    ``st = (running, below, above, stalled, restarted)``, ``dp`` the 17 constants in
    :data:`MOTOR_D_DEFAULTS`' order. Returns ``(p, q, running, below, above, stalled,
    restarted, jump)``: ``jump``, whether it stalls (or restarts) at this sample;
    ``force`` 0 / 1 makes it not / so (-1: as it falls).
    """
    return _d_sample(dt, vk, st[0], st[1], st[2], st[3], st[4], dp, _d_constants(dp), force)


@numba.njit(cache=True, nogil=True)
def _d_constants(dp):  # pragma: no cover - compiled
    # The run curves through (1, 1) and (1, tan_phi) on the unit's own base at V = 1, the
    # stalled units' conductance and susceptance: (p0, q0, gs, bs).
    vbrk, kp1, np1, kq1, nq1 = dp[0], dp[1], dp[2], dp[3], dp[4]
    rstall, xstall, comp_pf = dp[11], dp[12], dp[16]
    tan_phi = math.sqrt(1.0 - comp_pf * comp_pf) / comp_pf
    p0 = 1.0 - kp1 * (1.0 - vbrk) ** np1
    q0 = tan_phi - kq1 * (1.0 - vbrk) ** nq1
    zz = rstall * rstall + xstall * xstall
    return p0, q0, rstall / zz, xstall / zz


@numba.njit(cache=True, nogil=True, inline="always")
def _d_sample(dt, vk, running, below, above, stalled, restarted, dp, c,
              force):  # pragma: no cover - compiled  # fmt: skip
    # d_step with its state in scalars and its constants c (_d_constants) made once.
    vbrk, kp1, np1, kq1, nq1, kp2, np2, kq2, nq2 = dp[:9]
    vstall, tstall, frst, vrst, trst = dp[9], dp[10], dp[13], dp[14], dp[15]
    p0, q0, gs, bs = c
    jump = False
    if stalled == 0.0:
        below = below + dt if vk < vstall else 0.0
        jump = below >= tstall
        if jump if force < 0 else force == 1:
            stalled, running = 1.0, 0.0
    elif restarted == 0.0:
        above = above + dt if vk > vrst else 0.0
        jump = above >= trst
        if jump if force < 0 else force == 1:
            restarted, running = 1.0, frst
    if vk >= vbrk:
        pr = p0 + kp1 * (vk - vbrk) ** np1
        qr = q0 + kq1 * (vk - vbrk) ** nq1
    else:
        pr = p0 + kp2 * (vbrk - vk) ** np2
        qr = q0 + kq2 * (vbrk - vk) ** nq2
    p = running * pr + (1.0 - running) * gs * vk * vk
    q = running * qr + (1.0 - running) * bs * vk * vk
    return p, q, running, below, above, stalled, restarted, jump


@numba.njit(cache=True, nogil=True)
def _motor_d(t, v, vbrk, kp1, np1, kq1, nq1, kp2, np2, kq2, nq2, vstall, tstall, rstall,
             xstall, frst, vrst, trst, comp_pf):  # pragma: no cover - compiled  # fmt: skip
    # Sample by sample (d_step, the march's step too), from every unit running.
    n = t.size
    p = np.empty(n)
    q = np.empty(n)
    dp = np.array([vbrk, kp1, np1, kq1, nq1, kp2, np2, kq2, nq2, vstall, tstall, rstall,
                   xstall, frst, vrst, trst, comp_pf])  # fmt: skip
    c = _d_constants(dp)
    running, below, above, stalled, restarted = 1.0, 0.0, 0.0, 0.0, 0.0
    for k in range(n):
        dt = 0.0 if k == 0 else t[k] - t[k - 1]
        p[k], q[k], running, below, above, stalled, restarted, _ = _d_sample(
            dt, v[k], running, below, above, stalled, restarted, dp, c, -1)  # fmt: skip
    return p, q


def motor_d(t: NDArray, v: NDArray, **params: float) -> tuple[NDArray, NDArray]:
    """Motor D's P, Q on its own base (P = 1 at V = 1 running) at the samples ``(t, v)``.

    ``params`` override :data:`MOTOR_D_DEFAULTS` by name. Stalling is decided on the
    samples (a dip shorter than a sample interval is not seen).
    """
    kw = {**MOTOR_D_DEFAULTS, **params}
    unknown = set(params) - set(MOTOR_D_DEFAULTS)
    if unknown:
        raise ValueError(f"motor D has no parameter {sorted(unknown)[0]!r}")
    return _motor_d(np.asarray(t, dtype=float), np.asarray(v, dtype=float),
                    *(float(kw[k]) for k in MOTOR_D_DEFAULTS))  # fmt: skip


def electronics_fraction(v: NDArray, vd1: float, vd2: float, frcel: float = 0.0) -> NDArray:
    """The share of the electronics connected at each sample (1 before the event).

    Linear from 1 at ``vd1`` down to 0 at ``vd2``; what tripped stays off except the
    fraction ``frcel`` of it, which follows the voltage back up.
    """
    ramp = np.clip((np.asarray(v, dtype=float) - vd2) / (vd1 - vd2), 0.0, 1.0)
    low = np.minimum.accumulate(ramp)
    return low + frcel * (ramp - low)


def motor_y2(rs, xp, dx, tp_s, f_hz: float, slip: float = 0.0):
    """A running motor's negative-sequence admittance on its own base (vectorised).

    The rotor sees the negative sequence at slip ``2 - s``: the equivalent circuit
    ``Z2 = Rs + jXs + jXm || (Rr / (2 - s) + jXr)``, with the closure of
    ``models/composite.py`` (``X = X' + (X - X')``, ``Xm = sqrt(X (X - X'))``,
    ``Xs = Xr = X - Xm``, ``Rr = X / (wb T')``). Close to the locked-rotor impedance
    ``Rs + Rr / 2 + jX'``: a running motor draws a large negative-sequence current.
    """
    x = xp + dx
    xm = np.sqrt(x * dx)
    xs = x - xm
    rr = x / (2.0 * math.pi * f_hz * tp_s)
    rotor = rr / (2.0 - slip) + 1j * xs
    z2 = rs + 1j * xs + (1j * xm * rotor) / (rotor + 1j * xm)
    return 1.0 / z2


def brake_drive(v2: NDArray | None, v2_load: NDArray | None) -> NDArray | None:
    """The motors' braking drive: ``|V2_L|`` where ``|V2| >= NEG_SEQ_MIN``, 0 elsewhere.

    ``v2`` is the recorded bus's negative-sequence voltage (it picks the rows, as the I2
    channel's), ``v2_load`` the load bus's (behind the series impedance; the motors see
    it). None where no row reaches the threshold: then the motors' arithmetic is the
    balanced one, to the bit. Below the threshold the braking is left out with the rest
    of the record's standing imbalance (about 1e-5 of torque at 0.5 % V2 on a motor of
    ``|Z2|`` 0.2): the motors start from their balanced steady state.
    """
    if v2 is None or v2_load is None:
        return None
    rows = np.abs(np.asarray(v2, dtype=complex)) >= NEG_SEQ_MIN
    if not rows.any():
        return None
    return np.where(rows, np.abs(np.asarray(v2_load, dtype=complex)), 0.0)


def gaps_of(t: NDArray, steps: NDArray | None = None) -> NDArray[np.bool_]:
    """``gap[k]``: a step between samples ``k`` and ``k + 1``.

    Rows were left out there (:data:`GAP`), or its instant is known (``steps[k]``).
    """
    dt = np.diff(np.asarray(t, dtype=float))
    out = np.zeros(max(t.size, 1), dtype=bool)
    if dt.size:
        out[:-1] = dt > GAP * float(np.median(dt))
    if steps is not None:
        out |= np.isfinite(steps)
    return out


def step_times(t: NDArray, v: NDArray, keep: NDArray[np.int64], window_s: float) -> NDArray:
    """Each gap's step instant, read from the rows left out (NaN: none to read).

    ``step[k]`` belongs to the gap after kept row ``k``. A one-cycle phasor across a step
    is about the window's mean, so a left-out row ``i`` between kept rows ``a`` and ``b``
    says the step came at ``t_i - w/2 + w (v_i - v_b) / (v_a - v_b)`` when that share
    lies strictly inside (0, 1); the estimates of a gap's rows are averaged.
    """
    out = np.full(keep.size, np.nan)
    for k in range(keep.size - 1):
        a, b = int(keep[k]), int(keep[k + 1])
        if b - a < 2 or abs(v[a] - v[b]) < 1e-6:
            continue
        est = []
        for i in range(a + 1, b):
            share = (v[i] - v[b]) / (v[a] - v[b])
            if 0.0 < share < 1.0:
                est.append(t[i] - 0.5 * window_s + window_s * share)
        if est:
            out[k] = min(max(float(np.mean(est)), t[a] + 1e-5), t[b] - 1e-5)
    return out


def step_knots(t: NDArray, v: NDArray, delta: NDArray | None, gap: NDArray[np.bool_],
               steps: NDArray | None = None):  # fmt: skip
    """The drive of a motor read as window means across gaps: a step in each gap.

    Returns ``(t, v, delta, real)``: the samples plus two knots 1 us either side of each
    gap's step (``steps[k]`` where known, :func:`step_times`; else the gap's middle),
    holding the values before and after it (the voltage steps there, instead of ramping
    across the rows left out), and ``real``, the samples' positions.
    """
    if not gap.any():
        return t, v, delta, np.arange(t.size)
    ts, vs, ds, real = [], [], [], []
    d = np.zeros(t.size) if delta is None else delta
    for k in range(t.size):
        real.append(len(ts))
        ts.append(t[k])
        vs.append(v[k])
        ds.append(d[k])
        if gap[k] and k + 1 < t.size:
            at = 0.5 * (t[k] + t[k + 1])
            if steps is not None and np.isfinite(steps[k]):
                at = float(steps[k])
            ts += [at - 1e-6, at + 1e-6]
            vs += [v[k], v[k + 1]]
            ds += [d[k], d[k + 1]]
    return (np.array(ts), np.array(vs), None if delta is None else np.array(ds),
            np.array(real, dtype=np.int64))  # fmt: skip
