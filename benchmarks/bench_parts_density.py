"""A model of parts' density compiled whole, against its Python path; the defaults' cost.

Usage::

    python benchmarks/bench_parts_density.py [--record CFG] [--seeds 0 1 2 3] [--output PATH]

Two measurements on the shared real record's first faults (``$LOADBAYES_REAL_RECORD`` or
``shared/real`` beside the repository, or ``--record``; 4 phasors per cycle):

1. **One proposal** (in this process): ``DesignProblem.collapsed`` at 2,000 states about
   the NLS start (sd 0.003 in every sampled coordinate), through the compiled density
   (``fit/composite/parts_density.py``) and through the Python path it replaced (the
   same problem with ``_density`` None), for ``slm`` and ``cmld-lite`` on transformer
   #1: microseconds per proposal, the ratio, and whether every number agreed to the bit.
2. **The defaults** (issue 36: "a ``cmld-lite`` fit of one 0.4 s real window at the
   defaults, converged, in under 60 s on 2 cores"; "``zip+motor`` no slower than
   today"): the whole command ``loadbayes fit composite EVENT --model M --seed S`` in a
   fresh process, until converged, for ``cmld-lite`` on both transformers and
   ``zip+motor`` on #1, each seed: wall and CPU seconds (the command's children, from
   ``resource.getrusage``), the rounds, the iterations a chain, the largest R-hat and
   the smallest bulk ESS at the end.

Writes ``benchmarks/results/parts_density.json``, with the load average at the start and
end: the machine may be shared.
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

import numpy as np

from bench_lanes import real_event

HERE = Path(__file__).resolve().parent
BAYS = ("1号主变", "2号主变")


def per_proposal(event: Path, name: str, n: int = 2000) -> dict:
    """µs per ``collapsed`` call, compiled and Python, on ``n`` states about the NLS start."""
    from loadbayes.fit.composite.design import DesignProblem
    from loadbayes.fit.composite.nls import nls
    from loadbayes.measurements.events import read_events
    from loadbayes.models.dynamic import dynamic_model

    events = read_events([str(event)], f_hz=50.0)
    model = dynamic_model(name, f_hz=50.0, window_s=1 / 50)
    problem = DesignProblem(model, events, model.default_prior(events))
    start = nls(problem).u
    rng = np.random.default_rng(0)
    states = start + 0.003 * rng.standard_normal((n, start.size))
    tau = np.array([3e4, 2e4, 500.0])[: problem.n_channels]
    density = problem._density
    density(states[0], tau)  # compiled (or read from numba's cache) outside the timing
    out, values = {}, {}
    for path in ("compiled", "python"):
        problem._density = density if path == "compiled" else None
        t0 = time.perf_counter()
        values[path] = [problem.collapsed(u, tau)[0] for u in states]
        out[f"{path}_us"] = round(1e6 * (time.perf_counter() - t0) / n, 1)
    out["ratio"] = round(out["python_us"] / out["compiled_us"], 2)
    out["same_to_the_bit"] = values["compiled"] == values["python"]
    out["feasible"] = int(np.isfinite(values["compiled"]).sum())
    return out


def default_fit(event: Path, out: Path, model: str, seed: int) -> dict:
    """The whole command at the defaults, until converged, in a fresh process."""
    args = [sys.executable, "-m", "loadbayes", "fit", "composite", str(event), "--model", model,
            "--seed", str(seed), "--json", str(out), "--quiet", "--force"]  # fmt: skip
    use = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu, wall = use.ru_utime + use.ru_stime, time.perf_counter()
    done = subprocess.run(args, capture_output=True, text=True)  # fmt: skip
    wall = time.perf_counter() - wall
    use = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = use.ru_utime + use.ru_stime - cpu
    if done.returncode != 0:
        raise RuntimeError(f"{' '.join(args)}: {done.stderr[-2000:]}")
    fit = json.loads(out.read_text())
    until = fit["settings"].get("until_converged") or {}
    rounds = until.get("rounds", [])
    params = fit["parameters"].values()
    return {"wall_s": round(wall, 1), "cpu_s": round(cpu, 1), "rounds": len(rounds),
            "iterations_per_chain": until.get("iterations_per_chain"),
            "r_hat_max": round(max(p["r_hat"] for p in params if p.get("r_hat") is not None), 4),
            "ess_bulk_min": round(min(p["ess_bulk"] for p in params
                                      if p.get("ess_bulk") is not None)),
            "stopped_by_budget": until.get("stopped_by_budget")}  # fmt: skip


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--record", type=Path, default=None, help="the real record's .cfg")
    parser.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2, 3])
    parser.add_argument("--output", type=Path, default=HERE / "results" / "parts_density.json")
    args = parser.parse_args(argv)
    from loadbayes.studies.real_record import find_record

    cfg = args.record or find_record(HERE)
    if cfg is None:
        print("the real record is not found (--record)", file=sys.stderr)
        return 1
    load0 = os.getloadavg()
    started = datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds")
    proposals, fits = [], []
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        events = {bay: real_event(Path(cfg), folder, bay) for bay in BAYS}
        for name in ("slm", "cmld-lite"):
            row = {"model": name, **per_proposal(events[BAYS[0]], name)}
            proposals.append(row)
            print(row, file=sys.stderr)
        cases = [("cmld-lite", bay) for bay in BAYS] + [("zip+motor", BAYS[0])]
        for name, bay in cases:
            for seed in args.seeds:
                row = {"model": name, "bay": bay, "seed": seed,
                       **default_fit(events[bay], folder / "fit.json", name, seed)}  # fmt: skip
                fits.append(row)
                print(row, file=sys.stderr)
    result = {"benchmark": "parts_density", "started": started,
              "machine": f"{platform.machine()}, {os.cpu_count()} CPUs, {platform.platform()}",
              "load_average_at_start": load0, "load_average_at_end": os.getloadavg(),
              "proposals": proposals, "fits": fits}  # fmt: skip
    args.output.parent.mkdir(parents=True, exist_ok=True)
    args.output.write_text(json.dumps(result, indent=1, ensure_ascii=False))
    print("| model | compiled: us a proposal | Python path | Python / compiled | same to the bit |")
    print("| --- | --- | --- | --- | --- |")
    for r in proposals:
        print(f"| `{r['model']}` | {r['compiled_us']} | {r['python_us']} | {r['ratio']} | "
              f"{'yes' if r['same_to_the_bit'] else 'NO'} |")  # fmt: skip
    print("\n| model | transformer | seed | wall s | CPU s | rounds | iterations a chain | "
          "R-hat max | bulk ESS min |")  # fmt: skip
    print("| --- | --- | --- | --- | --- | --- | --- | --- | --- |")
    for r in fits:
        print(f"| `{r['model']}` | {r['bay']} | {r['seed']} | {r['wall_s']} | {r['cpu_s']} | "
              f"{r['rounds']} | {r['iterations_per_chain']} | {r['r_hat_max']} | "
              f"{r['ess_bulk_min']} |")  # fmt: skip
    for name, bay in sorted({(r["model"], r["bay"]) for r in fits}):
        walls = [r["wall_s"] for r in fits if (r["model"], r["bay"]) == (name, bay)]
        print(f"{name} {bay}: median {np.median(walls):.1f} s, slowest {max(walls):.1f} s")
    print(f"\nload average at start {load0[0]:.1f}, at end {os.getloadavg()[0]:.1f}; "
          f"written {args.output}")  # fmt: skip
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
