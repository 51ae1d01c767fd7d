"""The bounded shares' density and share-only steps, compiled (``fit/composite/bounded.py``).

With ``shares="bounded"`` every iteration takes ``SHARE_STEPS`` Metropolis steps of each
event's four share log-ratios given the motor (``sampler._Gibbs._share_steps``). In Python
each step was a dozen NumPy calls on 3 x 3 arrays and SciPy's Owen's T: the bounded fit
cost 5.6 times the plain one per iteration. Here the same arithmetic runs in one compiled
call per iteration:

- :func:`event_term`: one event's share prior (Dirichlet(1, 1, 1) in log-ratio
  coordinates and any normal prior on a share) plus its evidence with ``gamma``
  integrated out over the positive quadrant (``bounded.log_evidence``), its 3 x 3
  moments written out (:func:`gamma_moments`);
- Owen's T, ``ndtr``, ``log_ndtr`` and ``ndtri`` are SciPy's own compiled functions
  (``scipy.special.cython_special``), called through their C addresses;
- :func:`share_steps`: the random-walk steps, drawing from the chain's generator in
  the order the Python loop drew (numba's ``Generator`` methods are NumPy's, on the same
  bit generator), so the stream of random numbers is unchanged; a step moves one event,
  so its ratio is that event's term alone (the motor's prior and the other events
  cancel);
- :func:`draw_gamma_one`: the sampler's exact draw of an event's coefficients
  (``bounded.draw_gamma`` with one draw), the same arithmetic and draws, bit for bit.
"""

from __future__ import annotations

import math

import llvmlite.binding as llvm
import numba
import numpy as np
from numba.extending import get_cython_function_address

__all__ = ["bounded_terms", "draw_gamma_one", "event_term", "gamma_moments", "owens_t",
           "share_steps", "shares_one", "stacked"]  # fmt: skip

_LOG_2PI = math.log(2.0 * math.pi)
_P_ZIP, _Q0, _P_M0 = 0, 1, 2
_SHARE_ACCEPT = 0.3


def _special(name: str, n_args: int):
    # A cpdef function of scipy.special.cython_special, double (double..., int skip),
    # declared to LLVM under its own symbol: the kernels call it by name, so they cache
    # (a ctypes pointer would be an address baked into the cached code).
    symbol = f"loadbayes_scipy_{name}"
    llvm.add_symbol(symbol, get_cython_function_address("scipy.special.cython_special", name))
    f64 = numba.types.float64
    return numba.types.ExternalFunction(symbol, f64(*(f64,) * n_args, numba.types.intc))


_owens_t = _special("owens_t", 2)
_ndtr = _special("__pyx_fuse_1ndtr", 1)  # the double version (fuse 0 is complex)
_log_ndtr = _special("__pyx_fuse_1log_ndtr", 1)
_ndtri = _special("ndtri", 1)
#: Rejection tries of the single coefficient draw (bounded._MAX_TRIES).
_MAX_TRIES = 10_000


@numba.njit(cache=True, nogil=True)
def owens_t(h, a):  # pragma: no cover - compiled
    """Owen's T(h, a): ``scipy.special.owens_t``, callable from compiled code."""
    return _owens_t(h, a, 0)


@numba.njit(cache=True, nogil=True)
def _log_quadrant(mu, cov):  # pragma: no cover - compiled
    # bounded._log_quadrant: log P(gamma_zip > 0, gamma_m > 0), Owen (1956).
    si, sj = math.sqrt(cov[_P_ZIP, _P_ZIP]), math.sqrt(cov[_P_M0, _P_M0])
    h, k = mu[_P_ZIP] / si, mu[_P_M0] / sj
    r = min(max(cov[_P_ZIP, _P_M0] / (si * sj), -0.999999), 0.999999)
    if abs(h) < 1e-12:
        h = 1e-12
    if abs(k) < 1e-12:
        k = 1e-12
    s = math.sqrt(1.0 - r * r)
    c = 0.0 if h * k > 0 else 0.5
    val = (
        0.5 * (_ndtr(h, 0) + _ndtr(k, 0))
        - _owens_t(h, (k - r * h) / (h * s), 0)
        - _owens_t(k, (h - r * k) / (k * s), 0)
        - c
    )
    if val > 1e-12:
        return math.log(val)
    return _log_ndtr(h, 0) + _log_ndtr(k, 0)


