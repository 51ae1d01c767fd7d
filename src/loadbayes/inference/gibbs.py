"""Gibbs sampling of a conjugate linear-Gaussian block ``r = Z b + e``, ``e ~ N(0, 1/tau)``.

The sampler sees the data only through :class:`~loadbayes.core.stats.RegressionStats`
(``Z'Z``, ``Z'r``, ``r'r``, ``n``), so one iteration costs O(k) (blocked) or O(k^2)
(single-site), and nothing in ``n``.

Schemes
-------
``blocked`` (default)
    ``b | tau`` drawn jointly from its multivariate normal conditional, then
    ``tau | b`` from its gamma conditional. Mixes on ridges (the ZIP a1-a2 ridge has a
    posterior correlation near -0.999 on the paper's data).
``single-site``
    The paper's Algorithm 1: one coefficient at a time from its univariate conditional,
    then ``tau``. Kept to reproduce the paper; it crawls along a ridge.
``exact``
    Independent draws from the closed-form posterior of the conjugate normal-gamma prior
    (only with ``BlockPrior(conjugate=True)``): the test oracle.

Randomness is drawn in bulk from per-chain generators (standard normals, and standard
gammas with the fixed posterior shape ``a0 + n/2``, :data:`SEGMENT` iterations at a
time), and a compiled loop turns them into the chain. The same seed gives the same draws
whatever runs the chains.

Speed
-----
``blocked`` never factorises a matrix inside the loop. The prior precision ``P0`` and
``Z'Z`` are diagonalised together once (``W' P0 W = E``, ``W' Z'Z W = D``, both
diagonal), so that the conditional precision ``s P0 + tau Z'Z`` is diagonal in the
coordinates ``u = W^-1 b`` for every ``tau``: a draw of ``u`` is ``k`` independent
univariate normals, ``b = W u``, and ``SSR(b)`` is a diagonal quadratic form in ``u``.
One iteration is ``O(k)`` with one division and one square root per coefficient, and
nothing in ``n``. (The map from standard normals to ``b`` is the symmetric-eigen factor
of the conditional covariance rather than its Cholesky factor: the same distribution.)

Chains run in threads (the kernels release the GIL), each chain drawing its randomness
from its own generator and writing its own rows of the output, so the draws do not
depend on the number of threads. ``LOADBAYES_NUM_THREADS`` caps the threads.

Why one module of this length: one idea, Gibbs on a block seen only through its
sufficient statistics. The three schemes share the settings, the starts, the bulk
random numbers and the output layout. The two compiled chain loops (each must stay one
loop, a whole chain per call, for speed) and the joint diagonalisation behind the
blocked scheme are nearly half the length.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Literal

import numpy as np
from numba import njit

from loadbayes.core.parallel import chain_generators, check_stop, num_threads, run_threads
from loadbayes.core.priors import BlockPrior
from loadbayes.core.settings import SamplerSettings
from loadbayes.core.stats import RegressionStats

__all__ = ["DEFAULTS", "SCHEMES", "BlockDraws", "sample_block", "chain_generators"]

Scheme = Literal["blocked", "single-site", "exact"]
SCHEMES: tuple[str, ...] = ("blocked", "single-site", "exact")
#: The settings of :func:`sample_block` when none are given (the paper's M and m; a fresh
#: seed from the operating system).
DEFAULTS = SamplerSettings(draws=40_000, burn=5_000, chains=4, seed=None)
_TAU_FLOOR = 1e-100  # a Gamma(1e-3, .) prior draw can underflow to 0; keep it positive


@dataclass(frozen=True)
class BlockDraws:
    """Posterior draws of one block.

    Attributes
    ----------
    coef : ndarray, shape (chain, draw, k)
        Coefficient draws.
    tau : ndarray, shape (chain, draw)
        Noise-precision draws.
    """

    coef: np.ndarray
    tau: np.ndarray


#: Iterations whose randomness is drawn at a time, per chain: normals, then gammas, for
#: each segment in turn. It defines the random stream, so changing it changes the draws.
SEGMENT = 4096


@njit(cache=True, nogil=True)
def _first_kept(start, burn, thin):  # pragma: no cover - compiled
    """First kept iteration at or after ``start``, and its index among the kept ones."""
    if start <= burn:
        return burn, 0
    kept = (start - burn + thin - 1) // thin
    return burn + kept * thin, kept


#: Chain iterations below which a second thread costs more than it saves.
_MIN_ITERS_PER_THREAD = 20_000


@njit(cache=True, nogil=True)
def _blocked_chains(
    w,
    e,
    d,
    c0,
    c1,
    u_ls,
    u0,
    ssr_min,
    rate0,
    conj,
    tau,
    u,
    z,
    g,
    m,
    start,
    burn,
    thin,
    out_b,
    out_t,
):  # pragma: no cover - compiled
    """Blocked Gibbs in the coordinates ``u = W^-1 b`` where both precisions are diagonal.

    ``b | tau``: ``u_i ~ N((s c0_i + tau c1_i) / den_i, 1 / den_i)``, independent, with
    ``den_i = s e_i + tau d_i`` and ``c0 = W' P0 m0``, ``c1 = W' Z'r``.
    ``tau | b``: ``SSR(b) = SSR_min + sum_i d_i (u_i - u_ls_i)^2`` and, for the
    conjugate prior, ``(b - m0)' P0 (b - m0) = sum_i e_i (u_i - u0_i)^2``.
    Chains are interleaved (the loop over chains is innermost) so that the processor
    overlaps their independent dependency chains. One call runs iterations
    ``start .. start + m - 1`` from the first ``m`` rows of ``z`` and ``g``.
    """
    nc = z.shape[0]
    k = z.shape[2]
    keep, kept = _first_kept(start, burn, thin)
    for j in range(m):
        it = start + j
        store = it == keep
        for c in range(nc):
            t = tau[c]
            s = t if conj else 1.0
            q = 0.0
            qp = 0.0
            for i in range(k):
                r = 1.0 / (s * e[i] + t * d[i])
                ui = (s * c0[i] + t * c1[i]) * r + z[c, j, i] * np.sqrt(r)
                u[c, i] = ui
                du = ui - u_ls[i]
                q += d[i] * du * du
                if conj:
                    dp = ui - u0[i]
                    qp += e[i] * dp * dp
            rate = rate0 + 0.5 * (ssr_min + q)
            if conj:
                rate += 0.5 * qp
            t = max(g[c, j] / rate, _TAU_FLOOR)
            tau[c] = t
            if store:
                for i in range(k):
                    acc = 0.0
                    for h in range(k):
                        acc += w[i, h] * u[c, h]
                    out_b[c, kept, i] = acc
                out_t[c, kept] = t
        if store:
            kept += 1
            keep += thin


@njit(cache=True, nogil=True)
def _single_site_chains(
    ztz,
    ztr,
    b_ls,
    ssr_min,
    m0,
    p0,
    rate0,
    conj,
    tau,
    b,
    z,
    g,
    m,
    start,
    burn,
    thin,
    out_b,
    out_t,
):  # pragma: no cover - compiled
    """The paper's Algorithm 1: each ``b_j | b_-j, tau`` in turn, then ``tau | b``."""
    nc = z.shape[0]
    k = z.shape[2]
    p0m = p0 @ m0
    inv = np.empty(k)
    sd = np.empty(k)
    keep, kept = _first_kept(start, burn, thin)
    for row in range(m):
        it = start + row
        store = it == keep
        for c in range(nc):
            t = tau[c]
            s = t if conj else 1.0
            for j in range(k):  # the diagonal depends on tau only: off the serial path
                inv[j] = 1.0 / (s * p0[j, j] + t * ztz[j, j])
                sd[j] = np.sqrt(inv[j])
            for j in range(k):
                acc = s * p0m[j] + t * ztr[j]
                for i in range(k):
                    if i != j:
                        acc -= (s * p0[j, i] + t * ztz[j, i]) * b[c, i]
                b[c, j] = acc * inv[j] + z[c, row, j] * sd[j]
            # SSR(b) = SSR_min + (b - b_ls)' Z'Z (b - b_ls): no cancellation even on
            # noise-free data.
            q = 0.0
            for i in range(k):
                di = b[c, i] - b_ls[i]
                for j in range(k):
                    q += di * ztz[i, j] * (b[c, j] - b_ls[j])
            rate = rate0 + 0.5 * (ssr_min + max(q, 0.0))
            if conj:
                q = 0.0
                for i in range(k):
                    di = b[c, i] - m0[i]
                    for j in range(k):
                        q += di * p0[i, j] * (b[c, j] - m0[j])
                rate += 0.5 * q
            t = max(g[c, row] / rate, _TAU_FLOOR)
            tau[c] = t
            if store:
                for i in range(k):
                    out_b[c, kept, i] = b[c, i]
                out_t[c, kept] = t
        if store:
            kept += 1
            keep += thin


