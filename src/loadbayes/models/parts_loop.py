"""The compiled pieces of one draw's feeder loop that ``parts_play._relax`` calls.

NumPy's complex division (the reference's rounding), the motors' braking drive through
the feeder (``parts_predict.brake_of``), and :func:`pv_root`: the load bus's voltage at
one sample solved jointly with what the load draws there, as a simulator's step solves
its network. Waveform relaxation alone (``V_L <- V - Z I(V_L)``, whole waveforms) moves
``V_L`` by ``|Z dI/dV_L|`` times its error each sweep; where a draw's static Q,
extrapolated, swings by hundreds of times its pre-fault value across the sag
(``tests/statistical/test_parts_stall_threshold.py``'s shallow fit: shares like -1350,
2484, -1133 of ``x^2, x, 1``), that factor is far above one and the sweeps run off
although the loop has a solution. :func:`pv_root` solves the static part's voltage
dependence exactly at each sample, the rest (motors, motor D, electronics: what the
sweep's trajectory decided) held as a constant impedance at that sample, so the sweeps
only carry the dynamic parts' lag. Where that equation has no root near the sweep's
voltage the load's P-V nose lies below what the feeder can carry at that sample: a
collapse, not a numerical failure (``parts_play.COLLAPSES``).

What was left failing (the shallow fit at a 44 % sag: 15 of 100, traced on 4; the tests'
cmld-lite fit, ``cmld_lite_nc``: 3 of 150 draws at 70 % and 3 at 80 %): the solved
sweeps do settle, at trajectories that :func:`continues` rejects, the load bus jumping
between two operating points of the draw's static Q from one sample to the next. Ten
times the sweeps did not help. ``parts_march`` now solves those draws step by step in
time (each sample from the last, the motors integrated with it, as a simulator does),
which picks one: on ``cmld_lite_nc`` the 6 play or collapse (5 play, 1 reaches the nose
at 80 %), none fails; and one draw at 80 % that the sweeps had called a collapse (a
sweep drove ``V_L`` to 0.036 of ``V``, none settled) plays when marched (its load bus
never below 0.80 of ``V``). Whole-waveform sweeps started from the previous sample's
root settled fewer (see :func:`pv_root`).
"""

from __future__ import annotations

import math

import numba
import numpy as np

from loadbayes.models.motor_kernel import steady_state
from loadbayes.models.parts import NEG_SEQ_MIN, _motor_d
from loadbayes.models.parts_kernel import motor_drive, motor_into

__all__ = [
    "CONTINUES",
    "PV_STEPS",
    "PV_TOL",
    "RAMP_STEPS",
    "SCAN",
    "SCAN_TOP",
    "SOLVE_SWEEPS",
    "brake_of",
    "cdiv",
    "columns",
    "continues",
    "pv_root",
]

#: Sweeps of a loop's third try (``parts_play._relax`` with ``solve``): each sample's
#: load bus by :func:`pv_root`, where the plain and the damped sweeps did not settle.
SOLVE_SWEEPS = 100

#: Newton steps of :func:`pv_root` (from the sweep's voltage it takes 3-8) and its
#: stopping rule on ``|V_L|`` (relative).
PV_STEPS = 60
PV_TOL = 1e-13
#: A solved loop's root at a sample must be within this share of the one Newton reaches
#: from the previous sample's root (:func:`continues`).
CONTINUES = 1e-6
#: ... carried there from the previous sample's along this many steps of ``|V|``.
RAMP_STEPS = 16
#: Where Newton fails, ``h``'s sign is read at SCAN points up to SCAN_TOP times the
#: larger of ``|V|``, the sweep's ``|V_L|`` and 1 (a root above that would need the
#: load to lift its own bus to four times the source's).
SCAN = 400
SCAN_TOP = 4.0


@numba.njit(cache=True, nogil=True)
def cdiv(a, b):  # pragma: no cover - compiled
    """NumPy's complex division (its divide loop, Smith's rule): the reference's rounding."""
    br, bi = b.real, b.imag
    if abs(br) >= abs(bi):
        if br == 0.0 and bi == 0.0:
            return complex(a.real / abs(br), a.imag / abs(br))
        rat = bi / br
        scl = 1.0 / (br + bi * rat)
        return complex((a.real + a.imag * rat) * scl, (a.imag - a.real * rat) * scl)
    rat = br / bi
    scl = 1.0 / (bi + br * rat)
    return complex((a.real * rat + a.imag) * scl, (a.imag * rat - a.real) * scl)


