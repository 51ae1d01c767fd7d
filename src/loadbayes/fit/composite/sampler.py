"""The composite fit's sampler: Metropolis-within-Gibbs on the collapsed density.

One idea needs these 689 lines: the composite's Metropolis-within-Gibbs sweep (one
``step`` that :class:`loadbayes.inference.chain.Chain` drives), with its jump proposal
and the chains' result. A plain ``zip+motor`` chain runs the same sweep compiled whole
(``chain_loop.py``, driven by ``chain_fast.py``: the same draws).
Each iteration: a block move on the sampled vector ``u`` (the motor's scale-free
coordinates, the steps' fractions, any torque log-ratios) with the linear coefficients
integrated out; each event's coefficients exactly; the noise precisions (and, with
Student-t noise, the weights); ``log T0`` from its prior conditional. The moves are
physics-free (:mod:`loadbayes.inference.moves`, whose :data:`MOVES` are the u-moves
:func:`sample` offers); the Metropolis moves also jump, after burn-in, from a t fitted to
every chain's late burn-in pooled (:data:`JUMP_SHARE`), and for a plain zip+motor from
t's along the posterior's ridge in ``log T'`` that the NLS's profile finds
(:data:`JUMP_RIDGE`, ``ridge.py``); docs/composite.md, "The sampler", "Jumps" and "Jumps
placed from the data". The steps' fractions are also refreshed across [0, 1] now and then
(:data:`REFRESH_SHARE`): an edge's instant can have a minor mode the jumps cannot leave.
A model of parts may ask for its chains that ended their burn-in in a far lower mode to
go on from the best chain's state (``restart.py``), said in words, and may ask for several
steps of the block move per iteration in a long run (:func:`block_steps`,
:data:`BLOCK_STEPS_MIN_BURN`; ``cmld-lite``: 12, one of them a jump on average,
:func:`jump_share`).
A ``deadline`` (the time budget) holds from the first iteration: past it the chains end
their burn-in and stop with what they drew (:class:`~loadbayes.inference.chain.Chain`),
all cut to the same length (:attr:`ChainResult.cut` says how many iterations the
deadline took); a run it never binds keeps its draws.
"""

from __future__ import annotations

import copy
import math
import threading
from collections.abc import Callable
from dataclasses import dataclass
from functools import partial
from typing import Any, NamedTuple

import numpy as np

from loadbayes.core.forked import Relay, SharedFlag, can_fork, run_forked
from loadbayes.core.parallel import asked_threads, chain_generators, num_threads, run_chains
from loadbayes.core.settings import check_iterations
from loadbayes.fit.composite.bounded import SHARE_COORDS
from loadbayes.fit.composite.bounded_kernel import share_steps
from loadbayes.fit.composite.chain_fast import BATCH, compiled_run, runs_compiled, step_batch
from loadbayes.fit.composite.checks import MIN_KEPT
from loadbayes.fit.composite.nls import NLSResult
from loadbayes.fit.composite.problem import CompositeProblem
from loadbayes.fit.composite.restart import late_gaps, restart_lagging
from loadbayes.fit.composite.restart import words as restart_words
from loadbayes.fit.composite.ridge import cached_ridge_points
from loadbayes.inference.ar1 import RHO_MAX, draw_rho
from loadbayes.inference.chain import Chain, is_kept
from loadbayes.inference.condlinear import draw_tau, residual_ss
from loadbayes.inference.moves import MOVES, BlockState
from loadbayes.inference.moves.adaptive_metropolis import JUMP_MIN_DRAWS
from loadbayes.inference.moves.refresh import UniformRefresh

__all__ = ["BLOCK_STEPS_MIN_BURN", "DEFAULT_MOVE", "JUMP_SHARE", "MOVES",
           "ONE_EVALUATION_MOVES", "ONE_THREAD_SAMPLES", "REFRESH_SHARE", "ChainResult",
           "block_steps", "chain_processes", "chain_threads", "jump_share", "sample",
           "steps_per_iteration"]  # fmt: skip

