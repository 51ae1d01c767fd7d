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

Where the fault has a negative sequence (``EventRecord.v2``, a profile's ``v2_re,
v2_im``), the motors brake (``motor_kernel.brake_torque``) with the load bus's ``|V2_L|``
(:func:`brake_of`): ``V2_L = V2 / (1 + Z Y2)`` with ``Y2`` the load's negative-sequence
admittance at its operating point, the one the I2 channel of a fit reads
(``PartsModel.channels``), at the rows ``|V2| >= NEG_SEQ_MIN`` (``parts.brake_drive``).

:func:`play_reference` plays many draws one by one through :func:`predict_parts` and reads
motor D's stall and the electronics' trip off each converged load bus, as a prediction
did before ``models/parts_play.play_draws`` did the same in compiled calls: the reference
that ``tests/unit/test_parts_play.py`` and ``benchmarks/bench_predict.py`` hold it to.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import replace

import numpy as np
from numpy.typing import NDArray

from loadbayes.measurements.record import EventRecord
from loadbayes.models.motor_kernel import steady_state
from loadbayes.models.part_priors import MOTOR_CLASSES
from loadbayes.models.parts import (
    MOTOR_D_DEFAULTS,
    brake_drive,
    electronics_fraction,
    motor_d,
    motor_y2,
)
from loadbayes.models.parts_loop import (
    CONTINUES,
    PV_STEPS,
    PV_TOL,
    RAMP_STEPS,
    SCAN,
    SCAN_TOP,
    SOLVE_SWEEPS,
)

__all__ = ["brake_of", "motor_ratings", "play_reference", "predict_parts"]


