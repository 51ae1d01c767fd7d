"""The sums a model of parts' likelihood needs, for one event, in two compiled calls.

One idea needs these lines: one event's parts solved once (:func:`event_parts`) and
summed two ways, at given shares (:func:`event_sums`) or as the shares' basis
(:func:`event_basis`), with the AR(1) stacks of each. ``parts_sums.py`` calls them, and
keeps each solve for the states that share it (the shares' steps read the block move's).

:meth:`PartsModel.channels <loadbayes.models.parts_model.PartsModel.channels>` builds
each channel's design and target in NumPy (the NLS start and the tests read those);
the sampler needs only their sums ``Z'Z, Z'y, y'y`` per channel, at every proposal.
:func:`event_parts` and :func:`event_sums` compute them in ``numba``: the load bus through the
recorded current (``parts.load_bus``), every motor (``motor_kernel``'s integrators, at
the samples or as window means, braked by the load bus's ``|V2 - Z I2|`` where the event
has V2 rows, ``parts.brake_drive``), motor D (``parts._motor_d``), the electronics, the
static part, and the negative-sequence rows; the same arithmetic as ``channels``, which
``tests/unit/test_parts_kernel.py`` checks to 1e-9 on random draws. About a tenth of the
NumPy path's cost (measured on ``cmld-lite`` with two 0.6 s events at 60/s). The motor
loop (:func:`motor_drive`, :func:`motor_into`) is the one ``parts_play`` runs in each of
a prediction's sweeps.

**The shares' basis.** Given everything but the shares, each part's response is fixed
(the load bus comes from the recorded current), and every channel's design is linear
in the weights ``w = (f_1, ..., f_K, f_s a1, f_s a2, f_s a3)`` (the dynamic parts'
shares, then the static part's Z, I, P shares of the load's P): ``Z_g = B_g W(w)`` with
``W = [[w, 0], [0, I_3]]`` and ``B_g`` (n_g, K + 6) the channel's basis: one column per
weight (each part's own response, normalised as the design normalises it) and three
fixed columns (Q's ``x^2, x, 1``; the negative-sequence current's ``-j V2_L / V_L(0)^2``
three times; P's none, zeros). :func:`event_basis` returns the basis' sums ``B'B, B'y,
y'y`` (and P's and Q's AR(1) stacks of them), so the sums at any shares are
``W'(B'B)W, W'(B'y), y'y`` with no motor solve (``fit/composite/shares.py``). Both
kernels read the parts' responses from one function, :func:`event_parts`.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from loadbayes.models.motor_kernel import (
    integrate_v2_into,
    integrate_window_v2_into,
)
from loadbayes.models.parts import NEG_SEQ_MIN, _motor_d

__all__ = [
    "event_basis",
    "event_parts",
    "event_sums",
    "knots_of",
    "motor_drive",
    "motor_into",
]


@numba.njit(cache=True, nogil=True)
def motor_drive(t, vm, dl, u2, gap, steps, window_s):  # pragma: no cover - compiled
    """The motors' input: ``(ta, va, da, ua, real)``, the knots across gaps (:func:`knots_of`).

    ``u2``: the braking drive ``|V2_L|`` at the samples (``parts.brake_drive``; empty:
    none), stepped across the gaps as V is.
    """
    ta, va, da, real = knots_of(t, vm, dl, gap, steps, window_s)
    ua = u2
    if u2.size > 0 and window_s > 0.0:
        ua = knots_of(t, u2, dl, gap, steps, window_s)[1]
    return ta, va, da, ua, real


@numba.njit(cache=True, nogil=True)
def motor_into(m, t, vm, dl, u2, drive, window_s, pm, qm, states):  # pragma: no cover
    """One motor (``m``: its 11 constants, :func:`event_sums`) through the load bus.

    The one motor loop of the likelihood's sums and of a prediction's sweeps
    (``parts_play``): window means over ``drive`` (:func:`motor_drive`) or the values
    at the samples ``(t, vm, dl)``, the braking torque driven by ``u2`` (at the samples)
    or ``drive[3]`` (at the knots). Writes ``pm``, ``qm``; False where it has no steady
    state or leaves the finite numbers.
    """
    # Without a drive the integrators get None: the braking compiled out (motor_kernel).
    if window_s > 0.0:
        ta, va, da, ua, real = drive
        if ua.size == 0:
            return integrate_window_v2_into(ta, va, da, None, real, window_s, m[0], m[1], m[2],
                                            m[3], m[4], m[5], m[6], m[7], m[8], m[9], m[10], pm,
                                            qm)  # fmt: skip
        return integrate_window_v2_into(ta, va, da, ua, real, window_s, m[0], m[1], m[2], m[3],
                                        m[4], m[5], m[6], m[7], m[8], m[9], m[10], pm,
                                        qm)  # fmt: skip
    if u2.size == 0:
        return integrate_v2_into(t, vm, dl, None, m[0], m[1], m[2], m[3], m[4], m[5], m[6], m[7],
                                 m[8], m[9], m[10], pm, qm, states)  # fmt: skip
    return integrate_v2_into(t, vm, dl, u2, m[0], m[1], m[2], m[3], m[4], m[5], m[6], m[7],
                             m[8], m[9], m[10], pm, qm, states)  # fmt: skip


@numba.njit(cache=True, nogil=True)
def event_parts(t, v, delta, has_angle, p, q, gap, steps, v2, i2, r, x, motors, window_s, d_on,
              d_params, el_on, vd1, vd2, frcel):  # pragma: no cover - compiled  # fmt: skip
    """Every part's own response at the load bus, for one event: no share enters here.

    Returns ``(ok, vm, xl, pl, ql, pr, qr, yraw)``: the load bus's voltage and its ratio
    to the first sample; the load's P and Q (the feeder's losses taken out); each dynamic
    part's P and Q (rows: the motors, motor D, the electronics' connected share with Q
    0); each motor's negative-sequence admittance at slip ``2 - s`` with its capacitor,
    per unit of its first P (``parts.motor_y2``). ``ok`` is False where a motor has no
    steady state. The motors brake with ``|V2 - Z I2|`` at the rows ``|V2| >=
    NEG_SEQ_MIN`` (``parts.brake_drive``; none: the balanced arithmetic).
    """
    n = t.size
    zc = complex(r, x)
    n_b = 0
    for k in range(n):
        if abs(v2[k]) >= NEG_SEQ_MIN:
            n_b += 1
    u2 = np.zeros(n if n_b > 0 else 0)
    if n_b > 0:
        for k in range(n):
            if abs(v2[k]) >= NEG_SEQ_MIN:
                u2[k] = abs(v2[k] - zc * i2[k])
    vm = np.empty(n)
    dl = np.zeros(n)
    pl = np.empty(n)
    ql = np.empty(n)
    a0 = 0.0
    for k in range(n):
        vk = v[k] * complex(math.cos(delta[k]), math.sin(delta[k]))
        cur = ((p[k] + 1j * q[k]) / vk).conjugate()
        vl = vk - zc * cur
        i2k = cur.real * cur.real + cur.imag * cur.imag
        pl[k] = p[k] - r * i2k
        ql[k] = q[k] - x * i2k
        vm[k] = abs(vl)
        if has_angle:
            if k == 0:
                a0 = math.atan2(vl.imag, vl.real)
            dl[k] = math.atan2(vl.imag, vl.real) - a0
    v0 = vm[0]
    xl = vm / v0
    n_m = motors.shape[0]
    n_dyn = n_m + (1 if d_on else 0) + (1 if el_on else 0)
    pr = np.zeros((n_dyn, n))
    qr = np.zeros((n_dyn, n))
    yraw = np.zeros(n_dyn, dtype=np.complex128)
    states = np.empty((3, n))
    # Window means across a gap (rows left out): the voltage steps at its middle.
    drive = motor_drive(t, vm, dl, u2, gap, steps, window_s)
    for j in range(n_m):
        m = motors[j]
        pm = pr[j]
        qm = qr[j]
        ok = motor_into(m, t, vm, dl, u2, drive, window_s, pm, qm, states)
        if not ok or not (pm[0] != 0.0):
            return False, vm, xl, pl, ql, pr, qr, yraw
        # The negative-sequence admittance at slip 2 - s (parts.motor_y2) and the capacitor.
        xo = m[1] + m[2]
        xmag = math.sqrt(xo * m[2])
        xs = xo - xmag
        rr = xo / (m[5] * m[3])
        rotor = complex(rr / 2.0, xs)
        z2 = complex(m[0], xs) + (1j * xmag * rotor) / (rotor + 1j * xmag)
        yraw[j] = 1.0 / z2 + 1j * qm[0] / (v0 * v0)
    j = n_m
    if d_on:
        dp = d_params
        pd, qd = _motor_d(t, vm, dp[0], dp[1], dp[2], dp[3], dp[4], dp[5], dp[6], dp[7],
                          dp[8], dp[9], dp[10], dp[11], dp[12], dp[13], dp[14], dp[15],
                          dp[16])  # fmt: skip
        pr[j] = pd
        qr[j] = qd
        j += 1
    if el_on:
        low = 1.0
        for k in range(n):
            ramp = min(max((vm[k] - vd2) / (vd1 - vd2), 0.0), 1.0)
            low = min(low, ramp)
            pr[j, k] = low + frcel * (ramp - low)
    return True, vm, xl, pl, ql, pr, qr, yraw


@numba.njit(cache=True, nogil=True)
def event_sums(solved, gap, v2, i2, i2_rows, r, x, n_m, d_on, shares, a_p, ns_on, ztz, zty, yty,
               nn, ar, mzz, mzy, myy):  # pragma: no cover - compiled  # fmt: skip
    """Fill ``ztz (G, 4, 4)``, ``zty (G, 4)``, ``yty (G,)``, ``nn (G,)``; False if infeasible.

    ``solved``: :func:`event_parts`' parts (its ``ok`` True), ``n_m`` the motors' count;
    ``shares`` the parts' shares of P (motors, then motor D, then electronics, the static
    part last); ``a_p`` the static P's Z, I, P split; ``v2, i2`` the event's (zeros
    without); ``i2_rows`` the I2 channel's rows (none where it is off).
    """
    vm, xl, pl, ql, pr, qr, yraw = solved
    n = vm.size
    zc = complex(r, x)
    v0 = vm[0]
    n_q = n_m + (1 if d_on else 0)  # the parts with a Q of their own
    f_s = shares[shares.size - 1]
    col_p = f_s * (a_p[0] * xl * xl + a_p[1] * xl + a_p[2])
    col_qp = np.zeros(n)
    y2p = complex(f_s / (v0 * v0), 0.0)
    for j in range(pr.shape[0]):
        fj = shares[j]
        if j >= n_q:  # the electronics: their connected share, no Q
            for k in range(n):
                col_p[k] += fj * pr[j, k]
            continue
        for k in range(n):
            col_p[k] += fj * pr[j, k] / pr[j, 0]
            col_qp[k] += fj * (qr[j, k] - qr[j, 0] * xl[k] * xl[k]) / pr[j, 0]
        if j < n_m:
            y2p += fj / pr[j, 0] * yraw[j]
        else:  # motor D: the constant impedance of its operating point
            y2p += fj / (v0 * v0)
    ztz[:] = 0.0
    zty[:] = 0.0
    yty[:] = 0.0
    nn[:] = 0.0
    z = np.zeros((2, n, 4))  # P's rows [col_p, 0, 0, 0], Q's [col_qp, x^2, x, 1]
    for k in range(n):
        if abs(col_p[k]) > 1e6 or abs(col_qp[k]) > 1e6:
            return False
        z[0, k, 0] = col_p[k]
        z[1, k, 0], z[1, k, 1], z[1, k, 2], z[1, k, 3] = col_qp[k], xl[k] * xl[k], xl[k], 1.0
    y = np.empty((2, n))
    y[0], y[1] = pl, ql
    _gram_into(z, y, ztz, zty, yty, nn)
    if ar:
        _ar_moments_into(z, y, gap, mzz, mzy, myy)
    if ns_on:
        row = np.zeros(4)
        for k in range(n):
            if not i2_rows[k]:
                continue
            v2l = v2[k] - zc * i2[k]
            c1 = v2l * y2p
            c2 = v2l * (-1j / (v0 * v0))
            for part in range(2):
                if part == 0:
                    row[0], row[1], row[2], row[3] = c1.real, c2.real, c2.real, c2.real
                    yk = i2[k].real
                else:
                    row[0], row[1], row[2], row[3] = c1.imag, c2.imag, c2.imag, c2.imag
                    yk = i2[k].imag
                _add_row(row, yk, ztz[2], zty[2])
                yty[2] += yk * yk
                nn[2] += 1.0
    for g in range(ztz.shape[0]):
        for a in range(4):
            if not math.isfinite(zty[g, a]):
                return False
    return True


@numba.njit(cache=True, nogil=True)
def event_basis(solved, gap, v2, i2, i2_rows, r, x, n_m, d_on, ns_on, bb, by, yy, nn, ar, mbb,
                mby, myy):  # pragma: no cover - compiled  # fmt: skip
    """Fill the shares' basis sums (module docstring); False if infeasible at some shares.

    ``solved``: :func:`event_parts`' parts (its ``ok`` True). ``bb (G, M, M)``, ``by (G,
    M)``, ``yy (G,)``, ``nn (G,)`` with ``M = K + 6`` (the ``K`` dynamic parts, the static
    part's three, three fixed columns); with ``ar``, P's and Q's AR(1) stacks ``mbb (2, 4,
    M, M)``, ``mby (2, 4, M)``, ``myy (2, 4)``. False also where a basis column passes 1e6
    (:func:`event_sums` refuses a column that large: below it every share vector is
    feasible, above it some are not).
    """
    vm, xl, pl, ql, pr, qr, yraw = solved
    n = vm.size
    n_dyn = pr.shape[0]
    n_q = n_m + (1 if d_on else 0)
    m_cols = n_dyn + 6
    zc = complex(r, x)
    v0 = vm[0]
    z = np.zeros((2, n, m_cols))
    for k in range(n):
        for j in range(n_dyn):
            if j < n_q:
                z[0, k, j] = pr[j, k] / pr[j, 0]
                z[1, k, j] = (qr[j, k] - qr[j, 0] * xl[k] * xl[k]) / pr[j, 0]
            else:
                z[0, k, j] = pr[j, k]
        z[0, k, n_dyn], z[0, k, n_dyn + 1], z[0, k, n_dyn + 2] = xl[k] * xl[k], xl[k], 1.0
        z[1, k, n_dyn + 3], z[1, k, n_dyn + 4], z[1, k, n_dyn + 5] = xl[k] * xl[k], xl[k], 1.0
        for c in range(m_cols):
            if abs(z[0, k, c]) > 1e6 or abs(z[1, k, c]) > 1e6:
                return False
    y = np.empty((2, n))
    y[0], y[1] = pl, ql
    bb[:] = 0.0
    by[:] = 0.0
    yy[:] = 0.0
    nn[:] = 0.0
    _gram_into(z, y, bb, by, yy, nn)
    if ar:
        _ar_moments_into(z, y, gap, mbb, mby, myy)
    if ns_on:
        cols = np.zeros(m_cols, dtype=np.complex128)
        row = np.zeros(m_cols)
        for k in range(n):
            if not i2_rows[k]:
                continue
            v2l = v2[k] - zc * i2[k]
            for j in range(n_dyn):
                if j < n_m:
                    cols[j] = v2l * (yraw[j] / pr[j, 0])
                elif j < n_q:
                    cols[j] = v2l / (v0 * v0)
            for c in range(3):
                cols[n_dyn + c] = v2l / (v0 * v0)
                cols[n_dyn + 3 + c] = v2l * (-1j / (v0 * v0))
            for part in range(2):
                for c in range(m_cols):
                    row[c] = cols[c].real if part == 0 else cols[c].imag
                yk = i2[k].real if part == 0 else i2[k].imag
                _add_row(row, yk, bb[2], by[2])
                yy[2] += yk * yk
                nn[2] += 1.0
    for g in range(bb.shape[0]):
        for a in range(m_cols):
            if not math.isfinite(by[g, a]):
                return False
    return True


@numba.njit(cache=True, nogil=True)
def _add_row(row, y, zz, zy):  # pragma: no cover - compiled
    # One row's terms of Z'Z and Z'y.
    for a in range(row.size):
        zy[a] += row[a] * y
        for b in range(row.size):
            zz[a, b] += row[a] * row[b]


@numba.njit(cache=True, nogil=True)
def _gram_into(z, y, zz, zy, yy, nn):  # pragma: no cover - compiled
    # P's and Q's rows (z (2, n, k), y (2, n)) added to groups 0 and 1, row by row.
    for k in range(z.shape[1]):
        for g in range(2):
            _add_row(z[g, k], y[g, k], zz[g], zy[g])
            yy[g] += y[g, k] * y[g, k]
            nn[g] += 1.0


@numba.njit(cache=True, nogil=True)
def _ar_moments_into(z, y, gap, mzz, mzy, myy):  # pragma: no cover - compiled
    # P's and Q's rows z (2, n, k), y (2, n); a segment starts at row 0 and after each gap.
    mzz[:] = 0.0
    mzy[:] = 0.0
    myy[:] = 0.0
    nk = z.shape[2]
    for k in range(z.shape[1]):
        first = k == 0 or gap[k - 1]
        for g in range(2):
            zc, yc = z[g, k], y[g, k]
            if first:
                for a in range(nk):
                    mzy[g, 3, a] += zc[a] * yc
                    for b in range(nk):
                        mzz[g, 3, a, b] += zc[a] * zc[b]
                myy[g, 3] += yc * yc
            else:
                zl, yl = z[g, k - 1], y[g, k - 1]
                for a in range(nk):
                    mzy[g, 0, a] += zc[a] * yc
                    mzy[g, 1, a] += zc[a] * yl + zl[a] * yc
                    mzy[g, 2, a] += zl[a] * yl
                    for b in range(nk):
                        mzz[g, 0, a, b] += zc[a] * zc[b]
                        mzz[g, 1, a, b] += zc[a] * zl[b] + zl[a] * zc[b]
                        mzz[g, 2, a, b] += zl[a] * zl[b]
                myy[g, 0] += yc * yc
                myy[g, 1] += 2.0 * yc * yl
                myy[g, 2] += yl * yl


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
