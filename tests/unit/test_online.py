import numpy as np
import pytest
from scipy import stats

from loadbayes.baselines.kalman import kalman_block
from loadbayes.core.priors import BlockPrior
from loadbayes.inference.online import (
    OnlinePrior,
    OnlineTracker,
    _quantile_table,
    _t_quantile,
    track,
)

PRIOR = OnlinePrior.weak(2, coef_sd=3.0, noise_sd=0.2, shape=2.0)
C = np.array([[1.0, 0.0], [0.0, 1.0], [-1.0, -1.0]])
C0 = np.array([0.0, 0.0, 1.0])


def _data(n=400, seed=0):
    rng = np.random.default_rng(seed)
    z = rng.normal(size=(n, 2))
    r = z @ np.array([0.5, -1.0]) + rng.normal(0, 0.1, n)
    return z, r


def _batch(z, r, w=None, prior=PRIOR, prob=0.95):
    """Weighted conjugate posterior in closed form: mean and central interval."""
    w = np.ones(len(r)) if w is None else w
    lam = prior.precision + (z * w[:, None]).T @ z
    m = np.linalg.solve(lam, prior.precision @ prior.mean + (z * w[:, None]).T @ r)
    a = prior.shape + 0.5 * w.sum()
    b = prior.rate + 0.5 * (
        np.sum(w * (r - z @ m) ** 2) + (m - prior.mean) @ prior.precision @ (m - prior.mean)
    )
    cov = np.linalg.inv(lam)
    loc = C @ m + C0
    sc = np.sqrt(b / a * np.einsum("ij,jk,ik->i", C, cov, C))
    q = stats.t.ppf(0.5 + prob / 2, 2 * a)
    return loc, loc - q * sc, loc + q * sc


def _check(res, t, expect):
    for got, want in zip((res.mean[t], res.low[t], res.high[t]), expect, strict=True):
        np.testing.assert_allclose(got, want, rtol=1e-8, atol=1e-8)


def test_exact_recursion_matches_the_batch_posterior():
    z, r = _data()
    res = track(z, r, prior=PRIOR, contrasts=C, offsets=C0)
    for t in (0, 1, 5, 100, 399):
        _check(res, t, _batch(z[: t + 1], r[: t + 1]))


@pytest.mark.parametrize("window", [1, 7, 50])
def test_window_matches_the_batch_posterior_of_the_last_n(window):
    z, r = _data()
    res = track(z, r, prior=PRIOR, window=window, contrasts=C, offsets=C0)
    for t in (0, window - 1, window, window + 3, 2 * window, 3 * window + 1, 399):
        s = max(0, t - window + 1)
        _check(res, t, _batch(z[s : t + 1], r[s : t + 1]))


def test_forgetting_matches_the_weighted_batch_posterior():
    z, r = _data()
    lam = 0.97
    res = track(z, r, prior=PRIOR, forgetting=lam, contrasts=C, offsets=C0)
    for t in (0, 3, 50, 399):
        # stabilised forgetting: weight lam^age on each sample, the prior's stays 1
        _check(res, t, _batch(z[: t + 1], r[: t + 1], lam ** np.arange(t, -1, -1.0)))


def test_forgetting_one_is_exact_bayes():
    z, r = _data()
    a = track(z, r, prior=PRIOR, forgetting=1.0)
    b = track(z, r, prior=PRIOR)
    np.testing.assert_array_equal(a.mean, b.mean)


def test_drift_mean_is_the_kalman_filter():
    z, r = _data()
    w = 0.01
    res = track(z, r, prior=PRIOR, drift=w)
    kf = kalman_block(
        z, r, measurement_var=1.0, process_noise=w, p0=np.linalg.inv(PRIOR.precision),
        x0=PRIOR.mean, return_path=True,
    )  # fmt: skip
    np.testing.assert_allclose(res.mean, kf.path_mean, rtol=1e-9, atol=1e-10)


