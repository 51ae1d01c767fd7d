"""Compiled fixed-step integrator of the third-order motor driven by a sampled voltage.

The equations are those of :mod:`loadbayes.models.motor` (time in seconds, slip terms
carry ``wb = 2 pi f``, load convention), written on the five quantities the dynamics
depend on: ``Rs``, ``X'``, ``X - X'``, ``T'`` (s), ``H`` (s), plus the loading ``T0`` and
the torque shares ``A, B, C``.

The terminal voltage is known only at the samples ``t_k``: its magnitude ``V_k`` and its
angle ``delta_k`` (radians, relative to the motor's synchronous frame at the nominal
frequency; zero when the recording has no angle). Between samples both are taken linear
in time, ``Ud + j Uq = V e^{j delta}``, and the state is advanced by classical RK4 with
``ceil((t_{k+1} - t_k) / h_max)`` equal sub-steps. The initial state is the steady state
at ``(V_0, delta_0 = 0)``, solved in closed form for the flux given the slip and by
bisection on the torque balance for the slip (the stable branch: the first slip at which
the electrical torque reaches the load torque).

Accuracy (``tests/unit/test_motor_kernel.py``): against ``scipy.integrate.solve_ivp``
(DOP853, ``rtol=1e-10``) driven by the same piecewise-linear voltage, on every motor of
``cases.motor_sim.MOTORS`` and sags of 10-60%, the largest error in P and Q is below
``1e-4`` p.u. on the motor's base with the default step ``min(5 ms, T'/50)``
(measured: 4.4e-5 for krause_3hp, whose T' = 0.087 s is the shortest, at most 5.2e-6 for
the others).
"""

from __future__ import annotations

import math

import numba
import numpy as np
from numpy.typing import NDArray

__all__ = ["H_MAX_S", "TP_STEPS", "integrate", "steady_slip", "steady_state", "step_size"]

#: Default largest RK4 sub-step (s), capped at ``T' / TP_STEPS`` by :func:`step_size`.
#: Measured against DOP853 on the library motors, sags of 10-60% at 60 samples/s
#: (tests/unit/test_motor_kernel.py): largest error in P, Q with this rule 4.4e-5 p.u. for
#: krause_3hp (T' = 0.087 s, so its step is T'/50 = 1.7 ms), at most 5.2e-6 for the
#: others (5 ms applies; at 8 ms krause_2250hp reaches 9e-5, at 2 ms the others 2e-7).
H_MAX_S = 5e-3
#: Sub-steps per T' at least: RK4's error grows as (h / T')^4, so a fast motor (as a
#: sampler may propose) gets a finer step. At T'/40, krause_3hp's error reaches 1.1e-4.
TP_STEPS = 50.0


@numba.njit(cache=True, nogil=True)
def step_size(tp_s, h_max):  # pragma: no cover - compiled
    """The largest RK4 sub-step (s) for a motor of transient time constant ``tp_s``."""
    return min(h_max, tp_s / TP_STEPS)


@numba.njit(cache=True, nogil=True)
def _te_pq(rs, xp, dx, tp, wb, v, s):  # pragma: no cover - compiled
    # Steady flux at slip s with U = v on the d axis (models/motor._flux):
    # E' = j D V / (Z (1 + j wb T' s) + j D), Z = Rs + j X'.
    z = complex(rs, xp)
    e = 1j * dx * v / (z * (1.0 + 1j * wb * tp * s) + 1j * dx)
    i = (v - e) / z
    te = (e * i.conjugate()).real
    sv = v * i.conjugate()
    return te, sv.real, sv.imag, e


