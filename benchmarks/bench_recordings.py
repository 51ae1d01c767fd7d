"""Recordings in: how fast COMTRADE files are read and turned into phasors, sags found.

Usage::

    python benchmarks/bench_recordings.py            # 10 min of 3.2 kHz COMTRADE, a day of cycles
    python benchmarks/bench_recordings.py --quick    # 20 s, an hour

Prints a table and writes ``benchmarks/results/recordings.json`` (the run_all contract:
``date``, ``machine``, ``versions``, ``results``). Rows:

- ``comtrade-<format>``: a synthetic 50 Hz three-phase record (6 channels, 64 samples per
  cycle, 1999 revision) written by the test writer, then read (``read_comtrade``:
  ``.cfg`` checks, ``.dat`` checks, the ``comtrade`` package's decoding, scaling), and
  its per-cycle phasors computed (``cycle_phasors``); seconds and samples per second.
- ``events``: ``find_sags`` on a per-cycle record (50 rows a second) with a sag a minute.
- ``real-xtz``: the State Grid record in ``../shared/real`` (48 analog channels, four
  rate segments; source and licence in its README): ``read_comtrade`` with a bay, then
  ``record_table`` at 4 phasors per cycle, per transformer; and ``loadbayes read
  comtrade`` end to end in a fresh process (imports included); and ``fit_composite`` of
  its first fault at the defaults (issue 20's target: under 20 s on 2 cores). Skipped
  when the record is not beside the repository.
- ``table-<s>s``: ``record_table`` (the least-squares phasors ``read comtrade`` writes)
  on a synthetic single-rate record, 1 and 4 phasors per cycle: its cost per window.
"""

from __future__ import annotations

import argparse
import datetime
import json
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_zip import _version, machine  # noqa: E402

OUT = Path(__file__).resolve().parent / "results" / "recordings.json"
FS = 3200.0


def _best(fn, repeat=3):
    best = float("inf")
    out = None
    for _ in range(repeat):
        t0 = time.perf_counter()
        out = fn()
        best = min(best, time.perf_counter() - t0)
    return best, out


def bench_comtrade(seconds: float, fmt: str, folder: Path) -> dict:
    """Write, read and phasor a record of ``seconds`` in format ``fmt``."""
    from loadbayes.recordings.comtrade import read_comtrade
    from loadbayes.recordings.phasors import cycle_phasors
    from loadbayes.recordings.synth import sag_profile, write_comtrade, zip_waveforms

    t = np.arange(int(seconds * FS)) / FS
    sags = [(s, 0.3, 0.3) for s in np.arange(5.0, seconds - 2, 60.0)]
    v, i = zip_waveforms(t, sag_profile(t, sags, recovery_s=1.0), (0.3, 0.2, 0.5, 0.6, 0.1, 0.3))
    cfg, dat = write_comtrade(folder / f"rec_{fmt}", t, v, i, fmt=fmt, force=True)
    read_s, w = _best(lambda: read_comtrade(cfg))
    ph_s, c = _best(lambda: cycle_phasors(w.t_s, w.v, w.i, f0=50.0, rate_hz=w.rate_hz))
    return {
        "case": f"comtrade-{fmt.lower()}",
        "samples": t.size,
        "dat_mb": round(dat.stat().st_size / 2**20, 1),
        "read_s": round(read_s, 3),
        "phasors_s": round(ph_s, 3),
        "samples_per_s": round(t.size / (read_s + ph_s)),
        "cycles": len(c["t_s"]),
    }


def bench_events(hours: float) -> dict:
    """Find the sags of a per-cycle record of ``hours``."""
    from loadbayes.recordings.events import find_sags
    from loadbayes.recordings.synth import sag_profile

    t = np.arange(int(hours * 3600 * 50)) / 50.0
    sags = [(s, 0.2, 0.25) for s in np.arange(30.0, t[-1] - 5, 60.0)]
    v = sag_profile(t, sags) + np.random.default_rng(0).normal(0, 0.002, t.size)
    sec, ev = _best(lambda: find_sags(t, v))
    return {"case": "events", "samples": t.size, "read_s": None, "phasors_s": None,
            "events_s": round(sec, 3), "events": len(ev), "expected": len(sags)}  # fmt: skip


REAL = next(
    (
        p / "shared" / "real" / "xtz.cfg"
        for p in Path(__file__).resolve().parents
        if (p / "shared" / "real" / "xtz.cfg").is_file()
    ),
    None,
)


def bench_real() -> list[dict]:
    """The shared real record: read + table per transformer, and the CLI in a new process."""
    import subprocess

    from loadbayes.recordings.comtrade import read_comtrade
    from loadbayes.recordings.record import record_table

    rows = []
    for bay in ("1号主变", "2号主变"):
        read_s, w = _best(lambda bay=bay: read_comtrade(REAL, bay=bay))
        table_s, rec = _best(lambda w=w: record_table(w, per_cycle=4))
        rows.append(
            {
                "case": f"real-xtz {bay}",
                "samples": int(w.t_s.size),
                "read_s": round(read_s, 3),
                "table_s": round(table_s, 3),
                "total_s": round(read_s + table_s, 3),
                "rows": rec.rows,
            }  # fmt: skip
        )
    with tempfile.TemporaryDirectory() as tmp:
        cmd = [sys.executable, "-m", "loadbayes", "read", "comtrade", str(REAL),
               "--bay", "1号主变", "--per-cycle", "4", "--out", f"{tmp}/x.parquet",
               "--quiet", "--force"]  # fmt: skip
        cli_s, _ = _best(lambda: subprocess.run(cmd, check=True, capture_output=True))
    rows.append({"case": "real-xtz CLI (fresh process)", "total_s": round(cli_s, 3)})
    rows.append(bench_real_fit())
    return rows