def brake_of(model, c, v: NDArray, v2: NDArray | None, z: complex, s0: complex):
    """The motors' braking drive through a feeder ``z`` with no recorded I2 (or None).

    ``v``, ``v2``: the recorded bus's voltage and negative sequence; ``s0`` its S before
    the event; ``c``: ``model._split`` of one draw. The load's ``Y2 = P_L(0) Y2_p - j
    Q_L(0) / V_L(0)^2`` (``PartsModel.load_columns``' ``Y2`` per ``p0``, the motors' from
    their steady state at ``V_L(0)``), then ``V2_L = V2 / (1 + Z Y2)``.
    """
    if v2 is None or brake_drive(v2, v2) is None:
        return None
    i0 = np.conj(s0 / v[0])
    s_l0 = s0 - z * abs(i0) ** 2
    v0 = abs(v[0] - z * i0)
    f = c["f"]
    y2p = f[-1] / v0**2 + 0j
    wb = 2 * math.pi * model.f_hz
    for j, (m, logs) in enumerate(zip(model.motors, c["motors"], strict=True)):
        rs, xp, dx, tp, _, t0 = np.exp(logs)
        a, b, cc = MOTOR_CLASSES[m]["torque"]
        pm0, qm0 = steady_state(rs, xp, dx, tp, wb, v0, t0, a, b, cc)[3:]
        if not math.isfinite(pm0):  # no steady state: the draw fails
            return np.full(len(v2), np.nan)
        y2p += f[j] / pm0 * (motor_y2(rs, xp, dx, tp, model.f_hz) + 1j * qm0 / v0**2)
    if model.motor_d:
        y2p += f[len(model.motors)] / v0**2
    y2 = s_l0.real * y2p - 1j * s_l0.imag / v0**2
    v2 = np.asarray(v2, dtype=complex)
    return brake_drive(v2, v2 / (1.0 + z * y2))


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
    why: list | None = None,
    low: list | None = None,
    solve: bool = False,
    retry: bool = True,
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
        not settle or leave the finite numbers (a part that switches, motor D stalling or
        a motor slowing, can make the sweeps bounce between two trajectories), again at
        ``w = 0.5`` for up to 200 sweeps, which settles them at the same fixed point;
        where neither settles, a third try (``solve``).
    why : list, optional
        Where the draw fails, gets why: ``"no operating point"`` (a motor with no steady
        state before the fault, read off the negative sequence's admittance),
        ``"no root"`` (the last try's last sweep found no load-bus voltage at some
        sample: the load's P-V nose below the feeder's) or ``"failed"`` (no try settled,
        or they left the finite numbers).
    low : list, optional
        ``[x]``: lowered to the lowest ``|V_L| / |V|`` a sweep drove the parts with
        (``parts_play.Played.low``: a failed loop is a collapse below ``COLLAPSE_RATIO``).
    solve : bool
        Each sweep solves every sample's load bus jointly with the static part's draw
        (:func:`_pv_root`, ``parts_loop.pv_root``'s NumPy twin): the rest of the load held
        as a constant impedance at the sample, so the sweeps carry only the dynamic
        parts' lag (up to ``parts_loop.SOLVE_SWEEPS``). The third try, where the plain
        and the damped sweeps both fail, then a fourth damped at 0.5: draws that settle
        before keep their numbers.
    retry : bool
        False: the one try asked for, no later one (a test shows what a try alone does).

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
    u2 = brake_of(model, c, v, event.v2, z, complex(p0, q0))
    if u2 is not None and not np.isfinite(u2).all():
        return _failed(why, "no operating point")  # a motor with no steady state
    nose = False  # the last sweep found no root at some sample (solve)
    for it in range(1, max_iterations + 1):
        if low is not None:  # the lowest |V_L| / |V| a sweep drives the parts with
            low[0] = min(low[0], float(np.min(np.abs(vl) / np.abs(v))))
        ev = replace(event, v=np.abs(vl), delta=None if event.delta is None else np.angle(vl))
        cols = model.load_columns(ev, c, steps, u2)
        if cols is None:
            break  # a motor with no steady state or its numbers not finite
        col_p, col_qp, _ = cols
        xl = np.abs(vl) / abs(vl0)
        p_l = s_l0.real * col_p
        q_l = s_l0.real * col_qp + s_l0.imag * (q_shares[0] * xl * xl + q_shares[1] * xl
                                                + q_shares[2])  # fmt: skip
        current = np.conj((p_l + 1j * q_l) / vl)
        new = v - z * current
        nose = False
        plain = float(np.max(np.abs(new - vl)))  # the loop's own residual
        if solve:  # each sample's loop solved with the static part's voltage dependence
            ap = s_l0.real * c["f"][-1] * np.asarray(c["a_p"], dtype=float)
            aq = s_l0.imag * np.asarray(q_shares, dtype=float)
            roots = np.full(len(v), np.nan)
            for k in range(len(v)):
                if abs(vl[k]) > 0 and abs(v[k]) > 0:
                    got = _pv_root(abs(vl[k]), vl[k], v[k], z, p_l[k] + 1j * q_l[k], ap, aq,
                                   abs(vl0))  # fmt: skip
                    nose |= got is None
                    new[k] = vl[k] if got is None else got[0]  # no root: held, not settled
                    roots[k] = np.nan if got is None else got[1]
        moved = float(np.max(np.abs(new - vl)))
        if solve:  # settled where both the solve and the plain step stay
            moved = max(moved, plain)
        if moved < tol and not nose:  # the fixed point: the load's draw is what drove it
            if solve and not _continues(vl, v, z, p_l + 1j * q_l, ap, aq, abs(vl0), roots):
                break  # it jumps between two operating points: not settled
            s = v * np.conj(current)
            return s.real, s.imag, it
        vl = new if damping is None else vl + damping * (new - vl)
        if not np.isfinite(moved):
            nose = False  # left the finite numbers: a failure, as parts_play's -1
            break
    if not retry:
        return _failed(why, "no root" if nose else "failed")
    if damping is None and not solve:  # the plain sweeps bounced or left the finite numbers
        return predict_parts(model, event, theta, p0, q0, q_shares, tol=tol,
                             max_iterations=200, damping=0.5, why=why, low=low)  # fmt: skip
    if not solve:  # the damped ones too: each sample solved
        return predict_parts(model, event, theta, p0, q0, q_shares, tol=tol,
                             max_iterations=SOLVE_SWEEPS, why=why, low=low, solve=True)  # fmt: skip
    if damping is None:  # and again damped at 0.5, where those bounce
        return predict_parts(model, event, theta, p0, q0, q_shares, tol=tol,
                             max_iterations=SOLVE_SWEEPS, damping=0.5, why=why, low=low,
                             solve=True)  # fmt: skip
    return _failed(why, "no root" if nose else "failed")


def _pv_root(m: float, vl: complex, v: complex, z: complex, s: complex, ap, aq, m0: float):
    """``V_L`` and ``|V_L|`` at one sample, Newton from ``m``; None where none is found.

    ``parts_loop.pv_root``'s equation: ``h(m) = |m^2 + conj(Z) S(m)| - m |V|``, ``S(m) =
    dd (m / m_k)^2 + P_s(m / m0) + j Q_s(m / m0)``, ``dd`` the load's S at the sweep's
    ``m_k = |V_L|`` less the static part's there; Newton from ``m`` (``m_k``), else the
    grid's sign change nearest ``m`` bisected (:func:`_scan`).
    """
    # Python's numbers, not NumPy's scalars: the same arithmetic in the same order (the
    # played draws byte for byte), a few times faster
    vl, v, z, s, m, m0 = complex(vl), complex(v), complex(z), complex(s), float(m), float(m0)
    ap, aq = [float(a) for a in ap], [float(a) for a in aq]
    mk = abs(vl)
    x = mk / m0
    dd = s - complex(ap[0] * x * x + ap[1] * x + ap[2], aq[0] * x * x + aq[1] * x + aq[2])
    zc, vabs, start = z.conjugate(), abs(v), m

    def s_parts(m):  # S(m)'s real and imaginary parts; m a number, or _scan's points at once
        x = m / m0
        d = dd * (m * m / (mk * mk))
        return (d.real + (ap[0] * x * x + ap[1] * x + ap[2]),
                d.imag + (aq[0] * x * x + aq[1] * x + aq[2]))  # fmt: skip

    def s_of(m):
        return complex(*s_parts(m))

    root = None
    for _ in range(PV_STEPS):
        x = m / m0
        ds = dd * (2.0 * m / (mk * mk)) + complex((2.0 * ap[0] * x + ap[1]) / m0,
                                                  (2.0 * aq[0] * x + aq[1]) / m0)  # fmt: skip
        w, dw = m * m + zc * s_of(m), 2.0 * m + zc * ds
        aw = abs(w)
        if aw == 0.0:
            break
        dh = (w.real * dw.real + w.imag * dw.imag) / aw - vabs
        if dh == 0.0:  # the nose itself
            break
        step = (aw - m * vabs) / dh
        if not math.isfinite(step):
            break
        new = m - step if m - step > 0.0 else 0.5 * m
        if abs(new - m) <= PV_TOL * m:
            root = new
            break
        m = new
    if root is None:
        root = _scan(start, vabs, zc, s_parts)
    if root is None:
        return None
    return np.complex128(root * root + zc * s_of(root)) / np.conj(np.complex128(v)), root


def _continues(vl, v, z, s, ap, aq, m0, roots) -> bool:
    # parts_loop.continues: each sample's root the one Newton reaches from the last's.
    for k in range(1, len(v)):
        if np.isfinite(roots[k]) and np.isfinite(roots[k - 1]):
            r, a, b = roots[k - 1], abs(v[k - 1]), abs(v[k])
            for i in range(1, RAMP_STEPS + 1):  # along a ramp of |V| across a step
                got = _pv_root(r, vl[k], a + (b - a) * i / RAMP_STEPS, z, s[k], ap, aq, m0)
                r = math.nan if got is None else got[1]
                if got is None:
                    break
            if not abs(r - roots[k]) <= CONTINUES * roots[k]:
                return False
    return True


def _scan(mk, vabs, zc, s_parts):
    # parts_loop._scan: h's sign change nearest mk (Newton's start), bisected; None: none.
    # h at the SCAN points at once, each point's arithmetic the scalar one's: ``zc S``
    # written out as a complex product is, ``|w|`` as hypot.
    def h(m):
        s_re, s_im = s_parts(m)
        w_re = m * m + (zc.real * s_re - zc.imag * s_im)
        return np.hypot(w_re, zc.real * s_im + zc.imag * s_re) - m * vabs

    top = SCAN_TOP * max(vabs, mk, 1.0)
    grid = top * np.arange(1, SCAN + 1) / SCAN  # the points top j / SCAN, j = 1 ... SCAN
    below = h(grid) <= 0.0
    j = np.flatnonzero(below[:-1] != below[1:])  # h changes sign in (grid[j], grid[j + 1])
    if j.size == 0:
        return None
    k = j[np.argmin(np.abs(0.5 * (grid[j] + grid[j + 1]) - mk))]  # the first nearest
    lo, hi = float(grid[k]), float(grid[k + 1])
    h_lo = h(lo)
    for _ in range(100):
        mid = 0.5 * (lo + hi)
        if hi - lo <= PV_TOL * mid:
            break
        h_mid = h(mid)
        if (h_mid <= 0.0) == (h_lo <= 0.0):
            lo, h_lo = mid, h_mid
        else:
            hi = mid
    return 0.5 * (lo + hi)


def _failed(why: list | None, reason: str) -> None:
    if why is not None:
        why.append(reason)
    return None


def play_reference(model, event: EventRecord, thetas: NDArray, p0: float, q0: float,
                   q_shares: NDArray, thresholds: Mapping[str, NDArray] | None = None):  # fmt: skip
    """``parts_play.play_draws``' answer, draw by draw in NumPy (the readable reference).

    Its four sweeping tries are NumPy's (``predict_parts``); a draw none settles is marched
    in time by the compiled ``parts_march`` (``play_draws(..., only_march=True)``).
    """
    from loadbayes.models.parts_play import (
        COLLAPSE_RATIO,
        COLLAPSES,
        FAILS,
        NO_OPERATING_POINT,
        Played,
        play_draws,
    )

    th = np.atleast_2d(np.asarray(thetas, dtype=float))
    n = th.shape[0]
    given = {k: np.broadcast_to(np.asarray(x, dtype=float), (n,)) for k, x in
             (thresholds or {}).items()}  # fmt: skip
    th = model.with_thresholds(th, given)  # a model that samples them reads them from theta
    keep = model.drive_of(event)[0]
    ev = event.take(keep) if keep.size < event.n else event  # the rows predict_parts returns
    v = ev.v * np.exp(1j * (np.zeros(ev.n) if ev.delta is None else ev.delta - ev.delta[0]))
    out = [np.full((n, ev.n), np.nan) for _ in range(3)]
    ok, stalled = np.zeros(n, bool), np.zeros(n, bool)
    tripped, its, whys = np.full(n, np.nan), np.zeros(n, np.int64), np.zeros(n, np.int64)
    lows = np.full(n, np.inf)
    for j in range(n):
        params = {**model.motor_d_params}
        params |= {k: float(given[k][j]) for k in ("vstall", "tstall") if k in given}
        mj = replace(model, motor_d_params=params, vd1=float(given.get("vd1", [model.vd1] * n)[j]),
                     vd2=float(given.get("vd2", [model.vd2] * n)[j]))  # fmt: skip
        why: list[str] = []
        low = [np.inf]
        got = predict_parts(mj, event, th[j], p0, q0, q_shares[j], why=why, low=low)
        lows[j] = low[0]
        if got is None and why[-1] != "no operating point":  # the fifth try: marched in
            # time (parts_march, compiled: it has no NumPy twin; tests/unit/test_parts_march.py
            # checks it against SciPy)
            one = play_draws(model, event, th[j : j + 1], p0, q0, q_shares[j : j + 1],
                             {k: x[j : j + 1] for k, x in given.items()},
                             only_march=True)  # fmt: skip
            lows[j] = low[0] = min(low[0], float(one.low[0]))
            if one.ok[0]:
                got = one.p[0], one.q[0], int(one.iterations[0])
            elif one.why[0] == COLLAPSES:
                why.append("no root")
        if got is None:  # parts_play's codes: no operating point, a collapse or a failure
            whys[j] = (NO_OPERATING_POINT if why[-1] == "no operating point" else
                       COLLAPSES if why[-1] == "no root" or low[0] < COLLAPSE_RATIO else
                       FAILS)  # fmt: skip
            continue
        mp, mq, its[j] = got
        ok[j] = True
        current = np.conj((mp + 1j * mq) / v)
        # The load bus's voltage the parts saw: the recorded one less the feeder's drop.
        z = complex(mj.rx, 1.0) * mj.feeder_x(p0, q0, mj._split(th[j]))
        vl = np.abs(v - z * current)
        out[0][j], out[1][j], out[2][j] = mp, mq, vl
        if model.motor_d:
            kw = {**MOTOR_D_DEFAULTS, **params}
            run = motor_d(ev.t, vl, **(kw | {"vstall": -1.0}))[0]
            stalled[j] = bool(np.any(np.abs(motor_d(ev.t, vl, **kw)[0] - run) > 1e-9))
        if model.electronics:
            tripped[j] = 1.0 - float(electronics_fraction(vl, mj.vd1, mj.vd2, mj.frcel)[-1])
    return Played(*out, ok, stalled, tripped, its, whys, lows)


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
