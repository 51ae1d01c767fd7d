"""The independent event generator (tests/independent_composite.py) checked on its own.

The generator is the yardstick of the composite fit (issue 21), so it is checked against
what holds whatever the code: the steady state before the sag, the steady-state
equivalent circuit (a hand formula), the rotor's energy balance, the window means of the
phasor samples, and the return to the operating point after the sag.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.integrate import trapezoid

import independent_composite as ic
from loadbayes.models.motor_library import MOTORS as LIBRARY

WB = 2.0 * math.pi * 60.0


@pytest.fixture(scope="module", params=sorted(ic.MOTORS))
def traj(request):
    sags = (ic.Sag(0.5123, 0.35, 0.15, 0.0, 0.02),)
    return ic.simulate(motor=request.param, t0=0.7, sags=sags, t_start_s=-0.05, t_end_s=4.0)


def test_motors_are_not_the_library_s():
    # Issue 21: two motors not in the library; a T' within 25% of a library motor's fails.
    lib = [m.tp_s for m in LIBRARY.values()]
    for m in ic.MOTORS.values():
        assert m.xs == m.xr
        assert min(abs(m.tp() / t - 1.0) for t in lib) > 0.25, m.name
    assert ic.MOTORS["small_fast"].tp() < 0.1 < 0.5 < ic.MOTORS["large_slow"].tp() < 1.0


@pytest.mark.parametrize("name", sorted(ic.MOTORS))
def test_steady_state_is_the_equivalent_circuit(name):
    # Hand case: at the steady slip the third-order model draws what the T circuit
    # Rs + jXs + jXm || (Rr/s + jXr) draws, and its air-gap torque is |Ir|^2 Rr / s.
    m = ic.MOTORS[name]
    for v, t0 in ((1.0, 0.7), (0.95, 0.5)):
        y = ic.steady_state(m, t0, v=v)
        s = 1.0 - y[2]
        assert 0.0 < s < 0.2
        zr = complex(m.rr / s, m.xr)
        zm = complex(0.0, m.xm)
        z = complex(m.rs, m.xs) + zm * zr / (zm + zr)
        i = v / z
        ir = i * zm / (zm + zr)
        e = complex(y[0], y[1])
        i_model = (v - e) / complex(m.rs, m.xp)
        assert abs(i_model - i) < 1e-9
        assert abs(abs(ir) ** 2 * m.rr / s - t0 * y[2] ** 2) < 1e-9  # A = 1: T0 w^2
        assert np.max(np.abs(ic._rhs_motor(m, 60.0, t0, complex(v, 0.0), y))) < 1e-10


def test_stall_is_refused():
    with pytest.raises(ValueError, match="stalls"):
        ic.steady_state(ic.MOTORS["small_fast"], 3.0, v=0.5)


def test_steady_before_the_sag_and_back_after(traj):
    for t in np.linspace(-0.05, 0.5122, 7):
        v, d, p, q = traj.point(t)
        assert (v, d) == (1.0, 0.0)
        assert p == pytest.approx(1.0, abs=1e-8) and q == pytest.approx(0.3, abs=1e-8)
    # Three seconds after the sag the motor is back at its operating point.
    _, _, p, q = traj.point(4.0)
    assert p == pytest.approx(1.0, abs=1e-4) and q == pytest.approx(0.3, abs=1e-4)
    # ... and during the sag it is not: the event has something to identify.
    assert abs(traj.point(0.55)[2] - 1.0) > 0.05


def _integral(f, kn, a, b, n=4001):
    """The integral of ``f(t)`` over [a, b], trapezoid on each piece between the knots.

    Inside a piece the integrand is smooth; at a knot it may jump (a step of V), so each
    piece is integrated from just after its first knot to just before its last.
    """
    total = 0.0
    for t, y in _pieces(f, kn, a, b, n):
        total += trapezoid(y, t)
    return total


def _pieces(f, kn, a, b, n=4001):
    """``(t, f(t))`` on each piece between the knots, as :func:`_integral` samples them."""
    edges = np.unique(np.clip(np.concatenate([[a, b], kn[:, 0]]), a, b))
    for lo, hi in zip(edges[:-1], edges[1:], strict=True):
        t = np.linspace(lo + 1e-12, hi - 1e-12, n)
        yield t, np.array([f(tk) for tk in t])


def test_rotor_energy_balance(traj):
    # d(H w^2)/dt = w (Te - Tm): the kinetic energy's change over the event equals the
    # integral of the net power, computed from the solution's outputs.
    def net(t):
        _, _, te, tm = traj.motor_power(t)
        return traj.state(t)[2] * (te - tm)

    # The net power sampled once; |net| and net integrated from the same samples.
    pieces = list(_pieces(net, traj.kn, -0.05, 2.0))
    swing, balance = 0.0, 0.0
    for t, y in pieces:
        swing += trapezoid(np.abs(y), t)
        balance += trapezoid(y, t)
    w0, w1 = traj.state(-0.05)[2], traj.state(2.0)[2]
    assert swing > 1e-3  # the rotor moved
    kinetic = traj.motor.h_s * (w1**2 - w0**2)
    assert balance == pytest.approx(kinetic, abs=1e-6 * swing)


def test_phasor_samples_are_window_means():
    # An exact step at t_f inside a sample's one-cycle window: the window mean of V is
    # v0 - depth * (the window's part after the step), analytically; P and Q are the
    # means of the instantaneous values (trapezoid on a fine grid, split at the step).
    sag = ic.Sag(1.0071, 0.4, 0.2)
    df, truth = ic.simulate_event(
        motor="large_slow", sags=(sag,), sampling="phasor", noise=0.0, t_end_s=2.0
    )
    traj = ic.simulate(motor="large_slow", sags=(sag,), t_start_s=-0.05, t_end_s=2.0 + 1e-9)
    k = 61  # t = 1.01667, window [1.0, 1.01667]
    tk, win = df.t_s[k], 1.0 / 60.0
    after = (tk - sag.start_s) / win
    assert df.v[k] == pytest.approx(1.0 - 0.4 * after, abs=1e-8)
    assert df.v[60] == pytest.approx(1.0, abs=1e-9)
    for col, j in (("p", 2), ("q", 3)):
        mean = _integral(lambda t, j=j: traj.point(t)[j], traj.kn, tk - win, tk) / win
        assert df[col][k] == pytest.approx(mean, abs=1e-7)
    # The point sample at the same instant is the value after the step, not the mean.
    dfp, _ = ic.simulate_event(motor="large_slow", sags=(sag,), noise=0.0, t_end_s=2.0)
    assert dfp.v[k] == pytest.approx(0.6, abs=1e-12)
    assert truth["t_fault_s"] == pytest.approx([1.0071, 1.2071])


def test_noise_angle_and_two_sags():
    sags = (ic.Sag(0.5, 0.3, 0.1, 0.01, 0.01, angle_rad=0.1), ic.Sag(1.5, 0.2, 0.12))
    clean, _ = ic.simulate_event(sags=sags, noise=0.0, angle=True, rate_hz=120, t_end_s=2.5)
    noisy, truth = ic.simulate_event(sags=sags, noise=0.005, angle=True, rate_hz=120, t_end_s=2.5)
    assert list(noisy.columns) == ["t_s", "v", "p", "q", "angle_rad"]
    assert len(noisy) == 301 and noisy.t_s.iloc[-1] == pytest.approx(2.5)
    sd = 0.005 * math.hypot(1.0, 0.3)
    for col in ("p", "q"):
        r = noisy[col] - clean[col]
        assert r.std() == pytest.approx(sd, rel=0.15)
    assert clean.angle_rad.max() == pytest.approx(0.1)
    assert clean.v.min() == pytest.approx(0.7)
    assert truth["t_fault_s"] == pytest.approx([0.5, 0.6, 1.5, 1.62])
    with pytest.raises(ValueError, match="overlaps"):
        ic.simulate(sags=(ic.Sag(0.5, 0.3, 0.2), ic.Sag(0.6, 0.2, 0.1)))


def test_the_study_s_cases_cross_every_cell():
    from loadbayes.studies.calibration.composite_independent import independent_cases

    def cell(c):
        return (c["motor"], c["rate_hz"], c["ramp_s"], c["sampling"])

    cases = independent_cases(96, seed=3)
    assert len({cell(c) for c in cases[:48]}) == 48
    assert [cell(c) for c in cases[:48]] == [cell(c) for c in cases[48:]]
    for k in range(0, 48, 12):
        block = cases[k : k + 12]
        assert len({(c["rate_hz"], c["ramp_s"]) for c in block}) == 12
        assert sum(c["motor"] == "small_fast" for c in block) == 6
        assert sum(c["sampling"] == "point" for c in block) == 6
    for c in cases:
        # The fault's instant lies strictly inside a sample interval.
        frac = (c["start_s"] * c["rate_hz"]) % 1.0
        assert 0.04 < frac < 0.96
        assert sum(c["shares"]) == pytest.approx(1.0) and min(c["shares"]) >= 0.0
    # A prefix of a longer run is the shorter run (the CI test's 12 are validate's first).
    assert independent_cases(12, seed=3) == cases[:12]
