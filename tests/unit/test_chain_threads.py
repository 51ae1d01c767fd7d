"""A short fit run in Python runs its chains in one thread, with the same draws.

Two threads lose to one on short events when the chains run the Python iteration (the
GIL: sampler.ONE_THREAD_SAMPLES gives the measurements); chains that run compiled take one
per CPU. The choice must change nothing but the time.
"""

from __future__ import annotations

import numpy as np

from loadbayes.cases.composite_sim import simulate_event
from loadbayes.fit.composite.design import DesignProblem
from loadbayes.fit.composite.nls import nls
from loadbayes.fit.composite.problem import CompositeProblem
from loadbayes.fit.composite.sampler import ONE_THREAD_SAMPLES, chain_threads, sample
from loadbayes.models.composite_prior import CompositePrior
from loadbayes.models.dynamic import dynamic_model


def _problem(t_end_s, fs=60.0):
    ev, _ = simulate_event("small_industrial", depth=0.3, t_end_s=t_end_s, fs=fs, seed=3)
    return CompositeProblem([ev], CompositePrior.default([ev]), window_s=0), ev.n


def test_one_thread_below_the_threshold_and_none_above_or_when_asked(monkeypatch):
    monkeypatch.delenv("LOADBAYES_NUM_THREADS", raising=False)
    short, n_short = _problem(1.0)
    long, n_long = _problem(6.0)
    assert n_short < ONE_THREAD_SAMPLES <= n_long
    assert chain_threads(short) == 1 and chain_threads(long) is None
    assert chain_threads(short, compiled=True) is None  # compiled chains hold no GIL
    monkeypatch.setenv("LOADBAYES_NUM_THREADS", "2")  # asked: the user's choice holds
    assert chain_threads(short) is None


def test_a_model_of_parts_takes_the_same_rule(monkeypatch):
    # cmld-lite and slm on the real first fault (76 samples) ran 1.14 and 1.26 times
    # longer on two threads than on one (ONE_THREAD_SAMPLES); they had kept one per CPU.
    monkeypatch.delenv("LOADBAYES_NUM_THREADS", raising=False)
    for t_end_s, threads in ((1.0, 1), (6.0, None)):
        ev, _ = simulate_event("small_industrial", depth=0.3, t_end_s=t_end_s, fs=60.0,
                               seed=3)  # fmt: skip
        for name in ("slm", "cmld-lite"):
            model = dynamic_model(name, f_hz=60.0, window_s=0.0)
            problem = DesignProblem(model, [ev], model.default_prior([ev]))
            assert chain_threads(problem) == threads


def test_the_draws_do_not_depend_on_the_threads(monkeypatch):
    monkeypatch.delenv("LOADBAYES_NUM_THREADS", raising=False)
    prob, _ = _problem(1.0)
    start = nls(prob)
    runs = [sample(prob, start=start, draws=300, burn=150, chains=2, seed=4, workers=w)
            for w in (None, 1, 2)]  # fmt: skip
    for other in runs[1:]:
        for a, b in zip(runs[0], other, strict=True):
            np.testing.assert_array_equal(a.theta, b.theta)
            np.testing.assert_array_equal(a.beta, b.beta)
