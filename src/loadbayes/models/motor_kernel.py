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
the electrical torque reaches the load torque), with the voltage turning at the speed the
angle turns at over the record's steady start (:func:`start_speed`; the nominal speed
without an angle): off the nominal frequency the angle turns, and a steady state at the
nominal speed would start a transient the data do not hold.

Accuracy (``tests/unit/test_motor_kernel.py``): against ``scipy.integrate.solve_ivp``
(DOP853, ``rtol=1e-10``) driven by the same piecewise-linear voltage, on every motor of
``models.motor_library.MOTORS`` and sags of 10-60%, the largest error in P and Q is below
``1e-4`` p.u. on the motor's base with the default step ``min(5 ms, T'/50)``
(measured: 4.4e-5 for krause_3hp, whose T' = 0.087 s is the shortest, at most 5.2e-6 for
the others).

:func:`integrate_window_into` gives each sample's **window mean** of P and Q instead (a
phasor sample, its window centred on the stamp): against DOP853 with dense output and
the window integrals by ``quad`` (``tests/unit/test_motor_window.py``), 1.4e-5 p.u. on
krause_3hp and 1.1e-5 on a fast motor (T' 0.06 s), a step inside an interval included.

**The negative sequence's braking torque.** Under an unbalanced fault the negative-
sequence voltage ``V2`` drives a rotor current at slip ``2 - s``, whose power in the rotor
resistance brakes the motor: ``T2 = |I_r2|^2 Rr / (2 - s)`` (:func:`brake_torque`, from the
T-circuit of ``parts.motor_y2``' closure), subtracted from the electrical torque in the
swing equation. ``integrate_v2_into`` and ``integrate_window_v2_into`` take ``|V2|`` at the
samples (linear between them, as V); None is a balanced input (``integrate_into``,
``integrate_window_into``), compiled apart: the term is chosen by the argument's type when
a caller is compiled (``numba.extending.overload``), so a balanced input's arithmetic is
the one without it, to the bit, and as fast (a branch in the right-hand side cost 15 %).
With V2 given, a stage whose ``|V2|`` is 0 (a record's rows outside the unbalanced fault:
all but 4 of the real first fault's 68) skips the T-circuit's complex arithmetic, whose
torque there is 0 to the bit: the braked motor costs 43 us instead of 77 on that window
(event_parts 79 instead of 117; ``cmld-lite``'s default fit 142 s instead of 185).
Against the tests' SciPy generator (``tests/sequence_generator.py``) at the true
parameters of a phase-to-ground fault, the model's P during the fault moved from 0.012 p.u.
(1.8 % of P0) low to 3.9e-4, the balanced sag's residual.

One idea needs these 735 lines: the motor integrated through a sampled voltage, at the
samples and as window means, in compiled loops that share the steady state and the RK4
step (the braking torque's drive carried beside the voltage).
"""

from __future__ import annotations

import math

import numba
import numpy as np
from numba import types
from numba.extending import overload
from numpy.typing import NDArray

__all__ = [
    "H_MAX_S",
    "TP_STEPS",
    "brake_circuit",
    "brake_torque",
    "integrate",
    "integrate_into",
    "integrate_v2_into",
    "integrate_window_into",
    "integrate_window_v2_into",
    "start_speed",
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
#: The start's steady part, over which the angle's slope gives the voltage's speed that
#: the initial steady state is taken at (:func:`start_speed`): at most this long (s)...
START_SPAN_S = 0.2
#: ...and before V first leaves V_0 by this much (p.u.). A recorder's angle turns at
#: 2 pi (f - f_nominal): at 59.98 Hz a steady state at 60 Hz was 3.3e-4 off in slip (2.5%
#: of a 0.013 slip), a start-up transient of 0.004 p.u. in P over 0.15 s at the truth
#: (tests/integration/test_recorder_chain.py).
START_DV = 0.005
#: A slope below this (Hz) is the angle's noise, and the start is at the nominal speed:
#: 0.27 mHz on the recorder chain at 60.00 Hz, 0.02 mHz on tests/sequence_generator.py's
#: record (the nominal frequency, read back), where the start transient of 1 mHz would be
#: about 2e-4 p.u. in P. Such records start as before, to the bit.
START_DF_HZ = 1e-3
#: After a step of the input (more than ``STEP_JUMP`` p.u. or rad within one interval),
#: the flux's fast mode, of time constant ``T' X' / X``, rings: for ``FAST_SPAN`` of
#: those time constants the sub-step is at most ``1 / FAST_STEPS`` of it. Without this a
#: true step placed inside a 60/s interval (models/composite_steps.py) put krause_3hp
#: (T' X' / X = 5 ms) 1.9e-4 off DOP853.
STEP_JUMP = 0.02
FAST_SPAN = 5.0
FAST_STEPS = 10.0
#: Most RK4 sub-steps in one interval; an input that asks for more (|V| far outside any
#: voltage, as a feeder loop's sweep running off drives it, or a sub-step tiny beside the
#: interval) is not integrated: the call returns False, as for states that leave the
#: finite numbers. Physical inputs need at most about 2,000 (a 10 s gap at 5 ms; a 2 p.u.
#: jump takes 20). Without it ``predict`` spun for minutes on one draw whose load bus ran
#: to very large |V| between two sweeps (issue 37's averaged band check, two of 20 data
#: sets: tests/unit/test_motor_kernel.py).
MAX_SUBSTEPS = 100_000
#: Largest turn (rad) of the rotor's frame against the voltage's, ``wb |1 - w| h``, in one
#: RK4 sub-step. The flux equations ring at ``wb (1 - w)``; RK4 is stable on that axis
#: only up to 2.83 rad a step. A running or stalled motor (``0 <= w <= 1``) never comes
#: near it at ``H_MAX_S`` (1.9 rad at 60 Hz), so its sub-steps are as before, to the bit;
#: a stalled motor that a constant load torque drives backwards (``w`` to -4 in a second
#: at H = 0.1 s and 15 % voltage: ``tests/unit/test_motor_backwards.py``) left the finite
#: numbers, and ``predict`` said such draws "fail numerically" at deep sags.
OSC_STEP = 2.0
#: A motor at rest is not integrated: where the input holds one value (V, angle and
#: |V2| equal to the bit) over at least ``REST_KNOTS`` knots and the state is within
#: ``REST_TOL`` (p.u. flux and speed, each) of the steady state at that input, the state is
#: held until the input moves. A stable steady state only draws the state nearer, so the
#: outputs move by a few ``REST_TOL / |Rs + jX'|`` at most: against the same record
#: integrated throughout, 4.2e-10 p.u. at most (the 20 s event at 60/s of
#: docs/composite.md, T' 0.3-1.5 s), far below the integrator's error (above;
#: tests/unit/test_motor_rest.py) and below the 1e-9 to which the feeder loop's march
#: and sweeps agree (test_parts_play; at REST_TOL 1e-9 they were 2.7e-9 apart). There
#: the motor rests from the first sample to the sag and from 0.6-2.9 s after its
#: recovery to the end: the integration cost 44-60 us instead of 240 (point samples),
#: 75-91 instead of 330 (window means, with the bounds merged in one pass,
#: ``_bounds_order``). A simulated event holds its voltage before and after the sag; a
#: recorded one with noise on V never holds a value and is integrated as before, to the
#: bit.
REST_TOL = 1e-11
REST_KNOTS = 4
#: The steady state at a held input is solved (a bisection, about 3 us) only once the
#: state's rate of change says it is near: ``|dEd'/dt| + |dEq'/dt|`` times T' plus
#: ``|dw/dt|`` times 2H, a bound on the distance to rest, below this. Without it a
#: recorder's voltage with noise quantised to 1e-3 p.u., which repeats a value over four
#: knots 30 times in 20 s at 60/s (far more often among the window bounds), spent the
#: solves for nothing: 307 us an integration against 249 before the rest was held, 607
#: against 345 with windows; with it 247 and 320 (idle, repeated twice).
REST_NEAR = 1e-8


@numba.njit(cache=True, nogil=True)
def _substeps(span, h_k, jump, turn=0.0):  # pragma: no cover - compiled
    # One interval's RK4 sub-steps, for both integrators: ceil(span / h_k), more for a fast
    # input (DV_STEP a sub-step) or a fast-turning frame (turn = wb |1 - w|, rad/s:
    # OSC_STEP a sub-step); 0 where it asks for more than MAX_SUBSTEPS (an input no load
    # sees: the caller returns False; NaN fails too).
    osc = span * turn / OSC_STEP
    if not (span / h_k < MAX_SUBSTEPS and jump / DV_STEP < MAX_SUBSTEPS and osc < MAX_SUBSTEPS):
        return 0
    m = max(1, int(math.ceil(span / h_k - 1e-9)), int(math.ceil(jump / DV_STEP)))
    if osc > m:
        m = int(math.ceil(osc))
    return m


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
def steady_slip(rs, xp, dx, tp, wb, v, t0, a, b, c, w_sync=1.0):  # pragma: no cover
    """Slip of the stable steady state, or -1.0 if the load exceeds the breakdown torque.

    ``w_sync``: the voltage's speed (units of ``wb``; 1 at the nominal frequency). The
    slip is the rotor's behind the voltage, ``s = w_sync - w`` (the flux sees it), the
    load torque the rotor's speed ``w``'s.
    """
    # f(s) = Te(s) - T0 (A w^2 + B w + C), w = w_sync - s; f(0) = -T0 < 0. The stable point
    # is the first zero crossing going up (d(Te - Tm)/ds > 0 there, so dw/dt restores w).
    s_prev = 0.0
    s = 1e-7
    ratio = 1.1
    while s <= 1.0:
        w = w_sync - s
        f = _te_pq(rs, xp, dx, tp, wb, v, s)[0] - t0 * (a * w * w + b * w + c)
        if f > 0.0:
            lo, hi = s_prev, s
            for _ in range(80):
                mid = 0.5 * (lo + hi)
                wm = w_sync - mid
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
def steady_state(rs, xp, dx, tp, wb, v, t0, a, b, c, w_sync=1.0):  # pragma: no cover
    """Steady ``(Ed', Eq', w, P, Q)`` at voltage ``v`` on the d axis; NaNs if none exists.

    ``w_sync``: the voltage's speed (:func:`steady_slip`); the flux is in the frame
    turning with the voltage, which is the nominal frame at the instant the angle is 0.
    """
    s = steady_slip(rs, xp, dx, tp, wb, v, t0, a, b, c, w_sync)
    if s <= 0.0:
        return math.nan, math.nan, math.nan, math.nan, math.nan
    te, p, q, e = _te_pq(rs, xp, dx, tp, wb, v, s)
    return e.real, e.imag, w_sync - s, p, q


@numba.njit(cache=True, nogil=True)
def start_speed(t, v, delta, wb):  # pragma: no cover - compiled
    """The voltage's speed at the start (units of ``wb``): where the steady state is taken.

    ``1 + slope / wb``, the slope (rad/s) of the angle fitted by least squares over the
    first samples: those within :data:`START_SPAN_S` of ``t[0]`` before V first leaves
    ``V_0`` by :data:`START_DV` (the record's steady part). Exactly 1.0 without an angle,
    with a constant angle there, with fewer than three such samples, or with a slope
    below :data:`START_DF_HZ` (noise).
    """
    n = 0
    st, sd, stt, std = 0.0, 0.0, 0.0, 0.0
    for k in range(t.size):
        if t[k] - t[0] > START_SPAN_S or abs(v[k] - v[0]) > START_DV:
            break
        x, y = t[k] - t[0], delta[k] - delta[0]
        n += 1
        st += x
        sd += y
        stt += x * x
        std += x * y
    den = n * stt - st * st
    if n < 3 or not den > 0.0:
        return 1.0
    slope = (n * std - st * sd) / den
    if abs(slope) < 2.0 * math.pi * START_DF_HZ:
        return 1.0
    return 1.0 + slope / wb


@numba.njit(cache=True, nogil=True)
def brake_circuit(xp, dx, tp, wb):  # pragma: no cover - compiled
    """``(Xs, Xm, Rr)`` of the T-circuit behind ``X', X - X', T'`` (``parts.motor_y2``' closure)."""
    x = xp + dx
    xm = math.sqrt(x * dx)
    return x - xm, xm, x / (wb * tp)


@numba.njit(cache=True, nogil=True)
def brake_torque(v2, w, rs, xs, xm, rr):  # pragma: no cover - compiled
    """The negative sequence's braking torque ``|I_r2|^2 Rr / (2 - s)`` at ``|V2| = v2``.

    The T-circuit ``Rs + jXs`` then ``jXm`` in parallel with ``Rr / (2 - s) + jXr``
    (``Xr = Xs``) at slip ``2 - s = 1 + w``: ``I2 = V2 / Z2`` and the rotor branch takes
    ``I_r2 = I2 jXm / (Rr / (2 - s) + jXr + jXm)``; the torque is the power its
    resistance draws per unit of synchronous speed (own base; it opposes the rotation).
    """
    rr2 = rr / (1.0 + w)
    rotor = complex(rr2, xs)
    loop = rotor + 1j * xm
    z2 = complex(rs, xs) + (1j * xm * rotor) / loop
    a2 = loop.real * loop.real + loop.imag * loop.imag
    z2a = z2.real * z2.real + z2.imag * z2.imag
    return v2 * v2 * xm * xm / (a2 * z2a) * rr2


@numba.njit(cache=True, nogil=True)
def _rhs(ed, eq, w, ud, uq, b2, rs, xp, dx, tp, h, wb, t0, a, b, c, nb):  # pragma: no cover
    # Reciprocals of the parameters only: inlined into the integrators' loops, these
    # three divisions are hoisted out of them and each stage multiplies (a third less
    # time per step than dividing in every stage). b2: |V2|, the braking torque's drive;
    # nb: the circuit's (Xs, Xm, Rr), None on a balanced input (the term compiled out).
    g = 1.0 / (rs * rs + xp * xp)
    r_tp = 1.0 / tp
    r_2h = 0.5 / h
    dd = ud - ed
    dq = uq - eq
    id_ = (rs * dd + xp * dq) * g
    iq = (rs * dq - xp * dd) * g
    ded = -(ed + dx * iq) * r_tp - wb * (w - 1.0) * eq
    deq = -(eq - dx * id_) * r_tp + wb * (w - 1.0) * ed
    te = ed * id_ + eq * iq - _brake_of(b2, w, rs, nb)  # x - 0.0 is x: balanced, to the bit
    dw = (te - t0 * (a * w * w + b * w + c)) * r_2h
    return ded, deq, dw


@numba.njit(cache=True, nogil=True)
def _u(vv, dd, has_angle, b2=0.0):  # pragma: no cover - compiled
    # (Ud, Uq, |V2|). Without an angle U is real: no cos/sin.
    if has_angle:
        return vv * math.cos(dd), vv * math.sin(dd), b2
    return vv, 0.0, b2


@numba.njit(cache=True, nogil=True)
def _rk4(ed, eq, w, ua, ub, um, hs, rs, xp, dx, tp, h, wb, t0, a, b, c,
         nb):  # pragma: no cover - compiled  # fmt: skip
    # One classical RK4 step; ua, um, ub: (Ud, Uq, |V2|) at the start, middle and end.
    # Returns the state at the end and the first stage (the derivative at the start).
    k1 = _rhs(ed, eq, w, ua[0], ua[1], ua[2], rs, xp, dx, tp, h, wb, t0, a, b, c, nb)
    ed, eq, w = _rk4_from(k1, ed, eq, w, ub, um, hs, rs, xp, dx, tp, h, wb, t0, a, b, c, nb)
    return ed, eq, w, k1


@numba.njit(cache=True, nogil=True)
def _has_angle(delta):  # pragma: no cover - compiled
    # Whether the input has an angle at all (else U is real: no cos/sin, see _u).
    for k in range(delta.size):
        if delta[k] != 0.0:
            return True
    return False


@numba.njit(cache=True, nogil=True)
def _on_chord(t, v, delta, v2, k, j):  # pragma: no cover - compiled
    # Whether the samples strictly between k and j lie on the straight line from k to j
    # (then the piecewise-linear input is one linear piece over [t_k, t_j]); |V2| too
    # where it is given (v2 None: none).
    for i in range(k + 1, j):
        fr = (t[i] - t[k]) / (t[j] - t[k])
        if abs(v[i] - (v[k] + fr * (v[j] - v[k]))) > LINEAR_TOL:
            return False
        if abs(delta[i] - (delta[k] + fr * (delta[j] - delta[k]))) > LINEAR_TOL:
            return False
        if _off_chord(v2, i, k, j, fr):
            return False
    return True


# The braking chosen by the type of ``v2`` when a caller is compiled (None: a balanced
# input, each helper below a constant and the term gone from the code, as fast as before
# it; an array: the term). Plain Python stubs, implemented by overload for numba.
def _at(v2, k):  # pragma: no cover - compiled only
    """|V2| at sample k, 0.0 without one."""


def _circuit_if(v2, xp, dx, tp, wb):  # pragma: no cover - compiled only
    """The braking circuit (:func:`brake_circuit`) where there is a V2, None without."""


def _merged_v2(t, v2, real, window, n_m):  # pragma: no cover - compiled only
    """|V2| at integrate_window_v2_into's merged knots (_merge_bounds on V2 alone)."""


def _off_chord(v2, i, k, j, fr):  # pragma: no cover - compiled only
    """Whether |V2| at i leaves the chord from k to j (never without a V2)."""


def _brake_of(b2, w, rs, nb):  # pragma: no cover - compiled only
    """The braking torque at |V2| ``b2`` (:func:`brake_torque`), 0.0 where nb is None."""


def _none(x) -> bool:  # pragma: no cover - at numba's typing
    return isinstance(x, (types.NoneType, types.Omitted)) or x is None


@overload(_at, jit_options={"cache": True, "nogil": True})
def _at_impl(v2, k):  # pragma: no cover - at numba's typing
    if _none(v2):
        return lambda v2, k: 0.0
    return lambda v2, k: v2[k]


@overload(_circuit_if, jit_options={"cache": True, "nogil": True})
def _circuit_if_impl(v2, xp, dx, tp, wb):  # pragma: no cover - at numba's typing
    if _none(v2):
        return lambda v2, xp, dx, tp, wb: None
    return lambda v2, xp, dx, tp, wb: brake_circuit(xp, dx, tp, wb)


@overload(_merged_v2, jit_options={"cache": True, "nogil": True})
def _merged_v2_impl(t, v2, real, window, n_m):  # pragma: no cover - at numba's typing
    if _none(v2):
        return lambda t, v2, real, window, n_m: None

    def impl(t, v2, real, window, n_m):
        nr = real.size
        out = np.zeros(n_m)
        _merge_bounds(t, v2, np.zeros(t.size), real, window, np.empty(n_m), out, np.empty(n_m),
                      np.empty(nr, dtype=np.int64), np.empty(nr, dtype=np.int64))  # fmt: skip
        return out

    return impl


@overload(_off_chord, jit_options={"cache": True, "nogil": True})
def _off_chord_impl(v2, i, k, j, fr):  # pragma: no cover - at numba's typing
    if _none(v2):
        return lambda v2, i, k, j, fr: False
    return lambda v2, i, k, j, fr: abs(v2[i] - (v2[k] + fr * (v2[j] - v2[k]))) > LINEAR_TOL


@overload(_brake_of, jit_options={"cache": True, "nogil": True})
def _brake_of_impl(b2, w, rs, nb):  # pragma: no cover - at numba's typing
    if _none(nb):
        return lambda b2, w, rs, nb: 0.0

    def impl(b2, w, rs, nb):
        # |V2| = 0 (every row off the fault's unbalance): no torque, to the bit (0 * x).
        if b2 == 0.0:
            return 0.0
        return brake_torque(b2, w, rs, nb[0], nb[1], nb[2])

    return impl


@numba.njit(cache=True, nogil=True)
def _held_until(v, delta, v2, k, n):  # pragma: no cover - compiled
    # The last knot from k on at which the input still holds k's value, to the bit.
    e = k
    while (
        e + 1 < n and v[e + 1] == v[k] and delta[e + 1] == delta[k] and _at(v2, e + 1) == _at(v2, k)
    ):
        e += 1
    return e


@numba.njit(cache=True, nogil=True)
def _rest(v, delta, v2, k, e, has_angle, rs, xp, dx, tp, wb, t0, a, b, c):  # pragma: no cover
    # The steady state (Ed', Eq', w) at knot k's input, held to knot e: NaNs where the
    # stretch is shorter than REST_KNOTS, the input brakes (|V2| > 0: the balanced steady
    # state is not its own) or there is no steady state (stalled). In the frame of the
    # states: the flux turned by the voltage's angle.
    if e - k < REST_KNOTS or _at(v2, k) != 0.0:
        return math.nan, math.nan, math.nan
    ed, eq, w, _, _ = steady_state(rs, xp, dx, tp, wb, v[k], t0, a, b, c, 1.0)
    if has_angle and delta[k] != 0.0:
        cs, sn = math.cos(delta[k]), math.sin(delta[k])
        ed, eq = ed * cs - eq * sn, ed * sn + eq * cs
    return ed, eq, w


@numba.njit(cache=True, nogil=True)
def _near_rest(f, tp, h):  # pragma: no cover - compiled
    # Whether the state's rate of change f = (dEd', dEq', dw) bounds its distance to rest
    # below REST_NEAR (REST_NEAR's comment); only then is the steady state solved.
    return (abs(f[0]) + abs(f[1])) * tp + abs(f[2]) * 2.0 * h <= REST_NEAR


@numba.njit(cache=True, nogil=True)
def _at_rest(ed, eq, w, rest):  # pragma: no cover - compiled
    # Whether the state is within REST_TOL of the held input's steady state (NaN: never).
    return (abs(ed - rest[0]) <= REST_TOL and abs(eq - rest[1]) <= REST_TOL
            and abs(w - rest[2]) <= REST_TOL)  # fmt: skip


@numba.njit(cache=True, nogil=True)
def integrate_into(t, v, delta, rs, xp, dx, tp, h, wb, t0, a, b, c, h_max, p, q, states):
    """The compiled core of :func:`integrate`, for compiled callers (the composite's density).

    Writes P, Q and the states into ``p``, ``q``, ``states``; returns False when there is
    no steady state or the states leave the finite numbers. ``h_max`` is the sub-step
    itself (:func:`step_size` applied by the caller). No negative sequence
    (:func:`integrate_v2_into` with its braking torque).
    """  # pragma: no cover - compiled
    return integrate_v2_into(t, v, delta, None, rs, xp, dx, tp, h, wb, t0, a, b, c, h_max,
                             p, q, states)  # fmt: skip


@numba.njit(cache=True, nogil=True)
def integrate_v2_into(t, v, delta, v2, rs, xp, dx, tp, h, wb, t0, a, b, c, h_max, p, q,
                      states):  # fmt: skip
    """:func:`integrate_into` with the negative sequence's braking torque (:func:`brake_torque`).

    ``v2``: ``|V2|`` at the samples, linear between them as V is (None: none, compiled
    apart, the arithmetic of a balanced input to the bit). The steady state at the first
    sample is the balanced one (a row below ``parts.NEG_SEQ_MIN`` brakes with 0).
    """  # pragma: no cover - compiled
    n = t.size
    ed, eq, w, p0, q0 = steady_state(rs, xp, dx, tp, wb, v[0], t0, a, b, c,
                                     start_speed(t, v, delta, wb))  # fmt: skip
    if not math.isfinite(ed):
        return False
    den = rs * rs + xp * xp
    has_angle = _has_angle(delta)
    nb = _circuit_if(v2, xp, dx, tp, wb)
    states[0, 0], states[1, 0], states[2, 0] = ed, eq, w
    tau_fast = tp * xp / (xp + dx)
    fine_until = -math.inf
    held, solved, rest = -1, True, (math.nan, math.nan, math.nan)
    k = 0
    while k < n - 1:
        if k >= held:  # a new stretch of the input: how long it holds
            held = _held_until(v, delta, v2, k, n)
            rest = (math.nan, math.nan, math.nan)
            solved = held - k < REST_KNOTS  # too short: nothing to solve
        if not solved:  # its rest once the state is near it (REST_NEAR)
            uk = _u(v[k], delta[k], has_angle, _at(v2, k))
            if _near_rest(_rhs(ed, eq, w, uk[0], uk[1], uk[2], rs, xp, dx, tp, h, wb, t0, a, b, c,
                               nb), tp, h):  # fmt: skip
                rest = _rest(v, delta, v2, k, held, has_angle, rs, xp, dx, tp, wb, t0, a, b, c)
                solved = True
        if held > k and _at_rest(ed, eq, w, rest):  # REST_TOL: held to the stretch's end
            for i in range(k + 1, held + 1):
                states[0, i], states[1, i], states[2, i] = ed, eq, w
            k = held
            continue
        # Samples closer than the step: one RK4 step over several of them where the input
        # is one linear piece there (a sampled sag's corners are never inside a step), the
        # states between by cubic Hermite interpolation (smooth states, O(h^4) error).
        j = k + 1
        fine = t[k] < fine_until
        turn = wb * abs(1.0 - w)  # the rotor frame's speed against V's (OSC_STEP)
        while (
            not fine
            and j + 1 < n
            and t[j + 1] - t[k] <= h_max * (1.0 + 1e-9)
            and (t[j + 1] - t[k]) * turn <= OSC_STEP
            and _on_chord(t, v, delta, v2, k, j + 1)
        ):
            j += 1
        bk = _at(v2, k)
        bj = _at(v2, j)
        if j > k + 1:
            span = t[j] - t[k]
            ua = _u(v[k], delta[k], has_angle, bk)
            ub = _u(v[j], delta[j], has_angle, bj)
            um = _u(0.5 * (v[k] + v[j]), 0.5 * (delta[k] + delta[j]), has_angle, 0.5 * (bk + bj))
            e0, q0_, w0 = ed, eq, w
            ed, eq, w, f0 = _rk4(ed, eq, w, ua, ub, um, span, rs, xp, dx, tp, h, wb, t0, a, b, c,
                                 nb)  # fmt: skip
            f1 = _rhs(ed, eq, w, ub[0], ub[1], ub[2], rs, xp, dx, tp, h, wb, t0, a, b, c, nb)
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
            m = _substeps(span, h_k, jump, turn)
            if m == 0:
                return False
            if jump > STEP_JUMP:
                fine_until = t[j] + FAST_SPAN * tau_fast
            hs = span / m
            for r in range(m):
                fa, fm, fb = r / m, (r + 0.5) / m, (r + 1.0) / m
                ua = _u(v[k] + fa * (v[j] - v[k]), delta[k] + fa * (delta[j] - delta[k]), has_angle,
                        bk + fa * (bj - bk))  # fmt: skip
                um = _u(v[k] + fm * (v[j] - v[k]), delta[k] + fm * (delta[j] - delta[k]), has_angle,
                        bk + fm * (bj - bk))  # fmt: skip
                ub = _u(v[k] + fb * (v[j] - v[k]), delta[k] + fb * (delta[j] - delta[k]), has_angle,
                        bk + fb * (bj - bk))  # fmt: skip
                ed, eq, w, _ = _rk4(ed, eq, w, ua, ub, um, hs, rs, xp, dx, tp, h, wb, t0, a, b, c,
                                    nb)  # fmt: skip
        if not (math.isfinite(ed) and math.isfinite(eq) and math.isfinite(w)):
            return False
        states[0, j], states[1, j], states[2, j] = ed, eq, w
        k = j
    for i in range(n):
        # The algebraic output exactly at every sample, from the states and the sampled U.
        ud, uq, _ = _u(v[i], delta[i], has_angle)
        p[i], q[i] = _pq_at(states[0, i], states[1, i], ud, uq, rs, xp, den)
    return True


@numba.njit(cache=True, nogil=True)
def _rk4_from(k1, ed, eq, w, ub, um, hs, rs, xp, dx, tp, h, wb, t0, a, b, c,
              nb):  # pragma: no cover - compiled  # fmt: skip
    # _rk4 with its first stage given: the derivative at the start, which the window
    # path has already (the previous sub-step's end), so each sub-step costs four
    # right-hand sides with the end derivative the Hermite mid-state needs.
    k2 = _rhs(ed + 0.5 * hs * k1[0], eq + 0.5 * hs * k1[1], w + 0.5 * hs * k1[2], um[0], um[1],
              um[2], rs, xp, dx, tp, h, wb, t0, a, b, c, nb)  # fmt: skip
    k3 = _rhs(ed + 0.5 * hs * k2[0], eq + 0.5 * hs * k2[1], w + 0.5 * hs * k2[2], um[0], um[1],
              um[2], rs, xp, dx, tp, h, wb, t0, a, b, c, nb)  # fmt: skip
    k4 = _rhs(ed + hs * k3[0], eq + hs * k3[1], w + hs * k3[2], ub[0], ub[1], ub[2],
              rs, xp, dx, tp, h, wb, t0, a, b, c, nb)  # fmt: skip
    ed += hs / 6.0 * (k1[0] + 2.0 * k2[0] + 2.0 * k3[0] + k4[0])
    eq += hs / 6.0 * (k1[1] + 2.0 * k2[1] + 2.0 * k3[1] + k4[1])
    w += hs / 6.0 * (k1[2] + 2.0 * k2[2] + 2.0 * k3[2] + k4[2])
    return ed, eq, w


@numba.njit(cache=True, nogil=True)
def _pq_at(ed, eq, ud, uq, rs, xp, den):  # pragma: no cover - compiled
    # The algebraic output: P, Q at state (Ed', Eq') and terminal voltage (Ud, Uq).
    dd = ud - ed
    dq = uq - eq
    id_ = (rs * dd + xp * dq) / den
    iq = (rs * dq - xp * dd) / den
    return ud * id_ + uq * iq, uq * id_ - ud * iq


@numba.njit(cache=True, nogil=True)
def _bounds_order(bounds):  # pragma: no cover - compiled
    # np.argsort(bounds, kind="mergesort") (stable: ties by index), in one pass where the
    # windows' lower bounds (even entries) and upper bounds (odd) each increase, as they
    # do for samples in time order: the merge of two sorted lists. A mergesort of the
    # 2,402 bounds of a 20 s event at 60/s was 27 of the 41 us of the whole merge.
    m = bounds.size
    for k in range(2, m):
        if bounds[k] < bounds[k - 2]:
            return np.argsort(bounds, kind="mergesort")
    order = np.empty(m, dtype=np.int64)
    i, j = 0, 1  # the next lower bound's index, the next upper bound's
    for k in range(m):
        if j >= m or (i < m and (bounds[i] < bounds[j] or (bounds[i] == bounds[j] and i < j))):
            order[k] = i
            i += 2
        else:
            order[k] = j
            j += 2
    return order


@numba.njit(cache=True, nogil=True)
def _merge_bounds(t, v, delta, real, window, tm, vm, dm, lo_pos, hi_pos):  # pragma: no cover
    # The input's knots merged with every real sample's window bounds t_r -+ W/2 (the
    # input linear between knots there, held at its last value after the last knot).
    # Returns the merged length; lo_pos/hi_pos: each window's bounds in the merged arrays
    # (lo_pos -1 when the bound precedes the first knot: steady state there).
    n = t.size
    nr = real.size
    half = 0.5 * window
    bounds = np.empty(2 * nr)
    for i in range(nr):
        bounds[2 * i] = t[real[i]] - half
        bounds[2 * i + 1] = t[real[i]] + half
    order = _bounds_order(bounds)
    where = np.empty(2 * nr, dtype=np.int64)
    m = 0
    k = 0
    tol = 1e-12 * max(1.0, abs(t[n - 1]))
    for jj in range(2 * nr):
        b = bounds[order[jj]]
        if b < t[0] - tol:
            where[order[jj]] = -1
            continue
        # Knots up to b.
        while k < n and t[k] <= b + tol:
            tm[m], vm[m], dm[m] = t[k], v[k], delta[k]
            m += 1
            k += 1
        if m > 0 and abs(tm[m - 1] - b) <= tol:
            where[order[jj]] = m - 1
            continue
        if k >= n:
            vb, db = v[n - 1], delta[n - 1]
        else:
            fr = (b - t[k - 1]) / (t[k] - t[k - 1])
            vb = v[k - 1] + fr * (v[k] - v[k - 1])
            db = delta[k - 1] + fr * (delta[k] - delta[k - 1])
        tm[m], vm[m], dm[m] = b, vb, db
        where[order[jj]] = m
        m += 1
    while k < n:
        tm[m], vm[m], dm[m] = t[k], v[k], delta[k]
        m += 1
        k += 1
    for i in range(nr):
        lo_pos[i] = where[2 * i]
        hi_pos[i] = where[2 * i + 1]
    return m


@numba.njit(cache=True, nogil=True)
def integrate_window_into(
    t, v, delta, real, window, rs, xp, dx, tp, h, wb, t0, a, b, c, h_max, p, q
):  # pragma: no cover - compiled
    """:func:`integrate_window_v2_into` without a negative sequence (a balanced input)."""
    return integrate_window_v2_into(t, v, delta, None, real, window, rs, xp, dx, tp, h, wb,
                                    t0, a, b, c, h_max, p, q)  # fmt: skip


@numba.njit(cache=True, nogil=True)
def integrate_window_v2_into(
    t, v, delta, v2, real, window, rs, xp, dx, tp, h, wb, t0, a, b, c, h_max, p, q
):  # pragma: no cover - compiled
    """Window means of the motor's P and Q: the mean over ``[t_r - W/2, t_r + W/2]``.

    The samples ``real`` (indices into ``t``) are read as ``W``-second window means
    centred on their stamps, as a phasor estimator (IEEE C37.118) gives them; ``t, v,
    delta`` is the input as :func:`integrate_into` takes it (the voltage linear between
    knots). Before ``t[0]`` the motor is in its steady state at ``V_0``; after the last
    knot the input holds its last value. Writes ``p``, ``q`` (one per real sample);
    returns False as :func:`integrate_into` does.

    The same RK4 steps as :func:`integrate_into` (every window bound is a knot, and no
    step spans several knots), with the integrals of P and Q accumulated by Simpson's
    rule on every sub-step: the mid-step state is the cubic Hermite interpolant of the
    end states and their derivatives (error O(h^5) per sub-step, the fine sub-steps of
    a step's fast flux transient included). ``v2``: ``|V2|`` at the knots, the braking
    torque's drive as in :func:`integrate_v2_into` (None: none).
    """
    nr = real.size
    n_m = t.size + 2 * nr
    tm, vm, dm = np.empty(n_m), np.empty(n_m), np.empty(n_m)
    lo_pos = np.empty(nr, dtype=np.int64)
    hi_pos = np.empty(nr, dtype=np.int64)
    n = _merge_bounds(t, v, delta, real, window, tm, vm, dm, lo_pos, hi_pos)
    bm = _merged_v2(t, v2, real, window, n_m)  # |V2| at the same merged knots
    nb = _circuit_if(v2, xp, dx, tp, wb)
    ed, eq, w, p_ss, q_ss = steady_state(rs, xp, dx, tp, wb, vm[0], t0, a, b, c,
                                         start_speed(t, v, delta, wb))  # fmt: skip
    if not math.isfinite(ed):
        return False
    den = rs * rs + xp * xp
    has_angle = _has_angle(dm[:n])
    # Running integrals of P and Q from tm[0], at every merged knot.
    ip, iq_ = np.empty(n), np.empty(n)
    ip[0], iq_[0] = 0.0, 0.0
    tau_fast = tp * xp / (xp + dx)
    fine_until = -math.inf
    ua = _u(vm[0], dm[0], has_angle, _at(bm, 0))
    f0 = _rhs(ed, eq, w, ua[0], ua[1], ua[2], rs, xp, dx, tp, h, wb, t0, a, b, c, nb)
    pa, qa = _pq_at(ed, eq, ua[0], ua[1], rs, xp, den)
    sp, sq = 0.0, 0.0
    held, solved, rest = -1, True, (math.nan, math.nan, math.nan)
    k = 0
    while k < n - 1:
        if k >= held:  # as integrate_v2_into: a motor at rest is held (REST_TOL)
            held = _held_until(vm, dm, bm, k, n)
            rest = (math.nan, math.nan, math.nan)
            solved = held - k < REST_KNOTS
        if not solved and _near_rest(f0, tp, h):  # f0: the rate at knot k's input
            rest = _rest(vm, dm, bm, k, held, has_angle, rs, xp, dx, tp, wb, t0, a, b, c)
            solved = True
        if held > k and _at_rest(ed, eq, w, rest):
            for i in range(k + 1, held + 1):
                sp += pa * (tm[i] - tm[i - 1])
                sq += qa * (tm[i] - tm[i - 1])
                ip[i], iq_[i] = sp, sq
            k = held
            continue
        j = k + 1
        fine = tm[k] < fine_until
        span = tm[j] - tm[k]
        jump = max(abs(vm[j] - vm[k]), abs(dm[j] - dm[k]))
        h_k = min(h_max, tau_fast / FAST_STEPS) if fine else h_max
        m = _substeps(span, h_k, jump, wb * abs(1.0 - w))
        if m == 0:
            return False
        if jump > STEP_JUMP:
            fine_until = tm[j] + FAST_SPAN * tau_fast
        hs = span / m
        bk = _at(bm, k)
        bj = _at(bm, j)
        for r in range(m):
            fm, fb = (r + 0.5) / m, (r + 1.0) / m
            um = _u(vm[k] + fm * (vm[j] - vm[k]), dm[k] + fm * (dm[j] - dm[k]), has_angle,
                    bk + fm * (bj - bk))  # fmt: skip
            ub = _u(vm[k] + fb * (vm[j] - vm[k]), dm[k] + fb * (dm[j] - dm[k]), has_angle,
                    bk + fb * (bj - bk))  # fmt: skip
            e0, q0_ = ed, eq
            # The start's derivative f0 is the previous sub-step's end (the input is
            # continuous): RK4's first stage.
            ed, eq, w = _rk4_from(f0, ed, eq, w, ub, um, hs, rs, xp, dx, tp, h, wb, t0, a, b, c,
                                  nb)  # fmt: skip
            f1 = _rhs(ed, eq, w, ub[0], ub[1], ub[2], rs, xp, dx, tp, h, wb, t0, a, b, c, nb)
            # Cubic Hermite at the mid-step: (y0 + y1) / 2 + h (f0 - f1) / 8.
            em = 0.5 * (e0 + ed) + 0.125 * hs * (f0[0] - f1[0])
            qm_ = 0.5 * (q0_ + eq) + 0.125 * hs * (f0[1] - f1[1])
            pm, qmm = _pq_at(em, qm_, um[0], um[1], rs, xp, den)
            pb, qb = _pq_at(ed, eq, ub[0], ub[1], rs, xp, den)
            sp += hs / 6.0 * (pa + 4.0 * pm + pb)
            sq += hs / 6.0 * (qa + 4.0 * qmm + qb)
            pa, qa, f0 = pb, qb, f1
        if not (math.isfinite(ed) and math.isfinite(eq) and math.isfinite(w)):
            return False
        ip[j], iq_[j] = sp, sq
        k = j
    for i in range(nr):
        hi = hi_pos[i]
        lo = lo_pos[i]
        # A bound before the first knot: the steady state's power over the part before it.
        before = tm[0] - (t[real[i]] - 0.5 * window)
        jp = ip[lo] if lo >= 0 else -p_ss * before
        jq = iq_[lo] if lo >= 0 else -q_ss * before
        p[i] = (ip[hi] - jp) / window
        q[i] = (iq_[hi] - jq) / window
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
    window_s: float = 0.0,
    real: NDArray[np.int64] | None = None,
    v2: NDArray[np.float64] | None = None,
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64] | None] | None:
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
    window_s : float
        0 (default): ``p``, ``q`` at the sample instants. Above 0: each sample's mean over
        ``[t_k - window_s / 2, t_k + window_s / 2]`` (:func:`integrate_window_into`), as a
        phasor estimator stamped at its window's centre gives it.
    real : ndarray of int, optional
        The samples whose values (or window means) are wanted, the others being knots of
        the input only; ``p``, ``q`` (and the states) then have one entry per ``real``
        sample. Default: every sample.
    v2 : ndarray, shape (n,), optional
        ``|V2|`` (p.u.) at the samples: the negative sequence's braking torque
        (:func:`brake_torque`) in the swing equation. None: a balanced input.

    Returns
    -------
    (p, q, states) or None
        ``p``, ``q`` shaped (n,) (or one per ``real`` sample) and the states ``(Ed', Eq',
        w)`` shaped (3, n) at the same samples (None for window means); None when the
        load torque exceeds the breakdown torque at ``v[0]`` (no steady state) or the
        integration leaves the finite numbers.
    """
    t = np.ascontiguousarray(t, dtype=float)
    v = np.ascontiguousarray(v, dtype=float)
    # The steady state puts the first sample's voltage on the d axis: angles are relative.
    d = np.zeros_like(t) if delta is None else np.asarray(delta, dtype=float) - float(delta[0])
    d = np.ascontiguousarray(d)
    n = t.size
    a, b, c = (float(x) for x in torque)
    motor = (float(rs), float(xp), float(dx), float(tp_s), float(h_s),
             2.0 * math.pi * float(f_hz), float(t0), a, b, c,
             float(step_size(float(tp_s), float(h_max))))  # fmt: skip
    u2 = None if v2 is None else np.ascontiguousarray(v2, dtype=float)
    if window_s > 0.0:
        real = np.arange(n, dtype=np.int64) if real is None else np.asarray(real, np.int64)
        p, q = np.empty(real.size), np.empty(real.size)
        ok = integrate_window_v2_into(t, v, d, u2, real, float(window_s), *motor, p, q)
        return (p, q, None) if ok else None
    p, q, states = np.empty(n), np.empty(n), np.empty((3, n))
    if not integrate_v2_into(t, v, d, u2, *motor, p, q, states):
        return None
    if real is None:
        return p, q, states
    return p[real], q[real], states[:, real]
