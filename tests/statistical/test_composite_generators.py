"""The default composite fit's coverage on events from independent generators (issue 35).

The generators and the truth in the fit's definitions (f_m the motor's share of P0, T'
its transient open-circuit time constant in s) are in
:mod:`loadbayes.studies.calibration.composite_generators`: tests/independent_composite.py
(SciPy), ANDES 2.0's Motor3 and Motor5, GridDyn 0.13.0's CMLDBLU1 with one motor. Each
event is fitted as ``loadbayes fit composite`` fits a plain table at its defaults.

``make test`` fits event 0 of each of ANDES Motor3 and ANDES Motor5 (the independent
generator's events run in test_composite_independent.py): two fits of 8-9 s of CPU each
(measured in the study's log), side by side, plus the simulations (ANDES's runs are
cached on disk) and one GridDyn run for its truth's check. GridDyn's single-motor events
are fitted by ``make validate`` only, for the 12-minute suite's time. ``make validate``
(LOADBAYES_VALIDATE=1) fits 20 events of each of the four.

False-alarm rates (fixed seeds make the outcome deterministic: this is the chance such
seeds fail when every 95% interval has exactly 95% coverage, independently):

- ``make test``: over the Motor3 and Motor5 events (n 2 per quantity), fewer than 1 hit
  (both missed): 0.25% per quantity, 0.5% for the two.
- ``make validate``: per generator and quantity, fewer than 16 of 20 (0.26% each,
  binomial_floor(20, alpha=0.01); of fewer when a simulator cannot run a case, as GridDyn
  could not its 13th: 15 of 19); at most 2.1% over the 8 asserted (no strict xfail is
  left).

A generator the fit does not cover at its defaults is a strict xfail with its measured
numbers (:data:`FULL_XFAIL`), not a looser floor. GridDyn's was one (f_m and T' 9 of its
first 12) until 2026-11-29: its fits did not read the record's angle column, and a
window-read step into the bus's moving voltage became a ramp (docs/composite.md, "Four
generators at the defaults"). Measured since, seed 0, 19 events (the 13th does not run):
f_m 18 of 19, T' 19 of 19. ANDES's fits read the angle too since 2026-11-29 (seed 0, 20
events each): Motor3 f_m 18 -> 19, T' 20 -> 20; Motor5 f_m 18 -> 18, T' 20 -> 20 (docs,
"ANDES: the angle"). Events 0, the ``make test`` pair, are covered either way: Motor3
f_m [0.441, 0.485] -> [0.448, 0.495] for 0.467, Motor5 [0.358, 0.513] -> [0.373, 0.523]
for 0.421.
"""

from __future__ import annotations

import os

import pytest

from loadbayes.cases.griddyn.cases import S_BASE_MVA, Cmld, run_case, skip_reason
from loadbayes.studies.calibration.composite_generators import (
    NEGLIGIBLE_FEEDER,
    run_generators,
    table,
)
from loadbayes.studies.calibration.composite_independent import binomial_floor

pytestmark = pytest.mark.statistical

FULL = os.environ.get("LOADBAYES_VALIDATE") == "1"
N_FULL = 20
QUANTITIES = ("f_m", "t_prime_s")


@pytest.fixture(scope="module")
def results():
    pytest.importorskip("andes", reason="ANDES is in the optional 'andes' extra")
    counts = {"andes_motor3": 1, "andes_motor5": 1}
    if FULL:
        counts = {"independent": N_FULL, "andes_motor3": N_FULL, "andes_motor5": N_FULL}
    if FULL and skip_reason() is None:
        counts["griddyn"] = N_FULL
    return run_generators(counts, seed=0, workers=2)


def test_griddyn_truth_is_the_motors_share():
    # The truth's f_m reads the motor's P from the case with a constant-P static part,
    # whose P must then be exactly its share of the .raw's P (GridDyn's one-pass start
    # leaves a ZIP static part's P off it: the reason for the second run).
    reason = skip_reason()
    if reason:
        pytest.skip(reason)
    cmld = Cmld(f_a=0.0, f_b=0.0, f_d=0.0, f_el=0.0, p1c=0.0, p2c=0.0, **NEGLIGIBLE_FEEDER)
    _, info = run_case(cmld, 0.2, window_s=0.0)
    assert info["event"]["p0"] == pytest.approx(cmld.load_mw / S_BASE_MVA, abs=1e-6)


@pytest.mark.skipif(FULL, reason="the full counts run below")
def test_andes_motor3_and_motor5_events_are_covered(results):
    for k in QUANTITIES:
        hits = sum(results[g]["hits"][k] for g in ("andes_motor3", "andes_motor5"))
        assert hits >= binomial_floor(2, alpha=0.01), (k, "\n" + table(results))


#: Strict xfails of the full count, with what was measured (docs/composite.md, "Four
#: generators at the defaults").
#: ANDES Motor5's f_m is asserted: 18 of 20 above the floor of 16 (measured 2026-11-29,
#: seeds 0-19, with the angle read; T' 20 of 20; the same 18 and 20 without it). Its two
#: misses, [0.631, 0.869] for 0.562 (13% sag) and [0.298, 0.365] for 0.376 (30%), were
#: misses without the angle too ([0.674, 0.977], [0.294, 0.362]) and are the same cases'
#: misses with ANDES's Motor3 (the same first cage, sag and noise, without the angle:
#: [0.585, 0.779], [0.280, 0.332]), so the second cage is not their cause
#: (docs/composite.md, "Four generators at the defaults").
FULL_XFAIL: dict[tuple[str, str], str] = {}
GENERATORS = ("independent", "andes_motor3", "andes_motor5", "griddyn")


@pytest.mark.skipif(not FULL, reason="make validate (LOADBAYES_VALIDATE=1)")
@pytest.mark.parametrize(
    ("generator", "quantity"),
    [
        pytest.param(g, k, marks=pytest.mark.xfail(strict=True, reason=FULL_XFAIL[g, k]))
        if (g, k) in FULL_XFAIL
        else (g, k)
        for g in GENERATORS
        for k in QUANTITIES
    ],
)
def test_each_generator_covers_at_the_binomial_floor(results, generator, quantity):
    if generator not in results:
        pytest.skip(skip_reason())
    res = results[generator]
    floor = binomial_floor(res["events"], alpha=0.01)
    assert res["hits"][quantity] >= floor, (generator, quantity, floor, "\n" + table(results))
