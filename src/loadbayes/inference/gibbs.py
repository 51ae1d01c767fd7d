"""Gibbs sampling of a conjugate linear-Gaussian block ``r = Z b + e``, ``e ~ N(0, 1/tau)``.

The sampler sees the data only through :class:`~loadbayes.inference.stats.RegressionStats`
(``Z'Z``, ``Z'r``, ``r'r``, ``n``), so one iteration costs O(k^3) and nothing in ``n``.

Schemes
-------
``blocked`` (default)
    ``b | tau`` drawn jointly from its multivariate normal conditional, then
    ``tau | b`` from its gamma conditional. Mixes on ridges (the ZIP a1-a2 ridge has a
    posterior correlation near -0.999 on the paper's data).
``single-site``
    The paper's Algorithm 1: one coefficient at a time from its univariate conditional,
    then ``tau``. Kept to reproduce the paper; it crawls along a ridge.
``exact``
    Independent draws from the closed-form posterior of the conjugate normal-gamma prior
    (only with ``BlockPrior(conjugate=True)``): the test oracle.

Randomness is drawn in bulk from per-chain generators (standard normals, and standard
gammas with the fixed posterior shape ``a0 + n/2``), and a compiled loop turns them into
the chain. The same seed gives the same draws whatever runs the chains.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np
from numba import njit

from loadbayes.inference.priors import BlockPrior
from loadbayes.inference.stats import RegressionStats

__all__ = ["SCHEMES", "BlockDraws", "sample_block", "chain_generators"]

Scheme = Literal["blocked", "single-site", "exact"]
SCHEMES: tuple[str, ...] = ("blocked", "single-site", "exact")
_TAU_FLOOR = 1e-100  # a Gamma(1e-3, .) prior draw can underflow to 0; keep it positive


@dataclass(frozen=True)
class BlockDraws:
    """Posterior draws of one block.

    Attributes
    ----------
    coef : ndarray, shape (chain, draw, k)
        Coefficient draws.
    tau : ndarray, shape (chain, draw)
        Noise-precision draws.
    """

    coef: np.ndarray
    tau: np.ndarray


@njit(cache=True, nogil=True)
def _chain(
    ztz, ztr, b_ls, ssr_min, m0, p0, rate0, conj, single, tau, b, z, g, burn, thin, out_b, out_t
):  # pragma: no cover - compiled
    k = ztr.shape[0]
    p0m = p0 @ m0
    lam = np.empty((k, k))
    h = np.empty(k)
    chol = np.empty((k, k))
    y = np.empty(k)
    d = np.empty(k)
    kept = 0
    for it in range(z.shape[0]):
        s = tau if conj else 1.0
        for i in range(k):
            h[i] = s * p0m[i] + tau * ztr[i]
            for j in range(k):
                lam[i, j] = s * p0[i, j] + tau * ztz[i, j]
        if single:
            # The paper's Algorithm 1: b_j | b_-j, tau, one coordinate at a time.
            for j in range(k):
                acc = h[j]
                for i in range(k):
                    if i != j:
                        acc -= lam[j, i] * b[i]
                b[j] = acc / lam[j, j] + z[it, j] / np.sqrt(lam[j, j])
        else:
            # b | tau ~ N(lam^-1 h, lam^-1): Cholesky lam = L L', b = L'^-1 (L^-1 h + z).
            for j in range(k):
                sdiag = lam[j, j]
                for m in range(j):
                    sdiag -= chol[j, m] * chol[j, m]
                chol[j, j] = np.sqrt(sdiag)
                for i in range(j + 1, k):
                    acc = lam[i, j]
                    for m in range(j):
                        acc -= chol[i, m] * chol[j, m]
                    chol[i, j] = acc / chol[j, j]
            for i in range(k):
                acc = h[i]
                for m in range(i):
                    acc -= chol[i, m] * y[m]
                y[i] = acc / chol[i, i]
            for i in range(k):  # add the noise only after the solve: y = L^-1 h + z
                y[i] += z[it, i]
            for i in range(k - 1, -1, -1):
                acc = y[i]
                for m in range(i + 1, k):
                    acc -= chol[m, i] * b[m]
                b[i] = acc / chol[i, i]
        # tau | b ~ Gamma(shape fixed, rate): SSR(b) = SSR_min + (b - b_ls)' Z'Z (b - b_ls),
        # a form with no cancellation even on noise-free data.
        for i in range(k):
            d[i] = b[i] - b_ls[i]
        q = 0.0
        for i in range(k):
            for j in range(k):
                q += d[i] * ztz[i, j] * d[j]
        rate = rate0 + 0.5 * (ssr_min + max(q, 0.0))
        if conj:
            for i in range(k):
                d[i] = b[i] - m0[i]
            q = 0.0
            for i in range(k):
                for j in range(k):
                    q += d[i] * p0[i, j] * d[j]
            rate += 0.5 * q
        tau = max(g[it] / rate, 1e-100)
        if it >= burn and (it - burn) % thin == 0:
            for i in range(k):
                out_b[kept, i] = b[i]
            out_t[kept] = tau
            kept += 1


def chain_generators(
    rng: np.random.Generator | int | np.random.SeedSequence | None, chains: int
) -> list[np.random.Generator]:
    """One independent generator per chain, derived from ``rng`` (a seed or a Generator)."""
    if isinstance(rng, np.random.Generator):
        return list(rng.spawn(chains))
    seq = rng if isinstance(rng, np.random.SeedSequence) else np.random.SeedSequence(rng)
    return [np.random.default_rng(s) for s in seq.spawn(chains)]


def _n_kept(draws: int, burn: int, thin: int) -> int:
    return len(range(burn, draws, thin))


def _check_settings(stats: RegressionStats, prior: BlockPrior, draws, burn, thin, chains):
    if prior.k != stats.k:
        raise ValueError(f"prior has {prior.k} coefficients, the data block {stats.k}")
    if chains < 1 or draws < 1 or thin < 1 or burn < 0:
        raise ValueError("chains, draws and thin must be >= 1 and burn >= 0")
    if burn >= draws:
        raise ValueError(f"burn-in ({burn}) must be smaller than the draws ({draws})")


def _posterior_shape(stats: RegressionStats, prior: BlockPrior) -> float:
    return prior.shape + 0.5 * stats.n + (0.5 * stats.k if prior.conjugate else 0.0)


def _initial(stats, prior, gen, init, b_ls, ssr_min):
    k = stats.k
    if init == "prior":
        tau = float(gen.gamma(prior.shape, 1.0 / prior.rate))
        s = tau if prior.conjugate else 1.0
        try:
            b = gen.multivariate_normal(prior.mean, np.linalg.inv(s * prior.precision))
        except np.linalg.LinAlgError:  # flat prior: start where the data are
            b = b_ls + gen.standard_normal(k)
        return max(tau, _TAU_FLOOR), np.asarray(b, dtype=float)
    if init == "dispersed":
        dof = max(stats.n - k, 1)
        sigma2 = max(ssr_min / dof, 1e-12 * (stats.rtr / stats.n + 1e-300))
        cov = sigma2 * np.linalg.pinv(stats.ztz)
        sd = np.sqrt(np.clip(np.diag(cov), 0.0, None))
        b = b_ls + 3.0 * sd * gen.standard_normal(k)
        tau = float(np.exp(gen.standard_normal() * 1.0) / sigma2)
        return max(tau, _TAU_FLOOR), b
    raise ValueError(f"init must be 'prior' or 'dispersed', got {init!r}")


def sample_block(
    stats: RegressionStats,
    prior: BlockPrior,
    *,
    scheme: Scheme = "blocked",
    chains: int = 4,
    draws: int = 40_000,
    burn: int = 5_000,
    thin: int = 1,
    init: Literal["prior", "dispersed"] = "prior",
    rng: np.random.Generator | int | np.random.SeedSequence | None = None,
) -> BlockDraws:
    """Draw from the posterior of one linear-Gaussian block.

    Parameters
    ----------
    stats : RegressionStats
        ``Z'Z``, ``Z'r``, ``r'r`` and ``n`` of the block.
    prior : BlockPrior
        Normal prior on the coefficients, gamma prior on the precision.
    scheme : {"blocked", "single-site", "exact"}
        See the module docstring.
    chains : int
        Independent chains, each from its own generator spawned from ``rng``.
    draws : int
        Iterations per chain *including* burn-in (the paper's M).
    burn : int
        Leading iterations discarded (the paper's m).
    thin : int
        Keep every ``thin``-th iteration after burn-in.
    init : {"prior", "dispersed"}
        Starting point: a draw from the prior (as the paper), or a draw scattered three
        standard errors around the least-squares estimate (to test convergence).
    rng : Generator, int, SeedSequence or None
        Source of randomness; an int is a seed.

    Returns
    -------
    BlockDraws
        ``coef`` shaped (chain, kept, k) and ``tau`` shaped (chain, kept), with
        ``kept = len(range(burn, draws, thin))``.

    Notes
    -----
    Conditionals (the paper's section "Gibbs in ZIP Model", with its slips fixed: the
    likelihood's minus sign, and the gamma update in rate form):

    * ``b | tau ~ N(L^-1 h, L^-1)``, ``L = s P0 + tau Z'Z``, ``h = s P0 m0 + tau Z'r``,
      with ``s = 1`` for the independent prior and ``s = tau`` for the conjugate one;
    * ``tau | b ~ Gamma(a0 + n/2 [+ k/2], b0 + SSR(b)/2 [+ (b-m0)' P0 (b-m0)/2])``.
    """
    _check_settings(stats, prior, draws, burn, thin, chains)
    if scheme not in SCHEMES:
        raise ValueError(f"scheme must be one of {SCHEMES}, got {scheme!r}")
    gens = chain_generators(rng, chains)
    kept = _n_kept(draws, burn, thin)
    k = stats.k
    if scheme == "exact":
        return _sample_exact(stats, prior, gens, kept)
    b_ls, ssr_min = stats.least_squares()
    shape = _posterior_shape(stats, prior)
    out_b = np.empty((chains, kept, k))
    out_t = np.empty((chains, kept))
    for c, gen in enumerate(gens):
        tau0, b0 = _initial(stats, prior, gen, init, b_ls, ssr_min)
        z = gen.standard_normal((draws, k))
        g = gen.standard_gamma(shape, draws)
        _chain(
            np.ascontiguousarray(stats.ztz, dtype=float),
            np.ascontiguousarray(stats.ztr, dtype=float),
            b_ls,
            float(ssr_min),
            prior.mean,
            prior.precision,
            float(prior.rate),
            bool(prior.conjugate),
            scheme == "single-site",
            tau0,
            b0.copy(),
            z,
            g,
            burn,
            thin,
            out_b[c],
            out_t[c],
        )
    return BlockDraws(out_b, out_t)


def exact_posterior(stats: RegressionStats, prior: BlockPrior) -> dict[str, np.ndarray | float]:
    """Closed-form posterior of the conjugate normal-gamma prior.

    Returns ``mean``, ``precision`` (of ``b`` given ``tau = 1``), ``shape`` and ``rate``:
    ``tau ~ Gamma(shape, rate)``, ``b | tau ~ N(mean, (tau precision)^-1)``, and the
    marginal of ``b`` is a multivariate t with ``2 shape`` degrees of freedom, location
    ``mean`` and scale matrix ``rate / shape * precision^-1``.
    """
    if not prior.conjugate:
        raise ValueError("the exact posterior needs the conjugate normal-gamma prior")
    lam = prior.precision + stats.ztz
    h = prior.precision @ prior.mean + stats.ztr
    mean = np.linalg.solve(lam, h)
    b_ls, ssr_min = stats.least_squares()
    # r'r + m0'P0 m0 - mn'Ln mn, written as sums of non-negative terms to avoid cancellation.
    d0 = prior.mean - mean
    dl = b_ls - mean
    quad = ssr_min + float(dl @ stats.ztz @ dl) + float(d0 @ prior.precision @ d0)
    return {
        "mean": mean,
        "precision": lam,
        "shape": prior.shape + 0.5 * stats.n,
        "rate": prior.rate + 0.5 * quad,
    }


def _sample_exact(stats, prior, gens, kept) -> BlockDraws:
    post = exact_posterior(stats, prior)
    chol = np.linalg.cholesky(post["precision"])
    k = stats.k
    out_b = np.empty((len(gens), kept, k))
    out_t = np.empty((len(gens), kept))
    for c, gen in enumerate(gens):
        z = gen.standard_normal((kept, k))
        tau = gen.standard_gamma(post["shape"], kept) / post["rate"]
        # b = mean + L'^-1 z / sqrt(tau), with precision = L L'
        e = np.linalg.solve(chol.T, z.T).T
        out_b[c] = post["mean"] + e / np.sqrt(tau)[:, None]
        out_t[c] = tau
    return BlockDraws(out_b, out_t)
