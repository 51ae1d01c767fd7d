"""Benchmark: fit the induction motor to 1e6 samples, from arrays and from a CSV file.

Data: 334 independent 3 s records of the default sag (krause_2250hp, 3001 samples each,
fresh 5% noise on the targets of each), cut to 1,000,000 rows. The estimator treats rows
as independent equations, so this is the same problem as one long record; it avoids
integrating a 1000 s ODE just to make data.

Timed (best and median of ``--repeat`` runs, after a warm-up that loads the compiled
kernels):

- ``fit_im`` from in-memory arrays, the paper's settings (40,000 iterations, 5,000
  burn-in, 4 chains), split into the one pass over the data (rows + Gram matrix) and the
  sampling, which costs the same at n = 3001 and n = 1e6 (O(1) per iteration);
- the same for the paper's form (measured currents, three independent blocks);
- ``fit_im_file`` on the CSV (reading, validating and the pass, plus the sampling).

Writes ``benchmarks/results/im.json`` and prints a table.

Run: ``python benchmarks/bench_im.py [--n 1000000] [--repeat 3]``.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import statistics
import sys
import tempfile
import time
from pathlib import Path

import numpy as np


def _timed(fn, repeat):
    out, times = None, []
    for _ in range(repeat):
        t = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - t)
    return out, {"best_s": min(times), "median_s": statistics.median(times), "runs": times}


def make_data(n: int, seed: int = 0) -> tuple[dict[str, np.ndarray], dict]:
    from loadbayes.cases.motor_sim import simulate
    from loadbayes.models.motor_fit import DATA_COLUMNS

    base = simulate("krause_2250hp", noise=0.0)
    reps = -(-n // len(base))
    rng = np.random.default_rng(seed)
    cols = {}
    for k in DATA_COLUMNS:
        x = base[k].to_numpy()
        tiled = np.tile(x, reps)[:n]
        if k in ("ded", "deq", "dw", "id", "iq"):
            tiled = tiled + 0.05 * np.sqrt(np.mean(x**2)) * rng.standard_normal(n)
        cols[k] = np.ascontiguousarray(tiled)
    return cols, base.attrs


def main(argv: list[str] | None = None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=1_000_000)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--out", default=str(Path(__file__).parent / "results" / "im.json"))
    args = ap.parse_args(argv)

    from loadbayes.core.settings import SamplerSettings
    from loadbayes.fit import accumulate, fit_im, fit_im_file
    from loadbayes.inference.bilinear import sample_bilinear
    from loadbayes.models.motor import COEFFICIENT_NAMES
    from loadbayes.models.motor_fit import DATA_COLUMNS, InductionMotorModel

    paper = {"draws": 40_000, "burn": 5_000, "chains": 4}
    smp = SamplerSettings(**paper)
    cols, attrs = make_data(args.n)
    small = {k: v[:3001] for k, v in cols.items()}
    fit_im(
        small, sampler=SamplerSettings(draws=200, burn=50, chains=1)
    )  # load the compiled kernels
    fit_im(small, sampler=SamplerSettings(draws=200, burn=50, chains=1), currents="measured")

    model = InductionMotorModel(f_hz=60.0)
    gram, t_pass = _timed(lambda: accumulate(model, [cols]), args.repeat)
    priors = model.default_priors()

    def sampler(g, data):
        st = model.bilinear_stats(g, model.first_row(data))
        v = model.current_estimate(g)
        return sample_bilinear(
            st,
            [priors["flux"], priors["speed"]],
            priors["current"],
            tau_shape=[1e-3] * 3,
            tau_rate=[1e-9] * 3,
            v_start=v[:2],
            settings=SamplerSettings(**paper, seed=0),
        )

    _, t_sample = _timed(lambda: sampler(gram, cols), args.repeat)
    _, t_sample_small = _timed(lambda: sampler(accumulate(model, [small]), small), args.repeat)
    post, t_fit = _timed(lambda: fit_im(cols, sampler=smp), args.repeat)
    _, t_fit_measured = _timed(lambda: fit_im(cols, currents="measured", sampler=smp), args.repeat)
    truth = attrs["coefficients"]
    err = {k: 100 * (post.mean()[k] / truth[k] - 1) for k in COEFFICIENT_NAMES}

    with tempfile.TemporaryDirectory() as tmp:
        import pandas as pd

        csv = os.path.join(tmp, "im.csv")
        pd.DataFrame(
            {"t_s": np.arange(args.n) * 1e-3, **{k: cols[k] for k in DATA_COLUMNS[1:]}}
        ).to_csv(csv, index=False)
        size_mb = os.path.getsize(csv) / 1e6
        _, t_file = _timed(lambda: fit_im_file(csv, sampler=smp), args.repeat)

        def read_only():
            from loadbayes.io.tables import iter_chunks

            acc = None
            for chunk in iter_chunks(csv, list(DATA_COLUMNS)):
                rows = model.rows(chunk.data)
                if acc is None:
                    from loadbayes.core.stats import GramAccumulator

                    acc = GramAccumulator(model.gram_columns)
                acc.update(rows)
            return acc.result()

        _, t_read = _timed(read_only, args.repeat)

    result = {
        "n": args.n,
        "sampler": paper,
        "iterations_total": paper["draws"] * paper["chains"],
        "fit_from_arrays_s": t_fit,
        "fit_from_arrays_measured_form_s": t_fit_measured,
        "data_pass_s": t_pass,
        "sampling_n_1e6_s": t_sample,
        "sampling_n_3001_s": t_sample_small,
        "fit_from_csv_s": t_file,
        "csv_read_and_pass_s": t_read,
        "csv_mb": size_mb,
        "coefficient_error_pct": err,
        "machine": {
            "python": sys.version.split()[0],
            "numpy": np.__version__,
            "platform": platform.platform(),
            "cpu_count": os.cpu_count(),
            "load_avg_1min": os.getloadavg()[0] if hasattr(os, "getloadavg") else None,
        },
    }
    rows = [
        ("fit_im from arrays (modelled currents)", t_fit),
        ("  of which: one pass, rows + Gram", t_pass),
        ("  of which: Gibbs sampling (n = 1e6)", t_sample),
        ("  Gibbs sampling, same draws, n = 3001", t_sample_small),
        ("fit_im from arrays (paper's form)", t_fit_measured),
        (f"fit_im_file on CSV ({size_mb:.0f} MB)", t_file),
        ("  of which: read + validate + pass", t_read),
    ]
    print(
        f"induction motor, n = {args.n:,}, {paper['draws']:,} iterations x {paper['chains']} chains"
    )
    print(f"{'stage':45s} {'best s':>8s} {'median s':>9s}")
    for label, t in rows:
        print(f"{label:45s} {t['best_s']:8.3f} {t['median_s']:9.3f}")
    print("coefficient error at n = 1e6 (%): " + ", ".join(f"{k} {v:+.4f}" for k, v in err.items()))
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(result, indent=2) + "\n")
    print(f"wrote {out}")
    return result


if __name__ == "__main__":
    main()
