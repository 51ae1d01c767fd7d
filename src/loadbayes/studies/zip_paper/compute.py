"""The ZIP study's computation: data by power flow, the fits, validation and the sweep.

:func:`run` does the study's steps 1-5 (see :mod:`loadbayes.studies.zip_paper`) and
returns a :class:`~loadbayes.studies.zip_paper.study.ZipStudy`; nothing here draws or
writes.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping, Sequence
from typing import Any

import numpy as np
import pandas as pd

from loadbayes.posterior import Posterior
from loadbayes.studies.zip_paper.study import (
    FULL,
    KF_RANDOM_WALK,
    METHODS,
    QUICK,
    SMOKE,
    SWEEP_NOISE,
    TRUE_ZIP,
    ZipStudy,
)
from loadbayes.studies.zip_paper.validation import _validation


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
    from loadbayes.fit.sampler import MODEL_DEFAULTS
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
            sampler=MODEL_DEFAULTS.with_(seed=seed, **smp),
            observed=cols,
            settings=settings,
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
    from loadbayes.core.settings import SamplerSettings
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
            settings=SamplerSettings(chains=smp["chains"], draws=smp["draws"], burn=0, seed=child),
        )
        out[scheme] = res.coef[..., 0]
    return out


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
    from loadbayes.core.settings import SamplerSettings
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
                settings=SamplerSettings(
                    chains=smp["chains"],
                    draws=smp["draws"],
                    burn=smp["burn"],
                    seed=np.random.SeedSequence([int(seed), 3, int(n), int(round(s * 1e6))]),
                ),
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
    smoke: bool = False,
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
    smoke : bool
        :data:`SMOKE` sizes (a check of the pipeline, not a result) instead of ``quick``'s.

    Returns
    -------
    ZipStudy
    """
    from loadbayes.cases import ieee33
    from loadbayes.fit import prior_settings
    from loadbayes.models.zip import ZIPModel

    cfg = dict(SMOKE if smoke else QUICK if quick else FULL)
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
        "smoke": smoke,
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
