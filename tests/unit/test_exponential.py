import math

import numpy as np
import pytest
from scipy import integrate

from loadbayes.core.settings import DataSpec, SamplerSettings
from loadbayes.fit import fit_exp, fit_zip
from loadbayes.io.errors import DataError
from loadbayes.models.exponential import ExponentialModel
from loadbayes.posterior import Posterior
from loadbayes.studies.model_choice import pointwise_loglik, verdict

FAST = {"chains": 2, "draws": 1500, "burn": 400}


def _data(n=300, seed=0, np_=1.3, nq=3.0, kpf=0.0, kqf=0.0, p0=1.0, q0=0.5, noise=0.01):
    rng = np.random.default_rng(seed)
    v = rng.uniform(0.85, 1.05, n)
    f = 60 + rng.normal(0, 0.3, n)
    df = (f - 60) / 60
    p = p0 * v**np_ * (1 + kpf * df) + rng.normal(0, noise, n)
    q = q0 * v**nq * (1 + kqf * df) + rng.normal(0, noise, n)
    return {"v": v, "p": p, "q": q, "f": f}


def test_structure_by_options():
    m = ExponentialModel()
    assert m.coefficients == ["np", "nq"]
    m = ExponentialModel(p0="auto", with_q=False, with_f=True)
    assert m.coefficients == ["np", "kpf", "p0"]
    m = ExponentialModel(p0="auto", with_f=True, noise="multiplicative")
    assert m.gram_columns == ("lx", "1", "df", "lp", "lq")
    assert [b.coef_names for b in m.blocks] == [("log_p0", "np", "kpf"), ("nq", "kqf")]
    for bad in ({"v0": 0.0}, {"f0": -1.0}, {"noise": "loud"}, {"p0": 0.0}, {"q0": "x"}):
        with pytest.raises(ValueError):
            ExponentialModel(**bad)


def test_multiplicative_refuses_non_positive_power_with_its_row():
    d = _data(20)
    d["p"][6] = -0.1
    with pytest.raises(DataError, match="row 7") as err:
        ExponentialModel(noise="multiplicative").rows(d)
    assert err.value.column == "p"


@pytest.mark.parametrize("noise", ["additive", "multiplicative"])
def test_recovers_exponents(noise):
    d = _data()
    post = fit_exp(
        d,
        sampler=SamplerSettings(seed=1, **FAST),
        spec=DataSpec(f_col="f", q0=0.5, p0=1.0),
        with_f=False,
        noise=noise,
    )
    m, s = post.mean(), post.summary()
    assert set(post.names) == {"np", "nq", "tau_p", "tau_q"}
    assert abs(m["np"] - 1.3) < 4 * s.loc["np", "sd"] + 0.01
    assert abs(m["nq"] - 3.0) < 4 * s.loc["nq", "sd"] + 0.01
    assert s.loc["np", "r_hat"] < 1.02


def test_auto_nominal_and_frequency():
    d = _data(n=600, kpf=2.0, kqf=-1.0, p0=0.8, noise=0.005)
    post = fit_exp(
        d, sampler=SamplerSettings(seed=2, **FAST), spec=DataSpec(f_col="f", p0=None, q0=None)
    )
    m, s = post.mean(), post.summary()
    assert set(post.names) == {"np", "kpf", "p0", "nq", "kqf", "q0", "tau_p", "tau_q"}
    for name, true in (("np", 1.3), ("p0", 0.8), ("kpf", 2.0), ("q0", 0.5), ("kqf", -1.0)):
        assert abs(m[name] - true) < 4 * s.loc[name, "sd"], (name, m[name], s.loc[name, "sd"])
    assert post.settings["acceptance"]["p"] > 0.15


def test_seed_reproducibility_and_predict():
    d = _data(100)
    a = fit_exp(
        d, sampler=SamplerSettings(seed=3, **FAST), spec=DataSpec(f_col="f", q0=0.5, p0=1.0)
    )
    b = fit_exp(
        d, sampler=SamplerSettings(seed=3, **FAST), spec=DataSpec(f_col="f", q0=0.5, p0=1.0)
    )
    assert np.array_equal(a.draws["np"], b.draws["np"])
    model = ExponentialModel(q0=0.5)
    pred = model.predict(a.draws, np.linspace(0.9, 1.0, 5), rng=0)
    assert list(pred.columns) == ["v", "p_mean", "p_low", "p_high", "q_mean", "q_low", "q_high"]
    assert np.all(pred["p_low"] <= pred["p_mean"]) and np.all(pred["p_mean"] <= pred["p_high"])
    assert pred["p_mean"].iloc[-1] == pytest.approx(1.0, abs=0.01)


