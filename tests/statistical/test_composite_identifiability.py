"""On a shallow (5%) sag the fit must say which motor parameters the event cannot fix."""

from __future__ import annotations

import pytest

from loadbayes.cases.composite_sim import simulate_event
from loadbayes.core.settings import SamplerSettings
from loadbayes.fit.composite.driver import fit_composite
from loadbayes.models.zip_motor import CompositeModel

pytestmark = pytest.mark.statistical


def _fit(depth):
    ev, _ = simulate_event(
        "small_industrial", depth=depth, noise=0.01, seed=5, t_end_s=2.0, duration_s=0.3
    )
    run = SamplerSettings(draws=1500, burn=700, chains=2, seed=1)
    return fit_composite(CompositeModel(window_s=0), [ev], sampler=run).posterior


def test_a_shallow_sag_is_reported_as_prior_driven_and_a_deep_one_is_not():
    shallow = _fit(0.05)
    ident = shallow.extra_json["identifiability"]
    verdicts = {k: v["verdict"] for k, v in ident["parameters"].items()}
    assert "prior-driven" in verdicts.values(), verdicts
    assert "close to the prior" in ident["summary"]
    assert any("deeper" in h for h in ident["what_would_help"])
    assert any("more events" in h for h in ident["what_would_help"])
    assert any("nameplate" in h for h in ident["what_would_help"])
    assert any("prior-driven" in w for w in shallow.warnings)

    deep = _fit(0.5)
    deep_ident = deep.extra_json["identifiability"]
    n_weak = sum(v["verdict"] == "prior-driven" for v in deep_ident["parameters"].values())
    assert n_weak < sum(v == "prior-driven" for v in verdicts.values())
    # The ratio that the paper's b2 is, (X - X') / T', is what a deep sag pins down.
    assert deep_ident["motor_share"]["well_determined"]
