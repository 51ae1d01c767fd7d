"""Warnings about what a sampled recording hides: steps inside an interval, angles from f."""

from __future__ import annotations

import numpy as np

from loadbayes.fit.composite.checks import jumps, own_bases_warnings, sampling_warnings
from loadbayes.measurements.record import EventRecord


def _event(fs=120.0, depth=0.3, angle_from="", smooth=False):
    t = np.arange(0, 2.0, 1 / fs)
    if smooth:  # a 0.1 s ramp: a motor start or a tap change, no switching step
        v = 1.0 - depth * np.clip((t - 0.5) / 0.1, 0, 1)
    else:
        v = np.where((t > 0.5) & (t <= 0.7), 1.0 - depth, 1.0)
    z = np.zeros_like(t)
    return EventRecord(t, v, z + 1.0, z + 0.3, None if not angle_from else z, "ev", angle_from)


def test_jumps_are_the_intervals_with_a_switching_step():
    ev = _event()
    k = jumps(ev)
    assert k.tolist() == [60, 84]  # into the sag after t = 0.5 s, out after t = 0.7 s
    assert jumps(_event(smooth=True)).size == 0
    assert jumps(_event(depth=0.04)).size == 0


def test_a_short_t_prime_next_to_a_step_is_flagged_and_a_long_one_is_not():
    ev = _event()
    (w,) = sampling_warnings([ev], np.full(100, 0.02))  # 2.4 intervals of 1/120 s
    assert "steps by 30%" in w and "t = 0.5 s" in w and "higher sampling rate" in w
    assert sampling_warnings([ev], np.full(100, 0.5)) == []  # 60 intervals
    assert sampling_warnings([_event(smooth=True)], np.full(100, 0.02)) == []


def test_an_angle_read_from_frequency_is_flagged_only_where_the_voltage_steps():
    out = sampling_warnings([_event(angle_from="frequency")], np.full(10, 0.5))
    assert len(out) == 1 and "angle_rad" in out[0]
    assert sampling_warnings([_event(angle_from="angle")], np.full(10, 0.5)) == []
    assert sampling_warnings([_event(angle_from="frequency", smooth=True)], np.full(10, 0.5)) == []


def test_p_and_q_each_per_unit_of_its_own_initial_value_are_warned_of():
    # The fan motor of issue 35 wrote P/P0 and Q/Q0: both 1 before the sag, Q on a base
    # P0/Q0 times P's, and the fit (which ties the motor's Q to its P) read f_m 0.337
    # [0.308, 0.370] for 0.400. Both channels at 1 in every event is that signature; a
    # load on one base (Q0 = 0.3 P0) is not warned of, nor one event of many at 1.
    t = np.arange(120) / 60.0
    v = np.where((t > 1.0) & (t < 1.2), 0.7, 1.0)
    rng = np.random.default_rng(0)

    def event(q0):
        p = v**2 + 0.005 * rng.standard_normal(t.size)
        return EventRecord(t, v, p, q0 * v**2 + 0.005 * rng.standard_normal(t.size))

    (words,) = own_bases_warnings([event(1.0), event(1.0)])
    assert "P/P0, Q/Q0" in words and "one base" in words
    assert own_bases_warnings([event(0.3)]) == []
    assert own_bases_warnings([event(1.0), event(0.3)]) == []
