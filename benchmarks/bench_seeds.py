"""Seed to seed: how long the default composite fit of one event runs, per seed.

Usage::

    python benchmarks/bench_seeds.py events/event_001.csv --seeds 0-7
    python benchmarks/bench_seeds.py events/event_001.csv --seeds 0-7 -- --draws 6000 \
        --burn 2000 --until-converged

Each seed runs ``loadbayes fit composite EVENT --seed S`` (plus anything after ``--``) in
a fresh process; the table gives its iterations per chain and rounds (the run until
converged), the CPU seconds of the whole process (imports and NLS included; measured
with ``resource.getrusage`` of the children, so a shared machine's load does not count),
the min bulk ESS and max R-hat over every reported quantity, and ``f_m`` and T' with
their intervals; then the median iterations and the slowest seed's multiple of it (issue
35: every seed under 3x the median). Wall seconds are shown beside, with the load average
before each run: on a shared machine they measure the other users too. ``--stages`` runs
each seed through ``composite_stages.py`` (the same command, timers around its stages)
and ends with the median wall and CPU seconds of each stage, the interpreter's start and
exit included. Not part of ``run_all.py`` (it needs an event file: the real record's, cut
by ``loadbayes events``, docs/formats.md).
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent


def _seeds(text: str) -> list[int]:
    lo, _, hi = text.partition("-")
    return list(range(int(lo), int(hi or lo) + 1))


def _cpu() -> float:
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


def run(event: str, seed: int, extra: list[str], out: Path, netcdf: bool = False,
        stages: bool = False) -> dict:  # fmt: skip
    """One fit in a fresh process: its JSON's numbers, the process's CPU and wall seconds."""
    load = os.getloadavg()[0]
    keep = ["--netcdf", str(out.with_suffix(".nc"))] if netcdf else []
    how = [str(HERE / "composite_stages.py")] if stages else ["-m", "loadbayes", "fit", "composite"]
    cmd = [sys.executable, *how, event, "--seed", str(seed), "--json", str(out), "--quiet",
           "--force", *keep, *extra]  # fmt: skip
    env = {**os.environ, "STAGES_OUT": str(out.with_suffix(".stages.json"))}
    before, t0 = _cpu(), time.perf_counter()
    subprocess.run(cmd, check=True, stderr=subprocess.DEVNULL, env=env)
    wall, cpu = time.perf_counter() - t0, _cpu() - before
    split = {}
    if stages:
        table = json.loads(out.with_suffix(".stages.json").read_text())
        split = {name: (w, c) for name, w, c in table}
        inside = [(w, c) for name, w, c in table if not name.startswith("(")]
        split["interpreter start and exit"] = (wall - sum(w for w, _ in inside),
                                               cpu - sum(c for _, c in inside))  # fmt: skip
        split["the whole process"] = (wall, cpu)
    fit = json.loads(out.read_text())
    par = fit["parameters"]
    judged = [v for v in par.values() if v.get("r_hat") is not None]
    until = fit["settings"].get("until_converged") or {}
    return {
        "seed": seed,
        "iterations": until.get("iterations_per_chain", fit["draws"]),
        "rounds": len(until.get("rounds", [])) or 1,
        "cpu_s": cpu,
        "wall_s": wall,
        "load": load,
        "stages": split,
        "ess_min": min(v["ess_bulk"] for v in judged),
        "r_hat_max": max(v["r_hat"] for v in judged),
        **{
            f"{k}_{s}": par[k][s]
            for k in ("f_m", "t_prime_s")
            for s in ("mean", "hdi_low", "hdi_high")
        },
    }


def main() -> None:
    argv = sys.argv[1:]
    extra = argv[argv.index("--") + 1 :] if "--" in argv else []
    argv = argv[: argv.index("--")] if "--" in argv else argv
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("event")
    ap.add_argument("--seeds", default="0-7", help="a range, e.g. 0-7")
    ap.add_argument("--keep", metavar="DIR", help="keep each seed's JSON and NetCDF here")
    ap.add_argument("--stages", action="store_true", help="time each stage of the command")
    args = ap.parse_args(argv)
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(args.keep or tmp)
        folder.mkdir(parents=True, exist_ok=True)
        for seed in _seeds(args.seeds):
            r = run(args.event, seed, extra, folder / f"fit_{seed}.json", bool(args.keep),
                    args.stages)  # fmt: skip
            rows.append(r)
            print(f"seed {seed}: {r['iterations']:>8,} iterations per chain "
                  f"({r['rounds']} rounds), CPU {r['cpu_s']:6.1f} s, wall {r['wall_s']:6.1f} s "
                  f"(load {r['load']:.1f}), "
                  f"min ESS {r['ess_min']:6.0f}, R-hat {r['r_hat_max']:.4f}; "
                  f"f_m {r['f_m_mean']:.3f} [{r['f_m_hdi_low']:.3f}, {r['f_m_hdi_high']:.3f}], "
                  f"T' {r['t_prime_s_mean']:.4f} [{r['t_prime_s_hdi_low']:.4f}, "
                  f"{r['t_prime_s_hdi_high']:.4f}] s", flush=True)  # fmt: skip
    its = np.array([r["iterations"] for r in rows], dtype=float)
    med = float(np.median(its))
    print(f"median {med:,.0f} iterations per chain; slowest {its.max() / med:.1f} x the median; "
          f"median CPU {np.median([r['cpu_s'] for r in rows]):.2f} s, "
          f"wall {np.median([r['wall_s'] for r in rows]):.2f} s")  # fmt: skip
    if args.stages:
        print("| stage | wall s (median) | CPU s (median) |\n| --- | --- | --- |")
        for name in rows[0]["stages"]:
            w, c = zip(*(r["stages"][name] for r in rows if name in r["stages"]), strict=True)
            print(f"| {name} | {np.median(w):.2f} | {np.median(c):.2f} |")


if __name__ == "__main__":
    main()