def test_bad_input():
    d = _data(50)
    with pytest.raises(DataError, match="'p'"):
        fit_exp(
            {"v": d["v"]}, sampler=SamplerSettings(**FAST), spec=DataSpec(f_col="f", p0=1.0, q0=1.0)
        )
    d2 = dict(d, v=d["v"].copy())
    d2["v"][3] = -1
    with pytest.raises(DataError, match="row 4"):
        fit_exp(d2, sampler=SamplerSettings(**FAST), spec=DataSpec(f_col="f", p0=1.0, q0=1.0))
    with pytest.raises(DataError, match="fewer"):
        fit_exp(
            {"v": d["v"][:2], "p": d["p"][:2]},
            sampler=SamplerSettings(**FAST),
            spec=DataSpec(f_col="f", p0=None),
            with_f=False,
        )
    with pytest.raises(DataError, match="spread"):
        fit_exp(
            {"v": np.ones(10), "p": np.ones(10)},
            sampler=SamplerSettings(**FAST),
            spec=DataSpec(f_col="f", p0=1.0, q0=1.0),
        )


# ------------------------------------------------ pointwise likelihoods (model choice)
def _one_draw(model, method, **draws):
    return Posterior({k: np.full((1, 2), v) for k, v in draws.items()}, model=model, method=method)


def test_pointwise_loglik_is_a_density_of_p_in_data_units():
    """Each candidate's density of P integrates to one over P: the Jacobians are right."""
    data = {"v": np.array([0.9]), "p": np.array([0.0])}
    cases = [
        ("zip", {"a1": 0.3, "a2": 0.2, "a3": 0.5, "tau_p": 400.0}, {"v0": 1.0, "p0": 2.0}),
        ("zip", {"a1": 0.3, "a2": 0.2, "a3": 0.5, "tau_p": 400.0, "p0": 2.0},
         {"v0": 1.0, "p0": "auto"}),
        ("exp", {"np": 1.5, "tau_p": 400.0}, {"v0": 1.0, "p0": 2.0, "noise": "additive"}),
        ("exp", {"np": 1.5, "tau_p": 400.0}, {"v0": 1.0, "p0": 2.0, "noise": "multiplicative"}),
        ("exp", {"np": 1.5, "tau_p": 400.0, "p0": 2.0},
         {"v0": 1.0, "p0": "auto", "noise": "multiplicative"}),
    ]  # fmt: skip
    for model, draws, settings in cases:
        post = _one_draw(model, "t", **draws)
        post.settings.update(settings)

        def dens(p, post=post):
            return math.exp(pointwise_loglik(post, {"v": data["v"], "p": np.array([p])})[0, 0, 0])

        total, _ = integrate.quad(dens, 1e-9, 4.0, points=[1.5, 1.7, 1.9], limit=200)
        assert total == pytest.approx(1.0, abs=1e-6), (model, settings)


def test_student_t_pointwise_and_verdict():
    post = _one_draw("zip", "t", a1=0.0, a2=0.0, a3=1.0, tau_p=1.0, nu_p=3.0)
    post.settings.update(v0=1.0, p0=1.0, likelihood="student-t", nu="auto")
    ll = pointwise_loglik(post, {"v": np.array([1.0]), "p": np.array([1.0])})
    from scipy import stats

    assert ll[0, 0, 0] == pytest.approx(stats.t.logpdf(0.0, 3.0))
    import pandas as pd

    t = pd.DataFrame({"elpd_diff": [0.0, 30.0], "dse": [0.0, 5.0], "z": [0.0, 6.0]},
                     index=["zip", "exponential"])  # fmt: skip
    assert "clearly support zip over exponential" in verdict(t)


def test_same_scale_as_zip():
    """A ZIP fit and an exponential fit of the same data give log-likelihoods of one scale."""
    d = _data(200, np_=2.0)
    d = {"v": d["v"], "p": d["p"]}
    z = fit_zip(
        d, with_q=False, sampler=SamplerSettings(seed=0, **FAST), spec=DataSpec(p0=1.0, q0=1.0)
    )
    e = fit_exp(
        d,
        with_q=False,
        sampler=SamplerSettings(seed=0, **FAST),
        spec=DataSpec(f_col="f", p0=1.0, q0=1.0),
    )
    lz = pointwise_loglik(z, d, max_draws=200).mean()
    le = pointwise_loglik(e, d, max_draws=200).mean()
    # x^2 is both a ZIP (a1 = 1) and an exponential (np = 2) load: equal fits
    assert lz == pytest.approx(le, abs=0.05)


def test_a_frequency_column_of_another_system_or_per_unit_is_refused():
    # 50 Hz data at the default f0 = 60: every sample a -17% excursion, kpf and kqf
    # fitted to it (it ran, silently); a column in per unit: -98%.
    data = _data(n=120)
    with pytest.raises(DataError, match=r"column 'f': the frequency has median 49.97.*give f0=50"):
        fit_exp(dict(data, f=data["f"] - 10.0), sampler=SamplerSettings(**FAST))
    with pytest.raises(DataError, match=r"median 0.9995, .*looks per unit"):
        fit_exp(dict(data, f=data["f"] / 60.0), sampler=SamplerSettings(**FAST))
    # Right as given: 50 Hz data with f0=50, and the default on 60 Hz data.
    fit_exp(dict(data, f=data["f"] - 10.0), f0=50.0, sampler=SamplerSettings(**FAST))
    fit_exp(data, sampler=SamplerSettings(**FAST))
