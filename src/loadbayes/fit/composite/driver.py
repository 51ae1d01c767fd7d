"""Fit the composite load (ZIP + motor) to recorded events: NLS start, sampler, Posterior.

:func:`fit_composite` builds the problem (:mod:`~loadbayes.fit.composite.problem`), runs
the penalised NLS (the start, and the point-estimate baseline returned as a
:class:`~loadbayes.posterior.Posterior` of its Gaussian approximation), then the
Metropolis-within-Gibbs sampler (:mod:`~loadbayes.fit.composite.sampler`), and assembles
the posterior: draws named by :mod:`~loadbayes.fit.composite.naming`, provenance by
:mod:`~loadbayes.fit.composite.provenance`, the plain-words identifiability section by
:mod:`~loadbayes.fit.composite.identifiability` and the warnings of
:mod:`~loadbayes.fit.composite.checks`.

One idea needs these 470 lines: one fit's pipeline, events in and a Posterior out, each
stage in its own module and only their order and hand-overs here.
"""

from __future__ import annotations

import math
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from loadbayes.core.parallel import one_blas_thread
from loadbayes.core.settings import SamplerSettings, new_spelling
from loadbayes.fit.composite.bounded import share_start
from loadbayes.fit.composite.checks import (
    check_run,
    convergence_warnings,
    own_bases_warnings,
    start_warnings,
)
from loadbayes.fit.composite.describe import describe_fit
from loadbayes.fit.composite.describe_parts import describe_parts, parts_residuals
from loadbayes.fit.composite.design import DesignProblem
from loadbayes.fit.composite.naming import (
    ChainDraws,
    coefficient_names,
    free_names,
    named_draws,
)
from loadbayes.fit.composite.nls import NLSResult, nls
from loadbayes.fit.composite.predict_scope import covered
from loadbayes.fit.composite.predictive import event_arrays
from loadbayes.fit.composite.problem import CompositeProblem
from loadbayes.fit.composite.provenance import (
    METHOD,
    baseline_record,
    problem_settings,
    sampler_record,
)
from loadbayes.fit.composite.residuals import ar1_memory_warning
from loadbayes.fit.composite.robust import StudentT, robust_outputs
from loadbayes.fit.composite.sampler import (
    DEFAULT_MOVE,
    ONE_EVALUATION_MOVES,
    chain_processes,
    chain_threads,
    sample,
    steps_per_iteration,
)
from loadbayes.fit.composite.torque import TorqueProblem, extend_start
from loadbayes.fit.composite.until import DEFAULT_MAX_SECONDS, UntilConverged
from loadbayes.io.errors import OptionError
from loadbayes.measurements.record import EventRecord
from loadbayes.models.base import DynamicLoadModel
from loadbayes.models.composite_prior import CoefficientPrior
from loadbayes.models.zip_motor import CompositeModel
from loadbayes.posterior import Posterior, gaussian_draws

__all__ = ["COMPOSITE_DEFAULTS", "MOVED", "PARTS_DEFAULTS", "CompositeFit", "SamplingProgress",
           "parts_defaults",
           "fit_composite"]  # fmt: skip

#: The old signature's keywords that are neither SamplerSettings' nor DataSpec's fields,
#: and where each went (``core/settings.new_spelling`` refuses them in one line).
MOVED = {
    "workers": "sampler=SamplerSettings(threads={value})",
    **{k: f"model=CompositeModel({k}={{value}})" for k in
       ("f_hz", "torque", "h_max", "steps", "window_s", "shares", "noise", "likelihood",
        "nu", "priors", "prior")},
    "coefficient_prior": "model=CompositeModel(priors={value})",
    "settings": "provenance={value}",
    "wording": "(gone: the reader words its own checks)",
}  # fmt: skip
#: The data keywords of the old signature (``spec=DataSpec(...)`` of the public door).
DATA_KEYWORDS = ("t_col", "v_col", "p_col", "q_col", "f_col", "angle_col", "event_col",
                 "v_base", "s_base", "accept_units")  # fmt: skip

#: The composite fit's sampler defaults (the CLI's too): a first round of 6,000 iterations
#: with 4,000 burn-in, four chains, then on until converged. Was 16,000: the shorter round
#: stopped "converged" without a tail of T' that no burn-in had reached, until the jumps
#: got t's along the ridge (sampler.JUMP_RIDGE; docs/composite.md, "Jumps placed from the
#: data").
COMPOSITE_DEFAULTS = SamplerSettings(draws=6_000, burn=4_000, chains=4)
#: A model of parts' defaults: its first round stays 16,000 iterations (the shorter round
#: was measured on ``zip+motor`` alone, and its ridge's t's are the plain model's).
PARTS_DEFAULTS = COMPOSITE_DEFAULTS.with_(draws=16_000)


