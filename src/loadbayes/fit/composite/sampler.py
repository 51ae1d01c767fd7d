"""The composite fit's sampler: Metropolis-within-Gibbs on the collapsed density.

Each iteration: a block move on the sampled vector ``u`` (the motor's scale-free
coordinates, the steps' fractions, any torque log-ratios) with the linear coefficients
integrated out; each event's coefficients exactly; the noise precisions (and, with
Student-t noise, the weights); ``log T0`` from its prior conditional. The moves are
physics-free (:mod:`loadbayes.inference.moves`, whose :data:`MOVES` are the u-moves
:func:`sample` offers); docs/composite.md, "The sampler".
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from loadbayes.core.parallel import chain_generators, check_stop, run_chains
from loadbayes.core.settings import check_iterations
from loadbayes.fit.composite.nls import NLSResult
from loadbayes.fit.composite.problem import CompositeProblem, theta_of
from loadbayes.inference.condlinear import (
    draw_beta,
    draw_tau,
    residual_ss,
)
from loadbayes.inference.moves import MOVES
from loadbayes.models.composite_prior import POSITIVE_BETA

__all__ = ["DEFAULT_MOVE", "MOVES", "ChainResult", "sample"]

#: The default u-move: the better ESS per second on the benchmark (docs/composite.md).
DEFAULT_MOVE = "am"
#: Seconds between two progress reports of one chain.
PROGRESS_EVERY_S = 0.2


@dataclass
class ChainResult:
    """One chain's kept draws and acceptance."""

    theta: np.ndarray  # (kept, 6) THETA_NAMES
    beta: np.ndarray  # (kept, events, 7)
    tau: np.ndarray  # (kept, 2)
    acceptance: float
    phi: np.ndarray | None = None  # (kept, steps) fractions of the step intervals
    evaluations_per_iteration: float = 1.0  # collapsed-density evaluations of the u-move
    # Coordinates of u after the motor's five and the steps (estimated torque shares).
    u_extra: np.ndarray | None = None
    # Student-t only (fit.composite_robust): nu draws (kept, 2), mean weights (2, n).
    nu: np.ndarray | None = None
    weight: np.ndarray | None = None
    nu_acceptance: float | None = None