#: The default u-move: the better ESS per second on the benchmark (docs/composite.md).
DEFAULT_MOVE = "shear"
#: The moves that take one density evaluation per step, as the prior factors' estimated
#: density (importance weights) needs: a slice move cannot use an estimated density.
ONE_EVALUATION_MOVES = ("am", "shear")
#: Share of the Metropolis moves' steps after burn-in that jump (an independence
#: proposal from a t fitted to the burn-in, inference.moves.adaptive_metropolis): the
#: random walk alone crossed the narrow lower tail of T' in issue 21's 120/s event so
#: slowly that a chain sat there for thousands of iterations (docs/composite.md, "Jumps").
JUMP_SHARE = 0.35
#: The zip+motor's jumps propose from a mixture of this many t's over regions of the pooled
#: burn-in (inference.moves.mixture): one t accepted 2.3% of its jumps on the real
#: record's first fault, whose T' has a long one-sided tail; the mixture 22-31%
#: (docs/composite.md, "Jumps from regions"). A model of parts asks for its own
#: (``jump_regions``: ``cmld-lite``'s chains find two modes, which the regions join).
JUMP_COMPONENTS = 10
#: Share of the iterations that also refresh one step's fraction uniformly across
#: [0, 1] (inference.moves.refresh): an edge's instant can have a minor mode the burn-in
#: missed, which the jumps cannot leave; the real record's reclose, seed 4, ran 100,000
#: iterations per chain for a median of 24,000 (docs/composite.md, "A minor mode of an
#: edge's instant").
REFRESH_SHARE = 0.1
#: The weight of a wide, heavy-tailed t among the zip+motor's jumps (inference.moves.
#: mixture; 0: none, the draws as before). Off: on issue 35's 10 s event at 60/s, whose
#: seed 7 stopped "converged" at a first round of 6,000 (4,000) with no draw of T' < 0.2 s
#: where 3.7% of the posterior is, a weight of 0.1 (and 0.2 wider along the principal
#: direction alone) still left that seed with under 0.1% there, and the median run went
#: from 8,182 to 11,204 (14,550) iterations (docs/composite.md, "A tail the burn-in
#: missed").
JUMP_WIDE = 0.0
#: The total weight of t's placed along the posterior's ridge in ``log T'`` among the
#: zip+motor's jumps (``ridge.py``: profile points of the NLS, each with its Laplace
#: covariance; 0: none). On issue 35's 10 s event, 6,000 (4,000) iterations run until
#: converged: every chain of seeds 0-9 reached T' < 0.2 s (1.9-5.5% of the draws, the
#: reference's 3.7%), where without it seed 7 stopped "converged" with none
#: (docs/composite.md, "Jumps placed from the data").
JUMP_RIDGE = 0.2
#: ... placed only after a burn-in of at least this many iterations: the profile costs
#: 0.1-1 CPU s, as much as a whole short run (the calibration's 600-iteration burn-ins),
#: and serves the long runs whose chains could otherwise all miss the ridge's far end.
RIDGE_MIN_BURN = 2_000

#: A model of parts' own block steps per iteration (``PartsModel.block_steps``) only in a
#: run whose burn-in is at least this: the defaults' (4,000) and longer. They pay where the
#: walk must cross a long ridge (``cmld-lite`` on the real record, seeds 0-4: min ESS per
#: CPU s 0.10-0.20 -> 0.09-4.27, 12 times summed; docs/composite.md); a short run (a
#: test's, a quick study's) keeps one step, its cost and its draws.
BLOCK_STEPS_MIN_BURN = 4_000


def steps_per_iteration(problem, burn: int) -> int:
    """The block move's steps per iteration: the model's own in a long run, else 1."""
    asked = int(getattr(getattr(problem, "model", None), "block_steps", 1))
    return asked if burn >= BLOCK_STEPS_MIN_BURN else 1


def jump_share(problem, steps: int) -> float:
    """The share of the block move's steps after burn-in that jump.

    :data:`JUMP_SHARE`, but with several block steps per iteration a model of parts may
    ask for a number of jumps per iteration instead (``PartsModel.jumps_per_iteration``):
    ``cmld-lite``'s jumps are accepted about 1 in 400 times, and its walk steps are what
    cross its ridge. One step per iteration: :data:`JUMP_SHARE`, draw for draw.
    """
    own = getattr(getattr(problem, "model", None), "jumps_per_iteration", None)
    return JUMP_SHARE if own is None or steps <= 1 else min(JUMP_SHARE, float(own) / steps)


def block_steps(move, state: BlockState, logp, rng: np.random.Generator, iteration: int,
                steps: int) -> BlockState:  # fmt: skip
    """``steps`` steps of the block move in turn, each from where the last one left.

    Each step leaves the density invariant, so their composition does; one step is the
    move's own, draw for draw (a model of parts may ask for more: ``block_steps``).
    """
    for _ in range(steps):
        state, _ = move.step(state, logp, rng, iteration)
    return state


