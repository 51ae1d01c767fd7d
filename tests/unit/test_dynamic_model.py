"""A second dynamic model is one class against the protocol plus a line in the registry.

The model here is written in this file and nowhere in the package: a static-only
"composite" with no motor, ``P = p0 x^n_p``, ``Q = q0 x^n_q`` with ``x = V / V0``, whose
exponents are nonlinear and whose powers are linear. It goes through the same
``fit_composite`` as ``zip+motor`` (the NLS start, the Metropolis-within-Gibbs sampler,
the named draws, the JSON contract), on data generated here.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np
import pandas as pd
import pytest

import loadbayes
from loadbayes.core.settings import SamplerSettings
from loadbayes.io.errors import OptionError
from loadbayes.models.base import DynamicLoadModel, GaussianPrior
from loadbayes.models.dynamic import DYNAMIC_MODELS, dynamic_model


@dataclass(frozen=True)
class ExponentialLoad:
    """``P = p0 x^n_p``, ``Q = q0 x^n_q``: two nonlinear exponents, two linear powers."""

    name: ClassVar[str] = "exponential-static"
    theta_names: ClassVar[tuple[str, ...]] = ("n_p", "n_q")
    free_coordinates: ClassVar[tuple[str, ...]] = ("n_p", "n_q")
    scale_free: ClassVar[np.ndarray] = np.eye(2)
    beta_names: ClassVar[tuple[str, ...]] = ("p0", "q0")
    quantities: ClassVar[dict] = {
        "n_p": ("-", "exponent of P in V"),
        "n_q": ("-", "exponent of Q in V"),
        "p0": ("p.u.", "load P at v0"),
        "q0": ("p.u.", "load Q at v0"),
    }

    def default_prior(self, events):
        s = max(float(np.max(np.hypot(e.p, e.q))) for e in events)
        return GaussianPrior(mean=[1.0, 2.0], sd=[3.0, 3.0], beta_sd=[10 * s, 10 * s])

    def response(self, event, theta):
        return event.x ** theta[0], event.x ** theta[1]

    def design(self, event, rp, rq):
        zero = np.zeros(event.n)
        return np.column_stack([rp, zero]), np.column_stack([zero, rq])

    def composition(self, beta):
        return {"p0": beta[..., 0], "q0": beta[..., 1]}


TRUTH = {"n_p": 1.3, "n_q": 2.6, "p0": 0.8, "q0": 0.3}


def _sag(depth: float, seed: int, noise: float = 0.003) -> pd.DataFrame:
    # Two seconds at 60/s with a sag of `depth` from 0.5 to 0.8 s and a slow recovery,
    # powers from the exponential law plus Gaussian noise (written here).
    rng = np.random.default_rng(seed)
    t = np.arange(0.0, 2.0, 1 / 60)
    v = (
        1.0
        - depth * ((t >= 0.5) & (t < 0.8))
        - 0.03 * depth * np.exp(-(t - 0.8) / 0.3) * (t >= 0.8)
    )
    p = TRUTH["p0"] * v ** TRUTH["n_p"] + rng.normal(0, noise, t.size)
    q = TRUTH["q0"] * v ** TRUTH["n_q"] + rng.normal(0, noise, t.size)
    return pd.DataFrame({"t_s": t, "v": v, "p": p, "q": q})


def test_the_toy_is_a_dynamic_model_and_registers_in_one_line(monkeypatch):
    assert isinstance(ExponentialLoad(), DynamicLoadModel)
    monkeypatch.setitem(DYNAMIC_MODELS, ExponentialLoad.name, ExponentialLoad)  # the line
    assert isinstance(dynamic_model("exponential-static"), ExponentialLoad)
    with pytest.raises(OptionError, match="one of zip\\+motor"):
        dynamic_model("no-such-model")


def test_a_static_only_model_goes_through_the_same_fit():
    events = [_sag(0.3, seed=1), _sag(0.15, seed=2)]
    fit = loadbayes.fit_composite(
        ExponentialLoad(), events,
        sampler=SamplerSettings(draws=3000, burn=1000, chains=2, seed=4, threads=1),
    )  # fmt: skip
    post = fit.posterior
    # The contract of any composite fit: event 0's plain names, event 1's suffixed.
    for name in ("n_p", "n_q", "p0", "q0", "p0_e1", "q0_e1", "tau_p", "tau_q"):
        assert post.draws[name].shape == (2, 2000), name
    assert post.free == ["n_p", "n_q"]
    summary = post.summary()
    # Every true value inside its 95% interval (seed fixed; the fit's own chains). With
    # 240 samples at 0.3% noise the exponents are known to about +-0.02.
    for name, true in TRUTH.items():
        lo, hi = summary.loc[name, "hdi_low"], summary.loc[name, "hdi_high"]
        assert lo <= true <= hi, (name, lo, hi)
        assert hi - lo < 0.1, (name, lo, hi)
    assert summary.loc[["n_p", "n_q"], "r_hat"].max() < 1.05
    # The baseline (NLS) names the same quantities, its start the model's coordinates.
    assert set(fit.baseline.draws) == set(post.draws)
    assert set(fit.baseline.settings["estimate_u"]) == {"n_p", "n_q"}
    # What only zip+motor has (its identifiability in words, the residuals) is absent,
    # not made up.
    assert "identifiability" not in post.extra_json


def test_the_old_keywords_and_a_missing_model_say_the_new_spelling():
    with pytest.raises(TypeError, match=r"draws= is now sampler=SamplerSettings\(draws=100\)"):
        loadbayes.fit_composite(ExponentialLoad(), [_sag(0.3, 1)], draws=100)
    with pytest.raises(TypeError, match="the first argument is the model"):
        loadbayes.fit_composite([_sag(0.3, 1)])


def test_the_driver_names_the_new_place_of_an_old_keyword_too():
    from loadbayes.fit.composite.api import read
    from loadbayes.fit.composite.driver import fit_composite

    events = read([_sag(0.3, 1)])
    moved = r"torque= is now model=CompositeModel\(torque='estimate'\)"
    with pytest.raises(TypeError, match=moved):
        fit_composite(ExponentialLoad(), events, torque="estimate")
