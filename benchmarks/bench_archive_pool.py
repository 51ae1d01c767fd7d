"""``archive pool`` (issue 38): stations' fitted events pooled into seasonal curves.

Usage::

    python benchmarks/bench_archive_pool.py            # 5 stations x 100 events, and more
    python benchmarks/bench_archive_pool.py --quick    # 5 stations x 20 events, 200 draws

Prints a table and writes ``benchmarks/results/archive_pool.json``.

The data, generated here (as ``catalog.fits_frame`` gives them): each station's bay has
a motor share ``base + amp cos(2 pi (d - peak) / 365.25)`` with its own base, amplitude
and peak; an event's share adds logit-normal spread (sd 0.15) and its "fit" a normal
error of known sd in [0.01, 0.05]; 2% of the rows failed and 1% did not converge. The
temperature case reads an hourly table per station: the season, a daily cycle and the
weather (a day-to-day anomaly of sd 3 C); the shares do not depend on it.

How it is counted: every row runs in its own Python process; ``cold_s`` is the first
``pool`` call in it (numba's cached kernels loaded, SciPy's distributions imported),
``warm_s`` a second call on the same frame; both with ``pool``'s defaults (4 chains x
1,000 draws after 500 of burn-in, run one after another in one thread). ``cpu_s`` is
the process's CPU time over the warm call. ``coverage`` is the share of (unit, month)
cells whose 95% band holds the true monthly share.
"""

from __future__ import annotations

import argparse
import datetime
import json
import resource
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
from bench_zip import machine  # noqa: E402  (one copy: the machine's description)

OUT = HERE / "results" / "archive_pool.json"
CASES = {
    "5 stations x 100 events (1 bay)": dict(stations=5, bays=1, events=100, hour=False),
    "5 stations x 2 bays x 100 events": dict(stations=5, bays=2, events=100, hour=False),
    "5 stations x 100 events, hour + temperature": dict(stations=5, bays=1, events=100,
                                                        hour=True),
    "quick: 5 stations x 20 events": dict(stations=5, bays=1, events=20, hour=False),
}  # fmt: skip
_MONTH_START = np.cumsum([0, 31, 28, 31, 30, 31, 30, 31, 31, 30, 31, 30])


def frame(stations: int, bays: int, events: int, hour: bool, seed: int = 0):
    """The fits frame, the temperature table (or None) and the true monthly shares."""
    import pandas as pd

    rng = np.random.default_rng(seed)
    rows, truth = [], {}
    year = pd.Timestamp("2025-01-01")
    for s in range(stations):
        for b in range(bays):
            base, amp, peak = rng.uniform(0.2, 0.4), rng.uniform(0.03, 0.12), rng.uniform(0, 365)

            def curve(d, base=base, amp=amp, peak=peak):
                return base + amp * np.cos(2 * np.pi * (d - peak) / 365.25)

            key = (f"S{s}", f"bay{b}")
            lengths = np.diff(np.append(_MONTH_START, 365))
            truth[key] = [curve(m + np.arange(n) + 0.5).mean()
                          for m, n in zip(_MONTH_START, lengths, strict=True)]  # fmt: skip
            day = rng.uniform(0, 365, events)
            logit = np.log(curve(day) / (1 - curve(day))) + rng.normal(0, 0.15, events)
            sd = rng.uniform(0.01, 0.05, events)
            mean = np.clip(1 / (1 + np.exp(-logit)) + rng.normal(0, sd), 0.002, 0.998)
            u = rng.random(events)
            for i in range(events):
                rows.append({"station": key[0], "bay": key[1], "event_id": f"{key}-{i}",
                             "time": year + pd.Timedelta(days=float(day[i])),
                             "model": "zip+motor", "part": "f_m", "mean": mean[i], "sd": sd[i],
                             "lo": mean[i] - 2 * sd[i], "hi": mean[i] + 2 * sd[i],
                             "rhat": 1.2 if u[i] < 0.01 else 1.0, "ess": 1000.0,
                             "status": "failed: no motor" if u[i] > 0.98 else "ok"})  # fmt: skip
    temps = None
    if hour:
        # hourly: the season, the day's cycle and the weather (a daily AR(1) anomaly)
        when = pd.date_range(year, year + pd.Timedelta(days=366), freq="1h")
        tables = []
        for s in range(stations):
            anomaly = np.zeros(367)
            for d in range(1, 367):
                anomaly[d] = 0.7 * anomaly[d - 1] + rng.normal(0, 3 * np.sqrt(1 - 0.49))
            day = (when - year).days.to_numpy()
            temp = (12 - 10 * np.cos(2 * np.pi * day / 365) + anomaly[day]
                    + 4 * np.cos(2 * np.pi * (when.hour.to_numpy() - 15) / 24))  # fmt: skip
            tables.append(pd.DataFrame({"station": f"S{s}", "time": when, "temperature": temp}))
        temps = pd.concat(tables)
    return pd.DataFrame(rows), temps, truth