@numba.njit(cache=True, nogil=True)
def pv_root(m, mk, vabs, zc, dd, ap0, ap1, ap2, aq0, aq1, aq2, m0):  # pragma: no cover - compiled
    """``|V_L|`` at one sample, Newton from ``m``; NaN where no root is found.

    ``V_L = V - Z conj(S(|V_L|) / V_L)`` times ``conj(V_L)`` gives ``conj(V_L) = (m^2 +
    Z conj(S(m))) / V``, so ``|V_L| = m`` is the real equation ``h(m) = |m^2 + conj(Z)
    S(m)| - m |V| = 0`` (``zc = conj(Z)``), the P-V curve's; ``S(m) = dd (m / m_k)^2 +
    P_s(x) + j Q_s(x)``, ``x = m / m0``, with ``dd`` the rest of the load's S at the
    sweep's ``m_k`` and ``P_s = ap0 x^2 + ap1 x + ap2``, ``Q_s`` likewise. Newton from
    ``m`` (``parts_play._relax`` gives the sweep's own ``m_k``: started from the previous
    sample's root instead, as a simulator's step would, the sweeps settled fewer of the
    stalling load's shallow-fit draws: 16 and 42 of 100 failed at 36 % and 44 % sags,
    against 1 and 1); where it fails, the sign change of ``h`` nearest ``m`` on a grid
    (:data:`SCAN` points), bisected; NaN where ``h`` has none: no root.
    ``parts_predict._pv_root`` is the same in NumPy.
    """
    start, mk2 = m, mk * mk
    for _ in range(PV_STEPS):
        x = m / m0
        s = dd * (m * m / mk2) + complex(ap0 * x * x + ap1 * x + ap2, aq0 * x * x + aq1 * x + aq2)
        ds = dd * (2.0 * m / mk2) + complex((2.0 * ap0 * x + ap1) / m0, (2.0 * aq0 * x + aq1) / m0)
        w = m * m + zc * s
        dw = 2.0 * m + zc * ds
        aw = abs(w)
        if aw == 0.0:
            break
        dh = (w.real * dw.real + w.imag * dw.imag) / aw - vabs
        if dh == 0.0:  # the nose itself
            break
        step = (aw - m * vabs) / dh
        if not math.isfinite(step):
            break
        new = m - step
        if new <= 0.0:  # not below zero: halve towards it
            new = 0.5 * m
        if abs(new - m) <= PV_TOL * m:
            return new
        m = new
    return _scan(start, vabs, zc, dd, ap0, ap1, ap2, aq0, aq1, aq2, m0, mk2)


@numba.njit(cache=True, nogil=True)
def _h(m, vabs, zc, dd, ap0, ap1, ap2, aq0, aq1, aq2, m0, mk2):  # pragma: no cover - compiled
    x = m / m0
    s = dd * (m * m / mk2) + complex(ap0 * x * x + ap1 * x + ap2, aq0 * x * x + aq1 * x + aq2)
    return abs(m * m + zc * s) - m * vabs


@numba.njit(cache=True, nogil=True)
def _scan(mk, vabs, zc, dd, ap0, ap1, ap2, aq0, aq1, aq2, m0, mk2):  # pragma: no cover - compiled
    # Where Newton fails: h's sign on SCAN points of (0, SCAN_TOP max(|V|, mk, 1)], the
    # change nearest mk (Newton's start) bisected; NaN where h keeps one sign (no root).
    top = SCAN_TOP * max(vabs, mk, 1.0)
    best, lo, hi = math.inf, math.nan, math.nan
    prev = _h(top / SCAN, vabs, zc, dd, ap0, ap1, ap2, aq0, aq1, aq2, m0, mk2)
    for j in range(2, SCAN + 1):
        a, b = top * (j - 1) / SCAN, top * j / SCAN
        hb = _h(b, vabs, zc, dd, ap0, ap1, ap2, aq0, aq1, aq2, m0, mk2)
        if (prev <= 0.0) != (hb <= 0.0) and abs(0.5 * (a + b) - mk) < best:
            best, lo, hi = abs(0.5 * (a + b) - mk), a, b
        prev = hb
    if not math.isfinite(best):
        return math.nan
    h_lo = _h(lo, vabs, zc, dd, ap0, ap1, ap2, aq0, aq1, aq2, m0, mk2)
    for _ in range(100):
        mid = 0.5 * (lo + hi)
        if hi - lo <= PV_TOL * mid:
            break
        h_mid = _h(mid, vabs, zc, dd, ap0, ap1, ap2, aq0, aq1, aq2, m0, mk2)
        if (h_mid <= 0.0) == (h_lo <= 0.0):
            lo, h_lo = mid, h_mid
        else:
            hi = mid
    return 0.5 * (lo + hi)


@numba.njit(cache=True, nogil=True)
def continues(v, vm, ddv, root, z, ap0, ap1, ap2, aq0, aq1, aq2, m0):  # pragma: no cover
    """Whether a solved loop's roots are each the one a simulator's step reaches.

    ``root``: each sample's ``|V_L|`` (``ddv`` its dynamic part, ``vm`` the sweep's).
    """
    # A solved loop's roots, each the one Newton reaches from the previous sample's (as a
    # simulator's step from the last): False where the trajectory jumps between two
    # operating points of the load from one sample to the next with nothing to move it.
    # Across a step of |V| the root is carried along a ramp of RAMP_STEPS (the step is
    # fast, not instantaneous).
    for k in range(1, v.size):
        if math.isfinite(root[k]) and math.isfinite(root[k - 1]):
            r, a, b = root[k - 1], abs(v[k - 1]), abs(v[k])
            for i in range(1, RAMP_STEPS + 1):
                r = pv_root(r, vm[k], a + (b - a) * i / RAMP_STEPS, z.conjugate(), ddv[k],
                            ap0, ap1, ap2, aq0, aq1, aq2, m0)  # fmt: skip
            if not abs(r - root[k]) <= CONTINUES * root[k]:
                return False
    return True


