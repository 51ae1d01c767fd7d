"""A class's pooling of per-bus estimates: the normal-normal model of a fleet fitted bus by bus.

The drifting-level ZIP and the CVR factor are fitted bus by bus from their rows
(:mod:`loadbayes.fleet.rows`); they leave no sums for the static fleet's pooled Gibbs
sampler (:mod:`loadbayes.fleet.hierarchical`). With ``--pool class`` each quantity ``k``
(dP/dV, the energy CVR factor) is pooled within a class by the normal-normal model of a
meta-analysis, each bus's own posterior taken as its likelihood (a normal of its mean
``y_i`` and sd ``s_i``: the bus fits' priors are flat at their scale)::

    y_i ~ N(theta_i, s_i^2),   theta_i ~ N(mu_c, sd_c^2),   mu_c flat,   sd_c ~ half-N(0, S_k)

The draws are exact: ``sd_c`` from its marginal on a grid (``mu_c`` and the ``theta_i``
integrated out in closed form), then ``mu_c`` and each ``theta_i`` given it
(Gelman et al., Bayesian Data Analysis, 3rd ed., section 5.4). A bus's pooled estimate is
its ``theta_i``; ``shrinkage`` is the weight of the class in its mean,
``E[s_i^2 / (s_i^2 + sd_c^2)]``.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

__all__ = ["SPREAD_SCALE", "pool_class"]

#: The half-normal scale of a class's spread, per quantity (per unit of the level for
#: dP/dV, dQ/dV; per cent per cent for a CVR factor): the spread of published values.
SPREAD_SCALE = {"dp_dv": 1.0, "dq_dv": 3.0, "cvr_p": 0.5, "cvr_q": 2.0}
#: Grid points of the spread's marginal.
GRID = 400


def pool_class(
    y: Sequence[float], s: Sequence[float], *, scale: float, draws: int, rng: np.random.Generator
) -> dict[str, np.ndarray]:
    """Exact draws of one class's pooled model (module notes).

    Parameters
    ----------
    y, s : sequences of length m
        Each bus's posterior mean and sd of the quantity.
    scale : float
        The half-normal scale of the class spread.
    draws : int
        Draws to make.
    rng : numpy.random.Generator

    Returns
    -------
    dict
        ``mu`` and ``sd`` (draws,), ``theta`` (draws, m), ``shrinkage`` (m,).
    """
    y = np.asarray(y, dtype=float)
    s2 = np.asarray(s, dtype=float) ** 2
    grid = np.linspace(0.0, 5.0 * scale, GRID + 1)[1:]
    v = s2[None, :] + grid[:, None] ** 2
    w = 1.0 / v
    v_mu = 1.0 / w.sum(axis=1)
    mu_hat = v_mu * (w * y[None, :]).sum(axis=1)
    logp = (
        -0.5 * (grid / scale) ** 2
        + 0.5 * np.log(v_mu)
        - 0.5 * np.log(v).sum(axis=1)
        - 0.5 * (w * (y[None, :] - mu_hat[:, None]) ** 2).sum(axis=1)
    )
    prob = np.exp(logp - logp.max())
    prob /= prob.sum()
    k = rng.choice(grid.size, size=draws, p=prob)
    # a uniform jitter within the grid cell: a continuous spread, not 400 values
    step = grid[1] - grid[0]
    sd = np.clip(grid[k] + step * (rng.random(draws) - 0.5), 1e-12, None)
    vv = s2[None, :] + sd[:, None] ** 2
    ww = 1.0 / vv
    vm = 1.0 / ww.sum(axis=1)
    mu = vm * (ww * y[None, :]).sum(axis=1) + np.sqrt(vm) * rng.standard_normal(draws)
    prec = 1.0 / s2[None, :] + 1.0 / sd[:, None] ** 2
    mean = (y[None, :] / s2[None, :] + mu[:, None] / sd[:, None] ** 2) / prec
    theta = mean + rng.standard_normal((draws, y.size)) / np.sqrt(prec)
    shrink = (s2[None, :] / vv).mean(axis=0)
    return {"mu": mu, "sd": sd, "theta": theta, "shrinkage": shrink}
