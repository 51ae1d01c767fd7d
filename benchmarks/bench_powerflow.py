"""Power flows per second on the 33-bus ZIP case, for each engine and worker count.

Usage::

    python benchmarks/bench_powerflow.py            # 2,000 flows per configuration
    python benchmarks/bench_powerflow.py --quick    # 5 flows (a smoke test)

Prints a table and writes ``benchmarks/results/powerflow.json``. Each configuration
solves the same load factors (the paper's U[0.1, 4.5]); timing covers ``run_many``,
including the start of worker processes, but not the one-off build of the feeder and the
numba compilation. ``flows_per_cpu_second`` divides by the CPU time of this process and
its workers, a figure that holds up when other jobs share the machine (the wall-clock
figure does not; the load average at the start is recorded). ``max_dv_pu`` is the
largest difference in V at bus 18 from the ``newton`` engine with one worker.
"""

from __future__ import annotations

import argparse
import datetime
import json
import resource
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_zip import _version, machine  # noqa: E402  (one copy of each)
from loadbayes.cases.ieee33 import Feeder33, draw_factors  # noqa: E402
from loadbayes.io.atomic import atomic_write  # noqa: E402

# newton/1 first: it is the reference for max_dv_pu.
CONFIGS = [("newton", 1), ("newton", 2), ("recycle", 1), ("recycle", 2), ("runpp", 1), ("runpp", 2)]
OUT = Path(__file__).resolve().parent / "results" / "powerflow.json"


def _cpu_seconds() -> float:
    # This process plus its finished children (the pool's workers are joined by then).
    me = resource.getrusage(resource.RUSAGE_SELF)
    kids = resource.getrusage(resource.RUSAGE_CHILDREN)
    return me.ru_utime + me.ru_stime + kids.ru_utime + kids.ru_stime


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="5 flows (a smoke test)")
    parser.add_argument("--n", type=int, default=None, help="flows per configuration")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--output", type=Path, default=OUT)
    args = parser.parse_args(argv)
    n = args.n or (5 if args.quick else 2000)
    factors = draw_factors(n, seed=args.seed)

    info = {
        "date": datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds"),
        "machine": machine(),
        "versions": {
            p: _version(p) for p in ("loadbayes", "pandapower", "numpy", "scipy", "pandas", "numba")
        },
        "n_flows": n,
        "seed": args.seed,
        "case": "case33bw, ZIP (0.25, 0.25, 0.5) at bus 18, factors U[0.1, 4.5]",
        "results": [],
    }
    reference = None
    print(f"{n} power flows per configuration")
    head = ("engine", "workers", "seconds", "flows/s", "flows/cpu-s", "failed", "max_dv_pu")
    print("{:<8} {:>7} {:>8} {:>8} {:>11} {:>6} {:>9}".format(*head))
    # The full run measures pandapower's numba kernels, built with the feeder as before
    # the default became automatic; --quick (5 flows) takes the default, SciPy's path,
    # which gives the same numbers without compiling (Feeder33's numba setting).
    numba = None if args.quick else True
    info["numba"] = "default (SciPy below NUMBA_FROM_FLOWS)" if numba is None else numba
    for engine, workers in CONFIGS:
        feeder = Feeder33(engine=engine, numba=numba)
        t0, c0 = time.perf_counter(), _cpu_seconds()
        res = feeder.run_many(factors, workers=workers)
        seconds, cpu = time.perf_counter() - t0, _cpu_seconds() - c0
        if reference is None:
            reference = res["v_pu"]
        row = {
            "engine": engine,
            "workers": workers,
            "seconds": round(seconds, 3),
            "flows_per_second": round(n / seconds, 1),
            "cpu_seconds": round(cpu, 3),
            "flows_per_cpu_second": round(n / cpu, 1),
            "n_failed": int((~res["converged"]).sum()),
            "max_dv_pu": float(np.nanmax(np.abs(res["v_pu"] - reference))),
        }
        info["results"].append(row)
        print(
            f"{engine:<8} {workers:>7} {seconds:>8.2f} {n / seconds:>8.1f} {n / cpu:>11.1f} "
            f"{row['n_failed']:>6} {row['max_dv_pu']:>9.1e}",
            flush=True,
        )
    args.output.parent.mkdir(parents=True, exist_ok=True)
    with atomic_write(args.output, mode="w", force=True) as fh:
        json.dump(info, fh, indent=2)
    print(f"wrote {args.output}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
