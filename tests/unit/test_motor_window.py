"""The kernel's window means of P and Q against SciPy (DOP853, dense output, quad)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from scipy.integrate import quad, solve_ivp

from loadbayes.models.motor import currents, derivatives, power
from loadbayes.models.motor_kernel import integrate
from loadbayes.models.motor_library import MOTORS
from turning_start import turning_start

#: Stated accuracy of the window means (docs/composite.md): p.u. on the motor's base.
TOL_PU = 1e-4
#: One cycle at 60 Hz, the default window; 60 samples/s.
W = 1.0 / 60.0


def _fast():
    # T' 0.06 s and a small X' (0.069): krause_3hp with its rotor resistance raised.
    m = MOTORS["krause_3hp"]
    return dataclasses.replace(m, rr=m.rr * m.tp_s / 0.06)


def _input():
    # 60 samples/s; a 36% sag whose fall is a true step at 0.3071 s (inside an interval:
    # two knots 1e-7 s apart, as models/composite_steps.py puts them) and whose recovery
    # is a 20 ms ramp; a slow angle swing.
    t = np.arange(0.0, 1.2, 1 / 60)
    ts, vs = list(t), list(np.where((t >= 0.3071) & (t < 0.5), 0.64, 1.0))
    k = int(np.searchsorted(t, 0.3071))
    ts[k:k] = [0.3071, 0.3071 + 1e-7]
    vs[k:k] = [1.0, 0.64]
    ta, va = np.array(ts), np.array(vs)
    va = np.where((ta >= 0.5) & (ta < 0.52), 0.64 + 0.36 * (ta - 0.5) / 0.02, va)
    real = np.flatnonzero(np.isin(ta, t))
    return ta, va, 0.05 * np.sin(2 * np.pi * 0.8 * ta), real


def _reference(m, t, v, delta, t0, real):
    def u(tt):
        vv, dd = np.interp(tt, t, v), np.interp(tt, t, delta)
        return vv * np.cos(dd), vv * np.sin(dd)

    def rhs(tt, y):
        return derivatives(y, *u(tt), m, t0=t0)

    y0 = turning_start(m, t, v, delta, t0)
    sol = solve_ivp(rhs, (t[0], t[-1] + W), y0, method="DOP853", dense_output=True,
                    rtol=1e-11, atol=1e-13, max_step=1e-3)  # fmt: skip
    assert sol.success
    # Before t[0] the steady state's power (the same whatever the angle).
    i0 = currents(*u(t[0]), y0[0], y0[1], m)
    p0q0 = power(*u(t[0]), *i0)

    def pq(tt, which):
        if tt < t[0]:
            return p0q0[which]
        ud, uq = u(tt)
        y = sol.sol(tt)
        i_d, iq = currents(ud, uq, y[0], y[1], m)
        return power(ud, uq, i_d, iq)[which]

    out = np.empty((2, real.size))
    for i, r in enumerate(real):
        lo, hi = t[r] - W / 2, t[r] + W / 2
        brk = [x for x in t if lo < x < hi]
        for which in (0, 1):
            val, _ = quad(pq, lo, hi, args=(which,), points=brk or None, limit=200,
                          epsabs=1e-12, epsrel=1e-11)  # fmt: skip
            out[which, i] = val / W
    return out


@pytest.mark.parametrize("motor", ["krause_3hp", "fast"])
def test_window_means_match_solve_ivp(motor):
    m = _fast() if motor == "fast" else MOTORS[motor]
    t, v, delta, real = _input()
    ref = _reference(m, t, v, delta, 0.6, real)
    kw = {"rs": m.rs, "xp": m.xp, "dx": m.x - m.xp, "tp_s": m.tp_s, "t0": 0.6}
    from loadbayes.models.motor_kernel import integrate_window_into, step_size

    p, q = np.empty(real.size), np.empty(real.size)
    ok = integrate_window_into(t, v, delta, real.astype(np.int64), W, m.rs, m.xp, m.x - m.xp,
                               m.tp_s, m.h_s, m.wb, 0.6, 1.0, 0.0, 0.0,
                               step_size(m.tp_s, 5e-3), p, q)  # fmt: skip
    assert ok
    err = max(np.max(np.abs(p - ref[0])), np.max(np.abs(q - ref[1])))
    print(f"{motor}: largest window-mean error {err:.1e} p.u.")
    assert err < TOL_PU
    # The check can fail: point values differ from the window means by far more near
    # the step (the fast flux transient), and a 5% error in H is outside too.
    pt, qt, _ = integrate(t, v, delta, h_s=m.h_s, **kw)
    assert np.max(np.abs(pt[real] - ref[0])) > 10 * TOL_PU
    p_bad = np.empty(real.size)
    integrate_window_into(t, v, delta, real.astype(np.int64), W, m.rs, m.xp, m.x - m.xp,
                          m.tp_s, 1.05 * m.h_s, m.wb, 0.6, 1.0, 0.0, 0.0,
                          step_size(m.tp_s, 5e-3), p_bad, q)  # fmt: skip
    assert np.max(np.abs(p_bad - ref[0])) > TOL_PU


def test_the_window_bounds_order_is_a_stable_argsort():
    # _merge_bounds orders the windows' bounds by merging the lower and the upper ones
    # (each sorted for samples in time order) instead of sorting them: the same order as
    # np.argsort's stable mergesort, ties (a window's upper bound on the next one's lower,
    # as at one window per sample interval) included, and argsort itself where the
    # bounds come unsorted. Deterministic cases: no false alarms.
    from loadbayes.models.motor_kernel import _bounds_order

    rng = np.random.default_rng(0)
    for case in range(2000):
        n = int(rng.integers(1, 60))
        t = np.cumsum(rng.choice([1 / 60, 1 / 120, 1 / 240, 0.005], size=n))
        if case % 3 == 0:
            t = np.round(t * 240) / 240  # on a grid: ties between bounds
        half = rng.choice([1 / 60, 1 / 120, 0.02, 0.0, 1 / 30]) / 2
        b = np.empty(2 * n)
        b[0::2], b[1::2] = t - half, t + half
        if case % 10 == 0:
            rng.shuffle(b)
        np.testing.assert_array_equal(_bounds_order(b), np.argsort(b, kind="mergesort"))
