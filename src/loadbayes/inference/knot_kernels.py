"""The compiled kernels of :mod:`loadbayes.inference.knots`: sums, factor, draw, level.

The sums (:func:`sums`) are one pass over the samples; the rest work on the knots only.
The precision of (knots, profile) is a band of width 2 (the integrated walk's second
differences, and an AR(1) row that spans three knots) bordered by the profile's
columns: factored as the band's Cholesky, then the border's Schur complement (dense,
``inference/linalg.py``'s Cholesky).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from loadbayes.inference.linalg import cholesky, solve_lower, solve_upper

__all__ = ["EPS", "draw_theta", "factor", "level", "sums"]

#: Diffuse prior precision of the first knots and the profile, in units of 1 / sigma^2.
EPS = 1e-14


@njit(cache=True, nogil=True)
def sums(yt, x1, x2, sw, k, lam, ptype, phase, ps, link, rho, nk, nh, m):  # pragma: no cover
    """The sums every evaluation needs, in one pass over the samples.

    ``sum_t row_c row_c'`` for the six pairs of (1, x1, x2) (band, border, profile
    blocks) and ``sum_t row_c target``; an AR(1) row is built from two samples.
    """
    gb = np.zeros((nk, 3, 6))  # knot-major: factor reads one knot's sums together
    guf = np.zeros((nk, m, 6))
    gff = np.zeros((6, m, m))
    r = np.zeros((3, nk + m))
    yy = 0.0
    rows = 0
    v = np.zeros((3, 3 + m))
    s0 = math.sqrt(max(1.0 - rho * rho, 0.0))
    pa = (0, 0, 0, 1, 1, 2)
    pb = (0, 1, 2, 1, 2, 2)
    for t in range(yt.size):
        v[:] = 0.0
        if link[t]:
            base = k[t - 1]
            srcs = ((t, 1.0), (t - 1, -rho))
            target = yt[t] - rho * yt[t - 1]
        else:
            base = k[t]
            srcs = ((t, s0), (t, 0.0))
            target = s0 * yt[t]
        for si in range(2):
            s, a = srcs[si]
            if a == 0.0:
                continue
            g = (1.0, x1[s], x2[s])
            off = k[s] - base
            for c in range(3):
                f = a * sw[s] * g[c]
                v[c, off] += f * (1.0 - lam[s])
                v[c, off + 1] += f * lam[s]
                if ptype[s] >= 0:
                    col = 3 + ptype[s] * 2 * nh
                    fp = f * ps[s]
                    for j in range(nh):
                        ang = 2.0 * math.pi * (j + 1) * phase[s]
                        v[c, col + 2 * j] += fp * math.cos(ang)
                        v[c, col + 2 * j + 1] += fp * math.sin(ang)
        for p in range(6):
            ca, cb = pa[p], pb[p]
            two = ca != cb
            for d in range(3):
                for i in range(3 - d):
                    e = v[ca, i + d] * v[cb, i]
                    if two:
                        e += v[cb, i + d] * v[ca, i]
                    if base + i + d < nk:
                        gb[base + i, d, p] += e
            for i in range(3):
                if base + i >= nk:
                    continue
                for j in range(m):
                    e = v[ca, i] * v[cb, 3 + j]
                    if two:
                        e += v[cb, i] * v[ca, 3 + j]
                    guf[base + i, j, p] += e
            for i in range(m):
                for j in range(m):
                    e = v[ca, 3 + i] * v[cb, 3 + j]
                    if two:
                        e += v[cb, 3 + i] * v[ca, 3 + j]
                    gff[p, i, j] += e
        for c in range(3):
            for i in range(3):
                if base + i < nk:
                    r[c, base + i] += v[c, i] * target
            for j in range(m):
                r[c, nk + j] += v[c, 3 + j] * target
        yy += target * target
        rows += 1
    return gb, guf, gff, r, yy, rows


@njit(cache=True, nogil=True)
def factor(gb, guf, gff, r, q0b, qs, b1, b2, lb, y, ls, sr):  # pragma: no cover
    """Factor the precision of (knots, profile) at (b1, b2); returns (ok, log det, r'M^-1 r).

    ``q0b`` (3, nk) is the walk's precision band at kappa = 1 (the diffuse start in it),
    ``qs`` = 1 / kappa. The banded block is factored in ``lb`` (lower band storage), ``y``
    (nk, m + 1) gets ``L^-1 [C | r_u]``, ``ls`` the Schur complement's factor and ``sr``
    its right-hand side.
    """
    nk = gb.shape[0]
    m = gff.shape[1]
    co = (1.0, b1, b2, b1 * b1, b1 * b2, b2 * b2)
    logdet = 0.0
    quad = 0.0
    s = np.zeros((m, m))
    sr[:] = 0.0
    for i in range(nk):
        # the band of M at row i: the data and the walk's prior
        d0 = qs * q0b[0, i]
        b1i = qs * q0b[1, i - 1] if i > 0 else 0.0
        b2i = qs * q0b[2, i - 2] if i > 1 else 0.0
        for p in range(6):
            d0 += co[p] * gb[i, 0, p]
            if i > 0:
                b1i += co[p] * gb[i - 1, 1, p]
            if i > 1:
                b2i += co[p] * gb[i - 2, 2, p]
        l2 = b2i / lb[0, i - 2] if i > 1 else 0.0
        l1 = (b1i - (l2 * lb[1, i - 2] if i > 1 else 0.0)) / lb[0, i - 1] if i > 0 else 0.0
        dd = d0 - l2 * l2 - l1 * l1
        if not dd > 0.0:
            return False, 0.0, 0.0
        lb[0, i] = math.sqrt(dd)
        if i > 0:
            lb[1, i - 1] = l1
        if i > 1:
            lb[2, i - 2] = l2
        logdet += 2.0 * math.log(lb[0, i])
        for j in range(m + 1):
            if j < m:
                rhs = 0.0
                for p in range(6):
                    rhs += co[p] * guf[i, j, p]
            else:
                rhs = r[0, i] + b1 * r[1, i] + b2 * r[2, i]
            if i > 0:
                rhs -= l1 * y[i - 1, j]
            if i > 1:
                rhs -= l2 * y[i - 2, j]
            y[i, j] = rhs / lb[0, i]
        for a in range(m):
            ya = y[i, a]
            for c in range(a + 1):
                s[a, c] += ya * y[i, c]
            sr[a] += ya * y[i, m]
        quad += y[i, m] * y[i, m]
    for a in range(m):
        for c in range(a + 1):
            full = EPS if a == c else 0.0
            for p in range(6):
                full += co[p] * gff[p, a, c]
            s[a, c] = full - s[a, c]
        sr[a] = r[0, nk + a] + b1 * r[1, nk + a] + b2 * r[2, nk + a] - sr[a]
    if m > 0:
        if not cholesky(s, ls):
            return False, 0.0, 0.0
        w = np.empty(m)
        solve_lower(ls, sr, w)
        for a in range(m):
            logdet += 2.0 * math.log(ls[a, a])
            quad += w[a] * w[a]
    return True, logdet, quad


@njit(cache=True, nogil=True)
def draw_theta(lb, y, ls, sr, sigma, z):  # pragma: no cover - compiled
    """Theta ~ N(M^-1 r, sigma^2 M^-1) from :func:`factor`'s pieces; ``z`` standard normals."""
    nk, m = y.shape[0], y.shape[1] - 1
    th = np.empty(nk + m)
    if m > 0:
        w = np.empty(m)
        solve_lower(ls, sr, w)
        for a in range(m):
            w[a] += sigma * z[nk + a]
        solve_upper(ls, w, w)
        th[nk:] = w
    for i in range(nk - 1, -1, -1):
        rhs = y[i, m] + sigma * z[i]
        for a in range(m):
            rhs -= y[i, a] * th[nk + a]
        if i + 1 < nk:
            rhs -= lb[1, i] * th[i + 1]
        if i + 2 < nk:
            rhs -= lb[2, i] * th[i + 2]
        th[i] = rhs / lb[0, i]
    return th


@njit(cache=True, nogil=True)
def level(theta, k, lam, ptype, phase, ps, nk, nh):  # pragma: no cover - compiled
    """The level L_t at the given samples (``ps``: the profile's scale there)."""
    out = np.empty(k.size)
    for t in range(k.size):
        lv = (1.0 - lam[t]) * theta[k[t]] + lam[t] * theta[k[t] + 1]
        if ptype[t] >= 0:
            col = nk + ptype[t] * 2 * nh
            for j in range(nh):
                ang = 2.0 * math.pi * (j + 1) * phase[t]
                lv += ps[t] * (
                    theta[col + 2 * j] * math.cos(ang) + theta[col + 2 * j + 1] * math.sin(ang)
                )
        out[t] = lv
    return out
