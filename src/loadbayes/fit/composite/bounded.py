"""Static ZIP shares held in [0, 1]: the composite fit's ``shares="bounded"``.

With free shares each event's seven linear coefficients ``beta = (cp2, cp1, cp0, cq2,
cq1, cq0, P_m0)`` have a Gaussian prior and are integrated out. Holding the shares in
[0, 1] makes that prior a polytope-truncated Gaussian whose normaliser has no closed
form. So the bounded model moves the shares into the sampled vector and keeps the rest
linear:

    P = P_zip0 (a1 x^2 + a2 x + a3) + P_m0 m_p(t),   Q = q0 (a4 x^2 + a5 x + a6) + P_m0 m_q(t)

- each event's shares ``(a1, a2, a3)`` and ``(a4, a5, a6)`` have a **Dirichlet(1, 1, 1)**
  prior (uniform on the simplex: every share in [0, 1]), sampled in additive log-ratio
  coordinates ``(log(a1/a3), log(a2/a3), log(a4/a6), log(a5/a6))`` (four per event,
  after the steps' fractions in ``u``; the density there is ``prod a_i``, as for the
  torque shares, fit/composite/torque.py);
- given them, ``gamma = (P_zip0, q0, P_m0)`` is linear: ``beta = T(a) gamma``, so its
  sums are ``T' Z'Z T`` and ``T' Z'y`` of the seven-column sums the kernel already
  computes; ``gamma`` has the same weak prior, ``N(0, s^2)``, truncated to ``P_zip0 > 0``
  and ``P_m0 > 0`` (a load that draws power through both parts, ``0 < f_m < 1``), and is
  integrated out exactly: the Gaussian evidence plus the log-probability of the
  positive quadrant under the conditional (a bivariate normal CDF, Owen's T function)
  minus its prior value, log(1/4).
- ``gamma | u`` is drawn exactly: ``P_m0`` from its positive-truncated conditional,
  accepted with the probability that ``P_zip0 > 0`` given it (rejection: the accepted
  ``P_m0`` has the quadrant-truncated marginal), then ``P_zip0`` and ``q0`` given it.
  The draw is returned as the seven coefficients, so everything downstream (noise
  precisions, names, exports) is unchanged.

``q0`` keeps any sign (a load that exports reactive power): its shares still lie in [0, 1].
"""

from __future__ import annotations

import math

import numpy as np
from scipy import special

from loadbayes.fit.composite.bounded_kernel import gamma_moments
from loadbayes.inference.condlinear import log_marginal_arrays, posterior_moments

__all__ = [
    "SHARE_COORDS",
    "draw_gamma",
    "log_evidence",
    "log_prior_shares",
    "share_start",
    "shares_of",
    "transform",
]

#: Sampled coordinates per event: two log-ratios per channel.
SHARE_COORDS = 4
#: Indices in gamma of the two coefficients truncated to positive values.
_P_ZIP, _Q0, _P_M0 = 0, 1, 2
#: Rejection tries for the quadrant-truncated draw before the conditional fallback.
_MAX_TRIES = 10_000


def shares_of(z: np.ndarray) -> np.ndarray:
    """``(a1..a6)`` from one event's log-ratios ``z`` (4,); vectorised over leading axes."""
    z = np.asarray(z, dtype=float)
    out = []
    for zz in (z[..., 0:2], z[..., 2:4]):
        full = np.concatenate([zz, np.zeros(zz.shape[:-1] + (1,))], -1)
        e = np.exp(full - full.max(-1, keepdims=True))
        out.append(e / e.sum(-1, keepdims=True))
    return np.concatenate(out, -1)


def log_prior_shares(z: np.ndarray) -> float:
    """Dirichlet(1, 1, 1) of both channels in log-ratio coordinates (Jacobian included)."""
    a = shares_of(z)
    return float(np.sum(np.log(np.clip(a, 1e-300, None))))


