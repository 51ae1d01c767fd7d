"""Benchmark: `loadbayes predict` (a fit of parts through a fault), before and after compiling.

Data: ``cmld-lite`` fitted once (2 chains x 1,000 kept draws after 300, seed 5) to one
15 % sag recorded by an independent simulator written with SciPy alone
(``tests/feeder_generator.py``: a ZIP load and a third-order motor behind a feeder,
Radau, 50 Hz, 50 samples/s, 0.5 % noise on P and Q).

Timed, each in a fresh process that loads the fit's NetCDF (the fit is not timed):

- one prediction of 1,000 draws through a 45 % sag of 0.1 s inside a 1 s record (240/s,
  ``predict_scope.sag_profile`` with 0.7 s after the sag, passed as a profile), its first
  call in the process and then warm (the best of two more); the same through the 1.8 s
  record ``predict --sag 0.45 --duration 0.1`` builds;
- a 10-depth sweep, ``sweep`` at depths 0.15 to 0.6 (``predict --sweep
  0.15:0.6:0.05 --duration 0.1``) at the default 300 draws and at 1,000;
- each **before** (``models/parts_predict.play_reference``, the loop ``predict`` ran
  before: ``predict_parts`` draw by draw in NumPy around the compiled motor integrators)
  and **after** (``models/parts_play.play_draws``: one compiled call a draw, the draws in
  threads), in the same run; after also with an empty numba cache (``cold``: the first
  call compiles, as in a fresh clone). Wall and CPU seconds (all threads); the
  before/after ratio; the largest relative difference between the two paths' Prediction
  JSON; where the time goes (cProfile of one 300-draw prediction in each path).

The machine is shared: its load average is recorded at the start and the end of each
process.

Run: ``python benchmarks/bench_predict.py [--quick] [--output PATH]``.
"""

from __future__ import annotations

import argparse
import cProfile
import datetime
import json
import os
import pstats
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
from bench_zip import machine  # noqa: E402  (one copy: the machine's description)

OUT = HERE / "results" / "predict.json"
TARGET_ONE_S = 5.0
TARGET_SWEEP_S = 30.0
DEPTHS = [round(0.15 + 0.05 * k, 2) for k in range(10)]


def _load() -> list[float] | None:
    return [round(x, 2) for x in os.getloadavg()] if hasattr(os, "getloadavg") else None


def _fit(path: Path, quick: bool) -> dict:
    import numpy as np

    sys.path.insert(0, str(HERE.parent / "tests"))
    from feeder_generator import simulate
    from loadbayes.core.settings import SamplerSettings
    from loadbayes.fit.composite.driver import fit_composite
    from loadbayes.measurements.record import EventRecord
    from loadbayes.models.dynamic import dynamic_model

    rng = np.random.default_rng(3)
    t, v, d, p, q, _ = simulate(sag=0.15)
    noise = 0.005 * np.hypot(p[0], q[0])
    ev = EventRecord(t, v, p + rng.normal(0, noise, t.size), q + rng.normal(0, noise, t.size),
                     d, "sag 0.15 (tests/feeder_generator.py)")  # fmt: skip
    draws = 300 if quick else 1000  # kept per chain
    run = SamplerSettings(draws=draws + 300, burn=300, chains=2, seed=5)
    t0 = time.perf_counter()
    fit = fit_composite(dynamic_model("cmld-lite", f_hz=50.0), [ev], sampler=run)
    fit.posterior.to_netcdf(path)
    return {"fit_s": time.perf_counter() - t0, "kept_draws": 2 * draws}


def _timed(fn):
    w, c = time.perf_counter(), time.process_time()
    out = fn()
    return out, time.perf_counter() - w, time.process_time() - c


