"""A fleet: the statistics pass, per-bus fits and the pooled fit, in process and on 1 and 2 workers.

Usage::

    python benchmarks/bench_fleet.py                        # what run_all.py runs
    python benchmarks/bench_fleet.py --quick                # smoke sizes
    python benchmarks/bench_fleet.py --stats-buses 10000    # the 1e8-row statistics pass

Two fleets (``loadbayes.fleet.generate``: 3 classes, per-bus scatter), written once as
Parquet files of 100 buses each:

- the statistics pass (read + exact per-bus Gram + reduce) on ``--stats-buses`` x
  ``--rows`` rows (default 1e3 x 1e4 = 1e7 rows: 1e8 rows take minutes to write and
  read on a shared 2-core machine; give ``--stats-buses 10000`` for them);
- the fits on ``--fit-buses`` buses (default 1e4) of 100 rows each (a fit costs the same
  whatever the rows: it sees each bus's Gram matrix only): per-bus fits and the pooled
  fit, 4 chains x 2,000 kept draws (500 burn-in), summaries included; P0 and Q0 of every
  bus unknown (``auto``, the CLI's default: the pooled fit samples them), the pooled
  fit's draws streamed to disk (they would take 2.6 GB).

Wall and CPU seconds (this process and its Dask workers, psutil) and peak memory per
stage; every engine must give the same table to the last bit. Writes the JSON of
``run_all.py``'s contract (``--output``).
"""

from __future__ import annotations

import argparse
import datetime
import json
import os
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_zip import PeakRSS, machine  # noqa: E402
from loadbayes.core.settings import SamplerSettings  # noqa: E402
from loadbayes.fleet.engine import Engine  # noqa: E402
from loadbayes.fleet.generate import fleet_truth, write_fleet  # noqa: E402
from loadbayes.fleet.partitions import ReadSpec  # noqa: E402
from loadbayes.fleet.run import fit_fleet, fleet_statistics  # noqa: E402

SPEC = ReadSpec(class_col="customer_class")


def cpu_seconds() -> float:
    """CPU time (user + system) of this process and of its live children (the workers).

    On a machine shared with other jobs, wall time measures the neighbours too; CPU time
    is what the fleet itself costs.
    """
    import psutil

    me = psutil.Process()
    total = 0.0
    for p in [me, *me.children(recursive=True)]:
        try:
            t = p.cpu_times()
        except psutil.Error:
            continue
        total += t.user + t.system
    return total


def _fleet(folder: Path, buses: int, rows: int) -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    if not any(folder.glob("*.parquet")):
        t = time.perf_counter()
        write_fleet(fleet_truth(buses, seed=0, rows=rows), folder, buses_per_file=100)
        print(f"wrote {buses} x {rows} rows in {time.perf_counter() - t:.1f} s", flush=True)
    return folder


def _warm_up(base: Path) -> None:
    """Compile the kernels first (a 12-bus fleet, both pools): numba's cache is per source
    file, so after an edit the first stage measured would include their compilation."""
    folder = _fleet(base / "warm-12", 12, 100)
    stats, model, _ = fleet_statistics(str(folder), SPEC, p0="auto", q0="auto")
    for pool in ("none", "class"):
        fit_fleet(stats, model, pool=pool, sampler=SamplerSettings(chains=2, draws=60, burn=20))


def _measure(row: dict, func):
    row["date"] = datetime.datetime.now(datetime.UTC).isoformat(timespec="minutes")
    row["load_1min"] = os.getloadavg()[0]
    with PeakRSS() as peak:
        t, c = time.perf_counter(), cpu_seconds()
        out = func()
        row["wall_s"] = time.perf_counter() - t
        row["cpu_s"] = cpu_seconds() - c
    row["peak_mb"] = peak.mb
    # What the stage would take on 2 idle cores if its threads (or workers) never waited
    # for each other: a lower bound, not a measurement (labelled so in the notes).
    row["cpu_s_over_2"] = row["cpu_s"] / 2
    print(row, flush=True)
    return out