@dataclass(frozen=True)
class _Diagonal:
    """``W`` with ``W' P0 W = diag(e)`` and ``W' Z'Z W = diag(d)``, and the data in ``u``."""

    w: np.ndarray
    w_inv: np.ndarray
    e: np.ndarray
    d: np.ndarray
    c0: np.ndarray
    c1: np.ndarray
    u_ls: np.ndarray
    u0: np.ndarray


def _diagonalise(stats: RegressionStats, prior: BlockPrior, b_ls: np.ndarray) -> _Diagonal:
    """Diagonalise ``P0`` and ``Z'Z`` together (a generalised symmetric eigenproblem).

    With ``S = P0 + Z'Z = L L'`` (after scaling to a unit diagonal, for conditioning),
    ``L^-1 Z'Z L^-T = V diag(d) V'`` and ``L^-1 P0 L^-T = V diag(1 - d) V'`` share their
    eigenvectors, so ``W = L^-T V`` makes both diagonal. ``S`` is positive definite
    exactly when the posterior is proper.
    """
    p0 = prior.precision
    ztz = np.asarray(stats.ztz, dtype=float)
    s = p0 + ztz
    diag = np.diag(s)
    if not np.all(np.isfinite(s)) or np.any(diag <= 0):
        raise ValueError(_IMPROPER)
    scale = 1.0 / np.sqrt(diag)
    outer = np.outer(scale, scale)
    try:
        chol = np.linalg.cholesky(s * outer)
    except np.linalg.LinAlgError:
        raise ValueError(_IMPROPER) from None
    chol_inv = np.linalg.inv(chol)
    m = chol_inv @ (ztz * outer) @ chol_inv.T
    _, v = np.linalg.eigh((m + m.T) / 2)
    w = (scale[:, None] * chol_inv.T) @ v
    w_inv = v.T @ (chol.T / scale[None, :])
    e = np.clip(np.einsum("ij,ik,kj->j", w, p0, w), 0.0, None)
    d = np.clip(np.einsum("ij,ik,kj->j", w, ztz, w), 0.0, None)
    if np.any(e + d <= 0):
        raise ValueError(_IMPROPER)
    return _Diagonal(
        w=np.ascontiguousarray(w),
        w_inv=w_inv,
        e=e,
        d=d,
        c0=w.T @ (p0 @ prior.mean),
        c1=w.T @ np.asarray(stats.ztr, dtype=float),
        u_ls=w_inv @ b_ls,
        u0=w_inv @ prior.mean,
    )