def bench_real_fit() -> dict:
    """The composite fit of the record's first fault (0.38 s at 4 phasors per cycle).

    ``fit_composite`` at its defaults (16,000 iterations, 4,000 burn-in, 4 chains, run on
    until converged) on the event ``read comtrade`` -> ``events`` writes for transformer
    #1: wall and CPU time of one run (after a warm-up that compiles), the iterations per
    chain it took, and the largest R-hat and smallest bulk ESS over **every reported
    quantity** the until-converged rule checks (the motor's, the coefficients and shares,
    the steps' instants: ``free`` and ``coefficients`` of the posterior), with bulk ESS per
    second of each.
    """
    from loadbayes.fit.composite import COMPOSITE_DEFAULTS, fit_composite
    from loadbayes.models.zip_motor import CompositeModel
    from loadbayes.studies.real_record import events_of

    events, _, info = events_of(REAL, "1号主变", per_cycle=4)
    model = CompositeModel(f_hz=info["f_hz"])
    warm = COMPOSITE_DEFAULTS.with_(draws=400, burn=200, seed=1)
    fit_composite(model, events[:1], sampler=warm)  # compile
    t0, c0 = time.perf_counter(), time.process_time()
    post = fit_composite(model, events[:1])  # the defaults, run on until converged
    wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    table = post.posterior.summary()
    # The until-converged rule's quantities (fit/composite/until.py): every reported one
    # that varies (constants have a null R-hat).
    watched = [n for n in dict.fromkeys(post.posterior.free + post.posterior.coefficients)
               if n in table.index and np.isfinite(table.loc[n, "r_hat"])]  # fmt: skip
    ess = float(table.loc[watched, "ess_bulk"].min())
    rounds = post.posterior.settings.get("until_converged", {})
    return {
        "case": "real-xtz fit composite, first fault, defaults",
        "samples": int(events[0].t.size),
        "total_s": round(wall, 2),
        "cpu_s": round(cpu, 2),
        "iterations_per_chain": rounds.get("iterations_per_chain"),
        "rounds": len(rounds.get("rounds", [])),
        "max_rhat": round(float(table.loc[watched, "r_hat"].max()), 4),
        "min_ess_bulk": round(ess),
        "slowest": str(table.loc[watched, "ess_bulk"].idxmin()),
        "ess_per_s": round(ess / wall, 1),
        "ess_per_cpu_s": round(ess / cpu, 1),
    }


def bench_table(seconds: float, folder: Path) -> list[dict]:
    """record_table's least-squares phasors on a synthetic single-rate record."""
    from loadbayes.recordings.comtrade import read_comtrade
    from loadbayes.recordings.record import record_table
    from loadbayes.recordings.synth import sag_profile, write_comtrade, zip_waveforms

    t = np.arange(int(seconds * FS)) / FS
    v, i = zip_waveforms(t, sag_profile(t, [(2.0, 0.3, 0.3)], recovery_s=1.0),
                         (0.3, 0.2, 0.5, 0.6, 0.1, 0.3))  # fmt: skip
    cfg, _ = write_comtrade(folder / "table", t, v, i, fmt="BINARY", force=True)
    w = read_comtrade(cfg)
    rows = []
    for per_cycle in (1, 4):
        sec, rec = _best(lambda pc=per_cycle: record_table(w, per_cycle=pc), repeat=1)
        rows.append(
            {
                "case": f"table-{seconds:g}s per_cycle {per_cycle}",
                "samples": t.size,
                "table_s": round(sec, 3),
                "rows": rec.rows,
                "us_per_window": round(1e6 * sec / rec.rows, 1),
            }  # fmt: skip
        )
    return rows


def main() -> None:
    """Run the benchmark, print the table, write the JSON."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--output", type=Path, default=OUT)
    args = ap.parse_args()
    seconds, hours = (20.0, 1.0) if args.quick else (600.0, 24.0)
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for fmt in ("ASCII", "BINARY", "FLOAT32"):
            rows.append(bench_comtrade(seconds, fmt, Path(tmp)))
        rows += bench_table(min(seconds, 60.0), Path(tmp))
    rows.append(bench_events(hours))
    if REAL is not None:
        rows += bench_real()
    for r in rows:
        print("  ".join(f"{k}={v}" for k, v in r.items()))
    doc = {
        "date": datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds"),
        "machine": machine(),
        "versions": {p: _version(p) for p in ("loadbayes", "numpy", "scipy", "comtrade")},
        "results": rows,
        "notes": [
            f"COMTRADE: {seconds:g} s at {FS:g} Hz, 6 channels; events: {hours:g} h of 50 cycles/s"
        ],  # fmt: skip
    }
    args.output.parent.mkdir(parents=True, exist_ok=True)
    args.output.write_text(json.dumps(doc, indent=2) + "\n")


if __name__ == "__main__":
    main()
