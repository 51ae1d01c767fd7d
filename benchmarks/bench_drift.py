"""ZIP with a drifting load level (``fit zip --level drift``) beside the plain fit.

Usage::

    python benchmarks/bench_drift.py            # a day at 1 s (86,400 rows), a year at
                                                # 1 min (525,600 rows): several minutes
    python benchmarks/bench_drift.py --quick    # a day at 1 min (1,440 rows)

Prints a table and writes ``benchmarks/results/drift.json``.

The data, generated here: a daily load profile (3.2-6.7 MW) times a slow random walk, an
LTC holding the voltage with 0.625% tap steps, a 3% CVR window of 30 minutes each day,
0.3% noise on P and Q; true dP/dV at v0 = 2 a1 + a2 = 1.15 (a1, a2 = 0.4, 0.35).

How it is counted: every row runs in its own Python process (its peak RSS is its own);
imports come before the clock, which covers the one fit call (numba's on-disk cache load
included; the kernels are compiled once beforehand); ``cpu_s`` is the process's CPU time
over all its threads (on a shared machine, ``cpu_s / 2`` is what 2 free cores would
take). ESS is the bulk ESS of dP/dV over
all chains; ESS/s divides it by the wall time. The drift fit runs P and Q, 2 chains (one a
core), with the defaults of ``fit zip --level drift`` (2,500 iterations, 500 burn-in)
unless the row says otherwise; the plain fit is ``fit_zip(..., p0="auto")`` with its
defaults (4 chains x 40,000).
"""

from __future__ import annotations

import argparse
import datetime
import json
import os
import resource
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
from bench_zip import machine  # noqa: E402  (one copy: the machine's description)

OUT = HERE / "results" / "drift.json"
A1, A2 = 0.4, 0.35
TRUE_DPDV = 2 * A1 + A2

CASES = {
    "day-1min": dict(days=1, dt=60.0),
    "day-1s": dict(days=1, dt=1.0),
    "year-1min": dict(days=365, dt=60.0),
}


def feeder(days: int, dt: float, seed: int = 0):
    """Times (s), V (p.u.), P (MW), Q (Mvar) of ``days`` days every ``dt`` seconds."""
    rng = np.random.default_rng(seed)
    per_day = int(round(86_400 / dt))
    n = days * per_day
    t = np.arange(n) * dt
    hour = (t / 3600.0) % 24
    base = 3.2 + 3.5 * np.clip(0.5 - 0.5 * np.cos(2 * np.pi * (hour - 4) / 24), 0, 1) ** 1.5
    level = base * np.exp(np.cumsum(rng.normal(0, 0.002 * np.sqrt(dt / 60), n)))
    v = 1.02 - 0.01 * (base - base.mean()) / base.std()
    # LTC: a tap of 0.625% when the voltage is 0.8% off, then 20 minutes of hold
    hold_steps = max(int(1200 / dt), 1)
    tap, hold, taps = 0.0, 0, np.zeros(n)
    for i in range(n):
        if abs(v[i] + tap - 1.0) > 0.008 and hold <= 0:
            tap -= 0.00625 * np.sign(v[i] + tap - 1.0)
            hold = hold_steps
        hold -= 1
        taps[i] = tap
    v = v + taps + rng.normal(0, 0.0005, n)
    width = max(int(1800 / dt), 2)
    for d in range(days):  # a CVR window each afternoon
        i0 = d * per_day + int(0.55 * per_day)
        v[i0 : i0 + width] -= 0.03
    p = level * (A1 * v**2 + A2 * v + 1 - A1 - A2) * (1 + rng.normal(0, 0.003, n))
    q = 0.4 * level * (2.0 * v**2 + 1.0 * v - 2.0) * (1 + rng.normal(0, 0.003, n))
    return t, v, p, q


