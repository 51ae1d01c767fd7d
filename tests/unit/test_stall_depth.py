"""The sweep's "how deep before it stalls" summary, on hand-made stall probabilities."""

from __future__ import annotations

import pytest

from loadbayes.fit.composite.stall_depth import crossing, stall_depth


def test_the_crossings_are_linear_between_the_swept_depths():
    depths = [0.1, 0.2, 0.3, 0.4, 0.5]
    probs = [0.0, 0.0, 0.2, 0.9, 1.0]
    out = stall_depth(depths, probs, duration=0.15)
    # 0.5 lies 0.3 / 0.7 of the way from 0.2 (at 0.3) to 0.9 (at 0.4).
    assert out["depth"] == pytest.approx(0.3 + 0.1 * 0.3 / 0.7)
    # 0.025 between 0.0 (0.2) and 0.2 (0.3); 0.975 between 0.9 (0.4) and 1.0 (0.5).
    assert out["interval"][0] == pytest.approx(0.2 + 0.1 * 0.025 / 0.2)
    assert out["interval"][1] == pytest.approx(0.4 + 0.1 * 0.075 / 0.1)
    assert out["levels"] == pytest.approx([0.025, 0.5, 0.975])
    assert "0.343 deep of sags lasting 0.15 s" in out["message"]
    assert "95% of the draws stall between depths 0.213 and 0.475" in out["message"]


def test_a_level_reached_exactly_at_a_swept_depth_is_that_depth():
    assert crossing([0.1, 0.2, 0.3], [0.0, 0.5, 1.0], 0.5) == (pytest.approx(0.2), None)
    # The first crossing: a sweep whose Monte Carlo noise dips back keeps the shallowest.
    assert crossing([0.1, 0.2, 0.3, 0.4], [0.0, 0.6, 0.4, 1.0], 0.5)[0] == pytest.approx(
        0.1 + 0.1 * 0.5 / 0.6
    )


def test_levels_not_crossed_within_the_sweep_are_null_and_said():
    never = stall_depth([0.1, 0.2, 0.3], [0.0, 0.0, 0.01])
    assert never["depth"] is None and never["interval"] == [None, None]
    assert "stays below 0.025 up to the deepest depth swept (0.3)" in never["message"]
    assert "not within the sweep (0.1 to 0.3)" in never["message"]
    always = stall_depth([0.1, 0.2, 0.3], [0.99, 1.0, 1.0])
    assert always["depth"] is None and always["interval"] == [None, None]
    assert "already 0.975 or more at the shallowest depth swept (0.1)" in always["message"]
    part = stall_depth([0.1, 0.2, 0.3], [0.0, 0.3, 0.8])
    assert part["depth"] == pytest.approx(0.24) and part["interval"][0] is not None
    assert part["interval"][1] is None
    assert "stays below 0.975" in part["message"] and "not within the sweep" in part["message"]
    # Another probability: the interval's levels follow it.
    assert stall_depth([0.1, 0.2], [0.0, 1.0], prob=0.9)["interval"] == pytest.approx(
        [0.105, 0.195]
    )


def test_no_motor_d_and_bad_depths():
    none = stall_depth([0.1, 0.2], [None, None])
    assert none["depth"] is None and "no motor D" in none["message"]
    zm = stall_depth([0.1, 0.2], [0.0, 1.0], part="the induction motor")
    assert zm["message"].startswith("the induction motor stalls with probability 0.5")
    with pytest.raises(ValueError, match="ascending"):
        stall_depth([0.2, 0.1], [0.0, 1.0])
    with pytest.raises(ValueError, match="one stall probability"):
        stall_depth([0.1, 0.2], [0.0])
