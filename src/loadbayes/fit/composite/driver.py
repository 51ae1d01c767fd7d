"""Fit the composite load (ZIP + motor) to recorded events: NLS start, sampler, Posterior.

:func:`fit_composite` builds the problem (:mod:`~loadbayes.fit.composite.problem`), runs
the penalised NLS (the start, and the point-estimate baseline returned as a
:class:`~loadbayes.posterior.Posterior` of its Gaussian approximation), then the
Metropolis-within-Gibbs sampler (:mod:`~loadbayes.fit.composite.sampler`), and assembles
the posterior: draws named by :mod:`~loadbayes.fit.composite.naming`, provenance by
:mod:`~loadbayes.fit.composite.provenance`, the plain-words identifiability section by
:mod:`~loadbayes.fit.composite.identifiability` and the warnings of
:mod:`~loadbayes.fit.composite.checks`.
"""

from __future__ import annotations

import math
import time
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from loadbayes.core.settings import SamplerSettings
from loadbayes.fit.composite.checks import (
    check_run,
    check_units,
    convergence_warnings,
    sampling_warnings,
    start_warnings,
)
from loadbayes.fit.composite.identifiability import (
    identifiability,
    prior_driven_warning,
    torque_identifiability,
)
from loadbayes.fit.composite.naming import (
    ChainDraws,
    coefficient_names,
    free_names,
    named_draws,
)
from loadbayes.fit.composite.nls import NLSResult, nls
from loadbayes.fit.composite.problem import CompositeProblem, theta_of
from loadbayes.fit.composite.provenance import (
    METHOD,
    baseline_record,
    problem_settings,
    sampler_record,
)
from loadbayes.fit.composite.robust import StudentT, robust_outputs
from loadbayes.fit.composite.sampler import DEFAULT_MOVE, sample
from loadbayes.fit.composite.torque import TorqueProblem, extend_start
from loadbayes.models.composite import THETA_NAMES, EventRecord
from loadbayes.models.composite_prior import CompositePrior
from loadbayes.models.motor_kernel import H_MAX_S
from loadbayes.posterior import Posterior, gaussian_draws

__all__ = ["COMPOSITE_DEFAULTS", "CompositeFit", "SamplingProgress", "fit_composite"]

#: The composite fit's sampler defaults (the CLI's too): 16000 iterations, 4000 burn-in,
#: four chains.
COMPOSITE_DEFAULTS = SamplerSettings(draws=16_000, burn=4_000, chains=4)
#: The sampled coordinates whose R-hat is checked: the motor's five, and the torque's
#: log-ratios when the shares are estimated.
_WATCH = tuple(THETA_NAMES[:5])
_WATCH_TORQUE = ("log_a_over_c", "log_b_over_c")


@dataclass
class CompositeFit:
    """What :func:`fit_composite` returns."""

    posterior: Posterior
    baseline: Posterior
    problem: CompositeProblem
    start: NLSResult
    seconds: dict[str, float]


def _baseline_draws(
    problem: CompositeProblem, start: NLSResult, chains: int, draws: int, seed: int
) -> dict[str, np.ndarray]:
    # Gaussian draws of the NLS estimate (its Laplace covariance), named as the posterior's.
    n_ev = len(problem.events)
    rng = np.random.default_rng(seed)
    mean = np.concatenate([start.u, start.betas.ravel()])
    x = gaussian_draws(mean, start.cov, chains, draws, rng)
    d = problem.dim
    u = x[..., :5]
    log_t0 = np.array([problem.prior.draw_log_t0(ui, rng) for ui in u.reshape(-1, 5)])
    theta = theta_of(u, log_t0.reshape(chains, draws))
    betas = x[..., d:].reshape(chains, draws, n_ev, 7)
    tau = np.broadcast_to(1.0 / start.sigma**2, (chains, draws, 2)).copy()
    return named_draws(problem, theta, betas, tau, phi=problem.phi(x[..., :d]))


class SamplingProgress:
    """What :func:`fit_composite` tells about the sampling while it runs (override both).

    :meth:`begin` gets the iterations to run (all chains) and the estimated wall time
    before the chains start; the instance is then called with the iterations done since
    its last call, from the chains' threads.
    """

    def begin(self, total: int, seconds: float) -> None:  # noqa: D102
        pass

    def __call__(self, n: int) -> None:  # noqa: D102
        pass