def run_row(case: str, draws: int) -> dict:
    """One case in this process: the cold and the warm call."""
    from loadbayes.archive import pool

    spec = CASES[case]
    f, temps, truth = frame(**spec)
    cov = ("season", "hour") if spec["hour"] else ("season",)
    t0 = time.perf_counter()
    pool(f, covariates=cov, temperature=temps, draws=draws, seed=1)
    cold = time.perf_counter() - t0
    t0, c0 = time.perf_counter(), time.process_time()
    res = pool(f, covariates=cov, temperature=temps, draws=draws, seed=1)
    warm, cpu = time.perf_counter() - t0, time.process_time() - c0
    part = res.parts["f_m"]
    mo = part.monthly
    hits = []
    for key, t in truth.items():
        r = mo[(mo.station == key[0]) & (mo.bay == key[1])].sort_values("month")
        hits += list((r["low"].to_numpy() <= t) & (np.asarray(t) <= r["high"].to_numpy()))
    return {
        "case": case,
        "events": int(len(f)),
        "units": len(part.units),
        "draws": f"4 x {draws} (burn {draws // 2})",
        "cold_s": cold,
        "warm_s": warm,
        "cpu_s": cpu,
        "rhat_max": part.diagnostics["rhat_max"],
        "ess_bulk_min": part.diagnostics["ess_bulk_min"],
        "coverage": float(np.mean(hits)),
        "left_out": sum(res.left_out.values()),
        "peak_rss_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024,
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="20 events a station, 200 draws")
    ap.add_argument("--output", default=str(OUT))
    ap.add_argument("--row", nargs=2, metavar=("CASE", "DRAWS"), help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.row:
        print(json.dumps(run_row(args.row[0], int(args.row[1]))))
        return
    cases = ["quick: 5 stations x 20 events"] if args.quick else [c for c in CASES if
                                                                    "quick" not in c]  # fmt: skip
    draws = 200 if args.quick else 1000
    import scipy

    info = {
        "date": datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds"),
        "machine": machine(),
        "versions": {"numpy": np.__version__, "scipy": scipy.__version__},
        "quick": args.quick,
        "results": [],
        "targets": [],
        "notes": [
            "cold_s: first pool call in a fresh process; warm_s: a second call; cpu_s: the "
            "warm call's CPU time (the machine's other load is in its load average)."
        ],
    }
    print(f"{'case':>44} {'events':>6} {'cold s':>7} {'warm s':>7} {'R-hat':>6} {'ESS':>6} "
          f"{'cover':>6}")  # fmt: skip
    for case in cases:
        proc = subprocess.run([sys.executable, __file__, "--row", case, str(draws)],
                              capture_output=True, text=True, check=False)  # fmt: skip
        if proc.returncode != 0:
            info["results"].append({"case": case, "error": proc.stderr.strip()[-300:]})
            print(case, "failed:", proc.stderr.strip()[-300:])
            continue
        r = json.loads(proc.stdout.strip().splitlines()[-1])
        info["results"].append(r)
        print(f"{case:>44} {r['events']:>6} {r['cold_s']:>7.1f} {r['warm_s']:>7.1f} "
              f"{r['rhat_max']:>6.3f} {r['ess_bulk_min']:>6.0f} {r['coverage']:>6.2f}")  # fmt: skip
    for r in info["results"]:
        if r.get("case") in ("5 stations x 100 events (1 bay)", "5 stations x 2 bays x 100 events"):
            info["targets"].append({
                "target": f"archive pool of {r['case']} in < 60 s (2 cores)",
                "measured": f"{r['cold_s']:.1f} s in a fresh process ({r['warm_s']:.1f} s "
                            f"warm), R-hat max {r['rhat_max']:.3f}, coverage "
                            f"{r['coverage']:.2f}",
                "met": r["cold_s"] < 60,
            })  # fmt: skip
    Path(args.output).parent.mkdir(parents=True, exist_ok=True)
    Path(args.output).write_text(json.dumps(info, indent=2) + "\n")
    print(f"wrote {args.output}")


if __name__ == "__main__":
    main()
