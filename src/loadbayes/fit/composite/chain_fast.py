"""Running a plain zip+motor chain through the compiled loop (``chain_loop.py``).

:func:`runs_compiled` says whether a chain's iterations can run compiled: a ``zip+motor``
problem (:class:`~loadbayes.fit.composite.problem.CompositeProblem`: free or bounded
shares, Gaussian noise white or AR(1), no prior factor on the coefficients, no estimated
torque) moved by ``am`` or ``shear``, whose jumps (if any) are a mixture of t's. Student-t
noise, the models of parts and the slice move run the Python iteration,
:meth:`_Gibbs.step`.

:func:`step_batch` is what :meth:`loadbayes.inference.chain.Chain.run_batched` calls:
it hands the chain's state and its move's to the compiled loop, and between the loop's
runs does in Python what the Python path does there once (the shear's switch at mid
burn-in, the covariance's refresh every 20 burn-in draws, the jumps' first fit), keeps
the burn-in draws the move and the jumps learn from, and stores the kept draws. The
draws are the Python path's, bit for bit (``tests/unit/test_compiled_chain.py``).
:data:`COMPILED` switches it off (the tests' comparison, and a fallback to name).
"""

from __future__ import annotations

import numpy as np

from loadbayes.fit.composite import chain_loop as L
from loadbayes.fit.composite.problem import (
    _NO_WEIGHTS,
    _T_INV_T0,
    _T_INV_U,
    CompositeProblem,
    ResponseSums,
)
from loadbayes.inference.ar1 import RHO_MAX
from loadbayes.inference.condlinear import GroupSums
from loadbayes.inference.moves.adaptive_metropolis import AdaptiveMetropolis
from loadbayes.inference.moves.mixture import StudentTMixture
from loadbayes.inference.moves.sheared import ShearedAM

__all__ = ["BATCH", "COMPILED", "compiled_run", "runs_compiled", "step_batch"]

#: Whether plain chains run compiled (False: every chain runs the Python iteration).
COMPILED = True
#: Iterations per call of :func:`step_batch`: the stop flag, the deadline and the
#: progress are looked at between them (a few ms to a few tenths of a second).
BATCH = 256

_NO_JUMPS = (np.ones(1), np.zeros((1, 1)), np.zeros((1, 1, 1)), np.zeros((1, 1, 1)),
             np.zeros(1), np.ones(1))  # fmt: skip


def compiled_run(problem, move: str, student_t=None, factor=None) -> bool:
    """Whether a run of ``sample`` with these settings runs its chains compiled.

    Asked before the chains exist: the thread count is chosen by it.
    """
    return bool(
        COMPILED
        and type(problem) is CompositeProblem
        and move in ("am", "shear")
        and student_t is None
        and not (factor is not None and factor.active)
        and problem.dim == problem.n_free + problem.n_steps + problem.n_share_coords
    )


def runs_compiled(gibbs) -> bool:
    """Whether ``gibbs`` (a :class:`~loadbayes.fit.composite.sampler._Gibbs`) runs compiled."""
    p, move = gibbs.problem, gibbs.am
    refresh = gibbs.refresh
    return bool(
        COMPILED
        and type(p) is CompositeProblem
        and gibbs.wt is None
        and gibbs.tilted is None
        and gibbs.own_moves is None
        and gibbs.block_steps == 1
        and p.dim == gibbs.n_base + p.n_share_coords
        and type(move) in (AdaptiveMetropolis, ShearedAM)
        and (refresh is None or (refresh.low, refresh.high) == (0.0, 1.0))
        and gibbs.start.sums is not None
        and gibbs.late_lp is None
    )


def _jumps_ready(move, it: int):
    # The one-off of AdaptiveMetropolis.step after burn-in: the jumps' first fit. Returns
    # the mixture's arrays, or None when the jump is another proposal (the Python path).
    if not (move.independence and it >= move.adapt_until):
        return _NO_JUMPS, 0, 0
    jump = move._jump_proposal()
    if jump is None:
        return _NO_JUMPS, 0, 0
    if not isinstance(jump, StudentTMixture):
        return None
    return jump.arrays(), jump.components, int(jump.components > 1)


def _shear_arrays(move):
    shear = getattr(move, "shear", None)
    if shear is None:
        z = np.zeros(move.d)
        return False, (z, z, z, z, z), (0.0, 0.0, 0.0)
    c0, c1 = shear._rows()
    e = np.ascontiguousarray(shear.e)
    return True, (shear.m, shear.D, e, c0, c1), (shear.s_lo, shear.s_hi, shear.c2)


