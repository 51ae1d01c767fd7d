"""The knot level's sums and factorisation against dense Gaussian algebra (issue 39).

``inference/knots.py`` never builds the design matrix: every sample enters through sums
over the knots, and the precision is factored as a band bordered by the profile's
columns. Here the same quantities are built densely, row by row (the AR(1) rows from two
samples, a gap that breaks the link, two day types), and must agree to rounding.
"""

import math

import numpy as np
import pytest

from loadbayes.inference.knot_kernels import EPS
from loadbayes.inference.knot_kernels import draw_theta as _draw_theta
from loadbayes.inference.knot_kernels import factor as _factor
from loadbayes.inference.knot_kernels import level as _level
from loadbayes.inference.knot_kernels import sums as _sums
from loadbayes.inference.knots import knot_design, walk_band


def _dense_rows(des, y, x1, x2, sw, ps, rho, b1, b2, nk, m, nh):
    def phi(s):
        f = np.zeros(nk + m)
        f[des.k[s]] += 1 - des.lam[s]
        f[des.k[s] + 1] += des.lam[s]
        col = nk + des.ptype[s] * 2 * nh
        for j in range(nh):
            a = 2 * np.pi * (j + 1) * des.phase[s]
            f[col + 2 * j] += ps[s] * np.cos(a)
            f[col + 2 * j + 1] += ps[s] * np.sin(a)
        return f * sw[s] * (1 + b1 * x1[s] + b2 * x2[s])

    rows, target = [], []
    for s in range(y.size):
        if des.link[s]:
            rows.append(phi(s) - rho * phi(s - 1))
            target.append(y[s] * sw[s] - rho * y[s - 1] * sw[s - 1])
        else:
            c = math.sqrt(1 - rho * rho)
            rows.append(c * phi(s))
            target.append(c * y[s] * sw[s])
    return np.array(rows), np.array(target)


def _prior(dw, order, nk, m):
    d = np.zeros((nk - order, nk))
    for k in range(nk - order):
        d[k, k : k + order + 1] = [-1, 1] if order == 1 else [1, -2, 1]
    q = np.zeros((nk + m, nk + m))
    q[:nk, :nk] = d.T @ np.diag(1 / dw[: nk - order]) @ d
    q[np.arange(order), np.arange(order)] += EPS
    q[np.arange(nk, nk + m), np.arange(nk, nk + m)] += EPS
    return q


@pytest.mark.parametrize("order", [1, 2])
def test_sums_and_factor_match_the_dense_posterior(order):
    rng = np.random.default_rng(0)
    n, nh = 60, 2
    t = np.cumsum(rng.uniform(0.5, 1.2, n)) * 3000.0
    t[40:] += 20_000.0  # a gap: the AR(1) link breaks there
    t -= t[0]
    y = rng.normal(5, 1, n)
    x1, x2 = rng.normal(0, 0.05, n), rng.normal(0, 0.03, n)
    sw = 1 / np.sqrt(rng.uniform(0.5, 2, n))
    des = knot_design(t, spacing_s=7000.0, harmonics=nh,
                      weekend=(np.floor(t / 86_400) % 2).astype(bool))  # fmt: skip
    assert not des.link[40] and des.link[1:40].sum() > 30
    nk, m = des.n_knots, 2 * nh * 2
    rho, b1, b2 = 0.4, 0.7, -0.3
    ps = rng.uniform(0.7, 1.3, n)  # the profile's scale (a season)
    sums = _sums(y * sw, x1, x2, sw, des.k, des.lam, des.ptype, des.phase, ps, des.link, rho,
                 nk, nh, m)  # fmt: skip
    a, target = _dense_rows(des, y, x1, x2, sw, ps, rho, b1, b2, nk, m, nh)
    assert sums[4] == pytest.approx(target @ target, rel=1e-12) and sums[5] == n
    dw = rng.uniform(0.5, 3, nk - 1)
    prec = _prior(dw, order, nk, m) + a.T @ a
    rv = a.T @ target
    lb, yw, ls, sr = np.zeros((3, nk)), np.zeros((nk, m + 1)), np.zeros((m, m)), np.zeros(m)
    ok, logdet, quad = _factor(*sums[:4], walk_band(dw, order), 1.0, b1, b2, lb, yw, ls, sr)
    assert ok
    assert logdet == pytest.approx(np.linalg.slogdet(prec)[1], rel=1e-10)
    mean = np.linalg.solve(prec, rv)
    assert quad == pytest.approx(rv @ mean, rel=1e-10)
    # the mean (sigma = 0) and a draw's covariance: theta = mean + sigma L'^-1 z
    np.testing.assert_allclose(_draw_theta(lb, yw, ls, sr, 0.0, np.zeros(nk + m)), mean,
                               rtol=1e-9, atol=1e-9)  # fmt: skip
    z = rng.standard_normal(nk + m)
    dev = _draw_theta(lb, yw, ls, sr, 1.0, z) - mean
    # dev' prec dev = z'z exactly when dev = L'^-1 z with prec = L L'
    assert dev @ prec @ dev == pytest.approx(z @ z, rel=1e-8)
    lev = _level(mean, des.k, des.lam, des.ptype, des.phase, ps, nk, nh)
    np.testing.assert_allclose(lev * sw * (1 + b1 * x1 + b2 * x2),
                               np.array([_dense_rows(des, y, x1, x2, sw, ps, 0.0, b1, b2, nk, m, nh)
                                         [0][s] @ mean for s in range(n)]), rtol=1e-10)  # fmt: skip
