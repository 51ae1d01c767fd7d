"""Latent weights of a Student-t likelihood, for a Gibbs sampler of any Gaussian block.

No physics here. The scale-mixture form of the Student-t: each residual ``e_i`` has a
latent weight ``lambda_i ~ Gamma(nu/2, rate nu/2)`` and ``e_i | lambda_i ~ N(0, 1/(tau
lambda_i))``; integrating ``lambda_i`` out gives ``e_i ~ t_nu(0, 1/tau)``. Given the
weights, every Gaussian block stays conjugate with weighted sums (``Z'WZ``, ``Z'Wy``,
``y'Wy``), so a sampler adds one step:

* ``(nu, lambda) | e, tau``: ``nu`` by a random-walk Metropolis step on ``log nu`` with
  the weights integrated out (target ``p(nu) prod_i t_nu(e_i; 0, 1/tau)``), then
  ``lambda_i | nu, e_i, tau ~ Gamma((nu + 1)/2, rate (nu + tau e_i^2)/2)``, independent.

This is the construction of :mod:`loadbayes.inference.robust` (the ZIP fit's
``--likelihood student-t``), with the same prior and support of ``nu`` (``NU_PRIOR``,
``NU_BOUNDS``) and the same Rao-Blackwellised mean weight ``(nu + 1)/(nu + tau e_i^2)``
for flagging bad samples; here it is a step to plug into another sampler's loop.
"""

from __future__ import annotations

import math

import numpy as np

from loadbayes.inference.robust import NU_BOUNDS, NU_PRIOR, _t_loglik_nu

__all__ = ["draw_weights", "step_nu"]


def draw_weights(
    e2: np.ndarray, tau: float, nu: float, rng: np.random.Generator
) -> tuple[np.ndarray, np.ndarray]:
    """Draw each ``lambda_i | e_i, tau, nu`` and return it with its conditional mean.

    Parameters
    ----------
    e2 : ndarray
        Squared residuals.
    tau : float
        Noise precision of these residuals.
    nu : float
        Degrees of freedom.
    rng : numpy.random.Generator
        Source of the draws.

    Returns
    -------
    (lam, mean)
        The draws and ``E[lambda_i | e_i, tau, nu] = (nu + 1)/(nu + tau e_i^2)``.
    """
    den = nu + tau * np.asarray(e2, dtype=float)
    lam = rng.gamma(0.5 * (nu + 1.0), 2.0 / den)
    # A weight of exactly 0 (underflow on a gross outlier) would make log(lambda) -inf.
    return np.maximum(lam, 1e-300), (nu + 1.0) / den


def step_nu(
    nu: float,
    e2: np.ndarray,
    tau: float,
    rng: np.random.Generator,
    *,
    step: float = 0.3,
    prior: tuple[float, float] = NU_PRIOR,
    bounds: tuple[float, float] = NU_BOUNDS,
) -> tuple[float, bool]:
    """One random-walk Metropolis step on ``log nu`` with the weights integrated out.

    Parameters
    ----------
    nu : float
        Current degrees of freedom.
    e2 : ndarray
        Squared residuals.
    tau : float
        Noise precision.
    rng : numpy.random.Generator
        Source of the draws.
    step : float
        Sd of the proposal on ``log nu``.
    prior : tuple of float
        Gamma (shape, rate) prior of ``nu``.
    bounds : tuple of float
        Support of ``nu`` (a proposal outside is rejected).

    Returns
    -------
    (nu, accepted)
    """
    e2 = np.ascontiguousarray(e2, dtype=float)
    lnu = math.log(nu)
    prop = lnu + step * rng.standard_normal()
    nup = math.exp(prop)
    log_u = math.log(rng.uniform())
    if not bounds[0] <= nup <= bounds[1]:
        return nu, False
    shape, rate = prior
    # shape (not shape - 1): the Jacobian of the log transform adds log nu.
    cur = _t_loglik_nu(nu, tau, e2, e2.size) + shape * lnu - rate * nu
    new = _t_loglik_nu(nup, tau, e2, e2.size) + shape * prop - rate * nup
    if log_u < new - cur:
        return nup, True
    return nu, False
