"""Short voltage ramps between point samples (issue 21): read as ramps, not steps.

The events come from tests/independent_composite.py (SciPy only, no loadbayes code):
two motors not in the library (T' 0.060 s and 0.70 s), point samples at 30, 60 and
120/s, a sag whose edges are straight ramps of 10, 20 or 50 ms, starting inside a sample
interval. Fitted with ``window_s=0`` (point samples), every sample on a ramp is kept and
the edge is a ramp through them (models/composite_steps.py).

1. The bias (deterministic): on 15 nearly noise-free 2.5 s events (noise 1e-5; each ramp
   placed so that at least one sample is on it; not the fast motor at 30/s, where an
   exact step is read with f_m 0.391 too), the NLS start's f_m is within 0.003 of the
   truth (measured: at most 0.0015). With the ramps read as steps (the samples on them
   left out) it missed by up to 0.046 (0.446 for 0.400 at 120/s, 10 ms; docs/composite.md,
   "Ramps between point samples"; measured there with the same sag at 1.0123 s).
2. Coverage: 6 short events with 0.5% noise (``CELLS``: each motor at each rate, each
   ramp twice, the ramp's start anywhere in an interval), each fitted at a fixed, shorter run (4
   chains x 4,000 draws, burn 1,000: about 6-10 s of CPU a fit on 1.2 s records). The
   test fails when fewer than 5 of 6 of the 95% intervals of f_m or of T' hold the
   truth: P(at most 4 of 6) = 0.033 per quantity with exact 95% intervals, about 6.5%
   in all (fixed seeds: the run is deterministic). That is ``make validate``'s
   (LOADBAYES_VALIDATE=1); ``make test`` fits the first 3 events (the same events and
   seeds: both motors, 30 and 60/s, the three ramps) and fails when fewer than 2 of 3
   hold the truth: P(at most 1 of 3) = 0.0073 per quantity, about 1.5% in all. Power
   lost: a true coverage of 80% fails the 6 with probability 0.34 (per quantity), the 3
   with 0.10; of 50%, 0.89 and 0.50. The longer loop is
   ``make validate``'s ``composite_independent`` study (144 events, half of them point
   samples with 0-50 ms ramps, fitted at the defaults).
3. Phasor samples (one-cycle window means) of a ramp longer than a step's edge: the
   samples whose window lies wholly on the ramp are kept and the ramp drawn through
   them, the others left out. Before, the samples drew the ramp (a line through window
   means, its corners rounded by the window) and a fast motor read as a slow one. The
   check (deterministic, like 1.): on four nearly noise-free 2.5 s events the NLS start's
   T' is within 30% of the truth and its f_m within 0.01 (measured 2026-11-25: T' -17%
   to +11%, f_m within 0.007; before: T' +56% to +1460%, f_m off by up to 0.015).
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

import numpy as np
import pytest

from loadbayes.core.settings import SamplerSettings
from loadbayes.fit.composite.driver import fit_composite
from loadbayes.models.zip_motor import CompositeModel
from loadbayes.studies.calibration.composite_independent import binomial_floor, event_records

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
import independent_composite as ic  # noqa: E402

pytestmark = pytest.mark.statistical

MOTORS = ("small_fast", "large_slow")
RATES = (30.0, 60.0, 120.0)
RAMPS_S = (0.010, 0.020, 0.050)
#: The coverage events: each motor at each rate, each ramp twice; the fast motor's 10 ms
#: ramp at 120/s among them (read as a step, its NLS f_m was 0.446 for 0.400).
CELLS = (
    ("small_fast", 30.0, 0.020),
    ("large_slow", 30.0, 0.010),
    ("small_fast", 60.0, 0.050),
    ("large_slow", 60.0, 0.020),
    ("small_fast", 120.0, 0.010),
    ("large_slow", 120.0, 0.050),
)
#: ``make test`` fits the first 3 (module docstring); ``make validate`` the 6.
N_CELLS = len(CELLS) if os.environ.get("LOADBAYES_VALIDATE") == "1" else 3


def _event(motor, rate, ramp, start, *, noise, seed, t_end=1.2, f_m=0.4):
    sag = ic.Sag(start, 0.36, 0.2, ramp, ramp)
    df, truth = ic.simulate_event(
        motor=motor, t0=0.7, f_m=f_m, q0=0.3, shares=(0.3, 0.3, 0.4, 0.4, 0.3, 0.3),
        sags=(sag,), rate_hz=rate, noise=noise, seed=seed, t_end_s=t_end,
    )  # fmt: skip
    return event_records(df, f"ramp_{motor}_{rate:g}_{1e3 * ramp:g}ms.csv"), truth


def _on_ramp_start(rate, ramp, base=1.0):
    # A start inside an interval with a sample on the ramp (a 10 ms ramp at 30/s: just
    # before a sample); the ramp out (0.2 s later) then has one too.
    dt = 1.0 / rate
    return round(base * rate) * dt + dt - min(0.5 * ramp, 0.4 * dt) + 1e-4


@pytest.mark.parametrize("motor", MOTORS)
def test_the_ramp_read_as_a_ramp_leaves_no_bias_in_f_m(motor):
    short = SamplerSettings(draws=100, burn=50, chains=2, seed=0, threads=1)
    got = {}
    # The fast motor's T' (0.060 s) is under two intervals at 30/s: there even an exact
    # step is read with f_m 0.391 (NLS, this record), so it is left out of this check.
    for rate in RATES[1:] if motor == "small_fast" else RATES:
        for ramp in RAMPS_S:
            start = _on_ramp_start(rate, ramp)
            ev, truth = _event(motor, rate, ramp, start, noise=1e-5, seed=1, t_end=2.5)
            fit = fit_composite(CompositeModel(window_s=0.0), ev, sampler=short)
            assert fit.problem.fit_samples.ramps == 2, (rate, ramp)
            assert fit.posterior.settings["steps"]["ramps"]["count"] == 2
            # The NLS estimate (the baseline's draws are its Gaussian, sd ~1e-4 here).
            got[rate, 1e3 * ramp] = float(np.mean(fit.baseline.draws["f_m"]))
    err = {k: round(v - truth["f_m"], 4) for k, v in got.items()}
    assert max(abs(e) for e in err.values()) < 0.003, err


def test_f_m_and_t_prime_covered_on_point_samples_with_ramps():
    rng = np.random.default_rng(21)
    n, hits, rows = 0, {"f_m": 0, "t_prime_s": 0}, []
    settings = SamplerSettings(draws=4000, burn=1000, chains=4, seed=0, threads=1)
    for i, (motor, rate, ramp) in enumerate(CELLS[:N_CELLS]):
        start = 0.4 + (int(rng.integers(0, 4)) + rng.uniform(0.05, 0.95)) / rate
        f_m = float(rng.uniform(0.3, 0.6))
        ev, truth = _event(motor, rate, ramp, start, noise=0.005, seed=100 + i, f_m=f_m)
        fit = fit_composite(CompositeModel(window_s=0.0), ev, sampler=settings)
        n += 1
        for k in hits:
            lo, hi = np.percentile(np.asarray(fit.posterior.draws[k], float), [2.5, 97.5])
            hits[k] += bool(lo <= truth[k] <= hi)
            rows.append((motor, rate, 1e3 * ramp, k, round(lo, 3), round(hi, 3), truth[k]))
    floor = binomial_floor(n)
    assert n == N_CELLS and floor == {6: 5, 3: 2}[n]
    assert all(h >= floor for h in hits.values()), (hits, rows)


#: Phasor events with ramps longer than a step's edge (motor, rate, fall s, recovery s,
#: f_m, depth, duration): the known limitation's event first (a 30 ms recovery at 120/s:
#: NLS T' was 0.94 s for 0.060), then 50 ms ramps at 60 and 120/s, both motors.
PHASOR_RAMPS = (
    ("small_fast", 120.0, 0.005, 0.030, 0.6, 0.5, 0.1),
    ("small_fast", 60.0, 0.050, 0.050, 0.4, 0.36, 0.2),
    ("small_fast", 120.0, 0.050, 0.050, 0.4, 0.36, 0.2),
    ("large_slow", 120.0, 0.030, 0.050, 0.4, 0.36, 0.2),
)


@pytest.mark.parametrize("case", PHASOR_RAMPS, ids=lambda c: f"{c[0]}-{c[1]:g}-{1e3 * c[3]:g}ms")
def test_phasor_ramps_read_as_ramps_leave_no_bias_in_t_prime(case):
    motor, rate, fall, rec, f_m, depth, duration = case
    sag = ic.Sag(1.0123, depth, duration, fall, rec)
    df, truth = ic.simulate_event(
        motor=motor, f_m=f_m, sags=(sag,), rate_hz=rate, sampling="phasor", noise=1e-5,
        seed=1, t_end_s=2.5,
    )  # fmt: skip
    short = SamplerSettings(draws=100, burn=50, chains=2, seed=0, threads=1)
    fit = fit_composite(
        CompositeModel(), event_records(df, f"phasor_ramp_{motor}_{rate:g}.csv"), sampler=short
    )
    steps = fit.posterior.settings["steps"]
    assert steps["ramps"]["count"] >= 1 and steps["left_out"]["count"] > 0
    t_prime = float(np.median(fit.baseline.draws["t_prime_s"]))
    assert abs(t_prime / truth["t_prime_s"] - 1) < 0.3, (t_prime, truth["t_prime_s"])
    assert abs(float(np.mean(fit.baseline.draws["f_m"])) - truth["f_m"]) < 0.01
