"""``slm`` with AR(1) noise on events the package did not make: its intervals widen honestly.

Two sags (15 % and 25 %, 0.12 s, 20 ms ramps) of one ZIP + motor load behind a feeder,
from the tests' own SciPy simulator (``tests/feeder_generator.py``), recorded at 100
samples/s for 0.5 s (50 rows each), with stationary AR(1) noise added to P and Q (rho
0.7, sd 1 % of the first sample's ``|S|``; written here, noise seed 0). Fitted jointly by
``slm`` at its defaults with white noise and with ``noise="ar1"`` (3000 iterations,
1500 burn-in, 2 chains, sampler seed 0).

**Measured** (this seed; truth ``f_m`` 0.4217, the data-determined share):

============ ================== ====================
fit          f_m 95% interval   rho_p, rho_q medians
============ ================== ====================
white        [0.367, 0.408]     missed
ar1          [0.344, 0.439]     covered; 0.86, 0.54
============ ================== ====================

The AR(1) interval is 2.3 times as wide. Over noise seeds 0-9 (the scan behind this
test, ``LOADBAYES_VALIDATE=1`` runs it): the white fit covered ``f_m`` 3 times in 10, the
AR(1) fit 6 (its interval 1.6-2.6 times as wide); with 1.0 s records (100 rows) 7 and 8.
So AR(1) widens the intervals for the correlated noise, but on 50 rows per event not to
their nominal 95 %: ``rho`` is found low (medians 0.48-0.86, mean 0.64, for a true 0.7; the slow
part of the noise is partly taken up by the model, and the lag-1 estimate of a short
series is biased low), and the series X under AR(1) sits low (truth 0.033 near the top
of its interval; missed in 1 seed of 10, this one, where the white fit's missed in 0: the
whitened rows weigh the sags' edges, where reading ramps between point samples errs, likely).

False-alarm rate: the run is deterministic (fixed seeds; seed 0 was the first tried).
With fresh noise each assertion would fail about as often as the scan says: the AR(1)
fit's coverage of ``f_m`` about 40 % of the time, the white fit's miss about 30 %; the
width ratio (> 1.5) held in all ten.
"""

from __future__ import annotations

import os

import numpy as np
import pytest

from feeder_generator import simulate
from loadbayes.core.settings import SamplerSettings
from loadbayes.fit.composite.driver import fit_composite
from loadbayes.measurements.record import EventRecord
from loadbayes.models.dynamic import dynamic_model

pytestmark = pytest.mark.statistical

RHO, LEVEL, RATE = 0.7, 0.01, 100
SAGS = (0.15, 0.25)
DRAWS, BURN, CHAINS = 3000, 1500, 2


def _ar1(rng, n, rho, sd):
    # Stationary AR(1): the first value from its stationary law.
    e = np.empty(n)
    e[0] = rng.normal(0, sd)
    for k in range(1, n):
        e[k] = rho * e[k - 1] + rng.normal(0, sd * np.sqrt(1 - rho**2))
    return e


@pytest.fixture(scope="module")
def records():
    return {sag: simulate(sag=sag, fs=RATE) for sag in SAGS}


def _events(records, seed):
    rng = np.random.default_rng(seed)
    out = []
    for sag, (t, v, d, p, q, _) in records.items():
        s = LEVEL * np.hypot(p[0], q[0])
        out.append(EventRecord(t, v, p + _ar1(rng, t.size, RHO, s),
                               q + _ar1(rng, t.size, RHO, s), d, f"sag {sag}"))  # fmt: skip
    return out


def _fit(events, noise, seed):
    model = dynamic_model("slm", f_hz=50.0, noise=noise)
    settings = SamplerSettings(draws=DRAWS, burn=BURN, chains=CHAINS, seed=seed)
    return fit_composite(model, events, sampler=settings).posterior


def _interval(post, name):
    return np.percentile(np.asarray(post.draws[name]).ravel(), [2.5, 97.5])


def test_ar1_noise_covers_the_motor_share_the_white_fit_misses(records):
    truth = records[SAGS[0]][-1]["f_m"]
    events = _events(records, 0)
    white, ar = _fit(events, "white", 0), _fit(events, "ar1", 0)
    lo_w, hi_w = _interval(white, "f_m")
    lo_a, hi_a = _interval(ar, "f_m")
    assert not lo_w <= truth <= hi_w, (lo_w, hi_w)
    assert lo_a <= truth <= hi_a, (lo_a, hi_a)
    assert hi_a - lo_a > 1.5 * (hi_w - lo_w)
    # The noise is found correlated, and said so in words and the table's names.
    assert np.median(ar.draws["rho_p"]) > 0.4 and np.median(ar.draws["rho_q"]) > 0.4
    assert "rho_p" not in white.draws
    assert "AR(1) noise" in ar.extra_json["parts"]["residuals"]["noise"]


@pytest.mark.skipif(os.environ.get("LOADBAYES_VALIDATE") != "1",
                    reason="ten noise seeds, 2-4 minutes: make validate")  # fmt: skip
def test_over_ten_noise_seeds_ar1_covers_more_often_with_wider_intervals(records):
    truth = records[SAGS[0]][-1]["f_m"]
    covered = {"white": 0, "ar1": 0}
    for seed in range(10):
        events = _events(records, seed)
        widths = {}
        for noise in covered:
            lo, hi = _interval(_fit(events, noise, seed), "f_m")
            covered[noise] += bool(lo <= truth <= hi)
            widths[noise] = hi - lo
        assert widths["ar1"] > 1.5 * widths["white"], (seed, widths)
    # Measured: 6 and 3 of 10 (the module docstring).
    assert covered["ar1"] >= covered["white"] + 2, covered
