"""The ZIP posterior from the windows around voltage steps (the field method).

The windows around each step (:func:`loadbayes.measurements.steps.find_steps`) are
stacked, and each step gets its own load level and its own slope in time, so the level
that follows the time of day, and its drift during the windows, drop out; what is left
to explain the change of P across the steps is the voltage:

    P_i / L_j = c_j + s_j (t_i - t_j) + a1 (x_i^2 - 1) + a2 (x_i - 1) + e_i

for sample ``i`` in the windows of step ``j`` (``x = V / V0``), with ``L_j`` the step's
level at V0 from the data (below) so that ``c_j`` is near 1, and one noise precision
per channel (Q the same with a4, a5). That is one conjugate linear block per channel,
sampled by the plain fit's Gibbs sampler (:func:`loadbayes.inference.linear.sample_blocks`)
on its Gram matrix; ``a1 = d1 / mean_j c_j`` (``a3 = 1 - a1 - a2``) makes the shares
exact when the levels ``L_j`` are off by a common factor.

``L_j``: a first pass takes the mean power over the step's windows; a second takes the
mean of ``P_i / g(x_i)`` with the shares of the first pass (``g`` the ZIP curve in per
unit), so that the linearisation ``c_j a1 ~ a1`` holds to the second order.

The steps span a narrow band of V each (a tap is 0.6%), so the data determine
``2 a1 + a2`` (dP/dV at V0, per unit of the level) well and ``a1`` against ``a2`` only
through the spread of the voltages at which the steps happen; the identifiability
warnings of every fit say so, and the JSON gives dP/dV and dQ/dV under ``derived``.

A step's recovery (thermostats taking the power back) has a lag the feeder does not
state: ``recovery="prior"`` averages the fit over a grid of lags by their marginal
likelihoods (:func:`fit_steps`). One idea needs these 420 lines: the fit from the steps'
windows, whose passes the mixture over lags repeats, so they stay together.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from loadbayes.core.blocks import LinearBlock
from loadbayes.core.parallel import one_blas_thread
from loadbayes.core.priors import BlockPrior
from loadbayes.core.settings import SamplerSettings
from loadbayes.core.stats import GramAccumulator
from loadbayes.inference.linear import log_evidence, sample_blocks
from loadbayes.io.errors import DataError
from loadbayes.measurements.steps import Step
from loadbayes.posterior import Posterior

__all__ = [
    "MIN_WEIGHT",
    "RECOVERY_LAGS_S",
    "RECOVERY_LAG_S",
    "STEP_DEFAULTS",
    "derived",
    "fit_steps",
    "lag_words",
]

#: The sampler's defaults: the block has 2 per step + 2 coefficients, O(k) per iteration.
STEP_DEFAULTS = SamplerSettings(draws=6_000, burn=1_000)
#: The lag (s) of a step's recovery term where a caller asks for one without saying: an
#: hour, a thermostat population's (fit_steps' notes).
RECOVERY_LAG_S = 3_600.0
#: The lags (s) of ``recovery="prior"``, equally likely a priori (log-uniform over the
#: grid, each a doubling): 15 min to 4 h, the time constants of thermostatic loads after a
#: voltage change (fit_steps' notes).
RECOVERY_LAGS_S = (900.0, 1_800.0, 3_600.0, 7_200.0, 14_400.0)
#: A lag whose posterior weight is under this is not sampled (under 1 draw in 10,000).
MIN_WEIGHT = 1e-4
#: Prior sd of every coefficient (weak: the shares are O(1), the levels near 1).
PRIOR_SD = 10.0

_SHARES = {"p": ("a1", "a2", "a3"), "q": ("a4", "a5", "a6")}


def _design(x, tt, steps: Sequence[Step], lag: float | None = None, per_end: bool = False):
    """Row indices, the step of each row, the voltage used, and the design columns.

    ``lag`` (s): each step also gets a recovery after it, ``1 - exp(-s / lag)`` of the
    time ``s`` since the last sample before it (a straight line for an infinite lag; the
    load's own recovery, :func:`fit_steps`); None: no recovery columns. ``per_end``: the
    recovery column is 1 at the window's end, so that its coefficient (the recovery by
    then, per unit of the level) means the same for every lag (the mixture's lags).

    The voltage of each window is its fitted line with a step (level, slope, jump): the
    measured one carries its noise into the regressor, which biases the slope toward a
    flat load by about ``2 sd^2 / dV^2`` per step (measured over 40 generated days with
    0.05% noise on V and 0.6% taps: dP/dV off by -0.37 posterior sd on average with the
    measured V, +0.03 with the fitted line, which averages the noise over the window).
    """
    from loadbayes.measurements.steps import jump

    idx = np.concatenate([np.arange(s.lo, s.hi) for s in steps])
    which = np.concatenate([np.full(s.hi - s.lo, j) for j, s in enumerate(steps)])
    k = len(steps)
    n = idx.size
    ind = np.zeros((n, k))
    trend = np.zeros((n, k))
    xi = np.zeros(n)
    kink = np.zeros((n, 0 if lag is None else k))
    ind[np.arange(n), which] = 1.0
    for j, s in enumerate(steps):
        rows = which == j
        dt = tt[idx[rows]] - tt[s.index]
        scale = max(float(np.abs(dt).max()), 1e-12)
        trend[rows, j] = dt / scale
        _, _, res = jump(x[idx[rows]], dt, idx[rows] >= s.index)
        xi[rows] = x[idx[rows]] - res
        if lag is not None:
            since = tt[idx[rows]] - tt[s.index - 1]
            rec = since if np.isinf(lag) else lag * -np.expm1(-since / lag)
            col = np.where(idx[rows] >= s.index, rec, 0.0)
            kink[rows, j] = col / (max(float(col.max()), 1e-12) if per_end else scale)
    return idx, which, xi, np.column_stack([ind, trend, kink, xi * xi - 1.0, xi - 1.0])


def _levels(y, x, which, n_steps, shares):
    """Each step's level at V0: the mean of ``y / g(x)`` over its windows."""
    a1, a2 = shares
    g = 1.0 + a1 * (x * x - 1.0) + a2 * (x - 1.0)
    out = np.zeros(n_steps)
    for j in range(n_steps):
        out[j] = float(np.mean(y[which == j] / g[which == j]))
    return out


def _blocks(design, ys, names, n_steps, recovery=False):
    """The Gram matrix of the stacked windows and the conjugate blocks (one per channel)."""
    cols = [f"c{j}" for j in range(n_steps)] + [f"s{j}" for j in range(n_steps)]
    cols += [f"r{j}" for j in range(n_steps)] if recovery else []
    cols += ["z1", "z2"]
    acc = GramAccumulator(tuple(cols) + tuple(names))
    acc.update(np.column_stack([design] + [ys[ch] for ch in names]))
    gram = acc.result()
    blocks, priors = [], {}
    for ch in names:
        coef = tuple(f"{ch}_{c}" for c in cols)
        blocks.append(LinearBlock(ch, coef, f"tau_{ch}", ((tuple(cols), ch),)))
        priors[ch] = BlockPrior.weak(len(cols), sd=PRIOR_SD)
    return gram, blocks, priors


def _sample(design, ys, names, n_steps, sampler, recovery=False):
    """The conjugate blocks (one per channel) on the stacked windows."""
    gram, blocks, priors = _blocks(design, ys, names, n_steps, recovery)
    return sample_blocks(gram, blocks, priors, settings=sampler), gram


def _first_pass(design, chans, levels, xs, which, k, first, recovery):
    """Pass 1 on the mean levels; the levels at V0 with its shares (module notes)."""
    ys = {ch: chans[ch] / levels[ch][which] for ch in chans}
    raw, _ = _sample(design, ys, list(chans), k, first, recovery)
    out = {}
    for ch in chans:
        a1 = float(np.mean(raw[f"{ch}_z1"]))
        a2 = float(np.mean(raw[f"{ch}_z2"]))
        out[ch] = _levels(chans[ch], xs, which, k, (a1, a2))
    return out


def _lags(recovery):
    """``(lags of a mixture or None, the one fixed lag or None)`` from ``recovery``."""
    if recovery is None:
        return None, None
    if isinstance(recovery, str):
        if recovery != "prior":
            raise ValueError(f'recovery is a lag in seconds, "prior" or lags, got {recovery!r}')
        return RECOVERY_LAGS_S, None
    if np.ndim(recovery) == 0:
        lag = float(recovery)  # type: ignore[arg-type]
        if not lag > 0:
            raise ValueError(f"recovery is a lag in seconds (> 0), got {recovery}")
        return None, lag
    lags = tuple(float(v) for v in recovery)  # type: ignore[union-attr]
    if not lags or not all(v > 0 for v in lags):
        raise ValueError(f"recovery lags are seconds (> 0), got {recovery}")
    return lags, None


def _mixture(x, tt, steps, chans, levels0, xs, which, sampler, first, lags):
    """Draws with the recovery's lag integrated out over ``lags`` (equally likely a priori).

    The levels ``L_j`` come from one pass 1, at the grid's middle lag (they enter at the
    second order only: module notes), so every lag's fit sees the same ``y = P / L_j``;
    each lag's is then the fixed lag's pass 2, its recovery column 1 at the window's end
    (:func:`_design`). Its weight is prior x the marginal likelihood of ``y`` (P, Q)
    given the lag: each channel's block evidence
    (:func:`loadbayes.inference.linear.log_evidence`, exact). Lags under
    :data:`MIN_WEIGHT` are not sampled; the draws are then picked, position by position,
    from each lag's chains with the probabilities of the weights (a generator of its own
    from the sampler's seed), so the chains keep their shape.
    """
    k = len(steps)
    names = list(chans)
    middle = float(np.exp(np.median(np.log(lags))))
    design = _design(x, tt, steps, middle, per_end=True)[3]
    levels = _first_pass(design, chans, levels0, xs, which, k, first, True)
    ys = {ch: chans[ch] / levels[ch][which] for ch in chans}
    logev, kept_blocks = [], []
    for lag in lags:
        design = _design(x, tt, steps, lag, per_end=True)[3]
        gram, blocks, priors = _blocks(design, ys, names, k, True)
        logev.append(sum(log_evidence(b.stats(gram), priors[b.name]) for b in blocks))
        kept_blocks.append((gram, blocks, priors))
    lw = np.array(logev) - max(logev)
    w = np.exp(lw) / np.exp(lw).sum()
    use = np.flatnonzero(w >= MIN_WEIGHT)
    raws = [sample_blocks(*kept_blocks[i], settings=sampler) for i in use]
    p = w[use] / w[use].sum()
    seq = sampler.seed
    seq = seq if isinstance(seq, np.random.SeedSequence) else np.random.SeedSequence(seq)
    own = np.random.SeedSequence(seq.entropy, spawn_key=(*seq.spawn_key, 39_001))
    gen = np.random.default_rng(own)
    shape = raws[0][f"tau_{names[0]}"].shape
    pick = gen.choice(use.size, size=shape, p=p)
    raw = {}
    for name in raws[0]:
        stack = np.stack([r[name] for r in raws])
        raw[name] = np.take_along_axis(stack, pick[None], axis=0)[0]
    info = {
        "lags_s": [float(v) for v in lags],
        "prior": "equally likely (log-uniform over the grid)",
        "log_evidence": [float(v) for v in logev],
        "weights": [float(v) for v in w],
        "sampled": [float(lags[i]) for i in use],
        "words": lag_words(lags, w),
    }
    return raw, info


def _hours(lag: float) -> str:
    return f"{lag / 60:g} min" if lag < 3_600 else f"{lag / 3_600:g} h"


def lag_words(lags: Sequence[float], weights: Sequence[float]) -> str:
    """Which recovery lags the data favour, in words (or that they cannot tell)."""
    w = np.asarray(weights, dtype=float)
    order = np.argsort(-w)
    top = int(order[0])
    listed = ", ".join(f"{_hours(lags[i])} {w[i]:.2f}" for i in range(len(lags)))
    if w[top] >= 0.9:
        head = f"the data favour a recovery lag of {_hours(lags[top])}"
    elif len(lags) > 1 and w[order[:2]].sum() >= 0.9 and abs(int(order[1]) - top) == 1:
        a, b = sorted(order[:2].tolist())
        head = f"the data favour a recovery lag between {_hours(lags[a])} and {_hours(lags[b])}"
    elif w.max() - w.min() < 0.15:
        head = "the data cannot tell the recovery lag apart"
    else:
        head = f"the data lean to a recovery lag of {_hours(lags[top])} but cannot pin it"
    return f"{head} (weights: {listed}); dP/dV averages over them"


@one_blas_thread  # k ~ 360 blocks: one LAPACK thread, the chains are the threads
def fit_steps(
    v: np.ndarray,
    p: np.ndarray,
    q: np.ndarray | None = None,
    *,
    steps: Sequence[Step],
    t: np.ndarray | None = None,
    v0: float = 1.0,
    sampler: SamplerSettings | None = None,
    settings: dict[str, Any] | None = None,
    warnings: Sequence[str] = (),
    recovery: float | str | Sequence[float] | None = None,
) -> Posterior:
    """The ZIP shares from the windows around voltage steps (module notes).

    Parameters
    ----------
    v, p, q : ndarray
        The whole record in per unit (V) and any units (P, Q), in time order.
    steps : sequence of Step
        From :func:`loadbayes.measurements.steps.find_steps` on the same arrays.
    t : ndarray, optional
        Sample times in seconds (the row number if None).
    v0 : float
        Nominal voltage (per unit).
    sampler : SamplerSettings, optional
        :data:`STEP_DEFAULTS` when not given.
    settings, warnings
        Recorded with the result.
    recovery : float, "prior" or sequence of float, optional
        A lag in seconds (``inf``: a straight line): give each step a recovery after it,
        ``1 - exp(-s / lag)`` of the time ``s`` since the last sample before it, with its
        own size per step. A load that recovers after a step (thermostats whose duty
        cycle lengthens) has already moved back by the first sample after it, and the
        jump alone reads that as a smaller response; with the term the jump is the
        response at the step's instant (the step taken to act just after the sample
        before it). Measured on tests/cvr_generator.py's feeders (5-minute samples,
        thermostats with a 1 h lag), the jumps of the 3% switches: dP/dV 0.056 low
        without the term (se 0.009, 5 feeders), 0.003 low with a lag of 1 h
        (:data:`RECOVERY_LAG_S`), 0.018 low with a straight line.

        A fixed lag is the feeder's own only by luck, and a wrong one biases the jump
        (thermostats with a 30 min lag read with 1 h: dP/dV 9 posterior sd low,
        tests/unit/test_steps.py). ``"prior"`` (or a sequence of lags): the lag is
        uncertain, equally likely at each of :data:`RECOVERY_LAGS_S` (15 min to 4 h, each
        a doubling: a log-uniform prior), and the draws are those of each lag's fit in
        proportion to prior x its exact marginal likelihood (:func:`_mixture`); the lags
        and their weights are in ``settings`` (``recovery_lags_s``,
        ``recovery_lag_weights``) and ``extra_json["recovery"]`` (with the words). The
        range: a thermostatic population's recovery after a voltage change is set by the
        units' duty cycles and thermal time constants, minutes for water heaters and
        cooling compressors cycling a few times an hour, one to a few hours for space
        heating of buildings (the cold-load-pickup and CVR literature: payback within
        15 min to a few hours); a lag under the 5-minute sample is a load that has
        recovered before the first sample and reads as a smaller jump whatever the fit,
        one over 4 h is a straight line over a window of half an hour. Whether the data
        tell the lags apart depends on the noise and the step sizes: 60 switches of 3% at
        0.1% noise pin 30 min (weight 1.00); tests/cvr_generator.py's feeders (120 steps,
        mostly taps, a level that moves) put their weight on 2-4 h whatever the true lag
        (docs/zip.md).

    Returns
    -------
    Posterior
        a1, a2, a3 (a4, a5, a6), tau_p (tau_q); ``extra_json["derived"]`` holds dP/dV
        (dQ/dV) at V0 in per unit of the load's level.

    Raises
    ------
    DataError
        Fewer than two steps, or a channel's level at V0 that is not positive.
    """
    sampler = sampler or STEP_DEFAULTS
    if len(steps) < 2:
        raise DataError(
            f"{len(steps)} voltage step(s) found: a fit from steps needs at least two "
            "(lower --min-step or --k, or fit the record with fit zip)"
        )
    v = np.asarray(v, dtype=float)
    tt = np.arange(v.size, dtype=float) if t is None else np.asarray(t, dtype=float)
    x = v / v0
    idx, which, xs, design = _design(x, tt, steps)
    chans = {"p": np.asarray(p, dtype=float)[idx]}
    if q is not None:
        chans["q"] = np.asarray(q, dtype=float)[idx]
    k = len(steps)
    first = sampler.with_(draws=min(sampler.draws, 2_000), burn=min(sampler.burn, 500))
    levels = {}
    for ch, y in chans.items():
        lv = _levels(y, xs, which, k, (0.0, 0.0))
        if not np.all(lv > 0):
            raise DataError(
                f"{ch.upper()} is not positive around every step: the fit from steps "
                "divides by the load's level (give the power into the load)"
            )
        levels[ch] = lv
    lags, lag = _lags(recovery)
    info = None
    if lags is not None:
        raw, info = _mixture(x, tt, steps, chans, levels, xs, which, sampler, first, lags)
    else:
        if lag is not None:  # the same rows, with the recovery's columns
            design = _design(x, tt, steps, lag)[3]
        # pass 1 on the mean levels, pass 2 on the levels at V0 with pass 1's shares
        levels = _first_pass(design, chans, levels, xs, which, k, first, lag is not None)
        ys = {ch: chans[ch] / levels[ch][which] for ch in chans}
        raw, _ = _sample(design, ys, list(chans), k, sampler, lag is not None)
    draws: dict[str, np.ndarray] = {}
    for ch in chans:
        c_bar = np.mean([raw[f"{ch}_c{j}"] for j in range(k)], axis=0)
        n1, n2, n3 = _SHARES[ch]
        draws[n1] = raw[f"{ch}_z1"] / c_bar
        draws[n2] = raw[f"{ch}_z2"] / c_bar
        draws[n3] = 1.0 - draws[n1] - draws[n2]
    for ch in chans:
        draws[f"tau_{ch}"] = raw[f"tau_{ch}"]
    coefficients = [c for ch in chans for c in _SHARES[ch]]
    free = [c for ch in chans for c in _SHARES[ch][:2]]
    warn = list(warnings)
    against = sum(1 for s in steps if s.dv * s.dp < 0)
    if against:
        warn.append(
            f"at {against} of {k} steps P moved against V: a load switching at the same "
            "moment, or a load that holds its power (check the steps table)"
        )
    full = dict(settings or {})
    full.update(
        n=int(idx.size),
        n_steps=k,
        v0=v0,
        scheme="blocked (steps: per-step level and drift"
        + (")" if lag is None else f", and a recovery after each step with a lag of {lag:g} s)")
        if info is None
        else "blocked (steps: per-step level and drift, and a recovery after each step, its "
        "lag averaged over a prior by each lag's marginal likelihood)",
        chains=sampler.chains,
        draws=sampler.draws,
        burn=sampler.burn,
        thin=sampler.thin,
        seed=sampler.seed,
    )
    if info is not None:
        full.update(recovery_lags_s=info["lags_s"], recovery_lag_weights=info["weights"])
    post = Posterior(
        draws,
        model="zip",
        method="gibbs-steps",
        coefficients=coefficients,
        free=free,
        settings=full,
        warnings=warn,
    )
    post.extra_json["derived"] = derived(post)
    if info is not None:
        post.extra_json["recovery"] = info
    return post


def derived(post: Posterior, hdi_prob: float = 0.95) -> dict[str, dict[str, float]]:
    """dP/dV (dQ/dV) at V0, per unit of the level: ``2 a1 + a2`` (``2 a4 + a5``)."""
    from loadbayes.core.convergence import hdi

    out = {}
    for name, (i, j) in (("dP/dV", ("a1", "a2")), ("dQ/dV", ("a4", "a5"))):
        if i not in post.draws:
            continue
        s = 2.0 * post.draws[i] + post.draws[j]
        lo, hi = hdi(s, hdi_prob)
        out[name] = {
            "mean": float(s.mean()),
            "sd": float(s.std(ddof=1)),
            "hdi_low": float(lo),
            "hdi_high": float(hi),
        }
    return out
