"""The sampler's own steps for a model of parts' shares: many, each without a motor solve.

Given the other coordinates (motors, feeder, thresholds), every part's response is fixed
(the load bus comes from the recorded current) and each channel's design is linear in
the weights ``w = (f_1, ..., f_K, f_s a1, f_s a2, f_s a3)``: ``Z_g = B_g W(w)``
(``models/parts_kernel.py``, "The shares' basis"). So each iteration, after the joint
block move, :class:`ShareMoves` solves the parts once (``PartsModel.event_basis``: the
basis sums ``B'B, B'y, y'y`` per event and channel, and P's and Q's AR(1) stacks of
them) and then takes :attr:`~loadbayes.models.parts_model.PartsModel.share_steps`
rounds of Metropolis steps on ``w`` alone, each costing a few 4 x 4 factorisations
(``inference/condlinear.log_marginal_arrays``, the function the problem's density
calls) instead of a solve of every motor. Each round has two steps:

- a **transfer**: a pair of weights ``(i, j)`` drawn uniformly, ``w_i -= d``, ``w_j +=
  d`` with ``d`` normal (one scale per pair). This is the ridge's own direction: over a
  shallow sag motor D above its break voltage, the electronics above ``Vd1`` and the
  static constant-P weight draw one column, and motors A and B trade; a transfer moves
  mass along it and nothing else;
- a **joint random walk** on ``w``'s first ``K + 2`` entries (the last one takes up
  the sum), its covariance the weights' own, learned over the burn-in (Haario et al.
  2001), scaled toward 25 % acceptance.

Both proposals are symmetric in ``w`` (a state-free pair and a centred normal step) and
refused off the simplex, so each is accepted by the ratio of the target in ``w``. The
sampled coordinates are the additive log-ratios of ``f`` and of ``a``, whose uniform
Dirichlet priors (``part_priors.PartsPrior.log_u``: density ``prod f prod a`` in those
coordinates) make ``(f, a)`` uniform on their simplexes; ``w`` is ``(f, a)`` with the
static share spread over three weights, the map's Jacobian ``f_s^2``. The target in ``w``
is therefore the collapsed likelihood times ``f_s^-2`` (``tests/unit/test_shares.py``
checks it against ``log_u`` and a numerical Jacobian). The step scales adapt during
burn-in only, then stay (Metropolis steps each leave the posterior invariant; a run
continued gives the draws of one run). Metropolis rather than slice steps: a step costs
one evaluation, a slice step several, and the learned scale is what follows the ridge.
The static Q's split is not a share (its three terms are linear coefficients, integrated
out), so it is not moved here.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from loadbayes.core.kept import Kept
from loadbayes.inference.ar1 import whitened
from loadbayes.inference.condlinear import GroupSums, log_marginal_arrays
from loadbayes.models.parts_state import share_weights

__all__ = ["ShareMoves"]

#: Target acceptance of the transfers and of the joint random walk.
TRANSFER_ACCEPT = 0.3
JOINT_ACCEPT = 0.25
#: Robbins-Monro gain of the scales' adaptation (log scale per step).
GAIN = 0.05
#: Starting sd of a transfer and of each weight in the joint walk.
START_SD = 0.05
#: Weights in the static part (its Z, I, P split), last in ``w``.
N_STATIC = 3


@numba.njit(cache=True, nogil=True)
def _project_into(bb, by, w, zz, zy):  # pragma: no cover - compiled
    # W'(B'B)W and W'(B'y) for W = [[w, 0], [0, I_3]]: (G, M, M) -> (G, 4, 4).
    nw = w.size
    for g in range(bb.shape[0]):
        bw = np.zeros(bb.shape[1])
        for a in range(bb.shape[1]):
            for b in range(nw):
                bw[a] += bb[g, a, b] * w[b]
        s = 0.0
        t = 0.0
        for a in range(nw):
            s += w[a] * bw[a]
            t += w[a] * by[g, a]
        zz[g, 0, 0] = s
        zy[g, 0] = t
        for c in range(3):
            zz[g, 0, 1 + c] = bw[nw + c]
            zz[g, 1 + c, 0] = bw[nw + c]
            zy[g, 1 + c] = by[g, nw + c]
            for d in range(3):
                zz[g, 1 + c, 1 + d] = bb[g, nw + c, nw + d]


@numba.njit(cache=True, nogil=True)
def _log_target(w, bb, by, yy, nn, tau, m0, p0, positive):  # pragma: no cover - compiled
    # The collapsed log-likelihood of every event at w, times f_s^-(N_STATIC - 1).
    nw = w.size
    s = 0.0
    for a in range(nw):
        if not w[a] > 0.0:
            return -np.inf
        if a >= nw - N_STATIC:
            s += w[a]
    out = -(N_STATIC - 1) * math.log(s)
    g = bb.shape[1]
    zz = np.empty((g, 4, 4))
    zy = np.empty((g, 4))
    for e in range(bb.shape[0]):
        _project_into(bb[e], by[e], w, zz, zy)
        try:
            out += log_marginal_arrays(zz, zy, yy[e], nn[e], tau, m0, p0, positive)
        except Exception:  # A not positive definite: an infeasible proposal
            return -np.inf
    return out


@numba.njit(cache=True, nogil=True)
def _sweep(w, bb, by, yy, nn, tau, m0, p0, positive, pairs, pick, shifts, normals, logu,
           pair_sd, chol, lam, adapt, counts, s1, s2):  # pragma: no cover - compiled  # fmt: skip
    # The rounds of transfers and joint steps (the module docstring); counts: accepted,
    # tried of each kind. With adapt, the scales move toward their targets and s1, s2
    # gather the weights' sums for the joint step's covariance.
    data = (bb, by, yy, nn, tau, m0, p0, positive)
    lp = _log_target(w, *data)
    nf = w.size - 1
    for r in range(pick.size):
        k = pick[r]
        cand = w.copy()
        d = pair_sd[k] * shifts[r]
        cand[pairs[k, 0]] -= d
        cand[pairs[k, 1]] += d
        w, lp, ok = _metropolis(w, lp, cand, logu[r, 0], data, counts, 0)
        if adapt:
            pair_sd[k] *= math.exp(GAIN * ((1.0 if ok else 0.0) - TRANSFER_ACCEPT))
        step = lam[0] * (chol @ normals[r])
        cand = w.copy()
        for a in range(nf):
            cand[a] += step[a]
            cand[nf] -= step[a]
        w, lp, ok = _metropolis(w, lp, cand, logu[r, 1], data, counts, 2)
        if adapt:
            lam[0] *= math.exp(GAIN * ((1.0 if ok else 0.0) - JOINT_ACCEPT))
            for a in range(nf):
                s1[a] += w[a]
                for b in range(nf):
                    s2[a, b] += w[a] * w[b]
    return w


@numba.njit(cache=True, nogil=True)
def _metropolis(w, lp, cand, logu, data, counts, at):  # pragma: no cover - compiled
    # One Metropolis decision on a symmetric proposal; counts[at], counts[at + 1]:
    # accepted, tried.
    lc = _log_target(cand, *data)
    counts[at + 1] += 1
    if logu < lc - lp:
        counts[at] += 1
        return cand, lc, True
    return w, lp, False


class ShareMoves:
    """The share-only steps of a :class:`~.design.DesignProblem` (module docstring)."""

    def __init__(self, problem) -> None:
        model = problem.model
        self.problem, self.model = problem, model
        names = list(model.theta_names)
        self.f_index = np.array([names.index(f"lr_{p}") for p in model.parts])
        self.a_index = np.array([names.index("lr_a1"), names.index("lr_a2")])
        self.rounds = int(model.share_steps)
        nw = len(model.parts) + N_STATIC
        self.pairs = np.array([(i, j) for i in range(nw) for j in range(i + 1, nw)])
        self.pair_sd = np.full(len(self.pairs), START_SD)
        nf = nw - 1
        self.chol = START_SD * np.eye(nf)
        self.lam = np.array([1.0])
        self.s1, self.s2, self.seen = np.zeros(nf), np.zeros((nf, nf)), 0
        self.counts = np.zeros(4, dtype=np.int64)
        self.positive = -1 if problem.positive is None else int(problem.positive)
        self._last = None  # (the other coordinates, their basis): the last solve
        self._weights = Kept(64)  # weights of the last share coordinates

    @property
    def acceptance(self) -> tuple[float, float]:
        """The transfers' and the joint steps' acceptance so far."""
        c = self.counts
        return (c[0] / max(c[1], 1), c[2] / max(c[3], 1))

    def weights(self, u: np.ndarray) -> np.ndarray:
        """``w = (f_1, ..., f_K, f_s a1, f_s a2, f_s a3)`` of the sampled vector ``u``."""
        zf, za = u[self.f_index], u[self.a_index]
        key = zf.tobytes() + za.tobytes()
        got = self._weights.get(key)
        if got is None:  # kept: an iteration asks them of the state the last one left
            # (compiled: the shares the model's density reads, parts_state.shares_of)
            got = self._weights.keep(key, share_weights(zf, za))
        return got.copy()

    def with_weights(self, u: np.ndarray, w: np.ndarray) -> np.ndarray:
        """``u`` with its share coordinates (additive log-ratios) those of ``w``."""
        out = np.array(u, dtype=float)
        static = w[-N_STATIC:]
        out[self.f_index] = np.log(w[:-N_STATIC]) - math.log(float(static.sum()))
        out[self.a_index] = np.log(static[:-1]) - math.log(float(static[-1]))
        return out

    def basis(self, u: np.ndarray, ar: bool) -> list | None:
        """Each event's basis sums at ``u``'s other coordinates (None where infeasible).

        Kept from the last call while those coordinates have not moved (the block move
        refused, the thresholds' steps taken without a solve): no solve then.
        """
        rest = np.array(u, dtype=float)
        rest[self.f_index] = 0.0
        rest[self.a_index] = 0.0
        key = (rest.tobytes(), ar)
        if self._last is not None and self._last[0] == key:
            return self._last[1]
        theta = self.problem.theta(u)
        out: list | None = []
        for ev in self.problem.events:
            got = self.model.event_basis(ev, theta, ar=ar)
            if got is None:
                out = None
                break
            out.append(got)
        self._last = (key, out)
        return out

    def stacked(self, basis: list, rho) -> tuple[np.ndarray, ...]:
        """The events' basis sums as arrays ``(E, G, ...)``, P's and Q's whitened for ``rho``."""
        bb, by, yy, nn = [], [], [], []
        for got in basis:
            white, moments = (got, None) if rho is None else got
            b, y, s, n = (np.array(x, dtype=float) for x in white)
            if moments is not None:
                for g in range(2):  # P, Q; a third channel (I2) stays white
                    r = float(rho[g])
                    b[g], y[g], s[g] = (whitened(m[g], r) for m in moments[:3])
            bb.append(b)
            by.append(y)
            yy.append(s)
            nn.append(n)
        return np.array(bb), np.array(by), np.array(yy), np.array(nn)

    def sums(self, basis: list, w: np.ndarray, rho):
        """The events' sums at weights ``w``, as ``DesignProblem.collapsed`` gives them."""
        white, moments = [], []
        for got in basis:
            plain, stacks = (got, None) if rho is None else got
            white.append(_projected(plain, w))
            if stacks is not None:
                mzz, mzy, myy, segments = stacks
                m = mzz.shape[-1]
                zz, zy = np.empty((8, 4, 4)), np.empty((8, 4))
                _project_into(mzz.reshape(8, m, m), mzy.reshape(8, m), w, zz, zy)
                moments.append((zz.reshape(2, 4, 4, 4), zy.reshape(2, 4, 4), myy, segments))
        return white if rho is None else self.problem.ar_whitened(white, moments, rho)

    def log_density(self, u: np.ndarray, tau: np.ndarray, rho=None) -> float:
        """The problem's log-density at ``u`` through the basis (what the steps target)."""
        basis = self.basis(u, rho is not None)
        if basis is None:
            return -math.inf
        return self.problem.log_collapsed(self.sums(basis, self.weights(u), rho), u, tau)

    def __call__(self, u, lp, sums, logp, rng, *, tau=None, rho=None, adapting=False):
        """:attr:`rounds` rounds of a transfer and a joint step (module docstring)."""
        if tau is None or self.rounds == 0:  # Student-t weights: not this likelihood
            return u, lp, sums
        basis = self.basis(u, rho is not None)
        if basis is None:
            return u, lp, sums
        bb, by, yy, nn = self.stacked(basis, rho)
        n, nf = self.rounds, self.chol.shape[0]
        pick = rng.integers(len(self.pairs), size=n)
        shifts = rng.standard_normal(n)
        normals = rng.standard_normal((n, nf))
        logu = np.log(rng.uniform(size=(n, 2)))
        w0 = self.weights(u)
        before = self.counts[[0, 2]].sum()
        w = _sweep(w0, bb, by, yy, nn, np.asarray(tau, dtype=float), self.problem.m0,
                   self.problem.p0, self.positive, self.pairs, pick, shifts, normals, logu,
                   self.pair_sd, self.chol, self.lam, adapting, self.counts, self.s1,
                   self.s2)  # fmt: skip
        if adapting:
            self._learn(n)
        if self.counts[[0, 2]].sum() == before:
            return u, lp, sums  # nothing accepted: the state as it was, bit for bit
        u2 = self.with_weights(u, w)
        s2 = self.sums(basis, self.weights(u2), rho)
        return u2, self.problem.log_collapsed(s2, u2, tau), s2

    def _learn(self, rounds: int) -> None:
        # The joint step's covariance: the weights' own over the burn-in so far.
        self.seen += rounds
        nf = self.chol.shape[0]
        if self.seen < 20 * nf:
            return
        mean = self.s1 / self.seen
        cov = self.s2 / self.seen - np.outer(mean, mean)
        try:
            self.chol = np.linalg.cholesky(cov + 1e-10 * np.eye(nf))
        except np.linalg.LinAlgError:
            return


def _projected(sums, w: np.ndarray) -> GroupSums:
    bb, by, yy, nn = sums
    zz, zy = np.empty((bb.shape[0], 4, 4)), np.empty((bb.shape[0], 4))
    _project_into(bb, by, w, zz, zy)
    return GroupSums(zz, zy, np.array(yy, dtype=float), np.array(nn, dtype=float))