@numba.njit(cache=True, nogil=True)
def gamma_moments(a, ztz, zty, tau, p0_gamma):  # pragma: no cover - compiled
    """``(mu, cov, h, log|A|)`` of ``gamma | u, a, tau`` untruncated (``beta = T(a) gamma``).

    ``gamma``'s sums are ``T' Z'Z T`` and ``T' Z'y`` per channel (``bounded.transform``).
    Written out for the 3 x 3 case: ``T`` has one block of weights per column (``a[0:3]``
    on rows 0-2, ``a[3:6]`` on rows 3-5, 1 on row 6), so ``T' Z'Z T`` is nine weighted
    block sums, and ``A``'s Cholesky factor, its inverse and ``cov = L^-T L^-1`` are
    closed forms. Through NumPy's ``@``, ``cholesky`` and ``inv`` (BLAS and LAPACK calls
    on 3 x 3 arrays) this took 1.9 us of an event term's 2.5; it is the same arithmetic
    to rounding (``tests/unit/test_composite_bounded.py`` against the Python code).
    Raises ``numpy.linalg.LinAlgError`` when ``A`` is not positive definite.
    """
    w = np.empty(7)
    w[0:6] = a[0:6]
    w[6] = 1.0
    a_m = np.zeros((3, 3))
    h = np.zeros(3)
    for g in range(tau.size):
        for i in range(3):
            lo_i, hi_i = 3 * i, (3 * i + 3 if i < 2 else 7)
            s_y = 0.0
            for k in range(lo_i, hi_i):
                s_y += w[k] * zty[g, k]
            h[i] += tau[g] * s_y
            for j in range(i, 3):
                lo_j, hi_j = 3 * j, (3 * j + 3 if j < 2 else 7)
                s = 0.0
                for k in range(lo_i, hi_i):
                    r = 0.0
                    for m in range(lo_j, hi_j):
                        r += ztz[g, k, m] * w[m]
                    s += w[k] * r
                a_m[i, j] += tau[g] * s
    for i in range(3):
        a_m[i, i] += p0_gamma[i]
    # A = L L' and L^-1 (lower triangular), in closed form.
    d0 = a_m[0, 0]
    if not d0 > 0.0:
        raise np.linalg.LinAlgError("Matrix is not positive definite.")
    l00 = math.sqrt(d0)
    l10, l20 = a_m[0, 1] / l00, a_m[0, 2] / l00
    d1 = a_m[1, 1] - l10 * l10
    if not d1 > 0.0:
        raise np.linalg.LinAlgError("Matrix is not positive definite.")
    l11 = math.sqrt(d1)
    l21 = (a_m[1, 2] - l20 * l10) / l11
    d2 = a_m[2, 2] - l20 * l20 - l21 * l21
    if not d2 > 0.0:
        raise np.linalg.LinAlgError("Matrix is not positive definite.")
    l22 = math.sqrt(d2)
    m00, m11, m22 = 1.0 / l00, 1.0 / l11, 1.0 / l22
    m10 = -l10 * m00 * m11
    m21 = -l21 * m11 * m22
    m20 = -(l20 * m00 + l21 * m10) * m22
    cov = np.empty((3, 3))
    cov[0, 0] = m00 * m00 + m10 * m10 + m20 * m20
    cov[1, 1] = m11 * m11 + m21 * m21
    cov[2, 2] = m22 * m22
    cov[0, 1] = cov[1, 0] = m11 * m10 + m21 * m20
    cov[0, 2] = cov[2, 0] = m22 * m20
    cov[1, 2] = cov[2, 1] = m22 * m21
    mu = np.empty(3)
    for i in range(3):
        mu[i] = cov[i, 0] * h[0] + cov[i, 1] * h[1] + cov[i, 2] * h[2]
    logdet = 2.0 * (math.log(l00) + math.log(l11) + math.log(l22))
    return mu, cov, h, logdet