@numba.njit(cache=True, nogil=True)
def brake_of(v, v2, z, s0, motors, shares, d_on):  # pragma: no cover - compiled
    """``parts_predict.brake_of``: ``|V2_L| = |V2 / (1 + Z Y2)|`` where ``|V2| >= NEG_SEQ_MIN``.

    ``Y2`` the load's negative-sequence admittance at its operating point (as the I2
    channel's); empty without V2, NaNs where a motor has no steady state.
    """
    n_b = 0
    for k in range(v2.size):
        if abs(v2[k]) >= NEG_SEQ_MIN:
            n_b += 1
    if n_b == 0:
        return np.zeros(0)
    i0 = cdiv(s0, v[0]).conjugate()
    s_l0 = s0 - z * abs(i0) ** 2
    v0 = abs(v[0] - z * i0)
    y2p = complex(shares[shares.size - 1] / (v0 * v0), 0.0)
    for j in range(motors.shape[0]):
        m = motors[j]
        pm0, qm0 = steady_state(m[0], m[1], m[2], m[3], m[5], v0, m[6], m[7], m[8], m[9])[3:]
        if not math.isfinite(pm0):  # no steady state: the draw fails
            return np.full(v2.size, math.nan)
        xo = m[1] + m[2]
        xmag = math.sqrt(xo * m[2])
        xs = xo - xmag
        rotor = complex(xo / (m[5] * m[3]) / 2.0, xs)
        z2 = complex(m[0], xs) + cdiv(1j * xmag * rotor, rotor + 1j * xmag)
        y2p += shares[j] / pm0 * (cdiv(1.0 + 0j, z2) + 1j * qm0 / (v0 * v0))
    if d_on:
        y2p += shares[motors.shape[0]] / (v0 * v0)
    y2 = s_l0.real * y2p - 1j * s_l0.imag / (v0 * v0)
    den = 1.0 + z * y2
    u2 = np.zeros(v2.size)
    for k in range(v2.size):
        if abs(v2[k]) >= NEG_SEQ_MIN:
            u2[k] = abs(cdiv(v2[k], den))
    return u2


@numba.njit(cache=True, nogil=True)
def columns(t, vm, dl, u2, gap, steps, window_s, motors, shares, a_p, d_on, dp, el_on, vd1,
             vd2, frcel, col_p, col_qp, pm, qm, states):  # pragma: no cover - compiled  # fmt: skip
    """``PartsModel.load_columns`` at the load bus: P's column on ``p0`` and Q's.

    ``vm, dl``: ``|V_L|`` and its angle from the first sample; ``u2`` the motors' braking
    drive, empty for none. False where a motor has no steady state. One sweep of
    ``parts_play._relax``, and the window means ``parts_march.marched`` reads.
    """
    n = t.size
    v0 = vm[0]
    f_s = shares[shares.size - 1]
    for k in range(n):
        xl = vm[k] / v0
        col_p[k] = f_s * (a_p[0] * xl * xl + a_p[1] * xl + a_p[2])
        col_qp[k] = 0.0
    drive = motor_drive(t, vm, dl, u2, gap, steps, window_s)  # parts.step_knots
    for j in range(motors.shape[0]):
        if not motor_into(motors[j], t, vm, dl, u2, drive, window_s, pm, qm, states):
            return False
        fj = shares[j]
        for k in range(n):
            xl = vm[k] / v0
            col_p[k] += fj * pm[k] / pm[0]
            col_qp[k] += fj * (qm[k] - qm[0] * xl * xl) / pm[0]
    j = motors.shape[0]
    if d_on:
        pd, qd = _motor_d(t, vm, dp[0], dp[1], dp[2], dp[3], dp[4], dp[5], dp[6], dp[7],
                          dp[8], dp[9], dp[10], dp[11], dp[12], dp[13], dp[14], dp[15],
                          dp[16])  # fmt: skip
        fj = shares[j]
        for k in range(n):
            xl = vm[k] / v0
            col_p[k] += fj * pd[k] / pd[0]
            col_qp[k] += fj * (qd[k] - qd[0] * xl * xl) / pd[0]
        j += 1
    if el_on:
        fj = shares[j]
        low = 1.0
        for k in range(n):
            ramp = min(max((vm[k] - vd2) / (vd1 - vd2), 0.0), 1.0)
            low = min(low, ramp)
            col_p[k] += fj * (low + frcel * (ramp - low))
    return True