def transform(a: np.ndarray) -> np.ndarray:
    """``T`` (7, 3) with ``beta = T gamma`` for shares ``a`` (6,)."""
    t = np.zeros((7, 3))
    t[0:3, _P_ZIP] = a[0:3]
    t[3:6, _Q0] = a[3:6]
    t[6, _P_M0] = 1.0
    return t


def _log_quadrant(mu: np.ndarray, cov: np.ndarray) -> float:
    # log P(g_i > 0, g_j > 0) of a Gaussian (i = P_zip0, j = P_m0): Owen (1956),
    # Phi2(h, k; r) = (Phi(h) + Phi(k)) / 2 - T(h, a_h) - T(k, a_k) - c.
    si, sj = math.sqrt(cov[_P_ZIP, _P_ZIP]), math.sqrt(cov[_P_M0, _P_M0])
    h, k = mu[_P_ZIP] / si, mu[_P_M0] / sj
    r = float(np.clip(cov[_P_ZIP, _P_M0] / (si * sj), -0.999999, 0.999999))
    if abs(h) < 1e-12:
        h = 1e-12
    if abs(k) < 1e-12:
        k = 1e-12
    s = math.sqrt(1.0 - r * r)
    c = 0.0 if h * k > 0 else 0.5
    val = (
        0.5 * (special.ndtr(h) + special.ndtr(k))
        - special.owens_t(h, (k - r * h) / (h * s))
        - special.owens_t(k, (h - r * k) / (k * s))
        - c
    )
    if val > 1e-12:
        return math.log(val)
    # Deep in the tail the formula cancels: the independent bound's logarithm there.
    return float(special.log_ndtr(h) + special.log_ndtr(k))


def log_evidence(ztz, zty, yty, n, tau, a, p0_gamma) -> float:
    """``log p(y | u, a, tau)`` of one event with ``gamma`` integrated out (quadrant)."""
    t = transform(a)
    zz = np.einsum("ji,gjk,kl->gil", t, ztz, t)
    zy = np.einsum("ji,gj->gi", t, zty)
    m0 = np.zeros(3)
    out = float(log_marginal_arrays(zz, zy, yty, n, tau, m0, p0_gamma, -1))
    mu, cov, _, _ = posterior_moments_3(zz, zy, tau, p0_gamma)
    return out + _log_quadrant(mu, cov) - math.log(0.25)


def posterior_moments_3(zz, zy, tau, p0_gamma):
    """The untruncated conditional of ``gamma``: ``(mu, cov, h, log|A|)``."""
    from loadbayes.inference.condlinear import GroupSums

    sums = GroupSums(zz, zy, np.zeros(zz.shape[0]), np.zeros(zz.shape[0]))
    return posterior_moments(sums, tau, np.zeros(3), p0_gamma)


