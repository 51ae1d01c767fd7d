"""Least squares on the same regression blocks as the Gibbs sampler.

With a flat prior, the posterior mean of a linear-Gaussian block is the least-squares
estimate: so with weak priors, Gibbs and LS must agree to Monte Carlo error (a check on
both). The paper's LS figures came from Matlab's ``fit`` with settings it does not give;
this is the textbook estimator with classical standard errors.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from loadbayes.core.stats import Gram, RegressionStats
from loadbayes.posterior import Posterior, gaussian_draws

__all__ = ["GaussianEstimate", "coupled_least_squares", "least_squares", "least_squares_block"]


@dataclass(frozen=True)
class GaussianEstimate:
    """A point estimate with its covariance (coefficients) and noise variance.

    Attributes
    ----------
    mean : ndarray, shape (k,)
        Estimated coefficients.
    cov : ndarray, shape (k, k)
        Their covariance (``sigma2 (Z'Z)^-1`` for least squares).
    sigma2 : float
        Estimated noise variance (residual sum of squares over ``n - k``).
    n : int
        Number of equations used.
    """

    mean: np.ndarray
    cov: np.ndarray
    sigma2: float
    n: int


def least_squares_block(stats: RegressionStats) -> GaussianEstimate:
    """Ordinary least squares of one block from its sufficient statistics.

    Notes
    -----
    ``b = (Z'Z)^-1 Z'r``, ``sigma2 = SSR / (n - k)``, ``cov = sigma2 (Z'Z)^-1``.
    A singular ``Z'Z`` (unidentifiable data) gives the minimum-norm solution and an
    infinite variance along the unidentified direction is reported as NaN-free
    pseudo-inverse covariance; callers should heed the model's identifiability warnings.
    """
    coef, ssr = stats.least_squares()
    dof = max(stats.n - stats.k, 1)
    sigma2 = ssr / dof
    cov = sigma2 * np.linalg.pinv(stats.ztz)
    return GaussianEstimate(coef, cov, sigma2, stats.n)


def least_squares(
    model: Any,
    gram: Gram,
    *,
    chains: int = 4,
    draws: int = 2000,
    seed: int | None = 0,
    settings: Mapping[str, Any] | None = None,
) -> Posterior:
    """Least squares of every block of ``model``, as a :class:`Posterior`.

    The result holds draws from the Gaussian sampling distribution of the estimate
    (transformed like the Gibbs draws, so a3 = 1 - a1 - a2 and physical motor
    parameters come out the same way); ``settings["estimate"]`` has the exact LS values.
    """
    rng = np.random.default_rng(seed)
    raw: dict[str, np.ndarray] = {}
    estimate: dict[str, float] = {}
    for block in model.blocks:
        est = least_squares_block(block.stats(gram))
        x = gaussian_draws(est.mean, est.cov, chains, draws, rng)
        for i, name in enumerate(block.coef_names):
            raw[name] = x[..., i]
            estimate[name] = float(est.mean[i])
        # The noise precision is reported at its point estimate (no sampling distribution).
        raw[block.tau_name] = np.full((chains, draws), 1.0 / max(est.sigma2, 1e-300))
        estimate[block.tau_name] = 1.0 / max(est.sigma2, 1e-300)
    point = model.transform({k: np.asarray(v).reshape(1, 1) for k, v in estimate.items()})
    full = {"n": gram.n, "scheme": "least-squares", "draws": draws, "seed": seed}
    full.update(settings or {})
    full["estimate"] = {k: float(np.asarray(v).reshape(-1)[0]) for k, v in point.items()}
    return Posterior(
        model.transform(raw),
        model=model.name,
        method="least-squares",
        coefficients=model.coefficients,
        free=getattr(model, "free", None),
        settings=full,
    )


def coupled_least_squares(
    model: Any,
    gram: Gram,
    *,
    first: Mapping[str, float] | None = None,
    chains: int = 4,
    draws: int = 2000,
    seed: int | None = 0,
    settings: Mapping[str, Any] | None = None,
) -> Posterior:
    """Least squares of the modelled-currents form (the coupled blocks), as a Posterior.

    The maximum-likelihood estimate of :func:`bilinear_least_squares`, started from the
    current equations' own least squares, with draws from its Gaussian approximation
    (transformed like the Gibbs draws); ``settings["estimate"]`` has the exact values.
    """
    from loadbayes.inference.bilinear import bilinear_least_squares
    from loadbayes.models.motor_fit import TAU_NAMES

    st = model.bilinear_stats(gram, first)
    v_ls, _, _ = model.current_estimate(gram)
    ml = bilinear_least_squares(st, v0=v_ls)
    names = list(st.u_names + st.v_names)
    mean = np.r_[ml["u"], ml["v"]]
    rng = np.random.default_rng(seed)
    x = gaussian_draws(mean, ml["cov"], chains, draws, rng)
    raw = {n: x[..., i] for i, n in enumerate(names)}
    est = dict(zip(names, mean.tolist(), strict=True))
    for n, t in zip(TAU_NAMES, ml["tau"], strict=True):
        raw[n] = np.full((chains, draws), float(t))
        est[n] = float(t)
    point = model.transform({k: np.asarray(v).reshape(1, 1) for k, v in est.items()})
    full = {"n": gram.n, "scheme": "least-squares", "currents": model.currents, "draws": draws}
    full.update(settings or {})
    full["iterations"] = ml["iterations"]
    full["estimate"] = {k: float(np.asarray(v).reshape(-1)[0]) for k, v in point.items()}
    return Posterior(
        model.transform(raw),
        model=model.name,
        method="least-squares",
        coefficients=model.coefficients,
        free=model.free,
        settings=full,
    )
