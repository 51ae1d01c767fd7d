"""A model of parts' sampled vector in compiled code: its prior, its ``theta``, its parts.

The sampler asks these of one vector ``u`` at every proposal: whether it lies in the
prior's hard limits and the prior's log-density there (:func:`prior_log_u`), the model's
``theta`` (each motor's ``z`` made its ``log T0``, ``part_scale.py``; :func:`theta_of`),
the parts' constants at ``theta`` (:func:`parts_constants`: the feeder's X on the load's
base, each motor's eleven constants as ``parts_kernel`` reads them, motor D's, the
electronics' trip voltages) and the shares (:func:`shares_of`). The same functions serve
the Python path (``part_scale.ScaleMap``, ``part_priors.PartsPrior`` and
``parts_sums`` on one vector) and the compiled density
(``fit/composite/parts_density.py``), so both give one number to the bit
(``tests/unit/test_parts_density.py``).

Their constants come packed in arrays, built once per prior and model:

- a motor's scale map (:class:`~loadbayes.models.part_scale.ScaleMap`) as a row of 12:
  ``(index, coef[5], m0, sd, log rs_max, log h_min, log x_min, log x_max)``;
- the prior (:meth:`PartsPrior.packed`): the Gaussian block's mean and precision, the maps'
  rows, the ranges ``(i, lo, hi)``, the order ``(i, j, gap)``, the simplexes ``(a, b)``;
- the model (``parts_sums.model_constants``).
"""

from __future__ import annotations

import math

import numba
import numpy as np

from loadbayes.core.normal import log_add_exp, log_ndtr, ndtr, ndtri
from loadbayes.models.motor_kernel import H_MAX_S, TP_STEPS

__all__ = [
    "K_NAMES",
    "K_SIZE",
    "alr_shares",
    "feeder_of",
    "log_mass_of",
    "log_t0_of",
    "lowest_load_bus",
    "map_row",
    "parts_constants",
    "prior_log_u",
    "share_weights",
    "shares_of",
    "theta_of",
]


def map_row(index, coef, m0, sd, rs_max, h_min, x_min, x_max) -> np.ndarray:
    """A scale map's constants as the compiled functions read them (module docstring)."""
    return np.array([float(index), *map(float, coef), float(m0), float(sd), math.log(rs_max),
                     math.log(h_min), math.log(x_min), math.log(x_max)])  # fmt: skip


@numba.njit(cache=True, nogil=True)
def map_ab(u, row):  # pragma: no cover - compiled
    """The conditional mean of ``log T0`` and its standardised bounds ``(m, a, b)`` at ``u``."""
    i = int(row[0])
    dot = 0.0
    for k in range(5):
        dot += u[i + k] * row[1 + k]
    m = row[6] + dot
    lo = max(u[i] - row[8], row[9] - u[i + 4], u[i + 1] - row[11])
    hi = u[i + 1] - row[10]
    return m, (lo - m) / row[7], (hi - m) / row[7]


@numba.njit(cache=True, nogil=True)
def log_mass_of(u, row):  # pragma: no cover - compiled
    """``log(Phi(b) - Phi(a))``: the prior mass of ``log T0`` the limits leave (-inf: none)."""
    _, a, b = map_ab(u, row)
    if not a < b:
        return -math.inf
    lo, hi = (-b, -a) if a > 0 else (a, b)
    top, bottom = log_ndtr(hi), log_ndtr(lo)
    if bottom >= top:
        return -math.inf
    out = top + math.log1p(-math.exp(bottom - top))
    return out if math.isfinite(out) else -math.inf


@numba.njit(cache=True, nogil=True)
def log_t0_of(u, row):  # pragma: no cover - compiled
    """``log T0`` of the sampled vector ``u`` (NaN where its interval is empty)."""
    m, a, b = map_ab(u, row)
    if not a < b:
        return math.nan
    z = u[int(row[0]) + 5]
    if a > 0:
        x = -ndtri(ndtr(-a) * ndtr(-z) + ndtr(z) * ndtr(-b))
    else:
        x = ndtri(ndtr(a) * ndtr(-z) + ndtr(z) * ndtr(b))
    return m + row[7] * min(max(x, a), b)


@numba.njit(cache=True, nogil=True)
def prior_log_u(u, gmean, gprec, maps, ranges, order, groups):  # pragma: no cover - compiled
    """Log prior density at ``u`` up to a constant; -inf outside the hard limits.

    The Gaussian block's term, each motor's mass of ``log T0`` inside its limits
    (``part_scale.py``), each simplex's uniform Dirichlet in additive log-ratios.
    """
    n = gmean.size
    masses = np.empty(maps.shape[0])
    for k in range(maps.shape[0]):
        masses[k] = log_mass_of(u, maps[k])
        if not math.isfinite(masses[k]):
            return -math.inf
    for k in range(ranges.shape[0]):
        x = u[int(ranges[k, 0])]
        if not (ranges[k, 1] <= x and x <= ranges[k, 2]):
            return -math.inf
    for k in range(order.shape[0]):
        if not u[int(order[k, 1])] <= u[int(order[k, 0])] - order[k, 2]:
            return -math.inf
    quad = 0.0
    for i in range(n):
        di = u[i] - gmean[i]
        row = 0.0
        for j in range(n):
            row += gprec[i, j] * (u[j] - gmean[j])
        quad += di * row
    out = -0.5 * quad
    for k in range(maps.shape[0]):
        out += masses[k]
    for g in range(groups.shape[0]):
        a, b = int(groups[g, 0]), int(groups[g, 1])
        total, lse = 0.0, 0.0  # z = (u[a:b], 0): sum(z) - size * logsumexp(z)
        for i in range(a, b):
            total += u[i]
            lse = u[i] if i == a else log_add_exp(lse, u[i])
        lse = 0.0 if b == a else log_add_exp(lse, 0.0)
        out += total - (b - a + 1) * lse
    return out


