"""A motor at rest under a held input is held, not integrated (``motor_kernel.REST_TOL``).

The kernel stops integrating where the input holds one value to the bit and the state is
within ``REST_TOL`` of that input's steady state. These tests check that it does stop
(the held states are one value, bit for bit), that what it then gives is the integrated
answer to well below the integrator's error (the same record with V moved by one part in
1e15 after the sag, which holds nothing, is integrated all the way), in both readings of
the samples, with an angle and with a braking negative sequence. All
deterministic: no false alarms.
"""

from __future__ import annotations

import numpy as np
import pytest

from loadbayes.models.motor_kernel import REST_TOL, _rest, _rhs, integrate
from loadbayes.models.motor_library import MOTORS

#: The held output against the integrated one (P, Q on the motor's base): a thousand
#: times below the kernel's stated error (1e-4, test_motor_kernel.TOL_PU).
HELD_TOL = 1e-7


def _record(fs=60.0, t_end=8.0, angle=0.0):
    # A 30 % sag of 0.2 s at 1 s with 20 ms ramps, the voltage held before and after;
    # the angle (rad) jumps with the sag and stays, so the held input after it has one.
    t = np.arange(0.0, t_end, 1.0 / fs)
    v = np.interp(t, [0, 1.0, 1.02, 1.2, 1.22, t_end], [1, 1, 0.7, 0.7, 1, 1])
    d = np.interp(t, [0, 1.0, 1.02, t_end], [0, 0, angle, angle])
    return t, v, d


def _kw(name="large_industrial"):
    m = MOTORS[name]
    return dict(rs=m.rs, xp=m.xp, dx=m.x - m.xp, tp_s=m.tp_s, h_s=m.h_s, t0=0.6, f_hz=60.0)


def _unheld(v, t):
    # The same voltage moved by one part in 1e15 at every sample after the sag, each by
    # a different amount: no two neighbours are equal, so nothing is held.
    w = v.copy()
    after = t > 1.3
    w[after] *= 1.0 + 1e-15 * (1 + np.arange(after.sum()) % 7)
    assert np.all(w[after][1:] != w[after][:-1])
    return w


@pytest.mark.parametrize("angle", [0.0, -0.1])
def test_a_held_input_is_held_and_gives_the_integrated_answer(angle):
    t, v, d = _record(angle=angle)
    kw = _kw()
    p, q, states = integrate(t, v, d, **kw)
    # Held: the states of the record's last second are one value, bit for bit (an
    # integration moves them in the last bits at least, and says so below).
    tail = states[:, t > t[-1] - 1.0]
    assert np.all(tail == tail[:, :1])
    # The steady start is held too, up to the sag.
    head = states[:, t < 0.95]
    assert np.all(head == head[:, :1])
    p2, q2, states2 = integrate(t, _unheld(v, t), d, **kw)
    assert not np.all(states2[:, t > t[-1] - 1.0] == states2[:, -1:])
    assert np.max(np.abs(p - p2)) < HELD_TOL
    assert np.max(np.abs(q - q2)) < HELD_TOL


def test_window_means_of_a_held_input_give_the_integrated_answer():
    t, v, d = _record(angle=0.05)
    kw = _kw("small_industrial")
    p, q, _ = integrate(t, v, d, window_s=1 / 60, **kw)
    p2, q2, _ = integrate(t, _unheld(v, t), d, window_s=1 / 60, **kw)
    assert np.max(np.abs(p - p2)) < HELD_TOL
    assert np.max(np.abs(q - q2)) < HELD_TOL
    # The held tail's window means are one value (each the mean of a held power).
    tail = p[t > t[-1] - 1.0]
    np.testing.assert_allclose(tail, tail[0], rtol=0, atol=1e-13)


@pytest.mark.parametrize("angle", [0.0, 0.3, -2.0])
def test_the_rest_is_the_steady_state_in_the_states_frame(angle):
    # At _rest's state the derivatives vanish under the held input V e^{j angle}: a
    # state in another frame (the flux not turned with the angle) would never be at
    # rest, and nothing would be held.
    kw = _kw()
    wb = 2 * np.pi * 60.0
    v = np.full(8, 0.93)
    d = np.full(8, angle)
    ed, eq, w = _rest(v, d, None, 0, 7, angle != 0.0, kw["rs"], kw["xp"], kw["dx"],
                      kw["tp_s"], wb, kw["t0"], 1.0, 0.0, 0.0)  # fmt: skip
    f = _rhs(ed, eq, w, 0.93 * np.cos(angle), 0.93 * np.sin(angle), 0.0, kw["rs"], kw["xp"],
             kw["dx"], kw["tp_s"], kw["h_s"], wb, kw["t0"], 1.0, 0.0, 0.0, None)  # fmt: skip
    # |f| T' bounds the distance to the rest (1e-14 measured: rounding), far inside it.
    assert np.max(np.abs(f)) * kw["tp_s"] < 1e-2 * REST_TOL
    # Too short a stretch, or a braking V2, has no rest.
    assert np.isnan(_rest(v, d, None, 0, 2, True, 0.01, 0.2, 3.0, 0.5, wb, 0.6, 1, 0, 0)[0])
    assert np.isnan(_rest(v, d, np.full(8, 0.1), 0, 7, True, 0.01, 0.2, 3.0, 0.5, wb, 0.6, 1,
                          0, 0)[0])  # fmt: skip


def test_a_braking_negative_sequence_gives_the_integrated_answer():
    # With |V2| > 0 held after the sag the motor settles where the brake holds it, not at
    # the balanced steady state: _rest has none there (above), and the output is the
    # integrated one.
    t, v, d = _record()
    v2 = np.where(t > 1.3, 0.05, 0.0)
    p, q, _ = integrate(t, v, d, v2=v2, **_kw())
    p2, q2, _ = integrate(t, _unheld(v, t), d, v2=v2, **_kw())
    assert np.max(np.abs(p - p2)) < HELD_TOL
    assert np.max(np.abs(q - q2)) < HELD_TOL
