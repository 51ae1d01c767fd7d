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
from loadbayes.fit.composite.bounded import share_start
from loadbayes.fit.composite.checks import (
    check_run,
    convergence_warnings,
    sampling_warnings,
    start_warnings,
)
from loadbayes.fit.composite.identifiability import (
    identifiability,
    prior_driven_warning,
    static_identifiability,
    torque_identifiability,
)
from loadbayes.fit.composite.naming import (
    ChainDraws,
    coefficient_names,
    free_names,
    named_draws,
)
from loadbayes.fit.composite.nls import NLSResult, nls
from loadbayes.fit.composite.predictive import event_arrays
from loadbayes.fit.composite.problem import CompositeProblem, theta_of
from loadbayes.fit.composite.provenance import (
    METHOD,
    baseline_record,
    problem_settings,
    sampler_record,
)
from loadbayes.fit.composite.residuals import residual_autocorrelation, residual_warning
from loadbayes.fit.composite.robust import StudentT, robust_outputs
from loadbayes.fit.composite.sampler import DEFAULT_MOVE, ONE_EVALUATION_MOVES, sample
from loadbayes.fit.composite.torque import TorqueProblem, extend_start
from loadbayes.fit.composite.until import DEFAULT_MAX_SECONDS, UntilConverged
from loadbayes.measurements.record import EventRecord, check_units
from loadbayes.models.composite import THETA_NAMES
from loadbayes.models.composite_prior import CoefficientPrior, CompositePrior
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


def _shares_outside(draws: dict[str, np.ndarray]) -> str:
    # The static shares (and f_m) whose posterior mean lies outside [0, 1], in words.
    out = []
    for name in sorted(draws):
        base = name.split("_e")[0]
        if base in ("a1", "a2", "a3", "a4", "a5", "a6", "f_m"):
            m = float(np.mean(draws[name]))
            if not -0.02 <= m <= 1.02:
                out.append(f"{name} {m:+.2f}")
    return ", ".join(out)


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


#: Iterations of the short run that times one iteration before the chains start.
_PROBE_ITERATIONS = 12


def _estimate_seconds(
    sampled, start, run: SamplerSettings, move: str, student_t, factor=None, noise="white"
) -> float:
    # Measure a few iterations of one chain (its own throw-away run) and extrapolate: the
    # chains share the threads, each runs run.draws iterations.
    from loadbayes.core.parallel import num_threads

    def probe(n: int) -> float:
        t0 = time.perf_counter()
        sample(sampled, start=start, draws=n, burn=n // 2, chains=1, seed=run.seed,
               workers=1, move=move, student_t=student_t, factor=factor,
               ar=noise == "ar1")  # fmt: skip
        return time.perf_counter() - t0

    probe(2)  # the first call compiles the kernels (the run would pay it anyway)
    per_iteration = probe(_PROBE_ITERATIONS) / _PROBE_ITERATIONS
    threads = run.threads or num_threads()
    rounds = math.ceil(run.chains / max(1, min(threads, run.chains)))
    return per_iteration * run.draws * rounds


def _factor(shares: str, normal: dict | None, move: str) -> CoefficientPrior | None:
    from loadbayes.io.errors import OptionError

    if shares not in ("free", "bounded"):
        raise OptionError(f"--shares {shares!r}: one of free, bounded")
    try:
        # Bounded shares are the bounded model's parametrisation (fit/composite/bounded.py),
        # not a factor; the normal factors stay factors.
        factor = CoefficientPrior(
            normal=tuple((n, float(m), float(s)) for n, (m, s) in (normal or {}).items()),
        )
    except ValueError as exc:
        raise OptionError(f"--prior: {exc}") from None
    if factor.active and move not in ONE_EVALUATION_MOVES:
        raise OptionError(
            "--shares bounded and priors on a1..a6, f_m, p0, q0 need a Metropolis move "
            f"({', '.join(ONE_EVALUATION_MOVES)}), not {move!r}"
        )
    return factor if factor.active else None


def _check_share_prior(items) -> None:
    from loadbayes.io.errors import OptionError

    for i, mean, sd in items:
        if not (math.isfinite(mean) and math.isfinite(sd) and sd > 0):
            raise OptionError(f"--prior a{i + 1}: the mean must be finite, the sd positive")


