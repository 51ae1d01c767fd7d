"""The compiled motor kernel against SciPy (DOP853) and against ``models.motor``."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from loadbayes.models.motor import currents, derivatives, power, steady_state
from loadbayes.models.motor_kernel import integrate
from loadbayes.models.motor_kernel import steady_state as kernel_steady_state
from loadbayes.models.motor_library import MOTORS
from turning_start import turning_start

#: The stated accuracy of the kernel (docs/composite.md): P, Q on the motor's base.
TOL_PU = 1e-4


@pytest.mark.parametrize("name", sorted(MOTORS))
@pytest.mark.parametrize("v0", [0.95, 1.0, 1.05])
def test_steady_state_matches_the_motor_module(name, v0):
    m = MOTORS[name]
    op = steady_state(m, v_pu=v0, t0=0.6)
    k = kernel_steady_state(m.rs, m.xp, m.x - m.xp, m.tp_s, m.wb, v0, 0.6, 1.0, 0.0, 0.0)
    np.testing.assert_allclose(k, [op.ed, op.eq, op.w, op.p, op.q], atol=1e-10)


def test_no_steady_state_beyond_breakdown():
    m = MOTORS["small_industrial"]
    out = integrate(
        np.arange(3.0),
        np.ones(3),
        None,
        rs=m.rs,
        xp=m.xp,
        dx=m.x - m.xp,
        tp_s=m.tp_s,
        h_s=m.h_s,
        t0=50.0,
    )
    assert out is None


def _reference(m, t, v, delta, t0, torque):
    m = m.__class__(**{**m.to_dict(), "a": torque[0], "b": torque[1], "c": torque[2]})

    def rhs(tt, y):
        vv, dd = np.interp(tt, t, v), np.interp(tt, t, delta)
        return derivatives(y, vv * np.cos(dd), vv * np.sin(dd), m, t0=t0)

    sol = solve_ivp(
        rhs,
        (t[0], t[-1]),
        turning_start(m, t, v, delta, t0),
        method="DOP853",
        t_eval=t,
        rtol=1e-10,
        atol=1e-12,
        max_step=float(np.min(np.diff(t))),
    )
    assert sol.success
    ud, uq = v * np.cos(delta), v * np.sin(delta)
    i_d, iq = currents(ud, uq, sol.y[0], sol.y[1], m)
    return power(ud, uq, i_d, iq)


@pytest.mark.parametrize("name", sorted(MOTORS))
@pytest.mark.parametrize("depth", [0.1, 0.35, 0.6])
def test_kernel_matches_solve_ivp_on_sags(name, depth):
    m = MOTORS[name]
    t = np.arange(0.0, 1.5, 1 / 60)
    v = np.where((t >= 0.3) & (t < 0.5), 1.0 - depth, 1.0)
    # A slow angle swing as a frequency excursion would give, and a non-quadratic torque.
    delta = 0.2 * np.sin(2 * np.pi * 0.8 * t)
    torque = (0.5, 0.3, 0.2)
    p_ref, q_ref = _reference(m, t, v, delta, 0.6, torque)
    p, q, _ = integrate(
        t,
        v,
        delta,
        rs=m.rs,
        xp=m.xp,
        dx=m.x - m.xp,
        tp_s=m.tp_s,
        h_s=m.h_s,
        t0=0.6,
        torque=torque,
    )
    assert np.max(np.abs(p - p_ref)) < TOL_PU
    assert np.max(np.abs(q - q_ref)) < TOL_PU
    # The check can fail: a 1% error in H is far outside the tolerance.
    p_bad, _, _ = integrate(
        t,
        v,
        delta,
        rs=m.rs,
        xp=m.xp,
        dx=m.x - m.xp,
        tp_s=m.tp_s,
        h_s=1.05 * m.h_s,
        t0=0.6,
        torque=torque,
    )
    assert np.max(np.abs(p_bad - p_ref)) > TOL_PU


@pytest.mark.parametrize("name", sorted(MOTORS))
def test_kernel_matches_solve_ivp_at_960_samples_per_second(name):
    # Samples closer than the RK4 step: steps span several samples where the input is
    # linear (states between by Hermite interpolation), and the sag's edges, inside one
    # 1 ms sample, get sub-steps of their own. No angle, so merging happens.
    m = MOTORS[name]
    t = np.arange(0.0, 1.5, 1 / 960)
    v = np.where((t >= 0.3) & (t < 0.5), 0.4, 1.0)
    delta = np.zeros_like(t)
    torque = (0.5, 0.3, 0.2)
    p_ref, q_ref = _reference(m, t, v, delta, 0.6, torque)
    kw = {"rs": m.rs, "xp": m.xp, "dx": m.x - m.xp, "tp_s": m.tp_s, "t0": 0.6, "torque": torque}
    p, q, _ = integrate(t, v, None, h_s=m.h_s, **kw)
    assert np.max(np.abs(p - p_ref)) < TOL_PU
    assert np.max(np.abs(q - q_ref)) < TOL_PU
    p_bad, _, _ = integrate(t, v, None, h_s=1.05 * m.h_s, **kw)
    assert np.max(np.abs(p_bad - p_ref)) > TOL_PU


@pytest.mark.parametrize("window_s", [0.0, 1 / 60])
def test_an_input_no_load_sees_is_refused_not_integrated_for_ever(window_s):
    # A feeder loop's sweep that runs off drives a motor with |V| of 1e9 between two
    # samples: 1e10 sub-steps of DV_STEP. Before MAX_SUBSTEPS predict spun on such a draw
    # for minutes; now the call says it has no result, as for non-finite states.
    import time

    from loadbayes.models.motor_kernel import DV_STEP, MAX_SUBSTEPS

    m = MOTORS["krause_3hp"]
    t = np.arange(0.0, 0.5, 1 / 60)
    kw = dict(rs=m.rs, xp=m.xp, dx=m.x - m.xp, tp_s=m.tp_s, h_s=m.h_s, t0=0.6,
              window_s=window_s)  # fmt: skip
    v = np.ones_like(t)
    assert integrate(t, v, None, **kw) is not None  # warm (compiled), and a plain input plays
    v[10:] = 1e9
    c0 = time.process_time()
    assert integrate(t, v, None, **kw) is None
    # A termination check, not a speed one: 1e10 RK4 steps are hours of CPU, the refusal
    # well under a second; a minute of CPU cannot be reached by load or a slow machine.
    assert time.process_time() - c0 < 60.0
    # The bound is far above what any voltage asks: a 2 p.u. jump is 20 sub-steps.
    assert 2.0 / DV_STEP < MAX_SUBSTEPS / 1000
    v[10:] = 2.5  # a large but physical swell still integrates
    assert integrate(t, v, None, **kw) is not None
