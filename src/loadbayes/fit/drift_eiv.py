"""Errors in variables for the drifting-level ZIP (``fit zip --level drift --v-noise SD``).

The drifting level learns the shares from the voltage's moves faster than the level
moves (taps, capacitors, a CVR switch): exactly where white noise on V is largest against
the true voltage's own moves. So noise of 0.05 % on V, small against the day's range,
pulls dP/dV toward a flat load (issue 39: 0.57 for a true 0.85).

The model, per channel ``c`` (P, and Q), with one latent true voltage ``x_t`` (per unit
of v0) shared by the channels::

    y_ct = L_ct (1 + b1c (x_t^2 - 1) + b2c (x_t - 1)) + e_ct,   e_ct ~ N(0, w_ct / tau_c)
    L_ct = L_c,t-1 + N(0, q_c dt_t w_ct)                          (as fit/drift.py)
    v_t / v0 = x_t + u_t,   u_t ~ N(0, s^2)                       (s = --v-noise, known)
    x_t = x_t-1 + N(0, qx dt_t / omega_t),  omega_t ~ Gamma(nu/2, nu/2)

The true voltage is a random walk whose steps are Student-t (``nu`` = :data:`NU_X`): it
wanders slowly and now and then steps (a tap), and its scale ``qx`` is learned. Why a
prior that knows V moves slowly, and not the flat one of the static fit
(:mod:`loadbayes.fit.eiv`): with a flat prior on each ``x_t`` the marginal of ``y_t``
given ``v_t`` is the plain regression on ``v_t`` with its variance widened by
``b^2 s^2``; the noise precision being free, P alone then gives back the plain,
attenuated slope. What tells noise from signal here is that the true voltage does not
jump by 0.05 % from one sample to the next and back.

The sampler, one Gibbs sweep per iteration:

1. each channel's (b1, b2) and (log tau, log q) by Metropolis on the Kalman marginal given
   ``x`` (:func:`loadbayes.inference.ffbs.kf_loglik`, the level integrated out), the
   proposals adapted in the burn-in as :func:`~loadbayes.inference.ffbs.sample_level_regression`
   does; then its level path by FFBS (:func:`~loadbayes.inference.ffbs.ffbs`);
2. each ``x_t`` given its neighbours, ``v_t`` and the channels at the drawn level: one
   Metropolis-Hastings step whose proposal is the exact conditional of the curves
   linearised at the current ``x_t`` (:func:`_x_sweep`, compiled; nearly always accepted);
3. ``omega_t`` (Gamma) and ``qx`` (inverse Gamma), conjugate.
"""

from __future__ import annotations

import math
from collections.abc import Mapping

import numpy as np
from numba import njit

from loadbayes.core.parallel import chain_generators, check_stop, run_chains
from loadbayes.core.settings import SamplerSettings
from loadbayes.inference.ffbs import LevelChains, ffbs, kf_loglik, local_scale

__all__ = ["NU_X", "sample_drift_eiv"]

#: Degrees of freedom of the true voltage's steps: heavy tails, so that a tap step is a
#: step and not a reason to believe V jitters.
NU_X = 2.0
#: Warm-up sweeps (path, then b, tau, q given it) before the Metropolis chain starts.
WARM = 30


@njit(cache=True, nogil=True)
def _gn(x0, prec, lin, y, lv, b, rate):  # pragma: no cover - compiled
    """The conditional of x_t with the curves linearised at ``x0``: (mean, precision)."""
    p = prec
    m = lin
    for c in range(y.size):
        f = lv[c] * (1.0 + b[c, 0] * (x0 * x0 - 1.0) + b[c, 1] * (x0 - 1.0))
        g = lv[c] * (2.0 * b[c, 0] * x0 + b[c, 1])
        p += rate[c] * g * g
        m += rate[c] * g * (y[c] - f + g * x0)
    return m / p, p


@njit(cache=True, nogil=True)
def _log_target(x, prec, lin, y, lv, b, rate):  # pragma: no cover - compiled
    out = -0.5 * prec * x * x + lin * x
    for c in range(y.size):
        e = y[c] - lv[c] * (1.0 + b[c, 0] * (x * x - 1.0) + b[c, 1] * (x - 1.0))
        out -= 0.5 * rate[c] * e * e
    return out


@njit(cache=True, nogil=True)
def _x_sweep(x, v, s2, ys, ls, b, tau, w, dt, omega, qx, z, u):  # pragma: no cover
    """Step 2 of the module notes over every sample in turn; returns the acceptances."""
    n = x.size
    k = ys.shape[0]
    rate = np.empty(k)
    acc = 0
    for t in range(n):
        prec = 1.0 / s2
        lin = v[t] / s2
        if t > 0:
            pv = omega[t] / (qx * dt[t])
            prec += pv
            lin += pv * x[t - 1]
        if t < n - 1:
            pv = omega[t + 1] / (qx * dt[t + 1])
            prec += pv
            lin += pv * x[t + 1]
        for c in range(k):
            rate[c] = tau[c] / w[c, t]
        y = ys[:, t]
        lv = ls[:, t]
        xc = x[t]
        m1, p1 = _gn(xc, prec, lin, y, lv, b, rate)
        xp = m1 + z[t] / math.sqrt(p1)
        m2, p2 = _gn(xp, prec, lin, y, lv, b, rate)
        log_a = (_log_target(xp, prec, lin, y, lv, b, rate)
                 - _log_target(xc, prec, lin, y, lv, b, rate)
                 - 0.5 * p2 * (xc - m2) ** 2 + 0.5 * math.log(p2)
                 + 0.5 * p1 * (xp - m1) ** 2 - 0.5 * math.log(p1))  # fmt: skip
        if math.log(u[t]) < log_a:
            x[t] = xp
            acc += 1
    return acc


