"""The sums a model of parts' likelihood needs, for one event, in one compiled call.

:meth:`PartsModel.channels <loadbayes.models.parts_model.PartsModel.channels>` builds
each channel's design and target in NumPy (the NLS start and the tests read those);
the sampler needs only their sums ``Z'Z, Z'y, y'y`` per channel, at every proposal.
:func:`event_sums` computes them in one ``numba`` function: the load bus through the
recorded current (``parts.load_bus``), every motor (``motor_kernel``'s integrators, at
the samples or as window means), motor D (``parts._motor_d``), the electronics, the
static part, and the negative-sequence rows; the same arithmetic as ``channels``, which
``tests/unit/test_parts_kernel.py`` checks to 1e-9 on random draws. About a tenth of the
NumPy path's cost (measured on ``cmld-lite`` with two 0.6 s events at 60/s).
"""

from __future__ import annotations

import math

import numba
import numpy as np

from loadbayes.models.motor_kernel import (
    H_MAX_S,
    TP_STEPS,
    integrate_into,
    integrate_window_into,
)
from loadbayes.models.part_priors import MOTOR_CLASSES
from loadbayes.models.parts import MOTOR_D_DEFAULTS, NEG_SEQ_MIN, _motor_d, gaps_of

__all__ = ["event_sums", "knots_of", "model_sums"]


@numba.njit(cache=True, nogil=True)
def event_sums(t, v, delta, has_angle, p, q, gap, steps, v2, i2, i2_rows, r, x, motors, window_s,
               shares, a_p, d_on, d_params, el_on, vd1, vd2, frcel, ns_on, ztz, zty, yty,
               nn, ar, mzz, mzy, myy):  # pragma: no cover - compiled  # fmt: skip
    """Fill ``ztz (G, 4, 4)``, ``zty (G, 4)``, ``yty (G,)``, ``nn (G,)``; False if infeasible.

    ``motors`` (k, 11): ``rs, xp, dx, tp, h, wb, t0, a, b, c, h_step`` each; ``shares``
    the parts' shares of P (motors, then motor D, then electronics, the static part
    last); ``a_p`` the static P's Z, I, P split; ``d_params`` motor D's 17 constants in
    ``parts.MOTOR_D_DEFAULTS``' order.
    """
    n = t.size
    zc = complex(r, x)
    vl = np.empty(n, dtype=np.complex128)
    vm = np.empty(n)
    dl = np.zeros(n)
    pl = np.empty(n)
    ql = np.empty(n)
    for k in range(n):
        vk = v[k] * complex(math.cos(delta[k]), math.sin(delta[k]))
        cur = ((p[k] + 1j * q[k]) / vk).conjugate()
        vl[k] = vk - zc * cur
        i2k = cur.real * cur.real + cur.imag * cur.imag
        pl[k] = p[k] - r * i2k
        ql[k] = q[k] - x * i2k
        vm[k] = abs(vl[k])
    if has_angle:
        a0 = math.atan2(vl[0].imag, vl[0].real)
        for k in range(n):
            dl[k] = math.atan2(vl[k].imag, vl[k].real) - a0
    v0 = vm[0]
    xl = vm / v0
    n_m = motors.shape[0]
    f_s = shares[shares.size - 1]
    col_p = f_s * (a_p[0] * xl * xl + a_p[1] * xl + a_p[2])
    col_qp = np.zeros(n)
    y2p = complex(f_s / (v0 * v0), 0.0)
    pm = np.empty(n)
    qm = np.empty(n)
    states = np.empty((3, n))
    # Window means across a gap (rows left out): the voltage steps at its middle.
    ta, va, da, real = knots_of(t, vm, dl, gap, steps, window_s)
    for j in range(n_m):
        m = motors[j]
        if window_s > 0.0:
            ok = integrate_window_into(ta, va, da, real, window_s, m[0], m[1], m[2], m[3],
                                       m[4], m[5], m[6], m[7], m[8], m[9], m[10], pm,
                                       qm)  # fmt: skip
        else:
            ok = integrate_into(t, vm, dl, m[0], m[1], m[2], m[3], m[4], m[5], m[6], m[7],
                                m[8], m[9], m[10], pm, qm, states)  # fmt: skip
        if not ok or not (pm[0] != 0.0):
            return False
        fj = shares[j]
        for k in range(n):
            col_p[k] += fj * pm[k] / pm[0]
            col_qp[k] += fj * (qm[k] - qm[0] * xl[k] * xl[k]) / pm[0]
        # The negative-sequence admittance at slip 2 - s (parts.motor_y2) and the capacitor.
        xo = m[1] + m[2]
        xmag = math.sqrt(xo * m[2])
        xs = xo - xmag
        rr = xo / (m[5] * m[3])
        rotor = complex(rr / 2.0, xs)
        z2 = complex(m[0], xs) + (1j * xmag * rotor) / (rotor + 1j * xmag)
        y2p += fj / pm[0] * (1.0 / z2 + 1j * qm[0] / (v0 * v0))
    j = n_m
    if d_on:
        dp = d_params
        pd, qd = _motor_d(t, vm, dp[0], dp[1], dp[2], dp[3], dp[4], dp[5], dp[6], dp[7],
                          dp[8], dp[9], dp[10], dp[11], dp[12], dp[13], dp[14], dp[15],
                          dp[16])  # fmt: skip
        fj = shares[j]
        for k in range(n):
            col_p[k] += fj * pd[k] / pd[0]
            col_qp[k] += fj * (qd[k] - qd[0] * xl[k] * xl[k]) / pd[0]
        y2p += fj / (v0 * v0)
        j += 1
    if el_on:
        fj = shares[j]
        low = 1.0
        for k in range(n):
            ramp = min(max((vm[k] - vd2) / (vd1 - vd2), 0.0), 1.0)
            low = min(low, ramp)
            col_p[k] += fj * (low + frcel * (ramp - low))
    ztz[:] = 0.0
    zty[:] = 0.0
    yty[:] = 0.0
    nn[:] = 0.0
    row = np.zeros(4)
    for k in range(n):
        if abs(col_p[k]) > 1e6 or abs(col_qp[k]) > 1e6:
            return False
        # P: [col_p, 0, 0, 0]
        ztz[0, 0, 0] += col_p[k] * col_p[k]
        zty[0, 0] += col_p[k] * pl[k]
        yty[0] += pl[k] * pl[k]
        nn[0] += 1.0
        # Q: [col_qp, x^2, x, 1]
        row[0], row[1], row[2], row[3] = col_qp[k], xl[k] * xl[k], xl[k], 1.0
        for a in range(4):
            zty[1, a] += row[a] * ql[k]
            for b in range(4):
                ztz[1, a, b] += row[a] * row[b]
        yty[1] += ql[k] * ql[k]
        nn[1] += 1.0
    if ar:
        _ar_moments_into(col_p, col_qp, xl, pl, ql, gap, mzz, mzy, myy)
    if ns_on:
        for k in range(n):
            if not i2_rows[k]:
                continue
            v2l = v2[k] - zc * i2[k]
            c1 = v2l * y2p
            c2 = v2l * (-1j / (v0 * v0))
            for part in range(2):
                if part == 0:
                    row[0], row[1], row[2], row[3] = c1.real, c2.real, c2.real, c2.real
                    y = i2[k].real
                else:
                    row[0], row[1], row[2], row[3] = c1.imag, c2.imag, c2.imag, c2.imag
                    y = i2[k].imag
                for a in range(4):
                    zty[2, a] += row[a] * y
                    for b in range(4):
                        ztz[2, a, b] += row[a] * row[b]
                yty[2] += y * y
                nn[2] += 1.0
    for g in range(ztz.shape[0]):
        for a in range(4):
            if not math.isfinite(zty[g, a]):
                return False
    return True


