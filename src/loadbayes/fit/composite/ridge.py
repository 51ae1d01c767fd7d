"""Points along the composite posterior's ridge in ``log T'``, for the jumps to propose.

The zip+motor posterior can run out along a narrow, bent ridge in ``log T'`` (the other
scale-free coordinates move with it: on issue 35's 10 s event the draws with T' < 0.2 s
have ``X - X'`` a third of the bulk's). A stretch of that ridge that no chain's burn-in
reached is proposed by no region of the jumps' mixture, and all four chains can miss it
together (docs/composite.md, "A tail the burn-in missed"). The ridge is not a second
least-squares optimum (the NLS from starts spanning T' ends at one point): it is found
by the profile instead. :func:`ridge_points` holds ``log T'`` at steps of
:data:`RIDGE_STEP` Laplace sds from the NLS optimum, each way, minimises the same
penalised least squares over the other coordinates (from the previous point: a
continuation), and stops where that cost has risen by :data:`RIDGE_DROP` or after
:data:`RIDGE_POINTS` points. Each point comes with the Gauss-Newton (Laplace) covariance
there; the sampler gives the jumps' mixture a t at each (docs/composite.md, "Jumps placed
from the data"). Each point's fit stops after :data:`RIDGE_NFEV` evaluations, converged
or not: a point only places a proposal's t, never the target, and on a flat profile the
fits ran to SciPy's cap (600 each, 6 CPU s for the ten points of one ANDES Motor5 event,
against 6-57 evaluations a point elsewhere). :func:`cached_ridge_points` computes them
once per problem and start (the cost probe and the run sample the same problem).
"""

from __future__ import annotations

import numpy as np
from scipy import optimize

from loadbayes.fit.composite.nls import NLSResult, _gauss_newton_cov, _project, penalty
from loadbayes.fit.composite.problem import CompositeProblem
from loadbayes.models.composite import SCALE_FREE_NAMES

__all__ = ["RIDGE_DROP", "RIDGE_NFEV", "RIDGE_POINTS", "RIDGE_STEP", "cached_ridge_points",
           "ridge_points"]  # fmt: skip

#: Spacing of the points, in Laplace sds of ``log T'`` at the optimum.
RIDGE_STEP = 0.5
#: At most this many points each way.
RIDGE_POINTS = 5
#: ... and none where the penalised cost (half the sum of squares, a negative log
#: density) has risen by more than this above the optimum's.
RIDGE_DROP = 8.0
#: Evaluations of one point's fit at most (``least_squares``' ``max_nfev``).
RIDGE_NFEV = 100

_TP = SCALE_FREE_NAMES.index("log_t_prime")


def ridge_points(problem: CompositeProblem, start: NLSResult) -> tuple[np.ndarray, np.ndarray]:
    """Profile points along ``log T'`` and their Laplace covariances.

    Returns
    -------
    (points (m, dim), covariances (m, dim, dim))
        In the sampler's coordinates ``u``; ``m`` may be 0.
    """
    d = problem.dim
    mean_u, cov_u, white, (lo, hi), scale = penalty(problem)
    prec_u = np.linalg.inv(cov_u)
    w = 1.0 / start.sigma
    free = np.array([i for i in range(d) if i != _TP])

    def residuals(u):
        out = _project(problem, u, w)
        return None if out is None else np.concatenate([out[0], white @ (u - mean_u)])

    r0 = residuals(start.u)
    if r0 is None:
        return np.empty((0, d)), np.empty((0, d, d))
    cost0 = 0.5 * float(r0 @ r0)
    sd = float(np.sqrt(start.cov[_TP, _TP]))
    points, covs = [], []
    for way in (-1.0, 1.0):
        x = start.u.copy()
        for k in range(1, RIDGE_POINTS + 1):
            level = start.u[_TP] + way * k * RIDGE_STEP * sd
            if not lo[_TP] < level < hi[_TP]:
                break

            def fun(v, x=x, level=level, n=r0.size):
                u = x.copy()
                u[free], u[_TP] = v, level
                r = residuals(u)
                return np.full(n, 1e3) if r is None else r

            v0 = np.clip(x[free], lo[free] + 1e-9, hi[free] - 1e-9)
            sol = optimize.least_squares(fun, v0, bounds=(lo[free], hi[free]),
                                         x_scale=scale[free], max_nfev=RIDGE_NFEV)  # fmt: skip
            if not np.isfinite(sol.cost) or sol.cost - cost0 > RIDGE_DROP:
                break
            x = x.copy()
            x[free], x[_TP] = sol.x, level
            out = _project(problem, x, w)
            if out is None:
                break
            points.append(x)
            covs.append(_gauss_newton_cov(problem, x, out[1], w, prec_u)[:d, :d])
    if not points:
        return np.empty((0, d)), np.empty((0, d, d))
    return np.array(points), np.array(covs)


def cached_ridge_points(problem: CompositeProblem, start: NLSResult):
    """:func:`ridge_points`, computed once per ``problem`` and start point."""
    key = np.asarray(start.u, dtype=float).tobytes()
    cached = getattr(problem, "_ridge_cache", None)
    if cached is None or cached[0] != key:
        cached = (key, ridge_points(problem, start))
        problem._ridge_cache = cached
    return cached[1]
