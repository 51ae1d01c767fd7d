"""The compiled pieces of the composite sampler's every iteration against NumPy's formulas.

They replaced NumPy code whose per-call overhead, held under the GIL by four chain
threads, was most of an iteration's cost (issue 21's speed); each must give what the
formula it replaced gives.
"""

import numpy as np
import pytest

from loadbayes.fit.composite.problem import _T_INV, theta_of
from loadbayes.inference.condlinear import GroupSums, _given_one, draw_tau, residual_ss


def _spd(k, rng):
    a = rng.normal(size=(k, k))
    return a @ a.T + 0.1 * np.eye(k)


@pytest.mark.parametrize("j", [0, 3, 6])
def test_the_conditional_draw_is_the_gaussian_conditional(j):
    rng = np.random.default_rng(j)
    cov, mu, z = _spd(7, rng), rng.normal(size=7), rng.normal(size=6)
    bj = mu[j] + 0.7
    rest = [i for i in range(7) if i != j]
    c = cov[rest, j]
    mean_r = mu[rest] + c / cov[j, j] * (bj - mu[j])
    cov_r = cov[np.ix_(rest, rest)] - np.outer(c, c) / cov[j, j]
    want = np.empty(7)
    want[j], want[rest] = bj, mean_r + np.linalg.cholesky(cov_r) @ z
    assert np.allclose(_given_one(mu, cov, j, bj, z), want, rtol=1e-12, atol=1e-12)


def test_a_semi_definite_conditional_raises_for_the_fallback():
    cov = np.ones((3, 3))  # rank one: the conditional covariance is zero
    with pytest.raises(np.linalg.LinAlgError):
        _given_one(np.zeros(3), cov, 0, 0.5, np.zeros(2))


def test_residual_sums_of_squares_from_the_sums():
    rng = np.random.default_rng(1)
    zs = [rng.normal(size=(40, 7)) for _ in range(2)]
    ys = [rng.normal(size=40) for _ in range(2)]
    beta = rng.normal(size=7)
    got = residual_ss(GroupSums.from_arrays(zs, ys), beta)
    want = [float(np.sum((y - z @ beta) ** 2)) for z, y in zip(zs, ys, strict=True)]
    assert np.allclose(got, want, rtol=1e-10)


def test_tau_draws_are_the_stream_of_one_array_call():
    n, ssr = np.array([600.0, 450.0]), np.array([0.01, 0.02])
    a, b = np.random.default_rng(3), np.random.default_rng(3)
    got = [draw_tau(ssr, n, 1e-3, 1e-9, a) for _ in range(5)]
    want = [b.gamma(1e-3 + 0.5 * n, 1.0 / (1e-9 + 0.5 * ssr)) for _ in range(5)]
    assert np.array_equal(np.array(got), np.array(want))
    assert draw_tau(0.5, n, 1.0, 1.0, a).shape == (2,)  # a scalar SSR broadcasts


def test_theta_of_is_the_inverse_map():
    rng = np.random.default_rng(2)
    u, log_t0 = rng.normal(size=(3, 4, 5)), rng.normal(size=(3, 4))
    full = np.concatenate([u, log_t0[..., None]], -1) @ _T_INV.T
    assert np.allclose(theta_of(u, log_t0), full, rtol=0, atol=1e-14)
    assert np.allclose(theta_of(u[0, 0], 0.3), np.r_[u[0, 0], 0.3] @ _T_INV.T, atol=1e-14)
