"""The paper's ZIP study on the IEEE 33-bus feeder, reproduced with its baselines.

What it does (the paper's section "Case Study: ZIP Model Identification" and
"Benchmarks"; NOTES.md for what the paper leaves unsaid):

1. Data: ``N = max(n, largest sweep n)`` power flows of ``case33bw`` with the ZIP load
   (0.25, 0.25, 0.5) at bus 18 and every other load scaled by its own U[0.1, 4.5]
   factor (:func:`loadbayes.cases.ieee33.generate_experiments`), noise sd ``noise`` in
   per unit of P0 and Q0 on P and Q. The fit uses the first ``n`` experiments; the sweep
   uses nested prefixes of the same ``N``, so nothing is generated twice.
2. Fits on the same data: Gibbs with blocked (a1, a2) (``GS``, the project's default),
   Gibbs one coefficient at a time (the paper's Algorithm 1), least squares with the
   sum-to-one constraint (``LS``) and without it (three free coefficients), a Kalman
   filter on (a1, a2) (``KF``: no process noise by default) and one with a random walk.
3. Validation: 100 fresh experiments (their own seed); power flow with the true ZIP and
   with each estimate (P and Q shares); ``dX = X_est - X_true`` at bus 18. Posterior-
   predictive power flows over a few hundred posterior draws give a 95% band of V and P.
4. Table II: mean absolute relative error, in %, of V and of P at bus 18 over the
   validation experiments::

       voltage_error_pct = 100 * mean_i |V_est,i - V_true,i| / V_true,i
       power_error_pct   = 100 * mean_i |P_est,i - P_true,i| / P_true,i

   where ``X_true`` is the power flow with the true ZIP load and ``X_est`` the one with
   the estimated ZIP load, on the same experiment (load factors). The paper calls it "the
   average absolute mean of voltage and active power errors" and gives no formula.
5. Sweep: posterior sd of a1 and a2 against n and noise (blocked Gibbs with the study's
   priors, and the least-squares standard error from the same sufficient statistics).

:func:`run` computes, :func:`write` writes ``OUT/zip/`` and the ZIP section of
``OUT/report.html`` (between ``<!-- loadbayes:section zip -->`` markers, as the motor
study does), :func:`html_section` returns that section.
"""

from __future__ import annotations

import base64
import io
import json
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from loadbayes.posterior import Posterior

__all__ = [
    "FULL",
    "METHODS",
    "PAPER_MEANS",
    "PAPER_TABLE2",
    "PAPER_VALIDATION",
    "QUICK",
    "ZipStudy",
    "error_pct",
    "figures",
    "html_section",
    "output_paths",
    "required_n",
    "run",
    "table2",
    "text_tables",
    "update_report",
    "write",
]

#: The paper's posterior means of a1 and a2 (Fig. 2); a3 = 1 - a1 - a2.
PAPER_MEANS = {"a1": 0.25, "a2": 0.249}
#: The paper's Table II (10% noise): (voltage error %, active-power error %).
PAPER_TABLE2 = {"GS": (0.007, 1.12), "LS": (0.062, 4.65), "KF": (0.024, 2.64)}
#: The paper's validation (Fig. 4): |dV| and |dP| "in the range of" these.
PAPER_VALIDATION = {"dv": 1e-4, "dp": 1e-3}
#: The true ZIP shares of P and of Q (the paper's a1, a2, a3).
TRUE_ZIP = (0.25, 0.25, 0.5)

#: Estimators, by key: label. ``gs``, ``ls``, ``kf`` are Table II's rows.
METHODS = {
    "gs": "GS (blocked Gibbs, posterior mean)",
    "ls": "LS (a1 + a2 + a3 = 1)",
    "kf": "KF (no process noise)",
    "gs_single": "GS (single-site, the paper's Algorithm 1)",
    "ls3": "LS (three free coefficients, normalised)",
    "kf_rw": "KF (random walk)",
}
TABLE2_ROWS = {"gs": "GS", "ls": "LS", "kf": "KF"}
#: Process noise of the random-walk Kalman filter (per measurement, times the identity).
KF_RANDOM_WALK = 1e-6
#: Coefficient sd targets for the "what n would the paper need" table.
SD_TARGETS = (0.01, 0.001)

FULL: dict[str, Any] = {
    "n": 1000,
    "sweep_n": (100, 300, 1_000, 3_000, 10_000, 30_000, 100_000),
    "draws": 40_000,
    "burn": 5_000,
    "chains": 4,
    "n_validation": 100,
    "predictive_experiments": 100,
    "predictive_draws": 200,
}
QUICK: dict[str, Any] = {
    "n": 300,
    "sweep_n": (100, 300, 1_000),
    "draws": 10_000,
    "burn": 2_000,
    "chains": 2,
    "n_validation": 100,
    "predictive_experiments": 20,
    "predictive_draws": 25,
}
SWEEP_NOISE = (0.01, 0.05, 0.1)
_MARK = "loadbayes:section zip"


@dataclass
class ZipStudy:
    """Everything the study computed.

    Attributes
    ----------
    settings : dict
        n, noise, seeds, priors, sampler, power-flow counts and failures, timings.
    data : pandas.DataFrame
        The fitted experiments (first ``n`` of the generated ones), failed ones flagged.
    fits : dict of str to Posterior
        One result per key of :data:`METHODS`.
    validation : pandas.DataFrame
        One row per validation experiment: true and estimated V, P, Q for each method,
        and the posterior-predictive band (NaN outside the predictive subset).
    traces : dict of str to ndarray
        ``a1`` of every chain from the first iteration (burn-in included), by scheme.
    sweep : pandas.DataFrame
        Posterior sd of a1, a2 by noise and n.
    """

    settings: dict[str, Any]
    data: pd.DataFrame
    fits: dict[str, Posterior]
    validation: pd.DataFrame
    traces: dict[str, np.ndarray]
    sweep: pd.DataFrame
    timings: dict[str, float] = field(default_factory=dict)
    _summaries: dict[str, pd.DataFrame] = field(default_factory=dict, repr=False)

    def summary(self, method: str) -> pd.DataFrame:
        """ArviZ summary (95% HDI) of a1, a2, a3 for one fit, cached."""
        if method not in self._summaries:
            self._summaries[method] = self.fits[method].summary(var_names=["a1", "a2", "a3"])
        return self._summaries[method]

    def estimate(self, method: str) -> dict[str, float]:
        """Point estimate of a method: the posterior mean, or the exact LS / KF value."""
        post = self.fits[method]
        if "estimate" in post.settings:
            return {k: float(v) for k, v in post.settings["estimate"].items()}
        return post.mean()


# ------------------------------------------------------------------ measures
def error_pct(est: Any, true: Any) -> float:
    """Mean absolute relative error in %: ``100 * mean |est - true| / |true|``.

    Pairs where either value is NaN (a power flow that did not converge) are left out;
    NaN if none is left.
    """
    e = np.asarray(est, dtype=float)
    t = np.asarray(true, dtype=float)
    ok = np.isfinite(e) & np.isfinite(t)
    if not ok.any():
        return float("nan")
    return float(100.0 * np.mean(np.abs(e[ok] - t[ok]) / np.abs(t[ok])))


