"""Fault edges that span samples: ramps and phasor windows (models/composite_steps.py).

The voltage records here are written in the test: a continuous sag (exact step or a
ramp) sampled as points or as one-cycle window means, so the edges are known exactly.
"""

import numpy as np
import pytest

from loadbayes.models.composite_steps import (
    FitSamples,
    StepGrid,
    edge_runs,
    max_intervals,
    ramp_ends,
)

F_HZ = 60.0


def _v_of(t, start, depth, ramp):
    # Continuous sag: 1 before start, 1 - depth after start + ramp, linear between.
    if ramp == 0:
        return np.where(t < start, 1.0, 1.0 - depth)
    return 1.0 - depth * np.clip((t - start) / ramp, 0.0, 1.0)


def _record(rate, start, depth, ramp, *, phasor=False, noise=0.0, seed=0):
    t = np.arange(int(1.0 * rate) + 1) / rate
    if phasor:  # one-cycle window means, by fine quadrature
        fine = np.linspace(0, 1 / F_HZ, 401)
        v = np.array([np.mean(_v_of(tk - fine, start, depth, ramp)) for tk in t])
    else:
        v = _v_of(t, start, depth, ramp)
    return t, v + noise * np.random.default_rng(seed).standard_normal(t.size)


def _inside(t, start, end):
    return set(np.flatnonzero((t > start) & (t < end)).tolist())


@pytest.mark.parametrize("rate", [30.0, 60.0, 120.0])
def test_an_exact_step_between_samples_is_one_interval(rate):
    t, v = _record(rate, 0.4013, 0.3, 0.0, noise=0.001)
    runs = edge_runs(v, longest=max_intervals(t, 1 / F_HZ))
    assert len(runs) == 1
    k0, k1 = runs[0]
    assert k1 - k0 == 1 and t[k0] < 0.4013 < t[k1]


@pytest.mark.parametrize("rate, ramp", [(60.0, 0.020), (120.0, 0.020), (30.0, 0.010)])
def test_a_short_ramp_becomes_one_edge_with_its_inside_samples_left_out(rate, ramp):
    start = 0.4013
    t, v = _record(rate, start, 0.35, ramp, noise=0.001)
    runs = edge_runs(v, longest=max_intervals(t, 1 / F_HZ))
    assert len(runs) == 1
    k0, k1 = runs[0]
    # The edge holds the whole ramp, and the samples on the ramp are the inside ones.
    assert t[k0] <= start and t[k1] >= start + ramp
    assert set(range(k0 + 1, k1)) == _inside(t, start, start + ramp)


def test_phasor_samples_whose_window_holds_the_step_are_left_out():
    # 4 phasors per cycle (240/s), a one-cycle window: a step spreads over 4 samples.
    rate, start = 240.0, 0.40131
    t, v = _record(rate, start, 0.3, 0.0, phasor=True, noise=0.0005)
    fs = FitSamples.find([t], [v], window_s=1 / F_HZ)
    ((k0, k1),) = fs.edges[0]
    contaminated = _inside(t, start, start + 1 / F_HZ)
    assert contaminated <= set(range(k0 + 1, k1))
    assert fs.left_out == k1 - k0 - 1
    assert np.setdiff1d(np.arange(t.size), fs.keep[0]).tolist() == list(range(k0 + 1, k1))
    # The kept samples' step interval is the edge, in the kept samples' numbering.
    kept = fs.keep[0]
    assert kept[fs.intervals[0][0]] == k0 and kept[fs.intervals[0][0] + 1] == k1


def test_a_ramp_the_samples_resolve_is_no_edge():
    # A 300 ms recovery at 60/s moves 1.7 % per interval: the samples draw it.
    t, v = _record(60.0, 0.4013, 0.3, 0.3)
    assert edge_runs(v, longest=max_intervals(t, 1 / F_HZ)) == []
    # A 50 ms ramp at 120/s spans 6 intervals, more than a one-cycle window makes.
    t, v = _record(120.0, 0.4013, 0.3, 0.05)
    assert edge_runs(v, longest=max_intervals(t, 1 / F_HZ)) == []


def test_noise_alone_and_detect_false_give_no_edge():
    t, v = _record(60.0, 0.4013, 0.0, 0.0, noise=0.005)
    assert edge_runs(v, longest=3) == []
    t, v = _record(60.0, 0.4013, 0.3, 0.02)
    fs = FitSamples.find([t], [v], window_s=1 / F_HZ, detect=False)
    assert fs.left_out == 0 and fs.keep[0].size == t.size


