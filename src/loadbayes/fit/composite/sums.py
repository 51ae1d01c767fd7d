"""The composite design's sufficient sums, with the motor-free part computed once.

The linear block of docs/composite.md has, per sample, the design rows
``zp = [x^2, x, 1, 0, 0, 0, a]`` and ``zq = [0, 0, 0, x^2, x, 1, b]`` with
``a = p_m / p_m(0)`` and ``b = (q_m - q_m(0) x^2) / p_m(0)``. Of the sums ``Z'Z``, ``Z'y``
and ``y'y`` only the ones involving ``a`` or ``b`` change with the motor: ten running
sums per sample instead of the ~200 products of the full 7 x 7 outer products, which at
960 samples/s cost as much as the ODE itself. The rest (powers of ``x``, ``x^k p``,
``x^k q``, ``p^2``, ``q^2``) is computed once per event by :func:`x_sums`.

``a`` and ``b`` are formed per sample (not expanded into sums of ``q_m x^2`` etc.): ``b``
is the small difference of two O(1) terms, and expanding ``sum b^2`` would cancel.
The result equals the direct sums to rounding (tests/unit/test_composite_speed.py).
"""

from __future__ import annotations

import math

import numba
import numpy as np

__all__ = [
    "ar_residual_sums",
    "ar_sums_into",
    "design_sums",
    "design_sums_into",
    "weighted_sums",
    "x_sums",
]


@numba.njit(cache=True, nogil=True)
def x_sums(x, p, q):  # pragma: no cover - compiled
    """Motor-free sums: ``[S0..S4, sum p x^{2,1,0}, sum q x^{2,1,0}, sum p^2, sum q^2]``."""
    out = np.zeros(13)
    for i in range(x.size):
        xi = x[i]
        pw = 1.0
        for k in range(5):
            out[k] += pw
            pw *= xi
        x2 = xi * xi
        out[5] += p[i] * x2
        out[6] += p[i] * xi
        out[7] += p[i]
        out[8] += q[i] * x2
        out[9] += q[i] * xi
        out[10] += q[i]
        out[11] += p[i] * p[i]
        out[12] += q[i] * q[i]
    return out


@numba.njit(cache=True, nogil=True)
def design_sums_into(x, pm, qm, p, q, xs, ztz, zty, yty):  # pragma: no cover - compiled
    """:func:`design_sums` from the motor-free sums ``xs`` (:func:`x_sums`), in place.

    ``ztz`` (2, 7, 7), ``zty`` (2, 7), ``yty`` (2,) are overwritten.
    """
    pm0, qm0 = pm[0], qm[0]
    sa = np.zeros(5)  # sum a x^2, a x, a, a^2, a p
    sb = np.zeros(5)  # sum b x^2, b x, b, b^2, b q
    for i in range(x.size):
        xi = x[i]
        x2 = xi * xi
        a = pm[i] / pm0
        b = (qm[i] - qm0 * x2) / pm0
        sa[0] += a * x2
        sa[1] += a * xi
        sa[2] += a
        sa[3] += a * a
        sa[4] += a * p[i]
        sb[0] += b * x2
        sb[1] += b * xi
        sb[2] += b
        sb[3] += b * b
        sb[4] += b * q[i]
    ztz[:] = 0.0
    zty[:] = 0.0
    # The voltage block [x^2, x, 1] x [x^2, x, 1]: S4 S3 S2 / S3 S2 S1 / S2 S1 S0.
    for g in range(2):
        off = 3 * g
        for r in range(3):
            for c in range(3):
                ztz[g, off + r, off + c] = xs[4 - r - c]
            zty[g, off + r] = xs[5 + 3 * g + r]
    for r in range(3):
        ztz[0, r, 6] = sa[r]
        ztz[0, 6, r] = sa[r]
        ztz[1, 3 + r, 6] = sb[r]
        ztz[1, 6, 3 + r] = sb[r]
    ztz[0, 6, 6] = sa[3]
    ztz[1, 6, 6] = sb[3]
    zty[0, 6] = sa[4]
    zty[1, 6] = sb[4]
    yty[0] = xs[11]
    yty[1] = xs[12]