def required_n(sd_at_n: float, n: int, target_sd: float) -> float:
    """Experiments needed for a posterior sd of ``target_sd``, from sd ~ 1 / sqrt(n).

    With a weak prior the posterior sd of a coefficient is its least-squares standard
    error, ``sigma sqrt([(Z'Z)^-1]_11)``, and ``Z'Z / n`` settles to a constant for i.i.d.
    experiments: so ``sd(n') = sd(n) sqrt(n / n')``.
    """
    if not (sd_at_n > 0 and target_sd > 0 and n > 0):
        raise ValueError("sd_at_n, n and target_sd must be positive")
    return float(n * (sd_at_n / target_sd) ** 2)


def table2(validation: pd.DataFrame, estimates: Mapping[str, Mapping[str, float]]) -> pd.DataFrame:
    """Table II from the validation frame: errors in % and coefficient errors, per method.

    Parameters
    ----------
    validation : pandas.DataFrame
        Columns ``v_true_pu``, ``p_true_pu`` and, per method ``m``, ``v_{m}_pu``,
        ``p_{m}_pu``.
    estimates : mapping
        ``{method: {"a1": .., "a2": .., "a3": ..}}``; keys of :data:`TABLE2_ROWS` give
        the paper's rows (GS, LS, KF), others are kept under their own name.

    Returns
    -------
    pandas.DataFrame
        Indexed by method; ``voltage_error_pct``, ``power_error_pct``, the paper's
        values beside them (NaN where the paper has none), ``a1, a2, a3``, their errors
        ``a1_err`` .. (estimate - truth), and the largest ``|dV|`` and ``|dP|`` (p.u.).
    """
    rows = []
    for m, est in estimates.items():
        name = TABLE2_ROWS.get(m, m)
        paper_v, paper_p = PAPER_TABLE2.get(name, (np.nan, np.nan))
        v, p = validation[f"v_{m}_pu"], validation[f"p_{m}_pu"]
        row: dict[str, Any] = {
            "method": name,
            "voltage_error_pct": error_pct(v, validation.v_true_pu),
            "paper_voltage_error_pct": paper_v,
            "power_error_pct": error_pct(p, validation.p_true_pu),
            "paper_power_error_pct": paper_p,
        }
        for i, k in enumerate(("a1", "a2", "a3")):
            row[k] = float(est[k])
            row[f"{k}_err"] = float(est[k]) - TRUE_ZIP[i]
        row["max_abs_dv_pu"] = float(np.nanmax(np.abs(v - validation.v_true_pu)))
        row["max_abs_dp_pu"] = float(np.nanmax(np.abs(p - validation.p_true_pu)))
        row["n_failed"] = int((~np.isfinite(v.to_numpy(dtype=float))).sum())
        rows.append(row)
    return pd.DataFrame(rows).set_index("method")


# ----------------------------------------------------------------- compute
def _columns(df: pd.DataFrame) -> dict[str, np.ndarray]:
    ok = df.converged.to_numpy(dtype=bool)
    return {
        "v": df.v_pu.to_numpy(dtype=float)[ok],
        "p": df.p_meas_pu.to_numpy(dtype=float)[ok],
        "q": df.q_meas_pu.to_numpy(dtype=float)[ok],
    }


def _validation_seed(seed: int) -> int:
    # A seed of its own, derived from the study's: fresh load factors, reproducible.
    return int(np.random.SeedSequence([int(seed), 1]).generate_state(1)[0])


def _fits(cols, priors, smp, seed, kf_process_noise, settings) -> dict[str, Posterior]:
    from loadbayes.baselines.kalman import kalman
    from loadbayes.baselines.least_squares import least_squares
    from loadbayes.fit import accumulate, fit_gram
    from loadbayes.models.zip import ZIPModel

    model = ZIPModel()
    gram = accumulate(model, [cols])
    fits = {}
    for key, scheme in (("gs", "blocked"), ("gs_single", "single-site")):
        fits[key] = fit_gram(
            model,
            gram,
            priors=priors,
            scheme=scheme,
            seed=seed,
            observed=cols,
            settings=settings,
            **smp,
        )
    fits["ls"] = least_squares(model, gram, seed=seed)
    free = ZIPModel(p0="auto", q0="auto")
    fits["ls3"] = least_squares(free, accumulate(free, [cols]), seed=seed)
    fits["kf"] = kalman(model, cols, process_noise=kf_process_noise, seed=seed)
    fits["kf_rw"] = kalman(model, cols, process_noise=KF_RANDOM_WALK, seed=seed)
    return fits


def _traces(cols, priors, smp, seed) -> dict[str, np.ndarray]:
    """Whole chains of a1 (burn-in included), for the single-site and blocked schemes.

    Same seeds as the fits (the P block is the first child of ``SeedSequence(seed)``), and
    the sampler draws its randomness for every iteration whatever the burn-in, so the
    part after the burn-in is the fitted chain itself.
    """
    from loadbayes.fit import accumulate
    from loadbayes.inference.gibbs import sample_block
    from loadbayes.models.zip import ZIPModel

    model = ZIPModel()
    block = model.blocks[0]
    stats = block.stats(accumulate(model, [cols]))
    out = {}
    for scheme in ("single-site", "blocked"):
        child = np.random.SeedSequence(seed).spawn(len(model.blocks))[0]
        res = sample_block(
            stats,
            priors[block.name],
            scheme=scheme,  # type: ignore[arg-type]
            chains=smp["chains"],
            draws=smp["draws"],
            burn=0,
            rng=child,
        )
        out[scheme] = res.coef[..., 0]
    return out


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


def _sweep(
    df_all: pd.DataFrame,
    z: np.ndarray,
    *,
    ns: Sequence[int],
    noises: Sequence[float],
    prior,
    smp: Mapping[str, int],
    seed: int,
) -> pd.DataFrame:
    """Posterior sd of a1, a2 on nested prefixes of one set of experiments.

    The noise at level ``s`` is ``s z`` with the same standard normals ``z`` for every
    level (common random numbers: the curves differ by the noise level only).
    """
    from loadbayes.baselines.least_squares import least_squares_block
    from loadbayes.fit import accumulate
    from loadbayes.inference.gibbs import sample_block
    from loadbayes.models.zip import ZIPModel

    model = ZIPModel(with_q=False)
    block = model.blocks[0]
    v = df_all.v_pu.to_numpy(dtype=float)
    p_true = df_all.p_true_pu.to_numpy(dtype=float)
    ok = df_all.converged.to_numpy(dtype=bool)
    rows = []
    for s in noises:
        p = p_true + s * z
        for n in ns:
            keep = ok[:n]
            stats = block.stats(accumulate(model, [{"v": v[:n][keep], "p": p[:n][keep]}]))
            ls = least_squares_block(stats)
            res = sample_block(
                stats,
                prior,
                scheme="blocked",
                chains=smp["chains"],
                draws=smp["draws"],
                burn=smp["burn"],
                rng=np.random.SeedSequence([int(seed), 3, int(n), int(round(s * 1e6))]),
            )
            a1, a2 = res.coef[..., 0].reshape(-1), res.coef[..., 1].reshape(-1)
            rows.append(
                {
                    "noise": s,
                    "n": int(n),
                    "n_used": int(keep.sum()),
                    "a1_mean": float(a1.mean()),
                    "a1_sd": float(a1.std(ddof=1)),
                    "a1_sd_ls": float(np.sqrt(ls.cov[0, 0])),
                    "a2_mean": float(a2.mean()),
                    "a2_sd": float(a2.std(ddof=1)),
                    "a2_sd_ls": float(np.sqrt(ls.cov[1, 1])),
                    "a3_sd": float((a1 + a2).std(ddof=1)),
                    "corr_a1_a2": float(np.corrcoef(a1, a2)[0, 1]),
                }
            )
    return pd.DataFrame(rows)