@numba.njit(cache=True, nogil=True)
def steady_slip(rs, xp, dx, tp, wb, v, t0, a, b, c):  # pragma: no cover - compiled
    """Slip of the stable steady state, or -1.0 if the load exceeds the breakdown torque."""
    # f(s) = Te(s) - T0 (A w^2 + B w + C), w = 1 - s; f(0) = -T0 < 0. The stable point is
    # the first zero crossing going up (d(Te - Tm)/ds > 0 there, so dw/dt restores w).
    s_prev = 0.0
    s = 1e-7
    ratio = 1.1
    while s <= 1.0:
        w = 1.0 - s
        f = _te_pq(rs, xp, dx, tp, wb, v, s)[0] - t0 * (a * w * w + b * w + c)
        if f > 0.0:
            lo, hi = s_prev, s
            for _ in range(80):
                mid = 0.5 * (lo + hi)
                wm = 1.0 - mid
                fm = _te_pq(rs, xp, dx, tp, wb, v, mid)[0] - t0 * (a * wm * wm + b * wm + c)
                if fm > 0.0:
                    hi = mid
                else:
                    lo = mid
                if hi - lo <= 1e-15 * hi:
                    break
            root = 0.5 * (lo + hi)
            # Past the breakdown slip the electrical torque falls with slip: a crossing
            # there (a quadratic load torque vanishes at standstill) is not a stable point.
            te_lo = _te_pq(rs, xp, dx, tp, wb, v, root * (1.0 - 1e-6))[0]
            te_hi = _te_pq(rs, xp, dx, tp, wb, v, root * (1.0 + 1e-6))[0]
            return root if te_hi > te_lo else -1.0
        s_prev = s
        s *= ratio
    return -1.0


@numba.njit(cache=True, nogil=True)
def steady_state(rs, xp, dx, tp, wb, v, t0, a, b, c):  # pragma: no cover - compiled
    """Steady ``(Ed', Eq', w, P, Q)`` at voltage ``v`` on the d axis; NaNs if none exists."""
    s = steady_slip(rs, xp, dx, tp, wb, v, t0, a, b, c)
    if s <= 0.0:
        return math.nan, math.nan, math.nan, math.nan, math.nan
    te, p, q, e = _te_pq(rs, xp, dx, tp, wb, v, s)
    return e.real, e.imag, 1.0 - s, p, q


@numba.njit(cache=True, nogil=True)
def _rhs(ed, eq, w, ud, uq, rs, xp, dx, tp, h, wb, t0, a, b, c):  # pragma: no cover
    den = rs * rs + xp * xp
    dd = ud - ed
    dq = uq - eq
    id_ = (rs * dd + xp * dq) / den
    iq = (rs * dq - xp * dd) / den
    ded = -(ed + dx * iq) / tp - wb * (w - 1.0) * eq
    deq = -(eq - dx * id_) / tp + wb * (w - 1.0) * ed
    dw = ((ed * id_ + eq * iq) - t0 * (a * w * w + b * w + c)) / (2.0 * h)
    return ded, deq, dw


@numba.njit(cache=True, nogil=True)
def _integrate(t, v, delta, rs, xp, dx, tp, h, wb, t0, a, b, c, h_max, p, q, states):
    # pragma: no cover - compiled
    n = t.size
    ed, eq, w, p0, q0 = steady_state(rs, xp, dx, tp, wb, v[0], t0, a, b, c)
    if not math.isfinite(ed):
        return False
    den = rs * rs + xp * xp
    # Without an angle U is real: skip the six cos/sin per sub-step (a third of the
    # kernel's time at one sub-step per sample). The same arithmetic otherwise.
    has_angle = False
    for k in range(n):
        if delta[k] != 0.0:
            has_angle = True
            break
    for k in range(n):
        if k > 0:
            span = t[k] - t[k - 1]
            m = max(1, int(math.ceil(span / h_max - 1e-9)))
            hs = span / m
            v0, v1 = v[k - 1], v[k]
            a0, a1 = delta[k - 1], delta[k]
            for j in range(m):
                # Linear V and angle inside the interval; RK4 needs them at 0, 1/2, 1.
                fr0 = j / m
                frm = (j + 0.5) / m
                fr1 = (j + 1.0) / m
                va = v0 + fr0 * (v1 - v0)
                vm = v0 + frm * (v1 - v0)
                vb = v0 + fr1 * (v1 - v0)
                da = a0 + fr0 * (a1 - a0)
                dm = a0 + frm * (a1 - a0)
                db = a0 + fr1 * (a1 - a0)
                if has_angle:
                    uda, uqa = va * math.cos(da), va * math.sin(da)
                    udm, uqm = vm * math.cos(dm), vm * math.sin(dm)
                    udb, uqb = vb * math.cos(db), vb * math.sin(db)
                else:
                    uda, uqa, udm, uqm, udb, uqb = va, 0.0, vm, 0.0, vb, 0.0
                k1 = _rhs(ed, eq, w, uda, uqa, rs, xp, dx, tp, h, wb, t0, a, b, c)
                k2 = _rhs(
                    ed + 0.5 * hs * k1[0],
                    eq + 0.5 * hs * k1[1],
                    w + 0.5 * hs * k1[2],
                    udm,
                    uqm,
                    rs,
                    xp,
                    dx,
                    tp,
                    h,
                    wb,
                    t0,
                    a,
                    b,
                    c,
                )
                k3 = _rhs(
                    ed + 0.5 * hs * k2[0],
                    eq + 0.5 * hs * k2[1],
                    w + 0.5 * hs * k2[2],
                    udm,
                    uqm,
                    rs,
                    xp,
                    dx,
                    tp,
                    h,
                    wb,
                    t0,
                    a,
                    b,
                    c,
                )
                k4 = _rhs(
                    ed + hs * k3[0],
                    eq + hs * k3[1],
                    w + hs * k3[2],
                    udb,
                    uqb,
                    rs,
                    xp,
                    dx,
                    tp,
                    h,
                    wb,
                    t0,
                    a,
                    b,
                    c,
                )
                ed += hs / 6.0 * (k1[0] + 2.0 * k2[0] + 2.0 * k3[0] + k4[0])
                eq += hs / 6.0 * (k1[1] + 2.0 * k2[1] + 2.0 * k3[1] + k4[1])
                w += hs / 6.0 * (k1[2] + 2.0 * k2[2] + 2.0 * k3[2] + k4[2])
            if not (math.isfinite(ed) and math.isfinite(eq) and math.isfinite(w)):
                return False
        ud = v[k] * math.cos(delta[k])
        uq = v[k] * math.sin(delta[k])
        dd = ud - ed
        dq = uq - eq
        id_ = (rs * dd + xp * dq) / den
        iq = (rs * dq - xp * dd) / den
        p[k] = ud * id_ + uq * iq
        q[k] = uq * id_ - ud * iq
        states[0, k] = ed
        states[1, k] = eq
        states[2, k] = w
    return True


