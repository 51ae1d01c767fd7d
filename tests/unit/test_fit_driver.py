"""One driver for every model: fit(model, data, method=...) picks the sampler by name."""

import numpy as np
import pytest

from loadbayes.core.settings import DataSpec, SamplerSettings
from loadbayes.fit import fit_exp, fit_zip
from loadbayes.fit.core import METHODS, fit
from loadbayes.models.exponential import ExponentialModel
from loadbayes.models.motor_fit import InductionMotorModel
from loadbayes.models.zip import ZIPModel

FAST = {"chains": 2, "draws": 1200, "burn": 200}


@pytest.fixture(scope="module")
def data():
    rng = np.random.default_rng(3)
    v = rng.uniform(0.9, 1.1, 400)
    p = 0.3 * v**2 + 0.2 * v + 0.5 + rng.normal(0, 0.01, v.size)
    return {"v": v, "p": p}


def test_gibbs_through_the_driver_is_the_zip_fit(data):
    a = fit(ZIPModel(with_q=False), data, sampler=SamplerSettings(seed=4, **FAST))
    b = fit_zip(data, sampler=SamplerSettings(seed=4, **FAST), spec=DataSpec(p0=1.0, q0=1.0))
    for name in ("a1", "a2", "a3", "tau_p"):
        np.testing.assert_array_equal(a.draws[name], b.draws[name])


def test_power_law_pieces_go_to_metropolis_within_gibbs(data):
    a = fit(ExponentialModel(with_q=False), data, sampler=SamplerSettings(seed=2, **FAST))
    b = fit_exp(
        data, sampler=SamplerSettings(seed=2, **FAST), spec=DataSpec(f_col="f", p0=1.0, q0=1.0)
    )
    assert a.method == b.method == "gibbs-mwg"
    np.testing.assert_array_equal(a.draws["np"], b.draws["np"])


@pytest.mark.parametrize("method", METHODS)
def test_every_method_returns_the_same_result_type(data, method):
    post = fit(ZIPModel(with_q=False), data, method=method, sampler=SamplerSettings(seed=1, **FAST))
    m = post.mean()
    assert abs(m["a1"] + m["a2"] + m["a3"] - 1.0) < 1e-9
    # The shares are nearly collinear on 0.9-1.1 p.u., but the load curve is pinned
    # (its sd is about 0.01 sqrt(3 / 400) = 1e-3): every method must find it, to 5 sd.
    x = np.array([0.9, 1.0, 1.1])
    curve = m["a1"] * x**2 + m["a2"] * x + m["a3"]
    truth = 0.3 * x**2 + 0.2 * x + 0.5
    assert np.max(np.abs(curve - truth)) < 5e-3, (method, m)
    assert post.draws["a1"].shape[0] == FAST["chains"]


def test_unknown_method_and_pieces_are_refused(data):
    with pytest.raises(ValueError, match="method must be one of"):
        fit(ZIPModel(with_q=False), data, method="nuts")
    with pytest.raises(ValueError, match="bilinear"):
        fit(InductionMotorModel(), {"ud": np.ones(3)})