def needed_n(sweep: pd.DataFrame, targets: Sequence[float] = SD_TARGETS) -> pd.DataFrame:
    """Experiments needed for each sd target at each noise, from the largest n swept."""
    rows = []
    for s, grp in sweep.groupby("noise"):
        last = grp.sort_values("n").iloc[-1]
        row: dict[str, Any] = {"noise": float(s), "from_n": int(last.n_used)}
        for t in targets:
            row[f"n_for_sd_{t:g}"] = required_n(last.a1_sd_ls, int(last.n_used), t)
        rows.append(row)
    return pd.DataFrame(rows)


def run(
    n: int | None = None,
    noise: float = 0.1,
    seed: int = 0,
    quick: bool = False,
    *,
    sweep_n: Sequence[int] | None = None,
    sweep_noise: Sequence[float] = SWEEP_NOISE,
    n_validation: int | None = None,
    predictive_experiments: int | None = None,
    predictive_draws: int | None = None,
    sampler: Mapping[str, int] | None = None,
    kf_process_noise: float = 0.0,
    workers: int = 1,
    engine: str = "newton",
    progress: Callable[[str], None] | None = None,
    pf_progress: bool = False,
) -> ZipStudy:
    """Run the ZIP study: data, fits, validation, predictive band and sweep.

    Parameters
    ----------
    n : int, optional
        Experiments fitted (the paper does not give its n): 1,000, or 300 with ``quick``.
    noise : float
        Noise sd on P and Q in per unit of P0 and Q0 (the paper's "10%" read as sd 0.1).
    seed : int
        Seed of the data (load factors and noise) and of the samplers; the validation
        experiments get a seed derived from it.
    quick : bool
        Small settings (:data:`QUICK`) for ``make demo`` and tests; else :data:`FULL`.
    sweep_n : sequence of int, optional
        Experiment counts of the sweep (nested prefixes of one generated set).
    sweep_noise : sequence of float
        Noise levels of the sweep.
    n_validation : int, optional
        Fresh experiments of the validation (100, as the paper).
    predictive_experiments, predictive_draws : int, optional
        Size of the posterior-predictive power flow (first experiments x draws).
    sampler : mapping, optional
        Overrides ``draws`` (iterations including burn-in), ``burn``, ``chains``.
    kf_process_noise : float
        Process noise of Table II's Kalman filter (0: constant coefficients).
    workers : int
        Processes for the power flows; the numbers do not depend on it.
    engine : {"newton", "recycle", "runpp"}
        Power-flow engine (:class:`loadbayes.cases.ieee33.Feeder33`). Only ``"newton"``
        takes shares with a1 + a2 > 1 (a negative constant-power share), which posterior
        draws on the a1-a2 ridge often have; pandapower's ``runpp`` refuses them.
    progress : callable, optional
        Called with a short message before each step.
    pf_progress : bool
        Progress bars of the power flows on stderr (needs ``tqdm``).

    Returns
    -------
    ZipStudy
    """
    from loadbayes.cases import ieee33
    from loadbayes.fit import prior_settings
    from loadbayes.models.zip import ZIPModel

    cfg = dict(QUICK if quick else FULL)
    for key, val in (
        ("n", n),
        ("sweep_n", sweep_n),
        ("n_validation", n_validation),
        ("predictive_experiments", predictive_experiments),
        ("predictive_draws", predictive_draws),
    ):
        if val is not None:
            cfg[key] = val
    smp = {k: int(cfg[k]) for k in ("draws", "burn", "chains")}
    smp.update({k: int(v) for k, v in (sampler or {}).items()})
    n_main = int(cfg["n"])
    ns = sorted({int(x) for x in cfg["sweep_n"]})
    if n_main < 10 or (ns and ns[0] < 10):
        raise ValueError("n and every sweep n must be at least 10")
    if not noise > 0:
        raise ValueError(f"noise must be positive (the posterior needs noise), got {noise}")
    if any(not s > 0 for s in sweep_noise):
        raise ValueError("sweep noise levels must be positive")
    n_val = int(cfg["n_validation"])
    n_pred = min(int(cfg["predictive_experiments"]), n_val)
    if n_val < 1 or n_pred < 1 or int(cfg["predictive_draws"]) < 1:
        raise ValueError("validation and predictive sizes must be at least 1")
    if smp["burn"] >= smp["draws"]:
        raise ValueError(f"burn ({smp['burn']}) must be smaller than draws ({smp['draws']})")
    say = progress or (lambda _msg: None)
    timings: dict[str, float] = {}

    n_gen = max([n_main, *ns])
    say(f"zip: {n_gen} power flows of the 33-bus feeder (seed {seed}) ...")
    t0 = time.perf_counter()
    df_all = ieee33.generate_experiments(
        n_gen,
        noise_sd=noise,
        seed=seed,
        workers=workers,
        progress=pf_progress,
        engine=engine,  # type: ignore[arg-type]
    )
    timings["generate_s"] = time.perf_counter() - t0
    # The standard normals of the P noise, recovered to scale them to the sweep's levels.
    z = ((df_all.p_meas_pu - df_all.p_true_pu) / noise).to_numpy(dtype=float)

    data = df_all.iloc[:n_main].copy()
    data.attrs = dict(df_all.attrs)
    cols = _columns(data)
    n_failed = int((~data.converged).sum())
    if cols["v"].size < 10:
        raise ValueError(f"only {cols['v'].size} of {n_main} power flows converged")
    model = ZIPModel()
    priors = model.default_priors()
    vseed = _validation_seed(seed)
    settings: dict[str, Any] = {
        "study": "zip",
        "bus": 18,
        "pandapower_bus": ieee33.ZIP_BUS,
        "true_zip_p": list(TRUE_ZIP),
        "true_zip_q": list(TRUE_ZIP),
        "factor_range": list(ieee33.FACTOR_RANGE),
        "noise_sd_pu": noise,
        "noise_on": "P and Q (sd in per unit of P0, Q0); V exact",
        "data_seed": seed,
        "p0_mw": df_all.attrs["p0_mw"],
        "q0_mvar": df_all.attrs["q0_mvar"],
    }

    say(f"zip: fitting GS (blocked, single-site), LS, KF on n = {n_main} ...")
    t0 = time.perf_counter()
    fits = _fits(cols, priors, smp, seed, kf_process_noise, settings)
    traces = _traces(cols, priors, smp, seed)
    timings["fit_s"] = time.perf_counter() - t0

    estimates = {m: _point(fits[m]) for m in METHODS}
    t0 = time.perf_counter()
    validation, vinfo = _validation(
        fits,
        estimates,
        vseed=vseed,
        n_validation=n_val,
        n_pred=n_pred,
        m_draws=int(cfg["predictive_draws"]),
        seed=seed,
        engine=engine,
        workers=workers,
        pf_progress=pf_progress,
        say=say,
    )
    timings["validation_s"] = time.perf_counter() - t0

    say(f"zip: sweep over n = {ns} and noise = {list(sweep_noise)} ...")
    t0 = time.perf_counter()
    sweep = _sweep(
        df_all, z, ns=ns, noises=list(sweep_noise), prior=priors["p"], smp=smp, seed=seed
    )
    timings["sweep_s"] = time.perf_counter() - t0

    flows = n_gen + vinfo["power_flows"]
    full_settings = {
        **settings,
        "n": n_main,
        "n_used": int(cols["v"].size),
        "n_failed": n_failed,
        "n_generated": n_gen,
        "n_failed_generated": int(df_all.attrs["n_failed"]),
        "v_range_pu": [float(cols["v"].min()), float(cols["v"].max())],
        "quick": quick,
        "sampler": smp,
        "priors": prior_settings(priors),
        "priors_text": "a1, a2 (a4, a5) ~ N(0, 10^2) independent; tau ~ Gamma(1e-3, rate 1e-9)",
        "init": "a draw from the prior (the paper's Algorithm 1)",
        "kalman": (
            f"state (a1, a2), x0 = 0, P0 = 100 I, R = LS residual variance, "
            f"Q = {kf_process_noise:g} (Table II) and {KF_RANDOM_WALK:g} (random walk)"
        ),
        "kf_process_noise": kf_process_noise,
        "kf_random_walk": KF_RANDOM_WALK,
        "sweep_n": ns,
        "sweep_noise": list(sweep_noise),
        "engine": engine,
        "workers": workers,
        **vinfo,
        "power_flows_total": flows,
        "flows_per_second_generate": n_gen / max(timings["generate_s"], 1e-9),
    }
    return ZipStudy(full_settings, data, fits, validation, traces, sweep, timings)


