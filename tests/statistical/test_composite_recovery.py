"""Recovery of the composite load on 48 simulated events (100 under make validate): coverage.

The generator and the quantities are those of ``make validate``
(``python -m loadbayes.studies.calibration.composite_recovery --events 200``): the four
library motors x sags of 15, 30 and 50%, held 0.1-0.5 s, the fault's instant anywhere in
a sample interval, ZIP mixes with negative shares, noise 0.5-2% of |S0|, simulated by
SciPy (DOP853) independently of the fit's kernel.
CI uses shorter records and chains (``CI_SETTINGS``: 2 s at 30 samples/s, 2 chains x
1,000 iterations, 400 burn-in), about 0.8 s of CPU an event; ``make validate`` runs
2.5 s records at 60/s with longer chains.

False-alarm rates, if each quantity's interval covered independently with probability
0.95 (the runs are deterministic: fixed seeds):
- too few hits: 15 or more misses of 100 for one quantity has probability 1.4e-4; over
  the 18 quantities (with the step's instant) at most 0.25%;
- too many hits (intervals too wide) for the 9 quantities the event determines (the
  operating point, the ZIP shares, the motor share): no miss of 100 has probability
  0.59%; three or more of the 9 with none, at most 1.7e-5.
The suite ran 200 events until 29 Nov 2026 (23 misses, at most 1), then 150 (at most 13
misses, on a4 and a5; at least 3 on the determined quantities), then 100 (at most 11
misses, on a4 and a5; none of the 9 with no miss). Since 30 Nov 2026 the suite runs the
first 48 (each motor at each depth 4 times; measured: at most 5 misses, on x_open and
q_c; 2 of the 9 with no miss; contraction ratios 1.80 and 2.92), with the thresholds
scaled to keep the false-alarm rates above: 10 or more misses of 48 has probability
1.1e-4 (at most 0.20% over the 18 quantities); no miss of 48 has probability 0.085, and
5 or more of the 9 with none 4.2e-4. ``make validate`` (LOADBAYES_VALIDATE=1) runs this
test at 100 with the thresholds above, and the study itself at 200.
Power lost (a quantity's true coverage c, the too-few-hits check alone): at 48 a c of
0.85 fails with probability 0.17, 0.80 with 0.50, 0.75 with 0.80; at 100 0.54, 0.92 and
0.99. Intervals too wide (every determined quantity covering 99%) fail at 48 with
probability 0.77 (0.70 at 100).
The quantities on the motor's base symmetry (X', H, Rs, T0, the rating) are left to
over-cover: their intervals are the prior's width along the symmetry (docs/composite.md).
"""

from __future__ import annotations

import os

import numpy as np
import pytest

from loadbayes.studies.calibration.composite_recovery import CI_SETTINGS, run_recovery

pytestmark = pytest.mark.statistical

N_EVENTS = 100 if os.environ.get("LOADBAYES_VALIDATE") == "1" else 48
#: Fewest misses of N_EVENTS that fail a quantity, and most of the 9 determined quantities
#: allowed no miss (module docstring: the false-alarm rates).
TOO_MANY_MISSES, MOST_WITH_NONE = {100: (15, 2), 48: (10, 4)}[N_EVENTS]
DETERMINED = ("p0", "q0", "a1", "a2", "a3", "a4", "a5", "a6", "f_m")


def test_the_events_cover_at_the_nominal_rate():
    # One test, not a module fixture shared by several: under pytest-xdist each worker
    # would fit the events again.
    rec = run_recovery(N_EVENTS, seed=2026, workers=2, **CI_SETTINGS)
    assert all(len(v) == N_EVENTS for v in rec["hits"].values())
    misses = {k: N_EVENTS - sum(v) for k, v in rec["hits"].items()}
    too_few = {k: m for k, m in misses.items() if m >= TOO_MANY_MISSES}
    assert not too_few, (too_few, rec["coverage"])
    # Too many hits (intervals too wide) for what the event determines.
    assert sum(misses[k] == 0 for k in DETERMINED) <= MOST_WITH_NONE, misses
    # Physics, not calibration: a deeper sag moves the motor further from its operating
    # point, so its share of the load is better determined (medians over 16-34 events).
    sd = {
        d: np.median([c["f_m_sd"] for c in rec["contraction"] if c["depth"] == d])
        for d in (0.15, 0.3, 0.5)
    }
    assert sd[0.15] > 1.5 * sd[0.3], sd
    assert sd[0.3] > 1.5 * sd[0.5], sd


@pytest.mark.parametrize("motor", ["small_industrial", "large_industrial"])
def test_the_motor_share_and_t_prime_contract_on_a_30_percent_sag(motor):
    # A 3 s record (the recovery's 2 s records are short for T' = 1.2 s: there the ratio
    # reached 0.54 on large_industrial, so the contraction is checked on a record long
    # enough to see the transient settle). f_m's prior (through the linear block's weak
    # prior) spans far more than [0, 1]; a 30% sag pins it to a few hundredths and
    # shrinks log T' well inside its prior (sd ratio < 0.5: the 95% interval of T' is
    # less than half as wide as the prior's on the log scale).
    from loadbayes.cases.composite_sim import simulate_event
    from loadbayes.core.settings import SamplerSettings
    from loadbayes.fit.composite.driver import fit_composite
    from loadbayes.models.zip_motor import CompositeModel

    # The bound on f_m is the fit's own "well determined" (sd < 0.1, fit/composite/driver.py).
    # Measured with 4 x 6,000 iterations on small_industrial: sd 0.054 with the fault's
    # step placed (its instant unknown), 0.037 with the step read as a ramp (the model
    # that does not know the instant is over-confident about f_m).
    ev, truth = simulate_event(motor, depth=0.3, noise=0.01, seed=8, t_end_s=3.0)
    run = SamplerSettings(draws=3000, burn=1000, chains=2, seed=3)
    fit = fit_composite(CompositeModel(window_s=0), [ev], sampler=run)
    post = fit.posterior
    assert np.std(post.draws["f_m"]) < 0.1
    ratio = np.std(post.draws["log_t_prime"]) / fit.problem.prior.theta_sd[3]
    assert ratio < 0.5, ratio
