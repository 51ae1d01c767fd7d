import numpy as np
import pytest

from loadbayes.core.priors import BlockPrior
from loadbayes.core.settings import SamplerSettings
from loadbayes.core.stats import RegressionStats
from loadbayes.fit import fit_robust
from loadbayes.inference.gibbs import sample_block
from loadbayes.inference.robust import FLAG_SIGMAS, flag_threshold, sample_student_t
from loadbayes.models.zip import ZIPModel

FAST = {"chains": 2, "draws": 1500, "burn": 300}


def _data(n=300, seed=0, noise=0.05, lo=0.7, hi=1.1, bad=()):
    rng = np.random.default_rng(seed)
    x = rng.uniform(lo, hi, n)
    z = np.column_stack([x**2 - 1, x - 1])
    r = z @ np.array([0.4, 0.3]) + rng.normal(0, noise, n)
    r[list(bad)] = -1.0  # dropouts of y = P / P0 to zero
    return z, r


@pytest.mark.parametrize("nu", ["auto", 4.0])
def test_shapes_and_seed_reproducibility(nu):
    z, r = _data()
    prior = BlockPrior.weak(2)
    a = sample_student_t(z, r, prior, nu=nu, settings=SamplerSettings(**FAST, thin=2, seed=5))
    b = sample_student_t(z, r, prior, nu=nu, settings=SamplerSettings(**FAST, thin=2, seed=5))
    kept = len(range(300, 1500, 2))
    assert a.coef.shape == (2, kept, 2) and a.tau.shape == a.nu.shape == (2, kept)
    assert a.weight.shape == (300,)
    assert np.array_equal(a.coef, b.coef) and np.array_equal(a.nu, b.nu)
    c = sample_student_t(z, r, prior, nu=nu, settings=SamplerSettings(**FAST, thin=2, seed=6))
    assert not np.array_equal(a.coef, c.coef)
    assert np.all(np.isfinite(a.coef)) and np.all(a.tau > 0)
    if nu == "auto":
        assert np.all((a.nu >= 1) & (a.nu <= 1000)) and np.all(a.accept_nu > 0.1)
    else:
        assert np.all(a.nu == 4.0) and np.all(np.isnan(a.accept_nu))


def test_chains_do_not_depend_on_how_many_run():
    z, r = _data()
    two = sample_student_t(
        z, r, BlockPrior.weak(2), settings=SamplerSettings(chains=2, draws=400, burn=0, seed=9)
    )
    four = sample_student_t(
        z, r, BlockPrior.weak(2), settings=SamplerSettings(chains=4, draws=400, burn=0, seed=9)
    )
    assert np.array_equal(two.coef, four.coef[:2])


def test_large_nu_matches_the_gaussian_sampler():
    z, r = _data(n=400, noise=0.1)
    prior = BlockPrior.weak(2)
    t = sample_student_t(
        z, r, prior, nu=1e7, settings=SamplerSettings(chains=4, draws=4000, burn=500, seed=1)
    )
    st = RegressionStats(z.T @ z, z.T @ r, float(r @ r), len(r))
    g = sample_block(st, prior, settings=SamplerSettings(chains=4, draws=4000, burn=500, seed=1))
    sd = g.coef.std(axis=(0, 1))
    # means within 0.15 posterior sd (MCSE with ESS in the thousands is ~0.02 sd)
    diff = np.abs(t.coef.mean(axis=(0, 1)) - g.coef.mean(axis=(0, 1)))
    assert np.all(diff < 0.15 * sd), (diff, sd)
    np.testing.assert_allclose(t.coef.std(axis=(0, 1)), sd, rtol=0.1)
    np.testing.assert_allclose(np.mean(t.tau), np.mean(g.tau), rtol=0.05)


def test_outliers_get_low_weights_and_are_flagged():
    bad = [5, 50, 120, 200]
    z, r = _data(n=300, noise=0.02, bad=bad)
    res = sample_student_t(z, r, BlockPrior.weak(2), settings=SamplerSettings(**FAST, seed=3))
    assert set(bad) <= set(res.flagged().tolist())
    assert np.all(res.weight[bad] < 0.05)
    assert len(res.flagged()) <= len(bad) + 3
    assert np.median(res.nu) < 10  # heavy tails found
    # the estimate ignores the dropouts: it matches a Gaussian fit without them
    keep = np.setdiff1d(np.arange(300), bad)
    zk, rk = z[keep], r[keep]
    g = sample_block(
        RegressionStats(zk.T @ zk, zk.T @ rk, float(rk @ rk), keep.size),
        BlockPrior.weak(2),
        settings=SamplerSettings(**FAST, seed=3),
    )
    diff = np.abs(res.coef.mean(axis=(0, 1)) - g.coef.mean(axis=(0, 1)))
    assert np.all(diff < 0.5 * g.coef.std(axis=(0, 1))), diff


