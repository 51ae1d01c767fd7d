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

A **wide** t (``wide > 0``) is one more component over all the draws with a scale
``wide_inflation`` times their covariance and ``wide_dof`` degrees of freedom (heavier
tails than the rest): it proposes a tail that no chain's burn-in reached, which the
regions and the broad t (both fitted to where the burn-in was) propose too seldom for
R-hat to notice that every chain missed it (docs/composite.md, "A tail the burn-in
missed").

**Anchored** t's (``anchors``, weight ``anchor``) are placed from outside the draws: a
caller's points and covariances (the composite's: points along the posterior's ridge in
``log T'`` found by least squares, each with its Laplace covariance, docs/composite.md,
"Jumps placed from the data"). They propose a stretch the burn-in may not have drawn,
where the data say the posterior runs; as more fixed components of the independence
proposal they keep the kernel exact.

Its :meth:`~StudentTMixture.log_density` is normalised across components (each t's
``log det`` enters, and with a wide t of other degrees of freedom each t's gamma
functions), as the Hastings ratio of a mixture needs; the constant common to all is
left out.
"""

from __future__ import annotations

import math
import warnings

import numba
import numpy as np
from scipy.cluster.vq import kmeans2
from scipy.special import gammaln

from loadbayes.core.normal import log_add_exp

__all__ = ["StudentTMixture"]


#: How far the weights may sum from 1 (NumPy's ``choice``'s own check).
_ATOL = float(np.sqrt(np.finfo(np.float64).eps))


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
    wide : float
        The weight of a wide t over all the draws (the module's notes; 0: none).
    wide_inflation, wide_dof : float
        Its covariance's factor and its degrees of freedom.
    wide_axis : bool
        Widen it along the draws' principal direction alone (the covariance plus
        ``(wide_inflation - 1) lambda_1 v_1 v_1^T``), not in every direction.
    anchors : (ndarray (m, d), ndarray (m, d, d)), optional
        Centres and covariances of ``m`` more t's (``dof`` degrees of freedom), placed
        by the caller, not fitted to ``draws``.
    anchor : float
        Their total weight, shared equally (0: none).
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
        wide: float = 0.0,
        wide_inflation: float = 9.0,
        wide_dof: float = 3.0,
        wide_axis: bool = False,
        anchors: tuple[np.ndarray, np.ndarray] | None = None,
        anchor: float = 0.0,
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
        dofs = [self.dof] * len(w)
        if wide > 0:
            cov = np.cov(draws, rowvar=False).reshape(d, d)
            if wide_axis:  # wider along the draws' principal direction alone
                lam, vec = np.linalg.eigh(cov)
                cov = cov + (wide_inflation - 1) * lam[-1] * np.outer(vec[:, -1], vec[:, -1])
            else:
                cov = wide_inflation * cov
            cov = cov + 1e-10 * np.eye(d)
            means.append(draws.mean(axis=0))
            roots.append(np.linalg.cholesky((cov + cov.T) / 2))
            self.counts = np.append(self.counts, n)
            w = np.append((1 - wide) * w, wide)
            dofs.append(float(wide_dof))
        if anchor > 0 and anchors is not None and len(anchors[0]):
            centres, covs = np.asarray(anchors[0], dtype=float), np.asarray(anchors[1], dtype=float)
            m = len(centres)
            for c, cov in zip(centres, covs, strict=True):
                cov = cov.reshape(d, d) + 1e-10 * np.eye(d)
                means.append(c)
                roots.append(np.linalg.cholesky((cov + cov.T) / 2))
            self.counts = np.append(self.counts, np.zeros(m, dtype=int))
            w = np.append((1 - anchor) * w, np.full(m, anchor / m))
            dofs += [self.dof] * m
        self.weights = w
        self._dofs = np.array(dofs)
        self.means = np.array(means)
        self._roots = np.array(roots)
        self._inverse_roots = np.array([np.linalg.inv(r) for r in roots])
        log_det = np.array([np.sum(np.log(np.diag(r))) for r in roots])
        self._const = np.log(self.weights) - log_det
        if wide > 0:  # the t's normalising constants, relative to the first's
            nu = self._dofs
            c = gammaln((nu + d) / 2) - gammaln(nu / 2) - 0.5 * d * np.log(nu)
            self._const = self._const + (c - c[0])

    @property
    def components(self) -> int:
        """How many t's the mixture holds."""
        return len(self.weights)

    def draw(self, rng: np.random.Generator) -> np.ndarray:
        """One draw."""
        k = self._component(rng) if self.components > 1 else 0
        z = rng.standard_normal(self.d)
        nu = float(self._dofs[k])
        return self.means[k] + math.sqrt(nu / rng.chisquare(nu)) * (self._roots[k] @ z)

    def _component(self, rng: np.random.Generator) -> int:
        # rng.choice(components, p=weights), its cumulative weights made once: NumPy's
        # choice normalises p.cumsum() by its last entry and searches one rng.random().
        return int(self._component_cdf().searchsorted(rng.random(), side="right"))

    def _component_cdf(self) -> np.ndarray:
        cdf = self.__dict__.get("_cdf")
        if cdf is None or cdf[0] is not self.weights:
            p = np.ascontiguousarray(self.weights, dtype=float)
            if p.ndim != 1 or not np.all(p >= 0) or not abs(p.sum() - 1.0) <= _ATOL:
                raise ValueError(f"the mixture's weights are not probabilities: {p}")
            c = p.cumsum()
            c /= c[-1]
            cdf = self._cdf = (self.weights, c)
        return cdf[1]

    def log_density(self, x: np.ndarray) -> float:
        """``log q(x)`` up to a constant common to every ``x``."""
        return float(mixture_log_density(np.asarray(x, dtype=float), self.means,
                                         self._inverse_roots, self._const, self._dofs))  # fmt: skip

    def arrays(self) -> tuple[np.ndarray, ...]:
        """What a compiled loop draws and weighs with.

        ``(cdf, means, roots, inverse roots, constants, dofs)``, ``cdf`` the cumulative
        weights :meth:`draw` searches.
        """
        return (self._component_cdf(), self.means, self._roots, self._inverse_roots,
                self._const, self._dofs)  # fmt: skip


@numba.njit(cache=True, nogil=True)
def mixture_log_density(x, means, inverse_roots, const, dofs):  # pragma: no cover
    """:meth:`StudentTMixture.log_density` on its arrays, compiled.

    The compiled chain loop's and the Python path's one function, so both weigh a jump
    alike (NumPy's einsum summed in another order).
    """
    k_n, d = means.shape
    out = 0.0
    for k in range(k_n):
        q = 0.0
        for i in range(d):
            zi = 0.0
            for j in range(d):
                zi += inverse_roots[k, i, j] * (x[j] - means[k, j])
            q += zi * zi
        nu = dofs[k]
        v = const[k] - 0.5 * (nu + d) * math.log1p(q / nu)
        out = v if k == 0 else log_add_exp(out, v)
    return out