def _level_sums(y, lv, z1, z2, w):
    u1, u2, iw = lv * z1, lv * z2, 1.0 / w
    res = y - lv
    xtx = np.array([[np.sum(u1 * u1 * iw), np.sum(u1 * u2 * iw)],
                    [np.sum(u1 * u2 * iw), np.sum(u2 * u2 * iw)]])  # fmt: skip
    return xtx, np.array([np.sum(u1 * res * iw), np.sum(u2 * res * iw)]), float(np.sum(res**2 * iw))


def sample_drift_eiv(
    ys: Mapping[str, np.ndarray],
    v: np.ndarray,
    dt: np.ndarray,
    v_noise: float,
    *,
    settings: SamplerSettings,
    b_sd: float = 10.0,
    keep_points: int = 500,
    window_s: float = 3600.0,
) -> tuple[dict[str, LevelChains], dict[str, np.ndarray]]:
    """Draws of the module's model: each channel's :class:`LevelChains`, and the latent V's.

    Parameters
    ----------
    ys : mapping
        ``{"p": P, "q": Q}`` (or P alone), in time order.
    v : ndarray
        The measured voltage in per unit of v0.
    dt : ndarray
        The time step before each sample (``dt[0]`` unused), positive.
    v_noise : float
        The sd of the noise on ``v`` (per unit of v0).
    settings : SamplerSettings
        Chains, draws (burn-in included), thinning, seed, threads.

    Returns
    -------
    (dict, dict)
        Per channel its draws; and ``acceptance_x`` (per chain: the latent voltages'
        Metropolis acceptance) and ``qx`` (chain, draw: the true voltage's walk variance
        per second).
    """
    chans = list(ys)
    k = len(chans)
    y_all = np.stack([np.ascontiguousarray(ys[c], dtype=float) for c in chans])
    v = np.ascontiguousarray(v, dtype=float)
    dt = np.ascontiguousarray(dt, dtype=float)
    n = v.size
    s2 = float(v_noise) ** 2
    draws, burn, thin = settings.draws, settings.burn, settings.thin
    kept = len(range(burn, draws, thin))
    keep_idx = np.unique(np.linspace(0, n - 1, min(keep_points, n)).astype(np.int64))
    w_all = np.stack([local_scale(y, dt, window_s=window_s) ** 2 for y in y_all])
    med_dt = float(np.median(dt[1:]))
    prec0 = np.eye(2) / b_sd**2
    ta, tb = 1e-3, 1e-9
    qpri = [(1e-3, 1e-12 * (float(np.var(y)) or 1.0) / med_dt) for y in y_all]
    m0s = [float(y[0]) for y in y_all]
    v0s = [(10.0 * (float(np.mean(np.abs(y))) or 1.0)) ** 2 for y in y_all]
    qx_a, qx_b = 1e-3, 1e-16 / med_dt

    def log_post(c, th, z1, z2):
        b1, b2, lt, lq = th
        if not (-30.0 < lt < 60.0 and -120.0 < lq < 60.0):
            return -np.inf
        qa, qb = qpri[c]
        lp = -0.5 * (b1 * b1 + b2 * b2) / b_sd**2 + ta * lt - tb * math.exp(lt) - qa * lq
        lp -= qb / math.exp(lq)
        return lp + kf_loglik(y_all[c], z1, z2, dt, w_all[c], b1, b2, math.exp(-lt),
                              math.exp(lq), m0s[c], v0s[c])  # fmt: skip

    def chain(ci: int, gen: np.random.Generator):
        x = v.copy()
        omega = np.ones(n)
        dx = np.diff(x)
        # the measured steps' variance less the noise's share (2 s^2 per step)
        raw = float(np.mean(dx * dx / dt[1:]))
        qx = max(raw - 2.0 * s2 / med_dt, 0.1 * raw, 1e-300)
        paths = np.empty((k, n))
        mwork, pwork, zwork, hwork = np.empty(n), np.empty(n), np.empty(n), np.empty(n)
        th = np.zeros((k, 4))
        props, starts = [], []
        for c in range(k):
            y = y_all[c]
            tau = 2.0 / max(float(np.var(np.diff(y))), 1e-300)
            q = max(float(np.var(np.diff(y) / np.sqrt(dt[1:]))) / 4.0, 1e-300)
            b = np.zeros(2)
            z1, z2 = (x - 1.0) * (x + 1.0), x - 1.0
            for _ in range(WARM):  # Gibbs sweeps reach the bulk (fit/drift.py's start)
                check_stop(None)
                hwork[:] = 1.0 + b[0] * z1 + b[1] * z2
                gen.standard_normal(out=zwork)
                ffbs(y, hwork, dt, w_all[c], 1.0 / tau, q, m0s[c], v0s[c], zwork, paths[c],
                     mwork, pwork)  # fmt: skip
                xtx, xtr, srr = _level_sums(y, paths[c], z1, z2, w_all[c])
                prec = tau * xtx + prec0
                b = np.linalg.solve(prec, tau * xtr) + np.linalg.solve(
                    np.linalg.cholesky(prec).T, gen.standard_normal(2)
                )
                ssr = max(srr - 2.0 * b @ xtr + b @ xtx @ b, 1e-300)
                tau = gen.gamma(ta + n / 2.0, 1.0 / (tb + ssr / 2.0))
                d = np.diff(paths[c])
                sdl = float(np.sum(d * d / (dt[1:] * w_all[c][1:])))
                q = 1.0 / gen.gamma(qpri[c][0] + (n - 1) / 2.0, 1.0 / (qpri[c][1] + sdl / 2.0))
            th[c] = (b[0], b[1], math.log(tau), math.log(q))
            start = [np.linalg.inv(prec) * 4.0, np.eye(2) * 8.0 / n]
            starts.append(start)
            props.append([np.linalg.cholesky(s) * (2.38 / math.sqrt(2)) for s in start])
        hist = np.empty((k, max(burn, 1), 4))
        out_b = np.empty((k, kept, 2))
        out_tau, out_q = np.empty((k, kept)), np.empty((k, kept))
        out_path = np.empty((k, kept, keep_idx.size))
        out_qx = np.empty(kept)
        acc_b = np.zeros(k)
        acc_x = 0
        j = 0
        for it in range(draws):
            check_stop(None)
            z1, z2 = (x - 1.0) * (x + 1.0), x - 1.0
            for c in range(k):
                lp = log_post(c, th[c], z1, z2)
                for blk, idx in enumerate(((0, 1), (2, 3))):
                    cand = th[c].copy()
                    cand[list(idx)] += props[c][blk] @ gen.standard_normal(2)
                    lp_c = log_post(c, cand, z1, z2)
                    if math.log(gen.random()) < lp_c - lp:
                        th[c], lp = cand, lp_c
                        acc_b[c] += (it >= burn) and blk == 0
                if it < burn:
                    hist[c, it] = th[c]
                    if it >= 60 and it % 30 == 0:
                        recent = hist[c, it // 2 : it + 1]
                        for blk, idx in enumerate(((0, 1), (2, 3))):
                            mix = 0.9 * np.cov(recent[:, list(idx)].T) + 0.1 * starts[c][blk] / 4
                            try:
                                props[c][blk] = np.linalg.cholesky(mix) * (2.38 / math.sqrt(2))
                            except np.linalg.LinAlgError:
                                pass
                hwork[:] = 1.0 + th[c, 0] * z1 + th[c, 1] * z2
                gen.standard_normal(out=zwork)
                ffbs(y_all[c], hwork, dt, w_all[c], math.exp(-th[c, 2]), math.exp(th[c, 3]),
                     m0s[c], v0s[c], zwork, paths[c], mwork, pwork)  # fmt: skip
            acc_x += _x_sweep(x, v, s2, y_all, paths, np.ascontiguousarray(th[:, :2]),
                              np.exp(th[:, 2]), w_all, dt, omega, qx, gen.standard_normal(n),
                              gen.random(n))  # fmt: skip
            eta2 = np.diff(x) ** 2 / dt[1:]
            omega[1:] = gen.gamma((NU_X + 1.0) / 2.0, 2.0 / (NU_X + eta2 / qx))
            qx = 1.0 / gen.gamma(qx_a + (n - 1) / 2.0,
                                 1.0 / (qx_b + 0.5 * float(np.sum(omega[1:] * eta2))))  # fmt: skip
            if it >= burn and (it - burn) % thin == 0:
                out_b[:, j] = th[:, :2]
                out_tau[:, j], out_q[:, j] = np.exp(th[:, 2]), np.exp(th[:, 3])
                out_path[:, j] = paths[:, keep_idx]
                out_qx[j] = qx
                j += 1
        acc = (acc_b / max(kept * thin, 1), acc_x / (n * draws))
        return out_b, out_tau, out_q, out_path, *acc, out_qx

    res = run_chains(chain, chain_generators(settings.seed, settings.chains),
                     workers=settings.threads)  # fmt: skip
    out = {}
    for c, ch in enumerate(chans):
        out[ch] = LevelChains(
            b=np.stack([r[0][c] for r in res]), tau=np.stack([r[1][c] for r in res]),
            q=np.stack([r[2][c] for r in res]), path=np.stack([r[3][c] for r in res]),
            keep_idx=keep_idx, acceptance=np.array([r[4][c] for r in res]),
        )  # fmt: skip
    extra = {"acceptance_x": np.array([r[5] for r in res]), "qx": np.stack([r[6] for r in res])}
    return out, extra