def test_flag_threshold_rule():
    assert flag_threshold(np.array([4.0, 4.0, 4.0])) == pytest.approx(5 / (4 + FLAG_SIGMAS**2))
    assert flag_threshold(1e9) == pytest.approx(1.0, rel=1e-6)


def test_conjugate_prior_runs():
    z, r = _data()
    prior = BlockPrior(mean=[0, 0], precision=[1e-2, 1e-2], shape=1e-3, rate=1e-6, conjugate=True)
    res = sample_student_t(z, r, prior, nu=5.0, settings=SamplerSettings(**FAST, seed=0))
    np.testing.assert_allclose(res.coef.mean(axis=(0, 1)), [0.4, 0.3], atol=0.2)


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"nu": 0.0}, "nu"),
        ({"nu": "many"}, "nu"),
        ({"burn": 2000}, "burn-in"),
        ({"chains": 0}, "chains"),
        ({"init": "nowhere"}, "init"),
    ],
)
def test_bad_settings(kwargs, match):
    z, r = _data(n=50)
    opts = {**FAST, **kwargs}
    nu = opts.pop("nu", "auto")
    with pytest.raises(ValueError, match=match):
        sample_student_t(z, r, BlockPrior.weak(2), nu=nu, settings=SamplerSettings(seed=0, **opts))


def test_bad_data():
    z, r = _data(n=50)
    with pytest.raises(ValueError, match="n = len"):
        sample_student_t(z, r[:-1], BlockPrior.weak(2))
    with pytest.raises(ValueError, match="coefficients"):
        sample_student_t(z, r, BlockPrior.weak(3))
    with pytest.raises(ValueError, match="too few"):
        sample_student_t(z[:2], r[:2], BlockPrior.weak(2))
    r2 = r.copy()
    r2[3] = np.nan
    with pytest.raises(ValueError, match="finite"):
        sample_student_t(z, r2, BlockPrior.weak(2))


def test_fit_robust_on_zip_model():
    rng = np.random.default_rng(2)
    v = rng.uniform(0.85, 1.08, 300)
    p = 0.3 * v**2 + 0.2 * v + 0.5 + rng.normal(0, 0.01, 300)
    q = 0.6 * v**2 + 0.1 * v + 0.3 + rng.normal(0, 0.01, 300)
    p[[7, 70]] = 0.0
    post = fit_robust(ZIPModel(), {"v": v, "p": p, "q": q}, sampler=SamplerSettings(seed=1, **FAST))
    assert post.method == "gibbs-student-t" and post.model == "zip"
    assert {"a1", "a2", "a3", "a4", "a5", "a6", "tau_p", "tau_q", "nu_p", "nu_q"} == set(post.names)
    assert post.constant["weight_p"].shape == (300,)
    assert {7, 70} <= set(post.settings["flagged"]["p"])
    assert post.settings["likelihood"] == "student-t"
    assert any("bad data" in w for w in post.warnings)
    m = post.mean()
    assert m["a1"] + m["a2"] + m["a3"] == pytest.approx(1.0)
    assert abs(m["a3"] - 0.5) < 0.15
    fixed = fit_robust(
        ZIPModel(with_q=False), {"v": v, "p": p}, nu=4.0, sampler=SamplerSettings(seed=1, **FAST)
    )
    assert "nu_p" not in fixed.names and fixed.settings["nu"] == 4.0


@pytest.mark.parametrize("kind", ["spike", "dropout", "stuck", "mixed"])
def test_corrupt_scenarios(kind):
    import pandas as pd

    from loadbayes.cases.scenarios import corrupt

    rng = np.random.default_rng(0)
    df = pd.DataFrame({"p_meas_pu": rng.normal(0.85, 0.1, 400), "q_meas_pu": 0.8})
    out = corrupt(df, kind=kind, fraction=0.05, seed=1)
    assert out["bad"].sum() == 20 and out.attrs["corruption"]["n_bad"] == 20
    assert np.array_equal(out["p_meas_pu"][~out["bad"]], df["p_meas_pu"][~out["bad"]])
    changed = out["p_meas_pu"][out["bad"]].to_numpy()
    if kind == "dropout":
        assert np.all(changed == 0.0)
    if kind == "spike":
        diff = np.abs(changed - df["p_meas_pu"][out["bad"]].to_numpy())
        assert np.all((diff >= 0.5) & (diff <= 1.0))
    if kind == "stuck":
        idx = np.flatnonzero(out["bad"])
        assert np.all(out["p_meas_pu"].to_numpy()[idx] == out["p_meas_pu"].to_numpy()[idx - 1])
    again = corrupt(df, kind=kind, fraction=0.05, seed=1)
    pd.testing.assert_frame_equal(out, again)
    with pytest.raises(ValueError, match="kind"):
        corrupt(df, kind="noise", fraction=0.05)