def _kept_rows(path: Path, results: list[dict]) -> list[dict]:
    """Rows of an earlier run of ``path`` for stages and engines this run did not measure.

    Each keeps its own date (the earlier file's, when the row has none) and says so in
    its engine column, so a table never passes old numbers off as new.
    """
    if not path.exists():
        return []
    old = json.loads(path.read_text())
    done = {(r["stage"], str(r["engine"]).split(" ")[0]) for r in results}
    kept = []
    for r in old.get("results", []):
        if (r["stage"], str(r["engine"]).split(" ")[0]) in done:
            continue
        r = dict(r)
        r.setdefault("date", str(old.get("date", "?"))[:16])
        if "earlier" not in str(r["engine"]):
            r["engine"] = f"{r['engine']} (earlier run)"
        kept.append(r)
    return kept


def fleet_targets(results: list[dict]) -> list[dict]:
    """The issue's targets from the result rows (the largest size of each stage measured,
    on its fastest engine).

    Peak memory is judged on the in-process pooled fit: with workers, the high-water
    marks of the client and of every worker are added up, which says little about
    whether the fit fits in 1 GB.
    """
    targets = []
    for stage in ("statistics", "per-bus fits", "pooled fit"):
        rows = [r for r in results if r["stage"] == stage]
        if not rows:
            continue
        # the largest size measured (the target's), then its fastest engine
        size_of = (lambda r: r["rows"]) if stage == "statistics" else (lambda r: r["buses"])
        largest = max(size_of(r) for r in rows)
        r = min((r for r in rows if size_of(r) == largest), key=lambda r: r["wall_s"])
        size = f"{r['rows']:.0e} rows" if stage == "statistics" else f"{r['buses']:.0e} buses"
        targets.append({
            "target": f"{stage} of {size} < 60 s (2 cores)",
            "measured": f"{r['wall_s']:.1f} s wall ({r['engine']}), {r['cpu_s']:.1f} s CPU",
            "met": r["wall_s"] < 60.0,
        })  # fmt: skip
    own = [
        r for r in results
        if r["stage"] == "pooled fit" and str(r["engine"]).split(" ")[0] == "inproc"
    ]  # fmt: skip
    if own:
        peak = min(r["peak_mb"] for r in own)
        targets.append({
            "target": "pooled fit's peak memory < 1 GB (in process)",
            "measured": f"{peak:.0f} MB",
            "met": peak < 1024,
        })  # fmt: skip
    return targets


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--quick", action="store_true", help="smoke sizes")
    ap.add_argument("--stats-buses", type=int, default=1_000)
    ap.add_argument("--rows", type=int, default=10_000)
    ap.add_argument("--fit-buses", type=int, default=10_000)
    ap.add_argument("--data", type=str, help="folder to keep (or reuse) the fleets in")
    ap.add_argument("--engines", default="inproc,1,2")
    ap.add_argument("--stages", default="stats,none,class")
    ap.add_argument(
        "--keep",
        action="store_true",
        help="keep the output file's rows of stages and engines not measured now (dated)",
    )
    ap.add_argument(
        "--output", type=str, default=str(Path(__file__).parent / "results" / "fleet.json")
    )
    ap.add_argument(
        "--rejudge",
        action="store_true",
        help="measure nothing: recompute the targets of the output file from its rows",
    )
    args = ap.parse_args()
    if args.rejudge:
        path = Path(args.output)
        out = json.loads(path.read_text())
        rows = out["results"]
        new = [r for r in rows if "earlier" not in str(r["engine"])]
        now = {r["stage"] for r in new}
        out["targets"] = fleet_targets(new + [r for r in rows if r["stage"] not in now])
        path.write_text(json.dumps(out, indent=2))
        print("rejudged", path)
        return
    if args.quick:
        args.stats_buses, args.rows, args.fit_buses = 40, 500, 60
        args.engines = "inproc,2"
    sampler = SamplerSettings(chains=4, draws=2500, burn=500)
    if args.quick:
        sampler = SamplerSettings(chains=4, draws=300, burn=100)
    tmp = tempfile.TemporaryDirectory() if not args.data else None
    base = Path(args.data or tmp.name)
    stages = args.stages.split(",")
    _warm_up(base)
    load_start = list(os.getloadavg())
    results, tables = [], {}
    for eng_name in args.engines.split(","):
        workers = None if eng_name == "inproc" else int(eng_name)
        with Engine(workers=workers) as eng:
            if "stats" in stages:
                folder = _fleet(base / f"stats-{args.stats_buses}x{args.rows}", args.stats_buses,
                                args.rows)  # fmt: skip
                row = {"stage": "statistics", "buses": args.stats_buses,
                       "rows": args.stats_buses * args.rows, "engine": eng_name}  # fmt: skip
                _measure(row, lambda f=folder, e=eng: fleet_statistics(str(f), SPEC, engine=e))
                results.append(row)
            fit_stages = [p for p in ("none", "class") if p in stages]
            if fit_stages:
                folder = _fleet(base / f"fit-{args.fit_buses}", args.fit_buses, 100)
                # P0 and Q0 of every bus unknown and sampled, as the CLI's default does
                stats, model, _ = fleet_statistics(str(folder), SPEC, engine=eng, p0="auto",
                                                   q0="auto")  # fmt: skip
            for pool in fit_stages:
                row = {"stage": "per-bus fits" if pool == "none" else "pooled fit",
                       "buses": args.fit_buses, "rows": args.fit_buses * 100,
                       "engine": eng_name}  # fmt: skip
                table = _measure(
                    row,
                    lambda p=pool, e=eng, st=stats, m=model: fit_fleet(
                        st, m, pool=p, sampler=sampler, engine=e
                    ),
                )
                if pool == "class":
                    row["streamed"] = bool(table.attrs["loadbayes"].get("streamed"))
                tables.setdefault(pool, []).append(table)
                results.append(row)
    identical = all(t.equals(ts[0]) for ts in tables.values() for t in ts[1:])
    compared = sum(len(ts) > 1 for ts in tables.values())
    kept = _kept_rows(Path(args.output), results) if args.keep else []
    # stages not measured now are judged on their kept rows (which say "earlier run")
    now = {r["stage"] for r in results}
    targets = fleet_targets(results + [r for r in kept if r["stage"] not in now])
    out = {
        "date": datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds"),
        "machine": {**machine(), "load_average_at_start": load_start},
        "versions": {
            "numpy": __import__("numpy").__version__,
            "dask": __import__("dask").__version__,
        },  # fmt: skip
        "quick": args.quick,
        "sampler": {"chains": sampler.chains, "draws": sampler.draws, "burn": sampler.burn},
        "results": results + kept,
        "targets": targets,
        "notes": [
            (
                f"Identical tables across engines: {identical}."
                if compared
                else "Tables across engines: not compared (one engine measured in this run)."
            )
            + " Load average at start "
            f"{', '.join(f'{x:.1f}' for x in load_start)}, at the end "
            f"{', '.join(f'{x:.1f}' for x in os.getloadavg())}: on a shared machine wall time "
            "measures the neighbours too; CPU seconds are the fleet's own cost. Peak memory "
            "is this process's high-water mark plus its workers' (so it never goes down from "
            "one stage to the next within an engine). The fits run on buses of 100 rows: a "
            "fit sees each bus's Gram matrix only, so its cost does not depend on the rows. "
            "cpu_s_over_2 is CPU / 2: the wall time on 2 idle cores if the stage's threads "
            "never waited for each other (a lower bound, not a measurement); date and "
            "load_1min are each row's own (start of the stage)."
            + (
                " Rows marked (earlier run) are kept from an earlier run of this script "
                "(--keep), with their own dates, for what this run did not measure; a target "
                "is judged on this run's rows when it measured that stage."
                if kept
                else ""
            ),
        ],
    }
    Path(args.output).parent.mkdir(parents=True, exist_ok=True)
    Path(args.output).write_text(json.dumps(out, indent=2))
    print("wrote", args.output)
    if tmp is not None:
        tmp.cleanup()


if __name__ == "__main__":
    main()