@numba.njit(cache=True, nogil=True)
def _ar_moments_into(col_p, col_qp, xl, pl, ql, gap, mzz, mzy, myy):  # pragma: no cover
    # P's and Q's rows as in event_sums; a segment starts at row 0 and after each gap.
    mzz[:] = 0.0
    mzy[:] = 0.0
    myy[:] = 0.0
    zc = np.zeros((2, 4))
    zl = np.zeros((2, 4))
    yc = np.zeros(2)
    yl = np.zeros(2)
    for k in range(col_p.size):
        zc[0, 0] = col_p[k]
        zc[1, 0], zc[1, 1], zc[1, 2], zc[1, 3] = col_qp[k], xl[k] * xl[k], xl[k], 1.0
        yc[0], yc[1] = pl[k], ql[k]
        first = k == 0 or gap[k - 1]
        for g in range(2):
            if first:
                for a in range(4):
                    mzy[g, 3, a] += zc[g, a] * yc[g]
                    for b in range(4):
                        mzz[g, 3, a, b] += zc[g, a] * zc[g, b]
                myy[g, 3] += yc[g] * yc[g]
            else:
                for a in range(4):
                    mzy[g, 0, a] += zc[g, a] * yc[g]
                    mzy[g, 1, a] += zc[g, a] * yl[g] + zl[g, a] * yc[g]
                    mzy[g, 2, a] += zl[g, a] * yl[g]
                    for b in range(4):
                        mzz[g, 0, a, b] += zc[g, a] * zc[g, b]
                        mzz[g, 1, a, b] += zc[g, a] * zl[g, b] + zl[g, a] * zc[g, b]
                        mzz[g, 2, a, b] += zl[g, a] * zl[g, b]
                myy[g, 0] += yc[g] * yc[g]
                myy[g, 1] += 2.0 * yc[g] * yl[g]
                myy[g, 2] += yl[g] * yl[g]
            for a in range(4):
                zl[g, a] = zc[g, a]
            yl[g] = yc[g]


