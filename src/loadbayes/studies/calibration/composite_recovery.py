"""Recovery of the composite load on simulated events: interval coverage and contraction.

Events are simulated by :func:`loadbayes.cases.composite_sim.simulate_event` (SciPy's
DOP853 on the library motors, independent of the compiled kernel the fit uses), with
the settings of issue 11: the four library motors, ZIP mixes with negative shares, sags
of 15, 30 and 50% held 0.1-0.5 s, noise 0.5-2% of |S0|. Each is fitted by
:func:`loadbayes.fit.composite.fit_composite` and the 95% central interval of every
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
import sys
from typing import Any

import numpy as np

__all__ = ["CHECKED", "recovery_cases", "run_recovery"]

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
)
_MOTORS = ("small_industrial", "large_industrial", "krause_3hp", "krause_2250hp")
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
) -> dict[str, Any]:
    """Fit ``n_events`` simulated events and count interval coverage per quantity.

    Returns
    -------
    dict
        ``coverage`` (fraction of events whose central ``prob`` interval holds the truth,
        per quantity), ``hits`` (per event and quantity), ``contraction`` (per event: the
        posterior sd of f_m and of log T' over its prior sd), ``cases``, ``r_hat_max``.
    """
    from loadbayes.cases.composite_sim import simulate_event
    from loadbayes.fit.composite import fit_composite

    cases = recovery_cases(n_events, seed=seed)
    hits = {k: [] for k in CHECKED}
    contraction, rhat = [], []
    lo_q, hi_q = 50 * (1 - prob), 50 * (1 + prob)
    for i, case in enumerate(cases):
        ev, truth = simulate_event(
            case["motor"],
            depth=case["depth"],
            start_s=0.5,
            duration_s=case["duration_s"],
            recovery_s=case["recovery_s"],
            t_end_s=t_end_s,
            fs=fs,
            t0=case["t0"],
            f_m=case["f_m"],
            q0=case["q0"],
            zip_p=case["zip_p"],
            zip_q=case["zip_q"],
            noise=case["noise"],
            seed=case["seed"],
        )
        fit = fit_composite([ev], draws=draws, burn=burn, chains=chains, seed=seed + i)
        post = fit.posterior
        for k in CHECKED:
            lo, hi = np.percentile(post.draws[k], [lo_q, hi_q])
            hits[k].append(bool(lo <= truth[k] <= hi))
        prior_sd_tp = float(fit.problem.prior.theta_sd[3])
        contraction.append(
            {
                "depth": case["depth"],
                "f_m_sd": float(np.std(post.draws["f_m"])),
                "log_t_prime_sd_over_prior": float(np.std(post.draws["log_t_prime"])) / prior_sd_tp,
            }
        )
        import arviz as az

        rhat.append(float(az.rhat(post.draws["log_t_prime"])))
    return {
        "events": n_events,
        "prob": prob,
        "coverage": {k: float(np.mean(v)) for k, v in hits.items()},
        "hits": hits,
        "contraction": contraction,
        "r_hat_log_t_prime": rhat,
        "cases": cases,
        "settings": {"t_end_s": t_end_s, "fs": fs, "draws": draws, "burn": burn, "chains": chains},
    }


def main(argv: list[str] | None = None) -> int:
    """Command-line entry: run the recovery check and write its JSON."""
    ap = argparse.ArgumentParser(description="Composite-load recovery on simulated events.")
    ap.add_argument("--events", type=int, default=200)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--output", required=True)
    args = ap.parse_args(argv)
    res = run_recovery(args.events, seed=args.seed)
    with open(args.output, "w") as fh:
        json.dump(res, fh, indent=1)
    for k, v in res["coverage"].items():
        print(f"{k:10s} {v:.3f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