def _append_start(start: NLSResult, values: np.ndarray, *, sd: float) -> NLSResult:
    # The sampler's start with coordinates appended (independent, sd ``sd``).
    from dataclasses import replace

    d, k = start.u.size, values.size
    cov = np.zeros((d + k, d + k))
    cov[:d, :d] = start.cov[:d, :d]
    cov[d:, d:] = sd**2 * np.eye(k)
    return replace(start, u=np.concatenate([start.u, values]), cov=cov)


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
    max_seconds: float = DEFAULT_MAX_SECONDS,
    until_converged: bool | None = None,
    window_s: float | None = None,
    shares: str = "free",
    noise: str = "white",
    coefficient_prior: dict[str, tuple[float, float]] | None = None,
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
        the check is ``fit zip``'s: :func:`loadbayes.measurements.record.check_units`).
    progress : SamplingProgress, optional
        Told the estimated cost before sampling (a short timed run) and the iterations
        as they are done.
    max_seconds : float
        Time budget of the sampling when it runs until convergence (s).
    window_s : float, optional
        The recorder's phasor window (s; default one cycle of ``f_hz``): the samples
        inside a fault's edge, whose window straddles the change, are left out
        (``models/composite_steps.py``), and the edge becomes a step at an unknown
        instant. ``0``: point samples (a simulation), each the value at its instant;
        they are all kept, and an edge with samples inside it is a straight ramp
        through them from an unknown instant (``models/composite_steps.py``).
    shares : {"free", "bounded"}
        ``"bounded"`` holds every static share in [0, 1] (and so ``f_m`` in (0, 1)) by
        its prior: a physically admissible load, as an export needs. ``"free"`` (the
        default) lets the data put them anywhere (a negative share fits a load that
        the ZIP form cannot describe, or an undetermined static part).
    noise : {"white", "ar1"}
        Noise on P and Q independent from sample to sample, or AR(1) in each channel
        (``rho_p``, ``rho_q`` sampled, uniform on (-1, 1); Gaussian likelihood only):
        the likelihood a recording whose residuals run in stretches needs for honest
        intervals (docs/composite.md, "Residuals that run in time").
    coefficient_prior : dict, optional
        ``{name: (mean, sd)}``: a normal prior factor on ``a1..a6``, ``f_m``, ``p0`` or
        ``q0`` of every event (:class:`~loadbayes.models.composite_prior.CoefficientPrior`).
    until_converged : bool, optional
        After ``draws`` iterations, run the chains on until every reported quantity has
        R-hat < 1.01 and bulk ESS >= 400, or ``max_seconds`` runs out (then a warning
        says so): :mod:`loadbayes.fit.composite.until`. Default: True when the number
        of draws was left at its default (neither ``sampler`` nor ``draws`` given),
        False when it was given (that many iterations, as asked).
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
    if until_converged is None:
        until_converged = sampler is None and "draws" not in overrides
    base = sampler if sampler is not None else COMPOSITE_DEFAULTS
    run = SamplerSettings.of(base, threads=workers, **overrides)
    events = list(events)
    if not events:
        raise ValueError("no events to fit")
    check_run(
        f_hz=f_hz, draws=run.draws, burn=run.burn, thin=run.thin, seed=run.seed,
        max_seconds=max_seconds,
    )  # fmt: skip
    unit_warnings = check_units(events, accept_units=accept_units, wording=wording)
    prior = prior or CompositePrior.default(events)
    estimate = isinstance(torque, str)
    if estimate and torque != "estimate":
        raise ValueError(f"torque must be (A, B, C) or 'estimate', got {torque!r}")
    # Estimated shares: NLS (the start) at the prior's centre A = B = C = 1/3.
    fixed = (1 / 3, 1 / 3, 1 / 3) if estimate else tuple(torque)
    if window_s is not None and not (math.isfinite(window_s) and 0 <= window_s <= 1.0):
        from loadbayes.io.errors import OptionError

        raise OptionError(f"--window-s {window_s}: the phasor window must be 0-1 s")
    kw = dict(f_hz=f_hz, torque=fixed, h_max=h_max, steps=steps, window_s=window_s)
    problem = CompositeProblem(events, prior, **kw)
    bounded = shares == "bounded"
    coefficient_prior = dict(coefficient_prior or {})
    # With bounded shares a prior on a share is part of the sampled density (exact and
    # free); the other coefficient priors are factors (importance weights).
    share_prior = tuple(
        (int(n[1]) - 1, float(m), float(sd))
        for n, (m, sd) in coefficient_prior.items()
        if bounded and n in ("a1", "a2", "a3", "a4", "a5", "a6")
    )
    factor = _factor(
        shares,
        {n: v for n, v in coefficient_prior.items() if not (bounded and n[0] == "a")},
        move,
    )
    if noise not in ("white", "ar1"):
        from loadbayes.io.errors import OptionError

        raise OptionError(f"--noise {noise!r}: one of white, ar1")
    if noise == "ar1" and likelihood != "normal":
        from loadbayes.io.errors import OptionError

        raise OptionError("--noise ar1 works with --likelihood normal only")
    if bounded and likelihood != "normal":
        from loadbayes.io.errors import OptionError

        raise OptionError("--shares bounded works with --likelihood normal only (for now)")
    t0 = time.perf_counter()
    start = nls(problem)
    t1 = time.perf_counter()
    sampled, sample_start = problem, start
    if bounded:
        # The shares become sampled coordinates (fit/composite/bounded.py), started at
        # the free estimate's shares moved inside the simplex.
        _check_share_prior(share_prior)
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
    if until_converged and run.chains >= 2:

        def quantities(results) -> dict[str, np.ndarray]:
            named = ChainDraws.stack(results, steps=bool(problem.n_steps), torque=estimate)
            named = named.named(problem)
            out = {n: named[n] for n in (*free_names(problem), *coefficient_names(named))}
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
    )  # fmt: skip
    t2 = time.perf_counter()
    seconds = {"nls": t1 - t0, "sampler": t2 - t_sample}
    blocks = ChainDraws.stack(res, steps=bool(problem.n_steps), torque=estimate)
    draws_named = blocks.named(problem)
    if noise == "ar1":
        rho = np.stack([r.rho for r in res])
        draws_named["rho_p"], draws_named["rho_q"] = rho[..., 0], rho[..., 1]
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
        constant={**constant, **event_arrays(events)},  # the recordings, for the report
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
    # The static (ZIP) part: which shares the events fixed, and the combinations they do.
    ident["static_part"] = static_identifiability(draws_named, events, prior=prior,
                                                  hdi_prob=run.hdi_prob)  # fmt: skip
    post.extra_json["identifiability"] = ident
    weak = prior_driven_warning(ident)
    if weak:
        post.warnings.append(weak)
    if ident["static_part"]["warning"]:
        post.warnings.append(ident["static_part"]["warning"])
    post.warnings.extend(sampling_warnings(events, draws_named["t_prime_s"], steps_modelled=steps))
    watch = _WATCH + (_WATCH_TORQUE if estimate else ())
    post.warnings.extend(convergence_warnings(draws_named, watch, run.chains))
    lag1 = residual_autocorrelation(
        problem, blocks.theta, blocks.phi, blocks.betas, seed=run.seed, abc=blocks.abc
    )
    post.settings["noise"] = noise
    post.settings["residuals"] = {
        "lag1_autocorrelation": lag1,
        "what": "lag-1 autocorrelation of each event's P and Q residuals, mean over 20 "
        "posterior draws (white noise: within +-2/sqrt(n) of 0)",
    }
    lag_warning = residual_warning(lag1) if noise == "white" else None
    if lag_warning:
        post.warnings.append(lag_warning)
    post.settings["coefficient_prior"] = {
        "shares": shares,
        "normal": {n: [float(m), float(sd)] for n, (m, sd) in coefficient_prior.items()},
    }
    if not bounded:
        outside = _shares_outside(draws_named)
        if outside:
            post.warnings.append(
                f"the static part is not a physical ZIP load: {outside}; a simulator's "
                "static load needs every share in [0, 1]: refit with --shares bounded "
                "(shares='bounded') to hold them there"
            )
    if until is not None:
        post.settings["until_converged"] = {
            **until.record(),
            "iterations_per_chain": run.burn + res[0].theta.shape[0] * run.thin,
        }
        budget = until.warning(res)
        if budget:
            post.warnings.append(budget)
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
