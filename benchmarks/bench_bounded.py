"""Bounded shares and AR(1) noise against the plain fit: CPU to a converged posterior (issue 35).

Usage::

    python benchmarks/bench_bounded.py events/event_001.csv --f-hz 50 --seeds 0-4
    python benchmarks/bench_bounded.py events/event_001.csv --f-hz 50 --against ar1 \\
        --model slm

Each seed fits the event until converged at the model's defaults (``zip+motor``: 6,000
iterations, 4,000 burn-in; a model of parts: 16,000, 4,000; 4 chains) with the variant
(``--against bounded``: ``shares="bounded"``, zip+motor only; ``--against ar1``:
``noise="ar1"``) and then plain (free shares, white noise), in this process (one warm-up
fit of each first, so numba's compilation is not counted), and prints the CPU seconds of
each ``fit_composite`` call (``core.forked.cpu_seconds``: every chain's thread or
process, not the machine's other users), the iterations per chain, the smallest bulk ESS
over the reported quantities (and which), and the variant / plain ratio, then the
ratios' median and range and the load average (``os.getloadavg``; the machine may be
shared). ``--fixed-draws`` runs the first round alone (CPU per iteration, where a model
does not converge: the real record's ``cmld-lite``, whose motors' regions do not join,
docs/composite.md). The tables in docs/composite.md ("Bounded shares and AR(1) noise:
where the cost goes") are its output on the real record's first fault. Not part of
``run_all.py`` (it needs an event file: the real record's, cut by ``loadbayes events``,
docs/formats.md).
"""

from __future__ import annotations

import argparse
import os
import statistics

import arviz as az
import numpy as np

from loadbayes.core.forked import cpu_seconds
from loadbayes.core.settings import SamplerSettings
from loadbayes.fit.composite import fit_composite
from loadbayes.fit.composite.api import read
from loadbayes.fit.composite.driver import COMPOSITE_DEFAULTS, PARTS_DEFAULTS
from loadbayes.models.dynamic import dynamic_model
from loadbayes.models.zip_motor import CompositeModel


def _seeds(text: str) -> list[int]:
    lo, _, hi = text.partition("-")
    return list(range(int(lo), int(hi or lo) + 1))


def build(name: str, f_hz: float, variant: str):
    """The model ``name`` plain, or with bounded shares / AR(1) noise."""
    shares = {"shares": "bounded"} if variant == "bounded" else {}
    noise = {"noise": "ar1"} if variant == "ar1" else {}
    if name == "zip+motor":
        return CompositeModel(f_hz=f_hz, **shares, **noise)
    if shares:
        raise SystemExit("--against bounded is a zip+motor option")
    return dynamic_model(name, f_hz=f_hz, **noise)


def run(model, events, seed: int, first: SamplerSettings) -> tuple[float, int, float, str]:
    """CPU seconds, iterations per chain, min bulk ESS and its quantity of one fit."""
    settings = first.with_(seed=seed, max_seconds=1e5)
    c0 = cpu_seconds()
    fit = fit_composite(model, events, sampler=settings)
    cpu = cpu_seconds() - c0
    post = fit.posterior
    ess = {k: float(az.ess(np.asarray(v))) for k, v in post.draws.items()
           if np.ndim(v) == 2 and np.std(v) > 0}  # fmt: skip
    worst = min(ess, key=ess.get)
    rounds = post.settings.get("until_converged")
    its = int(rounds["iterations_per_chain"]) if rounds else settings.draws
    return cpu, its, ess[worst], worst


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("event")
    ap.add_argument("--f-hz", type=float, default=60.0)
    ap.add_argument("--seeds", default="0-4", help="a range, e.g. 0-4")
    ap.add_argument("--against", choices=("bounded", "ar1"), default="bounded")
    ap.add_argument("--model", default="zip+motor", help="zip+motor, slm or cmld-lite")
    ap.add_argument("--fixed-draws", action="store_true",
                    help="the first round only: CPU per iteration, converged or not")  # fmt: skip
    args = ap.parse_args()
    events = read([args.event], f_hz=args.f_hz)
    first = COMPOSITE_DEFAULTS if args.model == "zip+motor" else PARTS_DEFAULTS
    first = first.with_(until_converged=not args.fixed_draws)
    models = {v: build(args.model, args.f_hz, v) for v in (args.against, "plain")}
    warm = SamplerSettings(draws=120, burn=60, chains=2, seed=99, until_converged=False)
    for m in models.values():
        fit_composite(m, events, sampler=warm)
    ratios = []
    print(f"{args.model}, {args.against} against plain; load average "
          f"{os.getloadavg()[0]:.1f}", flush=True)  # fmt: skip
    for seed in _seeds(args.seeds):
        b = run(models[args.against], events, seed, first)
        p = run(models["plain"], events, seed, first)
        ratios.append(b[0] / p[0])
        print(f"seed {seed}: {args.against} {b[1]:>7,} iterations, CPU {b[0]:6.1f} s, min ESS "
              f"{b[2]:5.0f} ({b[3]}) | plain {p[1]:>7,} iterations, CPU {p[0]:6.1f} s, min ESS "
              f"{p[2]:5.0f} ({p[3]}) | ratio {ratios[-1]:.2f}; load {os.getloadavg()[0]:.1f}",
              flush=True)  # fmt: skip
    print(f"{args.against} / plain CPU: median {statistics.median(ratios):.2f}, "
          f"range {min(ratios):.2f}-{max(ratios):.2f}")  # fmt: skip


if __name__ == "__main__":
    main()