@numba.njit(cache=True, nogil=True)
def knots_of(t, vm, dl, gap, steps, window_s):  # pragma: no cover - compiled
    """The drive of window means across gaps: ``(ta, va, da, real)`` (``parts.step_knots``).

    Each gap (rows left out, ``gap[k]`` between rows k and k + 1) gets two knots 1 us
    either side of its step instant (``steps[k]``, else the gap's middle), where the
    voltage steps from row k's value to row k + 1's; ``real`` gives each row's position.
    Without a window (point samples) no knots are added.
    """
    n = t.size
    n_gap = 0
    if window_s > 0.0:
        for k in range(n - 1):
            if gap[k]:
                n_gap += 1
    ta = np.empty(n + 2 * n_gap)
    va = np.empty(n + 2 * n_gap)
    da = np.empty(n + 2 * n_gap)
    real = np.empty(n, dtype=np.int64)
    pos = 0
    for k in range(n):
        real[k] = pos
        ta[pos], va[pos], da[pos] = t[k], vm[k], dl[k]
        pos += 1
        if n_gap > 0 and k + 1 < n and gap[k]:
            mid = steps[k] if math.isfinite(steps[k]) else 0.5 * (t[k] + t[k + 1])
            ta[pos], va[pos], da[pos] = mid - 1e-6, vm[k], dl[k]
            ta[pos + 1], va[pos + 1], da[pos + 1] = mid + 1e-6, vm[k + 1], dl[k + 1]
            pos += 2
    return ta, va, da, real


def model_sums(model, event, theta, ar=False):
    """:func:`event_sums` for a ``PartsModel`` at ``theta``: ``(ztz, zty, yty, n)`` or None.

    With ``ar``, ``((ztz, zty, yty, n), (mzz, mzy, myy, segments))``: P's and Q's AR(1)
    sums beside them (``inference.ar1.ar_moments``' stacks, one per channel).
    """
    fixed = _fixed_of(model, event)
    c = model._split(np.asarray(theta, dtype=float))
    x_fd = model.feeder_x(fixed[4][0], fixed[5][0], c)  # the first kept row's P, Q
    wb = 2.0 * math.pi * model.f_hz
    motors = np.empty((len(model.motors), 11))
    for j, (m, logs) in enumerate(zip(model.motors, c["motors"], strict=True)):
        rs, xp, dx, tp, h, t0 = np.exp(logs)
        a, b, cc = MOTOR_CLASSES[m]["torque"]
        motors[j] = (rs, xp, dx, tp, h, wb, t0, a, b, cc, min(H_MAX_S, tp / TP_STEPS))
    g = len(model.channel_names)
    ztz, zty, yty, nn = np.empty((g, 4, 4)), np.empty((g, 4)), np.empty(g), np.empty(g)
    moments = ((np.empty((2, 4, 4, 4)), np.empty((2, 4, 4)), np.empty((2, 4))) if ar
               else _NO_MOMENTS)  # fmt: skip
    params = {**MOTOR_D_DEFAULTS, **model.motor_d_params, "vstall": float(c["vstall"]),
              "tstall": float(c["tstall"])}  # fmt: skip
    d_params = np.array([float(params[k]) for k in MOTOR_D_DEFAULTS])
    ok = event_sums(*fixed, model.rx * x_fd, x_fd, motors, float(model.window_s),
                    np.ascontiguousarray(c["f"]), np.ascontiguousarray(c["a_p"]),
                    model.motor_d, d_params, model.electronics, float(c["vd1"]),
                    float(c["vd2"]), float(model.frcel), g == 3 and bool(fixed[10].any()),
                    ztz, zty, yty, nn, ar, *moments)  # fmt: skip
    if not ok:
        return None
    if not ar:
        return ztz, zty, yty, nn
    segments = 1.0 + float(np.count_nonzero(fixed[6][:-1]))
    return (ztz, zty, yty, nn), (*moments, segments)


#: The AR(1) sums' arguments of the white-noise kernel call (not read).
_NO_MOMENTS = (np.zeros((2, 4, 4, 4)), np.zeros((2, 4, 4)), np.zeros((2, 4)))


def _fixed_of(model, event) -> tuple:
    # The event's arrays the kernel reads, once per event (kept on the model).
    key = (id(event), event.n)
    if key not in model._fixed:
        keep, steps = model.drive_of(event)
        if keep.size < event.n:  # as channels: the rows left out make a gap
            event = event.take(keep)
        n = event.n
        ns = model.negative_sequence != "off" and model.uses_negative_sequence(event)
        v2 = np.zeros(n, complex) if not ns else np.asarray(event.v2, dtype=complex)
        i2 = np.zeros(n, complex) if not ns else np.asarray(event.i2, dtype=complex)
        rows = (np.abs(v2) >= NEG_SEQ_MIN) if ns else np.zeros(n, dtype=bool)
        delta = np.zeros(n) if event.delta is None else np.asarray(event.delta, float)
        model._fixed[key] = (
            np.ascontiguousarray(event.t, float), np.ascontiguousarray(event.v, float),
            np.ascontiguousarray(delta), event.delta is not None,
            np.ascontiguousarray(event.p, float), np.ascontiguousarray(event.q, float),
            gaps_of(event.t, steps), np.ascontiguousarray(steps, float), v2, i2, rows,
        )  # fmt: skip
    return model._fixed[key]
