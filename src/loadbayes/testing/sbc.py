"""Simulation-based calibration (Talts et al., 2018) and interval coverage of the samplers.

SBC draws parameters from the prior, data from the model given them, and fits the data
with the sampler under test. If the sampler draws from the posterior of that prior and
model, the rank of each true value among ``L`` posterior draws is uniform on
``{0, ..., L}`` (for every parameter, and for any function of them such as
``a3 = 1 - a1 - a2``). Ranks are binned and tested for uniformity with a chi-square test.
The same replications give the coverage of the credible intervals, which is exactly the
nominal probability when the truth is drawn from the prior.

Independent draws are assumed: the fit thins its chain until the kept draws are nearly
independent (the lag-1 autocorrelation of the kept draws is reported so that this can be
checked), otherwise the ranks pile up at the ends.

A sampler under test is one :class:`SamplerUnderTest`: a prior simulator, a data
simulator and a fit function. :data:`loadbayes.studies.calibration.registry.REGISTRY` holds one
per sampler; adding a sampler (a robust or an online estimator) means adding one entry
there, and the SBC and coverage tests and ``make validate`` pick it up.

References
----------
Talts, Betancourt, Simpson, Vehtari, Gelman (2018), "Validating Bayesian inference
algorithms with simulation-based calibration", arXiv:1804.06788.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy import stats

from loadbayes.core.priors import BlockPrior

__all__ = [
    "CoverageResult",
    "SBCResult",
    "SamplerUnderTest",
    "draw_block_prior",
    "hdi",
    "replicate",
    "run_coverage",
    "run_sbc",
]

Draws = Mapping[str, np.ndarray]


@dataclass(frozen=True)
class SamplerUnderTest:
    """A sampler as SBC and coverage see it.

    Parameters
    ----------
    name : str
        Registry key, e.g. ``"zip-blocked"``.
    parameters : tuple of str
        Names checked: keys of what ``draw_prior`` returns and of what ``fit`` returns.
    draw_prior : callable or None
        ``draw_prior(rng) -> {name: float}``: one draw of every parameter from the prior
        that ``fit`` uses (extra keys, e.g. a latent path the data simulator needs, are
        passed along and not ranked). None when the entry is for fixed-truth coverage
        only.
    simulate : callable
        ``simulate(theta, rng) -> data``: a data set given the parameters.
    fit : callable
        ``fit(data, seed) -> {name: ndarray of shape (kept,)}``: posterior draws, thinned
        to near independence.
    kept : int
        Draws ``fit`` returns per parameter (``L`` in Talts et al.).
    notes : str
        Design, prior and thinning, for the report.
    ci_replications : int, optional
        Replications the CI test runs, when fewer than its default (an expensive fit).
    """

    name: str
    parameters: tuple[str, ...]
    draw_prior: Callable[[np.random.Generator], dict[str, Any]] | None
    simulate: Callable[[Mapping[str, Any], np.random.Generator], Any]
    fit: Callable[[Any, int], Draws]
    kept: int
    notes: str = ""
    #: Replications in CI when the default would exceed the test-time budget (None:
    #: the test's default).
    ci_replications: int | None = None


# --------------------------------------------------------------------------- running
def replicate(
    sut: SamplerUnderTest,
    count: int,
    *,
    seed: int,
    truth: Mapping[str, float] | None = None,
) -> Iterator[tuple[dict[str, Any], Draws]]:
    """Yield ``(theta, draws)`` for ``count`` simulated data sets.

    Replication ``i`` uses child ``i`` of ``SeedSequence(seed)``, itself split into the
    prior, data and fit streams: the result does not depend on how many replications run
    or in which order. With ``truth`` every data set is simulated from it; otherwise from
    a fresh prior draw.
    """
    if truth is None and sut.draw_prior is None:
        raise ValueError(f"{sut.name} has no prior simulator: give a truth")
    for child in np.random.SeedSequence(seed).spawn(count):
        s_prior, s_data, s_fit = child.spawn(3)
        if truth is None:
            theta = sut.draw_prior(np.random.default_rng(s_prior))  # type: ignore[misc]
        else:
            theta = dict(truth)
        data = sut.simulate(theta, np.random.default_rng(s_data))
        yield theta, sut.fit(data, int(s_fit.generate_state(1)[0]))


def hdi(x: np.ndarray, prob: float = 0.95) -> tuple[float, float]:
    """Highest-density interval of draws, by the algorithm ArviZ's ``hdi`` uses.

    The shortest interval between order statistics ``i`` and ``i + floor(prob n)``; the
    same numbers as :meth:`loadbayes.posterior.Posterior.summary` reports.
    """
    s = np.sort(np.asarray(x, dtype=float).reshape(-1))
    inc = int(np.floor(prob * s.size))
    width = s[inc:] - s[: s.size - inc]
    i = int(np.argmin(width))
    return float(s[i]), float(s[i + inc])


def _lag1(x: np.ndarray) -> float:
    d = x - x.mean()
    den = float(d @ d)
    return float(d[1:] @ d[:-1] / den) if den > 0 else 0.0


@dataclass
class SBCResult:
    """Ranks of the truth among the posterior draws, and their uniformity tests.

    Attributes
    ----------
    name : str
        Sampler under test.
    parameters : tuple of str
        Parameters ranked.
    kept : int
        Posterior draws per replication (ranks run from 0 to ``kept``).
    bins : int
        Bins of the rank histogram (``kept + 1`` is a multiple of ``bins``).
    ranks : ndarray, shape (replications, parameters)
        Rank of the truth: how many draws fall below it.
    lag1 : ndarray, shape (replications, parameters)
        Lag-1 autocorrelation of the kept draws (near 0: thinning was enough).
    covered : ndarray of bool, shape (replications, parameters)
        Whether the 95% HDI of the draws holds the truth.
    seconds : float
        Wall time.
    """

    name: str
    parameters: tuple[str, ...]
    kept: int
    bins: int
    ranks: np.ndarray
    lag1: np.ndarray
    covered: np.ndarray
    seconds: float
    notes: str = ""

    @property
    def replications(self) -> int:
        """Number of replications."""
        return self.ranks.shape[0]

    def counts(self) -> np.ndarray:
        """Rank histogram, shape (parameters, bins)."""
        width = (self.kept + 1) // self.bins
        return np.stack([np.bincount(r // width, minlength=self.bins) for r in self.ranks.T])

    def pvalues(self) -> dict[str, float]:
        """Chi-square p-value of uniform ranks, per parameter."""
        return {
            p: float(stats.chisquare(c).pvalue)
            for p, c in zip(self.parameters, self.counts(), strict=True)
        }

    def passes(self, alpha: float) -> bool:
        """True when every p-value exceeds ``alpha / len(parameters)`` (Bonferroni).

        ``alpha`` is then the false-alarm rate of the whole check for a correct sampler.
        """
        return min(self.pvalues().values()) > alpha / len(self.parameters)

    def to_dict(self) -> dict[str, Any]:
        """Plain summary for the validation report."""
        return {
            "name": self.name,
            "replications": self.replications,
            "kept_draws": self.kept,
            "bins": self.bins,
            "seconds": round(self.seconds, 2),
            "notes": self.notes,
            "parameters": {
                p: {
                    "chi2_pvalue": pv,
                    "counts": c.tolist(),
                    "max_lag1_autocorrelation_median": float(np.median(self.lag1[:, j])),
                    "coverage_hdi95": float(self.covered[:, j].mean()),
                }
                for j, (p, pv, c) in enumerate(
                    zip(self.parameters, self.pvalues().values(), self.counts(), strict=True)
                )
            },
        }


def run_sbc(sut: SamplerUnderTest, replications: int, *, seed: int, bins: int = 20) -> SBCResult:
    """Simulation-based calibration of one sampler.

    Parameters
    ----------
    sut : SamplerUnderTest
        The sampler, its prior and its data simulator.
    replications : int
        Simulated data sets.
    seed : int
        Root seed (see :func:`replicate`).
    bins : int
        Rank-histogram bins; ``sut.kept + 1`` must be a multiple of it.

    Returns
    -------
    SBCResult
    """
    if (sut.kept + 1) % bins:
        raise ValueError(f"kept + 1 = {sut.kept + 1} is not a multiple of bins = {bins}")
    t0 = time.perf_counter()
    npar = len(sut.parameters)
    ranks = np.empty((replications, npar), dtype=np.int64)
    lag1 = np.empty((replications, npar))
    covered = np.empty((replications, npar), dtype=bool)
    for i, (theta, draws) in enumerate(replicate(sut, replications, seed=seed)):
        for j, name in enumerate(sut.parameters):
            x = np.asarray(draws[name], dtype=float)
            if x.shape != (sut.kept,):
                raise ValueError(f"{sut.name}: fit returned {x.shape} draws of {name}")
            ranks[i, j] = np.count_nonzero(x < theta[name])
            lag1[i, j] = _lag1(x)
            lo, hi = hdi(x)
            covered[i, j] = lo <= theta[name] <= hi
    return SBCResult(
        sut.name,
        sut.parameters,
        sut.kept,
        bins,
        ranks,
        lag1,
        covered,
        time.perf_counter() - t0,
        sut.notes,
    )


@dataclass
class CoverageResult:
    """How often the credible intervals held the truth.

    Attributes
    ----------
    name : str
        Sampler under test.
    prob : float
        Nominal probability of the intervals (HDI).
    covered : dict of str to ndarray of bool
        Per parameter, one entry per data set.
    truth : dict or None
        The fixed truth, or None when it was drawn from the prior each time.
    seconds : float
        Wall time.
    """

    name: str
    prob: float
    covered: dict[str, np.ndarray]
    truth: dict[str, float] | None
    seconds: float
    notes: str = ""

    @property
    def datasets(self) -> int:
        """Number of simulated data sets."""
        return next(iter(self.covered.values())).size

    def rates(self) -> dict[str, float]:
        """Fraction of data sets whose interval held the truth, per parameter."""
        return {p: float(c.mean()) for p, c in self.covered.items()}

    def to_dict(self) -> dict[str, Any]:
        """Plain summary for the validation report."""
        se = float(np.sqrt(self.prob * (1 - self.prob) / self.datasets))
        return {
            "name": self.name,
            "datasets": self.datasets,
            "interval": f"{self.prob:.0%} HDI",
            "truth": self.truth if self.truth is not None else "drawn from the prior",
            "binomial_se": se,
            "seconds": round(self.seconds, 2),
            "notes": self.notes,
            "coverage": self.rates(),
        }


def run_coverage(
    sut: SamplerUnderTest,
    datasets: int,
    *,
    seed: int,
    truth: Mapping[str, float] | None = None,
    prob: float = 0.95,
) -> CoverageResult:
    """Coverage of the ``prob`` HDI over ``datasets`` simulated data sets.

    With ``truth`` (frequentist coverage at one point) the nominal rate holds when the
    prior is weak enough for the posterior to match the sampling distribution (true of
    the conjugate linear blocks with the default priors); with ``truth=None`` (drawn from
    the prior) it holds exactly for any prior.
    """
    t0 = time.perf_counter()
    hits: dict[str, list[bool]] = {p: [] for p in sut.parameters}
    for theta, draws in replicate(sut, datasets, seed=seed, truth=truth):
        for p in sut.parameters:
            lo, hi = hdi(draws[p], prob)
            hits[p].append(lo <= theta[p] <= hi)
    return CoverageResult(
        sut.name,
        prob,
        {p: np.asarray(h) for p, h in hits.items()},
        dict(truth) if truth is not None else None,
        time.perf_counter() - t0,
        sut.notes,
    )


# ------------------------------------------------------------------ prior simulators
def draw_block_prior(prior: BlockPrior, rng: np.random.Generator) -> tuple[np.ndarray, float]:
    """One draw ``(coef, tau)`` from a block prior (independent or conjugate)."""
    tau = float(rng.gamma(prior.shape, 1.0 / prior.rate))
    cov = np.linalg.inv(prior.precision * (tau if prior.conjugate else 1.0))
    return rng.multivariate_normal(prior.mean, cov), tau
