"""The feeder loop marched in time (``models/parts_march.py``) on a fit's own draws.

The posterior is the tests' short cmld-lite fit of one 15 % sag from the SciPy feeder
simulator (``tests/conftest.py``'s ``cmld_lite_short_nc``: one chain of 300, frozen,
its static Q still wild, where the sweeps fail at deep sags). ``play_draws`` is called
with the arguments ``predict`` gives it (captured), three ways: as ``predict`` runs it
(the four sweeping tries, the march where none settles), with the sweeps' tolerance at
1e-12, and marching every draw (``only_march``).

**Where the sweeps settle, the march agrees.** At point samples and 240/s (below 1/h_max,
so no sweep merges samples into one RK4 step) the two solve the same equations: the
march in order, each sample's Newton to 1e-12 of ``|V_L|``; the sweeps until one moves
``V_L`` by less than ``tol``, which leaves an error up to ``tol rho / (1 - rho)`` for a
contraction ``rho`` (the slowest settle in about 200 sweeps: ``rho`` up to 0.99, so 100
``tol``), and P, Q move by at most about 10 times that (the load's ``|dS / dV_L|`` at these
draws). At ``tol`` 1e-12 that is 1e-9: the bound asserted. Measured (40 draws each at 30,
50, 70 % sags): at most 2.8e-12 at 30 and 50 %, 2.3e-10 at 70 %, medians 1.2e-12 to
1.5e-12. At the default ``tol`` 1e-7 the medians are 1e-7 to 3e-7 and the worst differ
by up to 0.02 p.u. at the record's last samples: there motor A, stalled and turning
backwards (w = -1.6), has its flux ringing at ``wb (1 - w)``, and ``h`` times that, 4.1,
is past RK4's stability bound on the imaginary axis (2.83), so both solvers' numbers
grow from their rounding (1e-13 at 1.7 s to 2e-3 at 1.8 s): the fit's own motor model,
not the loop.

**The draws no sweep settles play or collapse.** Of the fixture's 150 draws, 3 at 70 %
and 3 at 80 % failed numerically before the march; after it none does (2 + 1 play, 1 at
80 % collapses, its root reaching the nose), and the 115 and 95 that settled keep their
numbers byte for byte (sha256 of every Played field, measured when the march was added).

Deterministic (fixed seeds): no false alarm.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

import loadbayes.fit.composite.predict as predict_module
from loadbayes.fit.composite.predict import predict
from loadbayes.models.parts_play import COLLAPSES, FAILS, PLAYS, play_draws
from loadbayes.posterior import Posterior

pytestmark = pytest.mark.integration


def _captured(monkeypatch, post, sag, draws, told=None):
    """``play_draws``' arguments and result as ``predict`` calls it at this sag.

    ``told``: a list the prediction itself is appended to.
    """
    got = {}

    def spy(*a, **k):
        got["call"] = (a, k, play_draws(*a, **k))
        return got["call"][2]

    monkeypatch.setattr(predict_module, "play_draws", spy)
    pred = predict(post, sag=sag, duration=0.1, draws=draws, seed=0)
    monkeypatch.undo()
    if told is not None:
        told.append(pred)
    return got["call"]


@pytest.mark.parametrize("sag", [0.3, 0.5, 0.7])
def test_where_the_sweeps_settle_the_march_agrees(cmld_lite_short_nc, monkeypatch, sag):
    post = Posterior.from_netcdf(cmld_lite_short_nc)
    a, k, _ = _captured(monkeypatch, post, sag, 40)
    swept = play_draws(*a, **{**k, "tol": 1e-12})
    marched = play_draws(*a, **k, only_march=True)
    assert np.array_equal(swept.why, marched.why)  # the same draws play and collapse
    ok = swept.ok
    assert ok.sum() >= 30
    d = np.maximum(np.abs(swept.p - marched.p), np.abs(swept.q - marched.q))[ok].max(1)
    assert d.max() < 1e-9, d.max()
    assert np.median(d) < 1e-11, np.median(d)


def test_the_draws_no_sweep_settles_are_marched(cmld_lite_short_nc, monkeypatch):
    # Also the fit as it is at deep sags, the check test_predict_collapse.py made on 100
    # draws of this chain (80 and 67 played, 20 and 33 collapsed, none failed; before the
    # march 2 and 3 failed): here the same predictions on predict's 150 (200 asked of the
    # 300), measured 118 and 98 play, 32 and 52 collapse, none fails numerically. At most
    # one of the 300 may fail: a failure here is the solver's.
    post = Posterior.from_netcdf(cmld_lite_short_nc)
    marched = fails = 0
    for sag in (0.7, 0.8):
        told = []
        a, k, played = _captured(monkeypatch, post, sag, 200, told)
        out = told[0].outcome
        assert out is not None and out["collapses"]["n"] >= 1, out  # deep enough to matter
        fails += out["fails_numerically"]["n"]
        n = a[1].n
        by_march = played.iterations == n  # the march returns the samples it played
        marched += int(by_march.sum())
        assert played.ok[by_march].all() or (played.why[by_march] == COLLAPSES).any()
        assert int(np.sum(played.why == FAILS)) <= 1
        # Marching every draw gives each the outcome the tries and the march gave it.
        alone = play_draws(*a, **k, only_march=True)
        assert np.array_equal(alone.why, played.why)
    # The frozen draws still reach the march: 3 at 70 % and 3 at 80 % when it was added;
    # 2 since motor_kernel.OSC_STEP, with which the sweeps settle the draws whose motor
    # the load turned backwards (tests/unit/test_motor_backwards.py).
    assert marched >= 2
    assert fails <= 1, fails


def test_a_feeder_too_big_collapses_in_the_march(cmld_lite_short_nc, monkeypatch):
    # Every draw's feeder six times the fit's (test_predict_collapse.py's big feeder): at a
    # 70 % sag the draws with an operating point have no root continuing through the sag.
    post = Posterior.from_netcdf(cmld_lite_short_nc)
    x = np.array(post.draws["log_x_fd"], dtype=float)
    post.draws["log_x_fd"] = x + 1.8
    a, k, _ = _captured(monkeypatch, post, 0.7, 20)
    alone = play_draws(*a, **k, only_march=True)
    started = np.isfinite(alone.low)  # the others have no steady state before the fault
    assert started.sum() >= 5
    assert (alone.why[started] == COLLAPSES).all(), alone.why
    assert not alone.ok[started].any()


def test_with_a_window_the_march_reports_its_trajectorys_window_means(cmld_lite_short_nc,
                                                                      monkeypatch):  # fmt: skip
    # A fit read as one-cycle phasor window means (window_s 0.02): the march solves the
    # loop at the instants (as without a window: the record has no gaps) and reports the
    # motors' window means through that load bus. Where a sample's window holds no step
    # of V, a window mean differs from the point value by W^2 / 24 P'' (the mean of a
    # smooth curve over W): bounded here by the point trajectory's second differences
    # (and 1.5 for their own error). Near a step the two differ by the step's share of
    # the window: not checked.
    post = Posterior.from_netcdf(cmld_lite_short_nc)
    a, k, _ = _captured(monkeypatch, post, 0.5, 20)
    point = play_draws(*a, **k, only_march=True)
    w = 0.02
    windowed = play_draws(dataclasses.replace(a[0], window_s=w), *a[1:], **k, only_march=True)
    assert np.array_equal(point.why, windowed.why)
    assert (point.why == PLAYS).sum() >= 15
    t, v = a[1].t, a[1].v
    steps = t[1:][np.abs(np.diff(v)) > 0.02]
    clear = np.all(np.abs(t[:, None] - steps[None, :]) > w / 2 + (t[1] - t[0]), axis=1)
    clear &= t < t[-1] - w / 2 - (t[1] - t[0])  # past the last sample the input is held
    dt = t[1] - t[0]
    for i in np.flatnonzero(point.ok):
        p = point.p[i]
        curv = np.zeros_like(p)
        curv[1:-1] = np.abs(p[2:] - 2 * p[1:-1] + p[:-2]) / dt**2
        reach = int(np.ceil(w / 2 / dt)) + 1  # the window's samples and one more
        bound = np.array([curv[max(0, j - reach) : j + reach + 1].max() for j in range(p.size)])
        diff = np.abs(windowed.p[i] - p)
        assert np.all(diff[clear] <= w * w / 24 * bound[clear] * 1.5 + 1e-9), i
        assert diff[t < steps[0] - w].max() < 1e-12  # before the fault: steady, the same
        assert diff[~clear].max() > 1e-3  # and the window's means are not the point values