@numba.njit(cache=True, nogil=True)
def event_term(z, ztz, zty, yty, n, tau, p0_gamma, sp_i, sp_mean, sp_sd):  # pragma: no cover
    """One event's share prior plus ``bounded.log_evidence`` at log-ratios ``z`` (4,)."""
    a = np.empty(6)
    for c in range(2):  # bounded.shares_of: a softmax of (z1, z2, 0) per channel
        z1, z2 = z[2 * c], z[2 * c + 1]
        m = max(z1, z2, 0.0)
        e1, e2, e3 = math.exp(z1 - m), math.exp(z2 - m), math.exp(-m)
        tot = e1 + e2 + e3
        a[3 * c], a[3 * c + 1], a[3 * c + 2] = e1 / tot, e2 / tot, e3 / tot
    out = 0.0
    for i in range(6):  # Dirichlet(1, 1, 1) of both channels, Jacobian included
        out += math.log(max(a[i], 1e-300))
    for j in range(sp_i.size):
        out -= 0.5 * ((a[sp_i[j]] - sp_mean[j]) / sp_sd[j]) ** 2
    mu, cov, h, logdet = gamma_moments(a, ztz, zty, tau, p0_gamma)
    ev = 0.0
    for g in range(tau.size):  # condlinear.log_marginal_arrays with m0 = 0, no truncation
        ev += 0.5 * n[g] * (math.log(tau[g]) - _LOG_2PI) - 0.5 * tau[g] * yty[g]
    ev += 0.5 * (np.sum(np.log(p0_gamma)) + np.sum(h * mu) - logdet)
    return out + ev + _log_quadrant(mu, cov) - math.log(0.25)


@numba.njit(cache=True, nogil=True)
def bounded_terms(z, ztz, zty, yty, n, tau, p0_gamma, sp_i, sp_mean, sp_sd):  # pragma: no cover
    """Every event's :func:`event_term` summed; ``z`` (E, 4), the sums (E, G, ...)."""
    out = 0.0
    for e in range(z.shape[0]):
        out += event_term(z[e], ztz[e], zty[e], yty[e], n[e], tau, p0_gamma, sp_i, sp_mean,
                          sp_sd)  # fmt: skip
    return out


@numba.njit(cache=True, nogil=True)
def share_steps(z, ztz, zty, yty, n, tau, p0_gamma, sp_i, sp_mean, sp_sd, steps, rng,
                scale, adapting):  # pragma: no cover - compiled  # fmt: skip
    """``steps`` random-walk steps of each event's share log-ratios ``z`` (E, 4), in place.

    Step s of event e proposes ``z[e] + scale[e] * normal(4)`` and accepts when ``log
    uniform`` is below the change of the event's term; the four normals, then the
    uniform, come from ``rng`` (the chain's generator: numba draws from its bit
    generator as NumPy does, so the stream is the Python loop's ``rng.standard_normal(4)``
    then ``rng.uniform()``, step by step and event by event). ``scale`` (E,) adapts
    toward 30 % acceptance while ``adapting`` (the burn-in), in place.
    """
    n_ev = z.shape[0]
    cur = np.empty(n_ev)
    for e in range(n_ev):
        cur[e] = event_term(z[e], ztz[e], zty[e], yty[e], n[e], tau, p0_gamma, sp_i, sp_mean,
                            sp_sd)  # fmt: skip
    cand = np.empty(4)
    for _ in range(steps):
        for e in range(n_ev):
            for j in range(4):
                cand[j] = z[e, j] + scale[e] * rng.standard_normal()
            uniform = rng.uniform(0.0, 1.0)
            lc = event_term(cand, ztz[e], zty[e], yty[e], n[e], tau, p0_gamma, sp_i, sp_mean,
                            sp_sd)  # fmt: skip
            ok = math.log(uniform) < lc - cur[e]
            if ok:
                z[e, :] = cand
                cur[e] = lc
            if adapting:
                scale[e] *= math.exp(0.02 * ((1.0 if ok else 0.0) - _SHARE_ACCEPT))
    return z