_IMPROPER = (
    "the posterior is improper: the prior is flat along a direction of the coefficients "
    "that the data do not identify (prior precision + Z'Z is singular); give those "
    "coefficients a proper prior"
)


def _n_kept(draws: int, burn: int, thin: int) -> int:
    return len(range(burn, draws, thin))


def _check_prior(stats: RegressionStats, prior: BlockPrior) -> None:
    if prior.k != stats.k:
        raise ValueError(f"prior has {prior.k} coefficients, the data block {stats.k}")


def _posterior_shape(stats: RegressionStats, prior: BlockPrior) -> float:
    return prior.shape + 0.5 * stats.n + (0.5 * stats.k if prior.conjugate else 0.0)


def _initial(stats, prior, gen, init, b_ls, ssr_min):
    k = stats.k
    if init == "prior":
        tau = float(gen.gamma(prior.shape, 1.0 / prior.rate))
        s = tau if prior.conjugate else 1.0
        try:
            b = gen.multivariate_normal(prior.mean, np.linalg.inv(s * prior.precision))
        except np.linalg.LinAlgError:  # flat prior: start where the data are
            b = b_ls + gen.standard_normal(k)
        return max(tau, _TAU_FLOOR), np.asarray(b, dtype=float)
    if init == "dispersed":
        dof = max(stats.n - k, 1)
        sigma2 = max(ssr_min / dof, 1e-12 * (stats.rtr / stats.n + 1e-300))
        cov = sigma2 * np.linalg.pinv(stats.ztz)
        sd = np.sqrt(np.clip(np.diag(cov), 0.0, None))
        b = b_ls + 3.0 * sd * gen.standard_normal(k)
        tau = float(np.exp(gen.standard_normal() * 1.0) / sigma2)
        return max(tau, _TAU_FLOOR), b
    raise ValueError(f"init must be 'prior' or 'dispersed', got {init!r}")