#: Below this many samples (all events together) a fit whose chains run the Python
#: iteration runs them in one thread unless threads are asked for (``workers``,
#: ``SamplerSettings.threads``, ``LOADBAYES_NUM_THREADS``): an iteration's compiled
#: integration then lasts about as long as its Python, or less, and the Python holds the
#: GIL: two threads spend their time handing it back and forth. Sampler wall s on 2 idle
#: cores, one thread against two, plain ``zip+motor``: the real first fault (76 samples)
#: 2.7-3.2 against 4.3-4.6; a 3 s event at 60/s (181) 3.6 against 3.9; a 10 s event (601)
#: 5.7 against 3.9; a 20 s event (1,201) 7.9-9.2 against 4.4-5.2 (docs/composite.md, "One
#: thread for short events"). Models of parts alike (the whole command's wall s, 4 chains,
#: AMD Zen 4): the first fault, ``cmld-lite`` (12 block steps) 84.9 against 96.8 and ``slm``
#: 12.1 against 15.2, the two threads taking 1.5 times the CPU; 5 s at 60/s (301) ``slm``
#: 4.33 both, ``cmld-lite`` 8.1 against 7.4; 10 s (601) 4.7 against 4.5 and 10.2 against
#: 8.0. Chains that run compiled (``chain_fast.py``) hold no GIL and take one thread per
#: CPU: the first fault 1.2-1.3 s against 1.8-1.9 in one. The draws do not depend on it.
ONE_THREAD_SAMPLES = 300


def chain_threads(problem, compiled: bool = False) -> int | None:
    """1 for a short problem whose chains run in Python, no threads asked; else None.

    None: one thread per CPU. ``compiled``: the chains run compiled
    (:func:`~loadbayes.fit.composite.chain_fast.compiled_run`), and hold no GIL.
    """
    if asked_threads() is not None or compiled:
        return None
    short = sum(e.n for e in problem.events) < ONE_THREAD_SAMPLES
    return 1 if short else None


def chain_processes(problem, compiled: bool, chains: int, workers: int | None) -> int:
    """Processes to run the chains in, or 0 (threads, :func:`chain_threads`).

    Chains that run in Python hold the GIL while they do: on a short event two threads
    run them slower than one (:data:`ONE_THREAD_SAMPLES`), on a long one a little faster.
    Where the process may fork (:func:`~loadbayes.core.forked.can_fork`) they run in one
    process per CPU instead, unless threads or workers are asked for: faster than either
    on every event measured (docs/composite.md, "Models of parts in processes"). The
    draws are the same.
    """
    if workers is not None or compiled or chains < 2 or asked_threads() is not None:
        return 0
    cpus = num_threads()
    return min(chains, cpus) if cpus >= 2 and can_fork() else 0


@dataclass
class ChainResult:
    """One chain's kept draws and acceptance."""

    theta: np.ndarray  # (kept, problem.n_theta) the model's theta (THETA_NAMES)
    beta: np.ndarray  # (kept, events, coefficients)
    tau: np.ndarray  # (kept, 2)
    acceptance: float
    phi: np.ndarray | None = None  # (kept, steps) fractions of the step intervals
    evaluations_per_iteration: float = 1.0  # collapsed-density evaluations of the u-move
    jump_acceptance: float | None = None  # of the u-move's jumps (None: no jumps)
    # Coordinates of u after the motor's and the steps' (estimated torque shares).
    u_extra: np.ndarray | None = None
    # Student-t only (fit.composite_robust): nu draws (kept, 2), mean weights (2, n).
    nu: np.ndarray | None = None
    weight: np.ndarray | None = None
    nu_acceptance: float | None = None
    # AR(1) noise only: rho draws (kept, 2) of P and Q.
    rho: np.ndarray | None = None
    # Iterations the deadline (time budget) cut from this chain: 0 when it never bound.
    cut: int = 0
    # Chains restarted at the end of burn-in from a lower mode (restart.py), in words.
    restart_note: str | None = None


#: ChainResult's fields that hold one row per kept draw (cut to a common length).
_PER_DRAW = ("theta", "beta", "tau", "phi", "u_extra", "nu", "rho")


def _common_length(out: list[ChainResult]) -> list[ChainResult]:
    # Chains stopped by the deadline hold different numbers of draws: keep the first
    # ones every chain has (R-hat and the stacked draws need one length).
    from dataclasses import replace

    n = min(r.theta.shape[0] for r in out)
    if all(r.theta.shape[0] == n for r in out):
        return out
    return [
        replace(r, **{k: getattr(r, k)[:n] for k in _PER_DRAW if getattr(r, k) is not None})
        for r in out
    ]


#: With bounded shares the jumps are fitted again, before each round a run until
#: converged adds, to every chain's kept draws so far (every REFIT_THIN-th u, pooled).
#: Their late burn-in covers the motor's wide tail there poorly (the jumps accept 17-21%
#: of their proposals against the plain fit's 40%), and the real record's first fault
#: ran 11,500-30,811 iterations per chain (seeds 0-4) where it now runs 10,000-11,982
#: (docs/composite.md, "Bounded shares: the jumps refitted"). Each round's kernel is
#: fixed, and leaves the posterior invariant; the adaptation stops with the rounds.
#: Free shares: never (their draws as before).
REFIT_THIN = 4
#: Share-only Metropolis steps per iteration with bounded shares (no motor solve each).
SHARE_STEPS = 10
#: Their target acceptance (a 4-coordinate random walk).
SHARE_ACCEPT = 0.3
#: Candidates per event of the importance step that handles a coefficient prior factor.
TILT_TRIES = 512


