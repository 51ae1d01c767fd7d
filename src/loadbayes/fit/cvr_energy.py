"""The energy CVR factor: a Bayesian regression of daily energy with a drifting level.

For day ``d`` with energy ``E_d`` (net, at the head) the model is::

    log E_d = L(d) + g on_d + sum_w c_w [weekday_d = w] + h holiday_d
              + k1 max(18 - T_d, 0) + k2 max(T_d - 18, 0) + e_d,   e_d ~ N(0, 1/tau)

``L(d)`` a level that drifts: piecewise linear between knots ``knot_days`` apart, a
Gaussian random walk over the knots whose step sd is ``lam / sqrt(tau)`` (``lam`` the
walk's size against the noise's). The weather terms (heating and cooling degrees from
18 C of the day's mean temperature ``T_d``) enter when a weather column is given, and
``+ s pv_d`` (the day's mean PV output or irradiance, scaled to its largest) when a PV
column is: behind-the-meter PV takes a cloudy day's energy off the net load at the head.

The same regression with ``log V_d`` (the day's mean voltage) on the left gives ``dv``,
how far the reduction moved the voltage; the energy CVR factor is ``g / dv``, the
percentage change of energy per percentage change of voltage that the switching caused.
That is an instrumental-variable estimate (Wald's ratio): the on/off switching is an
outside cause of V (or an instrument the user names, whose daily mean then takes the
place of ``on_d`` in both regressions), whereas V's day-to-day moves follow the load
through the source impedance, so regressing ``log E`` on ``log V`` directly
(:func:`direct_factor`, given for comparison) is biased when the voltage answers to the
load.

Each regression is one conjugate normal-gamma block (:class:`~loadbayes.core.priors.
BlockPrior` with ``conjugate=True``; its exact posterior from
:func:`loadbayes.inference.gibbs.exact_posterior`). ``lam`` is not fixed: it takes the
values of ``LAMBDAS`` with a uniform prior, each weighed by its exact marginal likelihood,
and every draw first draws ``lam`` then the coefficients: exact draws from the posterior
with the level's smoothness integrated out (no Markov chain, nothing to converge).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from loadbayes.core.priors import BlockPrior
from loadbayes.core.stats import RegressionStats
from loadbayes.inference.gibbs import exact_posterior

__all__ = ["LAMBDAS", "Design", "design", "direct_factor", "sample_regression"]

#: The random walk's step sd per knot, in noise sd: the grid its posterior is over.
LAMBDAS = (0.02, 0.05, 0.1, 0.2, 0.5, 1.0, 2.0, 5.0)
#: Prior sd (in noise sd) of every coefficient other than the level's steps: weak.
WEAK = 1e3
#: Base temperature of the degree days (C).
BASE_C = 18.0


@dataclass
class Design:
    """The columns of the daily regression, their names and which are the level's."""

    z: np.ndarray
    names: list[str]
    n_knots: int


def design(
    days, *, knot_days: float = 7.0, treat: np.ndarray | None = None, name: str = "log_v"
) -> Design:
    """The design matrix of a :class:`~loadbayes.fit.cvr_data.Days` (module notes).

    ``treat`` replaces the on/off column, named ``name`` then (the direct regression
    puts ``log V`` there; an instrument the user names, its daily mean).
    """
    d = (days.date - days.date[0]).astype(np.int64).astype(float)
    span = max(float(d[-1]), 1.0)
    k = max(int(np.ceil(span / knot_days)) + 1, 2)
    knots = np.linspace(0.0, span, k)
    hat = np.zeros((d.size, k))
    for j in range(k):
        left = knots[j - 1] if j > 0 else knots[j] - 1.0
        right = knots[j + 1] if j + 1 < k else knots[j] + 1.0
        up = (d - left) / (knots[j] - left)
        down = (right - d) / (right - knots[j])
        hat[:, j] = np.clip(np.minimum(up, down), 0.0, 1.0)
    cols = [hat]
    names = [f"level_{j}" for j in range(k)]
    cols.append((days.on if treat is None else treat)[:, None].astype(float))
    names.append("on" if treat is None else name)
    for w in range(1, 7):
        col = (days.weekday == w).astype(float)
        if col.any() and not col.all():
            cols.append(col[:, None])
            names.append(("tue", "wed", "thu", "fri", "sat", "sun")[w - 1])
    if days.holiday.any() and not days.holiday.all():
        cols.append(days.holiday[:, None])
        names.append("holiday")
    if days.weather is not None:
        for nm, col in (("heating_deg", np.maximum(BASE_C - days.weather, 0.0)),
                        ("cooling_deg", np.maximum(days.weather - BASE_C, 0.0))):  # fmt: skip
            if np.ptp(col) > 0:
                cols.append(col[:, None])
                names.append(nm)
    if days.pv is not None and np.ptp(days.pv) > 0:
        cols.append((days.pv / np.abs(days.pv).max())[:, None])
        names.append("pv")
    return Design(np.hstack(cols), names, k)


