"""The composite fit, at its defaults, on 12 events it did not make (issue 21).

The events come from tests/independent_composite.py (SciPy only, no loadbayes code): two
motors not in the library (T' 0.060 s and 0.70 s), 30/60/120 samples/s, ramps of 0, 10,
20 and 50 ms, the fault's instant inside a sample interval, point and one-cycle phasor
samples, 0.5% noise (the first 12 cases of
:func:`loadbayes.studies.calibration.composite_independent.independent_cases`: each
ramp at each rate, both motors and both samplings six times each). ``make validate`` runs
the same study on 144 events (three times the full 48-cell crossing).

Each fit runs at the defaults (what a user gets; point samples with ``window_s=0``),
one thread; two fit side by side. The CI tier runs the first 3 events and issue 21's
phasor event (``ISSUE_CASE``: the fast motor, one-cycle phasors at 60/s, 20 ms ramps;
read as points its f_m interval was 0.352-0.394 for 0.400), four fits (83 s of wall for
five on 2 cores with the sampler's jumps from regions, 29 Nov 2026; the sixth and then
the fifth were cut that day and the next to keep the suite under 12 minutes); ``make
validate`` the 144.

Before the edges and the run-until-converged (main at 39e819f) the first 12 gave f_m
11/12 and T' 9/12; with them, f_m 12/12 and T' 10/12 (the first 6: 6/6 and 6/6). Per
event in docs/composite.md ("Events the package did not make").

Since 30 Nov 2026 ``make test`` fits the issue event alone (about 40% of the four fits'
CPU; 59 s summed for the four on the idle machine) and ``make validate``
(LOADBAYES_VALIDATE=1) the first 3 events and the issue event together, as the suite did
before. The issue event is fitted with the seed it had in the four (3: event ``i`` of a run
gets ``seed + i``), so its draws are those of before.

False-alarm rate: the issue event fails when its ``f_m`` interval misses 0.400: 0.05 with
an exact 95% interval. Under ``make validate`` the 3 events also fail when fewer than 2 of
3 of the 95% intervals of ``f_m`` or of ``t_prime_s`` hold the truth: P(at most 1 of 3) =
0.0073 per quantity, about 6.4% in all (the runs are deterministic: fixed seeds).
Power lost in ``make test``: the 3 events' check of ``f_m`` and ``t_prime_s`` (a true
coverage of 80% fails it with probability 0.10, of 50% with 0.50); the issue event alone
fails with probability 1 - coverage of ``f_m`` (0.20 at 80%), and ``t_prime_s`` on
independent events stays checked in ``make test`` by test_composite_ramps.py.
"""

from __future__ import annotations

import os

import pytest

from loadbayes.studies.calibration.composite_independent import (
    ISSUE_CASE,
    binomial_floor,
    run_independent,
    table,
)

pytestmark = pytest.mark.statistical

N_EVENTS = 3
#: The issue event's seed in the run of ``N_EVENTS`` + 1 (event ``i`` gets ``seed + i``).
ISSUE_SEED = N_EVENTS


@pytest.mark.skipif(
    os.environ.get("LOADBAYES_VALIDATE") != "1",
    reason="4 fits: make validate (LOADBAYES_VALIDATE=1); make test fits the issue event",
)
def test_f_m_and_t_prime_cover_on_independent_events():
    res = run_independent(N_EVENTS, seed=0, workers=2, extra=[ISSUE_CASE])
    floor = binomial_floor(N_EVENTS)
    assert floor == 2
    first, issue = res["per_event"][:N_EVENTS], res["per_event"][N_EVENTS]
    hits = {k: sum(r["hits"][k] for r in first) for k in ("f_m", "t_prime_s")}
    assert all(h >= floor for h in hits.values()), (hits, "\n" + table(res))
    # The samples read as window means: the fast motor's f_m is no longer read low.
    assert issue["hits"]["f_m"], issue["interval"]


def test_the_issue_events_f_m_is_covered_read_as_window_means():
    # The same fit as the issue event's above (its case, its seed 3), alone.
    res = run_independent(0, seed=ISSUE_SEED, workers=1, extra=[ISSUE_CASE])
    (issue,) = res["per_event"]
    # The samples read as window means: the fast motor's f_m is no longer read low.
    assert issue["hits"]["f_m"], (issue["interval"], "\n" + table(res))