def sample_block(
    stats: RegressionStats,
    prior: BlockPrior,
    *,
    scheme: Scheme = "blocked",
    settings: SamplerSettings | None = None,
) -> BlockDraws:
    """Draw from the posterior of one linear-Gaussian block.

    Parameters
    ----------
    stats : RegressionStats
        ``Z'Z``, ``Z'r``, ``r'r`` and ``n`` of the block.
    prior : BlockPrior
        Normal prior on the coefficients, gamma prior on the precision.
    scheme : {"blocked", "single-site", "exact"}
        See the module docstring.
    settings : SamplerSettings, optional
        ``chains`` (each from its own generator spawned from ``seed``), ``draws``
        (iterations per chain *including* burn-in, the paper's M), ``burn`` (the paper's
        m), ``thin``, ``init`` (a draw from the prior, as the paper, or ``"dispersed"``:
        scattered three standard errors around the least-squares estimate, to test
        convergence), ``seed`` (Generator, int, SeedSequence or None: the source of
        randomness) and ``threads`` (at most this many threads); :data:`DEFAULTS` when
        not given.

    Returns
    -------
    BlockDraws
        ``coef`` shaped (chain, kept, k) and ``tau`` shaped (chain, kept), with
        ``kept = len(range(burn, draws, thin))``.

    Notes
    -----
    Conditionals (the paper's section "Gibbs in ZIP Model", with its slips fixed: the
    likelihood's minus sign, and the gamma update in rate form):

    * ``b | tau ~ N(L^-1 h, L^-1)``, ``L = s P0 + tau Z'Z``, ``h = s P0 m0 + tau Z'r``,
      with ``s = 1`` for the independent prior and ``s = tau`` for the conjugate one;
    * ``tau | b ~ Gamma(a0 + n/2 [+ k/2], b0 + SSR(b)/2 [+ (b-m0)' P0 (b-m0)/2])``.
    """
    settings = DEFAULTS if settings is None else settings
    chains, draws, burn, thin = settings.chains, settings.draws, settings.burn, settings.thin
    init = settings.init
    _check_prior(stats, prior)  # the iteration counts were checked by SamplerSettings
    if scheme not in SCHEMES:
        raise ValueError(f"scheme must be one of {SCHEMES}, got {scheme!r}")
    gens = chain_generators(settings.seed, chains)
    kept = _n_kept(draws, burn, thin)
    k = stats.k
    if scheme == "exact":
        return _sample_exact(stats, prior, gens, kept)
    b_ls, ssr_min = stats.least_squares()
    shape = _posterior_shape(stats, prior)
    single = scheme == "single-site"
    diag = None if single else _diagonalise(stats, prior, b_ls)
    tau = np.empty(chains)
    state = np.empty((chains, k))  # b (single-site) or u = W^-1 b (blocked)
    out_b = np.empty((chains, kept, k))
    out_t = np.empty((chains, kept))
    ztz = np.ascontiguousarray(stats.ztz, dtype=float)
    ztr = np.ascontiguousarray(stats.ztr, dtype=float)

    def run(c0: int, c1: int) -> None:
        for c in range(c0, c1):
            tau[c], b0 = _initial(stats, prior, gens[c], init, b_ls, ssr_min)
            state[c] = b0 if diag is None else diag.w_inv @ b0
        # Randomness a segment at a time: small buffers that stay in cache and are reused
        # (fresh multi-megabyte buffers cost more in page faults than in drawing).
        z = np.empty((c1 - c0, min(SEGMENT, draws), k))
        g = np.empty((c1 - c0, min(SEGMENT, draws)))
        sl = slice(c0, c1)
        for start in range(0, draws, SEGMENT):
            # A signal whose KeyboardInterrupt a library swallowed (a bare except during
            # an import) still stops the run here, within one segment.
            check_stop(None)
            m = min(SEGMENT, draws - start)
            for j, c in enumerate(range(c0, c1)):  # per chain: the normals, then the gammas
                gens[c].standard_normal(out=z[j, :m])
                gens[c].standard_gamma(shape, out=g[j, :m])
            if diag is None:
                _single_site_chains(
                    ztz, ztr, b_ls, float(ssr_min), prior.mean, prior.precision,
                    float(prior.rate), bool(prior.conjugate), tau[sl], state[sl], z, g, m,
                    start, burn, thin, out_b[sl], out_t[sl],
                )  # fmt: skip
            else:
                _blocked_chains(
                    diag.w, diag.e, diag.d, diag.c0, diag.c1, diag.u_ls, diag.u0,
                    float(ssr_min), float(prior.rate), bool(prior.conjugate), tau[sl],
                    state[sl], z, g, m, start, burn, thin, out_b[sl], out_t[sl],
                )  # fmt: skip

    run_threads(_chain_groups(chains, draws, run, settings.threads))
    return BlockDraws(out_b, out_t)


