"""``slm`` where its model is true: a ZIP and one motor behind a feeder, simulated apart.

Two sags (15 % and 25 %, 0.12 s, 20 ms ramps) of one load, recorded at 50 samples/s
with 0.5 % noise on P and Q, from the tests' own SciPy simulator
(``tests/feeder_generator.py``: the feeder's loop solved at every instant, which the
package never does in a fit). Fitted jointly by ``slm`` at its defaults (published
priors, motors held physical), 6000 iterations x 2 chains, seed 7.

Each asserted interval is a 95 % one; with the seed fixed the test is deterministic,
and on a repeat with fresh seeds each of the five would miss about 5 % of the time
(jointly at most about 23 %, less since they are correlated): the seed was not chosen
to pass (7 was the first tried). What it checks beyond coverage: the shares are
physical and T0 (the rating's scale), which the positive sequence hardly sees, keeps
much of its prior's spread.
"""

from __future__ import annotations

import numpy as np
import pytest

from feeder_generator import simulate
from loadbayes.core.settings import SamplerSettings
from loadbayes.fit.composite.driver import fit_composite
from loadbayes.measurements.record import EventRecord
from loadbayes.models.dynamic import dynamic_model

pytestmark = pytest.mark.statistical


@pytest.fixture(scope="module")
def fit_and_truth():
    rng = np.random.default_rng(7)
    events, truth = [], None
    for sag in (0.15, 0.25):
        t, v, d, p, q, truth = simulate(sag=sag)
        noise = 0.005 * np.hypot(p[0], q[0])
        events.append(EventRecord(t, v, p + rng.normal(0, noise, t.size),
                                  q + rng.normal(0, noise, t.size), d, f"sag {sag}"))  # fmt: skip
    model = dynamic_model("slm", f_hz=50.0)
    fit = fit_composite(model, events, sampler=SamplerSettings(draws=6000, burn=3000, chains=2,
                                                               seed=7))  # fmt: skip
    return fit.posterior, truth


@pytest.mark.parametrize("name", ["f_m", "rs", "h_s", "x_prime", "x_fd"])
def test_slm_covers_the_truth_where_its_model_is_true(fit_and_truth, name):
    post, truth = fit_and_truth
    x = np.asarray(post.draws[name]).ravel()
    lo, hi = np.percentile(x, [2.5, 97.5])
    assert lo <= truth[name] <= hi, f"{name}: truth {truth[name]:.4g} outside [{lo:.4g}, {hi:.4g}]"


def test_slm_shares_are_physical_and_the_prior_is_named(fit_and_truth):
    post, _ = fit_and_truth
    for name in ("f_m", "f_s", "a1", "a2", "a3"):
        x = np.asarray(post.draws[name])
        assert (x >= 0).all() and (x <= 1).all()
    # T0 (so the rating) is seen by the positive sequence only through the motor's
    # loading: its posterior keeps at least half the prior's spread (sd_log 0.25).
    spread = float(np.std(np.log(np.asarray(post.draws["t0"]).ravel())))
    assert spread > 0.5 * 0.25, spread
