"""A model of parts driven by a voltage alone: the feeder's loop solved, for any fault.

A fit reads the load bus through the recorded current (``parts.load_bus``); a prediction
has no current: the load bus's voltage ``V_L = V - Z I`` depends on what the load draws,
which depends on ``V_L``. :func:`predict_parts` solves that loop over the whole
trajectory by waveform relaxation (Gauss-Jacobi over the record): start from the
pre-fault current, drive every part with ``V_L``, form the current the load draws, and
repeat until ``V_L`` moves by less than ``tol`` anywhere (a feeder of ``|Z|`` 0.1 p.u.
with a load whose current moves by about as much as its voltage contracts by about
``|Z| |dI/dV|``, a few iterations). What it returns is what a recorder would see at the
recorded bus: ``S = V conj(I) = S_L + Z |I|^2``.

The operating point is the event's own (its pre-fault P, Q at the recorded bus), as in
``fit/composite/validate.py``: what carries over from a fit is the load's make-up.
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
from numpy.typing import NDArray

from loadbayes.measurements.record import EventRecord
from loadbayes.models.motor_kernel import steady_state
from loadbayes.models.part_priors import MOTOR_CLASSES

__all__ = ["motor_ratings", "predict_parts"]


def predict_parts(
    model,
    event: EventRecord,
    theta: NDArray,
    p0: float,
    q0: float,
    q_shares: NDArray,
    *,
    tol: float = 1e-7,
    max_iterations: int = 60,
    damping: float | None = None,
) -> tuple[NDArray, NDArray, int] | None:
    """P, Q at the recorded bus of one draw, and the iterations the loop took.

    Parameters
    ----------
    model : PartsModel
    event : EventRecord
        The recorded bus's voltage (and angle) drive the load; its P, Q are not read.
    theta : ndarray
        One draw of the model's ``theta_names``.
    p0, q0 : float
        The recorded bus's P and Q before the event (the operating point).
    q_shares : ndarray, shape (3,)
        The static Q's split among ``x^2, x, 1`` (``cq / sum(cq)`` of the fit).
    damping : float, optional
        Under-relaxation ``V_L += w (new - V_L)``. None: plain sweeps, then, where they do
        not settle (a part that switches, motor D stalling or a motor slowing, can make
        the sweeps bounce between two trajectories), again at ``w = 0.5`` for up to 200
        sweeps, which settles them at the same fixed point.

    Returns
    -------
    (p, q, iterations) or None
        At the kept rows (``model.kept``: with a phasor window, not those straddling a
        step).
        None where a motor has no steady state or the loop does not converge.
    """
    c = model._split(np.asarray(theta, dtype=float))
    keep, steps = model.drive_of(event)
    if keep.size < event.n:  # the rows straddling a step left out: stepped across
        event = event.take(keep)
    z = complex(model.rx, 1.0) * model.feeder_x(p0, q0, c)
    delta = np.zeros(event.n) if event.delta is None else event.delta - event.delta[0]
    v = event.v * np.exp(1j * delta)
    i0 = np.conj(complex(p0, q0) / v[0])
    vl0 = v[0] - z * i0
    s_l0 = complex(p0, q0) - z * abs(i0) ** 2  # the load bus's S before the event
    vl = v - z * i0
    for it in range(1, max_iterations + 1):
        ev = replace(event, v=np.abs(vl), delta=None if event.delta is None else np.angle(vl))
        cols = model.load_columns(ev, c, steps)
        if cols is None:
            return None
        col_p, col_qp, _ = cols
        xl = np.abs(vl) / abs(vl0)
        p_l = s_l0.real * col_p
        q_l = s_l0.real * col_qp + s_l0.imag * (q_shares[0] * xl * xl + q_shares[1] * xl
                                                + q_shares[2])  # fmt: skip
        current = np.conj((p_l + 1j * q_l) / vl)
        new = v - z * current
        moved = float(np.max(np.abs(new - vl)))
        if moved < tol:  # the fixed point: what the load draws is what it was driven by
            s = v * np.conj(current)
            return s.real, s.imag, it
        vl = new if damping is None else vl + damping * (new - vl)
        if not np.isfinite(moved):
            return None
    if damping is None:
        return predict_parts(model, event, theta, p0, q0, q_shares, tol=tol,
                             max_iterations=200, damping=0.5)  # fmt: skip
    return None


def motor_ratings(model, event: EventRecord, theta: NDArray, p0: NDArray) -> dict[str, NDArray]:
    """Each motor's rating (system p.u. of MVA) per draw: ``f_k p0 / p_k(0)``."""
    th = np.atleast_2d(np.asarray(theta, dtype=float))
    p0 = np.atleast_1d(np.asarray(p0, dtype=float))
    c = model._split(th)
    wb = 2 * math.pi * model.f_hz
    out = {}
    for j, (m, logs, t) in enumerate(zip(model.motors, c["motors"], model._tags, strict=True)):
        a, b, cc = MOTOR_CLASSES[m]["torque"]
        mva = np.full(th.shape[0], np.nan)
        for i in range(th.shape[0]):
            x_fd = float(c["x_fd"][i]) if model.feeder else 0.0
            s_load = float(np.hypot(event.p[0], event.q[0]))
            vl = abs(event.v[0] - complex(model.rx, 1.0) * x_fd / s_load
                     * np.conj(complex(event.p[0], event.q[0]) / event.v[0]))  # fmt: skip
            rs, xp, dx, tp, h, t0 = np.exp(logs[i])
            pm0 = steady_state(rs, xp, dx, tp, wb, vl, t0, a, b, cc)[3]
            mva[i] = c["f"][i, j] * p0[i] / pm0
        out["mva" + (t or "_m")] = mva
    return out
