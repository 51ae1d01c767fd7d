"""Benchmark: online Bayesian tracking, updates per second (target >= 1e6).

One update = one sample absorbed by :class:`loadbayes.inference.online.OnlineTracker`
with k = 2 coefficients (the ZIP a1, a2 of one channel) and the mean and 95% interval of
three linear functions (a1, a2, a3 = 1 - a1 - a2) written for that sample: what
``loadbayes track zip`` does per sample and channel. Timed for each memory (exact,
forgetting 0.999, window 1000, random-walk drift) on n samples in one call (best of
``--repeat``, after a warm-up that compiles), and streamed in chunks of 10,000 samples
(the per-call overhead of the CLI's chunked reading included). For comparison, the
baselines' Kalman filter (``kalman_block`` with a path, k = 2, marginal sds only).

Writes ``benchmarks/results/online.json`` (or ``--output``) and prints a table.

Run: ``python benchmarks/bench_online.py [--quick] [--n 10000000] [--repeat 3]``.
"""

from __future__ import annotations

import argparse
import datetime
import json
import os
import platform
import sys
import time
from pathlib import Path

import numpy as np

TARGET = 1e6


def _data(n: int, seed: int = 0):
    rng = np.random.default_rng(seed)
    x = rng.uniform(0.66, 0.89, n)
    z = np.ascontiguousarray(np.column_stack([(x - 1) * (x + 1), x - 1]))
    r = z @ np.array([0.25, 0.25]) + rng.normal(0, 0.01, n)
    return z, r


def _best(fn, repeat):
    times = []
    for _ in range(repeat):
        t = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t)
    return min(times)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="n = 200,000, one repeat")
    ap.add_argument("--n", type=int, default=None, help="samples (default 10,000,000)")
    ap.add_argument("--repeat", type=int, default=None)
    ap.add_argument(
        "--output",
        default=str(Path(__file__).resolve().parent / "results" / "online.json"),
        help="result file",
    )
    args = ap.parse_args(argv)
    n = args.n or (200_000 if args.quick else 10_000_000)
    repeat = args.repeat or (1 if args.quick else 3)

    from loadbayes.baselines.kalman import kalman_block
    from loadbayes.inference.online import OnlineTracker, track

    z, r = _data(n)
    contrasts = np.array([[1.0, 0.0], [0.0, 1.0], [-1.0, -1.0]])
    offsets = np.array([0.0, 0.0, 1.0])
    modes = {
        "exact": {},
        "forgetting 0.999": {"forgetting": 0.999},
        "window 1000": {"window": 1000},
        "drift 0.1": {"drift": 0.1},
    }
    results = []
    for name, kw in modes.items():
        track(z[:2000], r[:2000], contrasts=contrasts, offsets=offsets, **kw)  # compile
        whole = _best(lambda kw=kw: track(z, r, contrasts=contrasts, offsets=offsets, **kw), repeat)

        def chunked(kw=kw):
            tr = OnlineTracker(2, contrasts=contrasts, offsets=offsets, **kw)
            for s in range(0, n, 10_000):
                tr.update(z[s : s + 10_000], r[s : s + 10_000])

        chunk = _best(chunked, repeat)
        results.append(
            {
                "method": f"online Bayes, {name}",
                "n": n,
                "seconds": round(whole, 4),
                "updates_per_s": n / whole,
                "seconds_chunked_10k": round(chunk, 4),
                "updates_per_s_chunked_10k": n / chunk,
            }
        )
    m = min(n, 2_000_000)
    kalman_block(z[:1000], r[:1000], measurement_var=1e-4, process_noise=1e-6, return_path=True)
    kf = _best(
        lambda: kalman_block(
            z[:m], r[:m], measurement_var=1e-4, process_noise=1e-6, return_path=True
        ),
        repeat,
    )
    results.append(
        {
            "method": "Kalman filter (baselines.kalman_block, path)",
            "n": m,
            "seconds": round(kf, 4),
            "updates_per_s": m / kf,
            "seconds_chunked_10k": None,
            "updates_per_s_chunked_10k": None,
        }
    )
    online = [x for x in results if x["method"].startswith("online")]
    slowest = min(x["updates_per_s"] for x in online)
    import numba

    out = {
        "date": datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds"),
        "machine": {
            "platform": platform.platform(),
            "processor": platform.processor() or platform.machine(),
            "cpus": os.cpu_count(),
            "load_average": list(os.getloadavg()) if hasattr(os, "getloadavg") else None,
        },
        "versions": {
            "python": platform.python_version(),
            "numpy": np.__version__,
            "numba": numba.__version__,
        },
        "settings": {"n": n, "repeat": repeat, "k": 2, "outputs_per_update": 3},
        "results": results,
        "targets": [
            {
                "target": ">= 1e6 updates per second (every memory, one call)",
                "measured": slowest,
                "met": bool(slowest >= TARGET),
            }
        ],
        "notes": [
            "one update: absorb a sample (k = 2) and write mean, low, high of a1, a2, a3",
            "single thread; the machine may be shared (load average recorded)",
        ],
    }
    path = Path(args.output)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(out, indent=2) + "\n", encoding="utf-8")
    print(f"{'method':<46}{'n':>11}{'updates/s':>14}{'chunked 10k':>14}")
    for x in results:
        ch = x["updates_per_s_chunked_10k"]
        ch_s = f"{ch:14.3g}" if ch else f"{'-':>14}"
        print(f"{x['method']:<46}{x['n']:>11}{x['updates_per_s']:14.3g}{ch_s}")
    print(f"target >= 1e6 updates/s: {'met' if slowest >= TARGET else 'NOT met'} ({slowest:.3g})")
    print(f"written: {path}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
