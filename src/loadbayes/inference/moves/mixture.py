"""A mixture of multivariate t's fitted to draws: the jumps' proposal on a skewed posterior.

Knows no physics: a block is a vector; the draws are what the mixture is fitted to.

An independence Metropolis-Hastings step accepts in proportion to how well its proposal
``q`` follows the density ``p``. One t with the draws' covariance follows an elliptical
posterior well and a skewed one badly: on the real record's first fault the posterior of
``log T'`` has a bulk 0.15 wide and a shelf and tail 2.5 long, the covariance of all the
draws spreads the t over a volume the posterior barely fills, and 2.3% of its jumps were
accepted. :class:`StudentTMixture` cuts the draws into regions by k-means
(:func:`scipy.cluster.vq.kmeans2`, standardised coordinates, a fixed seed), fits one t to
each region (its mean, its covariance times ``inflation``), and weighs region ``k`` by
``n_k^power`` (``power < 1`` proposes the sparsely drawn regions, a tail, more often
than their share of the draws: the Hastings ratio corrects for it, and a tail the
burn-in visited rarely is where the walk is slowest). The same jumps accepted 22-31%.

Its :meth:`~StudentTMixture.log_density` is normalised across components (each t's
``log det`` enters), as the Hastings ratio of a mixture needs; the constant common to
all (the t's gamma functions, ``pi``) is left out.
"""

from __future__ import annotations

import math
import warnings

import numpy as np
from scipy.cluster.vq import kmeans2

__all__ = ["StudentTMixture"]


class StudentTMixture:
    """A mixture of multivariate t's over k-means regions of ``draws``.

    Parameters
    ----------
    draws : ndarray, shape (n, d)
        Draws the mixture is fitted to.
    components : int
        Regions asked of k-means (1: one t over all the draws); a region with fewer than
        ``5 d`` draws is left out (its draws stay covered by the others' t tails).
    inflation : float
        Each region's covariance is multiplied by this (wider than the region).
    dof : float
        Degrees of freedom of every t.
    power : float
        Region ``k`` has weight proportional to ``n_k ** power``.
    broad : float
        The weight of one more t, over all the draws (their covariance times
        ``broad_inflation``): proposes what the regions' draws missed (0: none).
    broad_inflation : float
        Its covariance's factor.
    seed : int
        The k-means seed (the mixture is a function of ``draws``).

    Attributes
    ----------
    counts, weights, means : ndarray
        Each t's region's draws, its weight, its centre.
    """

    def __init__(
        self,
        draws: np.ndarray,
        *,
        components: int,
        inflation: float,
        dof: float,
        power: float = 1.0,
        broad: float = 0.0,
        broad_inflation: float = 2.0,
        seed: int = 0,
    ) -> None:
        draws = np.asarray(draws, dtype=float)
        n, d = draws.shape
        self.d, self.dof = d, float(dof)
        labels = np.zeros(n, dtype=int)
        if components > 1:
            sd = draws.std(axis=0)
            z = (draws - draws.mean(axis=0)) / np.where(sd > 0, sd, 1.0)
            with warnings.catch_warnings():  # an empty region is dropped below
                warnings.simplefilter("ignore", UserWarning)
                _, labels = kmeans2(z, int(components), seed=seed, minit="++")
        means, roots, counts = [], [], []
        for k in range(int(labels.max()) + 1):
            part = draws[labels == k]
            if len(part) < max(5 * d, 2) and components > 1:
                continue
            cov = inflation * np.cov(part, rowvar=False).reshape(d, d) + 1e-10 * np.eye(d)
            means.append(part.mean(axis=0))
            roots.append(np.linalg.cholesky((cov + cov.T) / 2))
            counts.append(len(part))
        self.counts = np.asarray(counts, dtype=int)
        w = self.counts.astype(float) ** power
        w = w / w.sum()
        if broad > 0 and components > 1:
            # A defensive component (Hesterberg 1995): one t over all the draws, so that a
            # region the draws missed is still proposed now and then.
            cov = broad_inflation * np.cov(draws, rowvar=False) + 1e-10 * np.eye(d)
            means.append(draws.mean(axis=0))
            roots.append(np.linalg.cholesky((cov + cov.T) / 2))
            self.counts = np.append(self.counts, n)
            w = np.append((1 - broad) * w, broad)
        self.weights = w
        self.means = np.array(means)
        self._roots = np.array(roots)
        self._inverse_roots = np.array([np.linalg.inv(r) for r in roots])
        log_det = np.array([np.sum(np.log(np.diag(r))) for r in roots])
        self._const = np.log(self.weights) - log_det

    @property
    def components(self) -> int:
        """How many t's the mixture holds."""
        return len(self.weights)

    def draw(self, rng: np.random.Generator) -> np.ndarray:
        """One draw."""
        k = int(rng.choice(self.components, p=self.weights)) if self.components > 1 else 0
        z = rng.standard_normal(self.d)
        return self.means[k] + math.sqrt(self.dof / rng.chisquare(self.dof)) * (self._roots[k] @ z)

    def log_density(self, x: np.ndarray) -> float:
        """``log q(x)`` up to a constant common to every ``x``."""
        z = np.einsum("kij,kj->ki", self._inverse_roots, np.asarray(x, dtype=float) - self.means)
        q = np.einsum("ki,ki->k", z, z)
        v = self._const - 0.5 * (self.dof + self.d) * np.log1p(q / self.dof)
        return float(np.logaddexp.reduce(v))
