"""A linear-Gaussian block seen through its sufficient sums, with groups of own precision.

The model (no physics here): ``y_g = Z_g beta + e_g``, ``e_g ~ N(0, 1/tau_g)`` for groups
``g = 1..G`` sharing one coefficient vector ``beta`` (k,), with the prior
``beta ~ N(m0, diag(1/p0))``, optionally truncated to ``beta_j > 0`` for one index ``j``
(a positive coefficient), and ``tau_g ~ Gamma(shape, rate)``.

Given ``tau``, ``beta`` is integrated out in closed form (:func:`log_marginal`): with
``A = diag(p0) + sum_g tau_g Z_g'Z_g``, ``h = p0 m0 + sum_g tau_g Z_g'y_g``,
``mu = A^-1 h``::

    log p(y | tau) = sum_g (n_g/2 log(tau_g / 2 pi) - tau_g y_g'y_g / 2)
                     + (sum log p0 - m0'diag(p0) m0 + h'mu - log|A|) / 2
                     + log Phi(mu_j / sd_j) - log Phi(m0_j sqrt(p0_j))     (truncation)

with ``sd_j^2 = (A^-1)_jj``. :func:`draw_beta` draws ``beta | tau, y`` exactly (the
truncated coordinate first, then the rest given it) and :func:`draw_tau` the gammas.
A Metropolis move on parameters that change the ``Z_g`` uses :func:`log_marginal` (a
collapsed step, which mixes far better along ridges than a step with ``beta`` fixed).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numba
import numpy as np
from scipy import special

__all__ = [
    "GroupSums",
    "conditional_one",
    "draw_beta",
    "draw_betas",
    "draw_tau",
    "log_marginal",
    "moments_arrays",
    "posterior_moments",
    "residual_ss",
    "residual_ss_arrays",
]

_LOG_2PI = math.log(2.0 * math.pi)


@dataclass(frozen=True)
class GroupSums:
    """Sufficient sums of each group: ``Z'Z`` (G, k, k), ``Z'y`` (G, k), ``y'y`` (G,), n (G,)."""

    ztz: np.ndarray
    zty: np.ndarray
    yty: np.ndarray
    n: np.ndarray

    @classmethod
    def from_arrays(cls, zs: list[np.ndarray], ys: list[np.ndarray]) -> GroupSums:
        """Sums of each group's design ``Z_g`` (n_g, k) and target ``y_g`` (n_g,)."""
        return cls(
            np.stack([z.T @ z for z in zs]),
            np.stack([z.T @ y for z, y in zip(zs, ys, strict=True)]),
            np.array([float(y @ y) for y in ys]),
            np.array([float(y.size) for y in ys]),
        )


@numba.njit(cache=True, nogil=True)
def _moments(ztz, zty, tau, m0, p0):  # pragma: no cover - compiled
    k = m0.size
    a = np.zeros((k, k))
    h = p0 * m0
    for g in range(tau.size):
        a += tau[g] * ztz[g]
        h = h + tau[g] * zty[g]
    for i in range(k):
        a[i, i] += p0[i]
    chol = np.linalg.cholesky(a)
    inv_l = np.linalg.inv(chol)
    cov = inv_l.T @ inv_l
    mu = cov @ h
    logdet = 0.0
    for i in range(k):
        logdet += 2.0 * np.log(chol[i, i])
    return mu, cov, h, logdet


#: :func:`posterior_moments` on raw arrays ``(ztz, zty, tau, m0, p0)``, compiled: for
#: other kernels to call (fit/composite/bounded_kernel.py).
moments_arrays = _moments


