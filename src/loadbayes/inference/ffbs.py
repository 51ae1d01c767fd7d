"""A level that drifts as a random walk, times a regression: Kalman filter, FFBS, Metropolis.

The model of one channel (no physics here: ``x1``, ``x2`` are any two regressors)::

    y_t = L_t (1 + b1 x1_t + b2 x2_t) + e_t,     e_t ~ N(0, w_t / tau)
    L_t = L_{t-1} + u_t,                         u_t ~ N(0, q dt_t w_t)

with ``dt_t`` the time step before sample ``t`` (gaps widen the walk's step) and ``w_t``
a known scale: the square of a local level of ``|y|`` (an hour's moving average), so that
noise and steps are relative to the load, as a random walk on the log-level would make
them, while the level stays linear and Gaussian (a year's level spans 20x: with
``w_t = 1`` the walk was too stiff at the peak and the profile leaked into b, measured
dP/dV 1.07 [1.05, 1.08] for a true 1.15).

The level is integrated out exactly by a Kalman filter (:func:`kf_loglik`, one compiled
O(n) pass): Metropolis moves (b1, b2) and (log tau, log q) on that marginal, each block's
proposal started from its curvature and adapted in the burn-in. The path is drawn, for
the kept draws only, by forward filtering, backward sampling (:func:`ffbs`; Carter and
Kohn 1994, Frühwirth-Schnatter 1994). A few plain Gibbs sweeps (path given the rest, b
given the path: conjugate; tau, q: Gamma, inverse Gamma) start the chain; Gibbs alone
mixed badly, the path absorbing what b would explain.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
from numba import njit

from loadbayes.core.parallel import chain_generators, check_stop, run_chains
from loadbayes.core.settings import SamplerSettings, new_spelling

__all__ = [
    "DEFAULTS",
    "LevelChains",
    "ffbs",
    "kf_loglik",
    "local_scale",
    "sample_level_regression",
]

#: The settings of :func:`sample_level_regression` when none are given (each iteration
#: runs two Kalman filters over the record).
DEFAULTS = SamplerSettings(draws=2500, burn=500, chains=2)


@njit(cache=True, nogil=True)
def ffbs(y, h, dt, w, r, q, m0, v0, z, out, m, p):  # pragma: no cover - compiled
    """Draw the path of ``x_t = x_{t-1} + N(0, q dt_t w_t)`` given ``y_t = h_t x_t + N(0, r w_t)``.

    ``x_0 ~ N(m0, v0)`` (before the first observation); ``z`` holds n standard normals;
    ``m``, ``p`` are work arrays of n (the filtered means and variances). The draw goes to
    ``out``.
    """
    n = y.size
    a = m0
    big_r = v0
    for t in range(n):
        if t > 0:
            a = m[t - 1]
            big_r = p[t - 1] + q * dt[t] * w[t]
        ht = h[t]
        rt = r * w[t]
        s = ht * ht * big_r + rt
        k = big_r * ht / s
        m[t] = a + k * (y[t] - ht * a)
        p[t] = big_r * rt / s
    x = m[n - 1] + math.sqrt(p[n - 1]) * z[n - 1]
    out[n - 1] = x
    for t in range(n - 2, -1, -1):
        step = q * dt[t + 1] * w[t + 1]
        big_r = p[t] + step
        j = p[t] / big_r
        x = m[t] + j * (x - m[t]) + math.sqrt(p[t] * step / big_r) * z[t]
        out[t] = x


@njit(cache=True, nogil=True)
def kf_loglik(y, x1, x2, dt, w, b1, b2, r, q, m0, v0):  # pragma: no cover - compiled
    """Log p(y | b, r, q), the level integrated out: the Kalman filter's forward pass."""
    n = y.size
    quad = 0.0
    logdet = 0.0
    prod = 1.0
    a = m0
    big_r = v0
    p_filt = 0.0
    for t in range(n):
        if t > 0:
            big_r = p_filt + q * dt[t] * w[t]
        ht = 1.0 + b1 * x1[t] + b2 * x2[t]
        rt = r * w[t]
        s = ht * ht * big_r + rt
        inv = 1.0 / s
        e = y[t] - ht * a
        quad += e * e * inv
        a = a + big_r * ht * inv * e
        p_filt = big_r * rt * inv
        # one log per 8 steps: the product of 8 variances stays well inside float64
        prod *= s
        if (t & 7) == 7:
            logdet += math.log(prod)
            prod = 1.0
    logdet += math.log(prod)
    return -0.5 * (logdet + quad + n * math.log(2.0 * math.pi))


