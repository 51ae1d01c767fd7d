"""Recovery of the composite load on simulated events (a CI-sized version of the check).

The full check (``python -m loadbayes.studies.calibration.composite_recovery --events 200``, in
``make validate``) fits 200 events; CI fits 12 (the test-time budget) with the same
generator and settings: the four library motors x sags of 15, 30 and 50%, held
0.1-0.5 s, ZIP mixes with negative shares, noise 0.5-2%.

False-alarm rates (if every interval covered with probability 0.95 independently):
per quantity, 4 or more misses in 12 has probability 0.0022 (checked for f_m, T', p0,
q0: at most 0.9% together); the pooled coverage of the 17 quantities below 0.85 has
probability below 1e-6 under independence (the quantities of one event are correlated,
which makes it larger, though still small: at most 3 events fully missed would be
needed). The runs are deterministic (fixed seeds).
"""

from __future__ import annotations

import numpy as np
import pytest

from loadbayes.studies.calibration.composite_recovery import run_recovery

pytestmark = pytest.mark.statistical


@pytest.fixture(scope="module")
def recovery():
    return run_recovery(12, seed=2026, draws=1600, burn=700, t_end_s=2.0)


@pytest.mark.parametrize("name", ["f_m", "t_prime_s", "p0", "q0"])
def test_intervals_cover_the_key_quantities(recovery, name):
    misses = len(recovery["hits"][name]) - sum(recovery["hits"][name])
    assert misses <= 3, (name, recovery["hits"][name])


def test_pooled_coverage(recovery):
    pooled = np.mean([h for v in recovery["hits"].values() for h in v])
    assert pooled >= 0.85, recovery["coverage"]


@pytest.mark.parametrize("motor", ["small_industrial", "large_industrial"])
def test_the_motor_share_and_t_prime_contract_on_a_30_percent_sag(motor):
    # A 3 s record (the recovery's 2 s records are short for T' = 1.2 s: there the ratio
    # reached 0.54 on large_industrial, so the contraction is checked on a record long
    # enough to see the transient settle). f_m's prior (through the linear block's weak
    # prior) spans far more than [0, 1]; a 30% sag pins it to a few hundredths and
    # shrinks log T' well inside its prior (sd ratio < 0.5: the 95% interval of T' is
    # less than half as wide as the prior's on the log scale).
    from loadbayes.cases.composite_sim import simulate_event
    from loadbayes.fit.composite import fit_composite

    ev, truth = simulate_event(motor, depth=0.3, noise=0.01, seed=8, t_end_s=3.0)
    fit = fit_composite([ev], draws=1600, burn=700, chains=2, seed=3)
    post = fit.posterior
    assert np.std(post.draws["f_m"]) < 0.06
    ratio = np.std(post.draws["log_t_prime"]) / fit.problem.prior.theta_sd[3]
    assert ratio < 0.5, ratio
