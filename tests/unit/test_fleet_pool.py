"""The class pooling of per-bus estimates (fleet/pool.py) against the same model by quadrature.

The model y_i ~ N(theta_i, s_i^2), theta_i ~ N(mu, sd^2), mu flat, sd ~ half-N(0, S): the
posterior of mu and of one theta_i computed here on a fine grid (sd) with mu and theta in
closed form, and compared with the module's exact draws. 20 000 draws: the Monte Carlo sd
of a mean is under 1% of its posterior sd, and the bound of 4 Monte Carlo sd (plus the
grid's own 1%) fails a correct sampler with probability about 1e-4 per check. Fixed seed.
"""

import numpy as np

from loadbayes.fleet.pool import pool_class

Y = np.array([0.62, 0.95, 0.71, 1.30, 0.48])
S = np.array([0.10, 0.25, 0.12, 0.30, 0.15])
SCALE = 0.5


def _quadrature():
    grid = np.linspace(1e-5, 5 * SCALE, 20_000)
    v = S[None, :] ** 2 + grid[:, None] ** 2
    w = 1 / v
    vm = 1 / w.sum(1)
    mh = vm * (w * Y).sum(1)
    logp = (-0.5 * (grid / SCALE) ** 2 + 0.5 * np.log(vm) - 0.5 * np.log(v).sum(1)
            - 0.5 * (w * (Y - mh[:, None]) ** 2).sum(1))  # fmt: skip
    p = np.exp(logp - logp.max())
    p /= p.sum()
    mu_mean = (p * mh).sum()
    mu_var = (p * (vm + mh**2)).sum() - mu_mean**2
    # theta_0 given sd: its mean and variance with mu integrated out
    b = S[0] ** 2 / v[:, 0]
    t_mean = (1 - b) * Y[0] + b * mh
    t_var = S[0] ** 2 * (1 - b) + b**2 * vm
    th_mean = (p * t_mean).sum()
    th_var = (p * (t_var + t_mean**2)).sum() - th_mean**2
    return mu_mean, np.sqrt(mu_var), th_mean, np.sqrt(th_var), (p * grid).sum()


def test_pooled_draws_match_the_model_by_quadrature():
    n = 20_000
    res = pool_class(Y, S, scale=SCALE, draws=n, rng=np.random.default_rng(5))
    mu_m, mu_s, th_m, th_s, sd_m = _quadrature()
    for draws, m, s in ((res["mu"], mu_m, mu_s), (res["theta"][:, 0], th_m, th_s)):
        assert abs(draws.mean() - m) < 4 * s / np.sqrt(n) + 0.01 * s
        assert abs(draws.std() - s) < 0.03 * s
    assert abs(res["sd"].mean() - sd_m) < 0.03 * sd_m
    # each bus is drawn toward the class, the least sure the most
    assert np.all((res["shrinkage"] > 0) & (res["shrinkage"] < 1))
    assert np.argmax(res["shrinkage"]) == np.argmax(S)
