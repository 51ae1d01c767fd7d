"""The AR(1) coefficient of a Gaussian noise series given its residuals (physics-free).

Noise ``e_k = rho e_k-1 + eps_k``, ``eps_k ~ N(0, 1/tau)``, stationary, in segments of
consecutive samples (the first of a segment drawn from the stationary law,
``N(0, 1 / (tau (1 - rho^2)))``). With a uniform prior on (-1, 1) the conditional of
``rho`` given the residuals is

    p(rho | e) ∝ exp(-tau/2 (a rho^2 - 2 b rho)) (1 - rho^2)^(S/2),

with ``b = sum e_k e_k-1``, ``a = sum e_k-1^2 - sum e_s^2`` (``k`` over the samples that
follow one in their segment, ``s`` over the segments' first samples) and ``S`` segments.
:func:`draw_rho` proposes from the Gaussian factor (truncated to (-1, 1), by inverse CDF)
and accepts with the ratio of the remaining factor: an independence Metropolis-Hastings
step that leaves the conditional invariant and is accepted nearly always (the factor
is flat where the residuals put ``rho`` unless ``|rho|`` nears 1).
"""

from __future__ import annotations

import math

import numpy as np
from scipy import special

__all__ = ["RHO_MAX", "ar_moments", "draw_rho", "residual_stats", "whitened"]

#: The proposal stays inside (-RHO_MAX, RHO_MAX): the stationary variance is finite.
RHO_MAX = 0.999


def draw_rho(
    stats: np.ndarray,
    tau: float,
    rho: float,
    rng: np.random.Generator,
    rho_max: float = RHO_MAX,
) -> tuple[float, bool]:
    """One step for ``rho``: ``stats = [b, sum e_k-1^2, sum e_s^2, S]``; (rho, moved).

    The prior is uniform on ``(-rho_max, rho_max)`` (a smaller ``rho_max`` keeps the noise
    from a random walk, whose stationary variance a short record cannot place).
    """
    b, a_ns, a_st, segments = (float(v) for v in stats)
    a = a_ns - a_st
    if not (a > 0 and tau > 0):
        return rho, False
    m, sd = b / a, 1.0 / math.sqrt(tau * a)
    lo, hi = special.ndtr((-rho_max - m) / sd), special.ndtr((rho_max - m) / sd)
    if not hi > lo:
        return rho, False
    w = rng.uniform(lo, hi)
    cand = float(np.clip(m + sd * special.ndtri(w), -rho_max, rho_max))
    log_ratio = 0.5 * segments * (math.log1p(-cand * cand) - math.log1p(-rho * rho))
    if log_ratio >= 0 or rng.uniform() < math.exp(log_ratio):
        return cand, True
    return rho, False


def ar_moments(
    z: np.ndarray, y: np.ndarray, first: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The sums that make a channel's whitened sums a closed form in ``rho``.

    ``z`` (n, k) the design, ``y`` (n,) the target, ``first`` (n,) True on each segment's
    first row. Over the rows ``k`` that follow another in their segment,
    ``A = sum z_k z_k'``, ``Bs = sum z_k z_k-1' + z_k-1 z_k'``, ``C = sum z_k-1 z_k-1'``,
    and ``F = sum z_s z_s'`` over the segments' first rows ``s``; the same for ``z'y``
    (``Bs = sum z_k y_k-1 + z_k-1 y_k``) and ``y'y``. Returns ``zz`` (4, k, k), ``zy``
    (4, k), ``yy`` (4,), each stacked ``A, Bs, C, F`` (:func:`whitened` reads them).
    """
    z = np.asarray(z, dtype=float)
    y = np.asarray(y, dtype=float)
    first = np.asarray(first, dtype=bool).copy()
    if first.size:
        first[0] = True
    nxt = np.flatnonzero(~first)
    zk, zl, yk, yl = z[nxt], z[nxt - 1], y[nxt], y[nxt - 1]
    zs, ys = z[first], y[first]
    bzz = zk.T @ zl
    zz = np.stack([zk.T @ zk, bzz + bzz.T, zl.T @ zl, zs.T @ zs])
    zy = np.stack([zk.T @ yk, zk.T @ yl + zl.T @ yk, zl.T @ yl, zs.T @ ys])
    yy = np.array([yk @ yk, 2.0 * (yk @ yl), yl @ yl, ys @ ys])
    return zz, zy, yy


def whitened(m: np.ndarray, rho: float) -> np.ndarray:
    """Prais-Winsten whitened sums from :func:`ar_moments`' stack ``m`` (4, ...).

    ``A - rho Bs + rho^2 C + (1 - rho^2) F``: the sums of the rows ``z_k - rho z_k-1``
    and each segment's first row scaled by ``sqrt(1 - rho^2)``; a new ``rho`` needs no
    new design.
    """
    r2 = rho * rho
    return m[0] - rho * m[1] + r2 * m[2] + (1.0 - r2) * m[3]


def residual_stats(
    zz: np.ndarray, zy: np.ndarray, yy: np.ndarray, beta: np.ndarray, segments: float
) -> np.ndarray:
    """:func:`draw_rho`'s ``stats`` from :func:`ar_moments`' sums and coefficients ``beta``.

    ``[sum e_k e_k-1, sum e_k-1^2, sum e_s^2, S]`` of the residuals ``e = y - z beta``.
    """
    b = np.asarray(beta, dtype=float)
    quad = yy - 2.0 * (zy @ b) + np.einsum("mij,i,j->m", zz, b, b)  # A, Bs, C, F
    return np.array([0.5 * quad[1], quad[2], quad[3], float(segments)])
