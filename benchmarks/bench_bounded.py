"""Bounded shares against the plain fit: CPU to a converged posterior, per seed (issue 35).

Usage::

    python benchmarks/bench_bounded.py events/event_001.csv --f-hz 50 --seeds 0-4

Each seed fits the event until converged (6,000 iterations, 4,000 burn-in, 4 chains) with
``shares="bounded"`` and then with free shares, in this process (one warm-up fit first,
so numba's compilation is not counted), and prints the CPU seconds of each
``fit_composite`` call (``time.process_time``: every chain's thread, not the machine's
other users), the iterations per chain, the smallest bulk ESS over the reported
quantities and the bounded / plain ratio. The table in docs/composite.md ("Bounded
shares: the rest compiled, the jumps refitted between rounds") is its output on the real
record's first fault. Not part of ``run_all.py`` (it needs an event file: the real
record's, cut by ``loadbayes events``, docs/formats.md).
"""

from __future__ import annotations

import argparse
import time

import arviz as az
import numpy as np

from loadbayes.core.settings import SamplerSettings
from loadbayes.fit.composite import fit_composite
from loadbayes.fit.composite.api import read
from loadbayes.models.zip_motor import CompositeModel


def _seeds(text: str) -> list[int]:
    lo, _, hi = text.partition("-")
    return list(range(int(lo), int(hi or lo) + 1))


def run(model: CompositeModel, events, seed: int) -> tuple[float, int, float]:
    """CPU seconds, iterations per chain and min bulk ESS of one fit until converged."""
    settings = SamplerSettings(draws=6000, burn=4000, chains=4, seed=seed,
                               until_converged=True, max_seconds=1e5)  # fmt: skip
    c0 = time.process_time()
    fit = fit_composite(model, events, sampler=settings)
    cpu = time.process_time() - c0
    post = fit.posterior
    moving = [np.asarray(v) for v in post.draws.values() if np.ndim(v) == 2 and np.std(v) > 0]
    ess = min(float(az.ess(v)) for v in moving)
    return cpu, int(post.settings["until_converged"]["iterations_per_chain"]), ess


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("event")
    ap.add_argument("--f-hz", type=float, default=60.0)
    ap.add_argument("--seeds", default="0-4", help="a range, e.g. 0-4")
    args = ap.parse_args()
    events = read([args.event], f_hz=args.f_hz)
    models = {s: CompositeModel(f_hz=args.f_hz, shares=s) for s in ("bounded", "free")}
    warm = SamplerSettings(draws=120, burn=60, chains=2, seed=99, until_converged=False)
    for m in models.values():
        fit_composite(m, events, sampler=warm)
    for seed in _seeds(args.seeds):
        b = run(models["bounded"], events, seed)
        p = run(models["free"], events, seed)
        print(f"seed {seed}: bounded {b[1]:>7,} iterations, CPU {b[0]:6.1f} s, min ESS "
              f"{b[2]:5.0f} | plain {p[1]:>7,} iterations, CPU {p[0]:6.1f} s, min ESS "
              f"{p[2]:5.0f} | bounded / plain {b[0] / p[0]:.1f}", flush=True)  # fmt: skip


if __name__ == "__main__":
    main()
