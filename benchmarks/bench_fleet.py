"""A fleet: per-bus statistics (map-reduce), per-bus fits and the pooled fit, 1 and 2 workers.

Usage::

    python benchmarks/bench_fleet.py                      # 1e4 buses x 1e4 rows (1e8 rows)
    python benchmarks/bench_fleet.py --buses 1000         # a tenth (1e7 rows)
    python benchmarks/bench_fleet.py --data DIR           # reuse (or create) the files

The fleet (``loadbayes.fleet.generate``: 3 classes, per-bus scatter, every bus with
``--rows`` rows) is written once as Parquet files of 100 buses each. Then, for the
in-process engine and for a LocalCluster of 1 and 2 worker processes: the statistics pass
(read + exact per-bus Gram + reduce), then from those statistics the per-bus fits
(4 chains x 2,000 kept draws, 500 burn-in, summaries included) and the pooled fit (same
chain settings). Peak memory is this process's
plus its workers' (psutil). Every engine must give the same table to the last bit.
Writes ``benchmarks/results/fleet.json``.
"""

from __future__ import annotations

import argparse
import datetime
import json
import sys
import tempfile
import time
from pathlib import Path

import pandas as pd

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_zip import PeakRSS, machine  # noqa: E402
from loadbayes.core.settings import SamplerSettings  # noqa: E402
from loadbayes.fleet.engine import Engine  # noqa: E402
from loadbayes.fleet.generate import fleet_truth, write_fleet  # noqa: E402
from loadbayes.fleet.partitions import ReadSpec  # noqa: E402
from loadbayes.fleet.run import fit_fleet, fleet_statistics  # noqa: E402

SAMPLER = SamplerSettings(chains=4, draws=2500, burn=500)


def cpu_seconds() -> float:
    """CPU time (user + system) of this process and of its live children (the workers).

    On a machine shared with other jobs, wall time measures the neighbours too; CPU time
    is what the fleet itself costs (wall time on an idle machine is about CPU time over
    the workers, when the work divides evenly).
    """
    import psutil

    me = psutil.Process()
    procs = [me, *me.children(recursive=True)]
    total = 0.0
    for p in procs:
        try:
            t = p.cpu_times()
        except psutil.Error:
            continue
        total += t.user + t.system
    return total


SPEC = ReadSpec(class_col="customer_class")


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--buses", type=int, default=10_000)
    ap.add_argument("--rows", type=int, default=10_000)
    ap.add_argument("--data", type=str)
    ap.add_argument(
        "--out", type=str, default=str(Path(__file__).parent / "results" / "fleet.json")
    )
    ap.add_argument("--engines", default="inproc,1,2")
    ap.add_argument("--pools", default="none,class")
    args = ap.parse_args()
    tmp = None
    if args.data:
        folder = Path(args.data)
    else:
        tmp = tempfile.TemporaryDirectory()
        folder = Path(tmp.name)
    if not any(folder.glob("*.parquet")):
        t = time.perf_counter()
        write_fleet(fleet_truth(args.buses, seed=0, rows=args.rows), folder, buses_per_file=100)
        print(f"wrote {args.buses} x {args.rows} rows in {time.perf_counter() - t:.1f} s")
    results = []
    tables = {}
    for eng_name in args.engines.split(","):
        workers = None if eng_name == "inproc" else int(eng_name)
        with Engine(workers=workers) as eng:
            row = {"engine": eng_name}
            with PeakRSS() as peak:
                t, c = time.perf_counter(), cpu_seconds()
                stats, model, files = fleet_statistics(str(folder), SPEC, engine=eng)
                row["stats_s"] = time.perf_counter() - t
                row["stats_cpu_s"] = cpu_seconds() - c
            row["stats_peak_mb"] = peak.mb
            for pool in [p for p in args.pools.split(",") if p]:
                with PeakRSS() as peak:
                    t, c = time.perf_counter(), cpu_seconds()
                    table = fit_fleet(stats, model, pool=pool, sampler=SAMPLER, engine=eng)
                row[f"{pool}_fit_s"] = time.perf_counter() - t
                row[f"{pool}_fit_cpu_s"] = cpu_seconds() - c
                row[f"{pool}_peak_mb"] = peak.mb
                tables.setdefault(pool, []).append(table)
            results.append(row)
            print(row, flush=True)
    identical = all(t.equals(ts[0]) for ts in tables.values() for t in ts[1:])
    df = pd.DataFrame(results)
    base = df.set_index("engine")
    eff = {}
    if {"1", "2"} <= set(base.index):
        for col in [c for c in ("stats_s", "none_fit_s", "class_fit_s") if c in base]:
            eff[col] = float(base.loc["1", col] / (2 * base.loc["2", col]))
    print(df.to_string(float_format=lambda x: f"{x:.1f}"))
    print("parallel efficiency on 2 workers:", {k: round(v, 2) for k, v in eff.items()})
    print("identical tables across engines:", identical)
    out = {
        "date": datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds"),
        "machine": machine(),
        "buses": args.buses,
        "rows_per_bus": args.rows,
        "files": files,
        "sampler": {"chains": SAMPLER.chains, "draws": SAMPLER.draws, "burn": SAMPLER.burn},
        "results": results,
        "efficiency_2_workers": eff,
        "identical_across_engines": identical,
        "load_average_at_end": list(__import__("os").getloadavg()),
    }
    Path(args.out).write_text(json.dumps(out, indent=2))
    print("wrote", args.out)


if __name__ == "__main__":
    main()
