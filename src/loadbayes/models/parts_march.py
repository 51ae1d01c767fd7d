"""One draw's feeder loop solved by marching in time: the fifth try of ``parts_play``.

``parts_play._play_block`` solves the loop ``V_L = V - Z I(V_L)`` by whole-waveform
sweeps, in four tries; where none settles (the sweeps settle on trajectories that jump
between two operating points, which ``parts_loop.continues`` rejects, or run off),
:func:`march` solves it as a simulator does: sample by sample, each from the last. At
sample ``k``, from every part's state at ``k - 1``:

- each motor is integrated across ``[t_{k-1}, t_k]`` by ``motor_kernel``'s RK4 (its
  ``_rhs``, ``_rk4``, ``_substeps``: the same sub-steps, the finer ones after a jump, the
  braking by ``|V2_L|`` where the drive has one) with the load bus's ``|V_L|`` and angle
  linear between the known ``V_L(k-1)`` and the unknown ``V_L(k)``;
- motor D (``parts._motor_d``, its stall and restart timers) and the electronics (the
  lowest ramp so far) take one step; the static part is algebraic;
- ``V_L(k)`` (complex) is the root of ``F(x) = x - V(k) + Z conj(S_L(x) / x)``, by Newton
  from ``V_L(k-1)`` (Jacobian by differences, steps halved while ``|F|`` grows). Where
  ``|V|`` moves by more than ``motor_kernel.STEP_JUMP`` in the interval the root is carried
  along ``V(k-1) + l (V(k) - V(k-1))``, ``l`` in steps of that size (halved, down to
  :data:`MIN_STEP`, where Newton fails): the continuous branch, not another root.

Where no root continues from the previous one (Newton fails at the finest step: the
load's P-V nose below the feeder's) or the root has ``|V_L|`` below ``COLLAPSE_RATIO`` of
``|V|``, the draw collapses there (-2); where the numbers leave the finite ones with
``|V_L|`` held above that, it fails (-1); else it plays (the samples marched, > 0). A
step where motor D stalls or restarts (a jump of its P and Q at ``vstall``, ``vrst``) is
tried, where Newton fails, with the jump forced each way; a root whose ``|V_L|`` agrees
with the way forced is kept (the one without the jump first).

At point samples (``window_s`` 0) this solves the very equations the sweeps solve, in
order (a sweep merges samples into one RK4 step only where two intervals fit in a
motor's step, 400/s and more at the default 5 ms): where the sweeps settle at ``tol``
1e-12 the two agree to 1e-11 on random draws (``tests/unit/test_parts_play.py``) and to
2.3e-10 on the tests' fit at a 70 % sag (``tests/integration/test_predict_march.py``,
which derives the 1e-9 it asserts from the sweeps' stopping rule). Against the same load
solved as a DAE by SciPy the march's error is of second order in the sample interval
(``V_L`` linear between samples): 1.1e-3 p.u. at 250/s, a quarter of it at 500/s
(``tests/unit/test_parts_march.py``). The motors' start speed is read off the recorded
bus's angle (the sweeps read it off ``V_L``'s, which in a steady start turns with it).

With a phasor window (``window_s`` > 0) the loop is solved at the instants, the voltage
stepping at each gap's step instant as ``parts_kernel.knots_of`` steps it; the P and Q
reported are one pass of ``parts_loop.columns`` (the motors' window means) through the
marched ``V_L`` (:func:`marched`). The loop the march solves is the instantaneous one,
not the window means' that the sweeps solve (a non-causal one, each window reaching half
a window ahead): where a sample's window holds no step the reported P is the window mean
of the march's own P to ``W^2 / 24 P''``; within a window of a step the two loops differ
(by up to 0.3 p.u. on the tests' fit read as one-cycle windows at a 50 % sag), and motor
D, deciding its stall on ``|V_L|`` at the samples, may stall in one and not the other.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from loadbayes.models.motor_kernel import (
    FAST_SPAN,
    FAST_STEPS,
    STEP_JUMP,
    _pq_at,
    _rk4,
    _substeps,
    _u,
    brake_circuit,
    start_speed,
    steady_state,
)
from loadbayes.models.parts import d_step as _d_step
from loadbayes.models.parts_loop import cdiv, columns

__all__ = ["MIN_STEP", "NEWTON_STEPS", "NEWTON_TOL", "march", "marched"]

#: Newton steps at one sample (from the last root it takes 2-4) and its stopping rule:
#: the step below this share of ``|V_L|``.
NEWTON_STEPS = 40
NEWTON_TOL = 1e-12
#: The finest step of the continuation parameter ``l`` before a sample's root is given up.
MIN_STEP = 1.0 / 4096.0


@numba.njit(cache=True, nogil=True)
def _piece(m, x, ta, tb, va, vb, da, db, ba, bb, has_angle, nb):  # pragma: no cover
    # One interval of motor_kernel.integrate_v2_into (its else branch: equal sub-steps, V,
    # angle and |V2| linear inside) from x = (Ed', Eq', w, fine_until), in place.
    span = tb - ta
    if span <= 0.0:
        return True
    rs, xp, dx, tp, h, wb, t0, a, b, c, h_max = m
    tau_fast = tp * xp / (xp + dx)
    fine = ta < x[3]
    jump = max(abs(vb - va), abs(db - da))
    h_k = min(h_max, tau_fast / FAST_STEPS) if fine else h_max
    n_s = _substeps(span, h_k, jump, wb * abs(1.0 - x[2]))
    if n_s == 0:
        return False
    if jump > STEP_JUMP:
        x[3] = tb + FAST_SPAN * tau_fast
    hs = span / n_s
    ed, eq, w = x[0], x[1], x[2]
    for r in range(n_s):
        fa, fm, fb = r / n_s, (r + 0.5) / n_s, (r + 1.0) / n_s
        ua = _u(va + fa * (vb - va), da + fa * (db - da), has_angle, ba + fa * (bb - ba))
        um = _u(va + fm * (vb - va), da + fm * (db - da), has_angle, ba + fm * (bb - ba))
        ub = _u(va + fb * (vb - va), da + fb * (db - da), has_angle, ba + fb * (bb - ba))
        ed, eq, w, _ = _rk4(ed, eq, w, ua, ub, um, hs, rs, xp, dx, tp, h, wb, t0, a, b, c, nb)
    x[0], x[1], x[2] = ed, eq, w
    return math.isfinite(ed) and math.isfinite(eq) and math.isfinite(w)


@numba.njit(cache=True, nogil=True)
def _load(xl, c, ms, trial, ds, dtrial, el, force):  # pragma: no cover - compiled
    # The load's S at the load bus at sample c.k with V_L = xl, from the parts' states at
    # c.k - 1 (ms, ds, el) into trial, dtrial; (S, ok, motor D's jump at this sample).
    (t0_, t1_, sa, sb, vm0, dl0, first, has_angle, ba, bb, motors, shares, a_p, q_sh, d_on,
     dp, el_on, vd1, vd2, frcel, s_l0, m_vl0, pm0, qm0, pd0, qd0, braking) = c  # fmt: skip
    vm1 = abs(xl)
    dl1 = math.atan2(xl.imag, xl.real) - first if has_angle else 0.0
    x = vm1 / m_vl0
    f_s = shares[shares.size - 1]
    col_p = f_s * (a_p[0] * x * x + a_p[1] * x + a_p[2])
    col_qp = 0.0
    for j in range(motors.shape[0]):
        m = motors[j]
        trial[j, :] = ms[j, :]
        nb = brake_circuit(m[1], m[2], m[3], m[5])
        for piece in range(3):  # hold, step (or ramp), hold: parts_kernel.knots_of
            ta, tb = (t0_, sa) if piece == 0 else ((sa, sb) if piece == 1 else (sb, t1_))
            va, vb = (vm0, vm0) if piece == 0 else ((vm0, vm1) if piece == 1 else (vm1, vm1))
            da, db = (dl0, dl0) if piece == 0 else ((dl0, dl1) if piece == 1 else (dl1, dl1))
            ua, ub = (ba, ba) if piece == 0 else ((ba, bb) if piece == 1 else (bb, bb))
            if braking:
                ok = _piece(m, trial[j], ta, tb, va, vb, da, db, ua, ub, has_angle, nb)
            else:
                ok = _piece(m, trial[j], ta, tb, va, vb, da, db, 0.0, 0.0, has_angle, None)
            if not ok:
                return complex(math.nan, math.nan), False, False
        ud, uq, _ = _u(vm1, dl1, has_angle)
        pm, qm = _pq_at(trial[j, 0], trial[j, 1], ud, uq, m[0], m[1], m[0] * m[0] + m[1] * m[1])
        trial[j, 4], trial[j, 5] = pm, qm
        col_p += shares[j] * pm / pm0[j]
        col_qp += shares[j] * (qm - qm0[j] * x * x) / pm0[j]
    j = motors.shape[0]
    jump = False
    if d_on:
        pd, qd, r, be, ab, sd, rd, jump = _d_step(t1_ - t0_, vm1, ds, dp, force)
        dtrial[0], dtrial[1], dtrial[2], dtrial[3], dtrial[4] = r, be, ab, sd, rd
        col_p += shares[j] * pd / pd0
        col_qp += shares[j] * (qd - qd0 * x * x) / pd0
        j += 1
    if el_on:
        ramp = min(max((vm1 - vd2) / (vd1 - vd2), 0.0), 1.0)
        lo = min(el[0], ramp)
        dtrial[5] = lo
        col_p += shares[j] * (lo + frcel * (ramp - lo))
    s = complex(
        s_l0.real * col_p,
        s_l0.real * col_qp + s_l0.imag * (q_sh[0] * x * x + q_sh[1] * x + q_sh[2]),
    )
    return s, math.isfinite(s.real) and math.isfinite(s.imag), jump


@numba.njit(cache=True, nogil=True)
def _resid(xl, vk, z, c, ms, trial, ds, dtrial, el, force):  # pragma: no cover - compiled
    s, ok, jump = _load(xl, c, ms, trial, ds, dtrial, el, force)
    if not ok or abs(xl) == 0.0:
        return complex(math.nan, math.nan), s, jump
    return xl - vk + z * cdiv(s, xl).conjugate(), s, jump


@numba.njit(cache=True, nogil=True)
def _newton(x, vk, z, c, ms, trial, ds, dtrial, el, force):  # pragma: no cover - compiled
    # The root of _resid from x: (root, S there, 1 converged / 0 not / -1 non-finite).
    f, s, _ = _resid(x, vk, z, c, ms, trial, ds, dtrial, el, force)
    if not (math.isfinite(f.real) and math.isfinite(f.imag)):
        return x, s, -1
    for _ in range(NEWTON_STEPS):
        e = 1e-7 * max(abs(x), 1e-3)
        fr = _resid(x + e, vk, z, c, ms, trial, ds, dtrial, el, force)[0]
        fi = _resid(x + 1j * e, vk, z, c, ms, trial, ds, dtrial, el, force)[0]
        a11, a21 = (fr.real - f.real) / e, (fr.imag - f.imag) / e
        a12, a22 = (fi.real - f.real) / e, (fi.imag - f.imag) / e
        det = a11 * a22 - a12 * a21
        if not (math.isfinite(det) and det != 0.0):
            return x, s, 0
        step = complex((a22 * f.real - a12 * f.imag) / det, (a11 * f.imag - a21 * f.real) / det)
        lam = 1.0
        for _ in range(12):  # halved while |F| grows
            new = x - lam * step
            fn, sn, _ = _resid(new, vk, z, c, ms, trial, ds, dtrial, el, force)
            if math.isfinite(fn.real) and math.isfinite(fn.imag) and abs(fn) < abs(f):
                break
            lam *= 0.5
        else:  # no step lowers |F|: at the root to rounding, or stuck
            if abs(f) > 1e-10 * max(abs(x), 1.0):
                return x, s, 0
            _resid(x, vk, z, c, ms, trial, ds, dtrial, el, force)  # the trial states there
            return x, s, 1
        x, f, s = new, fn, sn  # (the trial states are new's: it was evaluated last)
        if abs(lam * step) <= NEWTON_TOL * abs(x):
            return x, s, 1
    return x, s, 0


@numba.njit(cache=True, nogil=True)
def march(t, v, has_angle, gap, steps, window_s, z, s0, q_sh, motors, shares, a_p, d_on, dp,
          el_on, vd1, vd2, frcel, po, qo, vl, u2, low, ratio):  # pragma: no cover  # fmt: skip
    """One draw's loop marched in time (module docstring): the samples played, or -2, -1.

    The samples it played (> 0), -2 a collapse, -1 a numerical failure. Writes ``po, qo``
    (the recorded bus's P, Q), ``vl`` (complex ``V_L``); ``low[0]`` lowers to the least
    ``|V_L| / |V|``.
    """
    n = t.size
    i0 = cdiv(s0, v[0]).conjugate()
    vl[0] = v[0] - z * i0
    s_l0 = s0 - z * abs(i0) ** 2
    m_vl0 = abs(vl[0])
    first = math.atan2(vl[0].imag, vl[0].real)
    nm = motors.shape[0]
    ms, trial = np.empty((nm, 6)), np.empty((nm, 6))
    pm0, qm0 = np.empty(nm), np.empty(nm)
    ang = np.empty(n)
    for k in range(n):
        ang[k] = math.atan2(v[k].imag, v[k].real)
    vabs = np.abs(v)
    for j in range(nm):
        m = motors[j]
        ed, eq, w, _, _ = steady_state(m[0], m[1], m[2], m[3], m[5], m_vl0, m[6], m[7], m[8],
                                       m[9], start_speed(t, vabs, ang, m[5]))  # fmt: skip
        if not math.isfinite(ed):
            return -1
        ms[j, 0], ms[j, 1], ms[j, 2], ms[j, 3] = ed, eq, w, -math.inf
        pm0[j], qm0[j] = _pq_at(ed, eq, m_vl0, 0.0, m[0], m[1], m[0] * m[0] + m[1] * m[1])
    ds, dtrial, el = np.zeros(6), np.zeros(6), np.ones(1)
    ds[0] = 1.0
    pd0, qd0 = 1.0, 1.0
    if d_on:  # sample 0 (dt 0), as parts._motor_d
        pd0, qd0, ds[0], ds[1], ds[2], ds[3], ds[4], _ = _d_step(0.0, m_vl0, ds, dp, -1)
    if el_on:
        el[0] = min(1.0, min(max((m_vl0 - vd2) / (vd1 - vd2), 0.0), 1.0))
    braking = u2.size > 0
    s_k = s_l0
    po[0], qo[0] = s0.real, s0.imag
    low[0] = min(low[0], m_vl0 / vabs[0])
    for k in range(1, n):
        sa, sb = t[k - 1], t[k]  # the ramp: the whole interval, or a gap's step (knots_of)
        if window_s > 0.0 and gap[k - 1]:
            mid = steps[k - 1] if math.isfinite(steps[k - 1]) else 0.5 * (t[k - 1] + t[k])
            sa, sb = mid - 1e-6, mid + 1e-6
        dl0 = math.atan2(vl[k - 1].imag, vl[k - 1].real) - first if has_angle else 0.0
        ba, bb = (u2[k - 1], u2[k]) if braking else (0.0, 0.0)
        c = (t[k - 1], t[k], sa, sb, abs(vl[k - 1]), dl0, first, has_angle, ba, bb, motors,
             shares, a_p, q_sh, d_on, dp, el_on, vd1, vd2, frcel, s_l0, m_vl0, pm0, qm0, pd0,
             qd0, braking)  # fmt: skip
        x = vl[k - 1]
        dv = v[k] - v[k - 1]
        step = min(1.0, STEP_JUMP / abs(dv)) if abs(dv) > 0.0 else 1.0
        lam = 0.0
        while lam < 1.0:
            target = min(1.0, lam + step)
            vk = v[k - 1] + target * dv if target < 1.0 else v[k]
            root, s, got = x, s_k, 0
            for force in range(-1, 2 if d_on else 0):  # as it falls, then motor D's jump
                r2, s2, g2 = _newton(x, vk, z, c, ms, trial, ds, dtrial, el, force)
                if force < 0:
                    root, s, got = r2, s2, g2
                    if g2 != 0:
                        break
                # forced each way: kept where the root agrees with the way forced
                elif g2 == 1 and _d_step(t[k] - t[k - 1], abs(r2), ds, dp, -1)[7] == (force == 1):
                    root, s, got = r2, s2, 1
                    break
            if got == 1 and abs(root) < ratio * abs(vk):
                low[0] = min(low[0], abs(root) / abs(vk))
                return -2
            if got == -1:
                return -2 if abs(x) < ratio * abs(vk) else -1
            if got == 0:
                if step > MIN_STEP and abs(dv) > 0.0:  # (V still: the same problem again)
                    step *= 0.5
                    continue
                return -2  # no root continues from the previous one: the nose
            x, s_k, lam = root, s, target
        vl[k] = x
        low[0] = min(low[0], abs(x) / vabs[k])
        for j in range(nm):
            ms[j, :] = trial[j, :]
        for i in range(5):
            ds[i] = dtrial[i]
        el[0] = dtrial[5]
        rec = v[k] * cdiv(s_k, x)  # the recorded bus's S: V conj(I)
        po[k], qo[k] = rec.real, rec.imag
    return n


@numba.njit(cache=True, nogil=True)
def marched(t, v, has_angle, gap, steps, window_s, z, s0, q_sh, motors, shares, a_p, d_on, dp,
            el_on, vd1, vd2, frcel, po, qo, u2, low, ratio):  # pragma: no cover  # fmt: skip
    """The fifth try of ``parts_play._play_block``: :func:`march`, P and Q at the samples.

    With a window, the recorded bus's P and Q from the window means of one pass of
    ``parts_loop.columns`` through the marched load bus (the module docstring).
    """
    n = t.size
    vl = np.empty(n, dtype=np.complex128)
    got = march(t, v, has_angle, gap, steps, window_s, z, s0, q_sh, motors, shares, a_p, d_on,
                dp, el_on, vd1, vd2, frcel, po, qo, vl, u2, low, ratio)  # fmt: skip
    if got <= 0 or window_s <= 0.0:
        return got
    vm, dl = np.abs(vl), np.zeros(n)
    for k in range(n):
        dl[k] = math.atan2(vl[k].imag, vl[k].real) - math.atan2(vl[0].imag, vl[0].real)
    col_p, col_qp, pm, qm = np.empty(n), np.empty(n), np.empty(n), np.empty(n)
    if not columns(t, vm, dl if has_angle else np.zeros(n), u2, gap, steps, window_s, motors,
                    shares, a_p, d_on, dp, el_on, vd1, vd2, frcel, col_p, col_qp, pm, qm,
                    np.empty((3, n))):  # fmt: skip
        return -1
    s_l0 = s0 - z * abs(cdiv(s0, v[0])) ** 2
    for k in range(n):
        xl = vm[k] / vm[0]
        s = complex(s_l0.real * col_p[k], s_l0.real * col_qp[k] + s_l0.imag * (
            q_sh[0] * xl * xl + q_sh[1] * xl + q_sh[2]))  # fmt: skip
        rec = v[k] * cdiv(s, vl[k])
        po[k], qo[k] = rec.real, rec.imag
    return got
