"""The record table's rows around and inside a phase-to-ground fault (issue 40, the reader).

The waveforms are made here with numpy, not with the package's simulator: a static
constant-admittance load on three phases, one phase's voltage lowered by 40% for five
cycles, white noise; optionally a decaying offset in the faulted phase's current.
"""

from __future__ import annotations

import numpy as np
import pytest

from loadbayes.recordings.comtrade import Waveforms
from loadbayes.recordings.record import record_table

F0 = 50.0
PER_SAMPLE_CYCLE = 64
Y = complex(0.8, -0.3)  # the load's admittance per phase (p.u.)


def _record(t_fault: float, *, seed: int, noise: float = 0.002, offset: float = 0.0):
    rng = np.random.default_rng(seed)
    n = int(0.6 * F0 * PER_SAMPLE_CYCLE)
    t = np.arange(n) / (F0 * PER_SAMPLE_CYCLE)
    shift = np.array([0.0, -2 * np.pi / 3, 2 * np.pi / 3])[:, None]
    amp = np.ones((3, n))
    amp[0, (t >= t_fault) & (t < t_fault + 5 / F0)] = 0.6
    v = np.sqrt(2) * amp * np.cos(2 * np.pi * F0 * t + shift)
    i = np.sqrt(2) * amp * abs(Y) * np.cos(2 * np.pi * F0 * t + shift + np.angle(Y))
    if offset:
        on = t >= t_fault
        i[0, on] += offset * np.exp(-(t[on] - t_fault) / 0.03)
    v = v + noise * rng.standard_normal(v.shape)
    i = i + noise * rng.standard_normal(i.shape)
    return Waveforms(t, v * 6350.0, i * 100.0, F0, F0 * PER_SAMPLE_CYCLE, "", {})


# P (p.u. of the first row's |S1|) before and inside the fault: P1 = 3 |V1|^2 Re(Y)
# over |S1| = 3 |V1|^2 |Y|, with V1 = (0.6 + 1 + 1) / 3 inside.
P_BEFORE = Y.real / abs(Y)
P_INSIDE = ((0.6 + 2.0) / 3.0) ** 2 * Y.real / abs(Y)


@pytest.mark.parametrize("per_cycle", [1, 4])
def test_the_row_that_holds_the_inception_is_flagged_as_straddling(per_cycle):
    # Inceptions at 16 instants over a cycle (near phase a's zero crossings the step
    # is in the amplitude only, and the plain fit's misfit stays under 1%). Every row
    # not flagged must read P at one of the two levels, within 2% of P0 (the noise
    # moves P by about 0.3%); on the code before, the row whose window centre is at the
    # zero-crossing inception read P 12% of P0 off the nearer level, unflagged.
    for k in range(16):
        t_fault = 0.2 + k / 16 / F0
        c = record_table(_record(t_fault, seed=k), per_cycle=per_cycle).columns
        near = np.abs(c["t_s"] - t_fault) < 1.0 / F0
        kept = near & ~c["straddle"]
        off = np.minimum(np.abs(c["p"] - P_BEFORE), np.abs(c["p"] - P_INSIDE)) / P_BEFORE
        assert np.all(off[kept] < 0.02), (t_fault, c["t_s"][kept], off[kept])
        # ... and the clearing edge, five cycles on, the same way (3%: the window that
        # starts at the clearing can be read through the offset filter, which moves it
        # by about 2%, as the table's note on rows right after a step says).
        near = np.abs(c["t_s"] - t_fault - 5 / F0) < 1.0 / F0
        kept = near & ~c["straddle"]
        assert np.all(off[kept] < 0.03), (t_fault, c["t_s"][kept], off[kept])


def test_steady_rows_are_not_flagged():
    # A half-cycle change of 5% is far above what the noise makes (0.2% per sample).
    c = record_table(_record(0.2013, seed=3), per_cycle=4).columns
    steady = (np.abs(c["t_s"] - 0.2013) > 1.5 / F0) & (np.abs(c["t_s"] - 0.3013) > 1.5 / F0)
    assert not c["straddle"][steady].any()


def test_the_offset_filter_inside_an_unbalanced_fault_measured():
    # The decaying-offset filter in unbalanced rows (V2/V1 0.15 here), measured rather
    # than ruled out: without an offset in the currents (a static load) its test does not
    # fire inside the fault, so the rows are the plain phasors; with a 30 ms offset of
    # 40% of the current's peak in the faulted phase, it is what brings P back to the
    # truth (per_cycle 4, 3 seeds: worst row 1.5-2.0% of P0 off with --dc off, under
    # 0.6% with it).
    for seed in range(3):
        plain = record_table(_record(0.2013, seed=seed, noise=0.005), per_cycle=4).columns
        inside = (plain["t_s"] > 0.2013 + 0.012) & (plain["t_s"] < 0.3013 - 0.012)
        assert plain["unbalanced"][inside].all()
        assert not plain["dc_filtered"][inside].any()
        w = _record(0.2013, seed=seed, noise=0.005, offset=0.5)
        on = record_table(w, per_cycle=4).columns
        off = record_table(w, per_cycle=4, dc="off").columns
        err_on = np.max(np.abs(on["p"][inside] - P_INSIDE)) / P_BEFORE
        err_off = np.max(np.abs(off["p"][inside] - P_INSIDE)) / P_BEFORE
        assert on["dc_filtered"][inside].any()
        assert err_on < 0.006 < 0.012 < err_off, (seed, err_on, err_off)
