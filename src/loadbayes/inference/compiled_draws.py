"""The linear block's draws, compiled: what a compiled chain loop draws after its u-move.

:func:`draw_beta_positive` is :func:`loadbayes.inference.condlinear.draw_beta` with a
truncated coordinate, and :func:`draw_gammas` is :func:`~loadbayes.inference.condlinear.
draw_tau`, each callable from a compiled loop with the chain's own
:class:`numpy.random.Generator`. The same draws, bit for bit
(``tests/unit/test_compiled_chain.py``):

- numba's methods of a :class:`numpy.random.Generator` are NumPy's algorithms, and draw
  from the chain's generator, whose state they advance in place;
- the arithmetic is :mod:`~loadbayes.inference.condlinear`'s own compiled functions
  (``_moments``, ``_given_one``), in its order;
- the truncated coordinate's normal CDF and its inverse are SciPy's own (its
  ``cython_special`` ``ndtr`` and ``ndtri``, the functions behind ``scipy.special``'s),
  linked by name so that numba's on-disk cache holds (a ctypes pointer would not).

One path differs: where rounding leaves the conditional covariance of the other
coordinates semi-definite (Cholesky fails), the fallback's eigendecomposition is numba's
LAPACK call, not NumPy's; its draw is as exact, its last bits may differ.
"""

from __future__ import annotations

import math

import llvmlite.binding as llvm
import numba
import numpy as np
from numba import types
from numba.extending import get_cython_function_address

from loadbayes.inference.condlinear import _given_one, _moments, conditional_one

__all__ = ["draw_beta_positive", "draw_gammas", "draw_rho_one", "ndtr", "ndtri"]

# SciPy's ndtr (double: the second of its fused versions) and ndtri, both
# ``double f(double, int skip_dispatch)``, registered under names of our own.
llvm.add_symbol(
    "loadbayes_ndtr",
    get_cython_function_address("scipy.special.cython_special", "__pyx_fuse_1ndtr"),
)
llvm.add_symbol("loadbayes_ndtri",
                get_cython_function_address("scipy.special.cython_special", "ndtri"))  # fmt: skip
_ndtr = types.ExternalFunction("loadbayes_ndtr", types.float64(types.float64, types.intc))
_ndtri = types.ExternalFunction("loadbayes_ndtri", types.float64(types.float64, types.intc))


@numba.njit(cache=True, nogil=True)
def ndtr(x):  # pragma: no cover - compiled
    """``scipy.special.ndtr`` of a float, compiled (the same function)."""
    return _ndtr(x, 0)


@numba.njit(cache=True, nogil=True)
def ndtri(p):  # pragma: no cover - compiled
    """``scipy.special.ndtri`` of a float, compiled (the same function)."""
    return _ndtri(p, 0)


@numba.njit(cache=True, nogil=True)
def _truncated_standard(a, rng):  # pragma: no cover - compiled
    # condlinear._truncated_standard: Z ~ N(0, 1) given Z > a.
    upper = _ndtr(-a, 0)
    if upper > 1e-300:
        u = upper * rng.random()
        return -_ndtri(max(u, 1e-300), 0)
    return a + rng.exponential(1.0 / a)


@numba.njit(cache=True, nogil=True)
def _semidefinite(mu, cov, j, bj, z):  # pragma: no cover - compiled
    # condlinear.draw_beta's fallback: the others given coordinate j by eigh.
    rest, mean_r, cov_r = conditional_one(mu, cov, j, bj)
    w, v = np.linalg.eigh((cov_r + cov_r.T) / 2)
    out = np.empty(mu.size)
    out[j] = bj
    out[rest] = mean_r + v @ (np.sqrt(np.maximum(w, 0.0)) * z)
    return out


@numba.njit(cache=True, nogil=True)
def draw_beta_positive(ztz, zty, tau, m0, p0, positive, rng):  # pragma: no cover
    """``condlinear.draw_beta(..., positive=positive)`` on arrays, compiled: the same draw."""
    mu, cov, _, _ = _moments(ztz, zty, tau, m0, p0)
    j = positive
    sd = math.sqrt(cov[j, j])
    bj = mu[j] + sd * _truncated_standard(-mu[j] / sd, rng)
    z = rng.standard_normal(mu.size - 1)
    try:
        return _given_one(mu, cov, j, bj, z)
    except Exception:  # rounding made it semi-definite
        return _semidefinite(mu, cov, j, bj, z)


@numba.njit(cache=True, nogil=True)
def draw_gammas(shape, n, rate, ssr, rng):  # pragma: no cover - compiled
    """``condlinear.draw_tau``: each ``Gamma(shape + n_g / 2, rate + ssr_g / 2)``, in turn."""
    out = np.empty(n.size)
    for g in range(n.size):
        out[g] = rng.gamma(shape + 0.5 * n[g], 1.0 / (rate + 0.5 * ssr[g]))
    return out


@numba.njit(cache=True, nogil=True)
def draw_rho_one(stats, tau, rho, rng, rho_max):  # pragma: no cover - compiled
    """:func:`loadbayes.inference.ar1.draw_rho` compiled: the same step and draws."""
    b, a_ns, a_st, segments = stats[0], stats[1], stats[2], stats[3]
    a = a_ns - a_st
    if not (a > 0 and tau > 0):
        return rho
    m, sd = b / a, 1.0 / math.sqrt(tau * a)
    lo, hi = _ndtr((-rho_max - m) / sd, 0), _ndtr((rho_max - m) / sd, 0)
    if not hi > lo:
        return rho
    w = rng.uniform(lo, hi)
    cand = min(max(m + sd * _ndtri(w, 0), -rho_max), rho_max)
    log_ratio = 0.5 * segments * (math.log1p(-cand * cand) - math.log1p(-rho * rho))
    if log_ratio >= 0 or rng.uniform(0.0, 1.0) < math.exp(log_ratio):
        return cand
    return rho