def design_sums(
    x: np.ndarray, pm: np.ndarray, qm: np.ndarray, p: np.ndarray, q: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``Z'Z`` (2, 7, 7), ``Z'y`` (2, 7), ``y'y`` (2,) of one event's P and Q designs."""
    ztz, zty, yty = np.zeros((2, 7, 7)), np.zeros((2, 7)), np.zeros(2)
    design_sums_into(x, pm, qm, p, q, x_sums(x, p, q), ztz, zty, yty)
    return ztz, zty, yty


@numba.njit(cache=True, nogil=True)
def weighted_sums(x, pm, qm, p, q, wp, wq):  # pragma: no cover - compiled
    """``Z'WZ``, ``Z'Wy``, ``y'Wy`` of the two designs, each sample weighted (Student-t).

    The full products, sample by sample (the weights change every iteration, so no part
    is computed once); weights of 1 give :func:`design_sums` to rounding.
    """
    ztz = np.zeros((2, 7, 7))
    zty = np.zeros((2, 7))
    yty = np.zeros(2)
    pm0, qm0 = pm[0], qm[0]
    zp = np.zeros(7)
    zq = np.zeros(7)
    for i in range(x.size):
        x2 = x[i] * x[i]
        zp[0], zp[1], zp[2], zp[6] = x2, x[i], 1.0, pm[i] / pm0
        zq[3], zq[4], zq[5], zq[6] = x2, x[i], 1.0, (qm[i] - qm0 * x2) / pm0
        for a in range(7):
            zty[0, a] += wp[i] * zp[a] * p[i]
            zty[1, a] += wq[i] * zq[a] * q[i]
            for b in range(7):
                ztz[0, a, b] += wp[i] * zp[a] * zp[b]
                ztz[1, a, b] += wq[i] * zq[a] * zq[b]
        yty[0] += wp[i] * p[i] * p[i]
        yty[1] += wq[i] * q[i] * q[i]
    return ztz, zty, yty


@numba.njit(cache=True, nogil=True)
def ar_sums_into(x, pm, qm, p, q, seg, rho, ztz, zty, yty):  # pragma: no cover - compiled
    """The two designs' sums after AR(1) whitening, in place (Prais-Winsten).

    Each sample's row and target become ``z_k - rho z_k-1`` and ``y_k - rho y_k-1``;
    the first sample of a segment (``seg`` True: an event's first, or the first after
    samples left out) is scaled by ``sqrt(1 - rho^2)`` instead. ``rho`` (2,): P, Q.
    """
    ztz[:] = 0.0
    zty[:] = 0.0
    yty[:] = 0.0
    pm0, qm0 = pm[0], qm[0]
    zp, zq = np.zeros(7), np.zeros(7)
    lp, lq = np.zeros(7), np.zeros(7)  # the previous sample's rows
    wp, wq = np.zeros(7), np.zeros(7)
    yp_prev, yq_prev = 0.0, 0.0
    sp, sq = math.sqrt(1.0 - rho[0] * rho[0]), math.sqrt(1.0 - rho[1] * rho[1])
    for i in range(x.size):
        x2 = x[i] * x[i]
        zp[0], zp[1], zp[2], zp[6] = x2, x[i], 1.0, pm[i] / pm0
        zq[3], zq[4], zq[5], zq[6] = x2, x[i], 1.0, (qm[i] - qm0 * x2) / pm0
        if seg[i]:
            for a in range(7):
                wp[a], wq[a] = sp * zp[a], sq * zq[a]
            yp, yq = sp * p[i], sq * q[i]
        else:
            for a in range(7):
                wp[a] = zp[a] - rho[0] * lp[a]
                wq[a] = zq[a] - rho[1] * lq[a]
            yp, yq = p[i] - rho[0] * yp_prev, q[i] - rho[1] * yq_prev
        for a in range(7):
            zty[0, a] += wp[a] * yp
            zty[1, a] += wq[a] * yq
            for b in range(7):
                ztz[0, a, b] += wp[a] * wp[b]
                ztz[1, a, b] += wq[a] * wq[b]
        yty[0] += yp * yp
        yty[1] += yq * yq
        for a in range(7):
            lp[a], lq[a] = zp[a], zq[a]
        yp_prev, yq_prev = p[i], q[i]


@numba.njit(cache=True, nogil=True)
def ar_residual_sums(x, pm, qm, p, q, seg, beta):  # pragma: no cover - compiled
    """What the AR(1) coefficient's conditional needs from one event's residuals.

    Per channel (rows P, Q): ``[sum e_k e_k-1, sum e_k-1^2, sum e_s^2, segments]`` over
    the samples that follow one in their segment (``k``) and the segments' first
    samples (``s``).
    """
    out = np.zeros((2, 4))
    pm0, qm0 = pm[0], qm[0]
    ep_prev, eq_prev = 0.0, 0.0
    for i in range(x.size):
        x2 = x[i] * x[i]
        fp = beta[0] * x2 + beta[1] * x[i] + beta[2] + beta[6] * pm[i] / pm0
        fq = beta[3] * x2 + beta[4] * x[i] + beta[5] + beta[6] * (qm[i] - qm0 * x2) / pm0
        ep, eq = p[i] - fp, q[i] - fq
        if seg[i]:
            out[0, 2] += ep * ep
            out[1, 2] += eq * eq
            out[0, 3] += 1.0
            out[1, 3] += 1.0
        else:
            out[0, 0] += ep * ep_prev
            out[1, 0] += eq * eq_prev
            out[0, 1] += ep_prev * ep_prev
            out[1, 1] += eq_prev * eq_prev
        ep_prev, eq_prev = ep, eq
    return out