@pytest.mark.parametrize(
    "rate, ramp", [(30.0, 0.050), (60.0, 0.020), (60.0, 0.050), (120.0, 0.010), (120.0, 0.050)]
)
def test_point_samples_on_a_ramp_are_kept_and_the_knots_draw_the_ramp(rate, ramp):
    # Point samples of a linear ramp: every sample kept, the edge a ramp whose knots
    # reproduce the continuous voltage between the samples: with one sample on it, the
    # start (phi) put at the true start and the end by linearity; with more, both ends
    # fixed by the line through them (no phi).
    start, depth = 0.4013, 0.3
    t, v = _record(rate, start, depth, ramp)
    fs = FitSamples.find([t], [v], window_s=0.0)
    assert fs.left_out == 0 and fs.keep[0].size == t.size
    ((k0, k1),) = fs.edges[0]
    assert t[k0] < start < t[k0 + 1] and t[k1 - 1] < start + ramp < t[k1]
    assert k1 - k0 >= 2 and fs.ramps == 1
    angle = -0.2 * (1.0 - v) / depth  # the angle turns with the same shape
    grid = StepGrid.build([t], [v], [angle], intervals=fs.intervals, ends=fs.ends)
    inside = k1 - k0 - 1
    assert grid.n_steps == grid.n_ramps == (1 if inside == 1 else 0)
    t_aug = grid.times(grid.phi_of(np.array([start])[: grid.n_steps]))
    assert t_aug.size == t.size + 2 and np.all(np.diff(t_aug) > 0)
    np.testing.assert_array_equal(t_aug[grid.real], t)
    fine = np.linspace(0.3, 0.6, 3001)
    want = _v_of(fine, start, depth, ramp)
    np.testing.assert_allclose(np.interp(fine, t_aug, grid.v), want, atol=1e-9)
    np.testing.assert_allclose(np.interp(fine, t_aug, grid.delta), -0.2 * (1 - want) / depth,
                               atol=1e-9)  # fmt: skip
    if inside == 1:
        # A start later in its interval moves the end earlier: the same line, steeper.
        late = grid.times(np.array([0.9]))
        assert late[grid.pos[0]] > t_aug[grid.pos[0]] and late[grid.pos_b[0]] < t_aug[grid.pos_b[0]]


def test_a_step_between_point_samples_stays_a_step():
    # No sample inside the edge: the two knots sit side by side, V_k then V_k+1.
    t, v = _record(60.0, 0.4013, 0.3, 0.0)
    fs = FitSamples.find([t], [v], window_s=0.0)
    ((k0, k1),) = fs.edges[0]
    assert k1 == k0 + 1 and fs.ramps == 0
    grid = StepGrid.build([t], [v], [np.zeros(t.size)], intervals=fs.intervals, ends=fs.ends)
    assert grid.n_ramps == 0 and grid.pos_b[0] == grid.pos[0] + 1
    t_aug = grid.times(grid.phi_of(np.array([0.4013])))
    fine = np.linspace(0.3, 0.6, 3001)
    fine = fine[np.abs(fine - 0.4013) > 1e-6]
    np.testing.assert_allclose(np.interp(fine, t_aug, grid.v), _v_of(fine, 0.4013, 0.3, 0.0),
                               atol=1e-12)  # fmt: skip


@pytest.mark.parametrize("rate", [60.0, 120.0])
@pytest.mark.parametrize("noise", [0.0, 0.001])
def test_a_step_into_a_level_that_moves_on_stays_a_step(rate, noise):
    # A grid's bus after a fault (ANDES's IEEE 14-bus case): the voltage steps from 0.952
    # to 0.676 just after a sample, then falls on by itself, 1.9/s easing off with a time
    # constant of 60 ms; the recovery the same way up. The level's first intervals move
    # more than 5% of the step and grew the edge into a ramp through them (read as a
    # ramp, the step was spread over a whole interval: f_m 0.386-0.392, T' 0.14 s for
    # 0.50 at 60/s); they are the level's, and the edge is the step's one interval.
    t = np.arange(int(1.0 * rate) + 1) / rate
    drift = 0.114 * (1 - np.exp(-np.clip(t - 0.5001, 0, None) / 0.06))
    v = np.where(t <= 0.5001, 0.952, 0.676 - drift)
    rec = np.clip(t - 0.6001, 0, None)
    v = np.where(t > 0.6001, 0.80 + 0.09 * (1 - np.exp(-rec / 0.06)), v)
    v = v + noise * np.random.default_rng(3).standard_normal(t.size)
    fs = FitSamples.find([t], [v], window_s=0.0)
    edges = fs.edges[0]
    assert len(edges) == 2 and fs.ramps == 0, edges
    for (k0, k1), at in zip(edges, (0.5001, 0.6001), strict=True):
        assert k1 == k0 + 1 and t[k0] < at < t[k1]


