"""The Gibbs sampler of :mod:`loadbayes.archive.pool`: one part's units pooled.

The model (the equations are in :mod:`loadbayes.archive.pool`'s docstring): each unit
(a station's bay) ``u`` has coefficients ``beta_u`` of a curve ``x' beta_u`` on the logit
scale and an event-to-event spread ``tau_u``; each event ``e`` of the unit is measured as
``y_e ~ N(x_e' beta_u, s_e^2 + tau_u^2)`` with its known ``s_e``; ``beta_u ~ N(mu_g,
Sigma)`` with ``g`` the unit's group (one group, or one per bay name), ``mu_g ~ N(0,
M0)``, ``Sigma ~ InvWishart(nu0, Psi0)`` shared, ``tau_u ~ HalfNormal(T0)``.

One sweep:

1. ``(tau_u, beta_u)`` as one block given ``mu, Sigma``, each unit apart: ``log tau_u^2``
   by random-walk Metropolis on its density with ``beta_u`` integrated out (the
   Woodbury identity keeps it a ``p x p`` computation: ``y_u ~ N(X mu, X Sigma X' + D)``,
   ``D = diag(s^2 + tau^2)``), then ``beta_u`` from its conjugate normal (precision
   ``Sigma^-1 + X' D^-1 X``). The measurement errors differ from event to event, so
   ``tau`` has no conjugate update; integrating ``beta_u`` out lets it move freely.
2. each ``mu_g`` from its conjugate normal given its units' ``beta_u``.
3. ``Sigma`` from its conjugate inverse Wishart given the ``beta_u - mu_g``.

The Metropolis step's size is tuned per unit during burn-in (towards 44 % acceptance)
and then frozen, so the kept draws are a Markov chain with a fixed kernel. Every unit is
updated at once in arrays padded to the largest unit (the padding carries weight 0).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.stats import invwishart

from loadbayes.core.parallel import chain_generators, check_stop, run_chains

__all__ = ["PoolData", "PoolPrior", "sample_pool"]

#: Random-walk Metropolis proposals on log tau^2 per sweep (each costs a p x p batch).
MH_STEPS = 3


@dataclass(frozen=True)
class PoolData:
    """One part's events, padded by unit: ``x`` (U, n, p), ``y`` and ``s2`` (U, n), ``mask``."""

    x: np.ndarray
    y: np.ndarray
    s2: np.ndarray
    mask: np.ndarray

    @classmethod
    def of(cls, unit: np.ndarray, x: np.ndarray, y: np.ndarray, s2: np.ndarray, units: int):
        """Pad flat events (``unit`` the index of each event's unit) into unit rows."""
        counts = np.bincount(unit, minlength=units)
        n = max(int(counts.max()), 1)
        p = x.shape[1]
        xx, yy = np.zeros((units, n, p)), np.zeros((units, n))
        ss, mm = np.ones((units, n)), np.zeros((units, n), dtype=bool)
        slot = np.zeros(unit.size, dtype=int)
        for u in range(units):
            where = np.flatnonzero(unit == u)
            slot[where] = np.arange(where.size)
        xx[unit, slot], yy[unit, slot], ss[unit, slot], mm[unit, slot] = x, y, s2, True
        return cls(xx, yy, ss, mm)


@dataclass(frozen=True)
class PoolPrior:
    """``mu ~ N(0, diag(mu_sd^2))``, ``Sigma ~ IW(nu0, Psi0)``, ``tau ~ HalfNormal(tau_scale)``.

    ``Psi0 = (nu0 - p - 1) diag(sigma_sd^2)``: the prior mean of ``Sigma`` is
    ``diag(sigma_sd^2)``, the spread of the units' coefficients around the population's
    when few units tell it.
    """

    mu_sd: np.ndarray
    sigma_sd: np.ndarray
    nu_extra: float = 3.0
    tau_scale: float = 1.0

    @property
    def nu0(self) -> float:  # noqa: D102
        return self.mu_sd.size + 1 + self.nu_extra

    @property
    def psi0(self) -> np.ndarray:  # noqa: D102
        return np.diag(self.nu_extra * self.sigma_sd**2)


def _collapsed(data: PoolData, lam: np.ndarray, mu: np.ndarray, sigma_inv: np.ndarray,
               logdet_sigma: float):  # fmt: skip
    """Log density of each unit's ``y`` with ``beta_u`` integrated out, and its pieces.

    Returns ``(logp (U,), precision (U, p, p), cholesky (U, p, p), X'D^-1 r (U, p))`` with
    ``r = y - X mu`` (``mu`` (U, p): each unit's group mean).
    """
    w = data.mask / (data.s2 + np.exp(lam)[:, None])
    r = data.y - np.einsum("unp,up->un", data.x, mu)
    xtw = data.x * w[..., None]
    prec = sigma_inv + np.einsum("unp,unq->upq", xtw, data.x)
    chol = np.linalg.cholesky(prec)
    b = np.einsum("unp,un->up", xtw, r)
    z = np.linalg.solve(chol, b[..., None])[..., 0]
    logdet_d = -np.sum(np.log(np.where(data.mask, w, 1.0)), axis=1)
    logdet_p = 2 * np.sum(np.log(np.diagonal(chol, axis1=1, axis2=2)), axis=1)
    quad = np.sum(w * r * r, axis=1) - np.sum(z * z, axis=1)
    logp = -0.5 * (logdet_d + logdet_sigma + logdet_p + quad)
    return logp, chol, b


