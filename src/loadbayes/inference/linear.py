"""Independent conjugate blocks read off one Gram matrix, sampled together.

A model describes its parameters as :class:`~loadbayes.core.blocks.LinearBlock` objects;
this module knows nothing about power systems: it turns a Gram matrix and priors into
draws.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np
from scipy import integrate, special

from loadbayes.core.blocks import LinearBlock
from loadbayes.core.priors import BlockPrior
from loadbayes.core.settings import SamplerSettings
from loadbayes.core.stats import Gram, RegressionStats
from loadbayes.inference.gibbs import Scheme, sample_block

__all__ = ["DEFAULTS", "log_evidence", "sample_blocks"]

#: The settings of :func:`sample_blocks` when none are given: the paper's M and m, seed 0.
DEFAULTS = SamplerSettings(draws=40_000, burn=5_000, chains=4, seed=0)


def sample_blocks(
    gram: Gram,
    blocks: Sequence[LinearBlock],
    priors: Mapping[str, BlockPrior],
    *,
    scheme: Scheme = "blocked",
    settings: SamplerSettings | None = None,
) -> dict[str, np.ndarray]:
    """Sample every block and return named draws shaped (chain, draw).

    ``settings`` (:data:`DEFAULTS` when not given) are those of every block, except that
    each block gets its own child of ``settings.seed`` (``SeedSequence.spawn``), so adding
    a block (say Q next to P) leaves the draws of the others unchanged.
    """
    settings = DEFAULTS if settings is None else settings
    seed = settings.seed
    seq = seed if isinstance(seed, np.random.SeedSequence) else np.random.SeedSequence(seed)
    children = seq.spawn(len(blocks))
    out: dict[str, np.ndarray] = {}
    for block, child in zip(blocks, children, strict=True):
        res = sample_block(
            block.stats(gram),
            priors[block.name],
            scheme=scheme,
            settings=settings.with_(seed=child),
        )
        for i, name in enumerate(block.coef_names):
            out[name] = res.coef[..., i]
        out[block.tau_name] = res.tau
    return out


def log_evidence(stats: RegressionStats, prior: BlockPrior, *, points: int = 4_001) -> float:
    """``log p(r)`` of one block ``r = Z b + e`` under its (independent) prior, exactly.

    ``b ~ N(m0, P0^-1)`` and ``tau ~ Gamma(shape, rate)`` independent (``conjugate=False``,
    the prior :func:`sample_blocks` samples). Given ``tau``, ``b`` integrates out in
    closed form (``inference/condlinear.py``'s formula); one eigendecomposition of
    ``P0^-1/2 Z'Z P0^-1/2 = V diag(l) V'`` makes that O(k) in ``tau``::

        log p(r | tau) = n/2 log(tau / 2 pi) - tau r'r / 2
                         + (sum_i u_i^2 / (1 + tau l_i) - sum_i log(1 + tau l_i) - m0'P0 m0) / 2

    with ``u = V'(P0^1/2 m0 + tau P0^-1/2 Z'r)``; the one dimension left, ``tau``, is
    integrated on a grid of ``points`` in ``log tau`` around the integrand's peak (a
    trapezoid on a smooth peaked integrand: exact to rounding once the grid spans it).
    """
    if prior.conjugate:
        raise ValueError("log_evidence is for the independent prior (conjugate=False)")
    chol = np.linalg.cholesky(prior.precision)  # P0 = L L'
    w = np.linalg.solve(chol, np.linalg.solve(chol, stats.ztz).T).T  # L^-1 Z'Z L^-T
    lam, vec = np.linalg.eigh((w + w.T) / 2)
    lam = np.clip(lam, 0.0, None)
    c0 = vec.T @ (chol.T @ prior.mean)
    c1 = vec.T @ np.linalg.solve(chol, stats.ztr)
    m0p = float(prior.mean @ prior.precision @ prior.mean)
    a, b, n = prior.shape, prior.rate, float(stats.n)

    def g(s: np.ndarray) -> np.ndarray:  # log integrand in s = log tau (with the Jacobian)
        tau = np.exp(s)[:, None]
        d = 1.0 + tau * lam
        inner = np.sum((c0 + tau * c1) ** 2 / d, axis=1) - np.sum(np.log(d), axis=1) - m0p
        t = tau[:, 0]
        return (0.5 * n * (s - np.log(2 * np.pi)) - 0.5 * t * stats.rtr + 0.5 * inner
                + a * np.log(b) - special.gammaln(a) + a * s - b * t)  # fmt: skip

    coarse = np.linspace(-40.0, 60.0, 401)
    s0 = coarse[int(np.argmax(g(coarse)))]
    half = max(2.0, 12.0 * np.sqrt(2.0 / max(n + 2.0 * a, 1.0)))
    grid = np.linspace(s0 - half, s0 + half, points)
    vals = g(grid)
    top = float(vals.max())
    return top + float(np.log(integrate.trapezoid(np.exp(vals - top), grid)))