@pytest.mark.parametrize(
    ("fall", "tau_s", "noise"), [(0.114, 0.06, 0.0), (0.06, 0.03, 0.0), (0.114, 0.06, 0.0002)]
)
def test_a_step_into_a_moving_level_read_through_windows_stays_the_windows_smear(
    fall, tau_s, noise
):
    # The same through one-cycle windows centred on the stamps (GridDyn's CMLD bus after
    # a fault: the network answers the motor's current). The window spreads each step
    # over the two intervals beside the sample whose window holds it; the level's first
    # intervals after it joined the edge by the window's 2% growth, and the edge was read
    # as a ramp the phasors resolve through them (GridDyn, 41% sag: T' 0.85-1.67 s for
    # 0.2, NLS noise-free). They are the level's: the edge is the smear's two intervals. (A
    # level moving by less than the noise floor outside the edge is left in it: at 0.05%
    # noise here the record's noise estimate, inflated by the level's own drift, is.)
    t = np.arange(61) / F_HZ
    on, off = 0.5063, 0.6071

    def v_at(x):
        fallen = fall * 0.276 * (1 - np.exp(-np.clip(x - on, 0, None) / tau_s))
        v = np.where(x <= on, 0.952, 0.676 - fallen)
        back = 0.05 * np.exp(-np.clip(x - off, 0, None) / tau_s)
        return np.where(x > off, 0.952 - back, v)

    fine = np.linspace(-0.5 / F_HZ, 0.5 / F_HZ, 401)
    v = np.array([np.mean(v_at(tk + fine)) for tk in t])
    v = v + noise * np.random.default_rng(4).standard_normal(t.size)
    fs = FitSamples.find([t], [v], window_s=1 / F_HZ)
    edges = fs.edges[0]
    assert len(edges) == 2 and fs.ramps == 0, edges
    for (k0, k1), at in zip(edges, (on, off), strict=True):
        # The one sample whose window holds the step is inside; the ones beside it not.
        assert k1 == k0 + 2 and abs(t[k0 + 1] - at) < 0.5 / F_HZ, (edges, at)
    assert fs.left_out == 2


@pytest.mark.parametrize("noise", [0.0, 0.001])
@pytest.mark.parametrize(
    "rate, ramp, start",
    [(60.0, 0.020, 0.4013), (60.0, 0.020, 0.2123), (30.0, 0.050, 0.4013), (120.0, 0.010, 0.4013)],
)
def test_a_ramp_with_one_sample_inside_starts_where_its_straight_line_can_end(
    rate, ramp, start, noise
):
    """A start so early that the line through the inside sample reaches the level after
    only past the next sample was clamped into a kinked line; the chains spent most of
    their time there (issue 21's 60/s event: ESS of the recovery's instant 31-106 of
    48,000 draws, 589-711 without). The start's range now ends there, less a margin
    that keeps the true start inside with 0.1% noise on V, even for a ramp that ends
    just before a sample (0.2123 + 0.020 = 0.2323 < 0.2333)."""
    t, v = _record(rate, start, 0.3, ramp, noise=noise, seed=2)
    fs = FitSamples.find([t], [v], window_s=0.0)
    ((k0, k1),) = fs.edges[0]
    assert k1 == k0 + 2  # one sample inside
    grid = StepGrid.build([t], [v], [np.zeros(t.size)], intervals=fs.intervals, ends=fs.ends)
    lo, hi = grid.left[0], grid.left[0] + grid.width[0]
    assert t[k0] <= lo < start < hi <= t[k0 + 1]  # the truth inside
    # Past the margin every start gives a straight ramp ending inside the last interval.
    from loadbayes.models.composite_steps import RAMP_START_MARGIN

    past = 0.0 if lo == t[k0] else RAMP_START_MARGIN * (t[k0 + 1] - t[k0]) / (hi - lo)
    for phi in np.linspace(past + 0.01, 0.9, 7):
        ta = grid.times(np.array([phi]))
        a, b = ta[grid.pos[0]], ta[grid.pos_b[0]]
        on_line = v[k0] + (v[k0 + 1] - v[k0]) * (b - a) / (t[k0 + 1] - a)
        assert b < t[k1] and on_line == pytest.approx(v[k1], abs=1e-9)