def sample(
    problem: CompositeProblem,
    *,
    start: NLSResult,
    draws: int = 5000,
    burn: int = 2000,
    thin: int = 1,
    chains: int = 4,
    seed: int = 0,
    workers: int | None = None,
    dispersion: float = 2.0,
    move: str = DEFAULT_MOVE,
    student_t: Any = None,
    progress: Callable[[int], None] | None = None,
) -> list[ChainResult]:
    """Metropolis-within-Gibbs for the composite model.

    Each iteration: the scale-free motor coordinates ``u | tau`` by adaptive Metropolis
    on the collapsed density (beta integrated out); every event's
    ``beta | u, tau`` exactly; ``tau | u, beta`` (two gammas); ``log T0 | u`` from its
    prior conditional (the likelihood does not depend on it). The proposal starts from
    the Laplace covariance (the NLS one) and adapts during ``burn``, then freezes.
    Chains start ``dispersion`` Laplace sds around the NLS estimate (for R-hat).

    Parameters
    ----------
    problem : CompositeProblem
        Data, prior, settings.
    start : NLSResult
        From :func:`nls`.
    draws, burn, thin, chains : int
        Iterations per chain including burn-in, burn-in, thinning, chains.
    seed : int
        Root seed (chain ``i`` uses child ``i`` of ``SeedSequence(seed)``).
    workers : int, optional
        Threads for the chains.
    dispersion : float
        Spread of the chains' starting points, in Laplace sds.
    move : {"am", "slice"}
        The u-move (:data:`MOVES`): adaptive Metropolis, or factor slice sampling in
        the eigenbasis of the covariance learned in burn-in (docs/composite.md, "Why
        this move").
    student_t : loadbayes.fit.composite.robust.StudentT, optional
        Student-t noise (a weights step each iteration); Gaussian noise when None.
    progress : callable, optional
        Called with a number of iterations just done (of ``chains * draws``), about every
        :data:`PROGRESS_EVERY_S` seconds per chain, from the chains' threads.

    Returns
    -------
    list of ChainResult
    """
    check_iterations(draws, burn, thin, chains)
    if move not in MOVES:
        raise ValueError(f"move must be one of {sorted(MOVES)}, got {move!r}")
    prior = problem.prior
    # The motor's five, the steps' fractions, then any extra coordinates (torque shares).
    d = dim = problem.dim
    n_base = 5 + problem.n_steps
    lap = start.cov[:d, :d]
    lap = (lap + lap.T) / 2
    # A step the data barely place has a Laplace sd far wider than its [0, 1] support:
    # start its proposal at the support's scale instead (the adaptation takes over).
    shrink = np.ones(d)
    shrink[5:] = np.minimum(1.0, 0.3 / np.sqrt(np.diag(lap)[5:]))
    lap = lap * np.outer(shrink, shrink)
    tau0 = 1.0 / start.sigma**2
    n_tot = np.array([sum(e.n for e in problem.events)] * 2, dtype=float)
    kept_idx = range(burn, draws, thin)
    root = np.linalg.cholesky(lap + 1e-12 * np.eye(dim))
    # The chains' stop flag: SIGINT/SIGTERM (core.parallel.request_stop) or a failed
    # chain end every chain within one iteration, not when the chains finish.
    stop = threading.Event()

    def chain(index: int, rng: np.random.Generator) -> ChainResult:
        am = MOVES[move](lap, adapt_until=burn, adapt_start=min(200, max(burn // 4, 1)))
        u, sums = start.u, None
        for _ in range(100):
            cand = start.u + dispersion * root @ rng.standard_normal(dim)
            sums = problem.sums(cand)
            if sums is not None:
                u = cand
                break
        if sums is None:
            u, sums = start.u, problem.sums(start.u)
        tau = tau0.copy()
        th_out = np.empty((len(kept_idx), 6))
        phi_out = np.empty((len(kept_idx), problem.n_steps))
        b_out = np.empty((len(kept_idx), len(problem.events), 7))
        t_out = np.empty((len(kept_idx), 2))
        x_out = np.empty((len(kept_idx), dim - n_base))
        j = 0
        # Student-t noise: the weights' state (None for the Gaussian, whose path is unchanged).
        wt = None if student_t is None else student_t.chain(problem, u, tau, len(kept_idx))
        if wt is not None:
            sums = wt.sums
        told, last = 0, time.perf_counter()
        for it in range(draws):
            check_stop(stop)
            if progress is not None and time.perf_counter() - last > PROGRESS_EVERY_S:
                progress(it - told)
                told, last = it, time.perf_counter()
            if wt is None:
                lp = problem.log_collapsed(sums, u, tau)

                def logp(x, tau=tau):
                    return problem.collapsed(x, tau)

            else:
                lp, logp = wt.current(u, tau), wt.logp(tau)
            u, lp, sums, _ = am.step(u, lp, logp, rng, it, aux=sums)
            betas = [
                draw_beta(s, tau, problem.m0, problem.p0, rng, positive=POSITIVE_BETA) for s in sums
            ]
            if wt is not None:  # (nu, lambda) | u, beta, tau; then tau sees the weighted SSR
                sums = wt.update(sums, betas, tau, rng, it >= burn and (it - burn) % thin == 0)
            ssr = sum(residual_ss(s, b) for s, b in zip(sums, betas, strict=True))
            tau = draw_tau(ssr, n_tot, prior.tau_shape, prior.tau_rate, rng)
            log_t0 = prior.draw_log_t0(u[:5], rng)
            if it >= burn and (it - burn) % thin == 0:
                th_out[j] = theta_of(u[:5], log_t0)
                phi_out[j] = problem.phi(u)
                x_out[j] = u[n_base:]
                b_out[j], t_out[j] = np.array(betas), tau
                j += 1
        if progress is not None:
            progress(draws - told)
        robust = {}
        if wt is not None:
            robust = dict(zip(("nu", "weight", "nu_acceptance"), wt.result(), strict=True))
        return ChainResult(
            th_out,
            b_out,
            t_out,
            am.acceptance,
            phi=phi_out,
            evaluations_per_iteration=am.evaluations_per_step,
            u_extra=x_out if dim > n_base else None,
            **robust,
        )

    return run_chains(chain, chain_generators(seed, chains), workers=workers, stop=stop)
