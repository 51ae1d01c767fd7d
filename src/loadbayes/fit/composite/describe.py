"""What a ``zip+motor`` fit says in words beside its draws.

:func:`describe_fit` adds to the posterior the plain-words identifiability of the motor
(and of an estimated torque), the static part's (which shares the events fixed), the
warnings on sampling and convergence, the residuals' lag-1 autocorrelation, and whether
the static part is a physical ZIP load. The driver calls it for the ``zip+motor`` model;
the parts it reads (``f_m``, ``t_prime_s``, ``a1..a6``, the motor's theta) are that
model's.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from loadbayes.core.settings import SamplerSettings
from loadbayes.fit.composite.checks import convergence_warnings, sampling_warnings
from loadbayes.fit.composite.identifiability import (
    identifiability,
    prior_driven_warning,
    static_identifiability,
    torque_identifiability,
)
from loadbayes.fit.composite.naming import ChainDraws
from loadbayes.fit.composite.problem import CompositeProblem
from loadbayes.fit.composite.residuals import (
    N_DRAWS,
    residual_autocorrelation,
    residual_warning,
)
from loadbayes.posterior import Posterior

__all__ = ["WATCH_TORQUE", "describe_fit", "shares_outside"]

#: The torque's log-ratios, whose R-hat is checked (beside the model's free
#: coordinates) when the shares are estimated.
WATCH_TORQUE = ("log_a_over_c", "log_b_over_c")


def shares_outside(draws: dict[str, np.ndarray]) -> str:
    """The static shares (and ``f_m``) whose posterior mean lies outside [0, 1], in words."""
    out = []
    for name in sorted(draws):
        base = name.split("_e")[0]
        if base in ("a1", "a2", "a3", "a4", "a5", "a6", "f_m"):
            m = float(np.mean(draws[name]))
            if not -0.02 <= m <= 1.02:
                out.append(f"{name} {m:+.2f}")
    return ", ".join(out)


def describe_fit(
    post: Posterior,
    draws: dict[str, np.ndarray],
    model: Any,
    problem: CompositeProblem,
    blocks: ChainDraws,
    run: SamplerSettings,
    watch: tuple[str, ...],
) -> None:
    """Add the words of a ``zip+motor`` fit to ``post`` (its warnings, settings, JSON).

    ``draws`` are the named draws ``post`` was built from, ``blocks`` the sampled blocks
    they were named from, ``watch`` the coordinates whose R-hat is checked.
    """
    events, prior = problem.recorded, problem.prior
    estimate = model.estimate_torque
    span = max(float(e.t[-1] - e.t[0]) for e in events)
    bounded = model.shares == "bounded"  # f_m and the shares in [0, 1]: say when at a bound
    ident = identifiability(blocks.theta, draws["f_m"], prior, len(events), span_s=span,
                            bounded=bounded)  # fmt: skip
    if estimate:
        ident["torque"] = torque_identifiability(blocks.abc)
        ident["summary"] += " " + ident["torque"]["summary"]
    # The static (ZIP) part: which shares the events fixed, and the combinations they do.
    ident["static_part"] = static_identifiability(
        draws, events, prior=prior, hdi_prob=run.hdi_prob, bounded=bounded
    )
    if "at_bound" in ident["static_part"]:  # with the motor's words (the CLI prints them)
        ident["summary"] += " " + ident["static_part"]["at_bound"]
    post.extra_json["identifiability"] = ident
    weak = prior_driven_warning(ident)
    if weak:
        post.warnings.append(weak)
    if ident["static_part"]["warning"]:
        post.warnings.append(ident["static_part"]["warning"])
    post.warnings.extend(sampling_warnings(events, draws["t_prime_s"], steps_modelled=model.steps))
    watch = watch + (WATCH_TORQUE if estimate else ())
    post.warnings.extend(convergence_warnings(draws, watch, run.chains))
    lag1_mcse: dict[str, float] = {}
    lag1 = residual_autocorrelation(
        problem, blocks.theta, blocks.phi, blocks.betas, seed=run.seed, abc=blocks.abc,
        mcse=lag1_mcse,
    )  # fmt: skip
    post.settings["noise"] = model.noise
    post.settings["residuals"] = {
        "lag1_autocorrelation": lag1,
        "lag1_mcse": lag1_mcse,
        "what": f"lag-1 autocorrelation of each event's P and Q residuals, mean over "
        f"{N_DRAWS} posterior draws (white noise: within +-2/sqrt(n) of 0); lag1_mcse: "
        "each mean's standard error over the draws picked",
    }
    lag_warning = residual_warning(lag1) if model.noise == "white" else None
    if lag_warning:
        post.warnings.append(lag_warning)
    post.settings["coefficient_prior"] = {
        "shares": model.shares,
        "normal": {n: [float(m), float(sd)] for n, (m, sd) in model.coefficient_priors.items()},
    }
    if model.shares != "bounded":
        outside = shares_outside(draws)
        if outside:
            post.warnings.append(
                f"the static part is not a physical ZIP load: {outside}; a simulator's "
                "static load needs every share in [0, 1]: refit with --shares bounded "
                "(shares='bounded') to hold them there"
            )