def _point(post: Posterior) -> dict[str, float]:
    if "estimate" in post.settings:
        return {k: float(v) for k, v in post.settings["estimate"].items()}
    return post.mean()


# ------------------------------------------------------------------ tables
def study_table2(study: ZipStudy) -> pd.DataFrame:
    """Table II of the study (rows GS, LS, KF), with the paper's values beside."""
    return table2(study.validation, {m: study.estimate(m) for m in TABLE2_ROWS})


def comparison(study: ZipStudy) -> pd.DataFrame:
    """Every estimator: Table II's measures, a1..a6, and the sd of a1, a2 where it has one."""
    est = {m: study.estimate(m) for m in METHODS}
    t = table2(study.validation, est)
    t.index = list(METHODS)
    t.insert(0, "label", list(METHODS.values()))
    for m in METHODS:
        post = study.fits[m]
        for k in ("a4", "a5", "a6"):
            t.loc[m, k] = est[m][k]
        for k in ("a1", "a2"):
            t.loc[m, f"{k}_sd"] = float(np.std(post.draws[k]))
    t.index.name = "key"
    return t


def sampler_table(study: ZipStudy) -> pd.DataFrame:
    """Single-site against blocked Gibbs on the same data: mean, sd, ESS, R-hat."""
    rows = []
    for m in ("gs_single", "gs"):
        s = study.summary(m)
        for k, r in s.iterrows():
            rows.append(
                {
                    "scheme": "single-site" if m == "gs_single" else "blocked",
                    "parameter": k,
                    "mean": r["mean"],
                    "sd": r["sd"],
                    "hdi_low": r["hdi_low"],
                    "hdi_high": r["hdi_high"],
                    "ess_bulk": r["ess_bulk"],
                    "r_hat": r["r_hat"],
                }
            )
    return pd.DataFrame(rows)


def validation_summary(study: ZipStudy) -> pd.DataFrame:
    """|dV| and |dP| (p.u.; P also in kW) per method: median, mean, 95th percentile, max."""
    val = study.validation
    p0_kw = 1e3 * float(study.settings["p0_mw"])
    rows = []
    for m in METHODS:
        dv = np.abs(val[f"dv_{m}_pu"].to_numpy(dtype=float))
        dp = np.abs(val[f"dp_{m}_pu"].to_numpy(dtype=float))
        rows.append(
            {
                "method": m,
                "dv_median_pu": float(np.nanmedian(dv)),
                "dv_mean_pu": float(np.nanmean(dv)),
                "dv_p95_pu": float(np.nanpercentile(dv, 95)),
                "dv_max_pu": float(np.nanmax(dv)),
                "dp_median_pu": float(np.nanmedian(dp)),
                "dp_mean_pu": float(np.nanmean(dp)),
                "dp_p95_pu": float(np.nanpercentile(dp, 95)),
                "dp_max_pu": float(np.nanmax(dp)),
                "dp_mean_kw": float(np.nanmean(dp)) * p0_kw,
            }
        )
    return pd.DataFrame(rows).set_index("method")


def predictive_summary(study: ZipStudy) -> dict[str, float]:
    """Width of the 95% posterior-predictive band and how often it holds the truth."""
    val = study.validation
    sub = val[val.n_draws_ok >= 0]
    out: dict[str, float] = {"experiments": float(len(sub))}
    for x in ("v", "p"):
        lo, hi = sub[f"{x}_pred_q2.5_pu"], sub[f"{x}_pred_q97.5_pu"]
        t = sub[f"{x}_true_pu"]
        out[f"{x}_width_median_pu"] = float(np.nanmedian(hi - lo))
        out[f"{x}_covers"] = float(((lo <= t) & (t <= hi)).mean())
    return out


def text_tables(study: ZipStudy) -> str:
    """Table II, the coefficients and the sweep as plain text (what the CLI prints)."""
    t2 = study_table2(study)
    cols = [
        "voltage_error_pct",
        "paper_voltage_error_pct",
        "power_error_pct",
        "paper_power_error_pct",
        "a1",
        "a2",
        "a3",
    ]
    st = study.settings
    vs = validation_summary(study).loc[["gs", "ls", "kf"]]
    fmt = {"float_format": lambda x: f"{x:.4g}"}
    need = needed_n(study.sweep)
    return (
        f"ZIP study: n = {st['n_used']} experiments, noise sd {st['noise_sd_pu']:g} p.u., "
        f"seed {st['data_seed']}; validation on {st['n_validation']} fresh experiments\n"
        "Table II (mean |X_est - X_true| / X_true over the validation, %; paper beside)\n"
        + t2[cols].to_string(**fmt)
        + "\n\n|dV| and |dP| at bus 18 (p.u.; paper: about 1e-4 and 1e-3)\n"
        + vs[["dv_median_pu", "dv_max_pu", "dp_median_pu", "dp_max_pu"]].to_string(**fmt)
        + "\n\nSweep: posterior sd of a1 (blocked Gibbs)\n"
        + study.sweep.pivot(index="n", columns="noise", values="a1_sd").to_string(**fmt)
        + "\n\nExperiments needed for sd(a1) = target\n"
        + need.to_string(index=False, float_format=lambda x: f"{x:.3g}")
    )