def parts_defaults(model: Any) -> SamplerSettings:
    """A model of parts' defaults: :data:`PARTS_DEFAULTS` with the model's own first round.

    ``cmld-lite`` asks for 10,000 iterations (``CmldLite.first_round``): its 12 block
    steps mix more per iteration, and the run goes on until converged anyway.
    """
    return PARTS_DEFAULTS.with_(draws=int(getattr(model, "first_round", PARTS_DEFAULTS.draws)))


class _Plain:
    """The reading options of a model that has none: point samples, Gaussian white noise."""

    torque = None
    estimate_torque = False
    likelihood, nu, shares, noise = "normal", "auto", "free", "white"
    coefficient_priors: dict = {}


_PLAIN = _Plain()


@dataclass
class CompositeFit:
    """What :func:`fit_composite` returns.

    ``summary``, ``plot``, ``to_arviz`` and ``loo`` are the posterior's
    (:class:`~loadbayes.posterior.Posterior`).
    """

    posterior: Posterior
    baseline: Posterior
    problem: CompositeProblem
    start: NLSResult
    seconds: dict[str, float]

    def summary(self, **kwargs: Any) -> Any:  # noqa: D102
        return self.posterior.summary(**kwargs)

    def plot(self, **kwargs: Any) -> Any:  # noqa: D102
        return self.posterior.plot(**kwargs)

    def to_arviz(self, **kwargs: Any) -> Any:  # noqa: D102
        return self.posterior.to_arviz(**kwargs)

    def loo(self, **kwargs: Any) -> Any:  # noqa: D102
        return self.posterior.loo(**kwargs)


def _baseline_draws(
    problem: CompositeProblem, start: NLSResult, chains: int, draws: int, seed: int
) -> dict[str, np.ndarray]:
    # Gaussian draws of the NLS estimate (its Laplace covariance), named as the posterior's.
    n_ev = len(problem.events)
    rng = np.random.default_rng(seed)
    mean = np.concatenate([start.u, start.betas.ravel()])
    x = gaussian_draws(mean, start.cov, chains, draws, rng)
    d = problem.dim
    u = x[..., : problem.n_free]
    # A scale the data never see (zip+motor's log T0), drawn from its prior draw by draw as
    # the sampler does; a model with none draws nothing. One call for every draw: the loop
    # of single draws it replaced took 3.3 us a draw (26 ms of a default fit's 8,000, 1.3 s
    # of a run asked for 400,000).
    scale = problem.draw_scales(u.reshape(-1, problem.n_free), rng)
    theta = problem.theta(u, None if scale is None else scale.reshape(chains, draws))
    betas = x[..., d:].reshape(chains, draws, n_ev, problem.n_beta)
    tau = np.broadcast_to(1.0 / start.sigma**2, (chains, draws, start.sigma.size)).copy()
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

    def extend(self, total: int, seconds: float, short: str) -> None:
        """The run goes on: ``total`` more iterations (all chains), about ``seconds``.

        ``short`` names the quantities that have not converged yet.
        """


def _estimate_seconds(
    sampled, start, run: SamplerSettings, move: str, student_t, factor=None, noise="white"
) -> float:
    # The chains that run at once (one per thread), timed in rounds until their pace
    # settles (fit/composite/until.estimate_seconds), their own throw-away run.
    from loadbayes.core.parallel import num_threads
    from loadbayes.fit.composite.chain_fast import compiled_run
    from loadbayes.fit.composite.until import estimate_seconds

    compiled = compiled_run(sampled, move, student_t, factor)  # AR(1) noise runs compiled too
    # Chains in processes (sampler.chain_processes): as many lanes, each one chain at a
    # time, so the probe is one chain in this process; in threads, one chain per thread.
    lanes = chain_processes(sampled, compiled, run.chains, run.threads)
    per = 1
    if not lanes:
        lanes = per = max(1, min(run.threads or chain_threads(sampled, compiled)
                                 or num_threads(), run.chains))  # fmt: skip

    # The run's block steps per iteration (a model of parts takes 12 in a long run, and a
    # probe's short burn-in would take one: cmld-lite's estimate read 36 s for 4 min).
    steps = steps_per_iteration(sampled, run.burn)

    def probe(n: int, extend=None) -> None:
        sample(sampled, start=start, draws=n, burn=n // 2, chains=per, seed=run.seed,
               workers=per, move=move, student_t=student_t, factor=factor,
               ar=noise == "ar1", extend=extend, block_steps=steps)  # fmt: skip

    probe(2)  # the first call compiles the kernels (the run would pay it anyway)
    return estimate_seconds(probe, run.draws, math.ceil(run.chains / lanes))