@njit(cache=True, nogil=True)
def _sweep(y, x1, x2, dt, w, b1, b2, r, q, m0, v0, z, path, m, p, h):  # pragma: no cover
    """Step 1 (the path) and the sums steps 2-4 need, in two compiled passes."""
    n = y.size
    for t in range(n):
        h[t] = 1.0 + b1 * x1[t] + b2 * x2[t]
    ffbs(y, h, dt, w, r, q, m0, v0, z, path, m, p)
    s11 = s12 = s22 = s1r = s2r = srr = sdl = 0.0
    for t in range(n):
        lv = path[t]
        iw = 1.0 / w[t]
        u1 = lv * x1[t]
        u2 = lv * x2[t]
        res = y[t] - lv
        s11 += u1 * u1 * iw
        s12 += u1 * u2 * iw
        s22 += u2 * u2 * iw
        s1r += u1 * res * iw
        s2r += u2 * res * iw
        srr += res * res * iw
        if t > 0:
            d = lv - path[t - 1]
            sdl += d * d / (dt[t] * w[t])
    return s11, s12, s22, s1r, s2r, srr, sdl


def _laplace_cov(f, x: np.ndarray, step: np.ndarray, fallback: np.ndarray) -> np.ndarray:
    """Inverse of minus the finite-difference Hessian of ``f`` at ``x`` (a proposal's start).

    ``fallback`` when the Hessian is not negative definite there.
    """
    d = x.size
    hess = np.empty((d, d))
    f0 = f(x)
    e = np.eye(d) * step
    for i in range(d):
        for j in range(i, d):
            if i == j:
                hess[i, i] = (f(x + e[i]) - 2 * f0 + f(x - e[i])) / step[i] ** 2
            else:
                hess[i, j] = hess[j, i] = (
                    f(x + e[i] + e[j]) - f(x + e[i] - e[j]) - f(x - e[i] + e[j])
                    + f(x - e[i] - e[j])
                ) / (4 * step[i] * step[j])  # fmt: skip
    try:
        cov = np.linalg.inv(-hess)
        np.linalg.cholesky(cov)
        if np.all(np.isfinite(cov)):
            return cov
    except np.linalg.LinAlgError:
        pass
    return fallback


#: The Metropolis blocks of (b1, b2, log tau, log q).
BLOCKS: tuple[tuple[int, ...], ...] = ((0, 1), (2, 3))


