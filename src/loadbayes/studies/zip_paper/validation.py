"""The ZIP study's validation: power flows with the true and estimated ZIP, and the band.

Step 3 of the study (:mod:`loadbayes.studies.zip_paper`): fresh experiments, one power
flow per estimate, and posterior-predictive power flows over posterior draws.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import Any

import numpy as np
import pandas as pd

from loadbayes.posterior import Posterior


def _power_flows(feeder, factors, zip_p, zip_q, workers, progress) -> dict[str, np.ndarray]:
    return feeder.run_many(factors, zip_p=zip_p, zip_q=zip_q, workers=workers, progress=progress)


def _validation(
    study_fits: Mapping[str, Posterior],
    estimates: Mapping[str, Mapping[str, float]],
    *,
    vseed: int,
    n_validation: int,
    n_pred: int,
    m_draws: int,
    seed: int,
    engine: str,
    workers: int,
    pf_progress: bool,
    say: Callable[[str], None],
) -> tuple[pd.DataFrame, dict[str, Any]]:
    from loadbayes.cases import ieee33

    factors = ieee33.draw_factors(n_validation, seed=vseed)
    feeder = ieee33.Feeder33(engine=engine)  # type: ignore[arg-type]
    say(f"zip: validation: {n_validation} power flows with the true ZIP ...")
    true = _power_flows(feeder, factors, None, None, workers, pf_progress)
    cols: dict[str, Any] = {"experiment": np.arange(n_validation, dtype=np.int64)}
    for x in ("v", "p", "q"):
        cols[f"{x}_true_pu"] = true[f"{x}_pu"]
    failed = {"true": int((~true["converged"]).sum())}
    for m, est in estimates.items():
        say(f"zip: validation: {n_validation} power flows with the {m.upper()} estimate ...")
        res = _power_flows(
            feeder,
            factors,
            (est["a1"], est["a2"]),
            (est["a4"], est["a5"]),
            workers,
            pf_progress,
        )
        failed[m] = int((~res["converged"]).sum())
        for x in ("v", "p", "q"):
            cols[f"{x}_{m}_pu"] = res[f"{x}_pu"]
        for x in ("v", "p"):
            cols[f"d{x}_{m}_pu"] = res[f"{x}_pu"] - true[f"{x}_pu"]
    # Posterior-predictive power flows: m posterior draws (P and Q shares of the same
    # iteration) on each of the first n_pred validation experiments.
    gs = study_fits["gs"]
    flat = gs.flat(["a1", "a2", "a4", "a5"])
    pick = np.random.default_rng(np.random.SeedSequence([int(seed), 2]))
    idx = np.sort(pick.choice(flat.shape[0], size=min(m_draws, flat.shape[0]), replace=False))
    draws = flat[idx]
    say(
        f"zip: posterior-predictive: {len(idx)} draws x {n_pred} experiments = "
        f"{len(idx) * n_pred} power flows ..."
    )
    pred = feeder.run_draws(
        factors[:n_pred], draws[:, :2], zip_q=draws[:, 2:], workers=workers, progress=pf_progress
    )
    quant = (0.025, 0.5, 0.975)
    for x in ("v", "p"):
        full = np.full((len(quant), n_validation), np.nan)
        with np.errstate(invalid="ignore"):
            ok_any = np.isfinite(pred[f"{x}_pu"]).any(axis=0)
            if ok_any.any():
                full[:, :n_pred][:, ok_any] = np.nanquantile(
                    pred[f"{x}_pu"][:, ok_any], quant, axis=0
                )
        for q, row in zip(quant, full, strict=True):
            cols[f"{x}_pred_q{100 * q:g}_pu"] = row
    n_ok = np.full(n_validation, -1, dtype=np.int64)
    n_ok[:n_pred] = pred["converged"].sum(axis=0)
    cols["n_draws_ok"] = n_ok
    cols["converged"] = true["converged"]
    failed["predictive"] = int(pred["converged"].size - pred["converged"].sum())
    info = {
        "validation_seed": vseed,
        "n_validation": n_validation,
        "predictive_experiments": n_pred,
        "predictive_draws": int(len(idx)),
        "failed": failed,
        "power_flows": n_validation * (1 + len(estimates)) + len(idx) * n_pred,
    }
    return pd.DataFrame(cols), info