def run_row(case: str, method: str) -> dict:
    """One fit in this process: wall time, ESS of dP/dV, peak RSS."""
    from loadbayes import fit_zip
    from loadbayes.core.convergence import summarize
    from loadbayes.core.settings import DataSpec, SamplerSettings
    from loadbayes.fit.drift import fit_zip_drift
    from loadbayes.fit.sampler import MODEL_DEFAULTS

    t, v, p, q = feeder(**CASES[case])
    # compile (or load) the kernels before the clock
    tw, vw, pw, qw = feeder(1, 600.0, seed=9)
    fit_zip_drift(
        {"v": vw, "p": pw}, tw, sampler=SamplerSettings(chains=1, draws=20, burn=10, seed=0)
    )
    t0 = time.perf_counter()
    c0 = time.process_time()
    if method == "drift":
        post = fit_zip_drift(
            {"v": v, "p": p, "q": q},
            t,
            sampler=SamplerSettings(chains=2, draws=2500, burn=500, seed=1),
        )
        settings = "2 chains x 2500 (burn 500), P and Q"
    else:
        post = fit_zip(
            {"v": v, "p": p, "q": q},
            sampler=MODEL_DEFAULTS.with_(seed=1),
            spec=DataSpec(p0=None, q0=None),
            warn=False,
        )
        settings = "4 chains x 40000 (burn 5000), P and Q"
    wall = time.perf_counter() - t0
    cpu = time.process_time() - c0
    d = post.derived["dP/dV"]
    s = summarize(d[None])
    lo, hi = float(s["hdi_low"][0]), float(s["hdi_high"][0])
    return {
        "case": case,
        "n": int(t.size),
        "method": method,
        "settings": settings,
        "wall_s": wall,
        "cpu_s": cpu,
        "dpdv_mean": float(d.mean()),
        "dpdv_low": lo,
        "dpdv_high": hi,
        "covers_true": bool(lo <= TRUE_DPDV <= hi),
        "ess_dpdv": float(s["ess_bulk"][0]),
        "r_hat_dpdv": float(s["r_hat"][0]),
        "ess_per_s": float(s["ess_bulk"][0]) / wall,
        "peak_rss_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024,
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="a day at 1 min only")
    ap.add_argument("--output", default=str(OUT))
    ap.add_argument("--row", nargs=2, metavar=("CASE", "METHOD"), help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.row:
        print(json.dumps(run_row(*args.row)))
        return
    cases = ["day-1min"] if args.quick else ["day-1min", "day-1s", "year-1min"]
    info = {
        "date": datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds"),
        "machine": machine(),
        "versions": {"numpy": np.__version__},
        "results": [],
        "targets": [],
        "notes": [
            f"true dP/dV at v0 = {TRUE_DPDV}; covers_true says whether each 95% interval holds it."
        ],
    }
    print(f"{'case':>10} {'n':>8} {'method':>6} {'wall s':>8} {'dP/dV [95%]':>24} "
          f"{'ESS':>7} {'ESS/s':>8} {'RSS MB':>7}")  # fmt: skip
    for case in cases:
        for method in ("plain", "drift"):
            proc = subprocess.run(
                [sys.executable, __file__, "--row", case, method],
                capture_output=True, text=True, check=False,
            )  # fmt: skip
            if proc.returncode != 0:
                row = {"case": case, "method": method, "error": proc.stderr.strip()[-300:]}
                info["results"].append(row)
                print(case, method, "failed:", row["error"])
                continue
            r = json.loads(proc.stdout.strip().splitlines()[-1])
            info["results"].append(r)
            ci = f"{r['dpdv_mean']:.3f} [{r['dpdv_low']:.3f}, {r['dpdv_high']:.3f}]"
            cells = (f"{case:>10} {r['n']:>8,} {method:>6} {r['wall_s']:>8.2f} {ci:>24} "
                     f"{r['ess_dpdv']:>7.0f} {r['ess_per_s']:>8.1f}")  # fmt: skip
            print(f"{cells} {r['peak_rss_mb']:>7.0f}")
    # the machine is shared: its load over the run says how far wall times are from 2 free cores
    info["machine"]["load_average_at_end"] = list(os.getloadavg())
    rows = {(r["case"], r["method"]): r for r in info["results"] if "wall_s" in r}
    for case, limit, what in (("day-1s", 60.0, "a day at 1 s"),
                              ("year-1min", 30.0, "a year at 1 min")):  # fmt: skip
        r = rows.get((case, "drift"))
        if r is not None:
            info["targets"].append({
                "target": f"{what} with --level drift in < {limit:.0f} s (2 cores)",
                "measured": f"{r['wall_s']:.1f} s ({r['cpu_s']:.1f} s of CPU), ESS(dP/dV) "
                            f"{r['ess_dpdv']:.0f}, covers the truth: {r['covers_true']}",
                "met": r["wall_s"] < limit,
            })  # fmt: skip
    Path(args.output).parent.mkdir(parents=True, exist_ok=True)
    Path(args.output).write_text(json.dumps(info, indent=2) + "\n")
    print(f"wrote {args.output}")


if __name__ == "__main__":
    main()
