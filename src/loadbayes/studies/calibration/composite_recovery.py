"""Recovery of the composite load on simulated events: interval coverage and contraction.

Events are simulated by :func:`loadbayes.cases.composite_sim.simulate_event` (SciPy's
DOP853 on the library motors, independent of the compiled kernel the fit uses), with
the settings of issue 11: the four library motors, ZIP mixes with negative shares, sags
of 15, 30 and 50% held 0.1-0.5 s, noise 0.5-2% of |S0|. Each is fitted by
:func:`loadbayes.fit.composite.driver.fit_composite` and the 95% central interval of every
reported quantity is checked against the truth.

The truths are not drawn from the fit's prior (they are fixed library motors), so the
coverage need not be exactly 95% for every quantity; a sampler or model that is wrong
(a sign, a time base, a missing factor) shows as coverage far below it.

Run the full check (``make validate``)::

    python -m loadbayes.studies.calibration.composite_recovery \
        --events 200 --output composite_recovery.json
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
import time
from typing import Any

import numpy as np

from loadbayes.models.motor_library import MOTORS

__all__ = ["CHECKED", "CI_SETTINGS", "fit_case", "recovery_cases", "run_recovery"]

#: Quantities whose 95% interval is checked against the truth.
CHECKED: tuple[str, ...] = (
    "p0",
    "q0",
    "a1",
    "a2",
    "a3",
    "a4",
    "a5",
    "a6",
    "f_m",
    "t_prime_s",
    "x_prime",
    "x_open",
    "h_s",
    "rs",
    "t0",
    "mva_m",
    "q_c",
    "t_step0",
)
#: Settings of the CI test (tests/statistical/test_composite_recovery.py): short records
#: at 30 samples/s and short chains, so that 200 events fit in the test-time budget.
CI_SETTINGS: dict[str, Any] = {"t_end_s": 2.0, "fs": 30.0, "draws": 1000, "burn": 400, "chains": 2}
_MOTORS = tuple(MOTORS)
_DEPTHS = (0.15, 0.3, 0.5)


def recovery_cases(n: int, *, seed: int = 0) -> list[dict[str, Any]]:
    """The simulated events' settings: motor and depth cycled, the rest drawn."""
    rng = np.random.default_rng(seed)
    out = []
    for i in range(n):
        a1, a2 = rng.uniform(-0.5, 1.2), rng.uniform(-0.5, 1.0)
        a4, a5 = rng.uniform(-0.5, 1.5), rng.uniform(-0.8, 1.0)
        out.append(
            {
                "motor": _MOTORS[i % 4],
                "depth": _DEPTHS[(i // 4) % 3],
                "duration_s": float(rng.uniform(0.1, 0.5)),
                # The fault's instant, anywhere inside a sample interval (the fit places it).
                "start_s": float(0.5 + rng.uniform(0.0, 0.05)),
                "recovery_s": float(rng.uniform(0.1, 0.4)),
                "noise": float(rng.uniform(0.005, 0.02)),
                "f_m": float(rng.uniform(0.3, 0.7)),
                "t0": float(0.6 * math.exp(rng.uniform(-0.3, 0.3))),
                "q0": float(rng.uniform(0.2, 0.5)),
                "zip_p": (a1, a2, 1.0 - a1 - a2),
                "zip_q": (a4, a5, 1.0 - a4 - a5),
                "seed": int(rng.integers(2**31)),
            }
        )
    return out


def fit_case(case: dict[str, Any], settings: dict[str, Any], seed: int) -> dict[str, Any]:
    """Simulate one case, fit it, and return its interval hits and contraction.

    A module-level function (not a closure) so that a process pool can run it.
    """
    import arviz as az

    from loadbayes.cases.composite_sim import simulate_event
    from loadbayes.core.settings import SamplerSettings
    from loadbayes.fit.composite.driver import fit_composite
    from loadbayes.models.zip_motor import CompositeModel

    cpu = time.process_time()
    drawn = ("depth", "start_s", "duration_s", "recovery_s", "t0", "f_m", "q0", "zip_p")
    drawn += ("zip_q", "noise")
    ev, truth = simulate_event(
        case["motor"],
        t_end_s=settings["t_end_s"],
        fs=settings["fs"],
        seed=case["seed"],
        **{k: case[k] for k in drawn},
    )
    sampler = SamplerSettings(
        draws=settings["draws"],
        burn=settings["burn"],
        chains=settings["chains"],
        seed=seed,
        threads=1,
    )
    fit = fit_composite(CompositeModel(window_s=0), [ev], sampler=sampler)
    post = fit.posterior
    prob = settings["prob"]
    lo_q, hi_q = 50 * (1 - prob), 50 * (1 + prob)
    hits = {}
    for k in CHECKED:
        lo, hi = np.percentile(post.draws[k], [lo_q, hi_q])
        hits[k] = bool(lo <= truth[k] <= hi)
    prior_sd_tp = float(fit.problem.prior.theta_sd[3])
    return {
        "hits": hits,
        "contraction": {
            "depth": case["depth"],
            "f_m_sd": float(np.std(post.draws["f_m"])),
            "log_t_prime_sd_over_prior": float(np.std(post.draws["log_t_prime"])) / prior_sd_tp,
        },
        "r_hat_log_t_prime": float(az.rhat(post.draws["log_t_prime"])),
        "cpu_s": time.process_time() - cpu,
    }


def run_recovery(
    n_events: int,
    *,
    seed: int = 0,
    t_end_s: float = 2.5,
    fs: float = 60.0,
    draws: int = 2500,
    burn: int = 1000,
    chains: int = 2,
    prob: float = 0.95,
    workers: int = 1,
) -> dict[str, Any]:
    """Fit ``n_events`` simulated events and count interval coverage per quantity.

    Parameters
    ----------
    n_events : int
        Events (cases from :func:`recovery_cases`).
    seed : int
        Root seed: the cases' and the fits' (event ``i`` is fitted with ``seed + i``).
    t_end_s, fs : float
        Record length (s) and sampling rate (1/s) of every event.
    draws, burn, chains : int
        Sampler settings of each fit.
    prob : float
        Central interval checked.
    workers : int
        Processes fitting events side by side (each fit uses one thread); the results
        do not depend on it.

    Returns
    -------
    dict
        ``coverage`` (fraction of events whose central ``prob`` interval holds the truth,
        per quantity), ``hits`` (per event and quantity), ``contraction`` (per event: the
        posterior sd of f_m and of log T' over its prior sd), ``cases``, ``r_hat_log_t_prime``,
        ``cpu_s`` (per event).
    """
    cases = recovery_cases(n_events, seed=seed)
    settings = {
        "t_end_s": t_end_s,
        "fs": fs,
        "draws": draws,
        "burn": burn,
        "chains": chains,
        "prob": prob,
    }
    seeds = [seed + i for i in range(n_events)]
    if workers > 1:
        import multiprocessing
        from concurrent.futures import ProcessPoolExecutor

        # forkserver, not fork: the caller may hold threads (a test runner, a Dask
        # client) and forking a threaded process can deadlock.
        ctx = multiprocessing.get_context("forkserver")
        with ProcessPoolExecutor(workers, mp_context=ctx) as pool:
            per = list(pool.map(fit_case, cases, [settings] * n_events, seeds))
    else:
        per = [fit_case(c, settings, s) for c, s in zip(cases, seeds, strict=True)]
    hits = {k: [r["hits"][k] for r in per] for k in CHECKED}
    return {
        "events": n_events,
        "prob": prob,
        "coverage": {k: float(np.mean(v)) for k, v in hits.items()},
        "hits": hits,
        "contraction": [r["contraction"] for r in per],
        "r_hat_log_t_prime": [r["r_hat_log_t_prime"] for r in per],
        "cpu_s": [r["cpu_s"] for r in per],
        "cases": cases,
        "settings": settings,
    }


def main(argv: list[str] | None = None) -> int:
    """Command-line entry: run the recovery check and write its JSON."""
    ap = argparse.ArgumentParser(description="Composite-load recovery on simulated events.")
    ap.add_argument("--events", type=int, default=200)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--output", required=True)
    ap.add_argument("--workers", type=int, default=os.cpu_count() or 1)
    ap.add_argument("--ci", action="store_true", help="the CI test's shorter settings")
    args = ap.parse_args(argv)
    res = run_recovery(
        args.events, seed=args.seed, workers=args.workers, **(CI_SETTINGS if args.ci else {})
    )
    with open(args.output, "w") as fh:
        json.dump(res, fh, indent=1)
    for k, v in res["coverage"].items():
        print(f"{k:10s} {v:.3f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