# ----------------------------------------------------------------- figures
def figures(study: ZipStudy) -> dict[str, Any]:
    """Matplotlib figures, by file stem.

    ``fig2_posterior``, ``fig3_voltage``, ``fig4_dv_dp``, ``fig5_burn_in``,
    ``fig8_errors``, ``pair_a1_a2``, ``sweep``.
    """
    from loadbayes.plots import pyplot

    plt = pyplot()
    out: dict[str, Any] = {}
    gs, single = study.fits["gs"], study.fits["gs_single"]
    n_used = study.settings["n_used"]

    # Fig. 2: posterior histograms.
    fig, axes = plt.subplots(1, 3, figsize=(12, 3.2), constrained_layout=True)
    paper = {**PAPER_MEANS, "a3": 1 - PAPER_MEANS["a1"] - PAPER_MEANS["a2"]}
    for ax, k, true in zip(axes, ("a1", "a2", "a3"), TRUE_ZIP, strict=True):
        x, y = gs.draws[k].reshape(-1), single.draws[k].reshape(-1)
        bins = np.linspace(min(x.min(), y.min()), max(x.max(), y.max()), 100)
        ax.hist(x, bins=bins, density=True, color="#4c72b0", alpha=0.85, label="GS blocked")
        ax.hist(y, bins=bins, density=True, histtype="step", color="#dd8452", label="single-site")
        ax.axvline(true, color="k", ls="--", lw=1, label="true")
        ax.axvline(paper[k], color="#c44e52", ls=":", lw=1.5, label="paper's mean")
        ax.set_title(f"{k}: mean {x.mean():.3f}, sd {x.std():.3f}", fontsize=9)
        ax.set_yticks([])
    axes[0].legend(fontsize=7)
    fig.suptitle(f"Posterior of the P shares (paper Fig. 2), n = {n_used}", fontsize=10)
    out["fig2_posterior"] = fig

    # Fig. 3: V at bus 18, true vs estimated ZIP, and the posterior-predictive band.
    val = study.validation
    e = val.experiment.to_numpy()
    fig, axes = plt.subplots(3, 1, figsize=(10, 8), sharex=True, constrained_layout=True)
    axes[0].plot(e, val.v_true_pu, "--^", ms=4, color="k", lw=0.8, label="true ZIP")
    axes[0].plot(e, val.v_gs_pu, "-", color="#4c72b0", lw=1.2, label="GS estimate")
    axes[0].set_ylabel("V at bus 18 (p.u.)")
    axes[0].legend(fontsize=7)
    sub = val[val.n_draws_ok >= 0]
    for ax, x, unit in ((axes[1], "v", "dV"), (axes[2], "p", "dP")):
        t = sub[f"{x}_true_pu"]
        ax.fill_between(
            sub.experiment,
            sub[f"{x}_pred_q2.5_pu"] - t,
            sub[f"{x}_pred_q97.5_pu"] - t,
            step="mid",
            color="#4c72b0",
            alpha=0.25,
            label="95% posterior-predictive band",
        )
        for m, c, mk, ms in (
            ("gs", "#4c72b0", "o", 5),
            ("ls", "#55a868", "s", 3),
            ("kf", "#c44e52", "x", 3),
        ):
            ax.plot(e, val[f"d{x}_{m}_pu"], mk, ms=ms, mfc="none", color=c, label=TABLE2_ROWS[m])
        ax.axhline(0, color="k", lw=0.6)
        ax.set_ylabel(f"{unit} = est - true (p.u.)")
        ax.legend(fontsize=7, ncol=4)
    axes[2].set_xlabel("validation experiment")
    fig.suptitle(
        "Bus 18 over the validation experiments (paper Fig. 3), with the predictive band",
        fontsize=10,
    )
    out["fig3_voltage"] = fig

    # Fig. 4: |dV| and |dP| distributions (GS).
    fig, axes = plt.subplots(1, 2, figsize=(10, 3.2), constrained_layout=True)
    for ax, x, ref in ((axes[0], "dv", "dv"), (axes[1], "dp", "dp")):
        d = np.abs(val[f"{x}_gs_pu"].to_numpy(dtype=float))
        d = d[np.isfinite(d) & (d > 0)]
        if d.size:
            bins = np.logspace(np.log10(d.min()) - 0.1, np.log10(d.max()) + 0.1, 30)
            ax.hist(d, bins=bins, color="#4c72b0")
        ax.set_xscale("log")
        ax.axvline(PAPER_VALIDATION[ref], color="#c44e52", ls=":", lw=1.5, label="paper, if p.u.")
        if x == "dp":
            # The paper gives no unit for dP; 1e-3 MW is another reading.
            p0 = float(study.settings["p0_mw"])
            ax.axvline(1e-3 / p0, color="#8172b2", ls="--", lw=1.2, label="paper, if MW")
        ax.set_xlabel(f"|{'dV' if x == 'dv' else 'dP'}| (p.u.)")
        ax.legend(fontsize=7)
    axes[0].set_ylabel("experiments")
    fig.suptitle("|dV| and |dP| at bus 18, GS estimate (paper Fig. 4)", fontsize=10)
    out["fig4_dv_dp"] = fig

    # Fig. 5: burn-in, single-site against blocked.
    burn = study.settings["sampler"]["burn"]
    fig, axes = plt.subplots(2, 2, figsize=(12, 5.5), constrained_layout=True)
    for col, scheme in enumerate(("single-site", "blocked")):
        tr = study.traces[scheme]
        for row, stop in enumerate((tr.shape[1], min(2_000, tr.shape[1]))):
            ax = axes[row][col]
            for c in range(tr.shape[0]):
                ax.plot(np.arange(stop), tr[c, :stop], lw=0.4, alpha=0.8)
            ax.axhline(TRUE_ZIP[0], color="k", ls="--", lw=0.8)
            if burn < stop:
                ax.axvline(burn, color="0.4", ls=":", lw=1)
            ax.set_title(
                f"{scheme}: a1, {'all' if row == 0 else 'first'} {stop} iterations", fontsize=9
            )
    axes[1][0].set_xlabel("iteration")
    axes[1][1].set_xlabel("iteration")
    fig.suptitle("Burn-in of a1 from a prior draw (paper Fig. 5); dotted: burn-in end", fontsize=10)
    out["fig5_burn_in"] = fig

    # Fig. 8: error distributions of GS, LS, KF.
    fig, axes = plt.subplots(1, 2, figsize=(10, 3.4), constrained_layout=True)
    for ax, x, name in ((axes[0], "v", "voltage"), (axes[1], "p", "active power")):
        data, labels = [], []
        for m in TABLE2_ROWS:
            rel = 100 * np.abs(val[f"{x}_{m}_pu"] - val[f"{x}_true_pu"]) / val[f"{x}_true_pu"]
            data.append(rel.dropna().to_numpy())
            labels.append(TABLE2_ROWS[m])
        ax.boxplot(data, showfliers=True, showmeans=True)
        ax.set_xticks(range(1, len(labels) + 1), labels)
        for i, m in enumerate(TABLE2_ROWS, start=1):
            v_p = PAPER_TABLE2[TABLE2_ROWS[m]][0 if x == "v" else 1]
            ax.plot([i - 0.3, i + 0.3], [v_p, v_p], color="#c44e52", lw=1.5)
        ax.set_yscale("log")
        ax.set_ylabel(f"|{name} error| (%)")
    axes[1].plot([], [], color="#c44e52", label="paper's mean")
    axes[1].legend(fontsize=7)
    fig.suptitle("Absolute error distributions of GS, LS and KF (paper Fig. 8)", fontsize=10)
    out["fig8_errors"] = fig

    # The a1-a2 ridge.
    fig, ax = plt.subplots(figsize=(5.5, 4.5), constrained_layout=True)
    a1, a2 = gs.draws["a1"].reshape(-1), gs.draws["a2"].reshape(-1)
    idx = np.linspace(0, a1.size - 1, min(a1.size, 4000)).astype(int)
    ax.plot(a1[idx], a2[idx], ".", ms=1.5, alpha=0.4, color="#4c72b0", label="GS draws")
    s1, s2 = single.draws["a1"].reshape(-1), single.draws["a2"].reshape(-1)
    j = np.linspace(0, s1.size - 1, min(s1.size, 4000)).astype(int)
    ax.plot(s1[j], s2[j], ".", ms=1, alpha=0.25, color="#dd8452", label="single-site draws")
    for m, mk in (("ls", "s"), ("kf", "D")):
        est = study.estimate(m)
        ax.plot(est["a1"], est["a2"], mk, ms=6, mfc="none", color="k", label=TABLE2_ROWS[m])
    ax.plot(a1.mean(), a2.mean(), "o", ms=7, mfc="none", color="#4c72b0", label="GS mean")
    ax.plot(*TRUE_ZIP[:2], "k+", ms=12, mew=2, label="true")
    ax.plot(PAPER_MEANS["a1"], PAPER_MEANS["a2"], "x", color="#c44e52", ms=9, label="paper")
    r = np.corrcoef(a1, a2)[0, 1]
    ax.set_xlabel("a1 (Z share)")
    ax.set_ylabel("a2 (I share)")
    ax.set_title(f"The a1-a2 ridge: posterior correlation {r:+.4f}", fontsize=9)
    ax.legend(fontsize=7)
    out["pair_a1_a2"] = fig

    # The sweep.
    sw = study.sweep
    fig, axes = plt.subplots(1, 2, figsize=(11, 4), constrained_layout=True)
    for ax, k in zip(axes, ("a1", "a2"), strict=True):
        for s, grp in sw.groupby("noise"):
            grp = grp.sort_values("n")
            (line,) = ax.plot(grp.n, grp[f"{k}_sd"], "o", label=f"noise {100 * s:g}% (Gibbs)")
            last = grp.iloc[-1]
            nn = np.logspace(np.log10(grp.n.min()), 9, 50)
            ax.plot(
                nn,
                last[f"{k}_sd_ls"] * np.sqrt(last.n_used / nn),
                "-",
                lw=0.8,
                color=line.get_color(),
            )
        for t in SD_TARGETS:
            ax.axhline(t, color="0.5", ls=":", lw=0.8)
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel("experiments n")
        ax.set_ylabel(f"posterior sd of {k}")
        ax.set_title(f"sd of {k}: points Gibbs, lines LS standard error ~ 1/sqrt(n)", fontsize=9)
    axes[0].legend(fontsize=7)
    fig.suptitle(
        "How much data the paper's precision takes (dotted: sd 0.01 and 0.001)", fontsize=10
    )
    out["sweep"] = fig
    return out