def posterior_moments(
    sums: GroupSums, tau: np.ndarray, m0: np.ndarray, p0: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
    """``(mu, cov, h, log|A|)`` of the untruncated conditional ``beta | tau, y``.

    Raises ``numpy.linalg.LinAlgError`` when ``A`` is not positive definite.
    """
    # Compiled: k is small, so NumPy's per-call overhead would dominate the sampler.
    return _moments(
        sums.ztz,
        sums.zty,
        np.asarray(tau, dtype=float),
        np.asarray(m0, float),
        np.asarray(p0, float),
    )


@numba.njit(cache=True, nogil=True)
def log_ndtr(z):  # pragma: no cover - compiled
    """``log Phi(z)`` (standard normal CDF), accurate far into the lower tail."""
    if z > -30.0:
        return math.log(0.5 * math.erfc(-z / math.sqrt(2.0)))
    # Asymptotic series of the Mills ratio: Phi(z) ~ phi(z) / -z (1 - 1/z^2 + 3/z^4).
    z2 = z * z
    return -0.5 * z2 - math.log(-z) - 0.5 * _LOG_2PI + math.log1p(-1.0 / z2 + 3.0 / (z2 * z2))


@numba.njit(cache=True, nogil=True)
def log_marginal_arrays(ztz, zty, yty, n, tau, m0, p0, positive):  # pragma: no cover
    """:func:`log_marginal` on raw arrays (``positive < 0`` for none); compiled."""
    mu, cov, h, logdet = _moments(ztz, zty, tau, m0, p0)
    out = 0.0
    for g in range(tau.size):
        out += 0.5 * n[g] * (math.log(tau[g]) - _LOG_2PI) - 0.5 * tau[g] * yty[g]
    out += 0.5 * (np.sum(np.log(p0)) - np.sum(p0 * m0 * m0) + np.sum(h * mu) - logdet)
    if positive >= 0:
        sd = math.sqrt(cov[positive, positive])
        out += log_ndtr(mu[positive] / sd) - log_ndtr(m0[positive] * math.sqrt(p0[positive]))
    return out


def log_marginal(
    sums: GroupSums,
    tau: np.ndarray,
    m0: np.ndarray,
    p0: np.ndarray,
    *,
    positive: int | None = None,
) -> float:
    """``log p(y | tau)`` with ``beta`` integrated out (module docstring).

    Returns ``-inf`` when ``A`` is not positive definite (numerically singular design).
    """
    try:
        return float(
            log_marginal_arrays(
                sums.ztz,
                sums.zty,
                sums.yty,
                sums.n,
                np.asarray(tau, dtype=float),
                np.asarray(m0, dtype=float),
                np.asarray(p0, dtype=float),
                -1 if positive is None else int(positive),
            )
        )
    except np.linalg.LinAlgError:
        return -math.inf


def _truncated_standard(a: float, rng: np.random.Generator) -> float:
    """One draw of ``Z ~ N(0, 1)`` given ``Z > a`` (inverse CDF on the upper tail)."""
    upper = float(special.ndtr(-a))
    if upper > 1e-300:
        u = upper * rng.random()  # rng.uniform(0.0, upper)'s number (0 + upper d), cheaper
        return float(-special.ndtri(max(u, 1e-300)))
    # Far in the tail: the exponential approximation of the truncated normal is exact
    # to O(1/a^2) there, and only reached when the data contradict positivity entirely.
    return a + rng.exponential(1.0 / a)


def draw_beta(
    sums: GroupSums,
    tau: np.ndarray,
    m0: np.ndarray,
    p0: np.ndarray,
    rng: np.random.Generator,
    *,
    positive: int | None = None,
) -> np.ndarray:
    """One exact draw of ``beta | tau, y`` (truncated to ``beta_j > 0`` if ``positive``)."""
    mu, cov, _, _ = _moments(sums.ztz, sums.zty, np.asarray(tau, dtype=float),
                             np.asarray(m0, float), np.asarray(p0, float))  # fmt: skip
    k = mu.size
    if positive is None:
        return mu + np.linalg.cholesky(cov) @ rng.standard_normal(k)
    j = positive
    sd = math.sqrt(cov[j, j])
    bj = mu[j] + sd * _truncated_standard(-mu[j] / sd, rng)
    z = rng.standard_normal(k - 1)
    try:
        return _given_one(mu, cov, j, bj, z)
    except np.linalg.LinAlgError:  # rounding made it semi-definite: fall back to eigh
        rest = [i for i in range(k) if i != j]
        c_rj = cov[rest, j]
        mean_r = mu[rest] + c_rj / cov[j, j] * (bj - mu[j])
        cov_r = cov[np.ix_(rest, rest)] - np.outer(c_rj, c_rj) / cov[j, j]
        out = np.empty(k)
        out[j] = bj
        w, v = np.linalg.eigh((cov_r + cov_r.T) / 2)
        out[rest] = mean_r + v @ (np.sqrt(np.clip(w, 0.0, None)) * z)
        return out


@numba.njit(cache=True, nogil=True)
def conditional_one(mu, cov, j, bj):  # pragma: no cover - compiled
    """The other coordinates of ``N(mu, cov)`` given coordinate ``j = bj``, compiled.

    Returns ``(rest, mean, cov)``: their indices, and the conditional's mean and covariance
    (:func:`draw_beta`'s and its compiled fallback's one arithmetic).
    """
    k = mu.size
    m = k - 1
    rest = np.empty(m, dtype=np.int64)
    r = 0
    for i in range(k):
        if i != j:
            rest[r] = i
            r += 1
    cjj = cov[j, j]
    mean_r = np.empty(m)
    cov_r = np.empty((m, m))
    for a in range(m):
        ca = cov[rest[a], j]
        mean_r[a] = mu[rest[a]] + ca / cjj * (bj - mu[j])
        for b in range(m):
            cov_r[a, b] = cov[rest[a], rest[b]] - ca * cov[rest[b], j] / cjj
    return rest, mean_r, cov_r


@numba.njit(cache=True, nogil=True)
def _given_one(mu, cov, j, bj, z):  # pragma: no cover - compiled
    # The other coordinates of N(mu, cov) given coordinate j = bj, drawn with the
    # standard normals z (k - 1): mean and covariance of the conditional, its Cholesky
    # factor (numpy.linalg.LinAlgError when rounding made it semi-definite). Compiled:
    # k is 7, where NumPy's fancy indexing cost more than the arithmetic (issue 21).
    k = mu.size
    m = k - 1
    rest, mean_r, cov_r = conditional_one(mu, cov, j, bj)
    chol = np.linalg.cholesky(cov_r)
    out = np.empty(k)
    out[j] = bj
    for a in range(m):
        acc = mean_r[a]
        for b in range(a + 1):
            acc += chol[a, b] * z[b]
        out[rest[a]] = acc
    return out


def residual_ss(sums: GroupSums, beta: np.ndarray) -> np.ndarray:
    """Each group's sum of squared residuals ``|y_g - Z_g beta|^2`` from the sums."""
    return _residual_ss(sums.ztz, sums.zty, sums.yty, np.asarray(beta, dtype=float))


@numba.njit(cache=True, nogil=True)
def _residual_ss(ztz, zty, yty, beta):  # pragma: no cover - compiled
    out = np.empty(yty.size)
    k = beta.size
    for g in range(yty.size):
        acc = yty[g]
        for i in range(k):
            acc -= 2.0 * zty[g, i] * beta[i]
            for j in range(k):
                acc += beta[i] * ztz[g, i, j] * beta[j]
        out[g] = max(acc, 0.0)
    return out


#: :func:`residual_ss` on raw arrays ``(ztz, zty, yty, beta)``, compiled: for other
#: kernels to call (fit/composite/chain_loop.py).
residual_ss_arrays = _residual_ss


def draw_tau(
    ssr: np.ndarray, n: np.ndarray, shape: float, rate: float, rng: np.random.Generator
) -> np.ndarray:
    """One draw of each ``tau_g | beta, y ~ Gamma(shape + n_g/2, rate + SSR_g/2)``.

    ``ssr`` and ``n`` may be summed over several independent blocks sharing the ``tau_g``.
    """
    # One scalar call per group: the same stream as one call with arrays, at a fraction
    # of its cost for the two groups of a sampler's every iteration.
    # The sampler's two float groups of one shape need no np.broadcast_arrays (its cost,
    # not its result, differs there).
    if not (type(n) is np.ndarray and type(ssr) is np.ndarray and n.ndim == 1
            and n.shape == ssr.shape and n.dtype == ssr.dtype == np.float64):  # fmt: skip
        n, ssr = np.broadcast_arrays(np.asarray(n, dtype=float), np.asarray(ssr, dtype=float))
    return np.array([
        rng.gamma(shape + 0.5 * ni, 1.0 / (rate + 0.5 * si))
        for ni, si in zip(n.ravel().tolist(), ssr.ravel().tolist(), strict=True)
    ]).reshape(n.shape)  # fmt: skip


def draw_betas(
    sums: GroupSums,
    tau: np.ndarray,
    m0: np.ndarray,
    p0: np.ndarray,
    rng: np.random.Generator,
    size: int,
    *,
    positive: int | None = None,
) -> np.ndarray:
    """``size`` independent exact draws of ``beta | tau, y`` (as :func:`draw_beta`), (size, k)."""
    mu, cov, _, _ = posterior_moments(sums, np.asarray(tau, dtype=float), m0, p0)
    k = mu.size
    z = rng.standard_normal((size, k))
    if positive is None:
        return mu + z @ np.linalg.cholesky(cov).T
    j = positive
    sd = math.sqrt(cov[j, j])
    a = -mu[j] / sd
    upper = special.ndtr(-a)
    if upper > 1e-300:
        w = rng.uniform(0.0, upper, size)
        bj = mu[j] + sd * -special.ndtri(np.maximum(w, 1e-300))
    else:
        bj = mu[j] + sd * (a + rng.exponential(1.0 / a, size))
    rest = [i for i in range(k) if i != j]
    c_rj = cov[rest, j]
    cov_r = cov[np.ix_(rest, rest)] - np.outer(c_rj, c_rj) / cov[j, j]
    w_, v_ = np.linalg.eigh((cov_r + cov_r.T) / 2)
    root = v_ * np.sqrt(np.clip(w_, 0.0, None))
    out = np.empty((size, k))
    out[:, j] = bj
    out[:, rest] = mu[rest] + np.outer(bj - mu[j], c_rj / cov[j, j]) + z[:, : k - 1] @ root.T
    return out
