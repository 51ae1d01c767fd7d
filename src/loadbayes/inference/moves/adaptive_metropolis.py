"""Adaptive Metropolis for a block of Metropolis-within-Gibbs.

Knows no physics: a block is a vector ``x`` and a log-density callable.

:class:`AdaptiveMetropolis` is the random-walk proposal of Haario, Saksman and
Tamminen (2001), "An adaptive Metropolis algorithm", Bernoulli 7(2): a Gaussian step
whose covariance is the running covariance of the chain's own draws, scaled by
``2.38^2 / d`` (Roberts, Gelman and Gilks 1997), with the overall scale tuned towards an
acceptance rate of 0.234 by a Robbins-Monro recursion. Both are learned **only during
burn-in** and then frozen, so the kept draws come from a fixed, valid Metropolis kernel
(no diminishing-adaptation argument needed).

**Jumps** (``independence > 0``): after burn-in, that share of the steps proposes
from a fixed multivariate Student-t instead, centred on the mean of the draws the move
learned from, with their covariance times :data:`JUMP_INFLATION` and
:data:`JUMP_DOF` degrees of freedom: an independence Metropolis-Hastings step
(accepted by ``p(y) q(x) / (p(x) q(y))``). Both kernels leave the density invariant,
so their fixed mixture does too; the random walk explores locally, and a jump can
leave (or enter) a narrow stretch of the density that the walk, its scale set by the
bulk, crosses only slowly. The t is fitted in the coordinates the walk moves in (a
subclass's), where the density is the block's up to a constant factor. With fewer
than :data:`JUMP_MIN_DRAWS` burn-in draws to fit it from there are no jumps.
:meth:`AdaptiveMetropolis.fit_jumps` fits it to other draws instead (a sampler's
chains pooled: the composite sampler does), and with ``components > 1`` fits a mixture
of t's over regions of those draws (:class:`~loadbayes.inference.moves.mixture.
StudentTMixture`, each region's covariance times :data:`JUMP_REGION_INFLATION`, weights
``n_k^``:data:`JUMP_POWER`, and the one t with weight :data:`JUMP_BROAD`), which follows
a skewed posterior where one t cannot.

The contract (``step``, the burn-in window, the counters) is
:class:`~loadbayes.inference.moves.base.BlockMove`'s; chains run through
:func:`loadbayes.core.parallel.run_chains`.
"""

from __future__ import annotations

import math

import numpy as np

from loadbayes.inference.moves.base import BlockMove, BlockState, LogDensity
from loadbayes.inference.moves.mixture import StudentTMixture

__all__ = [
    "JUMP_BROAD",
    "JUMP_DOF",
    "JUMP_INFLATION",
    "JUMP_MIN_DRAWS",
    "JUMP_POWER",
    "JUMP_REGION_INFLATION",
    "JUMP_WIDE_DOF",
    "JUMP_WIDE_INFLATION",
    "AdaptiveMetropolis",
    "StudentTProposal",
]

#: Degrees of freedom of the jumps' multivariate t (tails heavier than the bulk's).
JUMP_DOF = 10.0
#: The jumps' scale matrix is the learned covariance times this (wider than the bulk).
JUMP_INFLATION = 2.0
#: Burn-in draws the jumps' t is fitted from, at least (else no jumps).
JUMP_MIN_DRAWS = 500
#: A mixture's regions: each one's covariance times this (a region is narrower than the
#: whole, so less inflation than :data:`JUMP_INFLATION` covers it).
JUMP_REGION_INFLATION = 1.5
#: ... and region ``k`` weighs ``n_k ** JUMP_POWER``: the sparsely drawn regions (a tail)
#: are proposed more often than their share of the burn-in.
JUMP_POWER = 0.5
#: ... and one more t over all the draws (the one-t jumps' own) weighs this much: where
#: the regions' t's are thin (a stretch the burn-in barely drew) an independence step
#: would accept its way in and seldom out; issue 21's 120/s event, seed 0: min ESS 45
#: without it, 1,057 with it (docs/composite.md, "Jumps from regions").
JUMP_BROAD = 0.15
#: A wide t's (``fit_jumps(wide=...)``) covariance is the draws' times this (three times
#: their sd) ...
JUMP_WIDE_INFLATION = 9.0
#: ... and its degrees of freedom (tails far heavier than the regions'): it reaches a
#: tail that no chain's burn-in did (docs/composite.md, "A tail the burn-in missed").
JUMP_WIDE_DOF = 3.0


