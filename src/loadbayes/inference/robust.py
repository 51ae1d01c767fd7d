"""Gibbs sampling of a linear block with a Student-t likelihood (robust to bad samples).

The model, generic over a design ``Z`` (n, k) and a target ``r`` (n,)::

    r_i = z_i' b + e_i,   e_i | w_i ~ N(0, 1 / (tau w_i)),   w_i ~ Gamma(nu / 2, rate nu / 2)

Integrating the latent weight ``w_i`` out gives ``e_i ~ t_nu(0, 1 / tau)``: a Student-t
likelihood written as a scale mixture of normals (West 1984; Geweke 1993). Given the
weights every conditional is conjugate, so this is still a Gibbs sampler:

* ``b | w, tau ~ N(L^-1 h, L^-1)``, ``L = s P0 + tau Z'WZ``, ``h = s P0 m0 + tau Z'Wr``
  (``s = tau`` for the conjugate prior, else 1), ``W = diag(w)``;
* ``tau | b, w ~ Gamma(a0 + n/2 [+ k/2], b0 + sum_i w_i e_i^2 / 2 [+ (b-m0)'P0(b-m0)/2])``;
* ``w_i | b, tau, nu ~ Gamma((nu + 1)/2, rate (nu + tau e_i^2)/2)``, independent.

The degrees of freedom ``nu`` are fixed, or sampled (``nu="auto"``) by a random-walk
Metropolis step on ``log nu`` with the weights integrated out: the target is
``p(nu) prod_i t_nu(e_i; 0, 1/tau)``, and the weights are then drawn given the new
``nu``. Drawing ``nu`` given the weights instead would mix badly (given n weights, nu is
pinned down); drawing ``(nu, w)`` jointly given ``(b, tau)`` is a valid blocked update.
The prior on ``nu`` is Gamma(2, rate 0.1) (Juarez & Steel 2010: mode 10, mean 20),
truncated to [1, 1000]. The step size is adapted during burn-in only (target acceptance
0.44), so the kept chain is a plain Metropolis-within-Gibbs chain.

Cost: every iteration touches every sample (a residual, a gamma draw and the weighted
Gram), O(n k^2), in a compiled loop; ``nu="auto"`` adds two passes of ``log1p``. The
Gaussian sampler of :mod:`loadbayes.inference.gibbs` is O(1) in n per iteration: use it
when the data are clean.

Flagging suspect samples
------------------------
The posterior mean weight of sample ``i`` is accumulated Rao-Blackwellised, as the mean
over kept draws of ``E[w_i | b, tau, nu] = (nu + 1) / (nu + tau e_i^2)``. A sample is
flagged when its mean weight is below ``(nu_hat + 1) / (nu_hat + c^2)`` with ``nu_hat``
the posterior median of ``nu`` and ``c = 3.5`` (:data:`FLAG_SIGMAS`): the weight of a
residual of ``c`` scale units ``1/sqrt(tau)``, so the rule reads "the model discounts
this sample as much as a 3.5-sigma outlier". Measured on the paper's design (n = 2000,
noise sd 0.1, 4 replicates; ``docs/past_paper.md``): on clean Gaussian data 0.075% of
the samples are flagged (``nu`` is then large and the rule is a 3.5-sigma residual
test, 0.047% in theory); with 5% spikes of 5-10 sigma or 5% dropouts every bad sample is
flagged and 0.4-0.5% of the good ones (``nu`` near 2 shrinks the scale the residuals
are measured in). ``c = 3`` flags 0.4% of clean samples and 1.3-1.5% of good ones
among bad data; ``c = 4``, 0.01% and 0.14%.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal

import numpy as np
from numba import njit

from loadbayes.core.parallel import chain_generators, num_threads, run_chains
from loadbayes.core.priors import BlockPrior
from loadbayes.core.settings import SamplerSettings
from loadbayes.inference.linalg import precision_draw

__all__ = [
    "DEFAULTS",
    "FLAG_SIGMAS",
    "NU_BOUNDS",
    "NU_PRIOR",
    "RobustDraws",
    "flag_threshold",
    "sample_student_t",
]

#: The settings of :func:`sample_student_t` when none are given (the paper's M and m; a
#: fresh seed from the operating system).
DEFAULTS = SamplerSettings(draws=40_000, burn=5_000, chains=4, seed=None)
#: Gamma(shape, rate) prior of nu when it is sampled (Juarez & Steel 2010).
NU_PRIOR = (2.0, 0.1)
#: Support of nu when it is sampled.
NU_BOUNDS = (1.0, 1000.0)
#: A sample is flagged when it is discounted as much as a residual of this many scales.
FLAG_SIGMAS = 3.5
_TAU_FLOOR = 1e-100
_ADAPT_EVERY = 50


@dataclass(frozen=True)
class RobustDraws:
    """Posterior draws of a Student-t block.

    Attributes
    ----------
    coef : ndarray, shape (chain, draw, k)
        Coefficient draws.
    tau : ndarray, shape (chain, draw)
        Precision (inverse squared scale) of the t noise.
    nu : ndarray, shape (chain, draw)
        Degrees of freedom (constant when fixed).
    weight : ndarray, shape (n,)
        Posterior mean latent weight of each sample (over chains and kept draws).
    accept_nu : ndarray, shape (chain,)
        Acceptance rate of the ``nu`` step after burn-in (NaN when ``nu`` is fixed).
    """

    coef: np.ndarray
    tau: np.ndarray
    nu: np.ndarray
    weight: np.ndarray
    accept_nu: np.ndarray

    def flagged(self, *, sigmas: float = FLAG_SIGMAS) -> np.ndarray:
        """0-based indices of the samples flagged as suspect (see the module notes)."""
        return np.flatnonzero(self.weight < flag_threshold(self.nu, sigmas=sigmas))


def flag_threshold(nu: np.ndarray | float, *, sigmas: float = FLAG_SIGMAS) -> float:
    """Weight below which a sample is flagged: ``(nu + 1) / (nu + sigmas^2)``.

    ``nu`` is the median of the given draws (or the fixed value).
    """
    nu_hat = float(np.median(np.asarray(nu, dtype=float)))
    return (nu_hat + 1.0) / (nu_hat + sigmas * sigmas)


# ----------------------------------------------------------------- compiled kernel
@njit(cache=True, nogil=True)
def _t_loglik_nu(nu, tau, e2, n):  # pragma: no cover - compiled
    """The part of sum_i log t_nu(e_i; 0, 1/tau) that depends on nu."""
    acc = 0.0
    for i in range(n):
        acc += math.log1p(tau * e2[i] / nu)
    return (
        n * (math.lgamma(0.5 * (nu + 1.0)) - math.lgamma(0.5 * nu) - 0.5 * math.log(nu))
        - (0.5 * (nu + 1.0)) * acc
    )


@njit(cache=True, nogil=True)
def _student_t_chain(
    z, r, m0, p0, a0, b0, conj, nu_fixed, nu_shape, nu_rate, lo, hi, b, tau, nu, step,
    gen, draws, burn, thin, out_b, out_t, out_nu, wsum, stats,
):  # pragma: no cover - compiled  # fmt: skip
    """One chain. ``stats = [accepted, proposed]`` of the nu step after burn-in."""
    n, k = z.shape
    w = np.ones(n)
    e2 = np.empty(n)
    zw = np.zeros((k, k))
    cw = np.zeros(k)
    for i in range(n):
        for p in range(k):
            cw[p] += z[i, p] * r[i]
            for q in range(k):
                zw[p, q] += z[i, p] * z[i, q]
    p0m = p0 @ m0
    lam = np.empty((k, k))
    fac = np.empty((k, k))
    h = np.empty(k)
    zs = np.empty(k)
    ws = np.empty(k)
    sample_nu = nu_fixed <= 0.0
    shape_tau = a0 + 0.5 * n + (0.5 * k if conj else 0.0)
    acc_win = 0
    kept = 0
    keep = burn
    for it in range(draws):
        # b | w, tau
        s = tau if conj else 1.0
        for p in range(k):
            h[p] = s * p0m[p] + tau * cw[p]
            for q in range(k):
                lam[p, q] = s * p0[p, q] + tau * zw[p, q]
            zs[p] = gen.standard_normal()
        if not precision_draw(lam, h, zs, fac, ws, b):
            return False
        # residuals; tau | b, w
        q_w = 0.0
        for i in range(n):
            e = r[i]
            for p in range(k):
                e -= z[i, p] * b[p]
            e2[i] = e * e
            q_w += w[i] * e * e
        rate = b0 + 0.5 * q_w
        if conj:
            qp = 0.0
            for p in range(k):
                for q in range(k):
                    qp += (b[p] - m0[p]) * p0[p, q] * (b[q] - m0[q])
            rate += 0.5 * qp
        tau = max(gen.standard_gamma(shape_tau) / rate, _TAU_FLOOR)
        # (nu, w) | b, tau: nu with the weights integrated out, then the weights.
        if sample_nu:
            lnu = math.log(nu)
            prop = lnu + step * gen.standard_normal()
            u = gen.random()
            if lo <= prop <= hi:
                nup = math.exp(prop)
                cur = _t_loglik_nu(nu, tau, e2, n) + nu_shape * lnu - nu_rate * nu
                new = _t_loglik_nu(nup, tau, e2, n) + nu_shape * prop - nu_rate * nup
                # nu_shape (not shape - 1): the Jacobian of the log transform adds log nu.
                if math.log(u) < new - cur:
                    nu = nup
                    acc_win += 1
                    if it >= burn:
                        stats[0] += 1
            if it >= burn:
                stats[1] += 1
            elif (it + 1) % _ADAPT_EVERY == 0:
                rate_acc = acc_win / _ADAPT_EVERY
                step *= math.exp(rate_acc - 0.44)
                acc_win = 0
        g_shape = 0.5 * (nu + 1.0)
        store = it == keep
        for p in range(k):
            cw[p] = 0.0
            for q in range(k):
                zw[p, q] = 0.0
        for i in range(n):
            den = nu + tau * e2[i]
            wi = gen.standard_gamma(g_shape) * 2.0 / den
            w[i] = wi
            if store:
                wsum[i] += (nu + 1.0) / den  # Rao-Blackwellised E[w_i | b, tau, nu]
            for p in range(k):
                zp = wi * z[i, p]
                cw[p] += zp * r[i]
                for q in range(p, k):
                    zw[p, q] += zp * z[i, q]
        for p in range(k):
            for q in range(p):
                zw[p, q] = zw[q, p]
        if store:
            for p in range(k):
                out_b[kept, p] = b[p]
            out_t[kept] = tau
            out_nu[kept] = nu
            kept += 1
            keep += thin
    return True


# ----------------------------------------------------------------------- driver
def _start(z, r, prior, gen, init):
    """Starting (b, tau): b from the prior or scattered around LS; tau scaled by the data.

    A prior draw of tau under the vague default Gamma(1e-3, 1e-9) is astronomically
    large or small, a poor start for the latent weights; so tau always starts at
    ``exp(N(0, 1)) / sigma2_LS`` whatever ``init`` says.
    """
    n, k = z.shape
    coef, *_ = np.linalg.lstsq(z, r, rcond=None)
    res = r - z @ coef
    sigma2 = max(float(res @ res) / max(n - k, 1), 1e-12 * (float(r @ r) / n + 1e-300))
    tau = float(np.exp(gen.standard_normal()) / sigma2)
    if init == "prior":
        try:
            b = gen.multivariate_normal(prior.mean, np.linalg.inv(prior.precision))
        except np.linalg.LinAlgError:
            b = coef + gen.standard_normal(k)
    elif init == "dispersed":
        cov = sigma2 * np.linalg.pinv(z.T @ z)
        b = coef + 3.0 * np.sqrt(np.clip(np.diag(cov), 0, None)) * gen.standard_normal(k)
    else:
        raise ValueError(f"init must be 'prior' or 'dispersed', got {init!r}")
    return np.asarray(b, dtype=float), tau


def sample_student_t(
    z: np.ndarray,
    r: np.ndarray,
    prior: BlockPrior,
    *,
    nu: float | Literal["auto"] = "auto",
    nu_prior: tuple[float, float] = NU_PRIOR,
    nu_bounds: tuple[float, float] = NU_BOUNDS,
    settings: SamplerSettings | None = None,
) -> RobustDraws:
    """Draw from the posterior of ``r = Z b + e`` with Student-t noise.

    Parameters
    ----------
    z : ndarray, shape (n, k)
        Design.
    r : ndarray, shape (n,)
        Target.
    prior : BlockPrior
        Normal prior on ``b``, gamma prior on ``tau`` (``conjugate`` honoured).
    nu : float or "auto"
        Degrees of freedom: fixed (> 0), or sampled (see the module notes).
    nu_prior : (float, float)
        Gamma(shape, rate) prior of ``nu`` when sampled.
    nu_bounds : (float, float)
        Support of ``nu`` when sampled.
    settings : SamplerSettings, optional
        ``chains``, ``draws``, ``burn``, ``thin`` as
        :func:`loadbayes.inference.gibbs.sample_block` (``draws`` includes burn-in);
        ``init``: the start of ``b``, a prior draw or three standard errors around least
        squares; ``seed`` (Generator, int, SeedSequence or None): each chain gets its own
        spawned generator, so a chain's draws do not depend on how many chains run or on
        threads; ``threads``: at most this many. :data:`DEFAULTS` when not given.

    Returns
    -------
    RobustDraws

    Notes
    -----
    With ``nu`` fixed and large (say 1e6) the draws match the Gaussian sampler's up to
    Monte Carlo error; the tests check that.
    """
    settings = DEFAULTS if settings is None else settings
    chains, draws, burn, thin = settings.chains, settings.draws, settings.burn, settings.thin
    init = settings.init
    z = np.ascontiguousarray(z, dtype=float)
    r = np.ascontiguousarray(r, dtype=float).reshape(-1)
    if z.ndim != 2 or z.shape[0] != r.size:
        raise ValueError(f"z must be (n, k) with n = len(r); got {z.shape} and {r.shape}")
    n, k = z.shape
    if prior.k != k:
        raise ValueError(f"prior has {prior.k} coefficients, the design {k}")
    if n <= k:
        raise ValueError(f"{n} samples for {k} coefficients and a noise scale: too few")
    if not (np.all(np.isfinite(z)) and np.all(np.isfinite(r))):
        raise ValueError("z and r must be finite")
    lo, hi = (float(x) for x in nu_bounds)
    if nu == "auto":
        if not 0 < lo < hi:
            raise ValueError(f"nu_bounds must satisfy 0 < low < high, got {nu_bounds}")
        if not (nu_prior[0] > 0 and nu_prior[1] >= 0):
            raise ValueError(f"nu_prior (shape, rate) must be positive, got {nu_prior}")
        nu_fixed = 0.0
    else:
        try:
            nu_fixed = float(nu)
        except (TypeError, ValueError):
            nu_fixed = float("nan")
        if not (np.isfinite(nu_fixed) and nu_fixed > 0):
            raise ValueError(f"nu must be a positive number or 'auto', got {nu!r}")
    gens = chain_generators(settings.seed, chains)
    kept = len(range(burn, draws, thin))
    out_b = np.empty((chains, kept, k))
    out_t = np.empty((chains, kept))
    out_nu = np.empty((chains, kept))
    wsum = np.zeros((chains, n))
    acc = np.zeros((chains, 2))

    def run(c: int, gen: np.random.Generator) -> bool:
        b, tau = _start(z, r, prior, gen, init)
        if nu_fixed > 0:
            nu0 = nu_fixed
        else:
            nu0 = float(np.clip(gen.gamma(nu_prior[0], 1.0 / max(nu_prior[1], 1e-300)), lo, hi))
        return _student_t_chain(
            z, r, prior.mean, prior.precision, float(prior.shape), float(prior.rate),
            bool(prior.conjugate), nu_fixed, float(nu_prior[0]), float(nu_prior[1]),
            math.log(lo), math.log(hi), b, tau, nu0, 0.5, gen, draws, burn, thin,
            out_b[c], out_t[c], out_nu[c], wsum[c], acc[c],
        )  # fmt: skip

    workers = min(chains, num_threads(), max(n * draws * chains // 2_000_000, 1))
    if settings.threads is not None:
        workers = min(workers, settings.threads)
    ok = run_chains(run, gens, workers=workers)
    if not all(ok):
        raise ValueError(
            "the posterior precision of the coefficients is not positive definite: the "
            "prior is flat along a direction the data do not identify; give those "
            "coefficients a proper prior"
        )
    weight = wsum.sum(axis=0) / (chains * kept)
    with np.errstate(invalid="ignore", divide="ignore"):
        accept = np.where(acc[:, 1] > 0, acc[:, 0] / acc[:, 1], np.nan)
    return RobustDraws(out_b, out_t, out_nu, weight, accept)
