"""Estimated torque shares on a constant-torque motor under a deep sag."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from loadbayes.cases.composite_sim import simulate_event
from loadbayes.core.settings import SamplerSettings
from loadbayes.fit.composite.driver import fit_composite
from loadbayes.models.motor_library import MOTORS
from loadbayes.models.zip_motor import CompositeModel

pytestmark = pytest.mark.statistical


def test_a_constant_torque_motor_moves_the_shares_toward_c():
    motor = dataclasses.replace(MOTORS["small_industrial"], a=0.0, b=0.0, c=1.0)
    ev, truth = simulate_event(
        motor, depth=0.5, duration_s=0.3, noise=0.005, seed=4, t_end_s=2.5, fs=60.0
    )
    long_run = SamplerSettings(draws=8000, burn=2700, chains=2, seed=1)
    est = fit_composite(CompositeModel(window_s=0, torque="estimate"), [ev], sampler=long_run)
    short_run = SamplerSettings(draws=4000, burn=1300, chains=2, seed=1)
    default = fit_composite(CompositeModel(window_s=0), [ev], sampler=short_run)
    d = est.posterior.draws
    # Fixed seeds (deterministic). Measured with a long run (2 x 30,000 iterations, R-hat
    # <= 1.01): a 0.085, b 0.16, c 0.75 (sd 0.14) against the prior mean 1/3 each, f_m 0.511;
    # the misspecified A = 1 default puts f_m at 0.595 (truth 0.5, sd 0.011). The shares
    # mix slowly (ESS ~20 per 8,000 iterations; 4,000 were not enough: c 0.46), so this
    # run is 8,000 (it gives c 0.78). c > 0.5 and a < 0.2 sit 1.8 posterior sds from the
    # long run's means; the outcome is deterministic, its false-alarm rate over other
    # seeds was not measured (one other seed at 8,000 iterations: c 0.78, a 0.09).
    assert d["c"].mean() > 0.5 and d["a"].mean() < 0.2
    assert np.allclose(d["a"] + d["b"] + d["c"], 1.0)
    err_est = abs(d["f_m"].mean() - truth["f_m"])
    err_default = abs(default.posterior.draws["f_m"].mean() - truth["f_m"])
    assert err_est < 0.5 * err_default
    ident = est.posterior.extra_json["identifiability"]["torque"]
    assert set(ident["shares"]) == {"a", "b", "c"}
    assert "torque" in est.posterior.extra_json["identifiability"]["summary"]
    summary = est.posterior.summary()
    assert summary.loc["c", "sd"] > 0