class StudentTProposal:
    """A multivariate Student-t: draws and the log density up to a constant.

    Parameters
    ----------
    mean : ndarray, shape (d,)
    scale : ndarray, shape (d, d)
        The scale matrix (positive definite).
    dof : float
    """

    def __init__(self, mean: np.ndarray, scale: np.ndarray, dof: float) -> None:
        self.mean = np.asarray(mean, dtype=float).copy()
        self._chol = np.linalg.cholesky((scale + scale.T) / 2)
        self.dof = float(dof)
        self.d = self.mean.size

    def draw(self, rng: np.random.Generator) -> np.ndarray:
        """One draw."""
        z = rng.standard_normal(self.d)
        return self.mean + math.sqrt(self.dof / rng.chisquare(self.dof)) * (self._chol @ z)

    def log_density(self, x: np.ndarray) -> float:
        """``log q(x)`` up to a constant."""
        z = np.linalg.solve(self._chol, np.asarray(x, dtype=float) - self.mean)
        return -0.5 * (self.dof + self.d) * math.log1p(float(z @ z) / self.dof)


class AdaptiveMetropolis(BlockMove):
    """Random-walk Metropolis on a block, adapting its covariance during burn-in.

    Parameters
    ----------
    cov0 : ndarray, shape (d, d)
        Initial proposal covariance (before scaling), e.g. a Laplace approximation.
    adapt_until : int
        Iterations during which the covariance and scale adapt (the burn-in).
    adapt_start : int
        Iterations with ``cov0`` before the empirical covariance takes over.
    target : float
        Acceptance rate the scale is tuned towards.
    independence : float
        Share of the steps after burn-in that are jumps (the module's notes); 0: none.

    Attributes
    ----------
    jumps, jumps_accepted : int
        Jump steps proposed and accepted (among ``steps`` and ``accepted``).
    """

    def __init__(
        self,
        cov0: np.ndarray,
        *,
        adapt_until: int,
        adapt_start: int = 100,
        target: float = 0.234,
        independence: float = 0.0,
    ) -> None:
        super().__init__(cov0, adapt_until=adapt_until, adapt_start=adapt_start)
        self.log_scale = math.log(2.38**2 / self.d)
        self.target = float(target)
        if not 0.0 <= independence < 1.0:
            raise ValueError(f"independence must be in [0, 1), got {independence}")
        self.independence = float(independence)
        self._jump: StudentTProposal | None = None
        self._jump_ready = False
        self.jumps = 0
        self.jumps_accepted = 0
        self._q_current: tuple[np.ndarray, float] | None = None  # (x, log q(w(x)))

    def step(
        self, state: BlockState, logp: LogDensity, rng: np.random.Generator, iteration: int
    ) -> tuple[BlockState, bool]:
        """One Metropolis step (or a jump); adapts when ``iteration < adapt_until``.

        The contract is :meth:`BlockMove.step`'s.
        """
        if self.independence and iteration >= self.adapt_until:
            jump = self._jump_proposal()
            if jump is not None and rng.random() < self.independence:
                return self._jump_step(jump, state, logp, rng)
        w = self._walk(state.x)
        z = rng.standard_normal(self.d)
        w_prop = w + math.exp(0.5 * self.log_scale) * (self._root @ z)
        prop = self._block(w_prop)
        lp_prop, aux_prop = logp(prop)
        # rng.random() is rng.uniform()'s number (0 + 1 * d) at a third of its call's cost.
        log_u = math.log(rng.random())
        logp_x = state.logp
        alpha = min(1.0, math.exp(min(0.0, lp_prop - logp_x))) if math.isfinite(lp_prop) else 0.0
        accept = log_u < lp_prop - logp_x if math.isfinite(lp_prop) else False
        self.steps += 1
        self.evaluations += 1
        if accept:
            state, w = BlockState(prop, lp_prop, aux_prop), w_prop
            self.accepted += 1
        if iteration < self.adapt_until:
            self._adapt(w, alpha, iteration)
        return state, bool(accept)

    def fit_jumps(
        self,
        draws: np.ndarray,
        components: int = 1,
        wide: float = 0.0,
        wide_axis: bool = False,
        anchors: tuple[np.ndarray, np.ndarray] | None = None,
        anchor: float = 0.0,
    ) -> None:
        """Fit the jumps' t to ``draws`` of the block (e.g. several chains' burn-in).

        Call after burn-in (the walk's coordinates are fixed then); without it the t is
        fitted to the draws this move learned from, at the first step after burn-in.
        Fewer than :data:`JUMP_MIN_DRAWS` draws: no jumps. ``components > 1``: a mixture
        of t's over that many k-means regions of the draws instead of one t, and with
        ``wide > 0`` one more t of that weight, :data:`JUMP_WIDE_INFLATION` times wider
        with :data:`JUMP_WIDE_DOF` degrees of freedom (a tail no burn-in reached; with
        ``wide_axis`` wider along the draws' principal direction alone), and with
        ``anchor > 0`` t's of that total weight at ``anchors`` (centres and covariances in
        the block's coordinates, carried into the walk's by its Jacobian there).
        """
        w = self._walk_rows(np.asarray(draws, dtype=float))
        placed = None
        if anchor > 0 and anchors is not None and len(anchors[0]):
            placed = self._walked(*anchors)
        self._jump_ready = True
        self._jump = None
        self._q_current = None
        if len(w) >= JUMP_MIN_DRAWS and components > 1:
            self._jump = StudentTMixture(
                w, components=components, inflation=JUMP_REGION_INFLATION, dof=JUMP_DOF,
                power=JUMP_POWER, broad=JUMP_BROAD, broad_inflation=JUMP_INFLATION,
                wide=wide, wide_inflation=JUMP_WIDE_INFLATION, wide_dof=JUMP_WIDE_DOF,
                wide_axis=wide_axis, anchors=placed, anchor=anchor if placed else 0.0,
            )  # fmt: skip
        elif len(w) >= JUMP_MIN_DRAWS:
            cov = np.cov(w, rowvar=False) + 1e-10 * np.eye(self.d)
            self._jump = StudentTProposal(w.mean(axis=0), JUMP_INFLATION * cov, JUMP_DOF)

    def _walked(self, centres, covs) -> tuple[np.ndarray, np.ndarray]:
        # Points and covariances of the block in the walk's coordinates: the centre
        # mapped, the covariance through the map's Jacobian there (central differences).
        out_c, out_v = [], []
        for c, cov in zip(np.asarray(centres, dtype=float), np.asarray(covs, dtype=float),
                          strict=True):  # fmt: skip
            jac = np.empty((self.d, self.d))
            for i in range(self.d):
                h = 1e-6 * max(1.0, abs(c[i]))
                up, um = c.copy(), c.copy()
                up[i] += h
                um[i] -= h
                jac[:, i] = (self._walk(up) - self._walk(um)) / (2 * h)
            out_c.append(self._walk(c))
            out_v.append(jac @ cov @ jac.T)
        return np.array(out_c), np.array(out_v)

    def _jump_proposal(self) -> StudentTProposal | None:
        # Fitted once, at the first step after burn-in, from what the move learned.
        if not self._jump_ready:
            self._jump_ready = True
            if self._running.count >= JUMP_MIN_DRAWS:
                self._jump = StudentTProposal(
                    self._running.mean, JUMP_INFLATION * self.cov, JUMP_DOF
                )
        return self._jump

    def _jump_step(self, jump, state, logp, rng):
        # Independence Metropolis-Hastings in the walk's coordinates (unit Jacobian to
        # the block up to a constant, which cancels in the ratio).
        w_prop = jump.draw(rng)
        prop = self._block(w_prop)
        lp_prop, aux_prop = logp(prop)
        self.steps += 1
        self.evaluations += 1
        self.jumps += 1
        log_u = math.log(rng.random())
        if not math.isfinite(lp_prop):
            return state, False
        q_prop = jump.log_density(w_prop)
        log_ratio = lp_prop - state.logp + self._q_of(jump, state.x) - q_prop
        if log_u < log_ratio:
            self.accepted += 1
            self.jumps_accepted += 1
            self._q_current = (np.array(prop, dtype=float), q_prop)
            return BlockState(prop, lp_prop, aux_prop), True
        return state, False

    def _q_of(self, jump, x: np.ndarray) -> float:
        # log q of the current state, kept from the jump that reached it or the last one
        # from it (the same number recomputed: a mixture's density costs K solves). Equal
        # bytes: a block that compares equal with other bytes (0.0 and -0.0) maps to the
        # same q anyway.
        cur = self._q_current
        if cur is not None and cur[0].tobytes() == np.asarray(x, dtype=float).tobytes():
            return cur[1]
        q = jump.log_density(self._walk(x))
        self._q_current = (np.array(x, dtype=float), q)
        return q

    @property
    def jump_acceptance(self) -> float | None:
        """Share of the jumps that moved (None before any jump)."""
        return self.jumps_accepted / self.jumps if self.jumps else None

    # The coordinates the walk moves in, and back: the block itself here; a subclass may
    # walk in others whose map to the block has a unit Jacobian (so the Metropolis
    # ratio stays the density ratio), and the covariance is then learned in them.
    def _walk(self, x: np.ndarray) -> np.ndarray:
        return x

    def _walk_rows(self, xs: np.ndarray) -> np.ndarray:
        # The walk's coordinates of many blocks (n, d) at once: the jumps' fit maps every
        # chain's kept draws, 4 x 70,000 a round of a long bounded run (1 s one at a time).
        return np.array(xs, dtype=float).reshape(len(xs), self.d)

    def _block(self, w: np.ndarray) -> np.ndarray:
        return w

    def _adapt(self, w: np.ndarray, alpha: float, iteration: int) -> None:
        # Robbins-Monro on the log scale, step size decaying as 1/sqrt(t).
        self.log_scale += (alpha - self.target) / math.sqrt(iteration + 1.0)
        self._learn(w)
