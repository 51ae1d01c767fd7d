"""The run-until-converged policy of the composite fit (fit/composite/until.py)."""

from __future__ import annotations

import time
from types import SimpleNamespace

import numpy as np

from loadbayes.fit.composite.until import UntilConverged


def _results(kept: int, seed: int = 0):
    # Two chains far apart: R-hat well above 1.01, so the policy wants more draws.
    rng = np.random.default_rng(seed)
    x = rng.normal(size=(2, kept)) + np.array([[0.0], [3.0]])
    res = [SimpleNamespace(theta=np.zeros((kept, 1))) for _ in range(2)]
    return res, {"x": x}


def _after(elapsed_s: float, round_s: float):
    """Unconverged chains of 400 kept draws, as if the last round of 1000 iterations took
    ``round_s`` and ``elapsed_s`` of a 100 s budget are gone: the policy and the results."""
    res, named = _results(400)
    policy = UntilConverged(lambda _: named, max_seconds=100.0, thin=1)
    policy.start(1000)
    now = time.perf_counter()
    policy.t_start, policy._t_round = now - elapsed_s, now - round_s
    return policy, res


def test_an_extension_is_planned_inside_the_time_left():
    # 90 s gone (the ESS asks for 1600 more iterations, 16 s: more than is left).
    policy, res = _after(90.0, 10.0)
    more = policy(res)
    assert more > 0
    per_iteration = 10.0 / 1000
    # at most 85% of the 10 s left, at the last round's pace: a slower round stays inside
    assert more * per_iteration <= 0.85 * 10.0 + 1e-9, more


def test_no_time_for_a_useful_extension_stops_and_says_so():
    policy, res = _after(99.5, 10.0)
    assert policy(res) == 0
    assert policy.stopped_by_budget
    assert "ran out" in policy.warning(res)