def integrate(
    t: NDArray[np.float64],
    v: NDArray[np.float64],
    delta: NDArray[np.float64] | None,
    *,
    rs: float,
    xp: float,
    dx: float,
    tp_s: float,
    h_s: float,
    t0: float,
    f_hz: float = 60.0,
    torque: tuple[float, float, float] = (1.0, 0.0, 0.0),
    h_max: float = H_MAX_S,
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]] | None:
    """Motor P, Q (own base) at the samples, from its steady state at the first sample.

    Parameters
    ----------
    t : ndarray, shape (n,)
        Sample times (s), strictly increasing.
    v : ndarray, shape (n,)
        Terminal voltage magnitude (p.u.).
    delta : ndarray or None
        Voltage angle (rad) relative to the frame rotating at ``f_hz``; None for zero.
    rs, xp, dx : float
        ``Rs``, ``X'`` and ``X - X'`` (p.u. on the motor's base).
    tp_s, h_s : float
        ``T'`` and ``H`` in seconds.
    t0 : float
        Load torque at synchronous speed (p.u. on the motor's base).
    f_hz : float
        Nominal frequency: ``wb = 2 pi f_hz``.
    torque : tuple of float
        ``(A, B, C)`` of ``Tm = T0 (A w^2 + B w + C)``.
    h_max : float
        Largest RK4 sub-step (s); the step used is :func:`step_size` ``(tp_s, h_max)``.

    Returns
    -------
    (p, q, states) or None
        ``p``, ``q`` shaped (n,) and the states ``(Ed', Eq', w)`` shaped (3, n); None when
        the load torque exceeds the breakdown torque at ``v[0]`` (no steady state) or the
        integration leaves the finite numbers.
    """
    t = np.ascontiguousarray(t, dtype=float)
    v = np.ascontiguousarray(v, dtype=float)
    # The steady state puts the first sample's voltage on the d axis: angles are relative.
    d = np.zeros_like(t) if delta is None else np.asarray(delta, dtype=float) - float(delta[0])
    d = np.ascontiguousarray(d)
    n = t.size
    p, q, states = np.empty(n), np.empty(n), np.empty((3, n))
    a, b, c = (float(x) for x in torque)
    ok = _integrate(
        t,
        v,
        d,
        float(rs),
        float(xp),
        float(dx),
        float(tp_s),
        float(h_s),
        2.0 * math.pi * float(f_hz),
        float(t0),
        a,
        b,
        c,
        float(step_size(float(tp_s), float(h_max))),
        p,
        q,
        states,
    )
    return (p, q, states) if ok else None
