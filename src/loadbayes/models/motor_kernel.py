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
``models.motor_library.MOTORS`` and sags of 10-60%, the largest error in P and Q is below
``1e-4`` p.u. on the motor's base with the default step ``min(5 ms, T'/50)``
(measured: 4.4e-5 for krause_3hp, whose T' = 0.087 s is the shortest, at most 5.2e-6 for
the others).
"""

from __future__ import annotations

import math

import numba
import numpy as np
from numpy.typing import NDArray

__all__ = [
    "H_MAX_S",
    "TP_STEPS",
    "integrate",
    "integrate_into",
    "steady_slip",
    "steady_state",
    "step_size",
]

#: Default largest RK4 sub-step (s), capped at ``T' / TP_STEPS`` by :func:`step_size`.
#: Measured against DOP853 on the library motors, sags of 10-60% at 60 samples/s
#: (tests/unit/test_motor_kernel.py): largest error in P, Q with this rule 4.4e-5 p.u. for
#: krause_3hp (T' = 0.087 s, so its step is T'/50 = 1.7 ms), at most 5.2e-6 for the
#: others (5 ms applies; at 8 ms krause_2250hp reaches 9e-5, at 2 ms the others 2e-7).
H_MAX_S = 5e-3
#: Sub-steps per T' at least: RK4's error grows as (h / T')^4, so a fast motor (as a
#: sampler may propose) gets a finer step. At T'/40, krause_3hp's error reaches 1.1e-4.
TP_STEPS = 50.0
#: Largest deviation (p.u. of V, rad of angle) of a sample from the straight line through
#: its neighbours for one RK4 step to span several samples (when they are closer than the
#: step). Tiny on purpose: at 1e-5 an angle swing of 0.2 rad at 0.8 Hz sampled at 960/s
#: merges, and the error against DOP853 grows from 1e-7 to 4e-5 p.u. So in practice a
#: piecewise-linear input (flat stretches and ramps, as simulated events) is integrated
#: in steps of up to ``h_max``, and a recorded one with noise sample by sample, as before.
LINEAR_TOL = 1e-7
#: Largest change of V (p.u.) or angle (rad) per RK4 sub-step. Without it a 60% sag
#: edge inside one sample at 960/s puts krause_3hp 1.3e-4 off DOP853 (7.7e-6 with it).
DV_STEP = 0.1
#: After a step of the input (more than ``STEP_JUMP`` p.u. or rad within one interval),
#: the flux's fast mode, of time constant ``T' X' / X``, rings: for ``FAST_SPAN`` of
#: those time constants the sub-step is at most ``1 / FAST_STEPS`` of it. Without this a
#: true step placed inside a 60/s interval (models/composite_steps.py) put krause_3hp
#: (T' X' / X = 5 ms) 1.9e-4 off DOP853.
STEP_JUMP = 0.02
FAST_SPAN = 5.0
FAST_STEPS = 10.0


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
def _u(vv, dd, has_angle):  # pragma: no cover - compiled
    # Without an angle U is real: no cos/sin.
    if has_angle:
        return vv * math.cos(dd), vv * math.sin(dd)
    return vv, 0.0


@numba.njit(cache=True, nogil=True)
def _rk4(ed, eq, w, ua, ub, um, hs, rs, xp, dx, tp, h, wb, t0, a, b, c):  # pragma: no cover
    # One classical RK4 step; ua, um, ub: (Ud, Uq) at the start, middle and end.
    k1 = _rhs(ed, eq, w, ua[0], ua[1], rs, xp, dx, tp, h, wb, t0, a, b, c)
    k2 = _rhs(
        ed + 0.5 * hs * k1[0],
        eq + 0.5 * hs * k1[1],
        w + 0.5 * hs * k1[2],
        um[0],
        um[1],
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
        um[0],
        um[1],
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
        ub[0],
        ub[1],
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
    return ed, eq, w, k1


@numba.njit(cache=True, nogil=True)
def _on_chord(t, v, delta, k, j):  # pragma: no cover - compiled
    # Whether the samples strictly between k and j lie on the straight line from k to j
    # (then the piecewise-linear input is one linear piece over [t_k, t_j]).
    for i in range(k + 1, j):
        fr = (t[i] - t[k]) / (t[j] - t[k])
        if abs(v[i] - (v[k] + fr * (v[j] - v[k]))) > LINEAR_TOL:
            return False
        if abs(delta[i] - (delta[k] + fr * (delta[j] - delta[k]))) > LINEAR_TOL:
            return False
    return True


@numba.njit(cache=True, nogil=True)
def integrate_into(t, v, delta, rs, xp, dx, tp, h, wb, t0, a, b, c, h_max, p, q, states):
    """The compiled core of :func:`integrate`, for compiled callers (the composite's density).

    Writes P, Q and the states into ``p``, ``q``, ``states``; returns False when there is
    no steady state or the states leave the finite numbers. ``h_max`` is the sub-step
    itself (:func:`step_size` applied by the caller).
    """  # pragma: no cover - compiled
    n = t.size
    ed, eq, w, p0, q0 = steady_state(rs, xp, dx, tp, wb, v[0], t0, a, b, c)
    if not math.isfinite(ed):
        return False
    den = rs * rs + xp * xp
    has_angle = False
    for k in range(n):
        if delta[k] != 0.0:
            has_angle = True
            break
    states[0, 0], states[1, 0], states[2, 0] = ed, eq, w
    tau_fast = tp * xp / (xp + dx)
    fine_until = -math.inf
    k = 0
    while k < n - 1:
        # Samples closer than the step: one RK4 step over several of them where the input
        # is one linear piece there (a sampled sag's corners are never inside a step), the
        # states between by cubic Hermite interpolation (smooth states, O(h^4) error).
        j = k + 1
        fine = t[k] < fine_until
        while (
            not fine
            and j + 1 < n
            and t[j + 1] - t[k] <= h_max * (1.0 + 1e-9)
            and _on_chord(t, v, delta, k, j + 1)
        ):
            j += 1
        if j > k + 1:
            span = t[j] - t[k]
            ua = _u(v[k], delta[k], has_angle)
            ub = _u(v[j], delta[j], has_angle)
            um = _u(0.5 * (v[k] + v[j]), 0.5 * (delta[k] + delta[j]), has_angle)
            e0, q0_, w0 = ed, eq, w
            ed, eq, w, f0 = _rk4(ed, eq, w, ua, ub, um, span, rs, xp, dx, tp, h, wb, t0, a, b, c)
            f1 = _rhs(ed, eq, w, ub[0], ub[1], rs, xp, dx, tp, h, wb, t0, a, b, c)
            for i in range(k + 1, j):
                s = (t[i] - t[k]) / span
                h00 = (1.0 + 2.0 * s) * (1.0 - s) * (1.0 - s)
                h10 = s * (1.0 - s) * (1.0 - s) * span
                h01 = s * s * (3.0 - 2.0 * s)
                h11 = s * s * (s - 1.0) * span
                states[0, i] = h00 * e0 + h10 * f0[0] + h01 * ed + h11 * f1[0]
                states[1, i] = h00 * q0_ + h10 * f0[1] + h01 * eq + h11 * f1[1]
                states[2, i] = h00 * w0 + h10 * f0[2] + h01 * w + h11 * f1[2]
        else:
            # One interval in ceil(dt / h_max) equal sub-steps, V and angle linear inside.
            span = t[j] - t[k]
            # A fast input (a sag's edge within one sample at a high rate) gets more: RK4's
            # error follows the input's change per step as well as h / T'.
            jump = max(abs(v[j] - v[k]), abs(delta[j] - delta[k]))
            h_k = min(h_max, tau_fast / FAST_STEPS) if fine else h_max
            m = max(1, int(math.ceil(span / h_k - 1e-9)), int(math.ceil(jump / DV_STEP)))
            if jump > STEP_JUMP:
                fine_until = t[j] + FAST_SPAN * tau_fast
            hs = span / m
            for r in range(m):
                fa, fm, fb = r / m, (r + 0.5) / m, (r + 1.0) / m
                ua = _u(v[k] + fa * (v[j] - v[k]), delta[k] + fa * (delta[j] - delta[k]), has_angle)
                um = _u(v[k] + fm * (v[j] - v[k]), delta[k] + fm * (delta[j] - delta[k]), has_angle)
                ub = _u(v[k] + fb * (v[j] - v[k]), delta[k] + fb * (delta[j] - delta[k]), has_angle)
                ed, eq, w, _ = _rk4(ed, eq, w, ua, ub, um, hs, rs, xp, dx, tp, h, wb, t0, a, b, c)
        if not (math.isfinite(ed) and math.isfinite(eq) and math.isfinite(w)):
            return False
        states[0, j], states[1, j], states[2, j] = ed, eq, w
        k = j
    for i in range(n):
        # The algebraic output exactly at every sample, from the states and the sampled U.
        ud, uq = _u(v[i], delta[i], has_angle)
        dd = ud - states[0, i]
        dq = uq - states[1, i]
        id_ = (rs * dd + xp * dq) / den
        iq = (rs * dq - xp * dd) / den
        p[i] = ud * id_ + uq * iq
        q[i] = uq * id_ - ud * iq
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
    ok = integrate_into(
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