@numba.njit(cache=True, nogil=True)
def theta_of(u, maps):  # pragma: no cover - compiled
    """The model's ``theta`` of ``u``: each motor's ``z`` made its ``log T0``."""
    theta = u.copy()
    for k in range(maps.shape[0]):
        theta[int(maps[k, 0]) + 5] = log_t0_of(u, maps[k])
    return theta


#: Entries of ``parts_sums.model_constants``' first array, by name (indices).
K_NAMES = ("feeder", "wb", "n_motors", "i_vstall", "i_tstall", "i_vd1", "i_vd2", "vstall",
            "tstall", "vd1", "vd2", "d_vstall", "d_tstall", "n_gauss", "n_parts")  # fmt: skip
K_SIZE = len(K_NAMES)


@numba.njit(cache=True, nogil=True)
def parts_constants(theta, k, inv_sf, torques, d_base):  # pragma: no cover - compiled
    """``(x_fd, motors, d_params, vd1, vd2)`` at ``theta`` (its shares not read).

    ``x_fd`` the feeder's X on the load's base (0 without a feeder; :func:`feeder_of`
    puts it on the system's); ``motors`` (n, 11) as ``parts_kernel.event_parts`` reads
    them; motor D's constants with the sampled stall.
    """
    i = 0
    x_fd = 0.0
    if k[0] > 0.0:
        x_fd = math.exp(theta[0])
        i = 1
    n_m = int(k[2])
    motors = np.empty((n_m, 11))
    for j in range(n_m):
        logs = np.empty(6)
        for r in range(6):
            acc = 0.0
            for c in range(6):
                acc += theta[i + c] * inv_sf[r, c]
            logs[r] = acc
        rs, xp, dx = math.exp(logs[0]), math.exp(logs[1]), math.exp(logs[2])
        tp, h, t0 = math.exp(logs[3]), math.exp(logs[4]), math.exp(logs[5])
        m = motors[j]
        m[0], m[1], m[2], m[3], m[4], m[5], m[6] = rs, xp, dx, tp, h, k[1], t0
        m[7], m[8], m[9] = torques[j, 0], torques[j, 1], torques[j, 2]
        m[10] = min(H_MAX_S, tp / TP_STEPS)
        i += 6
    vals = np.empty(4)
    for q in range(4):  # vstall, tstall (its log sampled), vd1, vd2
        at = int(k[3 + q])
        if at < 0:
            vals[q] = k[7 + q]
        else:
            vals[q] = math.exp(theta[at]) if q == 1 else theta[at]
    d_params = d_base.copy()
    d_params[int(k[11])] = vals[0]
    d_params[int(k[12])] = vals[1]
    return x_fd, motors, d_params, vals[2], vals[3]


@numba.njit(cache=True, nogil=True)
def feeder_of(x_fd, p0, q0):  # pragma: no cover - compiled
    """The feeder's X in system p.u. from its draw on the load's base (``|S|`` at the start)."""
    return x_fd / math.hypot(p0, q0)


@numba.njit(cache=True, nogil=True)
def lowest_load_bus(v, delta, p, q, r, x):  # pragma: no cover - compiled
    """The lowest ``|V_L|`` behind ``Z = r + jx``, as ``parts_kernel.event_parts`` solves it."""
    zc = complex(r, x)
    low = math.inf
    for k in range(v.size):
        vk = v[k] * complex(math.cos(delta[k]), math.sin(delta[k]))
        cur = ((p[k] + 1j * q[k]) / vk).conjugate()
        low = min(low, abs(vk - zc * cur))
    return low


@numba.njit(cache=True, nogil=True)
def alr_shares(z):  # pragma: no cover - compiled
    """The shares whose additive log-ratios are ``z`` (the last share's 0)."""
    top = 0.0
    for x in z:
        top = max(top, x)
    e = np.empty(z.size + 1)
    total = 0.0
    for i in range(z.size + 1):
        e[i] = math.exp((z[i] if i < z.size else 0.0) - top)
        total += e[i]
    return e / total


@numba.njit(cache=True, nogil=True)
def shares_of(theta, n_gauss, n_parts):  # pragma: no cover - compiled
    """The parts' shares of P (static last) and the static P's Z, I, P split."""
    i = n_gauss
    return alr_shares(theta[i : i + n_parts]), alr_shares(theta[i + n_parts : i + n_parts + 2])


@numba.njit(cache=True, nogil=True)
def share_weights(zf, za):  # pragma: no cover - compiled
    """``w = (f_1, ..., f_K, f_s a1, f_s a2, f_s a3)`` of the shares' log-ratios ``zf, za``."""
    f, a = alr_shares(zf), alr_shares(za)
    k = f.size - 1
    w = np.empty(k + a.size)
    w[:k] = f[:k]
    for i in range(a.size):
        w[k + i] = f[k] * a[i]
    return w