def worker(path: str, mode: str, quick: bool, out: str) -> None:
    """One process: ``mode`` before or after (cold is after with an empty cache)."""
    t0 = time.perf_counter()
    import loadbayes.fit.composite.predict as pr
    from loadbayes.fit.composite.predict_scope import sag_profile
    from loadbayes.models.parts_predict import play_reference

    if mode == "before":
        pr.play_draws = play_reference  # the loop predict ran before, in NumPy
    post = pr.load_result(path)
    v0 = float(pr.events_of(post)[0].v0)
    one_s = sag_profile(0.45, 0.1, v0=v0, post_s=0.7)  # 0.2 + 0.1 + 0.7 s
    n = 200 if quick else 1000
    depths = DEPTHS[::4] if quick else DEPTHS
    small = 50 if quick else 300  # the sweep's draws: predict's default, 300
    res: dict = {"mode": mode, "load_start": _load(), "import_s": time.perf_counter() - t0}
    pred, res["first_s"], res["first_cpu_s"] = _timed(
        lambda: pr.predict(post, voltage=one_s, draws=n)
    )
    res["prediction"] = pred.to_dict()
    warm = [_timed(lambda: pr.predict(post, voltage=one_s, draws=n)) for _ in range(2)]
    res["warm_s"] = min(w for _, w, _ in warm)
    res["warm_cpu_s"] = min(c for _, _, c in warm)
    res["record_s"] = float(one_s.t[-1])
    res["samples"] = int(one_s.n)
    _, res["sag_1p8_s"], res["sag_1p8_cpu_s"] = _timed(
        lambda: pr.predict(post, sag=0.45, duration=0.1, draws=n)
    )
    preds, res["sweep_300_s"], res["sweep_300_cpu_s"] = _timed(
        lambda: pr.sweep(post, depths, duration=0.1, draws=small)
    )
    res["sweep_stall"] = [p.stall["probability"] for p in preds]
    if mode != "before" or quick:
        _, res["sweep_1000_s"], res["sweep_1000_cpu_s"] = _timed(
            lambda: pr.sweep(post, depths, duration=0.1, draws=n)
        )
    prof = cProfile.Profile()
    prof.enable()
    pr.predict(post, voltage=one_s, draws=small)
    prof.disable()
    stats = pstats.Stats(prof)
    rows = sorted(stats.stats.items(), key=lambda kv: -kv[1][2])[:6]
    res["profile"] = [{"function": f"{Path(f).name}:{name}", "calls": int(v[1]),
                       "tottime_s": round(v[2], 3)} for (f, _, name), v in rows]  # fmt: skip
    res["draws"], res["small"] = n, small
    res["depths"] = depths
    res["load_end"] = _load()
    Path(out).write_text(json.dumps(res))


def _spawn(path: Path, mode: str, quick: bool, tmp: Path) -> dict:
    env = dict(os.environ)
    if mode == "cold":
        env["NUMBA_CACHE_DIR"] = str(tmp / "numba-cache-cold")
    out = tmp / f"{mode}.json"
    cmd = [sys.executable, __file__, "--worker", mode, "--fit", str(path), "--worker-output",
           str(out)] + (["--quick"] if quick else [])  # fmt: skip
    subprocess.run(cmd, env=env, check=True)
    return json.loads(out.read_text())


def _largest_difference(a, b) -> float:
    worst = 0.0

    def walk(x, y):
        nonlocal worst
        if isinstance(x, dict):
            for k in x:
                walk(x[k], y[k])
        elif isinstance(x, list):
            for u, w in zip(x, y, strict=True):
                walk(u, w)
        elif isinstance(x, float) and isinstance(y, float):
            worst = max(worst, abs(x - y) / max(abs(x), abs(y), 1e-300))
        elif x != y:
            worst = float("inf")

    walk(a, b)
    return worst