def _prior(des: Design, y: np.ndarray, lam: float) -> BlockPrior:
    k, m = des.n_knots, des.z.shape[1]
    diff = np.diff(np.eye(k), axis=0)
    prec = np.eye(m) / WEAK**2
    prec[:k, :k] += diff.T @ diff / lam**2
    mean = np.zeros(m)
    mean[:k] = float(np.mean(y))
    return BlockPrior(mean, prec, conjugate=True)


def _log_marginal(stats: RegressionStats, prior: BlockPrior, post: dict) -> float:
    from scipy.special import gammaln

    _, ld0 = np.linalg.slogdet(prior.precision)
    _, ldn = np.linalg.slogdet(post["precision"])
    a0, b0 = prior.shape, prior.rate
    an, bn = post["shape"], post["rate"]
    return float(
        -0.5 * stats.n * np.log(2 * np.pi) + 0.5 * (ld0 - ldn)
        + a0 * np.log(b0) - an * np.log(bn) + gammaln(an) - gammaln(a0)
    )  # fmt: skip


@dataclass
class RegressionDraws:
    """Draws of one daily regression: coefficients (chain, draw, k), noise sd, ``lam``."""

    coef: np.ndarray
    sigma: np.ndarray
    lam: np.ndarray
    names: list[str]
    weights: np.ndarray  # the posterior of lam over LAMBDAS

    def __getitem__(self, name: str) -> np.ndarray:
        return self.coef[..., self.names.index(name)]


def sample_regression(
    des: Design, y: np.ndarray, gens: list[np.random.Generator], kept: int
) -> RegressionDraws:
    """Exact draws of the regression of ``y`` on ``des`` with ``lam`` integrated out."""
    z = des.z
    stats = RegressionStats(z.T @ z, z.T @ y, float(y @ y), int(y.size))
    posts, logml = [], []
    for lam in LAMBDAS:
        prior = _prior(des, y, lam)
        post = exact_posterior(stats, prior)
        posts.append((post, np.linalg.cholesky(post["precision"])))
        logml.append(_log_marginal(stats, prior, post))
    lw = np.array(logml) - max(logml)
    w = np.exp(lw) / np.exp(lw).sum()
    m = z.shape[1]
    coef = np.empty((len(gens), kept, m))
    sigma = np.empty((len(gens), kept))
    lam = np.empty((len(gens), kept))
    for c, gen in enumerate(gens):
        which = np.sort(gen.choice(len(LAMBDAS), size=kept, p=w))
        for g in np.unique(which):
            rows = np.flatnonzero(which == g)
            post, chol = posts[g]
            tau = gen.standard_gamma(post["shape"], rows.size) / post["rate"]
            e = np.linalg.solve(chol.T, gen.standard_normal((rows.size, m)).T).T
            coef[c, rows] = post["mean"] + e / np.sqrt(tau)[:, None]
            sigma[c, rows] = 1.0 / np.sqrt(tau)
            lam[c, rows] = LAMBDAS[g]
        order = gen.permutation(kept)
        coef[c], sigma[c], lam[c] = coef[c, order], sigma[c, order], lam[c, order]
    return RegressionDraws(coef, sigma, lam, des.names, w)


def direct_factor(days, y: np.ndarray, gens, kept: int, knot_days: float) -> np.ndarray:
    """Draws of the slope of ``log E`` on ``log V`` itself (biased when V follows the load)."""
    des = design(days, knot_days=knot_days, treat=np.log(days.v))
    return sample_regression(des, y, gens, kept)["log_v"]
