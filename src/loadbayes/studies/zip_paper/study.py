"""The ZIP study's settings and result: the paper's numbers, the estimators, ``ZipStudy``.

Every other module of :mod:`loadbayes.studies.zip_paper` reads these; this one imports
none of them.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
import pandas as pd

from loadbayes.posterior import Posterior

#: The paper's posterior means of a1 and a2 (Fig. 2); a3 = 1 - a1 - a2.
PAPER_MEANS = {"a1": 0.25, "a2": 0.249}
#: The paper's Table II (10% noise): (voltage error %, active-power error %).
PAPER_TABLE2 = {"GS": (0.007, 1.12), "LS": (0.062, 4.65), "KF": (0.024, 2.64)}
#: The paper's validation (Fig. 4): |dV| and |dP| "in the range of" these.
PAPER_VALIDATION = {"dv": 1e-4, "dp": 1e-3}
#: The true ZIP shares of P and of Q (the paper's a1, a2, a3).
TRUE_ZIP = (0.25, 0.25, 0.5)

#: Estimators, by key: label. ``gs``, ``ls``, ``kf`` are Table II's rows.
METHODS = {
    "gs": "GS (blocked Gibbs, posterior mean)",
    "ls": "LS (a1 + a2 + a3 = 1)",
    "kf": "KF (no process noise)",
    "gs_single": "GS (single-site, the paper's Algorithm 1)",
    "ls3": "LS (three free coefficients, normalised)",
    "kf_rw": "KF (random walk)",
}
TABLE2_ROWS = {"gs": "GS", "ls": "LS", "kf": "KF"}
#: Process noise of the random-walk Kalman filter (per measurement, times the identity).
KF_RANDOM_WALK = 1e-6
#: Coefficient sd targets for the "what n would the paper need" table.
SD_TARGETS = (0.01, 0.001)

FULL: dict[str, Any] = {
    "n": 1000,
    "sweep_n": (100, 300, 1_000, 3_000, 10_000, 30_000, 100_000),
    "draws": 40_000,
    "burn": 5_000,
    "chains": 4,
    "n_validation": 100,
    "predictive_experiments": 100,
    "predictive_draws": 200,
}
QUICK: dict[str, Any] = {
    "n": 300,
    "sweep_n": (100, 300, 1_000),
    "draws": 10_000,
    "burn": 2_000,
    "chains": 2,
    "n_validation": 100,
    "predictive_experiments": 20,
    "predictive_draws": 25,
}
#: ``reproduce all --smoke``: every step at a size that only checks the pipeline (the
#: numbers are not results).
SMOKE: dict[str, Any] = {
    "n": 40,
    "sweep_n": (20, 40),
    "draws": 600,
    "burn": 200,
    "chains": 2,
    "n_validation": 4,
    "predictive_experiments": 2,
    "predictive_draws": 3,
}
SWEEP_NOISE = (0.01, 0.05, 0.1)
_MARK = "loadbayes:section zip"


@dataclass
class ZipStudy:
    """Everything the study computed.

    Attributes
    ----------
    settings : dict
        n, noise, seeds, priors, sampler, power-flow counts and failures, timings.
    data : pandas.DataFrame
        The fitted experiments (first ``n`` of the generated ones), failed ones flagged.
    fits : dict of str to Posterior
        One result per key of :data:`METHODS`.
    validation : pandas.DataFrame
        One row per validation experiment: true and estimated V, P, Q for each method,
        and the posterior-predictive band (NaN outside the predictive subset).
    traces : dict of str to ndarray
        ``a1`` of every chain from the first iteration (burn-in included), by scheme.
    sweep : pandas.DataFrame
        Posterior sd of a1, a2 by noise and n.
    """

    settings: dict[str, Any]
    data: pd.DataFrame
    fits: dict[str, Posterior]
    validation: pd.DataFrame
    traces: dict[str, np.ndarray]
    sweep: pd.DataFrame
    timings: dict[str, float] = field(default_factory=dict)
    _summaries: dict[str, pd.DataFrame] = field(default_factory=dict, repr=False)

    def summary(self, method: str) -> pd.DataFrame:
        """ArviZ summary (95% HDI) of a1, a2, a3 for one fit, cached."""
        if method not in self._summaries:
            self._summaries[method] = self.fits[method].summary(var_names=["a1", "a2", "a3"])
        return self._summaries[method]

    def estimate(self, method: str) -> dict[str, float]:
        """Point estimate of a method: the posterior mean, or the exact LS / KF value."""
        post = self.fits[method]
        if "estimate" in post.settings:
            return {k: float(v) for k, v in post.settings["estimate"].items()}
        return post.mean()