#: Iterations of the short run that times one iteration before the chains start.
_PROBE_ITERATIONS = 12


def _estimate_seconds(sampled, start, run: SamplerSettings, move: str, student_t) -> float:
    # Measure a few iterations of one chain (its own throw-away run) and extrapolate: the
    # chains share the threads, each runs run.draws iterations.
    from loadbayes.core.parallel import num_threads

    def probe(n: int) -> float:
        t0 = time.perf_counter()
        sample(sampled, start=start, draws=n, burn=n // 2, chains=1, seed=run.seed,
               workers=1, move=move, student_t=student_t)  # fmt: skip
        return time.perf_counter() - t0

    probe(2)  # the first call compiles the kernels (the run would pay it anyway)
    per_iteration = probe(_PROBE_ITERATIONS) / _PROBE_ITERATIONS
    threads = run.threads or num_threads()
    rounds = math.ceil(run.chains / max(1, min(threads, run.chains)))
    return per_iteration * run.draws * rounds


def _student_t(likelihood: str, nu: float | str) -> StudentT | None:
    if likelihood == "student-t":
        return StudentT(nu=nu)
    if likelihood != "normal":
        raise ValueError(f"likelihood must be 'normal' or 'student-t', got {likelihood!r}")
    return None


def fit_composite(
    events: Sequence[EventRecord],
    *,
    sampler: SamplerSettings | None = None,
    prior: CompositePrior | None = None,
    f_hz: float = 60.0,
    torque: tuple[float, float, float] | str = (1.0, 0.0, 0.0),
    h_max: float = H_MAX_S,
    steps: bool = True,
    settings: dict[str, Any] | None = None,
    move: str = DEFAULT_MOVE,
    likelihood: str = "normal",
    nu: float | str = "auto",
    workers: int | None = None,
    accept_units: bool = False,
    progress: SamplingProgress | None = None,
    wording: str = "python",
    **overrides: Any,
) -> CompositeFit:
    """Fit the composite load to one or more events of the same load.

    Parameters
    ----------
    events : sequence of EventRecord
        Recordings (each its own operating point; the motor is shared).
    sampler : SamplerSettings, optional
        Draws, burn-in, chains, thinning, seed and threads; default
        :data:`COMPOSITE_DEFAULTS` (see :func:`loadbayes.fit.composite.sampler.sample`).
    prior : CompositePrior, optional
        Default :meth:`CompositePrior.default`.
    f_hz : float
        Nominal frequency (the motor's time base).
    torque : tuple of float or "estimate"
        ``(A, B, C)``, fixed, or ``"estimate"``: a Dirichlet(1, 1, 1) prior
        (fit.composite_torque).
    h_max : float
        RK4 sub-step of the motor kernel (s).
    steps : bool
        Model each voltage step between two samples as a step at an unknown instant
        inside its interval (``models/composite_steps.py``); False reads it as a ramp
        across the interval (the plain linear interpolation).
    settings : dict, optional
        Extra provenance stored in the result.
    move : str
        The sampler's u-move (:data:`~loadbayes.fit.composite.sampler.MOVES`).
    likelihood : {"normal", "student-t"}
        Noise on P and Q; Student-t adds latent weights (fit.composite_robust).
    nu : float or "auto"
        Student-t degrees of freedom, fixed or sampled (one per channel).
    workers : int, optional
        Threads for the chains (``sampler.threads`` overridden when given).
    accept_units : bool
        Fit events whose V is not per unit, or whose P is negative (warned, not refused;
        the check is ``fit zip``'s: :func:`loadbayes.fit.composite.checks.check_units`).
    progress : SamplingProgress, optional
        Told the estimated cost before sampling (a short timed run) and the iterations
        as they are done.
    wording : {"python", "cli"}
        Whose names the unit check's messages give (``accept_units=True`` or the CLI's
        ``--accept-units``; ``loadbayes fit composite`` passes "cli").
    **overrides
        ``draws``, ``burn``, ``thin``, ``chains``, ``seed``: change those of ``sampler``
        (``SamplerSettings.of``).

    Returns
    -------
    CompositeFit
        The posterior, the NLS baseline (Gaussian draws), the problem and timings.

    Raises
    ------
    loadbayes.io.errors.DataError
        Events whose units are not per unit (V) or whose P is negative, unless
        ``accept_units``.
    loadbayes.io.errors.OptionError
        ``f_hz`` outside 10-1000 Hz, fewer than 50 kept draws per chain, a negative seed.
    """
    base = sampler if sampler is not None else COMPOSITE_DEFAULTS
    run = SamplerSettings.of(base, threads=workers, **overrides)
    events = list(events)
    if not events:
        raise ValueError("no events to fit")
    check_run(f_hz=f_hz, draws=run.draws, burn=run.burn, thin=run.thin, seed=run.seed)
    unit_warnings = check_units(events, accept_units=accept_units, wording=wording)
    prior = prior or CompositePrior.default(events)
    estimate = isinstance(torque, str)
    if estimate and torque != "estimate":
        raise ValueError(f"torque must be (A, B, C) or 'estimate', got {torque!r}")
    # Estimated shares: NLS (the start) at the prior's centre A = B = C = 1/3.
    fixed = (1 / 3, 1 / 3, 1 / 3) if estimate else tuple(torque)
    problem = CompositeProblem(events, prior, f_hz=f_hz, torque=fixed, h_max=h_max, steps=steps)
    t0 = time.perf_counter()
    start = nls(problem)
    t1 = time.perf_counter()
    sampled, sample_start = problem, start
    if estimate:
        sampled = TorqueProblem(events, prior, f_hz=f_hz, torque=fixed, h_max=h_max, steps=steps)
        sample_start = extend_start(start, np.zeros(2))
    student_t = _student_t(likelihood, nu)
    t_sample = t1
    if progress is not None:
        progress.begin(
            run.draws * run.chains,
            _estimate_seconds(sampled, sample_start, run, move, student_t),
        )
        t_sample = time.perf_counter()
    res = sample(
        sampled, start=sample_start, draws=run.draws, burn=run.burn, thin=run.thin,
        chains=run.chains, seed=run.seed, workers=run.threads, move=move, student_t=student_t,
        progress=progress,
    )  # fmt: skip
    t2 = time.perf_counter()
    seconds = {"nls": t1 - t0, "sampler": t2 - t_sample}
    blocks = ChainDraws.stack(res, steps=bool(problem.n_steps), torque=estimate)
    draws_named = blocks.named(problem)
    common = problem_settings(problem, torque, settings)
    free = free_names(problem)
    coefficients = coefficient_names(draws_named)
    robust_settings, constant, robust_warn = {}, {}, []
    if student_t is not None:
        robust_settings, constant, robust_warn = robust_outputs(problem, res, nu, draws_named)
    post = Posterior(
        draws_named,
        model="composite",
        method=METHOD[move] + ("-student-t" if student_t else ""),
        constant=constant,
        warnings=unit_warnings + start_warnings(events) + robust_warn,
        coefficients=coefficients,
        free=free,
        observed={"t_s": events[0].t, "v": events[0].v, "p": events[0].p, "q": events[0].q},
        settings={
            **common,
            **sampler_record(run, move, res, dict(seconds), likelihood),
            **robust_settings,
        },
    )
    span = max(float(e.t[-1] - e.t[0]) for e in events)
    ident = identifiability(blocks.theta, draws_named["f_m"], prior, len(events), span_s=span)
    if estimate:
        ident["torque"] = torque_identifiability(blocks.abc)
        ident["summary"] += " " + ident["torque"]["summary"]
    post.extra_json["identifiability"] = ident
    weak = prior_driven_warning(ident)
    if weak:
        post.warnings.append(weak)
    post.warnings.extend(sampling_warnings(events, draws_named["t_prime_s"], steps_modelled=steps))
    watch = _WATCH + (_WATCH_TORQUE if estimate else ())
    post.warnings.extend(convergence_warnings(draws_named, watch, run.chains))
    # Baseline draws per chain: (draws - burn) // thin, at least one (not run.kept, which
    # rounds up: the baseline's size has always been this).
    n_baseline = max((run.draws - run.burn) // run.thin, 1)
    baseline = Posterior(
        _baseline_draws(problem, start, run.chains, n_baseline, run.seed),
        model="composite",
        method="nls-penalised",
        coefficients=coefficients,
        free=free,
        settings={**common, **baseline_record(problem, start)},
    )
    return CompositeFit(post, baseline, problem, start, seconds)
