"""The compiled samplers' shared Cholesky against numpy's."""

import numpy as np
import pytest

from loadbayes.inference.linalg import cholesky, precision_draw, solve_lower, solve_upper


def _spd(k, seed=0):
    a = np.random.default_rng(seed).standard_normal((k, k))
    return a @ a.T + k * np.eye(k)


@pytest.mark.parametrize("k", [1, 2, 4, 7])
def test_factor_and_solves_match_numpy(k):
    a = _spd(k, k)
    lo = np.zeros((k, k))
    assert cholesky(a, lo)
    np.testing.assert_allclose(lo, np.linalg.cholesky(a), rtol=1e-12, atol=1e-14)
    inplace = a.copy()
    assert cholesky(inplace, inplace)  # in place: same lower triangle, bit for bit
    np.testing.assert_array_equal(np.tril(inplace), lo)
    b = np.arange(1.0, k + 1)
    x = np.empty(k)
    solve_lower(lo, b, x)
    solve_upper(lo, x, x)
    np.testing.assert_allclose(x, np.linalg.solve(a, b), rtol=1e-10)


def test_precision_draw_has_the_mean_and_the_covariance():
    k = 3
    lam, h = _spd(k), np.array([1.0, -2.0, 0.5])
    lo, w, out = np.empty((k, k)), np.empty(k), np.empty(k)
    assert precision_draw(lam, h, np.zeros(k), lo, w, out)
    mean = np.linalg.solve(lam, h)
    np.testing.assert_allclose(out, mean, rtol=1e-12)
    # out - mean = lo'^-1 z is linear in z: its columns over z = e_j square to lam^-1.
    cols = []
    for j in range(k):
        assert precision_draw(lam, h, np.eye(k)[j], lo, w, out)
        cols.append(out - mean)
    m = np.array(cols).T
    np.testing.assert_allclose(m @ m.T, np.linalg.inv(lam), rtol=1e-9, atol=1e-12)


@pytest.mark.parametrize("bad", [np.diag([1.0, -1.0]), np.zeros((2, 2)), np.full((2, 2), np.nan)])
def test_not_positive_definite_is_refused(bad):
    out = np.full(2, 7.0)
    assert not cholesky(bad, np.empty((2, 2)))
    assert not precision_draw(bad, np.ones(2), np.zeros(2), np.empty((2, 2)), np.empty(2), out)
    np.testing.assert_array_equal(out, 7.0)  # untouched