def _png(fig: Any) -> bytes:
    from loadbayes.plots import pyplot

    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=100, bbox_inches="tight")
    pyplot().close(fig)
    return buf.getvalue()


# -------------------------------------------------------------------- html
def _needed_at(study: ZipStudy, noise: float) -> dict[str, float]:
    """Experiments for sd(a1) = each target at ``noise``, from the sweep's largest n.

    The sweep level nearest ``noise`` is scaled by ``(noise / level)^2`` (sd is
    proportional to the noise sd).
    """
    need = needed_n(study.sweep)
    k = int(np.argmin(np.abs(np.log(need.noise.to_numpy() / noise))))
    row = need.iloc[k]
    scale = (noise / float(row.noise)) ** 2
    return {f"{t:g}": float(row[f"n_for_sd_{t:g}"]) * scale for t in SD_TARGETS}


def _sentences(study: ZipStudy) -> list[str]:
    """One sentence (or a few) on each difference between the paper and this run."""
    st = study.settings
    noise = float(st["noise_sd_pu"])
    gs = study.fits["gs"]
    m1, m2 = float(gs.draws["a1"].mean()), float(gs.draws["a2"].mean())
    s1, s2 = float(gs.draws["a1"].std()), float(gs.draws["a2"].std())
    r = float(np.corrcoef(gs.draws["a1"].reshape(-1), gs.draws["a2"].reshape(-1))[0, 1])
    need = _needed_at(study, noise)
    need_1pct = _needed_at(study, 0.01)
    t2 = study_table2(study)
    vs = validation_summary(study)
    samp = sampler_table(study)
    a1_rows = samp[samp.parameter == "a1"].set_index("scheme")
    ess_s, ess_b = float(a1_rows.ess_bulk["single-site"]), float(a1_rows.ess_bulk["blocked"])
    rhat_s = float(a1_rows.r_hat["single-site"])
    kept = st["sampler"]["chains"] * (st["sampler"]["draws"] - st["sampler"]["burn"])
    pred = predictive_summary(study)
    p0_kw = 1e3 * float(st["p0_mw"])
    lo, hi = st["v_range_pu"]
    out = [
        f"<b>Posterior means.</b> Paper: a1 = 0.25, a2 = 0.249, with n, prior and number "
        f"of chains not given. Measured at n = {st['n_used']}, noise sd {noise:g}: a1 = "
        f"{m1:.3f} &plusmn; {s1:.3f}, a2 = {m2:.3f} &plusmn; {s2:.3f} (mean &plusmn; sd), "
        f"correlation {r:+.4f}. Over bus-18 voltages of {lo:.2f}-{hi:.2f} p.u., "
        "x<sup>2</sup> - 1 is nearly proportional to x - 1, so the data pin down one "
        "combination of a1 and a2 and leave the other almost free: the posterior is a "
        "ridge"
        + (
            f", and at an sd of {s1:.2g} a mean within 0.001 of the truth would be luck, "
            "not precision."
            if s1 > 0.01
            else "."
        ),
        f"<b>What the paper's digits would need.</b> With a weak prior the sd of a1 falls "
        f"as 1/&radic;n (sweep figure). At noise sd {noise:g}, sd(a1) = 0.01 needs about "
        f"{need['0.01']:.2g} experiments, and sd(a1) = 0.001 (the third decimal of 0.249) "
        f"about {need['0.001']:.2g}; at 1% noise {need_1pct['0.01']:.2g} and "
        f"{need_1pct['0.001']:.2g}. The other way is an informative prior on a1 (or a2) "
        "about as narrow as the claimed precision and centred on the truth, i.e. knowing "
        "the answer. The paper states neither its n nor its prior, so its 0.25 and 0.249 "
        "cannot be reproduced as a measured precision.",
    ]
    dv_med, dp_med = vs.loc["gs", "dv_median_pu"], vs.loc["gs", "dp_median_pu"]
    out.append(
        f"<b>Validation.</b> Paper: |dV| about 1e-4 and |dP| about 1e-3 (no unit given for "
        f"P). Measured with the GS mean on {st['n_validation']} fresh experiments: median "
        f"|dV| {dv_med:.2g} p.u. (max {vs.loc['gs', 'dv_max_pu']:.2g}), median |dP| "
        f"{dp_med:.2g} p.u. of P0, i.e. {dp_med * p0_kw / 1e3:.2g} MW (P0 = {p0_kw:g} kW; max "
        f"{vs.loc['gs', 'dp_max_pu']:.2g} p.u.). "
        + " ".join(
            f"{name} is of the paper's order."
            if 0.2 <= val / PAPER_VALIDATION[key] <= 5
            else f"{name} is {val / PAPER_VALIDATION[key]:.2g} times the paper's."
            for name, key, val in (("|dV|", "dv", dv_med), ("|dP| in p.u.", "dp", dp_med))
        )
        + " "
        + "The power flow only sees the ZIP curve over the voltages the data cover, and "
        "moving along the ridge barely changes it there: that is why coefficients off by "
        "tenths still predict V and P closely."
    )
    gsv, lsv, kfv = (float(t2.loc[k, "voltage_error_pct"]) for k in ("GS", "LS", "KF"))
    gsp, lsp, kfp = (float(t2.loc[k, "power_error_pct"]) for k in ("GS", "LS", "KF"))
    spread = max(
        max(gsv, lsv, kfv) / min(gsv, lsv, kfv) - 1, max(gsp, lsp, kfp) / min(gsp, lsp, kfp) - 1
    )
    out.append(
        f"<b>Table II.</b> Paper (V %, P %): GS 0.007 / 1.12, LS 0.062 / 4.65, KF 0.024 / "
        f"2.64. Measured: GS {gsv:.3g} / {gsp:.3g}, LS {lsv:.3g} / {lsp:.3g}, KF {kfv:.3g} / "
        f"{kfp:.3g}"
        + (
            f", the three within {100 * spread:.2g}% of each other. "
            if spread < 0.2
            else f"; they differ by up to {100 * spread:.2g}%. "
        )
        + "With a weak prior the posterior mean of this linear-Gaussian model is the "
        "least-squares estimate, and a Kalman filter without process noise is recursive "
        "least squares from a diffuse start; on the same data they must agree up to Monte "
        "Carlo error and the prior's slight pull, so the paper's ranking (LS 4 to 9 times "
        "worse than GS) cannot come from the estimators themselves. It has to come from "
        "what the paper does not give: Matlab's fit options, the KF tuning of its ref. "
        "[26], the data each method saw, the definition of the error. Ours is defined "
        "above."
    )
    comp = comparison(study)
    l3v, l3p = (
        float(comp.loc["ls3", "voltage_error_pct"]),
        float(comp.loc["ls3", "power_error_pct"]),
    )
    p0_hat = study.estimate("ls3").get("p0", float("nan"))
    out.append(
        "<b>A reading of the paper's LS row.</b> Least squares with three free "
        f"coefficients (a quadratic fit, as Matlab's fit would do) puts P at V = 1 at "
        f"{p0_hat:.3g} P0 by extrapolation; normalised to shares that sum to one and used "
        f"with the feeder's P0, it gives V {l3v:.3g}% and P {l3p:.3g}%"
        + (
            ", many times the constrained fit's errors and of the order of the paper's LS "
            "row. That is one way the paper's LS could have come out worst; the paper does "
            "not say what it did."
            if l3p > 3 * gsp
            else "."
        )
    )
    if ess_s < 0.05 * ess_b:
        burn_text = (
            f"the paper's one-at-a-time scheme crawls along the ridge (ESS {ess_s:.0f}, "
            f"R-hat {rhat_s:.3f}): its chains take thousands of iterations to leave their "
            "starting points and then drift slowly, so after the paper's M = 40,000 its "
            f"histogram still rests on about {ess_s:.0f} independent draws"
            if st["sampler"]["draws"] >= 40_000
            else f"the paper's one-at-a-time scheme crawls along the ridge (ESS "
            f"{ess_s:.0f}, R-hat {rhat_s:.3f})"
        )
    else:
        burn_text = f"the single-site scheme reaches ESS {ess_s:.0f}"
    out.append(
        "<b>Burn-in.</b> Paper (Fig. 5): no significant burn-in. Measured from a prior draw "
        f"(a1, a2 ~ N(0, 10<sup>2</sup>)): the blocked sampler is on the ridge after one "
        f"iteration (ESS of a1 {ess_b:.0f} of {kept} kept draws); {burn_text}. A start "
        "near the truth, or a narrow prior, hides this."
    )
    out.append(
        f"<b>Posterior-predictive power flow</b> (beyond the paper): "
        f"{st['predictive_draws']} posterior draws on each of "
        f"{st['predictive_experiments']} validation experiments give a 95% band of median "
        f"width {pred['v_width_median_pu']:.2g} p.u. in V and {pred['p_width_median_pu']:.2g}"
        f" p.u. in P; it holds the true V in {100 * pred['v_covers']:.0f}% and the true P "
        f"in {100 * pred['p_covers']:.0f}% of them (one posterior for all, so these move "
        "together rather than being independent 95% events)."
    )
    out.append(
        f"<b>Noise.</b> The paper's N(0, 0.1) is read as a standard deviation of {noise:g} "
        "p.u. of P0 and Q0 on P and Q (a variance of 0.1 would be sd 0.32); V is taken as "
        "exact, which the paper does not say."
    )
    return out


