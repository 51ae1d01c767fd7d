"""Issue 38's check over 20 generated archives (``make validate``): the rate it fails at.

Each archive is tests/pool_generator.py's: stations A, B, C with two bays of 30 events
(180 events over a year), D with 4 a bay, failed and unconverged fits among them; its
own seed (200-219), pooled with 4 chains x 1,000 draws.

Issue 38's check on one archive: the 95% monthly bands cover the truth at 90% or more of
the (unit, month) cells. The bands of one unit move together (a curve), so an archive
misses the 90% more often than independent cells would. Measured before this test was
written, on seeds 100-114: 0 of 15 archives missed it, the cells' mean coverage 0.970,
A and B said alike in 29 of 30 bay pairs. The test asserts at least 16 of the 20 meet
it: with a true miss rate of 5% that fails with probability 0.3% (Binomial(20, 0.95)),
at 10% with 4.3%: the test's false-alarm rate. And the cells' coverage over all 20 at
0.93 or more (its sd across archives is about 0.03, so under 0.01 over 20: four sd
below 0.97); A and B (same curves) said alike in 80% of the bay pairs or more, A and C
(different) never.

About two minutes on the 2 shared cores: LOADBAYES_VALIDATE=1 only.
"""

import os
import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from loadbayes.archive import pool  # noqa: E402
from pool_generator import archive, monthly_truth  # noqa: E402

pytestmark = [
    pytest.mark.statistical,
    pytest.mark.skipif(
        os.environ.get("LOADBAYES_VALIDATE") != "1",
        reason="the full count runs under make validate",
    ),
]

ARCHIVES = 20


def test_the_bands_cover_the_truth_over_20_archives():
    per_archive, cells, alike, apart = [], [], [], []
    for i in range(ARCHIVES):
        frame, _ = archive(200 + i, stations=("A", "B", "C", "D"), events=30, few={"D": 4})
        part = pool(frame, draws=1000, seed=i).parts["f_m"]
        mo = part.monthly
        hits = []
        for station, bay in part.units:
            r = mo[(mo.station == station) & (mo.bay == bay)].sort_values("month")
            t = monthly_truth(station, bay)
            hits += list((r["low"].to_numpy() <= t) & (t <= r["high"].to_numpy()))
        per_archive.append(np.mean(hits))
        cells += hits
        verdict = part.alike.set_index(["a", "b"])["verdict"]
        for bay in ("T1", "F2"):
            alike.append(verdict[(f"A / {bay}", f"B / {bay}")] == "alike")
            apart.append(verdict[(f"A / {bay}", f"C / {bay}")] != "alike")
    met = int(np.sum(np.array(per_archive) >= 0.9))
    print(f"archives meeting 90%: {met} of {ARCHIVES}; cells covered {np.mean(cells):.3f}")
    print(f"A~B said alike {np.mean(alike):.2f}; A~C not said alike {np.mean(apart):.2f}")
    assert met >= 16, per_archive
    assert np.mean(cells) >= 0.93
    assert np.mean(alike) >= 0.8 and all(apart)