def local_scale(y: np.ndarray, dt: np.ndarray, *, window_s: float = 3600.0) -> np.ndarray:
    """A centred moving average of ``|y|`` over about ``window_s`` seconds, mean 1.

    Floored at 10% of its mean (a Q that crosses zero keeps a usable scale). Any positive
    scale keeps the model valid (a known heteroscedasticity); this one makes noise and
    walk relative to the load.
    """
    n = y.size
    med = float(np.median(dt[1:])) if n > 1 else 1.0
    k = int(max(1, min(n, round(window_s / max(med, 1e-12)))))
    c = np.r_[0.0, np.cumsum(np.abs(y))]
    lo = np.clip(np.arange(n) - k // 2, 0, n)
    hi = np.clip(lo + k, 0, n)
    lo = np.clip(hi - k, 0, n)
    avg = (c[hi] - c[lo]) / np.maximum(hi - lo, 1)
    mean = float(avg.mean()) or 1.0
    return np.maximum(avg / mean, 0.1)


@dataclass
class LevelChains:
    """Draws of one channel: b (chain, draw, 2), tau, q (chain, draw), and the path.

    ``path`` holds the level at ``keep_idx`` for every kept draw (chain, draw, k).
    """

    b: np.ndarray
    tau: np.ndarray
    q: np.ndarray
    path: np.ndarray
    keep_idx: np.ndarray
    acceptance: np.ndarray


@new_spelling(sampler="settings")
def sample_level_regression(
    y: np.ndarray,
    x1: np.ndarray,
    x2: np.ndarray,
    dt: np.ndarray,
    *,
    settings: SamplerSettings | None = None,
    b_mean: Sequence[float] = (0.0, 0.0),
    b_sd: Sequence[float] = (10.0, 10.0),
    tau_prior: tuple[float, float] = (1e-3, 1e-9),
    q_prior: tuple[float, float] | None = None,
    keep_points: int = 500,
    warm: int = 30,
    window_s: float = 3600.0,
    path_draws: int = 200,
    progress: Callable[[int], None] | None = None,
) -> LevelChains:
    """Gibbs draws of ``y_t = L_t (1 + b1 x1_t + b2 x2_t) + e_t`` with a random-walk level.

    Parameters
    ----------
    y, x1, x2 : ndarray, shape (n,)
        Observations and the two regressors.
    dt : ndarray, shape (n,)
        Time step before each sample (``dt[0]`` is not used); positive.
    settings : SamplerSettings, optional
        ``draws`` iterations per chain including ``burn``, every ``thin``-th kept;
        ``chains`` draw from generators spawned from ``seed`` (:func:`chain_generators`),
        in at most ``threads`` threads. :data:`DEFAULTS` when not given.
    b_mean, b_sd : pair of float
        Normal prior of (b1, b2).
    tau_prior : (shape, rate)
        Gamma prior of the noise precision.
    q_prior : (shape, scale), optional
        Inverse-Gamma prior of the walk's variance per unit time; default (1e-3,
        1e-12 var(y) / median dt): weak at the data's scale.
    keep_points : int
        The path is kept at this many evenly spread samples (the level's summary).
    window_s : float
        Width of the moving average of ``|y|`` whose square scales the noise and the walk
        (:func:`local_scale`).

    Returns
    -------
    LevelChains
    """
    settings = settings if settings is not None else DEFAULTS
    chains, draws, burn, thin = settings.chains, settings.draws, settings.burn, settings.thin
    y = np.ascontiguousarray(y, dtype=float)
    x1 = np.ascontiguousarray(x1, dtype=float)
    x2 = np.ascontiguousarray(x2, dtype=float)
    dt = np.ascontiguousarray(dt, dtype=float)
    n = y.size
    if n < 4:
        raise ValueError(f"{n} samples: too few for a drifting level")
    if np.any(dt[1:] <= 0):
        raise ValueError("time steps must be positive")
    kept = len(range(burn, draws, thin))
    path_every = max(1, kept // max(path_draws, 1))
    keep_idx = np.unique(np.linspace(0, n - 1, min(keep_points, n)).astype(np.int64))
    med_dt = float(np.median(dt[1:]))
    var_y = float(np.var(y)) or float(np.mean(y * y)) or 1.0
    qa, qb = q_prior if q_prior is not None else (1e-3, 1e-12 * var_y / med_dt)
    ta, tb = tau_prior
    prec0 = np.diag(1.0 / np.asarray(b_sd, float) ** 2)
    mean0 = np.asarray(b_mean, float)
    scale = float(np.mean(np.abs(y))) or 1.0
    w = local_scale(y, dt, window_s=window_s) ** 2
    m0, v0 = float(y[0]), (10.0 * scale) ** 2
    dy = np.diff(y) / np.sqrt(dt[1:])
    q_start = max(float(np.var(dy)) / 4.0, 1e-300)
    tau_start = 2.0 / max(float(np.var(np.diff(y))), 1e-300)

    prior_sd_b = np.sqrt(1.0 / np.diag(prec0))

    def log_post(th: np.ndarray) -> float:
        # th = (b1, b2, log tau, log q); the priors in these coordinates (Jacobians in)
        b1, b2, lt, lq = th
        if not (-30.0 < lt < 60.0 and -120.0 < lq < 60.0):
            return -np.inf
        tau, q = math.exp(lt), math.exp(lq)
        lp = -0.5 * float(np.sum(((th[:2] - mean0) / prior_sd_b) ** 2))
        lp += ta * lt - tb * tau - qa * lq - qb / q
        return lp + kf_loglik(y, x1, x2, dt, w, b1, b2, 1.0 / tau, q, m0, v0)

    def chain(c: int, gen: np.random.Generator):
        b = np.zeros(2)
        tau, q = tau_start, q_start
        path = np.empty(n)
        m = np.empty(n)
        p = np.empty(n)
        h = np.empty(n)
        z = np.empty(n)
        # A few Gibbs sweeps (path | rest, b | path, tau, q) reach the bulk ...
        for _ in range(warm):
            check_stop(None)
            gen.standard_normal(out=z)
            s11, s12, s22, s1r, s2r, srr, sdl = _sweep(
                y, x1, x2, dt, w, b[0], b[1], 1.0 / tau, q, m0, v0, z, path, m, p, h
            )
            xtx = np.array([[s11, s12], [s12, s22]])
            xtr = np.array([s1r, s2r])
            prec = tau * xtx + prec0
            chol = np.linalg.cholesky(prec)
            mean = np.linalg.solve(prec, tau * xtr + prec0 @ mean0)
            b = mean + np.linalg.solve(chol.T, gen.standard_normal(2))
            ssr = max(srr - 2.0 * b @ xtr + b @ xtx @ b, 1e-300)
            tau = gen.gamma(ta + n / 2.0, 1.0 / (tb + ssr / 2.0))
            q = 1.0 / gen.gamma(qa + (n - 1) / 2.0, 1.0 / (qb + sdl / 2.0))
        # ... then Metropolis on (b, log tau, log q) with the level integrated out by the
        # Kalman filter, its proposal adapted in the burn-in (Haario et al. 2001). Gibbs
        # alone mixed badly: the path absorbs what b would explain, and q and the path
        # hold each other (ESS 5 of 960 draws on a day at 1 s).
        th = np.array([b[0], b[1], math.log(tau), math.log(q)])
        lp = log_post(th)
        # Two blocks, each a Metropolis step with the level integrated out: (b1, b2), and
        # (log tau, log q); each proposal adapted in the burn-in from its own history.
        blocks = BLOCKS
        diag_all = np.zeros((4, 4))
        diag_all[:2, :2] = np.linalg.inv(prec) * 4.0
        diag_all[2:, 2:] = np.eye(2) * 8.0 / n
        fallback = [diag_all[np.ix_(list(idx), list(idx))] for idx in blocks]
        start = []
        for j, idx in enumerate(blocks):
            # The block's curvature where the warm-up ended (the marginal of b is far wider
            # along the a1-a2 ridge than b given the path): the proposal's starting shape.
            def f(u, idx=idx):
                v = th.copy()
                v[list(idx)] = u
                return log_post(v)

            step = np.sqrt(np.diag(fallback[j]) / 4.0)
            start.append(_laplace_cov(f, th[list(idx)], step, fallback[j]))
        scale = [2.38 / math.sqrt(len(idx)) for idx in blocks]
        props = [np.linalg.cholesky(c_) * scale[j] for j, c_ in enumerate(start)]
        hist = np.empty((max(burn, 1), 4))
        out_b = np.empty((kept, 2))
        out_tau = np.empty(kept)
        out_q = np.empty(kept)
        out_path = np.empty((kept, keep_idx.size))
        k = 0
        acc = 0
        for it in range(draws):
            check_stop(None)
            for j, idx in enumerate(blocks):
                cand = th.copy()
                cand[list(idx)] += props[j] @ gen.standard_normal(len(idx))
                lp_c = log_post(cand)
                if math.log(gen.random()) < lp_c - lp:
                    th, lp = cand, lp_c
                    acc += (it >= burn) and j == 0
            if it < burn:
                hist[it] = th
                if it >= 60 and it % 30 == 0:
                    recent = hist[it // 2 : it + 1]
                    for j, idx in enumerate(blocks):
                        emp = np.cov(recent[:, list(idx)].T)
                        mix = 0.9 * emp + 0.1 * start[j] / 4.0
                        try:
                            props[j] = np.linalg.cholesky(mix) * scale[j]
                        except np.linalg.LinAlgError:
                            pass
            if it >= burn and (it - burn) % thin == 0:
                out_b[k] = th[:2]
                out_tau[k], out_q[k] = math.exp(th[2]), math.exp(th[3])
                # the level's path given this draw: FFBS, only for the kept draws
                if k % path_every == 0:
                    gen.standard_normal(out=z)
                    _sweep(y, x1, x2, dt, w, th[0], th[1], math.exp(-th[2]), out_q[k], m0,
                           v0, z, path, m, p, h)  # fmt: skip
                out_path[k] = path[keep_idx]
                k += 1
            if progress is not None and c == 0:
                progress(1)
        return out_b, out_tau, out_q, out_path, acc / max(kept * thin, 1)

    res = run_chains(chain, chain_generators(settings.seed, chains), workers=settings.threads)
    return LevelChains(
        b=np.stack([r[0] for r in res]),
        tau=np.stack([r[1] for r in res]),
        q=np.stack([r[2] for r in res]),
        path=np.stack([r[3] for r in res]),
        keep_idx=keep_idx,
        acceptance=np.array([r[4] for r in res]),
    )