def _html_table(df: pd.DataFrame, *, index: bool = False) -> str:
    def fmt(x: Any) -> str:
        if isinstance(x, (bool, np.bool_)):
            return "yes" if x else "no"
        if isinstance(x, (float, np.floating)):
            return f"{x:.4g}" if np.isfinite(x) else "n/a"
        return str(x)

    return df.to_html(index=index, formatters=dict.fromkeys(df.columns, fmt), border=0)


def html_section(study: ZipStudy, pngs: Mapping[str, bytes] | None = None) -> str:
    """The ZIP section of the report: settings, tables, figures and the comparison.

    Parameters
    ----------
    study : ZipStudy
        The study.
    pngs : mapping of str to bytes, optional
        PNG bytes of :func:`figures` by name (rendered here when not given).

    Returns
    -------
    str
        A ``<section id="zip">`` fragment with the figures embedded as base64 PNG.
    """
    if pngs is None:
        pngs = {k: _png(f) for k, f in figures(study).items()}
    st = study.settings
    smp = st["sampler"]
    fail = st["failed"]
    settings = [
        f"feeder: pandapower case33bw; ZIP load (P and Q: {TRUE_ZIP}) at bus 18 (pandapower "
        f"bus {st['pandapower_bus']}), P0 = {1e3 * st['p0_mw']:g} kW, Q0 = "
        f"{1e3 * st['q0_mvar']:g} kvar; every other load times its own U"
        f"[{st['factor_range'][0]:g}, {st['factor_range'][1]:g}] factor",
        f"n = {st['n']} experiments fitted ({st['n_used']} converged), the first {st['n']} "
        f"of {st['n_generated']} generated (the sweep uses nested prefixes of the same "
        f"set); bus-18 voltage {st['v_range_pu'][0]:.3f}-{st['v_range_pu'][1]:.3f} p.u.",
        f"noise: sd {st['noise_sd_pu']:g} p.u. on {st['noise_on']}",
        f"seeds: data {st['data_seed']}, validation {st['validation_seed']}, samplers "
        f"{st['data_seed']}",
        f"priors: {st['priors_text']}; start: {st['init']}",
        f"Gibbs: {smp['draws']} iterations including {smp['burn']} burn-in (the paper's M "
        f"and m), {smp['chains']} chains; blocked (a1, a2) unless said otherwise",
        f"Kalman filter: {st['kalman']}",
        f"power flows: {st['power_flows_total']} in all; not converged: "
        f"{st['n_failed_generated']} of {st['n_generated']} generated, "
        + ", ".join(f"{k} {v}" for k, v in fail.items())
        + " in the validation (counted and left out, never dropped silently)",
        f"throughput: {st['flows_per_second_generate']:.0f} power flows/s on "
        f"{st['workers']} worker(s), engine {st['engine']!r}",
    ]
    t2 = study_table2(study)
    t2_show = t2[
        [
            "voltage_error_pct",
            "paper_voltage_error_pct",
            "power_error_pct",
            "paper_power_error_pct",
            "a1",
            "a2",
            "a3",
            "a1_err",
            "a2_err",
            "a3_err",
        ]
    ].reset_index()
    comp = comparison(study)
    comp_show = comp[
        ["label", "voltage_error_pct", "power_error_pct", "a1", "a1_sd", "a2", "a2_sd", "a3"]
        + ["a4", "a5", "a6"]
    ]
    vs = validation_summary(study).reset_index()
    samp = sampler_table(study)
    sw = study.sweep[["noise", "n", "n_used", "a1_mean", "a1_sd", "a1_sd_ls", "a2_sd"]]
    sw = sw.assign(corr_a1_a2=study.sweep.corr_a1_a2)
    need = needed_n(study.sweep)

    def img(name: str, alt: str) -> str:
        if name not in pngs:
            return ""
        b64 = base64.b64encode(pngs[name]).decode("ascii")
        return f'<figure><img alt="{alt}" src="data:image/png;base64,{b64}"/></figure>'

    parts = [
        '<section id="zip">',
        "<h2>ZIP load on the IEEE 33-bus feeder: the paper's ZIP study</h2>",
        "<ul>" + "".join(f"<li>{s}</li>" for s in settings) + "</ul>",
        "<h3>Table II: errors in % over the validation experiments, paper beside</h3>",
        "<p>voltage_error_pct = 100 &middot; mean<sub>i</sub> |V<sub>est,i</sub> - "
        "V<sub>true,i</sub>| / V<sub>true,i</sub>, power_error_pct likewise with the active "
        "power of the bus-18 load; <i>true</i> is the power flow with the true ZIP load, "
        "<i>est</i> the one with the estimated ZIP load (P and Q shares) on the same "
        "experiment. a<sub>k</sub>_err = estimate - truth.</p>",
        _html_table(t2_show),
        "<h3>What differs from the paper</h3>",
        "<ul>" + "".join(f"<li>{s}</li>" for s in _sentences(study)) + "</ul>",
        "<h3>Every estimator on the same data</h3>",
        _html_table(comp_show.reset_index()),
        "<h3>Validation: |dV| and |dP| at bus 18 (p.u.)</h3>",
        _html_table(vs),
        img("fig3_voltage", "voltage at bus 18, true and estimated, with predictive band"),
        img("fig4_dv_dp", "distributions of |dV| and |dP|"),
        img("fig8_errors", "error distributions of GS, LS and KF"),
        "<h3>Posterior (Fig. 2) and the a1-a2 ridge</h3>",
        img("fig2_posterior", "posterior histograms of a1, a2, a3"),
        img("pair_a1_a2", "joint draws of a1 and a2"),
        "<h3>Sampler: single-site (the paper's) against blocked (Fig. 5)</h3>",
        _html_table(samp),
        img("fig5_burn_in", "burn-in traces"),
        "<h3>Sweep: posterior sd of a1 and a2 against n and noise</h3>",
        "<p>Blocked Gibbs (the study's priors and sampler settings) on nested prefixes of "
        "one set of experiments; a1_sd_ls is the least-squares standard error from the "
        "same sufficient statistics. The needed n is extrapolated from the largest n with "
        "sd &prop; 1/&radic;n.</p>",
        _html_table(sw),
        _html_table(need),
        img("sweep", "posterior sd against n"),
        "</section>",
    ]
    return "\n".join(parts)