class _Tilted:
    """A prior factor ``r(beta)`` on the coefficients, handled exactly (docs/composite.md).

    The state is ``(u, beta, tau)``. Each iteration extends it with ``M - 1`` fresh draws
    of every event's ``beta`` from its conjugate conditional (the current ``beta`` the
    M-th); the u-move proposes ``u'`` with ``M`` fresh draws at ``u'`` and accepts by the
    ratio of ``p(u) Z(u) mean_m r(beta_m)``, the collapsed density times the importance
    estimate of ``E[r]``; then ``beta`` is picked among the candidates of the state it
    landed on with probability proportional to ``r``. This is Metropolis-Hastings on the
    extended target ``pi(u, beta_k) prod_{m != k} q(beta_m | u)`` (the particle-marginal
    construction of Andrieu, Doucet & Holenstein 2010 with one time step): exact for any
    ``M``, whose size only sets how sticky the chain is where ``r`` is often zero.
    """

    def __init__(self, problem, factor, tries: int = TILT_TRIES) -> None:
        self.problem, self.factor, self.tries = problem, factor, int(tries)

    def candidates(self, sums, tau, u, rng, current=None):
        """Every event's candidates, their ``log r`` and the log estimate of ``E[r]``."""
        n = self.tries - (current is not None)
        sets = self.problem.draw_coefficient_sets(sums, tau, u, rng, n)
        cands, logr, est = [], [], 0.0
        for e, draws in enumerate(sets):
            if current is not None:
                draws = np.vstack([current[e][None, :], draws])
            lr = self.factor.log_factor(draws)
            top = float(np.max(lr))
            if not math.isfinite(top):
                return cands, logr, -math.inf
            est += top + math.log(float(np.mean(np.exp(lr - top))))
            cands.append(draws)
            logr.append(lr)
        return cands, logr, est

    def select(self, cands, logr, rng) -> list[np.ndarray]:
        """One candidate per event, with probability proportional to ``r``."""
        out = []
        for c, lr in zip(cands, logr, strict=True):
            w = np.exp(lr - np.max(lr))
            out.append(c[rng.choice(len(w), p=w / w.sum())].copy())
        return out

    def feasible(self, sums, tau, u, rng) -> list[np.ndarray]:
        """Starting coefficients drawn with probability proportional to ``r``."""
        cands, logr, est = self.candidates(sums, tau, u, rng)
        if not math.isfinite(est):
            # A normal factor is positive wherever its quantity is finite: only a start
            # whose every candidate has a zero static part (a share 0/0) lands here.
            raise ValueError("no starting coefficients where the coefficient prior is positive")
        return self.select(cands, logr, rng)


#: Decides, after a round of sampling, how many more iterations every chain runs (0:
#: stop). Called with the chains' results so far.
Extension = Callable[[list[ChainResult]], int]


class _State(NamedTuple):
    """The composite chain's state between iterations (the model's side of the driver)."""

    u: np.ndarray  # the sampled vector (motor, steps, shares, torque log-ratios)
    sums: Any  # the collapsed density's sums at u (weighted / whitened as the noise is)
    tau: np.ndarray  # (2,) noise precisions of P and Q
    rho: np.ndarray | None  # (2,) AR(1) coefficients, or None (white noise)
    betas: Any  # every event's coefficients (None before the first iteration)
    log_t0: float | None  # zip+motor's scale, drawn from its prior (None: before the first
    # iteration, or a model with no scale left to the prior)


