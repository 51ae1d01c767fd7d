"""A level at knots plus a daily profile, times a regression, with AR(1) noise: through sums.

The model of one channel (no physics here: ``x1``, ``x2`` are any two regressors)::

    y_t = L_t (1 + b1 x1_t + b2 x2_t) + e_t
    L_t = (1 - l_t) u_k + l_t u_{k+1} + sum_j f_j(t) c_j      (t between knots k and k+1)
    u_{k+1} = u_k + N(0, sigma^2 kappa D_k w_k)                (a random walk at the knots)
    e_t / s_t = rho e_{t-1} / s_{t-1} + N(0, sigma^2),        s_t^2 = w_t (a known scale)

``f_j`` are the harmonics of the time of day, one set per day type (weekday, weekend):
the mean daily profile, so that the walk follows only what the profile does not, and a
daily cycle of the regressors cannot stand in for the load's (issue 39: a year whose
voltage had its own daily cycle gave dP/dV 7.55 for 1.15 with a walk at every sample).
The knots are coarser than the samples on a long record (an hour on a year at 1 min):
given (b, rho), every sample enters through sums over the knots, so one evaluation of
the posterior costs O(knots x harmonics^2), not O(samples). The residuals' AR(1)
coefficient ``rho`` is estimated once, at the mode of a white-noise fit (a plug-in: at
the records this is for its sd is below 0.01), so that what the knots cannot follow
within an hour is not counted as independent samples.

Given (b, kappa) the knot values and the profile (``theta``) are Gaussian with a banded
precision (bandwidth 2) bordered by the profile's columns, and ``sigma^2`` is
inverse-Gamma: both are integrated out exactly. Metropolis moves (b1, b2, log kappa) on
that marginal, its proposal started from the curvature at the mode and adapted in the
burn-in. ``sigma^2`` and ``theta`` are drawn for the kept draws.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from loadbayes.core.parallel import chain_generators, check_stop, run_chains
from loadbayes.core.settings import SamplerSettings
from loadbayes.inference.knot_kernels import EPS, draw_theta, factor, level, sums

__all__ = ["KnotChains", "KnotDesign", "knot_design", "sample_knot_level"]


@dataclass
class KnotDesign:
    """Where each sample sits, and the knots.

    Its left knot ``k``, the weight ``lam`` of the right one, its profile type (-1:
    none), its time of day as a fraction, whether it follows the sample before (the AR(1)
    link); the knots' spacing (s).
    """

    k: np.ndarray
    lam: np.ndarray
    ptype: np.ndarray
    phase: np.ndarray
    link: np.ndarray
    spacing: np.ndarray
    n_knots: int
    harmonics: int
    types: int


def knot_design(t, *, spacing_s, harmonics, weekend=None, gap_factor=1.5) -> KnotDesign:
    """Knots every ``spacing_s`` seconds from ``t[0]``; ``harmonics`` per day type.

    ``weekend`` (bool per sample) splits the profile in two types; None: one type.
    A sample follows the one before it (the AR(1) link) when the step is at most
    ``gap_factor`` times the median step and the two share or neighbour a knot.
    """
    t = np.asarray(t, dtype=float)
    pos = (t - t[0]) / spacing_s
    k = np.floor(pos).astype(np.int64)
    lam = pos - k
    n_knots = int(k[-1]) + 2
    types = 0 if harmonics == 0 else (1 if weekend is None else 2)
    ptype = np.full(t.size, -1, np.int64) if types == 0 else (
        np.zeros(t.size, np.int64) if types == 1 else np.asarray(weekend, np.int64))  # fmt: skip
    dt = np.diff(t)
    med = float(np.median(dt)) if dt.size else 1.0
    link = np.r_[False, (dt <= gap_factor * med) & (np.diff(k) <= 1)]
    spacing = np.full(n_knots - 1, float(spacing_s))
    return KnotDesign(k, lam, ptype, (t / 86_400.0) % 1.0, link, spacing, n_knots, harmonics,
                      types)  # fmt: skip


def walk_band(dw: np.ndarray, order: int) -> np.ndarray:
    """The walk's prior precision at kappa = 1 in lower band storage (3, nk).

    ``order`` 1: ``u_{k+1} - u_k ~ N(0, dw_k)``; 2: ``u_{k+2} - 2 u_{k+1} + u_k ~ N(0,
    dw_k)`` (an integrated walk: a level that bends but does not jump). The first
    ``order`` knots get the diffuse precision :data:`EPS`.
    """
    nk = dw.size + 1
    band = np.zeros((3, nk))
    band[0, :order] += EPS
    if order == 1:
        lam = 1.0 / dw
        band[0, :-1] += lam
        band[0, 1:] += lam
        band[1, :-1] -= lam
        return band
    lam = 1.0 / dw[: nk - 2]
    coef = np.array([1.0, -2.0, 1.0])
    for i in range(3):
        for j in range(i + 1):
            band[i - j, j : j + nk - 2] += lam * coef[i] * coef[j]
    return band


class _Marginal:
    """log p(b, log kappa | y) with theta and sigma^2 integrated out, for one rho."""

    def __init__(
        self, yt, x1, x2, sw, ps, des: KnotDesign, rho, wk, b_mean, b_sd, kappa_floor, order
    ):
        m = 2 * des.harmonics * des.types
        self.m, self.nk = m, des.n_knots
        self.gb, self.guf, self.gff, self.r, self.yy, self.rows = sums(
            yt, x1, x2, sw, des.k, des.lam, des.ptype, des.phase, ps, des.link, float(rho),
            des.n_knots, des.harmonics, m)  # fmt: skip
        # the walk's variance per knot step over sigma^2 kappa: an integrated walk's
        # second difference grows with the spacing cubed (its unit: per second)
        dw = des.spacing ** (2 * order - 1) * wk
        self.q0b = walk_band(dw, order)
        self.free = self.nk - order  # the walk's steps
        self.log_dw = float(np.sum(np.log(dw[: self.free])))
        self.b_mean, self.b_sd, self.floor = np.asarray(b_mean), np.asarray(b_sd), kappa_floor
        # The prior's terms as plain floats: the density is evaluated a few thousand times
        # a fit, where NumPy's per-call cost on two-element arrays was most of its Python.
        self._prior = (*np.asarray(b_mean, float).tolist(), *np.asarray(b_sd, float).tolist())

    def work(self):
        return (np.zeros((3, self.nk)), np.zeros((self.nk, self.m + 1)),
                np.zeros((self.m, self.m)), np.zeros(self.m))  # fmt: skip

    def __call__(self, th, work) -> tuple[float, float]:
        """(log posterior, sum of squares) at th = (b1, b2, log kappa)."""
        b1, b2, lk = th.tolist() if type(th) is np.ndarray else th
        if not -80.0 < lk < 40.0:
            return -np.inf, np.nan
        kappa = math.exp(lk)
        lb, y, ls, sr = work
        ok, logdet, quad = factor(self.gb, self.guf, self.gff, self.r, self.q0b, 1.0 / kappa,
                                   b1, b2, lb, y, ls, sr)  # fmt: skip
        if not ok:
            return -np.inf, np.nan
        ssr = max(self.yy - quad, 1e-300)
        lp = -0.5 * (self.free * lk + self.log_dw) - 0.5 * logdet
        lp -= 0.5 * self.rows * math.log(ssr)  # sigma^2 integrated out (p ~ 1 / sigma^2)
        lp -= self.floor / kappa + 1e-3 * lk  # weak, proper at kappa -> 0
        m1, m2, s1, s2 = self._prior
        z1, z2 = (b1 - m1) / s1, (b2 - m2) / s2
        lp -= 0.5 * (z1 * z1 + z2 * z2)  # NumPy's sum of the two squares, to the bit
        return lp, ssr


def _mode(f, start, scale=None):
    """The maximum of ``f`` by Nelder-Mead from ``start``.

    ``scale`` (a Cholesky factor of a covariance near the answer's) makes the search run
    in the coordinates it whitens, from a simplex one sd wide. Why: a1 and a2 lie on a
    narrow ridge (2 a1 + a2 is known far better than either), which the simplex crawls
    along in the raw coordinates (measured on a year at 1 min: 5,181 evaluations, 10 s,
    and stopped by the iteration limit before the mode; 321 whitened).
    """
    from scipy.optimize import minimize

    start = np.asarray(start, float)
    if scale is None:
        res = minimize(lambda u: -f(u), start, method="Nelder-Mead",
                       options={"xatol": 1e-6, "fatol": 1e-6, "maxiter": 2000})  # fmt: skip
        return res.x if np.isfinite(res.fun) else start
    d = start.size
    simplex = np.vstack([np.zeros(d), np.eye(d)])
    res = minimize(lambda s: -f(start + scale @ s), np.zeros(d), method="Nelder-Mead",
                   options={"xatol": 1e-4, "fatol": 1e-6, "maxiter": 2000,
                            "initial_simplex": simplex})  # fmt: skip
    return start + scale @ res.x if np.isfinite(res.fun) else start


@dataclass
class KnotChains:
    """Draws of one channel, and what was held.

    b (chain, draw, 2), tau = 1 / sigma^2, q = sigma^2 kappa (the walk's variance per
    second at unit scale), the level at ``keep_idx`` (chain, draw, k); the residuals'
    AR(1) coefficient ``rho`` (fixed) and the knots' spacing (s).
    """

    b: np.ndarray
    tau: np.ndarray
    q: np.ndarray
    path: np.ndarray
    keep_idx: np.ndarray
    acceptance: np.ndarray
    rho: float
    spacing_s: float
    harmonics: int
    types: int


def sample_knot_level(
    y: np.ndarray,
    x1: np.ndarray,
    x2: np.ndarray,
    t: np.ndarray,
    w: np.ndarray,
    design: KnotDesign,
    *,
    settings: SamplerSettings,
    b_mean: Sequence[float] = (0.0, 0.0),
    b_sd: Sequence[float] = (10.0, 10.0),
    keep_points: int = 500,
    path_draws: int = 200,
    ar1: bool = True,
    order: int = 2,
    profile_scale: np.ndarray | None = None,
    progress: Callable[[int], None] | None = None,
) -> KnotChains:
    """Draws of ``y_t = L_t (1 + b1 x1_t + b2 x2_t) + e_t``; see the module notes.

    ``w`` (n) is the known scale squared of the noise and of the walk (mean about 1);
    ``profile_scale`` (n) multiplies the daily profile (a season's amplitude: the profile
    is then relative to the load's daily mean), ones when not given.
    """
    chains, draws, burn, thin = settings.chains, settings.draws, settings.burn, settings.thin
    y, x1, x2, t, w = (np.ascontiguousarray(a, dtype=float) for a in (y, x1, x2, t, w))
    n = y.size
    if n < 4:
        raise ValueError(f"{n} samples: too few for a drifting level")
    if np.any(np.diff(t) <= 0):
        raise ValueError("time steps must be positive")
    sw = 1.0 / np.sqrt(w)
    yt = y * sw
    knot_t = t[0] + np.arange(design.n_knots - 1) * design.spacing + design.spacing / 2
    wk = np.interp(knot_t, t, w)
    floor = 1e-8 / max(float(t[-1] - t[0]), 1.0)
    ps = np.ones(n) if profile_scale is None else np.ascontiguousarray(profile_scale, float)
    args = (yt, x1, x2, sw, ps, design)
    white = _Marginal(*args, 0.0, wk, b_mean, b_sd, floor, order)
    work = white.work()
    k0 = math.log(max(float(np.var(np.diff(yt))), 1e-300) / max(float(np.var(yt)), 1e-300)
                  / float(design.spacing.mean()) ** (2 * order - 1))  # fmt: skip
    mode = _mode(lambda u: white(u, work)[0], np.array([0.0, 0.0, k0]))
    rho = 0.0
    if ar1 and n > 20:
        # the residuals at the white fit's mode: their lag-1 coefficient, over linked rows
        _, ssr = white(mode, work)
        lb, yw, ls, sr = work
        theta = draw_theta(lb, yw, ls, sr, 0.0, np.zeros(white.nk + white.m))
        lev = level(theta, design.k, design.lam, design.ptype, design.phase, ps, white.nk,
                     design.harmonics)  # fmt: skip
        e = (y - lev * (1.0 + mode[0] * x1 + mode[1] * x2)) * sw
        ln = design.link
        rho = float(np.clip(np.sum(e[1:][ln[1:]] * e[:-1][ln[1:]])
                            / max(np.sum(e[:-1][ln[1:]] ** 2), 1e-300), -0.95, 0.99))  # fmt: skip
    post = _Marginal(*args, rho, wk, b_mean, b_sd, floor, order) if rho != 0.0 else white
    white_work, work = work, post.work()
    if rho != 0.0:  # from the white fit's mode, in the coordinates its curvature whitens
        shape = _curvature(lambda u: white(u, white_work)[0], mode)
        # (when the curvature there is not a covariance, the raw search: measured on a
        # day at 1 s, whitening by the diagonal guess led to a point whose curvature
        # failed too, and the chains' ESS fell from 454 to 156)
        usable = not np.array_equal(shape, _GUESS)
        mode = _mode(lambda u: post(u, work)[0], mode,
                     np.linalg.cholesky(shape) if usable else None)  # fmt: skip
    cov = _curvature(lambda u: post(u, work)[0], mode)
    kept = len(range(burn, draws, thin))
    path_every = max(1, kept // max(path_draws, 1))
    keep_idx = np.unique(np.linspace(0, n - 1, min(keep_points, n)).astype(np.int64))
    dk = (design.k[keep_idx], design.lam[keep_idx], design.ptype[keep_idx],
          design.phase[keep_idx], ps[keep_idx])  # fmt: skip

    def chain(c: int, gen: np.random.Generator):
        wk_ = post.work()
        chol = np.linalg.cholesky(cov)
        th = mode + chol @ gen.standard_normal(3)
        lp, ssr = post(th, wk_)
        if not np.isfinite(lp):
            th = mode.copy()
            lp, ssr = post(th, wk_)
        prop = chol * (2.38 / math.sqrt(3))
        hist = np.empty((max(burn, 1), 3))
        out = np.empty((kept, 3))
        out_tau = np.empty(kept)
        out_path = np.empty((kept, keep_idx.size))
        path = np.zeros(keep_idx.size)
        acc, k = 0, 0
        for it in range(draws):
            check_stop(None)
            cand = th + prop @ gen.standard_normal(3)
            lp_c, ssr_c = post(cand, wk_)
            if math.log(gen.random()) < lp_c - lp:
                th, lp, ssr = cand, lp_c, ssr_c
                acc += it >= burn
            if it < burn:
                hist[it] = th
                if it >= 60 and it % 30 == 0:
                    emp = np.cov(hist[it // 2 : it + 1].T)
                    try:
                        prop = np.linalg.cholesky(0.9 * emp + 0.1 * cov) * (2.38 / math.sqrt(3))
                    except np.linalg.LinAlgError:
                        pass
            if it >= burn and (it - burn) % thin == 0:
                out[k] = th
                out_tau[k] = gen.gamma(post.rows / 2.0, 2.0 / ssr)
                if k % path_every == 0:
                    post(th, wk_)  # the factors at this draw
                    z = gen.standard_normal(post.nk + post.m)
                    theta = draw_theta(*wk_, 1.0 / math.sqrt(out_tau[k]), z)
                    path = level(theta, *dk, post.nk, design.harmonics)
                out_path[k] = path
                k += 1
            if progress is not None and c == 0:
                progress(1)
        return out, out_tau, out_path, acc / max(kept * thin, 1)

    res = run_chains(chain, chain_generators(settings.seed, chains), workers=settings.threads)
    th = np.stack([r[0] for r in res])
    tau = np.stack([r[1] for r in res])
    return KnotChains(
        b=th[..., :2], tau=tau, q=np.exp(th[..., 2]) / tau, path=np.stack([r[2] for r in res]),
        keep_idx=keep_idx, acceptance=np.array([r[3] for r in res]), rho=rho,
        spacing_s=float(design.spacing.mean()), harmonics=design.harmonics, types=design.types,
    )  # fmt: skip


def _curvature(f, x):
    """Minus the inverse Hessian of ``f`` at ``x`` (finite differences).

    A diagonal guess when it is not positive definite.
    """
    from loadbayes.inference.ffbs import _laplace_cov

    step = np.array([1e-3, 1e-3, 1e-2])
    return _laplace_cov(f, x, step, _GUESS)


#: The diagonal covariance taken when the curvature at a mode is not one.
_GUESS = np.diag([1e-4, 1e-4, 0.1])
