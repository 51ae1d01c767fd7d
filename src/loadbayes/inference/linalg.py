"""Small dense linear algebra for the compiled samplers: the one Cholesky they all use.

Every conjugate step of a Gibbs sampler draws ``x ~ N(lam^-1 h, lam^-1)`` from a
precision ``lam`` and a linear term ``h``, on matrices of a few rows, many times per
iteration. LAPACK's call overhead is larger than the work there, so the kernels
factorise by hand; these are the functions they share (they were six copies).

The loops fix the floating-point order of every sum (``k`` ascending), so the draws are
the same bits wherever they are called from. Only the lower triangles of ``a`` and
``lo`` are read or written.

The functions are inlined into their callers (``inline="always"``: a call per bus cost
the fleet's sweep 40 %). numba's cache keys a kernel on its own file only, so after
editing this module delete the callers' cached ``*.nbi``/``*.nbc`` files.
"""

from __future__ import annotations

import math

from numba import njit

__all__ = ["cholesky", "precision_draw", "solve_lower", "solve_upper"]


@njit(cache=True, nogil=True, inline="always")
def cholesky(a, lo):  # pragma: no cover - compiled
    """Lower Cholesky factor ``a = lo lo'`` from the lower triangle of ``a``.

    ``lo`` may be ``a`` itself (factorised in place); its upper triangle is left alone.
    Returns False at the first pivot that is not > 0 (not positive definite, or NaN);
    ``lo`` is then incomplete.
    """
    k = a.shape[0]
    for j in range(k):
        s = a[j, j]
        for p in range(j):
            s -= lo[j, p] * lo[j, p]
        if not s > 0.0:
            return False
        lo[j, j] = math.sqrt(s)
        for i in range(j + 1, k):
            s = a[i, j]
            for p in range(j):
                s -= lo[i, p] * lo[j, p]
            lo[i, j] = s / lo[j, j]
    return True


@njit(cache=True, nogil=True, inline="always")
def solve_lower(lo, b, out):  # pragma: no cover - compiled
    """``out = lo^-1 b`` by forward substitution (``out`` may be ``b``)."""
    k = b.shape[0]
    for i in range(k):
        s = b[i]
        for p in range(i):
            s -= lo[i, p] * out[p]
        out[i] = s / lo[i, i]


@njit(cache=True, nogil=True, inline="always")
def solve_upper(lo, b, out):  # pragma: no cover - compiled
    """``out = lo'^-1 b`` by back substitution (``out`` may be ``b``)."""
    k = b.shape[0]
    for i in range(k - 1, -1, -1):
        s = b[i]
        for p in range(i + 1, k):
            s -= lo[p, i] * out[p]
        out[i] = s / lo[i, i]


@njit(cache=True, nogil=True, inline="always")
def precision_draw(lam, h, z, lo, w, out):  # pragma: no cover - compiled
    """``out ~ N(lam^-1 h, lam^-1)`` from the standard normals ``z``.

    ``out = lo'^-1 (lo^-1 h + z)`` with ``lam = lo lo'``: mean ``lam^-1 h``, covariance
    ``lo'^-1 lo^-1 = lam^-1``. ``lo`` (k, k) and ``w`` (k,) are workspaces (``lo`` may
    be ``lam``, factorised in place). Returns False, ``out`` untouched, when ``lam`` is
    not positive definite.
    """
    if not cholesky(lam, lo):
        return False
    solve_lower(lo, h, w)
    for i in range(h.shape[0]):
        w[i] += z[i]
    solve_upper(lo, w, out)
    return True
