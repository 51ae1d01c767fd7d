"""Compiled loops over buses of the pooled model's Gibbs sweep (see :mod:`.hierarchical`).

Each works on small dense matrices per bus (``d`` = 2 or 4) without allocating inside
the loop. Per bus and channel the data enter through ``G = X'X`` and ``X'y`` of the
regression of ``y`` (P, or P / P0 when P0 is given) on ``X = [1, z1, z2]``, the
least-squares ``beta_hat`` and ``SSR_min``; the state is the shares ``theta``, the
level ``s`` (P0) and the absolute noise precision ``t`` (of ``y``). Given ``s``, the
shares see the per-unit regression ``y / s - 1 = Z theta + e`` with precision
``t s^2``: ``J = t s^2 Z'Z`` and ``u = t (s Z'y - s^2 Z'1)``.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from loadbayes.inference.linalg import cholesky, precision_draw, solve_lower, solve_upper

__all__ = [
    "_bartlett",
    "_bus_sweep",
    "_class_sums",
    "_mu_draw",
    "_factor",
    "_mu_terms",
    "_scale_apply",
    "_scale_moves_all",
    "_scale_terms",
    "_scale_tries",
]

_TAU_FLOOR = 1e-100  # a gamma draw can underflow to 0; keep the precision positive


@njit(cache=True, nogil=True)
def _factor(cls, g3, xy, s, t, sig_inv, chol, u, ok):  # pragma: no cover - compiled
    """Per bus: the Cholesky factor of ``L_b = Sigma_c^-1 + J_b`` (in ``chol``) and ``u_b``.

    ``L_b`` and ``u_b`` are shared by the collapsed draw of ``mu`` and the draw of
    ``theta_b`` (same ``Sigma``, ``s``, ``t``), so they are built and factorised once a
    sweep. ``ok[b]`` is False when ``L_b`` is not positive definite.
    """
    d = chol.shape[1]
    nch = t.shape[1]
    for b in range(cls.shape[0]):
        c = cls[b]
        lm = chol[b]
        for i in range(d):
            for j in range(d):
                lm[i, j] = sig_inv[c, i, j]
        for ch in range(nch):
            sc = s[b, ch]
            w = t[b, ch] * sc * sc
            for i in range(2):
                u[b, 2 * ch + i] = t[b, ch] * (sc * xy[b, ch, 1 + i] - sc * sc * g3[b, 1 + i, 0])
                for j in range(2):
                    lm[2 * ch + i, 2 * ch + j] += w * g3[b, 1 + i, 1 + j]
        ok[b] = cholesky(lm, lm)


@njit(cache=True, nogil=True)
def _mu_terms(cls, chol, u, ok, sig_inv, prec, lin):  # pragma: no cover - compiled
    """Per class: the precision and linear term of ``mu_c | Sigma_c, s, t, data``.

    With ``theta_b`` integrated out, bus ``b`` adds ``Sigma^-1 - Sigma^-1 L_b^-1
    Sigma^-1`` to the precision and ``Sigma^-1 L_b^-1 u_b`` to the linear term
    (``L_b = R R'`` factorised by :func:`_factor`). With ``W = R^-1 Sigma^-1`` and
    ``w = R^-1 u_b`` these are ``W'W`` and ``W'w``: d + 1 triangular solves a bus, no
    inverse.
    """
    d = sig_inv.shape[1]
    prec[:] = 0.0
    lin[:] = 0.0
    wm = np.empty((d, d))
    wv = np.empty(d)
    for b in range(cls.shape[0]):
        c = cls[b]
        if not ok[b]:
            # L is not positive definite (a failed factor): NaN, as before
            for i in range(d):
                lin[c, i] = np.nan
                for j in range(d):
                    prec[c, i, j] = np.nan
            continue
        r = chol[b]
        # forward substitution, for the columns of Sigma^-1 and for u
        for i in range(d):
            for j in range(d):
                acc = sig_inv[c, i, j]
                for k in range(i):
                    acc -= r[i, k] * wm[k, j]
                wm[i, j] = acc / r[i, i]
            acc = u[b, i]
            for k in range(i):
                acc -= r[i, k] * wv[k]
            wv[i] = acc / r[i, i]
        for i in range(d):
            acc = 0.0
            for k in range(d):
                acc += wm[k, i] * wv[k]
            lin[c, i] += acc
            for j in range(d):
                acc = 0.0
                for k in range(d):
                    acc += wm[k, i] * wm[k, j]
                prec[c, i, j] += sig_inv[c, i, j] - acc


@njit(cache=True, nogil=True)
def _bus_sweep(
    cls, chol, u, ok, sig_inv_mu, g3, xy, beta_ls, ssr_min, fixed, rate, theta, s, t, z, zs, g
):  # pragma: no cover - compiled
    """Per bus: ``theta_b | mu, Sigma, s, t``, then ``s_b | theta_b, t``, then ``t_b | .``.

    ``z`` (bus, d) and ``zs`` (bus, channel) hold standard normals, ``g`` standard gammas
    of shape ``a0 + n_b / 2``; ``rate`` the gamma prior's rate per bus and channel.
    With ``a = (1, theta_ch)``, ``y = s X a + e``: ``s | . ~ N(a'X'y / a'Ga, 1 / (t a'Ga))``
    (flat prior; skipped where ``fixed``) and ``SSR = SSR_min + (s a - beta_ls)' G
    (s a - beta_ls)``, exact for any least-squares solution ``beta_ls``.
    """
    d = theta.shape[1]
    nch = t.shape[1]
    h = np.empty(d)
    w = np.empty(d)
    a = np.empty(3)
    e = np.empty(3)
    for b in range(cls.shape[0]):
        c = cls[b]
        if ok[b]:
            # theta = R'^-1 (R^-1 h + z) with L = R R': mean L^-1 h, covariance L^-1
            for i in range(d):
                h[i] = sig_inv_mu[c, i] + u[b, i]
            solve_lower(chol[b], h, w)
            for i in range(d):
                w[i] += z[b, i]
            solve_upper(chol[b], w, theta[b])
        else:
            theta[b, :] = np.nan
        for ch in range(nch):
            a[0] = 1.0
            a[1] = theta[b, 2 * ch]
            a[2] = theta[b, 2 * ch + 1]
            gg = 0.0
            gy = 0.0
            for i in range(3):
                gy += a[i] * xy[b, ch, i]
                for j in range(3):
                    gg += a[i] * g3[b, i, j] * a[j]
            if not fixed[b, ch] and gg > 0.0:
                s[b, ch] = gy / gg + zs[b, ch] / np.sqrt(t[b, ch] * gg)
            sc = s[b, ch]
            for i in range(3):
                e[i] = sc * a[i] - beta_ls[b, ch, i]
            q = 0.0
            for i in range(3):
                for j in range(3):
                    q += e[i] * g3[b, i, j] * e[j]
            ssr = ssr_min[b, ch] + max(q, 0.0)
            t[b, ch] = max(g[b, ch] / (rate[b, ch] + 0.5 * ssr), _TAU_FLOOR)


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


@njit(cache=True, nogil=True)
def _scale_terms(cls, g3, xy, s, t, theta, mu, v, a_out, b_out):  # pragma: no cover - compiled
    """Per class, ``A`` and ``B`` of the scale move's log-likelihood ``-k^2 A / 2 + k B``.

    The move is ``theta_b -> theta_b + k (v'delta_b) v`` (``delta_b = theta_b - mu_c``):
    ``A = sum (v'delta)^2 v'J v``, ``B = sum (v'delta) v'(u - J theta)``, with ``J``, ``u``
    of the bus's data given ``s``, ``t``.
    """
    d = theta.shape[1]
    nch = t.shape[1]
    a_out[:] = 0.0
    b_out[:] = 0.0
    jv = np.empty(d)
    for b in range(cls.shape[0]):
        c = cls[b]
        vd = 0.0
        for i in range(d):
            vd += v[i] * (theta[b, i] - mu[c, i])
        vjv = 0.0
        res = 0.0
        for ch in range(nch):
            sc = s[b, ch]
            w = t[b, ch] * sc * sc
            for i in range(2):
                acc = 0.0
                for j in range(2):
                    acc += w * g3[b, 1 + i, 1 + j] * v[2 * ch + j]
                jv[2 * ch + i] = acc
                ui = t[b, ch] * (sc * xy[b, ch, 1 + i] - sc * sc * g3[b, 1 + i, 0])
                res += v[2 * ch + i] * ui - acc * theta[b, 2 * ch + i]
                vjv += v[2 * ch + i] * acc
        a_out[c] += vd * vd * vjv
        b_out[c] += vd * res


@njit(cache=True, nogil=True)
def _scale_apply(cls, theta, mu, v, factor):  # pragma: no cover - compiled
    """``theta_b <- theta_b + (factor_c - 1) (v'(theta_b - mu_c)) v`` for every bus."""
    d = theta.shape[1]
    for b in range(cls.shape[0]):
        c = cls[b]
        k = factor[c] - 1.0
        if k == 0.0:
            continue
        vd = 0.0
        for i in range(d):
            vd += v[i] * (theta[b, i] - mu[c, i])
        for i in range(d):
            theta[b, i] += k * vd * v[i]


@njit(cache=True, nogil=True)
def _rank_two(m, v, w, alpha, beta):  # pragma: no cover - compiled
    """``m <- m + alpha (w v' + v w') + beta v v'`` (``m`` symmetric, in place)."""
    d = v.shape[0]
    for i in range(d):
        for j in range(d):
            m[i, j] += alpha * (w[i] * v[j] + v[i] * w[j]) + beta * v[i] * v[j]


@njit(cache=True, nogil=True, inline="always")
def _times_v(m, v, w):  # pragma: no cover - compiled
    """``w = m v``; returns ``v'm v``."""
    d = v.shape[0]
    out = 0.0
    for i in range(d):
        acc = 0.0
        for j in range(d):
            acc += m[i, j] * v[j]
        w[i] = acc
        out += v[i] * acc
    return out


@njit(cache=True, nogil=True)
def _scale_tries(psi0, nu0, v, step, sigma, sig_inv, a, b, z, uni, total):  # pragma: no cover
    """The Metropolis tries of one direction's scale move, every class (in place).

    The same move as the matrix form it replaces (``hierarchical._scale_moves``): with
    ``C^-1 = I + al v v'`` (``al = 1/c - 1``, ``|v| = 1``) the proposed precision is
    ``S + al (S v v' + v v' S) + al^2 (v'S v) v v'`` and ``tr(Psi0 (new - S))`` =
    ``2 al v'Psi0 S v + al^2 (v'S v)(v'Psi0 v)``; an accepted ``c`` stretches ``Sigma``
    the same way with ``k = c - 1``. ``z``, ``uni`` (tries x classes) are the normals and
    uniforms the matrix form drew, in its order, so the chain's stream is unchanged.
    ``total`` (per class) is multiplied by each accepted ``c``; ``psi0`` is per class.
    """
    ncls, d = sigma.shape[0], sigma.shape[1]
    w = np.empty(d)
    for c in range(ncls):
        pv = psi0[c] @ v
        vpv = 0.0
        for i in range(d):
            vpv += v[i] * pv[i]
        ac, bc = a[c], b[c]
        for r in range(z.shape[0]):
            logc = step * z[r, c]
            logu = np.log(uni[r, c])
            cc = np.exp(logc)
            k = cc - 1.0
            al = 1.0 / cc - 1.0
            svv = _times_v(sig_inv[c], v, w)
            wpv = 0.0
            for i in range(d):
                wpv += w[i] * pv[i]
            dtr = 2.0 * al * wpv + al * al * svv * vpv
            log_ratio = -0.5 * k * k * ac + k * bc - nu0 * logc - 0.5 * dtr
            if not logu < log_ratio:
                continue
            _rank_two(sig_inv[c], v, w, al, al * al * svv)
            s2 = _times_v(sigma[c], v, w)
            _rank_two(sigma[c], v, w, k, k * k * s2)
            bc = cc * (bc - k * ac)
            ac = cc * cc * ac
            total[c] *= cc


@njit(cache=True, nogil=True)
def _mu_draw(s0_inv, s0_inv_m0, prec_data, lin_data, z, mu):  # pragma: no cover - compiled
    """``mu_c ~ N(prec^-1 rhs, prec^-1)`` per class from the normals ``z`` (into ``mu``).

    ``prec = S0^-1 + (P + P') / 2`` (the data part symmetrised), ``rhs = S0^-1 m0 + l``.
    Returns False when a class's precision is not positive definite.
    """
    ncls, d = lin_data.shape
    lam = np.empty((d, d))
    h = np.empty(d)
    w = np.empty(d)
    for c in range(ncls):
        for i in range(d):
            h[i] = s0_inv_m0[i] + lin_data[c, i]
            for j in range(d):
                lam[i, j] = s0_inv[i, j] + 0.5 * (prec_data[c, i, j] + prec_data[c, j, i])
        if not precision_draw(lam, h, z[c], lam, w, mu[c]):
            return False
    return True


@njit(cache=True, nogil=True)
def _spd_inverse(a, out, lo, e, w):  # pragma: no cover - compiled
    """``out = a^-1`` of a symmetric positive definite ``a`` (its Cholesky factor in ``lo``).

    Returns False when ``a`` is not positive definite.
    """
    d = a.shape[0]
    if not cholesky(a, lo):
        return False
    for j in range(d):
        e[:] = 0.0
        e[j] = 1.0
        solve_lower(lo, e, w)
        solve_upper(lo, w, e)
        for i in range(d):
            out[i, j] = e[i]
    return True


@njit(cache=True, nogil=True)
def _bartlett(chi, nrm, psi, sigma, sig_inv):  # pragma: no cover - compiled
    """Inverse-Wishart draws per class from their Bartlett variates (into the outputs).

    ``Sigma^-1 = C A A' C'`` with ``Psi^-1 = C C'`` (lower Cholesky factor), ``A`` lower
    triangular with ``sqrt(chi)`` on its diagonal and ``nrm`` below it. Small loops, not
    ``np.linalg`` (whose compilation took 5 s on a fresh install). Returns False when a
    matrix is not positive definite.
    """
    ncls, d = chi.shape
    lo = np.zeros((d, d))
    cf = np.zeros((d, d))
    pinv = np.empty((d, d))
    e = np.empty(d)
    w = np.empty(d)
    ca = np.empty((d, d))
    for c in range(ncls):
        if not _spd_inverse(psi[c], pinv, lo, e, w):
            return False
        cf[:] = 0.0
        if not cholesky(pinv, cf):
            return False
        for i in range(d):  # ca = cf A, both lower triangular
            for j in range(d):
                acc = 0.0
                for k in range(j, i + 1):
                    akj = np.sqrt(chi[c, j]) if k == j else nrm[c, k, j]
                    acc += cf[i, k] * akj
                ca[i, j] = acc
        for i in range(d):  # Sigma^-1 = ca ca', symmetric by construction
            for j in range(i + 1):
                acc = 0.0
                for k in range(d):
                    acc += ca[i, k] * ca[j, k]
                sig_inv[c, i, j] = acc
                sig_inv[c, j, i] = acc
        if not _spd_inverse(sig_inv[c], sigma[c], lo, e, w):
            return False
    return True


@njit(cache=True, nogil=True)
def _scale_moves_all(cls, g3, xy, s, t, theta, mu, dirs, psi0, nu0, step, sigma, sig_inv, a, b,
                 z, uni, total):  # fmt: skip  # pragma: no cover - compiled
    """Every direction's scale move in turn (``hierarchical._scale_moves``), in one call.

    For each row ``v`` of ``dirs``: :func:`_scale_terms`, :func:`_scale_tries` with that
    direction's normals and uniforms ``z[k]``, ``uni[k]`` (drawn before, in the order the
    moves use them) and, where a class accepted, :func:`_scale_apply`. The same steps as
    one call of each per direction, without the calls' cost (most of a small fleet's sweep).
    """
    for k in range(dirs.shape[0]):
        v = dirs[k]
        _scale_terms(cls, g3, xy, s, t, theta, mu, v, a, b)
        total[:] = 1.0
        _scale_tries(psi0, nu0, v, step, sigma, sig_inv, a, b, z[k], uni[k], total)
        moved = False
        for c in range(total.shape[0]):
            moved = moved or total[c] != 1.0
        if moved:
            _scale_apply(cls, theta, mu, v, total)