class _Gibbs:
    """The composite's conditional updates, one iteration at a time (the chain's ``step``).

    :class:`loadbayes.inference.chain.Chain` drives it: iterations, burn-in, thinning,
    storage of :attr:`fields` (:meth:`record`), the statistics (:meth:`stats`), and runs
    continued in rounds with the same draws as one uninterrupted run.
    """

    def __init__(self, problem, start, lap, root, tau0, n_tot, rng, *, burn, thin, move,
                 dispersion, student_t, factor=None, ar=False, jumps=False,
                 u0=None, steps=None):  # fmt: skip
        self.problem, self.rng, self.burn, self.thin = problem, rng, burn, thin
        self.n_tot = n_tot
        dim = problem.dim
        self.n_base = problem.n_free + problem.n_steps
        # Steps of the block move per iteration: a model of parts may ask for more
        # (PartsModel.block_steps, its notes) in a long run (BLOCK_STEPS_MIN_BURN); 1 for
        # any other problem and run. And the share of them that jump (jump_share).
        self.block_steps = steps_per_iteration(problem, burn) if steps is None else steps
        share = {"independence": jump_share(problem, self.block_steps)} if jumps else {}
        self.am = MOVES[move](
            lap, adapt_until=burn, adapt_start=min(200, max(burn // 4, 1)), **share
        )
        # The least-squares optimum this chain starts about (start.u but where a model
        # of parts' NLS found another: NLSResult.others).
        u0 = start.u if u0 is None else u0
        u, sums = u0, None
        for _ in range(100):
            cand = u0 + dispersion * root @ rng.standard_normal(dim)
            sums = problem.sums(cand)
            if sums is not None:
                u = cand
                break
        if sums is None:
            u, sums = u0, problem.sums(u0)
        tau = tau0.copy()
        # AR(1) noise: rho starts at 0 (white), the sums carry the motor's response.
        rho = np.zeros(2) if ar else None
        if ar:
            _, sums = problem.collapsed(u, tau, rho=rho)
        # Student-t noise: the weights' state (None for the Gaussian, whose path is unchanged).
        self.wt = None if student_t is None else student_t.chain(problem, u, tau0)
        if self.wt is not None:
            sums = self.wt.sums
        self.tilted = None
        betas = None
        self.share_scale = None  # bounded shares: the share-only steps' scale per event
        if factor is not None and factor.active:
            self.tilted = _Tilted(problem, factor)
            betas = self.tilted.feasible(sums, tau, u, rng)
        self.start = _State(u, sums, tau, rho, betas, None)
        # A model's own steps after the block move (a model of parts' thresholds).
        own = getattr(problem, "conditional_moves", None)
        self.own_moves = None if own is None else own()
        # The steps' fractions, refreshed now and then across [0, 1] (REFRESH_SHARE).
        nm, ns = problem.n_free, problem.n_steps
        self.refresh = (UniformRefresh(range(nm, nm + ns), share=REFRESH_SHARE)
                        if ns and isinstance(problem, CompositeProblem) else None)  # fmt: skip
        # The second half of the burn-in's u (with jumps): the pooled t is fitted to them.
        self.late_burn: list[np.ndarray] | None = [] if jumps else None
        # Bounded shares: every REFIT_THIN-th kept u, to refit the jumps before each
        # round run on until converged (REFIT_THIN); None: the jumps stay as fitted.
        self.kept_u: list[np.ndarray] | None = [] if jumps and problem.n_share_coords else None
        self.refit_thin, self.share_steps_n = REFIT_THIN, SHARE_STEPS  # (chain_fast reads them)
        # And their joint log densities, where the model asks for chains in a lower mode
        # to be restarted (a model of parts: restart.py); None: not kept.
        modes = bool(getattr(getattr(problem, "model", None), "restart_modes", False))
        self.late_lp: list[float] | None = [] if jumps and modes and student_t is None else None
        self.restart_note: str | None = None
        # What a kept iteration stores, by name (ChainResult's fields).
        self.fields = {
            "theta": (problem.n_theta,),
            "beta": (len(problem.events), problem.n_beta),
            "tau": (getattr(problem, "n_channels", 2),),
            "phi": (problem.n_steps,),
            "u_extra": (dim - self.n_base,),
        }
        if ar:
            self.fields["rho"] = (2,)

    def step(self, state: _State, rng: np.random.Generator, it: int) -> _State:
        """One iteration: the u-move, the coefficients, rho, the weights, tau, log T0."""
        problem, wt = self.problem, self.wt
        u, sums, tau, rho = state.u, state.sums, state.tau, state.rho
        if wt is None:
            lp = problem.log_collapsed(sums, u, tau)

            def logp(x, tau=tau, rho=rho):
                return problem.collapsed(x, tau, rho=rho)

        else:
            lp, logp = wt.current(u, tau), wt.logp(tau)
        if self.tilted is None:
            u, lp, sums = block_steps(self.am, BlockState(u, lp, sums), logp, rng, it,
                                      self.block_steps)  # fmt: skip
            if self.own_moves is not None:
                u, lp, sums = self.own_moves(u, lp, sums, logp, rng, rho=rho,
                                             tau=tau if wt is None else None,
                                             adapting=it < self.burn)  # fmt: skip
            if self.refresh is not None:
                u, lp, sums = self.refresh.step(BlockState(u, lp, sums), logp, rng)
            if problem.n_share_coords:
                u = self._share_steps(u, lp, sums, tau, it)

            betas = problem.draw_coefficients(sums, tau, u, rng)
        else:
            u, sums, betas = self._tilted_step(u, lp, logp, sums, tau, it, state.betas)
        burn = self.burn
        if self.kept_u is not None and it >= burn and it % REFIT_THIN == 0:
            self.kept_u.append(np.array(u, dtype=float))
        if self.late_burn is not None and burn // 2 <= it < burn:
            self.late_burn.append(np.array(u, dtype=float))
            if self.late_lp is not None:  # the state's density with tau's prior
                a, b, t = problem.prior.tau_shape, problem.prior.tau_rate, tau[tau > 0]
                self.late_lp.append(lp + float(np.sum((a - 1) * np.log(t) - b * t)))
        if rho is not None:  # rho | u, beta, tau; then the sums whitened for it
            stats = problem.ar_statistics(sums, betas)
            top = getattr(problem, "rho_max", RHO_MAX)  # a model of parts' own bound
            rho = np.array([draw_rho(stats[g], float(tau[g]), float(rho[g]), rng, top)[0]
                            for g in range(2)])  # fmt: skip
            sums = problem.resum(sums, rho)
        if wt is not None:  # (nu, lambda) | u, beta, tau; then tau sees the weighted SSR
            sums = wt.update(sums, betas, tau, rng, is_kept(it, burn, self.thin))
        ssr = sum(residual_ss(s, b) for s, b in zip(sums, betas, strict=True))
        tau = draw_tau(ssr, self.n_tot, problem.prior.tau_shape, problem.prior.tau_rate, rng)
        scale = problem.draw_scale(u, rng)  # zip+motor: log T0 | u from its prior
        return _State(u, sums, tau, rho, betas, scale)

    def record(self, state: _State) -> dict[str, Any]:
        """The kept values of an iteration (:attr:`fields`)."""
        u = state.u
        out = {
            "theta": self.problem.theta(u, state.log_t0),
            "beta": state.betas,
            "tau": state.tau,
            "phi": self.problem.phi(u),
            "u_extra": u[self.n_base :],
        }
        if state.rho is not None:
            out["rho"] = state.rho
        return out

    def stats(self) -> dict[str, Any]:
        """The u-move's acceptance and cost, the jumps' acceptance."""
        return {
            "acceptance": self.am.acceptance,
            "evaluations_per_iteration": self.am.evaluations_per_step,
            "jump_acceptance": getattr(self.am, "jump_acceptance", None),
        }

    def _share_steps(self, u, lp, sums, tau, it):
        # Bounded shares: SHARE_STEPS random-walk Metropolis steps on each event's share
        # coordinates alone. They need no motor solve (the motor's sums do not depend on
        # the shares), so the shares settle given the motor at a tenth of the cost of a
        # joint step; each step leaves the posterior invariant. The scale adapts toward
        # SHARE_ACCEPT during burn-in, then stays.
        # The steps run compiled (fit/composite/bounded_kernel.share_steps), drawing from
        # the chain's generator in the Python loop's order: a normal step, then a
        # uniform, for each step and event.
        p, rng = self.problem, self.rng
        i0, n_ev = self.n_base, len(p.events)
        if self.share_scale is None:
            self.share_scale = np.full(n_ev, 0.3)
        sl = slice(i0, i0 + SHARE_COORDS * n_ev)
        z = np.array(u[sl], dtype=float).reshape(n_ev, SHARE_COORDS)
        share_steps(z, *p.share_arguments(tau, sums), SHARE_STEPS, rng, self.share_scale,
                    it < self.burn)  # fmt: skip
        u = np.array(u, dtype=float)
        u[sl] = z.ravel()
        return u

    def _tilted_step(self, u, lp, logp, sums, tau, it, betas):
        # The u-move and the coefficients with a prior factor (_Tilted's notes).
        rng, tilt = self.rng, self.tilted
        cands, logr, est = tilt.candidates(sums, tau, u, rng, current=betas)

        def logp_tilted(x):
            lc, s2 = logp(x)
            if s2 is None or not math.isfinite(lc):
                return -math.inf, None
            c2, l2, e2 = tilt.candidates(s2, tau, x, rng)
            return lc + e2, (s2, c2, l2)

        state = BlockState(u, lp + est, (sums, cands, logr))
        (u, _, aux), _ = self.am.step(state, logp_tilted, rng, it)
        sums, cands, logr = aux
        return u, sums, tilt.select(cands, logr, rng)


def _run(gibbs: _Gibbs, chain: Chain, iterations: int) -> None:
    """``iterations`` more of a chain: compiled for a plain zip+motor (``chain_fast.py``)."""
    if runs_compiled(gibbs):
        chain.run_batched(iterations, BATCH, partial(step_batch, gibbs))
    else:
        chain.run(iterations)


def _result(gibbs: _Gibbs, chain: Chain) -> ChainResult:
    """A chain's kept draws so far and its statistics."""
    d, p = chain.draws(), gibbs.problem
    robust = {}
    if gibbs.wt is not None:
        robust = dict(zip(("nu", "weight", "nu_acceptance"), gibbs.wt.result(), strict=True))
    return ChainResult(
        d["theta"],
        d["beta"],
        d["tau"],
        phi=d["phi"],
        u_extra=d["u_extra"] if p.dim > gibbs.n_base else None,
        rho=d.get("rho"),
        cut=chain.cut,
        restart_note=gibbs.restart_note,
        **chain.sample_stats(),
        **robust,
    )


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
    extend: Extension | None = None,
    factor: Any = None,
    ar: bool = False,
    deadline: float | None = None,
    block_steps: int | None = None,
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
        Threads for the chains; by default one per CPU, but chains that run in Python go
        to one process per CPU where the process may fork (:func:`chain_processes`), and
        else to one thread on a short event (:func:`chain_threads`).
    dispersion : float
        Spread of the chains' starting points, in Laplace sds.
    move : {"shear", "am", "slice"}
        The u-move (:data:`MOVES`): adaptive Metropolis in coordinates that straighten
        the posterior's main bend (the default), plain adaptive Metropolis, or factor
        slice sampling in the eigenbasis of the covariance learned in burn-in
        (docs/composite.md, "Why this move").
    student_t : loadbayes.fit.composite.robust.StudentT, optional
        Student-t noise (a weights step each iteration); Gaussian noise when None.
    progress : callable, optional
        Called with a number of iterations just done (of ``chains * draws``), about every
        :data:`~loadbayes.inference.chain.PROGRESS_EVERY_S` seconds per chain, from the
        chains' threads.
    extend : callable, optional
        After the ``draws`` iterations, and after each further round, called with the
        chains' results; it returns how many more iterations every chain runs (all
        kept, at the thinning), 0 to stop. The moves stay frozen after burn-in, so a
        run extended by ``n`` gives the same draws as one of ``draws + n`` (but with
        bounded shares, whose jumps are refitted before each round: :data:`REFIT_THIN`).
    factor : loadbayes.models.composite_prior.CoefficientPrior, optional
        A prior factor on the coefficients (bounded shares, priors on named quantities),
        handled by :class:`_Tilted`; needs a move of :data:`ONE_EVALUATION_MOVES`.
    ar : bool
        AR(1) noise on P and Q (one ``rho`` each, uniform prior on (-1, 1),
        :func:`loadbayes.inference.ar1.draw_rho` each iteration); Gaussian noise only.
    deadline : float, optional
        A :func:`time.perf_counter` time: the time budget, from the first iteration. Past
        it every chain ends its burn-in and stops once it holds
        :data:`~loadbayes.fit.composite.checks.MIN_KEPT` kept draws; no extension runs.
    block_steps : int, optional
        Steps of the block move per iteration; by default :func:`steps_per_iteration` of
        ``burn``. The cost estimate's probe, whose burn-in is short, passes the run's.

    Returns
    -------
    list of ChainResult
    """
    check_iterations(draws, burn, thin, chains)
    if move not in MOVES:
        raise ValueError(f"move must be one of {sorted(MOVES)}, got {move!r}")
    if ar and student_t is not None:
        raise ValueError("AR(1) noise is for the Gaussian likelihood only")
    if factor is not None and factor.active and move not in ONE_EVALUATION_MOVES:
        raise ValueError(
            "bounded shares and priors on the coefficients need a Metropolis move "
            f"({', '.join(ONE_EVALUATION_MOVES)}): their density is estimated (importance "
            "weights), which a slice move cannot use"
        )
    # The motor's coordinates, the steps' fractions, then any extra ones (torque shares).
    d = dim = problem.dim
    nm = problem.n_free
    lap = start.cov[:d, :d]
    lap = (lap + lap.T) / 2
    # A step the data barely place has a Laplace sd far wider than its [0, 1] support:
    # start its proposal at the support's scale instead (the adaptation takes over).
    shrink = np.ones(d)
    shrink[nm:] = np.minimum(1.0, 0.3 / np.sqrt(np.diag(lap)[nm:]))
    lap = lap * np.outer(shrink, shrink)
    tau0 = 1.0 / start.sigma**2
    rows = getattr(problem, "channel_rows", None)  # a model's own channels (design.py)
    n_tot = (np.array([sum(e.n for e in problem.events)] * 2, dtype=float) if rows is None
             else rows())  # fmt: skip
    root = np.linalg.cholesky(lap + 1e-12 * np.eye(dim))
    # Chains that run in Python: in processes where it may fork (chain_processes).
    compiled = compiled_run(problem, move, student_t, factor)
    lanes = chain_processes(problem, compiled, chains, workers)
    # The chains' stop flag: SIGINT/SIGTERM (core.parallel.request_stop) or a failed
    # chain end every chain within one iteration, not when the chains finish.
    stop: Any = SharedFlag() if lanes else threading.Event()
    # The lanes' progress, to the caller's (none asked: none sent).
    relay = Relay(progress) if lanes and progress is not None else None
    state: list[Any] = [None] * chains  # each chain's (_Gibbs, Chain)

    # The Metropolis moves jump from a t fitted to every chain's late burn-in, pooled: a
    # chain's own burn-in may not have left the region it started in (one chain's t
    # accepted 5% of its jumps where the pooled one accepts 10-30%). So the chains stop
    # at the end of burn-in, and go on with the jumps fitted.
    pool = move in ONE_EVALUATION_MOVES

    # Chain k starts about the k-th least-squares optimum, in turn (one for zip+motor;
    # a model of parts may have two: restart.py then keeps the higher mode's).
    optima = [start.u, *getattr(start, "others", ())]

    def first(index: int, rng: np.random.Generator) -> ChainResult:
        u0 = optima[index % len(optima)]
        g = _Gibbs(problem, start, lap, root, tau0, n_tot, rng, burn=burn, thin=thin,
                   move=move, dispersion=dispersion, student_t=student_t, factor=factor,
                   ar=ar, jumps=pool, u0=u0, steps=block_steps)  # fmt: skip
        c = Chain(g.step, g.start, rng, fields=g.fields, record=g.record, burn=burn,
                  thin=thin, stats=g.stats, stop=stop, deadline=deadline, min_kept=MIN_KEPT,
                  progress=progress if relay is None else relay)  # fmt: skip
        state[index] = (g, c)
        _run(g, c, burn if pool else draws)
        return _result(g, c)

    def rest(index: int, rng: np.random.Generator) -> ChainResult:
        g, c = state[index]
        _run(g, c, draws - burn)
        return _result(g, c)

    generators = chain_generators(seed, chains)
    workers = workers or chain_threads(problem, compiled)
    shared = (problem, getattr(problem, "model", None), *problem.events)

    def run(fn: Callable[[int, np.random.Generator], ChainResult]) -> list[ChainResult]:
        if lanes:  # each chain's state comes back with its result (core/forked.py)
            return run_forked(fn, generators, lanes=lanes, stop=stop, state=state,
                              shared=shared, relay=relay)  # fmt: skip
        return run_chains(fn, generators, workers=workers, stop=stop)

    out = run(first)
    if pool:
        if state[0][0].late_lp is not None:  # chains left in a lower mode (restart.py)
            gaps = late_gaps([g.late_lp for g, _ in state])
            moved = restart_lagging([c for _, c in state], [g.late_lp for g, _ in state])
            for k, best, _ in moved:
                state[k][0].am = copy.deepcopy(state[best][0].am)
            for g, _ in state:
                g.restart_note = restart_words(moved, chains, gaps)
            for k, _, _ in moved:  # the jumps fitted to the higher mode's burn-in alone
                state[k][0].late_burn = []
        late = np.array([u for g, _ in state for u in g.late_burn])
        own = int(getattr(getattr(problem, "model", None), "jump_regions", 1))  # parts'
        regions = JUMP_COMPONENTS if isinstance(problem, CompositeProblem) else own
        wide = JUMP_WIDE if isinstance(problem, CompositeProblem) else 0.0
        # The ridge's points: a plain zip+motor (no share or torque coordinates).
        plain = type(problem) is CompositeProblem and not problem.bounded
        placed = plain and JUMP_RIDGE > 0 and burn >= RIDGE_MIN_BURN
        ridge = cached_ridge_points(problem, start) if placed else None
        for g, _ in state:
            g.am.fit_jumps(late, components=regions, wide=wide, anchors=ridge,
                           anchor=JUMP_RIDGE if ridge is not None else 0.0)  # fmt: skip
            g.late_burn = []
        out = run(rest)
    while extend is not None and not any(r.cut for r in out):
        more = int(extend(out))
        if more <= 0:
            break

        kept = [u for g, _ in state for u in (g.kept_u or ())] if pool else []
        if len(kept) >= JUMP_MIN_DRAWS:  # bounded shares (REFIT_THIN); else as fitted
            for g, _ in state:
                g.am.fit_jumps(np.array(kept), components=regions, wide=wide)

        def again(index: int, rng: np.random.Generator, more=more) -> ChainResult:
            g, c = state[index]
            _run(g, c, more)
            return _result(g, c)

        out = run(again)
    return _common_length(out)
