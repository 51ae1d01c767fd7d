"""The plain zip+motor chain's iterations in one compiled loop: the same draws, faster.

One idea needs these lines: :func:`run_iterations`, a run of iterations of
:class:`~loadbayes.fit.composite.sampler._Gibbs` for a plain ``zip+motor`` problem
(free or bounded shares, Gaussian noise white or AR(1)), compiled whole. An iteration of the
Python path makes about ten calls and 145 function calls, and its compiled motor
integration is a quarter of its time (docs/composite.md, "The sampler"); compiling its
pieces one by one did not pay, because numba unboxes a :class:`numpy.random.Generator`
argument on every call (12 us). Here the generator is passed once per run of iterations,
and the loop holds no GIL, so the chains' threads run side by side.

The loop is the Python path's arithmetic and draws, in its order (``tests/unit/
test_compiled_chain.py`` holds them equal, draw for draw), for white or AR(1) noise:

1. the opening density at the chain's ``tau`` (``CompositeProblem.log_collapsed``);
2. the u-move (``AdaptiveMetropolis.step`` / ``ShearedAM.step``): after burn-in, a jump
   from the mixture of t's with probability ``independence`` (its cumulative weights
   searched with one uniform, ``StudentTMixture.draw``), else a random-walk step in the
   walk's (sheared) coordinates; in burn-in the scale's Robbins-Monro step and the
   running covariance's Welford step;
3. the steps' uniform refresh (``UniformRefresh.step``);
4. bounded shares: the shares' own steps (``_Gibbs._share_steps``); every event's
   coefficients; with AR(1) noise, its coefficients and the sums whitened
   for them (``CompositeProblem.ar_statistics``, ``resum``); the noise precisions;
   ``log T0`` from its prior.

What it cannot do it hands back to Python between runs: a run ends after an iteration
whose Welford step asks for the covariance to be refreshed (every 20 draws in burn-in:
its eigendecomposition is NumPy's), and the caller never starts one across the shear's
switch at mid burn-in. The driver is :mod:`loadbayes.fit.composite.chain_fast`.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from loadbayes.fit.composite.bounded import SHARE_COORDS
from loadbayes.fit.composite.bounded_kernel import (
    bounded_terms,
    draw_gamma_one,
    share_steps,
    shares_one,
)
from loadbayes.fit.composite.problem import N_FREE, _collapsed
from loadbayes.fit.composite.sums import ar_residual_sums, ar_sums_into
from loadbayes.inference.compiled_draws import draw_beta_positive, draw_gammas, draw_rho_one
from loadbayes.inference.condlinear import log_marginal_arrays, residual_ss_arrays
from loadbayes.inference.moves.base import welford_step
from loadbayes.inference.moves.mixture import mixture_log_density
from loadbayes.inference.moves.sheared import sheared as _sheared
from loadbayes.inference.moves.sheared import unsheared as _unsheared

__all__ = ["run_iterations"]

# Indices into the float and integer vectors of the move's state (chain_fast packs them).
F_LOG_SCALE, F_TARGET, F_INDEPENDENCE, F_S_LO, F_S_HI, F_C2, F_Q, F_LOG_T0 = range(8)
(I_ADAPT_UNTIL, I_ADAPT_START, I_RUNNING_N, I_SHEARED, I_JUMPS, I_MULTI, I_STEPS,
 I_ACCEPTED, I_EVALUATIONS, I_JUMPED, I_JUMPS_ACCEPTED, I_REFRESH_STEPS,
 I_REFRESH_ACCEPTED, I_KERNEL_CALLS, I_Q_VALID, I_REFRESH_ASKED) = range(16)  # fmt: skip


@numba.njit(cache=True, nogil=True)
def _admissible(x, ns):  # pragma: no cover - compiled
    # CompositeProblem._admissible: every coordinate finite, the steps' fractions in [0, 1].
    for i in range(x.size):
        if not math.isfinite(x[i]):
            return False
    for i in range(N_FREE, N_FREE + ns):
        if not 0.0 <= x[i] <= 1.0:
            return False
    return True


@numba.njit(cache=True, nogil=True)
def _density(x, tau, kd, kc, ztz, zty, yty, pm, qm, ar, rho, bnd, pr):  # pragma: no cover
    # CompositeProblem.collapsed (plain; white noise, or AR(1) with coefficients rho): the
    # kernel's log density at x, its sums written into ztz, zty, yty and the motor's P, Q
    # into pm, qm; -inf where the kernel returns None. Bounded shares: the prior's log_u and
    # the shares' terms instead of the kernel's value (CompositeProblem._bounded_lp).
    (t_inv_u, a, b, c, h_max, xsums, seg, window, no_w, ns) = kc
    if not _admissible(x, ns):
        return -math.inf
    u5 = x[:N_FREE]
    phi = x[N_FREE : N_FREE + ns]
    # _collapsed's 45 arguments as tuples of fewer than 30 (Python builds a longer call's
    # arguments as a list, which numba cannot type).
    head = (u5, np.exp(u5 @ t_inv_u), tau, phi)
    tail = (a, b, c, h_max, xsums, False, no_w, pm, qm, ztz, zty, yty, ar, rho, seg, window)
    try:
        lp = _collapsed(*(head + kd + tail))
    except Exception:  # numpy.linalg.LinAlgError: a singular linear block
        return -math.inf
    if not math.isfinite(lp):
        return -math.inf
    if bnd[0]:
        return _log_u(x, pr) + _share_terms(x, tau, ztz, zty, yty, bnd)
    return lp


@numba.njit(cache=True, nogil=True)
def _log_u(u, pr):  # pragma: no cover - compiled
    # CompositePrior.log_u: (d @ prec) @ d, its order.
    d = u[:N_FREE] - pr[0]
    return -0.5 * ((d @ pr[1]) @ d)


@numba.njit(cache=True, nogil=True)
def _share_z(u, bnd, n_ev):  # pragma: no cover - compiled
    # CompositeProblem.share_z: the events' share log-ratios (E, 4), a copy.
    i0 = bnd[1]
    return u[i0 : i0 + SHARE_COORDS * n_ev].copy().reshape((n_ev, SHARE_COORDS))


@numba.njit(cache=True, nogil=True)
def _share_terms(u, tau, ztz, zty, yty, bnd):  # pragma: no cover - compiled
    # bounded_terms of CompositeProblem._bounded_lp, on the kernel's sums.
    _, _, nf, gamma_p0, sp_i, sp_mean, sp_sd, _, _ = bnd
    z = _share_z(u, bnd, yty.shape[0])
    return bounded_terms(z, ztz, zty, yty, nf, tau, gamma_p0, sp_i, sp_mean, sp_sd)


@numba.njit(cache=True, nogil=True)
def _opening(u, ztz, zty, yty, n, tau, m0, p0, pos, pr, ns, bnd):  # pragma: no cover
    # CompositeProblem.log_collapsed: the prior's log_u plus every event's log marginal at
    # tau (bounded shares: the shares' terms instead).
    if not _admissible(u, ns):
        return -math.inf
    out = _log_u(u, pr)
    if bnd[0]:
        return out + _share_terms(u, tau, ztz, zty, yty, bnd)
    for e in range(yty.shape[0]):
        try:
            out += log_marginal_arrays(ztz[e], zty[e], yty[e], n[e], tau, m0, p0, pos)
        except Exception:
            out += -math.inf
    return out


@numba.njit(cache=True, nogil=True)
def _take(ztz, zty, yty, p_ztz, p_zty, p_yty, ar, pm_s, qm_s, pm, qm):  # pragma: no cover
    # The proposal's sums become the state's (an accepted step): plain loops, which
    # compile in a fraction of the time of whole-array assignments of four dimensions.
    for e in range(ztz.shape[0]):
        for g in range(ztz.shape[1]):
            yty[e, g] = p_yty[e, g]
            for i in range(ztz.shape[2]):
                zty[e, g, i] = p_zty[e, g, i]
                for j in range(ztz.shape[3]):
                    ztz[e, g, i, j] = p_ztz[e, g, i, j]
    if ar:  # and the motor's P, Q, which the AR(1) step reads
        for i in range(pm.size):
            pm_s[i] = pm[i]
            qm_s[i] = qm[i]


@numba.njit(cache=True, nogil=True)
def _powers(s, lo, hi, c2):  # pragma: no cover - compiled
    # Shear._powers: s clipped, s^2 less its mean and s^3 (Python's float pow).
    s = min(max(s, lo), hi)
    return s * s - c2, math.pow(s, 3.0)


@numba.njit(cache=True, nogil=True)
def _walk(x, sheared, mf, sm, sd, se, c0, c1):  # pragma: no cover - compiled
    # ShearedAM._walk (Shear.forward), or the block itself.
    if not sheared:
        return x.copy()
    y = (x - sm) / sd
    a, b = _powers(np.dot(y, se), mf[F_S_LO], mf[F_S_HI], mf[F_C2])
    return _sheared(y, a, b, c0, c1)


@numba.njit(cache=True, nogil=True)
def _block(w, sheared, mf, sm, sd, se, c0, c1):  # pragma: no cover - compiled
    # ShearedAM._block (Shear.inverse), or the walk's point itself.
    if not sheared:
        return w
    a, b = _powers(np.dot(w, se), mf[F_S_LO], mf[F_S_HI], mf[F_C2])
    return _unsheared(w, a, b, c0, c1, sm, sd)


@numba.njit(cache=True, nogil=True)
def run_iterations(
    it0, count, burn, rng, u, tau, ztz, zty, yty, kd, kc, lin, prior, mf, mi, root,
    run_mean, run_m2, shear, jumps, q_x, refresh_index, refresh_share, ar, rho, pm_s, qm_s,
    rho_max, bnd, u_move, u_out, theta_out, beta_out, tau_out, rho_out,
):  # fmt: skip  # pragma: no cover - compiled
    """Iterations ``it0 .. it0 + count - 1`` of the plain chain; how many it ran.

    ``u`` (d,), ``tau`` (G,) and the sums ``ztz`` (E, G, k, k), ``zty`` (E, G, k), ``yty``
    (E, G) are the chain's state, updated in place. ``lin``: ``(n (E, G), m0, p0,
    positive, n_tot (G,), tau shape, tau rate)``; ``prior``: ``(mean, prec, gain, theta
    mean of log T0, sd of log T0 | u, T^-1 on u (5, 7), T^-1 on log T0 (7,))``. ``mf``,
    ``mi``: the move's floats and integers (the ``F_*`` and ``I_*`` indices, counters
    among them, updated in place), ``root`` its proposal's square root, ``run_mean``,
    ``run_m2`` its running covariance's sums; ``shear``: ``(m, D, e, A's rows)``;
    ``jumps``: the mixture's arrays (:meth:`StudentTMixture.arrays`); ``q_x``: the point
    whose jump density ``mf[F_Q]`` holds (``mi[I_Q_VALID]``). Each iteration ``i`` writes
    the u after its move (``u_move``), after the whole iteration (``u_out``), theta,
    every event's beta and tau. ``bnd``: bounded shares, ``(on, first index in u, n (E, G)
    as floats, gamma's prior precisions, the share priors' index, mean and sd, the share
    steps' scales (E,), updated in place, steps per iteration)``. With ``ar``, AR(1)
    noise: ``rho`` (G,) its coefficients and ``pm_s``, ``qm_s`` the motor's P, Q at ``u``
    (the state's, updated in place), the sums whitened for ``rho``; each iteration draws
    ``rho`` (``rho_out``) after beta.
    The run stops early after an iteration whose Welford step asks for the covariance's
    refresh (``mi[I_REFRESH_ASKED]`` is then 1).
    """
    n, m0, p0, pos, n_tot, shape, rate = lin
    p_mean, p_prec, gain, t0_mean, t0_sd, t_inv_u, t_inv_t0 = prior
    pr = (p_mean, p_prec)
    bounded, _, nf, gamma_p0, sp_i, sp_mean, sp_sd, share_scale, share_n = bnd
    sm, sd, se, c0, c1 = shear
    cdf, j_means, j_roots, j_inv, j_const, j_dofs = jumps
    ns = kc[9]
    xs, ps, qs, starts, seg = kd[14], kd[15], kd[16], kd[17], kc[6]
    d = u.size
    n_ev = yty.shape[0]
    sheared = mi[I_SHEARED] == 1
    # The proposal's sums and the kernel's scratch (a rejected proposal leaves the state's).
    p_ztz, p_zty, p_yty = np.empty_like(ztz), np.empty_like(zty), np.empty_like(yty)
    size = kd[17][-1]
    pm, qm = np.empty(size), np.empty(size)
    mi[I_REFRESH_ASKED] = 0
    done = 0
    for i in range(count):
        it = it0 + i
        lp = _opening(u, ztz, zty, yty, n, tau, m0, p0, pos, pr, ns, bnd)
        # The u-move: a jump after burn-in, else the walk.
        jump = False
        if mf[F_INDEPENDENCE] > 0.0 and it >= mi[I_ADAPT_UNTIL] and mi[I_JUMPS] > 0:
            jump = rng.random() < mf[F_INDEPENDENCE]
        if jump:
            k = 0
            if mi[I_MULTI] == 1:
                k = np.searchsorted(cdf, rng.random(), side="right")
            z = rng.standard_normal(d)
            nu = j_dofs[k]
            w_prop = j_means[k] + math.sqrt(nu / rng.chisquare(nu)) * (j_roots[k] @ z)
            prop = _block(w_prop, sheared, mf, sm, sd, se, c0, c1)
            lp_prop = _density(prop, tau, kd, kc, p_ztz, p_zty, p_yty, pm, qm, ar, rho, bnd, pr)
            mi[I_KERNEL_CALLS] += 1
            mi[I_STEPS] += 1
            mi[I_EVALUATIONS] += 1
            mi[I_JUMPED] += 1
            log_u = math.log(rng.random())
            if math.isfinite(lp_prop):
                q_prop = mixture_log_density(w_prop, j_means, j_inv, j_const, j_dofs)
                if mi[I_Q_VALID] == 1 and np.all(q_x == u):
                    q_cur = mf[F_Q]
                else:
                    q_cur = mixture_log_density(_walk(u, sheared, mf, sm, sd, se, c0, c1),
                                                j_means, j_inv, j_const, j_dofs)  # fmt: skip
                    q_x[:] = u
                    mf[F_Q] = q_cur
                    mi[I_Q_VALID] = 1
                if log_u < lp_prop - lp + q_cur - q_prop:
                    mi[I_ACCEPTED] += 1
                    mi[I_JUMPS_ACCEPTED] += 1
                    u[:] = prop
                    lp = lp_prop
                    _take(ztz, zty, yty, p_ztz, p_zty, p_yty, ar, pm_s, qm_s, pm, qm)
                    q_x[:] = prop
                    mf[F_Q] = q_prop
                    mi[I_Q_VALID] = 1
        else:
            w = _walk(u, sheared, mf, sm, sd, se, c0, c1)
            z = rng.standard_normal(d)
            w_prop = w + math.exp(0.5 * mf[F_LOG_SCALE]) * (root @ z)
            prop = _block(w_prop, sheared, mf, sm, sd, se, c0, c1)
            lp_prop = _density(prop, tau, kd, kc, p_ztz, p_zty, p_yty, pm, qm, ar, rho, bnd, pr)
            mi[I_KERNEL_CALLS] += 1
            log_u = math.log(rng.random())
            finite = math.isfinite(lp_prop)
            alpha = min(1.0, math.exp(min(0.0, lp_prop - lp))) if finite else 0.0
            mi[I_STEPS] += 1
            mi[I_EVALUATIONS] += 1
            if finite and log_u < lp_prop - lp:
                mi[I_ACCEPTED] += 1
                u[:] = prop
                lp = lp_prop
                _take(ztz, zty, yty, p_ztz, p_zty, p_yty, ar, pm_s, qm_s, pm, qm)
                w = w_prop
            if it < mi[I_ADAPT_UNTIL]:
                mf[F_LOG_SCALE] += (alpha - mf[F_TARGET]) / math.sqrt(it + 1.0)
                mi[I_RUNNING_N] += 1
                nr = mi[I_RUNNING_N]
                welford_step(run_mean, run_m2, w, float(nr))
                if nr >= mi[I_ADAPT_START] and nr % 20 == 0:
                    mi[I_REFRESH_ASKED] = 1
        u_move[i] = u
        # The steps' fractions, refreshed now and then across [0, 1].
        if refresh_share > 0.0 and refresh_index.size > 0 and rng.random() < refresh_share:
            if refresh_index.size > 1:
                j = refresh_index[rng.integers(0, refresh_index.size)]
            else:
                j = refresh_index[0]
            prop = u.copy()
            prop[j] = rng.uniform(0.0, 1.0)
            lp_prop = _density(prop, tau, kd, kc, p_ztz, p_zty, p_yty, pm, qm, ar, rho, bnd, pr)
            mi[I_KERNEL_CALLS] += 1
            mi[I_REFRESH_STEPS] += 1
            if math.isfinite(lp_prop) and math.log(rng.random()) < lp_prop - lp:
                mi[I_REFRESH_ACCEPTED] += 1
                u[:] = prop
                lp = lp_prop
                _take(ztz, zty, yty, p_ztz, p_zty, p_yty, ar, pm_s, qm_s, pm, qm)
        if bounded:  # the shares' own steps (no motor solve): _Gibbs._share_steps
            z = _share_z(u, bnd, n_ev)
            share_steps(z, ztz, zty, yty, nf, tau, gamma_p0, sp_i, sp_mean, sp_sd, share_n,
                        rng, share_scale, it < burn)  # fmt: skip
            i_s = bnd[1]
            for e in range(n_ev):
                for j in range(SHARE_COORDS):
                    u[i_s + SHARE_COORDS * e + j] = z[e, j]
        # Every event's coefficients, the noise precisions, log T0 from its prior.
        for e in range(n_ev):
            if bounded:
                a_e = shares_one(u[bnd[1] + SHARE_COORDS * e : bnd[1] + SHARE_COORDS * (e + 1)])
                beta_out[i, e] = draw_gamma_one(a_e, ztz[e], zty[e], tau, gamma_p0, rng)
            else:
                beta_out[i, e] = draw_beta_positive(ztz[e], zty[e], tau, m0, p0, pos, rng)
        if ar:  # rho | u, beta, tau; then the sums whitened for it (problem.resum)
            stats = np.zeros((2, 4))
            for e in range(n_ev):
                s0, s1 = starts[e], starts[e + 1]
                stats += ar_residual_sums(xs[s0:s1], pm_s[s0:s1], qm_s[s0:s1], ps[s0:s1],
                                          qs[s0:s1], seg[s0:s1], beta_out[i, e])  # fmt: skip
            for g in range(2):
                rho[g] = draw_rho_one(stats[g], tau[g], rho[g], rng, rho_max)
            for e in range(n_ev):
                s0, s1 = starts[e], starts[e + 1]
                ar_sums_into(xs[s0:s1], pm_s[s0:s1], qm_s[s0:s1], ps[s0:s1], qs[s0:s1],
                             seg[s0:s1], rho, ztz[e], zty[e], yty[e])  # fmt: skip
            rho_out[i] = rho
        ssr = np.zeros(yty.shape[1])
        for e in range(n_ev):
            ssr = ssr + residual_ss_arrays(ztz[e], zty[e], yty[e], beta_out[i, e])
        tau[:] = draw_gammas(shape, n_tot, rate, ssr, rng)
        u5 = u[:N_FREE]
        log_t0 = t0_mean + gain @ (u5 - p_mean) + t0_sd * rng.standard_normal()
        u_out[i] = u
        theta_out[i] = u5 @ t_inv_u + log_t0 * t_inv_t0
        tau_out[i] = tau
        mf[F_LOG_T0] = log_t0
        done = i + 1
        if mi[I_REFRESH_ASKED] == 1:
            break
    return done
