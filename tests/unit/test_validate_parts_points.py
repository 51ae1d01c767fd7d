"""``validate_parts_event`` of a model reading point samples, with rows left out.

A model of parts reading point samples (``window_s`` 0, the command's reading) predicts
every row of an event, straddling ones included; a window-means model predicts the kept
rows only. Scoring with rows excluded (``exclude=``, as ``compare_models`` and the
real-record study pass the reader's straddle flags) must score the kept rows of the same
prediction. Until 2026-12-02 it stopped with a broadcast error for point samples.
"""

from __future__ import annotations

import numpy as np
import pytest

from loadbayes.fit.composite.validate_parts import validate_parts_event
from loadbayes.measurements.record import EventRecord
from loadbayes.models.dynamic import dynamic_model
from loadbayes.posterior import Posterior


def _sag():
    # A 20% sag at 0.1 s for 0.1 s, 120 rows a second, P and Q written here with noise.
    t = np.arange(0.0, 0.5, 1.0 / 120)
    v = np.where((t >= 0.1) & (t < 0.2), 0.8, 1.0)
    rng = np.random.default_rng(3)
    p = 0.9 * v**1.5 + 0.005 * rng.standard_normal(t.size)
    q = 0.3 * v**2 + 0.005 * rng.standard_normal(t.size)
    return EventRecord(t, v, p, q, None, "sag")


def _posterior(model, n=6, seed=0):
    # Draws about the model's prior mean in its own coordinates (theta_names), and noise.
    ev = _sag()
    mean = model.default_prior([ev]).scale_free()[0]
    rng = np.random.default_rng(seed)
    draws = {name: np.full((1, n), m) for name, m in zip(model.theta_names, mean, strict=True)}
    draws.update(cq2=np.full((1, n), 1.0), cq1=np.zeros((1, n)), cq0=np.zeros((1, n)),
                 tau_p=rng.uniform(3e4, 4e4, (1, n)), tau_q=rng.uniform(3e4, 4e4, (1, n)),
                 p0=np.full((1, n), 0.9))  # fmt: skip
    return Posterior(draws, model=model.name, method="test")


@pytest.mark.parametrize("window_s", [0.0, 1 / 60])
def test_rows_left_out_are_not_scored_and_the_rest_match(window_s):
    model = dynamic_model("slm", f_hz=60.0, window_s=window_s)
    post = _posterior(model)
    ev = _sag()
    out = np.zeros(ev.n, bool)
    out[[12, 24]] = True  # the rows at the sag's inception and clearing
    whole = validate_parts_event(post, model, ev, seed=0)
    part = validate_parts_event(post, model, ev, exclude=out, seed=0)
    assert (part.n, part.n_excluded, int(part.scored.sum())) == (ev.n, 2, ev.n - 2)
    assert part.band["p_mean"].shape == (ev.n - 2,)
    if window_s == 0:  # point samples: the same prediction, the excluded rows dropped
        np.testing.assert_array_equal(part.band["p_mean"], whole.band["p_mean"][~out])
        np.testing.assert_array_equal(part.band["q_mean"], whole.band["q_mean"][~out])
