import math

import numpy as np
import pytest

from loadbayes.core.stats import GramAccumulator, gram_of


def _data(n, k=4, seed=0):
    rng = np.random.default_rng(seed)
    return rng.normal(size=(n, k)) * rng.uniform(0.1, 10, size=k)


def test_gram_matches_numpy():
    a = _data(10_000)
    g = gram_of(a, list("abcd"))
    np.testing.assert_allclose(g.matrix, a.T @ a, rtol=1e-12)
    assert g.n == 10_000
    np.testing.assert_array_equal(g.col_min, a.min(axis=0))
    np.testing.assert_array_equal(g.col_max, a.max(axis=0))


@pytest.mark.parametrize("chunk", [1, 7, 1000, 16384, 50_000])
def test_bitwise_identical_for_any_chunking(chunk):
    a = _data(50_001)
    ref = gram_of(a, list("abcd"), block_rows=4096).matrix
    acc = GramAccumulator(list("abcd"), block_rows=4096)
    for i in range(0, a.shape[0], chunk):
        acc.update(a[i : i + chunk])
    assert np.array_equal(acc.result().matrix, ref)


def test_merge_of_block_aligned_workers_is_identical():
    a = _data(30_000)
    ref = gram_of(a, list("abcd"), block_rows=1000).matrix
    left = GramAccumulator(list("abcd"), block_rows=1000)
    right = GramAccumulator(list("abcd"), block_rows=1000)
    left.update(a[:12_000])
    right.update(a[12_000:])
    left.merge(right)
    assert np.array_equal(left.result().matrix, ref)
    assert left.n == 30_000


def test_sum_is_close_to_exact_fsum():
    # Ill-conditioned sums: large offset plus small signal.
    rng = np.random.default_rng(3)
    a = (1e4 + rng.normal(size=(200_000, 1))).astype(float)
    g = gram_of(a, ["x"])
    exact = math.fsum((a[:, 0] * a[:, 0]).tolist())
    assert abs(g.matrix[0, 0] - exact) <= 1e-13 * exact


def test_regression_view_and_stacking():
    a = _data(500)
    g = gram_of(a, ["z1", "z2", "r", "s"])
    st = g.regression(["z1", "z2"], "r")
    np.testing.assert_allclose(st.ztz, a[:, :2].T @ a[:, :2], rtol=1e-12)
    np.testing.assert_allclose(st.ztr, a[:, :2].T @ a[:, 2], rtol=1e-12)
    both = st + g.regression(["z1", "z2"], "s")
    assert both.n == 1000
    coef, ssr = st.least_squares()
    ref, res, *_ = np.linalg.lstsq(a[:, :2], a[:, 2], rcond=None)
    np.testing.assert_allclose(coef, ref, rtol=1e-10)
    np.testing.assert_allclose(ssr, res[0], rtol=1e-9)


def test_bad_shape_rejected():
    acc = GramAccumulator(["a", "b"])
    with pytest.raises(ValueError, match=r"\(m, 2\)"):
        acc.update(np.zeros((3, 3)))
