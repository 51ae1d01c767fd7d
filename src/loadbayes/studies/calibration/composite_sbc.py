"""The composite sampler under SBC: a short event, parameters drawn from the fit's prior.

Design: one fixed voltage record (a 35% sag at 0.3 s for 0.2 s with a 0.2 s recovery,
1.5 s at 30 samples per second: 46 samples), the motor's scale-free coordinates drawn
from the prior of :class:`~loadbayes.fit.composite.problem.CompositePrior` (the default
THETA_PRIOR; draws with no stable steady state are redrawn, which is the prior the
sampler sees, since it gives them zero density), ``log T0`` from its prior given them,
the seven linear coefficients from their normal prior (sd 1, ``p_m0`` truncated to > 0)
and the noise precisions from Gamma(10, 10 * 0.02^2) (a noise sd near 2%). The sag's
step is placed at a fraction ``step_phi`` of its sample interval drawn uniformly (the
fit's prior, models/composite_steps.py). The data are the model's own P and Q (the
compiled kernel) plus normal noise. The fit is the
package's path (NLS start, then :func:`~loadbayes.fit.composite.sampler.sample`), one chain
thinned to near independence.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from loadbayes.testing.sbc import SamplerUnderTest

__all__ = ["PARAMETERS", "composite_sampler"]

PARAMETERS: tuple[str, ...] = (
    "log_rs_t0",
    "log_x_prime_t0",
    "log_dx_t0",
    "log_t_prime",
    "log_h_over_t0",
    "log_t0",
    "cp2",
    "cp0",
    "cq1",
    "p_m0",
    "f_m",
    "tau_p",
    "tau_q",
    "step_phi",
)
_TAU = (10.0, 10.0 * 0.02**2)


def _event():
    from loadbayes.cases.composite_sim import sag_samples
    from loadbayes.measurements.record import EventRecord

    t = np.arange(46) / 30.0
    v = sag_samples(t, depth=0.35, start_s=0.3, duration_s=0.2, recovery_s=0.2)
    return EventRecord(t, v, np.zeros_like(t), np.zeros_like(t), None, "sbc")


def _prior(event):
    from loadbayes.models.composite import THETA_NAMES
    from loadbayes.models.composite_prior import THETA_PRIOR, CompositePrior

    return CompositePrior(
        np.array([THETA_PRIOR[n][0] for n in THETA_NAMES]),
        np.array([THETA_PRIOR[n][1] for n in THETA_NAMES]),
        np.ones(7),
        *_TAU,
    )


def composite_sampler(
    name: str,
    *,
    thin: int = 40,
    burn: int = 600,
    kept: int = 59,
    notes: str = "",
    ci_replications: int | None = None,
) -> SamplerUnderTest:
    """The composite Metropolis-within-Gibbs sampler as SBC sees it (module docstring)."""
    from loadbayes.fit.composite.nls import nls
    from loadbayes.fit.composite.problem import CompositeProblem
    from loadbayes.fit.composite.sampler import sample
    from loadbayes.models.composite import BETA_NAMES, SCALE_FREE_MATRIX, design

    event = _event()
    prior = _prior(event)
    problem = CompositeProblem([event], prior, window_s=0)
    assert problem.n_steps == 1, "the SBC event has one step (into the sag)"
    mean_u, cov_u, _, _ = prior.scale_free()
    root_u = np.linalg.cholesky(cov_u)

    def draw_prior(rng: np.random.Generator) -> dict[str, float]:
        while True:
            u = mean_u + root_u @ rng.standard_normal(5)
            if problem.responses(np.r_[u, 0.5]) is not None:
                break
        log_t0 = prior.draw_log_t0(u, rng)
        beta = rng.standard_normal(7)
        beta[6] = abs(beta[6])
        tau = rng.gamma(_TAU[0], 1.0 / _TAU[1], 2)
        out = dict(zip(PARAMETERS[:5], u.tolist(), strict=True))
        out["log_t0"] = log_t0
        out.update(dict(zip(BETA_NAMES, beta.tolist(), strict=True)))
        out["f_m"] = beta[6] / (beta[0] + beta[1] + beta[2] + beta[6])
        out["tau_p"], out["tau_q"] = float(tau[0]), float(tau[1])
        out["step_phi"] = float(rng.uniform())
        return out

    def simulate(theta: Mapping[str, float], rng: np.random.Generator):
        from loadbayes.measurements.record import EventRecord

        phi = theta["step_phi"]
        u = np.array([theta[n] for n in PARAMETERS[:5]] + [phi])
        beta = np.array([theta[n] for n in BETA_NAMES])
        # The motor's columns on the base T0 = 1 with the step placed: the design's
        # motor columns are normalised by p_m(0), so the base does not matter.
        pm, qm = problem.responses(u)[0]
        zp, zq = design(event, pm, qm)
        p, q = zp @ beta, zq @ beta
        p = p + rng.standard_normal(p.size) / np.sqrt(theta["tau_p"])
        q = q + rng.standard_normal(q.size) / np.sqrt(theta["tau_q"])
        return EventRecord(event.t, event.v, p, q, None, "sbc")

    def fit(data, seed: int) -> dict[str, np.ndarray]:
        prob = CompositeProblem([data], prior, window_s=0)
        # One NLS start (the prior median): the chain's burn-in does the rest.
        start = nls(prob, starts=[mean_u])  # (the step starts mid-interval)
        res = sample(
            prob,
            start=start,
            draws=burn + thin * kept,
            burn=burn,
            thin=thin,
            chains=1,
            seed=seed,
            workers=1,
        )[0]
        u = res.theta @ SCALE_FREE_MATRIX.T
        out = {n: u[:, i] for i, n in enumerate(PARAMETERS[:6])}
        b = res.beta[:, 0, :]
        out.update({n: b[:, i] for i, n in enumerate(BETA_NAMES)})
        out["f_m"] = b[:, 6] / (b[:, 0] + b[:, 1] + b[:, 2] + b[:, 6])
        out["tau_p"], out["tau_q"] = res.tau[:, 0], res.tau[:, 1]
        out["step_phi"] = res.phi[:, 0]
        return out

    return SamplerUnderTest(
        name, PARAMETERS, draw_prior, simulate, fit, kept, notes, ci_replications
    )