def _factor(normal: dict, move: str) -> CoefficientPrior | None:
    # The normal factors on the coefficients (the model checked their names and values);
    # bounded shares are the bounded model's parametrisation (fit/composite/bounded.py).
    factor = CoefficientPrior(normal=tuple((n, float(m), float(s)) for n, (m, s) in normal.items()))
    if factor.active and move not in ONE_EVALUATION_MOVES:
        raise OptionError(
            "shares='bounded' and priors on a1..a6, f_m, p0, q0 need a Metropolis move "
            f"(SamplerSettings(move=...): {', '.join(ONE_EVALUATION_MOVES)}), not {move!r}"
        )
    return factor if factor.active else None


def _append_start(start: NLSResult, values: np.ndarray, *, sd: float) -> NLSResult:
    # The sampler's start with coordinates appended (independent, sd ``sd``).
    from dataclasses import replace

    d, k = start.u.size, values.size
    cov = np.zeros((d + k, d + k))
    cov[:d, :d] = start.cov[:d, :d]
    cov[d:, d:] = sd**2 * np.eye(k)
    return replace(start, u=np.concatenate([start.u, values]), cov=cov)


def _student_t(likelihood: str, nu: float | str) -> StudentT | None:
    return StudentT(nu=nu) if likelihood == "student-t" else None