def _chain_groups(
    chains: int, draws: int, run: Callable[[int, int], None], threads: int | None = None
) -> list[Callable[[], None]]:
    """Split the chains into contiguous groups, one per thread (at most ``threads``)."""
    workers = min(chains, num_threads(), max(chains * draws // _MIN_ITERS_PER_THREAD, 1))
    if threads is not None:
        workers = min(workers, threads)
    bounds = [chains * w // workers for w in range(workers + 1)]
    return [(lambda c0=c0, c1=c1: run(c0, c1)) for c0, c1 in zip(bounds, bounds[1:], strict=False)]


def exact_posterior(stats: RegressionStats, prior: BlockPrior) -> dict[str, np.ndarray | float]:
    """Closed-form posterior of the conjugate normal-gamma prior.

    Returns ``mean``, ``precision`` (of ``b`` given ``tau = 1``), ``shape`` and ``rate``:
    ``tau ~ Gamma(shape, rate)``, ``b | tau ~ N(mean, (tau precision)^-1)``, and the
    marginal of ``b`` is a multivariate t with ``2 shape`` degrees of freedom, location
    ``mean`` and scale matrix ``rate / shape * precision^-1``.
    """
    if not prior.conjugate:
        raise ValueError("the exact posterior needs the conjugate normal-gamma prior")
    lam = prior.precision + stats.ztz
    h = prior.precision @ prior.mean + stats.ztr
    mean = np.linalg.solve(lam, h)
    b_ls, ssr_min = stats.least_squares()
    # r'r + m0'P0 m0 - mn'Ln mn, written as sums of non-negative terms to avoid cancellation.
    d0 = prior.mean - mean
    dl = b_ls - mean
    quad = ssr_min + float(dl @ stats.ztz @ dl) + float(d0 @ prior.precision @ d0)
    return {
        "mean": mean,
        "precision": lam,
        "shape": prior.shape + 0.5 * stats.n,
        "rate": prior.rate + 0.5 * quad,
    }


def _sample_exact(stats, prior, gens, kept) -> BlockDraws:
    post = exact_posterior(stats, prior)
    chol = np.linalg.cholesky(post["precision"])
    k = stats.k
    out_b = np.empty((len(gens), kept, k))
    out_t = np.empty((len(gens), kept))
    for c, gen in enumerate(gens):
        z = gen.standard_normal((kept, k))
        tau = gen.standard_gamma(post["shape"], kept) / post["rate"]
        # b = mean + L'^-1 z / sqrt(tau), with precision = L L'
        e = np.linalg.solve(chol.T, z.T).T
        out_b[c] = post["mean"] + e / np.sqrt(tau)[:, None]
        out_t[c] = tau
    return BlockDraws(out_b, out_t)
