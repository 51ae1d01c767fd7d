"""Validation of a ZIP estimate on the 33-bus feeder, by power flow on fresh experiments.

Power flows with the true and with the estimated load, or a posterior-predictive band
from posterior draws: the paper's validation (Fig. 4) as a study on top of
:mod:`loadbayes.cases.ieee33`. The ZIP study (:mod:`loadbayes.studies.zip_paper`) has
its own variant of it.
"""

from __future__ import annotations

import warnings
from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

import numpy as np
import pandas as pd

from loadbayes.cases.ieee33.draws import (
    FACTOR_RANGE,
    Seed,
    check_range,
    draw_factors_from,
    factor_streams,
)
from loadbayes.cases.ieee33.feeder import Feeder33
from loadbayes.cases.ieee33.network import DEFAULT_ZIP, ZIP_BUS, Engine, as_zip

if TYPE_CHECKING:
    from numpy.typing import ArrayLike

__all__ = ["validate"]


def validate(
    zip_true: ArrayLike,
    zip_est: ArrayLike,
    *,
    seed: Seed,
    rng: np.random.Generator | None = None,
    n: int = 100,
    factor_range: tuple[float, float] = FACTOR_RANGE,
    zip_q_true: ArrayLike = DEFAULT_ZIP,
    zip_q_est: ArrayLike | None = None,
    quantiles: Sequence[float] = (0.025, 0.5, 0.975),
    engine: Engine = "newton",
    workers: int = 1,
    progress: bool = False,
) -> pd.DataFrame:
    """Compare power flows with the true and the estimated ZIP load on fresh experiments.

    Parameters
    ----------
    zip_true : array_like
        True P shares, ``(a1, a2)`` or ``(a1, a2, a3)``.
    zip_est : array_like
        Estimated P shares: one point estimate, shape ``(2,)`` or ``(3,)``, or posterior
        draws, shape ``(m, 2)`` or ``(m, 3)``.
    seed : int, numpy.random.SeedSequence or None
        Seed of the load factors (``draw_factors(n, seed=seed)``); use another seed than
        the one that generated the fitted data, so the experiments are fresh. None takes
        fresh entropy (not reproducible).
    rng : numpy.random.Generator, optional
        Generator to draw the factors from instead (then pass ``seed=None``).
    n : int
        Number of experiments.
    factor_range : (float, float)
        Range of the load factors.
    zip_q_true : array_like
        True Q shares.
    zip_q_est : array_like, optional
        Estimated Q shares, ``(3,)`` or draws ``(m, 2 | 3)`` paired with ``zip_est``;
        default ``zip_q_true`` (only P is estimated).
    quantiles : sequence of float
        Quantiles of the predictive band, used with draws.
    engine : {"newton", "recycle", "runpp"}
        Power-flow engine.
    workers : int
        Processes; results do not depend on it.
    progress : bool
        Progress bar (needs ``tqdm``).

    Returns
    -------
    pandas.DataFrame
        One row per experiment. Point estimate: ``experiment, v_true_pu, v_est_pu,
        p_true_pu, p_est_pu, q_true_pu, q_est_pu, dv_pu, dp_pu, dq_pu, converged`` with
        ``dX = X_est - X_true``. Draws: ``experiment, v_true_pu, p_true_pu, q_true_pu``,
        then for X in v, p, q: ``X_est_mean_pu`` and ``X_est_q{100 q}_pu`` (e.g.
        ``v_est_q2.5_pu``) over the draws, ``dv_pu, dp_pu, dq_pu`` (mean over draws of
        ``X_est - X_true``), ``n_draws_ok`` and ``converged`` (of the true run). Failed
        runs are NaN and left out of the band; ``attrs`` counts them.

    Notes
    -----
    The paper's validation (100 experiments, true vs estimated ZIP at bus 18) reports
    ``|dV|`` about 1e-4 and ``|dP|`` about 1e-3. With draws this is a posterior-
    predictive check: ``m * n`` power flows, spread over ``workers``.
    """
    factors = draw_factors_from(factor_streams(seed, rng)[0], n, factor_range)
    feeder = Feeder33(zip_p=zip_true, zip_q=zip_q_true, engine=engine)
    true = feeder.run_many(factors, workers=workers, progress=progress)
    est_p = as_zip(zip_est, "zip_est")
    est_q = feeder.zip_q if zip_q_est is None else as_zip(zip_q_est, "zip_q_est")
    attrs: dict[str, Any] = {
        "zip_true": feeder.zip_p.tolist(),
        "zip_q_true": feeder.zip_q.tolist(),
        "factor_range": list(check_range(factor_range)),
        "seed": seed if isinstance(seed, int) and rng is None else None,
        "n_failed": int(n - true["converged"].sum()),
        "bus": ZIP_BUS + 1,
    }
    cols: dict[str, Any] = {"experiment": np.arange(n, dtype=np.int64)}
    if est_p.ndim == 1:
        if est_q.ndim != 1:
            raise ValueError("zip_q_est has draws but zip_est is a point estimate")
        est = feeder.run_many(factors, zip_p=est_p, zip_q=est_q, workers=workers)
        for x in ("v", "p", "q"):
            cols[f"{x}_true_pu"] = true[f"{x}_pu"]
            cols[f"{x}_est_pu"] = est[f"{x}_pu"]
        for x in ("v", "p", "q"):
            cols[f"d{x}_pu"] = est[f"{x}_pu"] - true[f"{x}_pu"]
        cols["converged"] = true["converged"] & est["converged"]
        attrs.update(
            zip_est=est_p.tolist(), n_draws=None, n_failed_est=int(n - est["converged"].sum())
        )
        df = pd.DataFrame(cols)
        df.attrs.update(attrs)
        return df

    q = np.asarray(quantiles, dtype=float)
    if q.ndim != 1 or np.any((q < 0) | (q > 1)):
        raise ValueError(f"quantiles must be a 1-D sequence in [0, 1], got {quantiles}")
    draws = feeder.run_draws(factors, est_p, zip_q=est_q, workers=workers, progress=progress)
    for x in ("v", "p", "q"):
        cols[f"{x}_true_pu"] = true[f"{x}_pu"]
    # An experiment whose every draw failed has an all-NaN column: its band is NaN.
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", "All-NaN slice", RuntimeWarning)
        warnings.filterwarnings("ignore", "Mean of empty slice", RuntimeWarning)
        for x in ("v", "p", "q"):
            d = draws[f"{x}_pu"]
            cols[f"{x}_est_mean_pu"] = np.nanmean(d, axis=0)
            for qi, band in zip(q, np.nanquantile(d, q, axis=0), strict=True):
                cols[f"{x}_est_q{100 * qi:g}_pu"] = band
        for x in ("v", "p", "q"):
            cols[f"d{x}_pu"] = np.nanmean(draws[f"{x}_pu"] - true[f"{x}_pu"], axis=0)
    cols["n_draws_ok"] = draws["converged"].sum(axis=0).astype(np.int64)
    cols["converged"] = true["converged"]
    attrs.update(
        n_draws=int(est_p.shape[0]),
        quantiles=q.tolist(),
        n_failed_est=int(draws["converged"].size - draws["converged"].sum()),
    )
    df = pd.DataFrame(cols)
    df.attrs.update(attrs)
    return df
