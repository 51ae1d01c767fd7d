"""The fan motor of issue 35: a large-inertia motor not in the library, fitted at the defaults.

The events are made by tests/independent_composite.py (SciPy Radau, no loadbayes code):
ZIP (P shares 0.3, 0.2, 0.5) + one motor taking f_m 0.4 of P0, Rs 0.013, Xs 0.067, Xm 3.8,
Rr 0.009, Xr 0.17 (own base), H 1.5 s, torque 0.7 w^2 (T' 1.17 s); a 30% sag of 0.2 s and
a 45% sag of 0.12 s, each from t = 1.0 s exactly (a sample) with 20 ms linear ramps,
point samples at 60/s, 0.5% noise, P and Q on one base (Q0 = 0.3 P0). They go through
the CLI as plain CSVs, so the sample reading is the default's: chosen by the data
(fit/composite/reading.py; here a tie, read as points).

The finding's own files (P/P0 and Q/Q0, Q0 = 0.72 P0) are not fitted here: on them the
model is not true (Q on another base than P) and the run warns of it
(tests/unit/test_composite_checks.py).

False-alarm rates. ``make test``: one seed, f_m and T' 99% intervals, at most 2% if the
sampler is calibrated (fixed seeds make the outcome deterministic: this is the chance such
a seed fails). ``make validate`` (LOADBAYES_VALIDATE=1): 20 noise seeds, 95% intervals;
it fails when f_m or T' misses on 4 or more (binomial, n 20, p 0.05: 1.6% each, 3.2%
for the two).

Measured (2026-11-29, 4 x 8,000 iterations, 2,000 burn-in): seed 0 f_m [0.381, 0.412],
T' [0.32, 1.49] s at 95%. Over the 20 seeds 19 were read as points and one as window
means (the evidence favoured them); f_m missed on 2 (0.363-0.399, 0.361-0.395), T' on 3,
two of them with R-hat of T' 1.37 and 1.44: the pinned draws are short for this motor
(R-hat of T' 1.01-1.44, median 1.06), so the T' count sits at the bound; the
run-until-converged default goes on.
"""

from __future__ import annotations

import json
import os

import pytest
from click.testing import CliRunner

from independent_composite import Motor, Sag, simulate_event
from loadbayes.cli import main

pytestmark = [pytest.mark.statistical, pytest.mark.usefixtures("no_cost_probe")]

FAN = Motor(rs=0.013, xs=0.067, xm=3.8, rr=0.009, xr=0.17, h_s=1.5, name="fan")
SAGS = ((0.30, 0.20), (0.45, 0.12))
FULL = os.environ.get("LOADBAYES_VALIDATE") == "1"


def _fit(tmp_path, seed: int, hdi: float) -> tuple[dict, dict, str]:
    files = []
    for k, (depth, duration) in enumerate(SAGS):
        df, truth = simulate_event(motor=FAN, t0=0.7, f_m=0.4, q0=0.3,
                                   shares=(0.3, 0.2, 0.5, 0.4, 0.3, 0.3),
                                   sags=(Sag(1.0, depth, duration, 0.02, 0.02),), rate_hz=60.0,
                                   noise=0.005, seed=100 * seed + k, t_end_s=2.5)  # fmt: skip
        path = tmp_path / f"fan{seed}_{k}.csv"
        df.to_csv(path, index=False)
        files.append(str(path))
    out = tmp_path / f"fan{seed}.json"
    res = CliRunner().invoke(
        main,
        ["fit", "composite", *files, "--json", str(out), "--draws", "8000", "--burn", "2000",
         "--chains", "4", "--seed", "0", "--hdi-prob", str(hdi)],
        catch_exceptions=False,
    )  # fmt: skip
    assert res.exit_code == 0, res.output
    return json.loads(out.read_text()), truth, res.output


def _missed(fit: dict, truth: dict) -> list[str]:
    par = fit["parameters"]
    return [
        k for k in ("f_m", "t_prime_s") if not par[k]["hdi_low"] <= truth[k] <= par[k]["hdi_high"]
    ]


@pytest.mark.skipif(FULL, reason="the full count runs below")
def test_the_fan_motor_is_covered_at_the_default_reading(tmp_path):
    fit, truth, output = _fit(tmp_path, 0, 0.99)
    assert fit["settings"]["sample_reading"]["read_as"] == "points"
    assert "samples read as points" in output
    assert not _missed(fit, truth), (fit["parameters"]["f_m"], fit["parameters"]["t_prime_s"])


@pytest.mark.skipif(not FULL, reason="20 fits: make validate (LOADBAYES_VALIDATE=1)")
def test_the_fan_motor_coverage_over_noise_seeds(tmp_path):
    misses = {"f_m": 0, "t_prime_s": 0}
    for seed in range(20):
        fit, truth, _ = _fit(tmp_path, seed, 0.95)
        for k in _missed(fit, truth):
            misses[k] += 1
    assert max(misses.values()) <= 3, misses