@pytest.mark.parametrize("mode", [{}, {"forgetting": 0.99}, {"window": 37}, {"drift": 0.1}])
def test_chunked_stream_is_bit_identical(mode):
    z, r = _data()
    whole = track(z, r, prior=PRIOR, contrasts=C, offsets=C0, **mode)
    tr = OnlineTracker(2, prior=PRIOR, contrasts=C, offsets=C0, **mode)
    cuts = [0, 13, 100, 101, 250, 400]
    parts = [tr.update(z[a:b], r[a:b]) for a, b in zip(cuts, cuts[1:], strict=False)]
    for name in ("mean", "low", "high", "scale", "dof"):
        np.testing.assert_array_equal(
            np.concatenate([getattr(p, name) for p in parts]), getattr(whole, name)
        )
    assert tr.n_seen == 400


def test_long_window_run_stays_exact():
    # rounding of add/remove pairs is wiped out by the periodic refresh
    rng = np.random.default_rng(3)
    n = 200_000
    z = rng.normal(size=(n, 2)) * np.array([1.0, 1e-3]) + np.array([5.0, 0.0])
    r = z @ np.array([0.5, -1.0]) + rng.normal(0, 0.01, n)
    res = track(z, r, prior=PRIOR, window=500, contrasts=C, offsets=C0)
    _check(res, n - 1, _batch(z[-500:], r[-500:]))


def test_quantile_table_accuracy():
    table = _quantile_table(0.975)
    dof = np.exp(np.linspace(np.log(2.0), np.log(1e6), 500))
    got = np.array([_t_quantile(d, table) for d in dof])
    np.testing.assert_allclose(got, stats.t.ppf(0.975, dof), rtol=1e-7)


def test_prior_constructors_and_posterior():
    p = OnlinePrior.weak(3, coef_sd=2.0, noise_sd=0.1, shape=1.0)
    assert p.k == 3 and p.rate == pytest.approx(0.01)
    np.testing.assert_allclose(np.diag(p.precision), 0.01 / 4)
    bp = BlockPrior(mean=[1.0, 2.0], precision=[1.0, 2.0], shape=2.0, rate=3.0, conjugate=True)
    op = OnlinePrior.from_block_prior(bp)
    assert op.shape == 2.0 and op.rate == 3.0
    with pytest.raises(ValueError, match="conjugate"):
        OnlinePrior.from_block_prior(BlockPrior.weak(2))
    tr = OnlineTracker(2, prior=PRIOR)
    z, r = _data(50)
    tr.update(z, r)
    post = tr.posterior()
    lam = PRIOR.precision + z.T @ z
    np.testing.assert_allclose(post["precision"], lam, rtol=1e-12)
    assert post["shape"] == pytest.approx(PRIOR.shape + 25)


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"forgetting": 0.9, "window": 5}, "at most one"),
        ({"forgetting": 0.0}, "forgetting"),
        ({"forgetting": 1.5}, "forgetting"),
        ({"window": 0}, "window"),
        ({"drift": -1.0}, "semi-definite"),
        ({"prob": 1.0}, "prob"),
        ({"contrasts": np.ones((2, 3))}, "columns"),
        ({"prior": OnlinePrior.weak(3)}, "coefficients"),
    ],
)
def test_bad_settings(kwargs, match):
    with pytest.raises(ValueError, match=match):
        OnlineTracker(2, **kwargs)


def test_bad_data():
    tr = OnlineTracker(2)
    with pytest.raises(ValueError, match="must be"):
        tr.update(np.ones((5, 3)), np.ones(5))
    with pytest.raises(ValueError, match="finite"):
        tr.update(np.ones((2, 2)), np.array([1.0, np.nan]))
    with pytest.raises(ValueError, match="positive-definite"):
        OnlinePrior(np.zeros(2), np.zeros(2))


def test_windowed_ls_baseline_matches_lstsq():
    from loadbayes.studies.tracking import windowed_ls

    z, r = _data(200)
    mean, low, high = windowed_ls(z, r, 30)
    for t in (40, 199):
        coef = np.linalg.lstsq(z[t - 29 : t + 1], r[t - 29 : t + 1], rcond=None)[0]
        np.testing.assert_allclose(mean[t], [coef[0], coef[1], 1 - coef.sum()], rtol=1e-8)
        assert np.all(low[t] < mean[t]) and np.all(mean[t] < high[t])
    assert np.all(np.isnan(mean[:2]))
