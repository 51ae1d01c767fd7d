"""Chains that run in Python: one thread, two threads, or processes (the default).

Usage::

    python benchmarks/bench_lanes.py [--record CFG] [--output PATH]

The chains of a problem that runs the Python iteration (a model of parts, Student-t
noise) hold the GIL while they do. ``sampler.chain_processes`` runs them in one forked
process per CPU where it may (``core/forked.py``); before, they ran on one thread per CPU,
and on one thread for a short event. This script runs the same fit three ways, each the
whole command in a fresh process (``loadbayes fit composite ... --fixed-draws``, 4
chains, seed 0): ``LOADBAYES_NUM_THREADS=1``, ``=2``, and unset (the processes). Printed
per case: the wall and CPU seconds of each (the command's and its children's, from
``resource.getrusage``), the ratios to the processes, and whether the three JSONs agree
(the draws must not depend on the lanes). The cases:

- the real record's first fault (transformer #1, 4 phasors per cycle, 76 samples; from
  ``$LOADBAYES_REAL_RECORD`` or ``shared/real`` beside the repository, or ``--record``):
  ``slm`` and Student-t ``zip+motor``, 4 x 6,000 (4,000 burn-in), and ``cmld-lite``, 4 x
  1,500 (500);
- a 20 s event at 60/s (1,201 samples; ``loadbayes.cases.composite_sim.simulate_event``, a
  30% sag at 0.5 s): the same, 4 x 1,500 (500).

Writes ``benchmarks/results/lanes.json``, with the load average at the start and end:
the machine may be shared.
"""

from __future__ import annotations

import argparse
import datetime
import json
import os
import platform
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import pandas as pd

HERE = Path(__file__).resolve().parent
MODES = {"one thread": "1", "two threads": "2", "processes": None}


def _children_cpu() -> float:
    use = resource.getrusage(resource.RUSAGE_CHILDREN)
    return use.ru_utime + use.ru_stime


def run_fit(event: Path, out: Path, threads: str | None, *options) -> tuple[float, float, dict]:
    """The fit in a fresh process with ``LOADBAYES_NUM_THREADS`` set (or not)."""
    env = {k: v for k, v in os.environ.items() if k != "LOADBAYES_NUM_THREADS"}
    if threads is not None:
        env["LOADBAYES_NUM_THREADS"] = threads
    args = [
        sys.executable,
        "-m",
        "loadbayes",
        "fit",
        "composite",
        str(event),
        "--json",
        str(out),
        "--quiet",
        "--force",
        "--fixed-draws",
        "--seed",
        "0",
        *map(str, options),
    ]
    cpu, wall = _children_cpu(), time.perf_counter()
    done = subprocess.run(args, env=env, capture_output=True, text=True)  # fmt: skip
    wall, cpu = time.perf_counter() - wall, _children_cpu() - cpu
    if done.returncode != 0:
        raise RuntimeError(f"{' '.join(args)}: {done.stderr[-2000:]}")
    return wall, cpu, json.loads(out.read_text())["parameters"]


def real_event(cfg: Path, folder: Path, bay: str = "1号主变") -> Path:
    """The real record's first fault at ``bay``, cut as a user cuts it."""
    folder = folder / bay
    folder.mkdir(parents=True, exist_ok=True)
    table = folder / "xtz.parquet"
    for args in (
        [
            "read",
            "comtrade",
            cfg,
            "--bay",
            bay,
            "--per-cycle",
            "4",
            "--out",
            table,
            "--quiet",
        ],
        ["events", table, "--out", folder / "events", "--quiet"],
    ):
        subprocess.run([sys.executable, "-m", "loadbayes", *map(str, args)], check=True,
                       capture_output=True)  # fmt: skip
    return folder / "events" / "event_001.csv"


def long_event(folder: Path) -> Path:
    """A 20 s event at 60/s from the package's own simulator (ZIP + one motor)."""
    from loadbayes.cases.composite_sim import simulate_event

    ev, _ = simulate_event("small_industrial", depth=0.3, t_end_s=20.0, fs=60.0, seed=0)
    path = folder / "long.csv"
    pd.DataFrame({"t_s": ev.t, "v": ev.v, "p": ev.p, "q": ev.q}).to_csv(path, index=False)
    return path


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--record", type=Path, default=None, help="the real record's .cfg")
    parser.add_argument("--output", type=Path, default=HERE / "results" / "lanes.json")
    args = parser.parse_args(argv)
    load0 = os.getloadavg()
    started = datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds")
    long_run = ["--draws", 1500, "--burn", 500]
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        cases = []
        from loadbayes.studies.real_record import find_record

        cfg = args.record or find_record(HERE)
        if cfg is not None:
            real = real_event(Path(cfg), folder)
            full = ["--draws", 6000, "--burn", 4000]
            name = "real first fault (76)"
            cases += [(name, real, ["--model", "slm", *full]),
                      (name, real, ["--likelihood", "student-t", *full]),
                      (name, real, ["--model", "cmld-lite", *long_run])]  # fmt: skip
        else:
            print("the real record is not found: its cases are left out", file=sys.stderr)
        long = long_event(folder)
        name = "20 s at 60/s (1,201)"
        cases += [(name, long, ["--model", "slm", *long_run]),
                  (name, long, ["--likelihood", "student-t", *long_run])]  # fmt: skip
        for name, event, options in cases:
            row = {"event": name, "options": " ".join(map(str, options))}
            fits = {}
            for mode, threads in MODES.items():
                wall, cpu, fits[mode] = run_fit(event, folder / "fit.json", threads, *options)
                row[mode] = {"wall_s": round(wall, 2), "cpu_s": round(cpu, 2)}
                print(f"{name}, {row['options']}, {mode}: {wall:.1f} s wall, {cpu:.1f} CPU s",
                      file=sys.stderr)  # fmt: skip
            row["same_json"] = all(f == fits["processes"] for f in fits.values())
            rows.append(row)
    result = {
        "benchmark": "lanes",
        "started": started,
        "machine": f"{platform.machine()}, {os.cpu_count()} CPUs, {platform.platform()}",
        "load_average_at_start": load0,
        "load_average_at_end": os.getloadavg(),
        "rows": rows,
    }
    args.output.parent.mkdir(parents=True, exist_ok=True)
    args.output.write_text(json.dumps(result, indent=1))
    print(
        "| event | options | one thread: wall s (CPU s) | two threads | processes | "
        "one thread / processes | two threads / processes | same JSON |"
    )
    print("| --- | --- | --- | --- | --- | --- | --- | --- |")
    for r in rows:
        cells = [f"{r[m]['wall_s']:.1f} ({r[m]['cpu_s']:.1f})" for m in MODES]
        ratios = [r[m]["wall_s"] / r["processes"]["wall_s"] for m in ("one thread", "two threads")]
        print(
            f"| {r['event']} | `{r['options']}` | {' | '.join(cells)} | "
            f"{ratios[0]:.2f} | {ratios[1]:.2f} | {'yes' if r['same_json'] else 'NO'} |"
        )
    print(
        f"\nload average at start {load0[0]:.1f}, at end {os.getloadavg()[0]:.1f}; "
        f"written {args.output}"
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
