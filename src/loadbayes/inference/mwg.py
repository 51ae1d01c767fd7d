"""Metropolis-within-Gibbs for a power-law block ``y = x^theta (o + U c) + e``.

The block is linear in ``c`` given the exponent ``theta``. The exponent is drawn by a
random-walk Metropolis step *with the linear coefficients integrated out* (their Gaussian
integral given ``tau`` is closed-form), then ``c`` from its normal conditional, then
``tau`` from its gamma conditional. Integrating ``c`` out matters: on a narrow voltage band
the scale and the exponent are strongly correlated, and a one-at-a-time update would crawl
along that ridge. The step size is adapted during burn-in only (target acceptance 0.44).
Each iteration costs O(n): ``x^theta`` changes with ``theta``.

This module knows no physics: the exponential load model builds the blocks
(:meth:`loadbayes.models.exponential.ExponentialModel.power_law_blocks`).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from loadbayes.core.blocks import PowerLawBlock
from loadbayes.core.parallel import chain_generators, num_threads, run_chains
from loadbayes.core.priors import BlockPrior
from loadbayes.core.settings import SamplerSettings
from loadbayes.inference.linalg import cholesky, solve_lower, solve_upper

__all__ = ["DEFAULTS", "sample_power_law"]

#: The settings of :func:`sample_power_law` when none are given (it had no defaults
#: before: these are the fits' own, the paper's M and m).
DEFAULTS = SamplerSettings(draws=40_000, burn=5_000, chains=4, seed=0)

_ADAPT_EVERY = 50
_TAU_FLOOR = 1e-100


@njit(cache=True, nogil=True)
def _sums(th, lx, u, y, o, g2u, g2u1, guy, out3):  # pragma: no cover - compiled
    """Sums over samples at exponent ``th`` with ``g = exp(th lx)``.

    ``g2u = sum g^2 u u'``, ``g2u1 = sum g^2 u``, ``guy = sum g u y``,
    ``out3 = [sum g y, sum g^2]``.
    """
    n, kc = u.shape
    for p in range(kc):
        g2u1[p] = 0.0
        guy[p] = 0.0
        for q in range(kc):
            g2u[p, q] = 0.0
    gy = 0.0
    g2 = 0.0
    for i in range(n):
        g = math.exp(th * lx[i])
        gg = g * g
        gy += g * y[i]
        g2 += gg
        for p in range(kc):
            gu = g * u[i, p]
            guy[p] += gu * y[i]
            g2u1[p] += gg * u[i, p]
            for q in range(p, kc):
                g2u[p, q] += gu * g * u[i, q]
    for p in range(kc):
        for q in range(p):
            g2u[p, q] = g2u[q, p]
    out3[0] = gy
    out3[1] = g2


@njit(cache=True, nogil=True)
def _collapsed(tau, o, y2, s3, g2u, g2u1, guy, pc, pcm, lam, h, lo, w):  # pragma: no cover
    """Log p(y | exponent, tau) up to a constant, with the linear block integrated out.

    Leaves ``lam``, ``h`` (the linear block's conditional precision and linear term) and
    ``lo`` (Cholesky of ``lam``) and ``w = lo^-1 h`` behind for the draw that follows.
    """
    kc = h.shape[0]
    tt = y2 - 2.0 * o * s3[0] + o * o * s3[1]  # t't with t = y - o g
    val = -0.5 * tau * tt
    if kc == 0:
        return val
    for p in range(kc):
        h[p] = pcm[p] + tau * (guy[p] - o * g2u1[p])
        for q in range(kc):
            lam[p, q] = pc[p, q] + tau * g2u[p, q]
    if not cholesky(lam, lo):
        return -np.inf
    solve_lower(lo, h, w)
    logdet = 0.0
    for p in range(kc):
        logdet += math.log(lo[p, p])
    quad = 0.0
    for p in range(kc):
        quad += w[p] * w[p]
    return val - logdet + 0.5 * quad


@njit(cache=True, nogil=True)
def _exp_chain(
    lx,
    u,
    y,
    o,
    th_m,
    th_sd,
    pc,
    pcm,
    a0,
    b0,
    th,
    tau,
    step,
    gen,
    draws,
    burn,
    thin,
    out_th,
    out_c,
    out_t,
    stats,
):  # pragma: no cover - compiled
    """One chain: (exponent | tau) collapsed MH, (c | exponent, tau), (tau | exponent, c)."""
    n, kc = u.shape
    y2 = 0.0
    for i in range(n):
        y2 += y[i] * y[i]
    g2u = np.empty((kc, kc))
    g2u1 = np.empty(kc)
    guy = np.empty(kc)
    s3 = np.empty(2)
    g2u_n = np.empty((kc, kc))
    g2u1_n = np.empty(kc)
    guy_n = np.empty(kc)
    s3_n = np.empty(2)
    lam = np.empty((kc, kc))
    h = np.empty(kc)
    lo = np.zeros((kc, kc))
    w = np.empty(kc)
    c = np.zeros(kc)
    _sums(th, lx, u, y, o, g2u, g2u1, guy, s3)
    shape = a0 + 0.5 * n
    acc_win = 0
    kept = 0
    keep = burn
    for it in range(draws):
        # exponent | tau, with the linear coefficients integrated out
        cur = _collapsed(tau, o, y2, s3, g2u, g2u1, guy, pc, pcm, lam, h, lo, w)
        cur -= 0.5 * ((th - th_m) / th_sd) ** 2
        prop = th + step * gen.standard_normal()
        lu = math.log(gen.random())
        _sums(prop, lx, u, y, o, g2u_n, g2u1_n, guy_n, s3_n)
        new = _collapsed(tau, o, y2, s3_n, g2u_n, g2u1_n, guy_n, pc, pcm, lam, h, lo, w)
        new -= 0.5 * ((prop - th_m) / th_sd) ** 2
        if lu < new - cur:
            th = prop
            for p in range(kc):
                g2u1[p] = g2u1_n[p]
                guy[p] = guy_n[p]
                for q in range(kc):
                    g2u[p, q] = g2u_n[p, q]
            s3[0] = s3_n[0]
            s3[1] = s3_n[1]
            acc_win += 1
            if it >= burn:
                stats[0] += 1
        if it >= burn:
            stats[1] += 1
        elif (it + 1) % _ADAPT_EVERY == 0:
            step *= math.exp(2.0 * (acc_win / _ADAPT_EVERY - 0.44))
            acc_win = 0
        # c | exponent, tau  (lam, lo, w recomputed at the current exponent)
        _collapsed(tau, o, y2, s3, g2u, g2u1, guy, pc, pcm, lam, h, lo, w)
        for p in range(kc):
            w[p] += gen.standard_normal()
        solve_upper(lo, w, c)  # lo' c = w + z: c ~ N(lam^-1 h, lam^-1)
        # tau | exponent, c
        tt = y2 - 2.0 * o * s3[0] + o * o * s3[1]
        ssr = tt
        for p in range(kc):
            dty = guy[p] - o * g2u1[p]
            ssr -= 2.0 * c[p] * dty
            for q in range(kc):
                ssr += c[p] * g2u[p, q] * c[q]
        ssr = max(ssr, 0.0)
        tau = max(gen.standard_gamma(shape) / (b0 + 0.5 * ssr), _TAU_FLOOR)
        if it == keep:
            out_th[kept] = th
            for p in range(kc):
                out_c[kept, p] = c[p]
            out_t[kept] = tau
            kept += 1
            keep += thin
    return True


def _nls_start(lx: np.ndarray, u: np.ndarray, y: np.ndarray, o: float, th_m: float):
    """Nonlinear least squares of the channel: (exponent, its standard error, sigma2)."""
    from scipy.optimize import least_squares

    n, kc = u.shape

    def resid(p):
        g = np.exp(p[0] * lx)
        return g * (o + u @ p[1:]) - y

    # Start the exponent from a log-log fit where possible, else 1.
    th0 = 1.0
    pos = y > 0
    if o and pos.sum() > 2 and np.ptp(lx[pos]) > 0:
        th0 = float(np.polyfit(lx[pos], np.log(y[pos]), 1)[0])
    elif pos.sum() > 2 and np.ptp(lx[pos]) > 0:
        th0 = float(np.polyfit(lx[pos], np.log(y[pos]), 1)[0])
    th0 = float(np.clip(th0, -20, 20))
    c0 = np.zeros(kc)
    if kc:
        g = np.exp(th0 * lx)
        c0 = np.linalg.lstsq(g[:, None] * u, y - o * g, rcond=None)[0]
    try:
        fit = least_squares(resid, np.r_[th0, c0], method="lm" if n > kc + 1 else "trf")
        p, jac, res = fit.x, fit.jac, fit.fun
    except Exception:  # noqa: BLE001 - a start only; the sampler does the real work
        p = np.r_[th0, c0]
        res = resid(p)
        jac = None
    sigma2 = max(float(res @ res) / max(n - kc - 1, 1), 1e-24)
    se = 0.1
    if jac is not None:
        with np.errstate(all="ignore"):
            cov = sigma2 * np.linalg.pinv(jac.T @ jac)
        if np.isfinite(cov[0, 0]) and cov[0, 0] > 0:
            se = float(np.sqrt(cov[0, 0]))
    return float(p[0]), se, sigma2


def sample_power_law(
    block: PowerLawBlock,
    exponent: tuple[float, float],
    linear: BlockPrior,
    *,
    settings: SamplerSettings | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
    """Draws of (theta, c, tau) of one power-law block, shaped (chain, draw[, k]).

    Parameters
    ----------
    block : PowerLawBlock
        The data of the block.
    exponent : (float, float)
        Normal prior (mean, sd) of ``theta``.
    linear : BlockPrior
        Normal prior of ``c`` and gamma prior of ``tau`` (with no ``c``, only its
        ``shape`` and ``rate`` are used).
    settings : SamplerSettings, optional
        ``chains``, ``draws`` (burn-in included), ``burn``, ``thin``, ``seed`` (one
        generator per chain spawned from it) and ``threads`` (at most this many threads);
        :data:`DEFAULTS` when not given. ``init`` is not used (see below).

    Returns
    -------
    theta, c, tau, acceptance
    """
    settings = DEFAULTS if settings is None else settings
    chains, draws, burn, thin = settings.chains, settings.draws, settings.burn, settings.thin
    lx, u, y, o = block.log_x, block.design, block.target, block.offset
    n, kc = u.shape
    kept = len(range(burn, draws, thin))
    if kc and linear.k != kc:
        raise ValueError(f"priors['{block.name}'].linear needs {kc} coefficient(s), has {linear.k}")
    pc = np.ascontiguousarray(linear.precision if kc else np.zeros((0, 0)))
    pcm = np.ascontiguousarray(linear.precision @ linear.mean if kc else np.zeros(0))
    th_hat, se, sigma2 = _nls_start(lx, u, y, o, exponent[0])
    gens = chain_generators(settings.seed, chains)
    out_th = np.empty((chains, kept))
    out_c = np.empty((chains, kept, kc))
    out_t = np.empty((chains, kept))
    acc = np.zeros((chains, 2))

    def run(c: int, gen: np.random.Generator) -> bool:
        # The start is scattered around the NLS fit whatever ``init`` says: a prior
        # draw of an exponent (sd 10) is too far out for a step scaled to the posterior.
        th0 = th_hat + 3.0 * se * gen.standard_normal()
        tau0 = float(np.exp(gen.standard_normal()) / sigma2)
        return _exp_chain(
            lx,
            u,
            y,
            o,
            float(exponent[0]),
            float(exponent[1]),
            pc,
            pcm,
            float(linear.shape),
            float(linear.rate),
            th0,
            tau0,
            2.4 * se,
            gen,
            draws,
            burn,
            thin,
            out_th[c],
            out_c[c],
            out_t[c],
            acc[c],
        )

    workers = min(chains, num_threads(), max(n * draws * chains // 2_000_000, 1))
    if settings.threads is not None:
        workers = min(workers, settings.threads)
    run_chains(run, gens, workers=workers)
    return out_th, out_c, out_t, float(acc[:, 0].sum() / max(acc[:, 1].sum(), 1))
