"""The sampler's own steps for a model's thresholds: motor D's stall, the electronics' trip.

A model of parts that samples its thresholds (``PartsModel.fit_thresholds``: motor D's
``vstall, log_tstall``, the electronics' ``vd1, vd2``) has a likelihood that is flat in
them wherever the fitted events' load-bus voltage stays above them (nothing stalls or
trips, whatever their value) and jumps where it crosses them. The joint block move of
the sampler barely moves them (a flat direction in a proposal tuned to the others), so
each iteration adds, per part (the pair keyed by its upper voltage, ``vstall`` or
``vd1``):

- an **independence step from the prior**: the pair drawn afresh from its prior. Where
  the fitted events' lowest load-bus voltage (at the current feeder impedance) lies
  above both the current and the proposed key voltage, the two likelihoods are the same
  and the step is taken without solving the model (the Metropolis-Hastings ratio of an
  independence proposal from the prior is the likelihood ratio, here 1); otherwise the
  model is solved and the step accepted by that ratio. Over shallow events the pair
  therefore mixes as fast as the prior can be drawn, and its posterior is the prior less
  the values the events rule out (those that would have stalled or tripped in them);
- a **random-walk step** (a quarter of the prior's sd), only where the events reach the
  part's voltages: where a fitted event does stall or trip, the data pin the pair down
  and the draws from the prior are mostly refused.

Both leave the posterior invariant (a Metropolis-Hastings step each).
"""

from __future__ import annotations

import math

import numpy as np

from loadbayes.models.part_priors import THRESHOLD_COORDS

__all__ = ["ThresholdMoves"]

#: The random walk's sd, as a share of the prior's.
RW_SHARE = 0.25
#: Voltage margin (p.u.) above which a key voltage is taken as not reached.
MARGIN = 1e-6


class ThresholdMoves:
    """The thresholds' steps of a :class:`~.design.DesignProblem` (module docstring)."""

    def __init__(self, problem) -> None:
        model = problem.model
        self.problem, self.model = problem, model
        idx = {n: model.theta_names.index(THRESHOLD_COORDS[n]) for n in model.thresholds}
        self.pairs = [(idx[a], idx[b]) for a, b in (("vstall", "tstall"), ("vd1", "vd2"))
                      if a in idx]  # fmt: skip
        mean, cov, _, _ = problem.prior.scale_free()
        self.mean, self.sd = mean, np.sqrt(np.diag(cov))
        self.accepted = np.zeros(2)
        self.tried = np.zeros(2)

    def lowest_voltage(self, u: np.ndarray) -> float:
        """The fitted events' lowest load-bus voltage (rows the likelihood reads) at ``u``."""
        theta = self.problem.theta(u)
        return min(self.model.lowest_voltage(ev, theta) for ev in self.problem.events)

    def __call__(self, u, lp, sums, logp, rng, **state):
        """One independence and (where the voltages are reached) one random-walk step per pair."""
        prior, inside = self.problem.prior, self.problem.in_support
        low = self.lowest_voltage(u)
        prior_u = None  # prior.log_u(u), computed once per u (the same number each time)
        for pair in self.pairs:
            ix = list(pair)
            for kind in (0, 1):
                cand = u.copy()
                if kind == 0:
                    cand[ix] = self.mean[ix] + self.sd[ix] * rng.standard_normal(2)
                else:
                    if low > u[pair[0]] + MARGIN:
                        continue  # nothing reached: the independence step has mixed it
                    cand[ix] = u[ix] + RW_SHARE * self.sd[ix] * rng.standard_normal(2)
                self.tried[kind] += 1
                if not inside(cand):
                    continue
                prior_c = prior.log_u(cand)
                if prior_u is None:
                    prior_u = prior.log_u(u)
                dprior = prior_c - prior_u
                if low > max(u[pair[0]], cand[pair[0]]) + MARGIN:
                    # Neither value is reached: the same likelihood, no solve needed.
                    u, lp, prior_u = cand, lp + dprior, prior_c
                    self.accepted[kind] += 1
                    continue
                lc, s2 = logp(cand)
                if s2 is None or not math.isfinite(lc):
                    continue
                # Independence from the prior: the likelihood ratio; random walk: the posterior's.
                log_r = lc - lp - (dprior if kind == 0 else 0.0)
                if math.log(rng.uniform()) < log_r:
                    u, lp, sums, prior_u = cand, lc, s2, prior_c
                    self.accepted[kind] += 1
        return u, lp, sums
