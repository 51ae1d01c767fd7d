"""Benchmark: ``archive scan`` of 1,000 records, ``archive fit`` on 1 and 2 workers.

The records are ``loadbayes example archive``'s (three stations, two bays, 1.1 s at
1200 Hz, ASCII and BINARY): ``--records`` of them are simulated, and each is copied with
one sample changed until there are 1,000, so that every file has its own content hash and
is read in full (the scan's cost is the reading and the per-cycle phasors, not what the
waveforms hold).

The fit: ``N`` usable events with ``zip+motor`` at the command's defaults (6,000 draws
after 4,000 of burn-in, 4 chains; 3,000 after 1,000 x 2 until 30 Nov 2026), once in this
process (an event's chains on the cores, one event at a time) and once on a local Dask
cluster of 2 workers (a core each, an event each); per event the task's own seconds.
Projections: ``200`` events on 2 workers and ``10,000`` on N workers as ``start-up +
events x a worker's seconds per event / N``.

Writes ``benchmarks/results/archive.json``. Run:
``python benchmarks/bench_archive.py [--quick] [--output PATH]``.
"""

from __future__ import annotations

import argparse
import datetime
import json
import os
import platform
import shutil
import sys
import tempfile
import time
from pathlib import Path


def _machine(load: list[float]) -> dict:
    return {"platform": platform.platform(), "cpu": platform.processor() or platform.machine(),
            "cpu_count": os.cpu_count(), "cpus_usable": len(os.sched_getaffinity(0)),
            "load_average_at_start": load, "python": platform.python_version()}  # fmt: skip


def _copies(folder: Path, target: int) -> int:
    """Copy the records until there are ``target``, each with its own recorder name."""
    stems = sorted(
        p.with_suffix("") for p in folder.glob("*.cfg") if p.with_suffix(".dat").exists()
    )
    stems = [s for s in stems if not s.name.startswith(("broken", "no_data"))]
    n, k = len(stems), 0
    while n < target:
        src = stems[k % len(stems)]
        dst = folder / f"{src.name}_c{k:04d}"
        cfg = src.with_suffix(".cfg").read_bytes().replace(b",DFR-", f",C{k:04d}-DFR-".encode(), 1)
        dst.with_suffix(".cfg").write_bytes(cfg)
        shutil.copy(src.with_suffix(".dat"), dst.with_suffix(".dat"))
        n, k = n + 1, k + 1
    return n


def bench_scan(work: Path, records: int, total: int) -> dict:
    from loadbayes.archive import scan
    from loadbayes.cases.archive_example import archive_files

    folder = work / "records"
    folder.mkdir()
    for name, content in archive_files(records=records).items():
        (folder / name).write_bytes(content)
    n = _copies(folder, total)
    c0, t0 = time.process_time(), time.perf_counter()
    out = scan(folder, work / "archive.db")
    wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    c0, t0 = time.process_time(), time.perf_counter()
    again = scan(folder, work / "archive.db")
    rescan = time.perf_counter() - t0
    t0 = time.perf_counter()
    scan(folder, work / "two.db", workers=2)
    two = time.perf_counter() - t0
    return {"records": n, "scan_s": wall, "scan_cpu_s": cpu, "scan_2_workers_s": two,
            "rescan_s": rescan, "events": out.events, "usable": out.usable,
            "broken": out.broken, "rescan_unchanged": again.unchanged}  # fmt: skip


def bench_fit(work: Path, events: int, workers: int | None) -> dict:
    import sqlite3

    from loadbayes.archive import fit

    db = work / f"fit{workers or 1}" / "archive.db"
    db.parent.mkdir()
    shutil.copy(work / "archive.db", db)
    with sqlite3.connect(db) as conn:  # keep the first N usable events
        keep = [
            r[0]
            for r in conn.execute(
                "SELECT event_id FROM events WHERE usable = 1 ORDER BY event_id LIMIT ?", (events,)
            )
        ]
        conn.execute(f"UPDATE events SET usable = 0 WHERE event_id NOT IN "
                     f"({','.join('?' * len(keep))})", keep)  # fmt: skip
    seconds: list[float] = []
    t0 = time.perf_counter()
    run = fit(db, workers=workers, progress=lambda r, *_: seconds.append(r["seconds"]))
    wall = time.perf_counter() - t0
    # Each worker's first event pays the imports and the compilation: left out of the
    # seconds per event (they are in the start-up: the wall time beyond the events').
    warm = sorted(seconds)[: max(len(seconds) - (workers or 1), 1)]
    return {"workers": workers or 1, "events": run.done + run.failed, "failed": run.failed,
            "wall_s": wall, "per_event_s": sum(warm) / len(warm),
            "first_event_s": max(seconds) if seconds else None}  # fmt: skip


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--quick", action="store_true")
    ap.add_argument(
        "--output", type=Path, default=Path(__file__).parent / "results" / "archive.json"
    )
    args = ap.parse_args(argv)
    load = list(os.getloadavg())
    total, simulated, events = (100, 4, 4) if args.quick else (1000, 17, 16)
    with tempfile.TemporaryDirectory() as tmp:
        work = Path(tmp)
        s = bench_scan(work, simulated, total)
        print(f"scan: {s}", flush=True)
        one = bench_fit(work, events, None)
        print(f"fit, 1 process: {one}", flush=True)
        two = bench_fit(work, events, 2)
        print(f"fit, 2 workers: {two}", flush=True)
    # A worker's seconds per event (one core; in this process an event's chains take both).
    per = two["per_event_s"]
    # 200 events on 2 workers: the measured run's start-up (cluster, imports, compilation:
    # its wall time beyond its events' seconds over 2) plus 200 events' seconds over 2.
    startup2 = max(two["wall_s"] - two["events"] * per / 2, 0.0)
    p200 = startup2 + 200 * per / 2
    proj = {n: 10_000 * per / n / 60 for n in (2, 8, 32, 128)}
    targets = [
        {"target": f"archive scan of {s['records']:,} records < 60 s on 2 cores",
         "measured": f"{s['scan_2_workers_s']:.1f} s wall with --workers 2; one process "
                     f"{s['scan_s']:.1f} s wall, {s['scan_cpu_s']:.1f} s CPU; rescan "
                     f"{s['rescan_s']:.1f} s",
         "met": s["scan_2_workers_s"] < 60.0 * s["records"] / 1000},
        {"target": "archive fit of 200 events with zip+motor < 15 min on 2 cores (projected)",
         "measured": f"{p200 / 60:.1f} min: {startup2:.0f} s start-up + 200 x "
                     f"{per:.1f} s / 2 (measured on {two['events']} events, "
                     f"{two['wall_s']:.0f} s)",
         "met": p200 < 900},
    ]  # fmt: skip
    out = {
        "benchmark": "archive",
        "date": datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds"),
        "machine": _machine(load),
        "versions": {"python": sys.version.split()[0]},
        "quick": args.quick,
        "results": [s, one, two],
        "targets": targets,
        "notes": [
            f"fit: {one['per_event_s']:.1f} s per event in one process, its chains on the "
            f"cores ({one['first_event_s']:.1f} s for the first, which compiles and imports); "
            f"{per:.1f} s on a worker's one core; 10,000 events projected at "
            + ", ".join(f"{m:.0f} min on {n} workers" for n, m in proj.items())
            + " (events x seconds per event / workers, start-up aside)",
        ],
    }
    args.output.parent.mkdir(parents=True, exist_ok=True)
    args.output.write_text(json.dumps(out, indent=1) + "\n")
    print(json.dumps(targets, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