def step_batch(gibbs, state, rng, start: int, count: int, bufs, kept0: int):
    """Iterations ``start .. start + count - 1`` of a plain chain (``Chain.run_batched``)."""
    p, move, burn, thin = gibbs.problem, gibbs.am, gibbs.burn, gibbs.thin
    state_type = type(gibbs.start)  # sampler._State (not imported: sampler imports this)
    prior = p.prior
    p_mean, _, gain, t0_sd = prior.scale_free()
    prior.log_u(np.asarray(state.u, dtype=float)[: p.n_free])  # makes prior._prec_u
    prior_args = (p_mean, prior._prec_u, gain, float(prior.theta_mean[5]), float(t0_sd),
                  _T_INV_U, _T_INV_T0)  # fmt: skip
    lin = (np.asarray(p.samples.n, dtype=float), p.m0, p.p0, int(p._kernel_data[23]),
           np.asarray(gibbs.n_tot, dtype=float), float(prior.tau_shape),
           float(prior.tau_rate))  # fmt: skip
    a, b, c = p._torque
    kc = (_T_INV_U, a, b, c, float(p.h_max), p._xsums, p.seg, float(p.window), _NO_WEIGHTS,
          p._n_steps)  # fmt: skip
    ar = "rho" in gibbs.fields  # AR(1) noise: its coefficients and the motor's P, Q
    rho = np.array(state.rho, dtype=float) if ar else np.zeros(2)
    pm_s = np.array(state.sums.pm, dtype=float) if ar else np.zeros(0)
    qm_s = np.array(state.sums.qm, dtype=float) if ar else np.zeros(0)
    rho_max = float(getattr(p, "rho_max", RHO_MAX))
    bnd = _bounded(gibbs)
    refresh = gibbs.refresh
    r_index = np.zeros(0, dtype=np.int64) if refresh is None else refresh.index.astype(np.int64)
    r_share = 0.0 if refresh is None else float(refresh.share)
    u = np.array(state.u, dtype=float)
    tau = np.array(state.tau, dtype=float)
    ztz = np.stack([s.ztz for s in state.sums])
    zty = np.stack([s.zty for s in state.sums])
    yty = np.stack([s.yty for s in state.sums])
    d, n_ev = u.size, len(p.events)
    u_move, u_out = np.empty((count, d)), np.empty((count, d))
    theta_out = np.empty((count, p.n_theta))
    beta_out, tau_out = np.empty((count, n_ev, p.n_beta)), np.empty((count, tau.size))
    rho_out = np.empty((count, 2))
    betas, log_t0 = state.betas, state.log_t0
    it, end = start, start + count
    while it < end:
        if isinstance(move, ShearedAM):
            move.learn_shear(it)  # its one-off at mid burn-in
        ready = _jumps_ready(move, it)
        if ready is None:  # not a mixture: the Python iteration from here
            m = it - start
            _store(bufs, kept0, start, m, burn, thin, theta_out[:m], beta_out[:m], tau_out[:m],
                   u_out[:m], rho_out[:m], p._n_steps, gibbs.n_base, p.n_free)  # fmt: skip
            here = state_type(
                u,
                _sums(p, ztz, zty, yty, ar, pm_s, qm_s),
                tau,
                rho.copy() if ar else None,
                betas,
                log_t0,
            )
            return _python(gibbs, here, rng, it, end, bufs, kept0)
        jumps, n_jumps, multi = ready
        stop = end
        if isinstance(move, ShearedAM) and move.shear is None and it < move._switch:
            stop = min(end, move._switch)
        if it < move.adapt_until:  # the jumps are looked at again where burn-in ends
            stop = min(stop, move.adapt_until)
        sheared, shear, sf = _shear_arrays(move)
        q = move._q_current
        q_x = np.array(q[0], dtype=float) if q is not None else np.zeros(d)
        running = move._running
        mf = np.array([move.log_scale, move.target, move.independence, *sf,
                       q[1] if q is not None else 0.0, 0.0])  # fmt: skip
        mi = np.zeros(16, dtype=np.int64)
        mi[[L.I_ADAPT_UNTIL, L.I_ADAPT_START, L.I_RUNNING_N, L.I_SHEARED, L.I_JUMPS, L.I_MULTI,
            L.I_Q_VALID]] = (move.adapt_until, running.adapt_start, running._n, sheared,
                             n_jumps, multi, q is not None)  # fmt: skip
        root = np.ascontiguousarray(move._root)
        i0 = it - start
        done = L.run_iterations(
            it, stop - it, burn, rng, u, tau, ztz, zty, yty, p._kernel_data, kc, lin,
            prior_args, mf, mi, root, running._mean, running._m2, shear, jumps, q_x, r_index,
            r_share, ar, rho, pm_s, qm_s, rho_max, bnd, u_move[i0:], u_out[i0:], theta_out[i0:],
            beta_out[i0:], tau_out[i0:], rho_out[i0:],
        )  # fmt: skip
        # The move's state back into its objects.
        move.log_scale = float(mf[L.F_LOG_SCALE])
        move.steps += int(mi[L.I_STEPS])
        move.accepted += int(mi[L.I_ACCEPTED])
        move.evaluations += int(mi[L.I_EVALUATIONS])
        move.jumps += int(mi[L.I_JUMPED])
        move.jumps_accepted += int(mi[L.I_JUMPS_ACCEPTED])
        running._n = int(mi[L.I_RUNNING_N])
        p.evaluations += int(mi[L.I_KERNEL_CALLS])
        if refresh is not None:
            refresh.steps += int(mi[L.I_REFRESH_STEPS])
            refresh.accepted += int(mi[L.I_REFRESH_ACCEPTED])
        move._q_current = (q_x.copy(), float(mf[L.F_Q])) if mi[L.I_Q_VALID] else None
        if mi[L.I_REFRESH_ASKED]:
            running.refresh()
            move._refresh()
        _learned(gibbs, it, done, u_move[i0:], u_out[i0:])
        betas = [beta_out[i0 + done - 1, e].copy() for e in range(n_ev)]
        log_t0 = float(mf[L.F_LOG_T0])
        it += done
    _store(bufs, kept0, start, count, burn, thin, theta_out, beta_out, tau_out, u_out, rho_out,
           p._n_steps, gibbs.n_base, p.n_free)  # fmt: skip
    return state_type(
        u, _sums(p, ztz, zty, yty, ar, pm_s, qm_s), tau, rho.copy() if ar else None, betas, log_t0
    )


