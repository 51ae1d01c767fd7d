"""Many draws of a model of parts played through one voltage, in compiled calls.

:func:`loadbayes.models.parts_predict.predict_parts` is the readable reference: one
draw, the feeder's loop ``V_L = V - Z I`` solved by waveform relaxation in NumPy, each
sweep driving the parts through ``PartsModel.load_columns``. A prediction plays a
thousand draws, and each takes tens of sweeps: in NumPy the Python around the compiled
motor integrators cost as much as the integrators. :func:`play_draws` does the same
arithmetic (the same sweeps, the same stopping rule, the same damped second try) in one
``numba`` function per draw: the motors through ``parts_kernel.motor_into`` (the
likelihood's own motor loop: at the samples or as window means, across gaps, braked by
the fault's negative sequence where it has one, ``parts_predict.brake_of``), motor D through
``parts._motor_d``, the electronics, the static part; then what a prediction reads off
the converged load bus: whether motor D stalled (its trajectory against one that never
stalls, as ``fit/composite/predict.py`` decided it) and the electronics' share tripped.
The draws run in threads (the kernels release the GIL), each draw on its own, so the
answer does not depend on the number of threads. Complex division is NumPy's (Smith's
rule, as its ``divide`` loop), so the sweeps see the reference's numbers to rounding:
``tests/unit/test_parts_play.py`` checks every field against
``parts_predict.play_reference`` (``predict_parts`` draw by draw) to 1e-8.

Where the plain and the damped sweeps do not settle, two more tries (plain, then damped
at 0.5; ``parts_loop.SOLVE_SWEEPS`` each) solve every sample's load bus jointly with the
static part's draw (``parts_loop.pv_root``: the P-V equation of that sample, the rest of
the load held as a constant impedance there), so the sweeps carry only the dynamic
parts' lag; a settled loop must then be the one a simulator's step reaches from the
previous sample (``parts_loop.continues``), not one jumping between two operating points.
Where none of the four settles, a fifth try marches in time (``parts_march``: sample by
sample from the last, the motors integrated with it, each sample's load bus by Newton
from the previous one's), as a simulator does: it plays, or collapses where no root
continues from the previous one (the load's P-V nose below the feeder's) or the root
falls below :data:`COLLAPSE_RATIO`; it fails only where its numbers leave the finite
ones. On the tests' cmld-lite fit (``cmld_lite_nc``, 150 draws) 3 draws failed
numerically at 70 % and 3 at 80 % before the march; after it none (5 play, 1
collapses), and where the sweeps settle the march gives their numbers to the sweeps'
stopping rule (``tests/integration/test_predict_march.py``). Draws that settled before
keep their numbers byte for byte: each new try runs only where the ones before failed
(sha256 of every field of the 115 and 95 settled draws at 70 and 80 %, before and after).

The cost is the motor integrators' (``benchmarks/bench_predict.py``: about 2.5 ms of
CPU a draw of ``cmld-lite`` through a 1 s record at 240/s, some 28 sweeps of two motors;
the NumPy loop took twice that). A draw that no sweep settles pays for all four tries:
on the fixture's 1.8 s record at 80 % (one thread, load 4.5-5) 146 ms of CPU a
collapsing draw and 55 ms a marched one that plays, against 20 ms a settled one; the
march alone takes 5-8 ms a draw, settled or not (``predict`` at 80 %, 150 draws: 9.1-9.8
s of CPU before the march, 9.1-10.4 s after, within the machine's noise); compiling it
adds about 15 s to the first call with an empty numba cache (``predict`` at 80 %, 20
draws: 48.5 s of CPU before, 63.3 s after). Marching every
draw first would be cheaper, but would move each settled answer by up to the sweeps'
tolerance (1e-7 in ``V_L``; P and Q by a median 1e-7 to 3e-7 on the fixture), and is
not done here: a prediction keeps the numbers it gave.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass

import numba
import numpy as np
from numpy.typing import NDArray

from loadbayes.core.parallel import num_threads, run_threads
from loadbayes.measurements.record import EventRecord
from loadbayes.models.motor_kernel import H_MAX_S, TP_STEPS
from loadbayes.models.part_priors import MOTOR_CLASSES
from loadbayes.models.parts import MOTOR_D_DEFAULTS, _motor_d, gaps_of
from loadbayes.models.parts_loop import (
    SOLVE_SWEEPS,
    brake_of,
    cdiv,
    columns,
    continues,
    pv_root,
)
from loadbayes.models.parts_march import marched

__all__ = [
    "COLLAPSES",
    "COLLAPSE_RATIO",
    "FAILS",
    "NO_OPERATING_POINT",
    "PLAYS",
    "Played",
    "play_draws",
]

#: ``Played.why``: the loop converged (the draw plays through the fault); ...
PLAYS = 0
#: ... it did not (its sweeps did not settle, in none of the four tries, and the march
#: in time did not reach the end) after a sweep or the march drove the load bus below
#: :data:`COLLAPSE_RATIO` of the recorded bus's voltage, or the march found no root
#: continuing from the previous sample's (``parts_march``): what the load draws through
#: the feeder has no voltage to settle at, the model's voltage collapse (``Played.low``);
#: ...
COLLAPSES = 1
#: ... it did not, the load bus held above that: a numerical failure, not a collapse
#: (the march's numbers left the finite ones); ...
FAILS = 2
NO_OPERATING_POINT = 3
#: The load bus's voltage, as a share of the recorded bus's at the same sample, below
#: which a failed loop is a collapse: the feeder then drops four fifths of the voltage,
#: a current no running load draws (a stalled motor draws 5-7 times its rating).
#: Measured (``tests/integration/test_predict_collapse.py``): draws that collapse reach
#: 0.001-0.024, draws that play stay above 0.82.
COLLAPSE_RATIO = 0.2

_D_KEYS = tuple(MOTOR_D_DEFAULTS)
_VSTALL, _TSTALL = _D_KEYS.index("vstall"), _D_KEYS.index("tstall")


@dataclass(frozen=True)
class Played:
    """What :func:`play_draws` returns, one row per draw (rows of failed draws are NaN).

    ``p, q``: the recorded bus's P, Q; ``vl``: the load bus's ``|V_L|``; ``ok``: the loop
    converged (False where a motor has no steady state or the sweeps do not settle);
    ``stalled``: motor D stalled; ``tripped``: the electronics' share tripped at the
    end; ``iterations``: the sweeps of the try that converged (marched: the samples);
    ``why``: :data:`PLAYS`, :data:`COLLAPSES`, :data:`FAILS` or :data:`NO_OPERATING_POINT`
    (where a motor has no steady state at the operating point the loop's first sweep fails too:
    ``fit/composite/predict_outcome.py`` tells them apart by a fault-free record);
    ``low``: the lowest ``|V_L| / |V|`` any sweep (or the march) drove the parts with.
    """

    p: NDArray[np.float64]
    q: NDArray[np.float64]
    vl: NDArray[np.float64]
    ok: NDArray[np.bool_]
    stalled: NDArray[np.bool_]
    tripped: NDArray[np.float64]
    iterations: NDArray[np.int64]
    why: NDArray[np.int64]
    low: NDArray[np.float64]


@numba.njit(cache=True, nogil=True)
def _relax(t, v, has_angle, gap, steps, window_s, z, s0, q_sh, motors, shares, a_p, d_on,
           dp, el_on, vd1, vd2, frcel, tol, max_it, damp, po, qo, u2, low,
           solve):  # pragma: no cover - compiled  # fmt: skip
    # One try of parts_predict.predict_parts' loop: the sweeps it took, -1 where a motor
    # has no steady state or the loop leaves the finite numbers, 0 where it does not settle,
    # -2 where (solve: each sample's V_L by parts_loop.pv_root) its last sweep found no
    # root at some sample: the load's P-V nose below the feeder's, a collapse.
    n = t.size
    i0 = cdiv(s0, v[0]).conjugate()
    vl0 = v[0] - z * i0
    s_l0 = s0 - z * abs(i0) ** 2  # the load bus's S before the event
    vl = np.empty(n, dtype=np.complex128)
    cur = np.empty(n, dtype=np.complex128)
    for k in range(n):
        vl[k] = v[k] - z * i0
    vm, dl = np.empty(n), np.zeros(n)
    col_p, col_qp, pm, qm = np.empty(n), np.empty(n), np.empty(n), np.empty(n)
    states = np.empty((3, n))
    ddv, root = np.zeros(n, dtype=np.complex128), np.full(n, math.nan)
    m_vl0 = abs(vl0)
    f_s = shares[shares.size - 1]  # the static part's P and Q as polynomials of |V_L|
    ap0, ap1, ap2 = s_l0.real * f_s * a_p[0], s_l0.real * f_s * a_p[1], s_l0.real * f_s * a_p[2]
    aq0, aq1, aq2 = s_l0.imag * q_sh[0], s_l0.imag * q_sh[1], s_l0.imag * q_sh[2]
    for it in range(1, max_it + 1):
        for k in range(n):
            vm[k] = abs(vl[k])
            if abs(v[k]) > 0.0:  # the lowest |V_L| / |V| a sweep drove the parts with
                low[0] = min(low[0], vm[k] / abs(v[k]))
        if has_angle:
            first = math.atan2(vl[0].imag, vl[0].real)
            for k in range(n):
                dl[k] = math.atan2(vl[k].imag, vl[k].real) - first
        if not columns(t, vm, dl, u2, gap, steps, window_s, motors, shares, a_p, d_on, dp,
                        el_on, vd1, vd2, frcel, col_p, col_qp, pm, qm, states):  # fmt: skip
            return -1
        moved = 0.0
        bad = False
        nose = False
        for k in range(n):
            xl = vm[k] / m_vl0
            p_l = s_l0.real * col_p[k]
            q_l = s_l0.real * col_qp[k] + s_l0.imag * (q_sh[0] * xl * xl + q_sh[1] * xl + q_sh[2])
            cur[k] = cdiv(complex(p_l, q_l), vl[k]).conjugate()
            new = v[k] - z * cur[k]
            if solve and vm[k] > 0.0 and abs(v[k]) > 0.0:  # the sample's loop, solved
                # settled where both the solve and the plain step stay (the loop's own
                # residual below tol too)
                moved = max(moved, abs(new - vl[k]))
                dd = complex(p_l - (ap0 * xl * xl + ap1 * xl + ap2),
                             q_l - (aq0 * xl * xl + aq1 * xl + aq2))  # fmt: skip
                mk = pv_root(vm[k], vm[k], abs(v[k]), z.conjugate(), dd,
                             ap0, ap1, ap2, aq0, aq1, aq2, m_vl0)  # fmt: skip
                ddv[k], root[k] = dd, mk
                if math.isfinite(mk):
                    x = mk / m_vl0
                    s_k = dd * (mk * mk / (vm[k] * vm[k])) + complex(
                        ap0 * x * x + ap1 * x + ap2, aq0 * x * x + aq1 * x + aq2)  # fmt: skip
                    new = cdiv(mk * mk + z.conjugate() * s_k, v[k].conjugate())
                else:  # no root from here: held, and the sweep does not settle
                    new = vl[k]
                    nose = True
            d = abs(new - vl[k])
            if not math.isfinite(d):
                bad = True
            elif d > moved:
                moved = d
            vl[k] = new if damp <= 0.0 else vl[k] + damp * (new - vl[k])
        if not bad and not nose and moved < tol:  # the fixed point: what the load draws drove it
            if solve and not continues(v, vm, ddv, root, z, ap0, ap1, ap2, aq0, aq1, aq2,
                                       m_vl0):  # fmt: skip
                return 0  # it jumps between two operating points: not settled
            for k in range(n):
                s = v[k] * cur[k].conjugate()
                po[k], qo[k] = s.real, s.imag
            return it
        if bad:
            return -1
    return -2 if nose else 0


@numba.njit(cache=True, nogil=True)
def _play_block(first, every, t, v, has_angle, gap, steps, window_s, z, s0, q_sh, motors, shares,
                a_p, d_on, dp, el_on, vd1, vd2, frcel, tol, p, q, vl_out, ok, stalled, tripped,
                its, v2, why, low, only_march):  # pragma: no cover - compiled  # fmt: skip
    # Draws first, first + every, ...: each one's loop (plain sweeps, then damped at 0.5
    # for up to 200 where they do not settle or leave the finite numbers, then each
    # sample solved, plain and damped, then marched in time; only_march: that alone), ``why`` its
    # outcome (PLAYS, COLLAPSES, FAILS, NO_OPERATING_POINT), then its stall and the
    # electronics' trip read off |V_L| at every sample, as fit/composite/predict.py read them.
    n = t.size
    never = dp[0].copy()
    vl = np.empty(n)
    for i in range(first, shares.shape[0], every):
        u2 = brake_of(v, v2, z[i], s0, motors[i], shares[i], d_on)
        got = -1
        why[i] = NO_OPERATING_POINT
        if np.all(np.isfinite(u2)) and not only_march:
            got = _relax(t, v, has_angle, gap, steps, window_s, z[i], s0, q_sh[i], motors[i],
                         shares[i], a_p[i], d_on, dp[i], el_on, vd1[i], vd2[i], frcel, tol, 60,
                         0.0, p[i], q[i], u2, low[i : i + 1], False)  # fmt: skip
            if got <= 0:  # damped, where the plain sweeps bounce or leave the finite numbers
                got = _relax(t, v, has_angle, gap, steps, window_s, z[i], s0, q_sh[i],
                             motors[i], shares[i], a_p[i], d_on, dp[i], el_on, vd1[i], vd2[i],
                             frcel, tol, 200, 0.5, p[i], q[i], u2, low[i : i + 1],
                             False)  # fmt: skip
            if got <= 0:  # neither settled: each sample's load bus solved with its load
                got = _relax(t, v, has_angle, gap, steps, window_s, z[i], s0, q_sh[i],
                             motors[i], shares[i], a_p[i], d_on, dp[i], el_on, vd1[i], vd2[i],
                             frcel, tol, SOLVE_SWEEPS, 0.0, p[i], q[i], u2, low[i : i + 1],
                             True)  # fmt: skip
            if got <= 0:  # and damped at 0.5, where those bounce
                got = _relax(t, v, has_angle, gap, steps, window_s, z[i], s0, q_sh[i],
                             motors[i], shares[i], a_p[i], d_on, dp[i], el_on, vd1[i], vd2[i],
                             frcel, tol, SOLVE_SWEEPS, 0.5, p[i], q[i], u2, low[i : i + 1],
                             True)  # fmt: skip
        if np.all(np.isfinite(u2)):
            if got <= 0:  # none settled: marched in time, sample by sample
                got = marched(t, v, has_angle, gap, steps, window_s, z[i], s0, q_sh[i],
                              motors[i], shares[i], a_p[i], d_on, dp[i], el_on, vd1[i], vd2[i],
                              frcel, p[i], q[i], u2, low[i : i + 1], COLLAPSE_RATIO)  # fmt: skip
            why[i] = PLAYS if got > 0 else (COLLAPSES if got == -2 or low[i] < COLLAPSE_RATIO
                                            else FAILS)  # fmt: skip
        its[i] = got
        if got <= 0:
            ok[i] = False
            p[i, :] = math.nan
            q[i, :] = math.nan
            vl_out[i, :] = math.nan
            continue
        ok[i] = True
        for k in range(n):
            cur = cdiv(complex(p[i, k], q[i, k]), v[k]).conjugate()
            vl[k] = abs(v[k] - z[i] * cur)
            vl_out[i, k] = vl[k]
        if d_on:
            never[:] = dp[i]
            never[_VSTALL] = -1.0
            ps = _motor_d_of(t, vl, dp[i])
            pn = _motor_d_of(t, vl, never)
            for k in range(n):
                if abs(ps[k] - pn[k]) > 1e-9:
                    stalled[i] = True
                    break
        if el_on:
            least = 1.0
            ramp = 1.0
            for k in range(n):
                ramp = min(max((vl[k] - vd2[i]) / (vd1[i] - vd2[i]), 0.0), 1.0)
                least = min(least, ramp)
            tripped[i] = 1.0 - (least + frcel * (ramp - least))


@numba.njit(cache=True, nogil=True)
def _motor_d_of(t, v, x):  # pragma: no cover - compiled
    # Motor D's P with its 17 constants in MOTOR_D_DEFAULTS' order.
    return _motor_d(t, v, x[0], x[1], x[2], x[3], x[4], x[5], x[6], x[7], x[8], x[9], x[10],
                    x[11], x[12], x[13], x[14], x[15], x[16])[0]  # fmt: skip


def play_draws(
    model,
    event: EventRecord,
    thetas: NDArray,
    p0: float,
    q0: float,
    q_shares: NDArray,
    thresholds: Mapping[str, NDArray] | None = None,
    *,
    tol: float = 1e-7,
    threads: int | None = None,
    only_march: bool = False,
) -> Played:
    """Each draw's P, Q at the recorded bus through ``event``'s voltage (see the docstring).

    Parameters
    ----------
    model : PartsModel
    event : EventRecord
        The recorded bus's voltage (and angle); its P, Q are not read.
    thetas : ndarray, shape (n, k)
        Draws of the model's ``theta_names``.
    p0, q0 : float
        The recorded bus's P and Q before the event (the operating point).
    q_shares : ndarray, shape (n, 3)
        Each draw's static Q split among ``x^2, x, 1``.
    thresholds : mapping of name to ndarray (n,), optional
        Each draw's ``vstall, tstall`` (motor D) and ``vd1, vd2`` (electronics); a name
        left out is the model's own value for every draw.
    threads : int, optional
        Threads to run the draws on (default ``core.parallel.num_threads()``).
    only_march : bool
        Skip the sweeps: every draw marched in time (``parts_march``; the tests compare
        the two).

    Returns
    -------
    Played
        ``p, q, vl`` shaped (n, T) at the kept rows (``model.kept``: all of them without a
        phasor window), the rest (n,).
    """
    th = np.atleast_2d(np.asarray(thetas, dtype=float))
    n = th.shape[0]
    c = model._split(th)
    keep, steps = model.drive_of(event)
    ev = event.take(keep) if keep.size < event.n else event
    wb = 2.0 * math.pi * model.f_hz
    motors = np.empty((n, len(model.motors), 11))
    for j, (m, logs) in enumerate(zip(model.motors, c["motors"], strict=True)):
        a, b, cc = MOTOR_CLASSES[m]["torque"]
        rs, xp, dx, tp, h, t0 = np.exp(logs).T
        motors[:, j] = np.column_stack([rs, xp, dx, tp, h, np.full(n, wb), t0, np.full(n, a),
                                        np.full(n, b), np.full(n, cc),
                                        np.minimum(H_MAX_S, tp / TP_STEPS)])  # fmt: skip
    x_fd = c["x_fd"] / float(np.hypot(p0, q0)) if model.feeder else np.zeros(n)
    z = complex(model.rx, 1.0) * x_fd
    base = {**MOTOR_D_DEFAULTS, **model.motor_d_params}
    dp = np.tile(np.array([float(base[k]) for k in _D_KEYS]), (n, 1))
    # A model that samples its thresholds carries them in theta; those given win.
    given = {k: np.broadcast_to(c[k], (n,)) for k in model.thresholds} | dict(thresholds or {})
    for key, col in (("vstall", _VSTALL), ("tstall", _TSTALL)):
        if key in given:
            dp[:, col] = np.broadcast_to(np.asarray(given[key], dtype=float), (n,))
    vd1 = np.broadcast_to(np.asarray(given.get("vd1", model.vd1), dtype=float), (n,)).copy()
    vd2 = np.broadcast_to(np.asarray(given.get("vd2", model.vd2), dtype=float), (n,)).copy()

    v = ev.v * np.exp(1j * (0 if ev.delta is None else ev.delta - ev.delta[0]))
    gap = gaps_of(ev.t, steps)
    p, q, vl = np.empty((n, ev.n)), np.empty((n, ev.n)), np.empty((n, ev.n))
    v2 = np.zeros(0, complex) if ev.v2 is None else np.ascontiguousarray(ev.v2, dtype=complex)
    ok, stalled = np.zeros(n, bool), np.zeros(n, bool)
    tripped, its = np.full(n, np.nan), np.zeros(n, np.int64)
    why, low = np.zeros(n, np.int64), np.full(n, np.inf)
    args = (np.ascontiguousarray(ev.t, dtype=float), np.ascontiguousarray(v),
            ev.delta is not None, gap, np.ascontiguousarray(steps, dtype=float),
            float(model.window_s), np.ascontiguousarray(z, dtype=complex), complex(p0, q0),
            np.ascontiguousarray(q_shares, dtype=float), motors,
            np.ascontiguousarray(c["f"]), np.ascontiguousarray(c["a_p"]), bool(model.motor_d),
            dp, bool(model.electronics), vd1, vd2, float(model.frcel), float(tol), p, q, vl, ok,
            stalled, tripped, its, v2, why, low, bool(only_march))  # fmt: skip
    k = max(1, min(threads or num_threads(), n))
    run_threads([lambda i=i: _play_block(i, k, *args) for i in range(k)])
    tripped[~ok] = np.nan
    if not model.electronics:
        tripped[:] = np.nan
    return Played(p, q, vl, ok, stalled, tripped, its, why, low)
