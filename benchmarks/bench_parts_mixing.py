"""Benchmark: how the ``cmld-lite`` sampler mixes (issues 36, 37): R-hat, bulk ESS, ESS/s.

Cases:

- ``griddyn``: GridDyn's 13 % and 25 % CMLD events (``loadbayes.cases.griddyn``, noise
  0.5 % on P and Q with noise seed 0, 0.1 s before the fault to 0.4 s after it, one-cycle
  window means at 60/s), fitted jointly as ``tests/statistical/test_parts_griddyn.py``
  does; the shares' 95 % intervals are printed beside GridDyn's own fractions;
- ``real``: the shared real record's transformer #1, its first fault (the straddling
  rows flagged), as ``studies/planning.py`` fits it.

Every parameter's R-hat and bulk ESS (``Posterior.summary``), and ESS per CPU-second of
the fit (``core.forked.cpu_seconds``: the chains' threads or processes included, the NLS
start too).
Writes a JSON of the numbers and an ``.npz`` of the draws to ``--out``.

Run: ``python benchmarks/bench_parts_mixing.py griddyn LABEL [--draws 4000 --burn 2000
--chains 2 --seed 0 --out DIR]``.
"""

from __future__ import annotations

import argparse
import json
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from loadbayes.core.forked import cpu_seconds
from loadbayes.core.settings import SamplerSettings
from loadbayes.fit.composite.driver import fit_composite
from loadbayes.measurements.record import EventRecord
from loadbayes.models.dynamic import dynamic_model

SHARES = ("f_m_a", "f_m_b", "f_d", "f_el", "f_s", "f_motors", "a1", "a2", "a3")


def griddyn_case():
    """GridDyn's shallow and medium events, the model, GridDyn's fractions."""
    from loadbayes.cases.griddyn import cases
    from loadbayes.cases.griddyn.cmld import Cmld
    from loadbayes.cases.griddyn.events import griddyn_events

    depths = (cases.DEPTHS["shallow"], cases.DEPTHS["medium"])
    frames, truth = griddyn_events(depths, seed_noise=0, noise=0.005, rate_hz=60.0)
    events = []
    for k, (frame, ev) in enumerate(zip(frames, truth["events"], strict=True)):
        tf = ev["t_fault_s"]
        w = frame[(frame.t_s >= tf - 0.1) & (frame.t_s <= tf + 0.4)]
        events.append(EventRecord(w.t_s.to_numpy() - w.t_s.iloc[0], w.v.to_numpy(),
                                  w.p.to_numpy(), w.q.to_numpy(), w.angle_rad.to_numpy(),
                                  f"griddyn_{k}"))  # fmt: skip
    c = Cmld()
    static = 1.0 - c.f_a - c.f_b - c.f_d - c.f_el
    true = {"f_m_a": c.f_a, "f_m_b": c.f_b, "f_d": c.f_d, "f_el": c.f_el, "f_s": static,
            "f_motors": truth["three_phase_motor_share"]}  # fmt: skip
    return events, dynamic_model("cmld-lite", f_hz=60.0, window_s=1.0 / 60.0), true


def real_case():
    """The real record's transformer #1, first fault."""
    from loadbayes.studies.real_record import BAYS, events_of, find_record

    cfg = find_record(None)
    if cfg is None:
        raise SystemExit("the shared real record was not found beside the repository")
    evs, flags, info = events_of(cfg, BAYS[0][0])
    f = info["f_hz"]
    events = [replace(evs[0], straddle=np.asarray(flags[0]["straddle"], bool))]
    return events, dynamic_model("cmld-lite", f_hz=f, window_s=1.0 / f), {}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("case", choices=("griddyn", "real"))
    ap.add_argument("label")
    ap.add_argument("--draws", type=int, default=4000)
    ap.add_argument("--burn", type=int, default=2000)
    ap.add_argument("--chains", type=int, default=2)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--out", type=Path, default=Path("benchmarks/results/parts_mixing"))
    a = ap.parse_args()
    events, model, truth = griddyn_case() if a.case == "griddyn" else real_case()
    run = SamplerSettings(draws=a.draws, burn=a.burn, chains=a.chains, seed=a.seed, threads=1)
    c0, w0 = cpu_seconds(), time.perf_counter()
    post = fit_composite(model, events, sampler=run).posterior
    cpu, wall = cpu_seconds() - c0, time.perf_counter() - w0
    names = [n for n in (*model.theta_names, *SHARES) if n in post.draws]
    names += [n for n in post.draws if n.startswith("tau_")]
    s = post.summary(var_names=names)
    out = {"case": a.case, "label": a.label, "cpu": cpu, "wall": wall, "draws": a.draws,
           "burn": a.burn, "chains": a.chains, "seed": a.seed, "truth": truth,
           "acceptance": post.settings.get("acceptance"),
           "jump_acceptance": post.settings.get("jump_acceptance"), "params": {}}  # fmt: skip
    for n in names:
        x = np.asarray(post.draws[n]).ravel()
        lo, hi = np.quantile(x, [0.025, 0.975])
        out["params"][n] = {"rhat": float(s.loc[n, "r_hat"]), "ess": float(s.loc[n, "ess_bulk"]),
                            "mean": float(x.mean()), "sd": float(x.std()), "lo": float(lo),
                            "hi": float(hi)}  # fmt: skip
    a.out.mkdir(parents=True, exist_ok=True)
    stem = a.out / f"parts_mixing_{a.case}_{a.label}_{a.seed}"
    np.savez_compressed(f"{stem}.npz", **{n: np.asarray(post.draws[n]) for n in names})
    stem.with_suffix(".json").write_text(json.dumps(out, indent=1))
    ps = out["params"]
    low = min(p["ess"] for p in ps.values())
    print(f"{a.case} {a.label}: CPU {cpu:.1f} s, wall {wall:.1f} s, max R-hat "
          f"{max(p['rhat'] for p in ps.values()):.2f}, min ESS {low:.0f}, "
          f"min ESS/s {low / cpu:.3f}")  # fmt: skip
    for n, p in ps.items():
        t = f"  truth {truth[n]:.3g}" if n in truth else ""
        print(
            f"  {n:18s} R-hat {p['rhat']:.3f}  ESS {p['ess']:7.0f}  ESS/s {p['ess'] / cpu:8.3f}"
            f"  {p['mean']:.3f} [{p['lo']:.3f}, {p['hi']:.3f}]{t}"
        )


if __name__ == "__main__":
    main()