def _log_prior_lam(lam: np.ndarray, scale: float) -> np.ndarray:
    # tau ~ HalfNormal(scale), sampled as lam = log tau^2 (Jacobian tau / 2 -> lam / 2).
    return -0.5 * np.exp(lam) / scale**2 + 0.5 * lam


def _chain(data: PoolData, prior: PoolPrior, draws: int, burn: int, rng: np.random.Generator,
           start: dict[str, np.ndarray], group: np.ndarray) -> dict[str, np.ndarray]:  # fmt: skip
    units, _, p = data.x.shape
    groups = int(group.max()) + 1
    members = np.bincount(group, minlength=groups)
    mu, lam = start["mu"].copy(), start["lam"].copy()
    sigma = prior.psi0 / prior.nu_extra
    mu_prec = np.diag(1.0 / prior.mu_sd**2)
    step = np.full(units, 0.8)
    out = {
        "beta": np.empty((draws, units, p)),
        "mu": np.empty((draws, groups, p)),
        "sigma": np.empty((draws, p, p)),
        "tau": np.empty((draws, units)),
        "accept_tau": np.empty(draws),
    }
    for it in range(burn + draws):
        if it % 50 == 0:
            check_stop()
        sigma_inv = np.linalg.inv(sigma)
        logdet_sigma = float(np.linalg.slogdet(sigma)[1])
        mu_u = mu[group]
        logp, chol, b = _collapsed(data, lam, mu_u, sigma_inv, logdet_sigma)
        logp = logp + _log_prior_lam(lam, prior.tau_scale)
        moved = np.zeros(units)
        for _ in range(MH_STEPS):
            prop = lam + step * rng.standard_normal(units)
            lp_new, chol_new, b_new = _collapsed(data, prop, mu_u, sigma_inv, logdet_sigma)
            lp_new = lp_new + _log_prior_lam(prop, prior.tau_scale)
            take = np.log(rng.random(units)) < lp_new - logp
            lam = np.where(take, prop, lam)
            logp = np.where(take, lp_new, logp)
            chol = np.where(take[:, None, None], chol_new, chol)
            b = np.where(take[:, None], b_new, b)
            moved += take
        if it < burn:  # tune each unit's step towards 44 % acceptance, then freeze it
            step *= np.exp((moved / MH_STEPS - 0.44) / np.sqrt(1.0 + it / 10))
        # beta_u | tau_u, mu, Sigma: mean mu + P^-1 X'D^-1 (y - X mu), precision P
        z = np.linalg.solve(chol, b[..., None])
        noise = rng.standard_normal((units, p, 1))
        lt = np.swapaxes(chol, 1, 2)
        beta = mu_u + np.linalg.solve(lt, z + noise)[..., 0]
        # mu_g | beta, Sigma, each group apart
        prec = mu_prec + members[:, None, None] * sigma_inv
        c = np.linalg.cholesky(prec)
        sums = np.zeros((groups, p))
        np.add.at(sums, group, beta)
        rhs = sums @ sigma_inv
        mean = np.linalg.solve(np.swapaxes(c, 1, 2), np.linalg.solve(c, rhs[..., None]))[..., 0]
        noise = rng.standard_normal((groups, p, 1))
        mu = mean + np.linalg.solve(np.swapaxes(c, 1, 2), noise)[..., 0]
        # Sigma | beta, mu
        dev = beta - mu[group]
        scale = prior.psi0 + dev.T @ dev
        sigma = np.atleast_2d(invwishart.rvs(df=prior.nu0 + units, scale=scale, random_state=rng))
        if it >= burn:
            k = it - burn
            out["beta"][k], out["mu"][k], out["sigma"][k] = beta, mu, sigma
            out["tau"][k] = np.exp(0.5 * lam)
            out["accept_tau"][k] = moved.mean() / MH_STEPS
    return out


def sample_pool(
    data: PoolData,
    prior: PoolPrior,
    *,
    draws: int,
    burn: int,
    chains: int,
    seed: np.random.SeedSequence,
    start_beta: np.ndarray,
    group: np.ndarray | None = None,
) -> dict[str, np.ndarray]:
    """Run ``chains`` chains; each array shaped (chain, draw, ...).

    ``group`` (U,) the index of each unit's population (default: one for all).

    ``start_beta`` (U, p) is a rough per-unit estimate; each chain starts from its mean
    and a dispersed ``tau`` (its own generator), so that R-hat can see a chain stuck.
    """
    gens = chain_generators(seed, chains)
    units = start_beta.shape[0]
    group = np.zeros(units, dtype=int) if group is None else np.asarray(group, dtype=int)
    centre = np.stack([start_beta[group == g].mean(axis=0) for g in range(group.max() + 1)])

    def one(i: int, rng: np.random.Generator):
        start = {
            "mu": centre + 0.3 * rng.standard_normal(centre.shape),
            "lam": np.log(0.2**2) + rng.normal(0.0, 1.0, units),
        }
        return _chain(data, prior, draws, burn, rng, start, group)

    # numpy's small batched solves hold the GIL for most of their time: one thread.
    runs = run_chains(one, gens, workers=1)
    return {k: np.stack([r[k] for r in runs]) for k in runs[0]}
