import json

import numpy as np
import pytest

from loadbayes.posterior import Posterior


def _post(corr=0.0, seed=0):
    rng = np.random.default_rng(seed)
    a = rng.normal(size=(4, 500))
    b = corr * a + np.sqrt(1 - corr**2) * rng.normal(size=(4, 500))
    return Posterior(
        {"a1": a, "a2": b, "tau_p": rng.gamma(5.0, size=(4, 500))},
        model="zip",
        method="gibbs-blocked",
        observed={"v": np.linspace(0.9, 1.1, 10)},
        settings={"n": 10, "seed": 3},
    )


def test_summary_columns_and_order():
    s = _post().summary(hdi_prob=0.9)
    assert list(s.index) == ["a1", "a2", "tau_p"]
    for col in ("mean", "sd", "hdi_low", "hdi_high", "ess_bulk", "ess_tail", "r_hat", "mcse_mean"):
        assert col in s.columns
    assert (s["hdi_low"] < s["hdi_high"]).all()


def test_identifiability_warning_only_when_correlated():
    assert not _post(0.5).warnings
    w = _post(0.999).warnings
    assert len(w) == 1 and "a1 and a2" in w[0] and "cannot be told apart" in w[0]


def test_netcdf_round_trip(tmp_path):
    p = _post()
    path = p.to_netcdf(tmp_path / "post.nc")
    q = Posterior.from_netcdf(path)
    assert q.names == p.names and q.model == "zip" and q.settings["seed"] == 3
    np.testing.assert_array_equal(q["a1"], p["a1"])
    np.testing.assert_array_equal(q.observed["v"], p.observed["v"])
    with pytest.raises(Exception, match="exists"):
        p.to_netcdf(tmp_path / "post.nc")


def test_json_contract(tmp_path):
    p = _post()
    path = p.to_json(tmp_path / "out.json", hdi_prob=0.9)
    d = json.loads(path.read_text())
    for key in (
        "model",
        "n",
        "scheme",
        "chains",
        "draws",
        "hdi_prob",
        "parameters",
        "correlation",
        "warnings",
    ):
        assert key in d
    assert set(d["parameters"]["a1"]) == {
        "mean",
        "sd",
        "hdi_low",
        "hdi_high",
        "r_hat",
        "ess_bulk",
        "ess_tail",
    }
    assert d["hdi_prob"] == 0.9 and d["chains"] == 4
    assert d["loadbayes_version"]


def test_from_gaussian_matches_mean_and_cov():
    cov = np.array([[1.0, 0.8], [0.8, 1.0]]) * 1e-2
    p = Posterior.from_gaussian(
        [0.3, 0.2],
        cov,
        ["a1", "a2"],
        model="zip",
        method="least-squares",
        chains=4,
        draws=5000,
        rng=1,
    )
    x = p.flat(["a1", "a2"])
    np.testing.assert_allclose(x.mean(axis=0), [0.3, 0.2], atol=5e-3)
    np.testing.assert_allclose(np.cov(x, rowvar=False), cov, atol=1e-3)
    assert p.settings["estimate"] == {"a1": 0.3, "a2": 0.2}


def test_shapes_validated():
    with pytest.raises(ValueError, match="chain, draw"):
        Posterior({"a": np.zeros(5)}, model="m", method="x")