@new_spelling(data=DATA_KEYWORDS, more=MOVED)
@one_blas_thread  # small least squares; the chains are the threads (core/parallel.py)
def fit_composite(
    model: DynamicLoadModel,
    events: Sequence[EventRecord],
    *,
    sampler: SamplerSettings | None = None,
    progress: SamplingProgress | None = None,
    data_warnings: Sequence[str] = (),
    provenance: Mapping[str, Any] | None = None,
    start: NLSResult | None = None,
) -> CompositeFit:
    """Fit a dynamic load model to one or more recorded events of the same load.

    Parameters
    ----------
    model : DynamicLoadModel
        The model: ``zip+motor`` (:class:`~loadbayes.models.zip_motor.CompositeModel`,
        with how its events are read: torque law, steps, shares, noise, likelihood,
        phasor window, frequency, priors; checked when it was built), or any other
        model of the registry (``models/dynamic.py``), fitted through its design
        matrices (:class:`~loadbayes.fit.composite.design.DesignProblem`: point samples,
        Gaussian noise, white or AR(1) as the model's ``noise`` says).
    events : sequence of EventRecord
        Recordings in per unit (each its own operating point; the motor is shared),
        checked by their reader (:func:`loadbayes.fit.composite.api.read`).
    sampler : SamplerSettings, optional
        Draws, burn-in, chains, thinning, seed, threads, the Metropolis move, the run
        until converged and its time budget; default :data:`COMPOSITE_DEFAULTS`, which
        runs on after its draws until every reported quantity has R-hat < 1.01 and bulk
        ESS >= 400, or ``max_seconds`` runs out (:mod:`loadbayes.fit.composite.until`).
        Settings given with ``until_converged`` left None run exactly their draws.
    progress : SamplingProgress, optional
        Told the estimated cost before sampling (a short timed run) and the iterations
        as they are done.
    data_warnings : sequence of str
        What the events' reader warned of (units accepted as they are), put first in
        the posterior's warnings.
    provenance : mapping, optional
        Extra settings recorded in the result (the files, their bases).
    start : NLSResult, optional
        The NLS estimate of this ``zip+motor`` model on these events, when the caller
        has already run it (the choice of the samples' reading does,
        :func:`~loadbayes.fit.composite.reading.choose_reading`): the fit starts from
        it instead of running the same least squares again.

    Returns
    -------
    CompositeFit
        The posterior, the NLS baseline (Gaussian draws), the problem and timings.

    Raises
    ------
    TypeError
        A keyword of the old signature (``draws=``, ``torque=`` ...), naming its new
        place in one line.
    loadbayes.io.errors.OptionError
        Fewer than 50 kept draws per chain, a negative seed, a move that cannot take a
        prior on the shares.
    """
    until_converged = sampler is None if sampler is None else sampler.until_converged
    zip_motor = isinstance(model, CompositeModel)
    run = (sampler if sampler is not None else COMPOSITE_DEFAULTS if zip_motor
           else parts_defaults(model))  # fmt: skip
    move = run.move or DEFAULT_MOVE
    max_seconds = run.max_seconds if run.max_seconds is not None else DEFAULT_MAX_SECONDS
    events = list(events)
    if not events:
        raise ValueError("no events to fit")
    check_run(f_hz=getattr(model, "f_hz", 60.0), draws=run.draws, burn=run.burn, thin=run.thin,
              seed=run.seed)  # fmt: skip
    unit_warnings = list(data_warnings)
    prior = model.default_prior(events)
    settings = dict(provenance) if provenance else None
    if zip_motor:
        # Estimated shares: NLS (the start) at the prior's centre A = B = C = 1/3.
        kw = dict(f_hz=model.f_hz, torque=model.fixed_torque, h_max=model.h_max,
                  steps=model.steps, window_s=model.window_s)  # fmt: skip
        problem = CompositeProblem(events, prior, **kw)
        options = model
    else:  # any other model: its own design, point samples, Gaussian white noise
        problem = DesignProblem(model, events, prior)
        options = _PLAIN
    torque, estimate = options.torque, options.estimate_torque
    likelihood, nu, shares, noise = options.likelihood, options.nu, options.shares, options.noise
    if not zip_motor:  # a model of parts may carry AR(1) noise (design.py's whitened sums)
        noise = getattr(model, "noise", noise)
    bounded = shares == "bounded"
    coefficient_prior = dict(options.coefficient_priors)
    # With bounded shares a prior on a share is part of the sampled density (exact and
    # free); the other coefficient priors are factors (importance weights).
    share_prior = tuple(
        (int(n[1]) - 1, float(m), float(sd))
        for n, (m, sd) in coefficient_prior.items()
        if bounded and n in ("a1", "a2", "a3", "a4", "a5", "a6")
    )
    factor = _factor(
        {n: v for n, v in coefficient_prior.items() if not (bounded and n[0] == "a")}, move
    )
    t0 = time.perf_counter()
    if start is None:
        start = nls(problem)
    elif not zip_motor or start.u.size != problem.dim or start.betas.shape[0] != len(events):
        raise ValueError("start= is the NLS estimate of a zip+motor fit of the same events")
    project = getattr(prior, "project", None)
    if project is not None and not prior.inside(start.u):  # hard limits: start inside them
        start = replace(start, u=project(start.u))
    if project is not None and start.others:  # and any other optimum chains start about
        start = replace(start, others=tuple(x if prior.inside(x) else project(x)
                                            for x in start.others))  # fmt: skip
    t1 = time.perf_counter()
    sampled, sample_start = problem, start
    if bounded:
        # The shares become sampled coordinates (fit/composite/bounded.py), started at
        # the free estimate's shares moved inside the simplex.
        sampled = CompositeProblem(events, prior, bounded=True, share_prior=share_prior, **kw)
        sample_start = _append_start(start, share_start(start.betas), sd=0.5)
    if estimate:
        sampled = TorqueProblem(events, prior, bounded=bounded, share_prior=share_prior, **kw)
        sample_start = extend_start(sample_start, np.zeros(2))
    student_t = _student_t(likelihood, nu)
    t_sample = t1
    if progress is not None:
        progress.begin(
            run.draws * run.chains,
            _estimate_seconds(sampled, sample_start, run, move, student_t, factor, noise),
        )
        t_sample = time.perf_counter()
    until = None
    steady: dict | None = None  # the motor's steady P, Q of the draws named so far
    if until_converged and run.chains >= 2:
        steady = {}  # (naming.py: each round names them all; the last naming too)

        def quantities(results) -> dict[str, np.ndarray]:
            named = ChainDraws.stack(results, steps=bool(problem.n_steps), torque=estimate)
            # Every reported quantity, the noise precisions and sampled torque shares
            # included (a constant one is skipped by the rule): the JSON gives each its
            # R-hat and ESS, and the predictive band draws from the precisions.
            out = named.named(problem, cache=steady)
            if noise == "ar1":
                rho = np.stack([r.rho for r in results])
                out["rho_p"], out["rho_q"] = rho[..., 0], rho[..., 1]
            return out

        until = UntilConverged(
            quantities, max_seconds=float(max_seconds), thin=run.thin,
            announce=None if progress is None else progress.extend,
        )  # fmt: skip
        until.start(run.draws)
    res = sample(
        sampled, start=sample_start, draws=run.draws, burn=run.burn, thin=run.thin,
        chains=run.chains, seed=run.seed, workers=run.threads, move=move, student_t=student_t,
        progress=progress, extend=until, factor=factor, ar=noise == "ar1",
        deadline=None if until is None else until.deadline(),  # the budget from iteration 0
    )  # fmt: skip
    if until is not None:
        until.note_cut(res)
    t2 = time.perf_counter()
    seconds = {"nls": t1 - t0, "sampler": t2 - t_sample}
    blocks = ChainDraws.stack(res, steps=bool(problem.n_steps), torque=estimate)
    draws_named = blocks.named(problem, cache=steady)
    if noise == "ar1":
        rho = np.stack([r.rho for r in res])
        draws_named["rho_p"], draws_named["rho_q"] = rho[..., 0], rho[..., 1]
    if zip_motor:
        common = problem_settings(problem, torque, settings)
    else:
        common = {"model": model.name, "n": int(sum(e.n for e in events)),
                  "prior": prior.to_dict(), **(settings or {})}  # fmt: skip
        if hasattr(model, "options"):  # every field, so exports and playback can rebuild it
            common["model_options"] = model.options()
    free = free_names(problem)
    coefficients = coefficient_names(draws_named)
    robust_settings, constant, robust_warn = {}, {}, []
    if student_t is not None:
        robust_settings, constant, robust_warn = robust_outputs(problem, res, nu, draws_named)
    post = Posterior(
        draws_named,
        model="composite",
        method=METHOD[move] + ("-student-t" if student_t else ""),
        constant={**constant, **event_arrays(events)},  # the recordings, for the report
        warnings=unit_warnings + start_warnings(events) + own_bases_warnings(events) + robust_warn,
        coefficients=coefficients,
        free=free,
        observed={"t_s": events[0].t, "v": events[0].v, "p": events[0].p, "q": events[0].q},
        settings={
            **common,
            # The voltages and durations the events span: a prediction beyond them is
            # said to extrapolate (``loadbayes predict``).
            "covered": covered(events),
            **sampler_record(run, move, res, dict(seconds), likelihood),
            **robust_settings,
        },
    )
    watch = tuple(model.theta_names[: len(model.free_coordinates)])
    if zip_motor:
        # What the zip+motor fit says in words: identifiability, the static part, the
        # residuals, the convergence of its coordinates (fit/composite/describe.py).
        describe_fit(post, draws_named, model, problem, blocks, run, watch)
    else:
        post.warnings.extend(convergence_warnings(draws_named, watch, run.chains))
        if res and res[0].restart_note:  # chains moved out of a lower mode (restart.py)
            post.warnings.append(res[0].restart_note)
        if hasattr(model, "parts"):  # a model of parts: physical, prior's, negative sequence
            describe_parts(post, draws_named, model, events, run.hdi_prob,
                           residuals=parts_residuals(problem, blocks))  # fmt: skip
    if noise == "ar1":  # an error slower than the motors can stand in for them
        dt = float(np.median(np.concatenate([np.diff(e.t) for e in events])))
        slow = ar1_memory_warning(draws_named, dt)
        if slow:
            post.warnings.append(slow)
    if until is not None:
        post.settings["until_converged"] = {
            **until.record(),
            # What ran: with a budget that cut a round, the asked less the cut (the burn-in
            # too may have been cut short), else the burn-in and the kept draws.
            "iterations_per_chain": until.asked_iterations - until.cut_iterations
            if until.cut_iterations
            else run.burn + res[0].theta.shape[0] * run.thin,
        }
        budget = until.warning(res)
        if budget:
            post.warnings.append(budget)
    # Baseline draws per chain: (draws - burn) // thin, at least one (not run.kept, which
    # rounds up: the baseline's size has always been this); no more than the chains kept,
    # when a budget cut them short (a cut run of 200,000 asked spent 1.8 s naming them).
    n_baseline = max(min((run.draws - run.burn) // run.thin, res[0].theta.shape[0]), 1)
    base_draws = _baseline_draws(problem, start, run.chains, n_baseline, run.seed)
    baseline = Posterior(
        base_draws,
        model="composite",
        method="nls-penalised",
        # Its own: the NLS has no AR(1) rho nor torque log-ratios to summarise (naming
        # them crashed --baseline-json with --noise ar1 or --torque estimate).
        coefficients=[n for n in coefficients if n in base_draws],
        free=free,
        settings={**common, **baseline_record(problem, start)},
    )
    return CompositeFit(post, baseline, problem, start, seconds)
