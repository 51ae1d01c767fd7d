"""What a pooled archive fit says: which units are alike, and whether its chains mixed."""

from __future__ import annotations

import itertools
from typing import Any

import numpy as np
import pandas as pd

from loadbayes.core.convergence import summarize

__all__ = ["alike_pairs", "convergence_words", "groups_of"]

#: "alike": the probability that the curves differ by less than the tolerance everywhere
#: is at least ALIKE. "different": at some point of the grid, the probability that one
#: curve exceeds the other by more than the tolerance (one direction, one point) is at
#: least APART. Neither: "cannot tell".
ALIKE, APART = 0.8, 0.95
#: Draws (all chains) the alike probabilities are counted over.
THIN_DRAWS = 1000


def alike_pairs(
    names: list[str], beta: np.ndarray, x: np.ndarray, tolerance: float
) -> pd.DataFrame:
    """Each pair's verdict: alike, different, or the data cannot tell.

    ``beta`` (chain, draw, unit, p); ``x`` (G, p) the grid of covariates.
    ``prob_alike`` is the posterior probability that the curves differ by less than
    ``tolerance`` everywhere on the grid; ``prob_apart`` the largest simultaneous level
    at which the band of their difference lies beyond ``+-tolerance`` at some point
    (:func:`_apart`); ``max_diff_median`` the posterior median of the largest difference
    over the grid. The verdict: "alike" when ``prob_alike >= ALIKE``, "different" when
    ``prob_apart >= APART``, else "cannot tell".

    Why not "different" when ``prob_alike`` is low: with wide bands, the largest of the
    draws' differences over the grid exceeds the tolerance somewhere in most draws even
    when the two curves are the same (the spread alone makes it), so a low ``prob_alike``
    says only that the curves are not shown alike. A simultaneous band asks for a
    difference beyond the tolerance that the spread does not explain: two identical
    curves with calibrated bands 0.14-0.52 wide were said "different" in 1% of pairs or
    fewer (the old rule, "different" at P(alike) <= 0.2: in every pair at 0.28), curves
    0.2 apart with bands 0.07 wide in every pair (tests/unit/test_archive_alike.py).
    """
    rows = []
    if len(names) < 2:
        return pd.DataFrame(
            columns=["a", "b", "prob_alike", "prob_apart", "max_diff_median", "verdict"]
        )
    # at most THIN_DRAWS draws: the probability to about 0.015, the memory bounded
    flat = beta.reshape(-1, *beta.shape[2:])
    flat = flat[:: max(1, flat.shape[0] // THIN_DRAWS)]
    shares = 1.0 / (1.0 + np.exp(-(flat @ x.T)))  # (draw, unit, G)
    for i, j in itertools.combinations(range(len(names)), 2):
        diff = shares[:, i] - shares[:, j]  # (draw, G)
        gap = np.abs(diff).max(axis=-1)
        prob = float(np.mean(gap < tolerance))
        apart = _apart(diff, tolerance)
        verdict = "alike" if prob >= ALIKE else "different" if apart >= APART else "cannot tell"
        rows.append({"a": names[i], "b": names[j], "prob_alike": prob, "prob_apart": apart,
                     "max_diff_median": float(np.median(gap)), "verdict": verdict})  # fmt: skip
    return pd.DataFrame(rows)


def _apart(diff: np.ndarray, tolerance: float) -> float:
    """The largest simultaneous level at which the difference's band clears the tolerance.

    ``diff`` (draw, G): the difference of two curves on the grid. The simultaneous band
    at level L is ``m_g +- M_L s_g`` (``m``, ``s`` the draws' mean and sd at each point,
    ``M_L`` the L-quantile over draws of ``max_g |diff_g - m_g| / s_g``); it lies beyond
    ``+-tolerance`` at the point ``g`` once ``M_L <= (|m_g| - tolerance) / s_g``. The
    level is the share of draws whose largest standardised deviation is under the best
    point's margin.
    """
    m = diff.mean(axis=0)
    s = np.maximum(diff.std(axis=0), 1e-12)
    margin = float(np.max((np.abs(m) - tolerance) / s))
    if margin <= 0:
        return 0.0
    dev = np.max(np.abs(diff - m) / s, axis=1)
    return float(np.mean(dev <= margin))


def groups_of(names: list[str], pairs: pd.DataFrame) -> list[list[str]]:
    """The connected sets of alike pairs (each unit alone when alike to none)."""
    parent = {n: n for n in names}

    def root(n: str) -> str:
        while parent[n] != n:
            n = parent[n]
        return n

    for a, b in pairs.loc[pairs["verdict"] == "alike", ["a", "b"]].itertuples(index=False):
        parent[root(a)] = root(b)
    out: dict[str, list[str]] = {}
    for n in names:
        out.setdefault(root(n), []).append(n)
    return sorted(out.values(), key=lambda g: names.index(g[0]))


def convergence_words(
    part: str,
    names: list[str],
    groups: list[str],
    coefs: list[str],
    out: dict[str, np.ndarray],
    monthly: np.ndarray,
) -> dict[str, Any]:
    """R-hat and bulk ESS of every sampled quantity and monthly share, and the words.

    Thresholds as every fit's (:data:`loadbayes.diagnostics.RHAT_MAX`, ``ESS_MIN``).
    """
    from loadbayes.diagnostics import ESS_MIN, RHAT_MAX

    c, d, u, p = out["beta"].shape
    series = [
        np.moveaxis(out["beta"].reshape(c, d, u * p), 2, 0),
        np.moveaxis(out["mu"].reshape(c, d, len(groups) * p), 2, 0),
        np.moveaxis(out["tau"], 2, 0),
        np.log(np.moveaxis(np.diagonal(out["sigma"], axis1=2, axis2=3), 2, 0)),
        monthly,
    ]
    labels = (
        [f"beta[{n}, {k}]" for n in names for k in coefs]
        + [f"mu[{g}, {k}]" for g in groups for k in coefs]
        + [f"tau[{n}]" for n in names]
        + [f"log Sigma[{k}, {k}]" for k in coefs]
        + [f"share[{n}, month {m}]" for n in [*names, *groups] for m in range(1, 13)]
    )
    s = summarize(np.concatenate(series), tail=False)
    rhat, ess = s["r_hat"], s["ess_bulk"]
    words = []
    if c > 1 and np.nanmax(rhat) > RHAT_MAX:
        i = int(np.nanargmax(rhat))
        words.append(f"{part}: the chains have not mixed: R-hat up to {rhat[i]:.3f} "
                     f"({labels[i]}); the curves and bands are not to be trusted; "
                     "run more draws")  # fmt: skip
    if np.nanmin(ess) < ESS_MIN:
        i = int(np.nanargmin(ess))
        words.append(f"{part}: bulk ESS down to {ess[i]:.0f} ({labels[i]}; below {ESS_MIN}): "
                     "the bands' last digits are Monte Carlo noise; run more draws")  # fmt: skip
    return {
        "rhat_max": float(np.nanmax(rhat)) if c > 1 else None,
        "rhat_worst": labels[int(np.nanargmax(rhat))] if c > 1 else None,
        "ess_bulk_min": float(np.nanmin(ess)),
        "ess_worst": labels[int(np.nanargmin(ess))],
        "converged": not words,
        "accept_tau": float(out["accept_tau"].mean()),
        "warnings": words,
    }