@numba.njit(cache=True, nogil=True)
def draw_gamma_one(a, ztz, zty, tau, p0_gamma, rng):  # pragma: no cover - compiled
    """One exact draw of an event's ``beta`` (7,): ``bounded.draw_gamma`` with size 1.

    The same arithmetic and the same draws from ``rng`` in the same order: each
    rejection try a uniform on ``[lo, 1)`` then one on ``[0, 1)`` (the last try stands
    when none is accepted, far in a tail), then ``P_zip0``'s uniform and ``q0``'s normal.
    """
    mu, cov, _, _ = gamma_moments(a, ztz, zty, tau, p0_gamma)
    m = mu[_P_M0]
    sm = math.sqrt(cov[_P_M0, _P_M0])
    slope = cov[_P_ZIP, _P_M0] / cov[_P_M0, _P_M0]
    sz = math.sqrt(max(cov[_P_ZIP, _P_ZIP] - slope * cov[_P_ZIP, _P_M0], 1e-300))
    lo = _ndtr(-m / sm, 0)
    pm = m
    for _ in range(_MAX_TRIES):
        w = lo + (1.0 - lo) * rng.random()
        pm = m + sm * _ndtri(min(max(w, 1e-300), 1 - 1e-16), 0)
        mz = mu[_P_ZIP] + slope * (pm - m)
        if rng.random() < _ndtr(mz / sz, 0):
            break
    mz = mu[_P_ZIP] + slope * (pm - m)
    upper = _ndtr(mz / sz, 0)
    pz = mz + sz * -_ndtri(max(rng.uniform(0.0, 1.0) * upper, 1e-300), 0)
    # q0 given (P_zip0, P_m0): the 2 x 2 solve of draw_gamma.
    pair = np.empty((2, 2))
    pair[0, 0], pair[0, 1] = cov[_P_ZIP, _P_ZIP], cov[_P_ZIP, _P_M0]
    pair[1, 0], pair[1, 1] = cov[_P_M0, _P_ZIP], cov[_P_M0, _P_M0]
    c_q = np.array([cov[_Q0, _P_ZIP], cov[_Q0, _P_M0]])
    wq = np.linalg.solve(pair, c_q)
    mq = mu[_Q0] + ((pz - mu[_P_ZIP]) * wq[0] + (pm - m) * wq[1])
    vq = max(cov[_Q0, _Q0] - (wq[0] * c_q[0] + wq[1] * c_q[1]), 1e-300)
    q0 = mq + math.sqrt(vq) * rng.standard_normal()
    out = np.empty(7)
    for i in range(3):
        out[i] = pz * a[i]
        out[3 + i] = q0 * a[3 + i]
    out[6] = pm
    return out


@numba.njit(cache=True, nogil=True)
def shares_one(z):  # pragma: no cover - compiled
    """``bounded.shares_of`` of one event's log-ratios ``z`` (4,), compiled.

    NumPy's arithmetic in its order: the softmax of ``(z0, z1, 0)`` less its maximum, then
    of ``(z2, z3, 0)``; three terms summed left to right, as NumPy's sum of three does.
    """
    out = np.empty(6)
    for c in range(2):
        f0, f1, f2 = z[2 * c], z[2 * c + 1], 0.0
        top = max(max(f0, f1), f2)
        e0, e1, e2 = math.exp(f0 - top), math.exp(f1 - top), math.exp(f2 - top)
        total = (e0 + e1) + e2
        out[3 * c], out[3 * c + 1], out[3 * c + 2] = e0 / total, e1 / total, e2 / total
    return out


def stacked(groups) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The events' sums (``GroupSums`` each) as arrays (E, G, ...), for the kernels."""
    groups = list(groups)
    return (
        np.ascontiguousarray([g.ztz for g in groups], dtype=float),
        np.ascontiguousarray([g.zty for g in groups], dtype=float),
        np.ascontiguousarray([g.yty for g in groups], dtype=float),
        np.ascontiguousarray([g.n for g in groups], dtype=float),
    )
