"""Gibbs sampling of a bilinear Gaussian model from its sufficient statistics.

Some load models are linear in each of two coefficient blocks given the other (the
induction motor with modelled currents: linear in (b1, b2, b3) given (ab, ac) and the
reverse). Writing ``phi = kron([1, u], [1, v])``, every residual sum of squares is a
quadratic form ``phi' H phi`` in a few fixed matrices read off the Gram, so a Gibbs sweep
(``u | v, tau``; ``v | u, tau``; ``tau | u, v``) costs O(1) in the number of samples.
Nothing here knows about motors.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any, Literal

import numpy as np
from numba import njit

from loadbayes.core.blocks import BilinearStats
from loadbayes.core.parallel import chain_generators
from loadbayes.core.priors import BlockPrior
from loadbayes.core.settings import SamplerSettings
from loadbayes.inference.linalg import precision_draw

#: The settings of :func:`sample_bilinear` when none are given (the paper's M and m; a
#: fresh seed from the operating system).
DEFAULTS = SamplerSettings(draws=40_000, burn=5_000, chains=4, seed=None)


@njit(cache=True, nogil=True)
def _gauss_draw(lam, lin, z, x, single):  # pragma: no cover - compiled
    # x ~ N(lam^-1 lin, lam^-1), in place; single-site: one coordinate at a time given x.
    k = lin.shape[0]
    if single:
        for j in range(k):
            acc = lin[j]
            for i in range(k):
                if i != j:
                    acc -= lam[j, i] * x[i]
            x[j] = acc / lam[j, j] + z[j] / np.sqrt(lam[j, j])
        return
    lo = np.empty((k, k))
    w = np.empty(k)
    if not precision_draw(lam, lin, z, lo, w, x):
        x[:] = np.nan  # not positive definite: no draw (NaN, as a failed factor gives)


@njit(cache=True, nogil=True)
def _bilinear_chain(
    h, rate0, m1, p1, m2, p2, single, u, v, z1, z2, g, burn, thin, out_u, out_v, out_t
):  # pragma: no cover - compiled
    ng, p, _ = h.shape
    k1, k2 = u.shape[0], v.shape[0]
    q1, q2 = k1 + 1, k2 + 1
    ut = np.empty(q1)
    vt = np.empty(q2)
    phi = np.empty(p)
    tau = np.empty(ng)
    lam1 = np.empty((k1, k1))
    lin1 = np.empty(k1)
    lam2 = np.empty((k2, k2))
    lin2 = np.empty(k2)
    q = np.empty((max(q1, q2), max(q1, q2)))
    p1m = p1 @ m1
    p2m = p2 @ m2
    kept = 0
    n_iter = z1.shape[0]
    for it in range(n_iter + 1):
        if it > 0:
            # u | v, tau: Q[i, i2] = sum_g tau_g sum_jk vt_j vt_k h_g[i q2 + j, i2 q2 + k]
            for i in range(q1):
                for i2 in range(q1):
                    s = 0.0
                    for gg in range(ng):
                        a = 0.0
                        for j in range(q2):
                            for kk in range(q2):
                                a += vt[j] * vt[kk] * h[gg, i * q2 + j, i2 * q2 + kk]
                        s += tau[gg] * a
                    q[i, i2] = s
            for i in range(k1):
                lin1[i] = p1m[i] - q[i + 1, 0]
                for i2 in range(k1):
                    lam1[i, i2] = p1[i, i2] + q[i + 1, i2 + 1]
            _gauss_draw(lam1, lin1, z1[it - 1], u, single)
            # v | u, tau
            ut[0] = 1.0
            for i in range(k1):
                ut[i + 1] = u[i]
            for j in range(q2):
                for kk in range(q2):
                    s = 0.0
                    for gg in range(ng):
                        a = 0.0
                        for i in range(q1):
                            for i2 in range(q1):
                                a += ut[i] * ut[i2] * h[gg, i * q2 + j, i2 * q2 + kk]
                        s += tau[gg] * a
                    q[j, kk] = s
            for j in range(k2):
                lin2[j] = p2m[j] - q[j + 1, 0]
                for kk in range(k2):
                    lam2[j, kk] = p2[j, kk] + q[j + 1, kk + 1]
            _gauss_draw(lam2, lin2, z2[it - 1], v, single)
        # tau | u, v (at it = 0: the start, from the initial coefficients)
        ut[0] = 1.0
        for i in range(k1):
            ut[i + 1] = u[i]
        vt[0] = 1.0
        for j in range(k2):
            vt[j + 1] = v[j]
        for i in range(q1):
            for j in range(q2):
                phi[i * q2 + j] = ut[i] * vt[j]
        for gg in range(ng):
            s = 0.0
            for a in range(p):
                for b in range(p):
                    s += phi[a] * h[gg, a, b] * phi[b]
            tau[gg] = max(g[it, gg] / (rate0[gg] + 0.5 * max(s, 0.0)), 1e-100)
        if it > 0 and it - 1 >= burn and (it - 1 - burn) % thin == 0:
            for i in range(k1):
                out_u[kept, i] = u[i]
            for j in range(k2):
                out_v[kept, j] = v[j]
            for gg in range(ng):
                out_t[kept, gg] = tau[gg]
            kept += 1


def _block_diag(priors: Sequence[BlockPrior]) -> tuple[np.ndarray, np.ndarray]:
    k = sum(p.k for p in priors)
    mean, prec = np.zeros(k), np.zeros((k, k))
    i = 0
    for p in priors:
        mean[i : i + p.k] = p.mean
        prec[i : i + p.k, i : i + p.k] = p.precision
        i += p.k
    return mean, prec


def bilinear_least_squares(
    stats: BilinearStats, *, v0: Sequence[float], max_iter: int = 500, tol: float = 1e-13
) -> dict[str, Any]:
    """Maximum-likelihood fit of a bilinear model by alternating weighted least squares.

    Maximises ``-sum_g (n_g / 2) log SSR_g(u, v)`` (each precision profiled out at
    ``n_g / SSR_g``) by alternating the two linear sub-problems, from ``v0``.

    Returns
    -------
    dict
        ``u``, ``v``, ``tau`` (``n_g / SSR_g``), ``cov`` (inverse Gauss-Newton
        information of ``(u, v)``, precisions at their estimates) and ``iterations``.
    """
    k1, k2 = len(stats.u_names), len(stats.v_names)
    v = np.asarray(v0, dtype=float).copy()
    tau = np.ones(len(stats.n_eq))
    u = np.zeros(k1)
    prev = np.inf
    it = 0
    for it in range(1, max_iter + 1):  # noqa: B007
        u = _solve(*stats.conditional("u", v, tau))
        v = _solve(*stats.conditional("v", u, tau))
        ssr = stats.ssr(u, v)
        tau = stats.n_eq / np.maximum(ssr, 1e-300)
        obj = float(np.sum(stats.n_eq * np.log(np.maximum(ssr, 1e-300))))
        if abs(prev - obj) <= tol * max(abs(obj), 1.0):
            break
        prev = obj
    # Gauss-Newton information: d phi / d(u, v) is (p, k1 + k2).
    ut, vt = np.r_[1.0, u], np.r_[1.0, v]
    q2 = k2 + 1
    d = np.zeros((ut.size * vt.size, k1 + k2))
    for i in range(ut.size):
        for j in range(vt.size):
            if i > 0:
                d[i * q2 + j, i - 1] = vt[j]
            if j > 0:
                d[i * q2 + j, k1 + j - 1] = ut[i]
    info = np.einsum("g,ai,gab,bj->ij", tau, d, stats.h, d)
    try:
        cov = np.linalg.inv(info)
    except np.linalg.LinAlgError:
        cov = np.linalg.pinv(info)
    return {"u": u, "v": v, "tau": tau, "cov": cov, "iterations": it}


def _solve(lam: np.ndarray, lin: np.ndarray) -> np.ndarray:
    # Not lstsq: on noise-free data the groups' precisions differ by 1e8 and a relative
    # singular-value cut-off would zero the weakly weighted block.
    try:
        return np.linalg.solve(lam, lin)
    except np.linalg.LinAlgError:
        return np.linalg.lstsq(lam, lin, rcond=None)[0]


def sample_bilinear(
    stats: BilinearStats,
    prior_u: Sequence[BlockPrior],
    prior_v: BlockPrior,
    *,
    tau_shape: Sequence[float],
    tau_rate: Sequence[float],
    scheme: Literal["blocked", "single-site"] = "blocked",
    v_start: tuple[np.ndarray, np.ndarray] | None = None,
    settings: SamplerSettings | None = None,
) -> dict[str, np.ndarray]:
    """Gibbs sampling of a bilinear Gaussian model: ``u | v, tau``; ``v | u, tau``; ``tau``.

    Parameters
    ----------
    stats : BilinearStats
        The data, as the matrices ``h`` (O(1) per iteration in the number of rows).
    prior_u : sequence of BlockPrior
        Independent normal priors of the ``u`` coefficients, block by block (the motor's
        flux and speed blocks); non-conjugate.
    prior_v : BlockPrior
        Normal prior of ``v``.
    tau_shape, tau_rate : sequence of float
        Gamma prior of each group's precision.
    scheme : {"blocked", "single-site"}
        Each block drawn jointly, or one coefficient at a time (the paper's Algorithm 1).
    v_start : (mean, cov), optional
        Gaussian from which ``v`` starts with ``init="prior"``: a bilinear likelihood
        has mirror branches (``u2 -> -u2 / c``, ``v -> c v``, ``c < 0``) that Gibbs
        cannot cross, so ``v`` must start on the right one (the motor starts it from the
        current equations alone, which identify it).
    settings : SamplerSettings, optional
        ``chains``, ``draws``, ``burn``, ``thin`` as
        :func:`loadbayes.inference.gibbs.sample_block` (``draws`` includes burn-in);
        ``init``: ``u`` from its prior, or scattered three standard errors around the
        maximum-likelihood estimate (then ``v`` too); ``seed`` (Generator, int,
        SeedSequence or None): one child generator per chain. :data:`DEFAULTS` when not
        given. The chains run one after the other (``threads`` is not used).

    Returns
    -------
    dict of str to ndarray
        Draws shaped (chain, kept) named by ``stats.u_names``, ``v_names``, ``tau_names``.
    """
    if scheme not in ("blocked", "single-site"):
        raise ValueError(
            f"scheme {scheme!r} is not available for the coupled (bilinear) model; "
            "use 'blocked' or 'single-site'"
        )
    settings = DEFAULTS if settings is None else settings
    chains, draws, burn, thin = settings.chains, settings.draws, settings.burn, settings.thin
    init = settings.init
    if init not in ("prior", "dispersed"):
        raise ValueError(f"init must be 'prior' or 'dispersed', got {init!r}")
    priors = [*prior_u, prior_v]
    if any(p.conjugate for p in priors):
        raise ValueError("the coupled model takes independent (non-conjugate) priors only")
    m1, p1 = _block_diag(prior_u)
    m2, p2 = prior_v.mean.astype(float), prior_v.precision.astype(float)
    k1, k2, ng = m1.size, m2.size, len(stats.tau_names)
    if k1 != len(stats.u_names) or k2 != len(stats.v_names):
        raise ValueError("priors do not match the coefficient blocks")
    shape_post = np.asarray(tau_shape, float) + 0.5 * stats.n_eq
    rate0 = np.asarray(tau_rate, float)
    gens = chain_generators(settings.seed, chains)
    kept = len(range(burn, draws, thin))
    out_u = np.empty((chains, kept, k1))
    out_v = np.empty((chains, kept, k2))
    out_t = np.empty((chains, kept, ng))
    ml = None
    if init == "dispersed":
        ml = bilinear_least_squares(stats, v0=v_start[0] if v_start is not None else m2)
    for c, gen in enumerate(gens):
        if init == "prior":
            u0 = _prior_draw(gen, m1, p1)
            if v_start is not None:
                v0 = gen.multivariate_normal(v_start[0], v_start[1])
            else:
                v0 = _prior_draw(gen, m2, p2)
        else:
            sd = np.sqrt(np.clip(np.diag(ml["cov"]), 0.0, None))
            x0 = np.r_[ml["u"], ml["v"]] + 3.0 * sd * gen.standard_normal(k1 + k2)
            u0, v0 = x0[:k1], x0[k1:]
        z1 = gen.standard_normal((draws, k1))
        z2 = gen.standard_normal((draws, k2))
        g = np.stack([gen.standard_gamma(s, draws + 1) for s in shape_post], axis=1)
        _bilinear_chain(
            np.ascontiguousarray(stats.h, dtype=float),
            rate0,
            m1,
            p1,
            m2,
            p2,
            scheme == "single-site",
            np.asarray(u0, dtype=float).copy(),
            np.asarray(v0, dtype=float).copy(),
            z1,
            z2,
            g,
            burn,
            thin,
            out_u[c],
            out_v[c],
            out_t[c],
        )
    out: dict[str, np.ndarray] = {}
    for i, n in enumerate(stats.u_names):
        out[n] = out_u[..., i]
    for j, n in enumerate(stats.v_names):
        out[n] = out_v[..., j]
    for j, n in enumerate(stats.tau_names):
        out[n] = out_t[..., j]
    return out


def _prior_draw(gen: np.random.Generator, mean: np.ndarray, prec: np.ndarray) -> np.ndarray:
    try:
        return gen.multivariate_normal(mean, np.linalg.inv(prec))
    except np.linalg.LinAlgError:  # flat prior: any start
        return mean + gen.standard_normal(mean.size)
