import numpy as np
import pytest

from loadbayes.baselines.kalman import kalman, kalman_block
from loadbayes.baselines.least_squares import least_squares, least_squares_block
from loadbayes.core.stats import RegressionStats
from loadbayes.fit import accumulate
from loadbayes.models.zip import ZIPModel


def _zip_data(n=400, seed=0):
    rng = np.random.default_rng(seed)
    v = rng.uniform(0.8, 1.1, n)
    p = 0.4 * v**2 + 0.3 * v + 0.3 + rng.normal(0, 0.01, n)
    return {"v": v, "p": p}


def test_ls_block_closed_form():
    rng = np.random.default_rng(1)
    z = rng.normal(size=(50, 2))
    r = z @ [1.0, -2.0] + rng.normal(0, 0.1, 50)
    est = least_squares_block(RegressionStats(z.T @ z, z.T @ r, float(r @ r), 50))
    coef = np.linalg.solve(z.T @ z, z.T @ r)
    res = r - z @ coef
    s2 = res @ res / 48
    np.testing.assert_allclose(est.mean, coef, rtol=1e-10)
    np.testing.assert_allclose(est.sigma2, s2, rtol=1e-8)
    np.testing.assert_allclose(est.cov, s2 * np.linalg.inv(z.T @ z), rtol=1e-8)


def test_kalman_without_process_noise_is_recursive_least_squares():
    # With Q = 0 and a diffuse start, the filter's final state is the ridge solution
    # (Z'Z/R + P0^-1)^-1 Z'r/R: a closed form to check against.
    rng = np.random.default_rng(2)
    z = rng.normal(size=(30, 2))
    r = z @ [0.5, 1.5] + rng.normal(0, 0.2, 30)
    res = kalman_block(z, r, measurement_var=0.04, p0=10.0)
    lam = z.T @ z / 0.04 + np.eye(2) / 10.0
    np.testing.assert_allclose(res.mean, np.linalg.solve(lam, z.T @ r / 0.04), rtol=1e-9)
    np.testing.assert_allclose(res.cov, np.linalg.inv(lam), rtol=1e-9)


def test_kalman_with_process_noise_tracks_a_step():
    rng = np.random.default_rng(3)
    n = 4000
    z = np.column_stack([rng.uniform(0.5, 1.5, n), np.ones(n)])
    b = np.where(np.arange(n)[:, None] < n // 2, [1.0, 0.0], [2.0, 0.5])
    r = (z * b).sum(axis=1) + rng.normal(0, 0.05, n)
    fixed = kalman_block(z, r, measurement_var=0.0025)
    walk = kalman_block(z, r, measurement_var=0.0025, process_noise=1e-5, return_path=True)
    assert np.abs(walk.mean - [2.0, 0.5]).max() < 0.1
    assert np.abs(fixed.mean - [2.0, 0.5]).max() > 0.3  # averages the two regimes
    assert walk.path_mean.shape == (n, 2)


def test_zip_baselines_agree_with_truth_and_each_other():
    data = _zip_data()
    model = ZIPModel(with_q=False)
    gram = accumulate(model, [data])
    ls = least_squares(model, gram)
    kf = kalman(model, data)
    for post in (ls, kf):
        est = post.settings["estimate"]
        assert est["a1"] + est["a2"] + est["a3"] == pytest.approx(1.0)
        assert post.method in ("least-squares", "kalman")
    np.testing.assert_allclose(
        kf.settings["estimate"]["a1"], ls.settings["estimate"]["a1"], atol=0.01
    )
    s = ls.summary()
    assert s.loc["a1", "hdi_low"] < 0.4 < s.loc["a1", "hdi_high"]