def test_the_start_bound_leaves_the_interval_alone_when_the_inside_sample_is_not_between():
    from loadbayes.models.composite_steps import ramp_start_bound

    # Inside sample beyond the level after (an overshoot): no straight ramp to bound.
    assert ramp_start_bound(np.array([0.0, 1.0, 2.0]), np.array([1.0, 0.6, 0.7])) == 0.0
    # An inside sample near the level after: any start's line ends in the last interval.
    assert ramp_start_bound(np.array([0.0, 1.0, 2.0]), np.array([1.0, 0.6, 0.5])) == 0.0
    # A sample barely off the level before: the start just before it, less the margin.
    got = ramp_start_bound(np.array([0.0, 1.0, 2.0]), np.array([1.0, 0.997, 0.7]))
    assert got == pytest.approx(1.0 - 0.003 / 0.297 - 0.1)


@pytest.mark.parametrize("rate, ramp", [(120.0, 0.030), (120.0, 0.050), (60.0, 0.050)])
def test_a_phasor_ramp_keeps_the_samples_whose_window_lies_on_it(rate, ramp):
    # One-cycle window means of a ramp longer than a step's edge: before, the samples
    # drew it (a line through window means, its corners rounded by the window), and a
    # fast motor read as a slow one (T' 0.15-0.88 s for 0.060 at 120/s, 30 ms). Now the
    # samples whose window lies wholly on the ramp are kept (a window mean of a line is
    # its value at the window's middle), the others left out, and the ramp is drawn
    # through the kept ones, with sharp corners where it meets the levels.
    start, depth, w = 0.4013, 0.35, 1 / F_HZ
    t, v = _record(rate, start, depth, ramp, phasor=True, noise=0.0005)
    fs = FitSamples.find([t], [v], window_s=w)
    ((k0, k1),) = fs.edges[0]
    kept_inside = np.intersect1d(fs.keep[0], np.arange(k0 + 1, k1))
    # _record's window ends at the stamp: on the ramp when [t - W, t] lies in it.
    on_ramp = set(np.flatnonzero((t - w >= start) & (t <= start + ramp)).tolist())
    assert kept_inside.size >= 1 and set(kept_inside.tolist()) <= on_ramp
    assert fs.left_out == k1 - k0 - 1 - kept_inside.size and fs.ramps == 1
    if kept_inside.size >= 2:  # the ramp's ends are fixed by the kept samples' line
        idx = np.concatenate([[k0], kept_inside, [k1]])
        ta, tb = ramp_ends(t[idx], v[idx])
        # The stamps sit half a window after the values they hold (the window's end).
        assert ta == pytest.approx(start + w / 2, abs=1.5e-3)
        assert tb == pytest.approx(start + ramp + w / 2, abs=1.5e-3)


@pytest.mark.parametrize(
    "rate, depth, start",
    [(240.0, 0.06, 0.40131), (240.0, 0.10, 0.40131), (240.0, 0.20, 0.40131),
     (200.0, 0.10, 0.40131), (60.0, 0.08, 0.40 + 0.5 / 60.0)],
)  # fmt: skip
def test_a_shallow_step_smeared_by_the_window_is_still_an_edge(rate, depth, start):
    # With several phasors a window, a step moves each of the samples whose window holds
    # it by a fraction of the step: at 4 a cycle a 20% step moves each by 5%, the core
    # threshold of one interval, and a shallower one by less. No edge was found, the
    # window means were read as a ramp that drove the motor, and the model smeared it
    # once more: the archive generator's 5-30% dips at 4 phasors a cycle gave f_m
    # 1.2-1.4 times the truth, the 95% interval excluding it on 11 events of 12. At
    # 60/s a step half-way between two samples moves each interval by half of it.
    t, v = _record(rate, start, depth, 0.0, phasor=True, noise=0.0005)
    fs = FitSamples.find([t], [v], window_s=1 / F_HZ)
    ((k0, k1),) = fs.edges[0]
    # _record's window ends at the stamp: the samples whose window holds the step.
    contaminated = _inside(t, start, start + 1 / F_HZ)
    assert contaminated <= set(range(k0 + 1, k1))
    assert k1 - k0 <= max_intervals(t, 1 / F_HZ)
    assert np.setdiff1d(np.arange(t.size), fs.keep[0]).tolist() == list(range(k0 + 1, k1))


def test_window_noise_and_a_slow_recovery_at_four_phasors_a_cycle_are_no_edge():
    # The edge's core over several intervals asks them all to move the same way by
    # more than JUMP together: 0.5% noise on the window means, or a 300 ms recovery
    # (2% a window), does not.
    for seed in range(5):
        t, v = _record(240.0, 0.4013, 0.0, 0.0, phasor=True, noise=0.005, seed=seed)
        assert FitSamples.find([t], [v], window_s=1 / F_HZ).edges[0] == []
    t, v = _record(240.0, 0.4013, 0.3, 0.3, phasor=True, noise=0.0005)
    assert FitSamples.find([t], [v], window_s=1 / F_HZ).edges[0] == []