def _bounded(gibbs) -> tuple:
    # The bounded shares' arguments of the loop (chain_loop.run_iterations' ``bnd``), the
    # same types for free shares (one compiled loop for both).
    p = gibbs.problem
    nf = np.asarray(p.samples.n, dtype=float)
    if not p.bounded:
        none = np.zeros(0)
        return (False, 0, nf, np.zeros(3), np.zeros(0, dtype=np.int64), none, none,
                np.zeros(len(p.events)), 0)  # fmt: skip
    if gibbs.share_scale is None:  # _Gibbs._share_steps's start
        gibbs.share_scale = np.full(len(p.events), 0.3)
    return (True, gibbs.n_base, nf, *p._share_fixed(), gibbs.share_scale, gibbs.share_steps_n)


def _sums(p, ztz, zty, yty, ar, pm, qm):
    # The events' GroupSums, as CompositeProblem.group_sums makes them (AR(1): with the
    # motor's P, Q, as CompositeProblem.resum).
    groups = [GroupSums(ztz[e], zty[e], yty[e], n) for e, n in enumerate(p._n_rows)]
    return ResponseSums(groups, pm, qm) if ar else groups


def _learned(gibbs, it: int, done: int, u_move, u_out) -> None:
    # What the Python path keeps of burn-in iterations it .. it + done - 1: the shear's
    # history (the move's u, second quarter of the burn-in) and the jumps' (late) burn-in.
    move, burn = gibbs.am, gibbs.burn
    if isinstance(move, ShearedAM) and move.shear is None:
        lo, hi = max(it, move._switch // 2), min(it + done, move._switch)
        move._history.extend(np.array(r) for r in u_move[lo - it : hi - it])
    if gibbs.late_burn is not None:
        lo, hi = max(it, burn // 2), min(it + done, burn)
        gibbs.late_burn.extend(np.array(r) for r in u_out[lo - it : hi - it])
    if gibbs.kept_u is not None:  # bounded shares: every refit_thin-th kept u
        thin = gibbs.refit_thin
        gibbs.kept_u.extend(np.array(u_out[k - it]) for k in range(max(it, burn), it + done)
                            if k % thin == 0)  # fmt: skip


def _store(bufs, kept0, start, count, burn, thin, theta, beta, tau, u, rho, ns, n_base,
           n_free) -> None:  # fmt: skip
    # The kept iterations' fields (Chain.record's), row k - kept0 for the k-th kept draw.
    its = np.arange(start, start + count)
    keep = (its >= burn) & ((its - burn) % thin == 0)
    if not keep.any():
        return
    k = (its[keep] - burn) // thin - kept0
    bufs["theta"][k] = theta[keep]
    bufs["beta"][k] = beta[keep]
    bufs["tau"][k] = tau[keep]
    bufs["phi"][k] = u[keep][:, n_free : n_free + ns]
    bufs["u_extra"][k] = u[keep][:, n_base:]
    if "rho" in bufs:
        bufs["rho"][k] = rho[keep]


def _python(gibbs, state, rng, it, end, bufs, kept0):
    # The Python iteration for the rest of the batch, stored as Chain.run stores it.
    burn, thin = gibbs.burn, gibbs.thin
    while it < end:
        state = gibbs.step(state, rng, it)
        if it >= burn and (it - burn) % thin == 0:
            for name, value in gibbs.record(state).items():
                bufs[name][(it - burn) // thin - kept0] = value
        it += 1
    return state
