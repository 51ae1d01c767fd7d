"""Compiled loops over buses of the pooled model's Gibbs sweep (see :mod:`.hierarchical`).

Each works on small dense matrices per bus (``d`` = 2 or 4) without allocating inside
the loop, so a sweep costs about a microsecond per bus.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from loadbayes.inference.linalg import cholesky, precision_draw, solve_lower, solve_upper

__all__ = ["_bus_sweep", "_class_sums", "_mu_terms"]

_TAU_FLOOR = 1e-100  # a gamma draw can underflow to 0; keep the precision positive


@njit(cache=True, nogil=True)
def _bus_sweep(
    cls, ztz, ztr, ssr_min, theta_ls, sig_inv, sig_inv_mu, rate0, tau, theta, z, g
):  # pragma: no cover - compiled
    """Steps 2 and 3 of the sweep for every bus: theta_b given mu, Sigma, tau_b, then tau_b.

    ``z`` holds standard normals and ``g`` standard gammas of shape ``a0 + n_b / 2``.
    """
    nb = theta.shape[0]
    d = theta.shape[1]
    nch = tau.shape[1]
    lm = np.empty((d, d))
    h = np.empty(d)
    w = np.empty(d)
    for b in range(nb):
        c = cls[b]
        for i in range(d):
            h[i] = sig_inv_mu[c, i]
            for j in range(d):
                lm[i, j] = sig_inv[c, i, j]
        for ch in range(nch):
            t = tau[b, ch]
            for i in range(2):
                h[2 * ch + i] += t * ztr[b, ch, i]
                for j in range(2):
                    lm[2 * ch + i, 2 * ch + j] += t * ztz[b, i, j]
        # theta = R'^-1 (R^-1 h + z) with lm = R R' (factorised in place): mean L^-1 h,
        # covariance L^-1; NaN if lm is not positive definite (as a failed factor gives)
        if not precision_draw(lm, h, z[b], lm, w, theta[b]):
            theta[b, :] = np.nan
        for ch in range(nch):
            e0 = theta[b, 2 * ch] - theta_ls[b, ch, 0]
            e1 = theta[b, 2 * ch + 1] - theta_ls[b, ch, 1]
            q = ztz[b, 0, 0] * e0 * e0 + 2.0 * ztz[b, 0, 1] * e0 * e1 + ztz[b, 1, 1] * e1 * e1
            ssr = ssr_min[b, ch] + max(q, 0.0)
            tau[b, ch] = max(g[b, ch] / (rate0 + 0.5 * ssr), _TAU_FLOOR)


@njit(cache=True, nogil=True)
def _mu_terms(cls, ztz, ztr, tau, sig_inv, prec, lin):  # pragma: no cover - compiled
    """Per class: the precision and linear term of ``mu_c | Sigma_c, tau, data``.

    With ``theta_b`` integrated out, bus ``b`` adds ``Sigma^-1 - Sigma^-1 L_b^-1
    Sigma^-1`` to the precision and ``Sigma^-1 L_b^-1 u_b`` to the linear term, where
    ``L_b = Sigma^-1 + J_b``, ``J_b = diag_ch(tau_ch Z'Z)`` and ``u_b = (tau_ch Z'r_ch)``.
    """
    d = sig_inv.shape[1]
    nch = tau.shape[1]
    prec[:] = 0.0
    lin[:] = 0.0
    lm = np.empty((d, d))
    inv = np.empty((d, d))
    u = np.empty(d)
    e = np.empty(d)
    col = np.empty(d)
    mrow = np.empty(d)
    for b in range(cls.shape[0]):
        c = cls[b]
        for i in range(d):
            for j in range(d):
                lm[i, j] = sig_inv[c, i, j]
        for ch in range(nch):
            t = tau[b, ch]
            for i in range(2):
                u[2 * ch + i] = t * ztr[b, ch, i]
                for j in range(2):
                    lm[2 * ch + i, 2 * ch + j] += t * ztz[b, i, j]
        # inv = L^-1, column by column from the Cholesky factor (in place in lm); NaN if
        # L is not positive definite (as a failed factor gives)
        if cholesky(lm, lm):
            for j in range(d):
                for i in range(d):
                    e[i] = 1.0 if i == j else 0.0
                solve_lower(lm, e, col)
                solve_upper(lm, col, col)
                for i in range(d):
                    inv[i, j] = col[i]
        else:
            inv[:] = np.nan
        # prec += S^-1 - M S^-1, lin += M u, with M = S^-1 A (S^-1 = sig_inv[c], A = inv)
        for i in range(d):
            for k in range(d):
                acc = 0.0
                for j in range(d):
                    acc += sig_inv[c, i, j] * inv[j, k]
                mrow[k] = acc
            acc = 0.0
            for k in range(d):
                acc += mrow[k] * u[k]
            lin[c, i] += acc
            for j in range(d):
                acc = 0.0
                for k in range(d):
                    acc += mrow[k] * sig_inv[c, k, j]
                prec[c, i, j] += sig_inv[c, i, j] - acc


@njit(cache=True, nogil=True)
def _class_sums(cls, theta, mu, nc, sums, scatter):  # pragma: no cover - compiled
    """Per class: the sum of theta_b, and the scatter of theta_b about ``mu`` (if given)."""
    d = theta.shape[1]
    sums[:] = 0.0
    scatter[:] = 0.0
    for b in range(theta.shape[0]):
        c = cls[b]
        for i in range(d):
            sums[c, i] += theta[b, i]
            di = theta[b, i] - mu[c, i]
            for j in range(d):
                scatter[c, i, j] += di * (theta[b, j] - mu[c, j])