def _versions() -> dict:
    from importlib.metadata import PackageNotFoundError, version

    out = {}
    for pkg in ("loadbayes", "numpy", "numba", "scipy"):
        try:
            out[pkg] = version(pkg)
        except PackageNotFoundError:
            out[pkg] = None
    return out


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="200 draws, 3 depths")
    parser.add_argument("--output", type=Path, default=OUT)
    parser.add_argument("--worker", default=None, help=argparse.SUPPRESS)
    parser.add_argument("--fit", default=None, help=argparse.SUPPRESS)
    parser.add_argument("--worker-output", default=None, help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.worker:
        worker(args.fit, args.worker, args.quick, args.worker_output)
        return 0
    info = {
        "benchmark": "predict",
        "date": datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds"),
        "machine": machine(),
        "versions": _versions(),
        "quick": args.quick,
    }
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        path = tmp / "cmld-lite.nc"
        info["fit"] = _fit(path, args.quick)
        runs = {m: _spawn(path, m, args.quick, tmp) for m in ("cold", "after", "before")}
    before, after, cold = runs["before"], runs["after"], runs["cold"]
    diff = _largest_difference(before.pop("prediction"), after.pop("prediction"))
    cold.pop("prediction")
    n = after["draws"]
    rows = []
    for label, key, tag in (
        (f"one prediction, {n} draws, 45% sag of 0.1 s in a 1 s record: first call", "first_s",
         "first_cpu_s"),
        ("the same, warm (best of 2)", "warm_s", "warm_cpu_s"),
        (f"{n} draws, `--sag 0.45 --duration 0.1` (1.8 s record)", "sag_1p8_s", "sag_1p8_cpu_s"),
        (f"sweep of {len(after['depths'])} depths, {after['small']} draws each", "sweep_300_s",
         "sweep_300_cpu_s"),
        (f"sweep of {len(after['depths'])} depths, {n} draws each", "sweep_1000_s",
         "sweep_1000_cpu_s"),
    ):  # fmt: skip
        b, a = before.get(key), after.get(key)
        rows.append({"case": label, "before_s": b, "before_cpu_s": before.get(tag),
                     "after_s": a, "after_cpu_s": after.get(tag),
                     "after_cold_cache_s": cold.get(key),
                     "ratio": (b / a) if b and a else None})  # fmt: skip
    info["results"] = rows
    info["stall_by_depth"] = {"depths": after["depths"], "before": before["sweep_stall"],
                              "after": after["sweep_stall"]}  # fmt: skip
    info["largest_relative_difference"] = diff
    info["load_average_at_end"] = _load()
    one, sweep = after["warm_s"], after["sweep_300_s"]
    sweep_n = after.get("sweep_1000_s")
    loads = "; ".join(f"{m} {r['load_start']} -> {r['load_end']}" for m, r in runs.items())
    info["targets"] = [
        {"target": f"one prediction of 1,000 draws through a 45% sag of 0.1 s in a 1 s record "
                   f"< {TARGET_ONE_S:g} s on 2 cores (warm)",
         "measured": f"{one:.2f} s wall, {after['warm_cpu_s']:.2f} s CPU (before: "
                     f"{before['warm_s']:.2f} s, {before['warm_s'] / one:.1f}x); first call "
                     f"{after['first_s']:.2f} s, {cold['first_s']:.1f} s with an empty cache",
         "met": one < TARGET_ONE_S and n == 1000},
        {"target": f"10-depth sweep (`predict --sweep 0.15:0.6:0.05 --duration 0.1`, default "
                   f"300 draws) < {TARGET_SWEEP_S:g} s",
         "measured": f"{sweep:.1f} s wall (before: {before['sweep_300_s']:.1f} s, "
                     f"{before['sweep_300_s'] / sweep:.1f}x)",
         "met": sweep < TARGET_SWEEP_S and len(after["depths"]) == 10},
        {"target": f"the same sweep at 1,000 draws a depth < {TARGET_SWEEP_S:g} s",
         "measured": f"{sweep_n:.1f} s wall, {after['sweep_1000_cpu_s']:.1f} s CPU",
         "met": bool(sweep_n) and sweep_n < TARGET_SWEEP_S and n == 1000},
    ]  # fmt: skip

    def prof(r):
        return "; ".join(f"{p['function']} {p['tottime_s']} s ({p['calls']} calls)"
                         for p in r["profile"])  # fmt: skip

    info["notes"] = [
        f"Load average (1, 5, 15 min) of the 2-CPU machine, at the start and end of each "
        f"process: {loads}. Other work shared the CPUs: wall times above the CPU times "
        "include waiting for a CPU (the CPU column counts every thread's time).",
        f"Same answer: the largest relative difference between the Prediction JSON of the "
        f"two paths (the {n}-draw, 1 s record prediction, seed 0) is {diff:.1e}.",
        f"Where the time goes, one {after['small']}-draw prediction under cProfile "
        f"(tottime, top 6). Before: {prof(before)}. After: {prof(after)}.",
        f"The fit (not timed in the rows): {info['fit']['fit_s']:.1f} s, "
        f"{info['fit']['kept_draws']} kept draws.",
    ]
    for r in rows:
        print(r)
    for t in info["targets"]:
        print(f"target: {t['target']}: {t['measured']} ({'met' if t['met'] else 'NOT met'})")
    for note in info["notes"]:
        print(note)
    args.output.parent.mkdir(parents=True, exist_ok=True)
    args.output.write_text(json.dumps(info, indent=2) + "\n")
    print(f"wrote {args.output}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
