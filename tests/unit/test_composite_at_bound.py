"""A quantity piled against its prior's bound is "at its bound", never "well determined"
(issue 40: f_m 0.947 [0.847, 1.000] under bounded shares was called well determined).

The draws are built, not sampled: the verdict is a function of them.
"""

import numpy as np

from loadbayes.fit.composite.identifiability import (
    AT_BOUND,
    at_bound,
    identifiability,
    static_identifiability,
)
from loadbayes.measurements.record import EventRecord
from loadbayes.models.composite_prior import CompositePrior


def _event():
    t = np.arange(0, 1.0, 1 / 60)
    v = np.where((t > 0.3) & (t < 0.5), 0.8, 1.0)
    return EventRecord(t=t, v=v, p=np.ones_like(t), q=0.3 * np.ones_like(t), name="sag.csv")


def _piled(rng, shape, top=True):
    # Beta(6, 1) piles against 1 (its interval is about [0.54, 1.00]); 1 - it against 0.
    x = rng.beta(12.0, 1.0, shape)
    return x if top else 1 - x


def test_a_motor_share_on_its_bound_is_said_so():
    rng = np.random.default_rng(0)
    ev = _event()
    prior = CompositePrior.default([ev])
    theta = prior.theta_mean + 0.05 * rng.standard_normal((2, 500, 6))
    f_m = _piled(rng, (2, 500))
    assert float(np.std(f_m)) < 0.1  # the sd alone would say "well determined"
    ident = identifiability(theta, f_m, prior, 1, bounded=True)
    assert AT_BOUND in ident["summary"]
    assert "well determined" not in ident["summary"]
    assert not ident["motor_share"]["well_determined"]
    assert ident["motor_share"]["at_bound"][1] > 0.99
    # Free shares: f_m has no bound at 1, so nothing changes there.
    assert "well determined" in identifiability(theta, f_m, prior, 1)["summary"]
    # A share clear of its bounds is not at one.
    assert at_bound(0.5 + 0.02 * rng.standard_normal(1000)) is None


def test_a_static_share_on_its_bound_is_said_so():
    rng = np.random.default_rng(1)
    shape = (2, 1000)
    d = {"a1": _piled(rng, shape, top=False) * 0.3}
    d["a2"] = 0.3 + 0.01 * rng.standard_normal(shape)
    d["a3"] = 1 - d["a1"] - d["a2"]
    for k, m in (("a4", 0.4), ("a5", 0.3), ("a6", 0.3)):
        d[k] = m + 0.01 * rng.standard_normal(shape)
    d.update(p0=np.ones(shape), q0=0.3 * np.ones(shape), f_m=0.5 * np.ones(shape))
    out = static_identifiability(d, [_event()], bounded=True)
    assert "a1" in out["events"][0]["p"]["at_bound"]
    assert AT_BOUND in out["summary"] and "a1" in out["at_bound"]
    assert "determined by the data." not in out["summary"].replace(AT_BOUND, "")
    assert "at_bound" not in static_identifiability(d, [_event()])