# ------------------------------------------------------------------ output
FIGURES = (
    "fig2_posterior",
    "fig3_voltage",
    "fig4_dv_dp",
    "fig5_burn_in",
    "fig8_errors",
    "pair_a1_a2",
    "sweep",
)
TABLES = ("table2.csv", "comparison.csv", "validation.csv", "sweep.csv", "sampler.csv")


def output_paths(root: str | Path) -> list[Path]:
    """Files :func:`write` creates under ``root/zip`` (``report.html`` aside)."""
    d = Path(root) / "zip"
    names = ["experiments.csv", "summary.json", "posterior.nc", "study.json", *TABLES]
    names += [f"{f}.png" for f in FIGURES]
    names.append("section.html")
    return [d / n for n in names]


def _write_text(path: Path, text: str, force: bool) -> None:
    from loadbayes.io.atomic import atomic_write

    with atomic_write(path, force=force, mode="w") as fh:
        fh.write(text)


def _write_bytes(path: Path, data: bytes, force: bool) -> None:
    from loadbayes.io.atomic import atomic_write

    with atomic_write(path, force=force, mode="wb") as fh:
        fh.write(data)


def marked(section: str, mark: str = _MARK) -> str:
    """``section`` between the begin and end markers of ``mark``."""
    from loadbayes.studies.report import marked as _marked

    return _marked(section, mark)


def update_report(path: str | Path, section: str, *, mark: str = _MARK) -> Path:
    """Put ``section`` into the report between the markers of ``mark`` (``update_section``)."""
    from loadbayes.studies.report import update_section

    return update_section(path, section, mark=mark)


def _experiments_csv(study: ZipStudy) -> str:
    d = study.data
    out = pd.DataFrame(
        {
            "experiment": d.experiment,
            "v_pu": d.v_pu,
            "p_true_pu": d.p_true_pu,
            "q_true_pu": d.q_true_pu,
            "p_meas_pu": d.p_meas_pu,
            "q_meas_pu": d.q_meas_pu,
            "converged": d.converged,
            # The load factors of row i are ieee33.draw_factors(N, seed=factor_seed)[i].
            "factor_seed": int(study.settings["data_seed"]),
        }
    )
    return out.to_csv(index=False, float_format="%.17g")


def write(study: ZipStudy, root: str | Path, *, force: bool = False) -> list[Path]:
    """Write ``root/zip/`` (data, summary.json, posterior.nc, tables, figures) and the section.

    Returns
    -------
    list of Path
        Every file written, ``root/report.html`` last.
    """
    root = Path(root)
    d = root / "zip"
    d.mkdir(parents=True, exist_ok=True)
    if not force:
        existing = [p for p in output_paths(root) if p.exists()]
        if existing:
            from loadbayes.io.errors import DataError

            raise DataError("exists; use --force to overwrite", str(existing[0]))
    written: list[Path] = []
    path = d / "experiments.csv"
    _write_text(path, _experiments_csv(study), force)
    written.append(path)
    written.append(study.fits["gs"].to_json(d / "summary.json", force=force))
    written.append(study.fits["gs"].to_netcdf(d / "posterior.nc", force=force))
    info = {
        "settings": study.settings,
        "timings_s": study.timings,
        "paper": {
            "means": PAPER_MEANS,
            "table2": PAPER_TABLE2,
            "validation": PAPER_VALIDATION,
        },
        "methods": METHODS,
        "estimates": {m: study.estimate(m) for m in METHODS},
        "needed_n": needed_n(study.sweep).to_dict(orient="records"),
        "predictive": predictive_summary(study),
        "error_definition": (
            "voltage_error_pct = 100 * mean_i |V_est,i - V_true,i| / V_true,i over the "
            "validation experiments; power_error_pct likewise with P at bus 18"
        ),
    }
    path = d / "study.json"
    _write_text(path, json.dumps(info, indent=2, allow_nan=False, default=_json) + "\n", force)
    written.append(path)
    tables = {
        "table2.csv": study_table2(study).reset_index(),
        "comparison.csv": comparison(study).reset_index(),
        "validation.csv": study.validation,
        "sweep.csv": study.sweep,
        "sampler.csv": sampler_table(study),
    }
    for name, df in tables.items():
        _write_text(d / name, df.to_csv(index=False), force)
        written.append(d / name)
    pngs = {k: _png(f) for k, f in figures(study).items()}
    for name, data in pngs.items():
        _write_bytes(d / f"{name}.png", data, force)
        written.append(d / f"{name}.png")
    section = html_section(study, pngs)
    _write_text(d / "section.html", section + "\n", force)
    written.append(d / "section.html")
    written.append(update_report(root / "report.html", section))
    return written


def _json(obj: Any) -> Any:
    if isinstance(obj, np.ndarray):
        return obj.tolist()
    if isinstance(obj, (np.floating, np.integer, np.bool_)):
        return obj.item()
    if isinstance(obj, tuple):
        return list(obj)
    raise TypeError(f"not JSON serialisable: {type(obj).__name__}")
