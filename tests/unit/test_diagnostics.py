"""Warnings that say what is known (issue 14): R-hat/ESS, identifiability, priors, V noise."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from loadbayes.diagnostics import (
    identifiability_notes,
    prior_dominance,
    sampler_warnings,
    voltage_noise_warning,
)
from loadbayes.fit.motor import steady_start_problem
from loadbayes.posterior import Posterior


def _table(r_hat, ess):
    return pd.DataFrame(
        {"r_hat": r_hat, "ess_bulk": ess, "ess_tail": ess}, index=[f"x{i}" for i in range(len(ess))]
    )


def test_rhat_and_ess_warnings_name_the_worst_parameter():
    # issue item 12: R-hat 1.029 and ESS 141 of 140,000 went unsaid
    ws = sampler_warnings(_table([1.0, 1.029], [5000.0, 141.0]), chains=4, kept=35_000)
    assert len(ws) == 2
    assert "R-hat up to 1.029 (x1" in ws[0] and "141 of 140000" in ws[1]
    assert sampler_warnings(_table([1.001], [4000.0]), chains=4, kept=1000) == []


def test_few_kept_draws_and_one_chain_are_said():
    ws = sampler_warnings(_table([np.nan], [np.nan]), chains=1, kept=10)
    assert any("10 kept draws" in w for w in ws) and any("one chain" in w for w in ws)


def _zip_post(a1_sd, n=4000, seed=0):
    rng = np.random.default_rng(seed)
    s = rng.normal(0, 1, (2, n))
    slope = 1.085 + a1_sd / 20 * rng.normal(0, 1, (2, n))  # 2 a1 + a2, well determined
    a1 = 0.4 + a1_sd * s
    a2 = slope - 2 * a1
    return Posterior(
        {"a1": a1, "a2": a2, "a3": 1 - a1 - a2}, model="zip", method="test",
        coefficients=["a1", "a2", "a3"], free=["a1", "a2"],
    )  # fmt: skip


@pytest.mark.parametrize(("a1_sd", "told"), [(0.3, True), (0.002, False)])
def test_identifiability_says_what_is_determined(a1_sd, told):
    post = _zip_post(a1_sd)
    assert any("cannot be told apart" in w for w in post.warnings)  # Posterior's own
    (note,) = identifiability_notes(post)
    assert "2 a1 + a2 (dP/dV at V0, per unit) = 1.08" in note
    # at a1 = 0.4 +/- 0.002 (3 M rows in the issue) "cannot be told apart" is wrong
    assert ("cannot be told apart" in note) is told
    assert ("each is still determined" in note) is not told


def test_motor_pair_wording_is_the_motors():
    rng = np.random.default_rng(1)
    b2 = rng.normal(0, 1, (2, 3000))
    ac = 3 * b2 + 0.01 * rng.normal(0, 1, (2, 3000))
    post = Posterior({"b2": b2, "ac": ac}, model="im", method="t", coefficients=["b2", "ac"],
                     free=["b2", "ac"])  # fmt: skip
    (note,) = identifiability_notes(post)
    assert "voltage range" not in note and "disturbance" in note
    assert "the data determine" in note


def test_prior_dominance():
    post = _zip_post(0.3)
    assert prior_dominance(post, {"a1": 0.35})  # posterior sd 0.3 vs prior 0.35
    assert prior_dominance(post, {"a1": 10.0}) == []


def test_voltage_noise_warning_on_noisy_and_smooth_voltage():
    rng = np.random.default_rng(3)
    t = np.arange(2000)
    smooth = 1 + 0.03 * np.sin(2 * np.pi * t / 2000)
    assert voltage_noise_warning(smooth) is None
    assert voltage_noise_warning(smooth + rng.normal(0, 0.01, t.size)) is not None
    assert voltage_noise_warning(smooth + rng.normal(0, 0.0005, t.size)) is None
    # Independent experiments (the paper's power flows): no time order, nothing to say.
    assert voltage_noise_warning(rng.uniform(0.66, 0.89, t.size)) is None


def test_steady_start():
    rng = np.random.default_rng(0)
    n = 1000
    dw = rng.normal(0, 1e-3, n)
    dw[300:400] += 0.1 * np.exp(-np.arange(100) / 30)
    assert steady_start_problem({"dw": dw}) is None  # noise only before the event
    why = steady_start_problem({"dw": dw[310:]})
    assert why and "dw" in why and "--t0" in why
    assert steady_start_problem({"dw": rng.normal(0, 1e-3, n)}) is None  # noise alone