def draw_gamma(ztz, zty, tau, a, p0_gamma, rng: np.random.Generator, size: int = 1):
    """``size`` exact draws of one event's ``beta`` (size, 7) under the bounded model."""
    t = transform(a)
    mu, cov, _, _ = gamma_moments(np.asarray(a, dtype=float), np.asarray(ztz, dtype=float),
                                  np.asarray(zty, dtype=float), np.asarray(tau, dtype=float),
                                  np.asarray(p0_gamma, dtype=float))  # fmt: skip
    sm = math.sqrt(cov[_P_M0, _P_M0])
    # P_zip0 | P_m0: its conditional mean moves with P_m0, its sd does not.
    slope = cov[_P_ZIP, _P_M0] / cov[_P_M0, _P_M0]
    sz = math.sqrt(max(cov[_P_ZIP, _P_ZIP] - slope * cov[_P_ZIP, _P_M0], 1e-300))
    lo = special.ndtr(-mu[_P_M0] / sm)
    pm = np.empty(size)
    todo = np.arange(size) if size > 1 else np.arange(0)
    if size == 1:  # the sampler's draw: the same tries, a batch at a time
        pm[0] = _one_truncated(mu[_P_M0], sm, lo, mu[_P_ZIP], slope, sz, rng)
    for _ in range(_MAX_TRIES if todo.size else 0):
        w = rng.uniform(lo, 1.0, todo.size)
        cand = mu[_P_M0] + sm * special.ndtri(np.clip(w, 1e-300, 1 - 1e-16))
        mz = mu[_P_ZIP] + slope * (cand - mu[_P_M0])
        ok = rng.uniform(size=todo.size) < special.ndtr(mz / sz)
        pm[todo] = cand  # the last try stands if none is accepted (far in a tail)
        todo = todo[~ok]
        if todo.size == 0:
            break
    # P_zip0 given P_m0, truncated to > 0 (inverse CDF on the upper tail).
    mz = mu[_P_ZIP] + slope * (pm - mu[_P_M0])
    upper = special.ndtr(mz / sz)
    pz = mz + sz * -special.ndtri(np.maximum(rng.uniform(0.0, 1.0, size) * upper, 1e-300))
    idx = [_P_ZIP, _P_M0]
    c_q = cov[_Q0, idx]
    wq = np.linalg.solve(cov[np.ix_(idx, idx)], c_q)
    pair = np.stack([pz, pm], -1)
    mq = mu[_Q0] + (pair - mu[idx]) @ wq
    vq = max(cov[_Q0, _Q0] - wq @ c_q, 1e-300)
    out = np.stack([pz, mq + math.sqrt(vq) * rng.standard_normal(size), pm], -1)
    return out @ t.T


#: Tries of the single draw's rejection made at once, first and at most (x8 each batch).
_BATCH_FIRST, _BATCH_MAX = 4, 4096


def _one_truncated(m, sm, lo, mz0, slope, sz, rng: np.random.Generator) -> float:
    # draw_gamma's rejection loop for one draw, its tries made a batch at a time: far in
    # a tail (a chain's first iterations with bounded shares) it took up to 10,000 tries
    # of four NumPy calls each, a tenth of a second per iteration (issue 40: the cost
    # estimate read hours). Each try takes a uniform w then a uniform u, as the loop's
    # rng.uniform(lo, 1.0) and rng.uniform() do (lo + (1 - lo) d and d, d the next
    # double); the generator is then put back to just after the accepted try, so the
    # draws and the stream are the loop's, bit for bit.
    done, k, cand = 0, _BATCH_FIRST, np.array([m])
    while done < _MAX_TRIES:
        k = min(k, _MAX_TRIES - done)
        state = rng.bit_generator.state
        d = rng.random(2 * k)
        w = lo + (1.0 - lo) * d[0::2]
        cand = m + sm * special.ndtri(np.clip(w, 1e-300, 1 - 1e-16))
        mz = mz0 + slope * (cand - m)
        hit = np.flatnonzero(d[1::2] < special.ndtr(mz / sz))
        if hit.size:
            j = int(hit[0])
            if j < k - 1:
                rng.bit_generator.state = state
                rng.random(2 * (j + 1))
            return float(cand[j])
        done += k
        k = min(8 * k, _BATCH_MAX)
    return float(cand[-1])  # the last try stands (far in a tail), as in the loop


def share_start(betas: np.ndarray) -> np.ndarray:
    """Log-ratio coordinates of every event's shares near a free fit's ``betas`` (E, 7).

    The free estimate's shares, moved inside the simplex (each at least 0.05), then the
    log-ratios: the bounded chains' start.
    """
    out = []
    for b in np.atleast_2d(betas):
        z = []
        for part in (b[0:3], b[3:6]):
            tot = part.sum()
            a = part / tot if abs(tot) > 1e-12 else np.full(3, 1 / 3)
            a = np.clip(a, 0.05, None)
            a = a / a.sum()
            z.extend([math.log(a[0] / a[2]), math.log(a[1] / a[2])])
        out.append(z)
    return np.array(out, dtype=float).ravel()
