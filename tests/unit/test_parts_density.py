"""A model of parts' compiled density is the Python path's, to the bit, state for state.

``fit/composite/parts_density.log_density`` runs the support, the prior, ``theta``, the
parts' constants, every event's solve and sums and the marginal in one compiled call; the
``DesignProblem``'s Python path calls the same functions one by one. On random states about
a fitted one, near and far (many outside the support or with no steady state), both give
the same log-density and the same sums, bit for bit, with one event or three (one with
rows left out), point samples or window means, with and without an angle or the negative
sequence. And the special functions compiled code calls are SciPy's own.
"""

from __future__ import annotations

import math

import numba
import numpy as np
import pytest
from scipy import special
from test_parts_kernel import _events

from loadbayes.core.normal import log_ndtr, ndtr, ndtri
from loadbayes.fit.composite.design import DesignProblem
from loadbayes.models.dynamic import dynamic_model
from loadbayes.models.parts_model import PartsModel


@numba.njit
def _normal(x):  # pragma: no cover - compiled
    return ndtr(x), log_ndtr(x), ndtri(ndtr(x))


def test_the_compiled_normal_functions_are_scipys():
    for x in (-40.0, -12.5, -3.0, -1e-9, 0.0, 0.7, 5.0, 9.0, 39.0):
        got = _normal(x)
        want = (special.ndtr(x), special.log_ndtr(x), special.ndtri(special.ndtr(x)))
        for a, b in zip(got, want, strict=True):
            assert a == b or (math.isnan(a) and math.isnan(b)) or a == b == math.inf


def _python(problem, u, tau):
    density, problem._density = problem._density, None
    try:
        return problem.collapsed(u, tau)
    finally:
        problem._density = density


@pytest.mark.parametrize(
    ("name", "window", "angle", "negative", "events"),
    [("cmld-lite", 1 / 60, False, True, 1), ("cmld-lite", 0.0, True, False, 3),
     ("slm", 1 / 60, True, True, 3), ("slm", 0.0, False, False, 1)],
)  # fmt: skip
def test_the_compiled_density_is_the_python_paths(name, window, angle, negative, events):
    model = dynamic_model(name, f_hz=60.0, window_s=window)
    evs = _events(angle, negative)[-events:]
    problem = DesignProblem(model, evs, model.default_prior(evs))
    assert problem._density is not None
    mean, cov, _, _ = problem.prior.scale_free()
    start = problem.prior.project(mean)
    rng = np.random.default_rng(2)
    tau = np.array([4e4, 3e4, 900.0])[: problem.n_channels]
    feasible = infeasible = 0
    for spread in (0.01, 0.1, 0.5, 1.5):
        for _ in range(25):
            u = start + spread * rng.standard_normal(start.size)
            lp, sums = problem.collapsed(u, tau)
            want, want_sums = _python(problem, u, tau)
            if want_sums is None:
                assert sums is None and lp == -math.inf
                infeasible += 1
                continue
            feasible += 1
            assert lp == want
            for got, ref in zip(sums, want_sums, strict=True):
                for a, b in zip((got.ztz, got.zty, got.yty, got.n),
                                (ref.ztz, ref.zty, ref.yty, ref.n), strict=True):  # fmt: skip
                    np.testing.assert_array_equal(a, b)
    # Both kinds met (measured: 53 and 83 feasible of 100).
    assert feasible >= 20 and infeasible >= 5
    # A state with a NaN is outside, as in Python.
    bad = start.copy()
    bad[0] = math.nan
    assert problem.collapsed(bad, tau) == (-math.inf, None)


@pytest.mark.parametrize(
    "options",
    [dict(motors=("a", "b", "slm"), feeder=False, motor_d=True, electronics=True,
          fit_thresholds=False, window_s=1 / 60),
     dict(motors=("a",), physical_region=False, motor_d=True),
     dict(motors=("b", "a"), electronics=True, negative_sequence="off",
          motor_d_params={"vstall": 0.55, "kp2": 10.0})],
)  # fmt: skip
def test_any_model_of_parts_has_the_python_paths_density(options):
    # Three motors and no feeder with the thresholds held; one motor outside any limits;
    # motor D's own constants and no negative sequence (measured: 76, 77, 53 feasible).
    model = PartsModel(f_hz=60.0, **options)
    evs = _events(True, True)
    problem = DesignProblem(model, evs, model.default_prior(evs))
    start = problem.prior.project(problem.prior.scale_free()[0])
    rng = np.random.default_rng(0)
    tau = np.array([4e4, 3e4, 900.0])[: problem.n_channels]
    feasible = 0
    for spread in (0.01, 0.1, 0.5, 1.5):
        for _ in range(25):
            u = start + spread * rng.standard_normal(start.size)
            lp, sums = problem.collapsed(u, tau)
            want, want_sums = _python(problem, u, tau)
            assert (sums is None) == (want_sums is None)
            if sums is None:
                continue
            feasible += 1
            assert lp == want
            for got, ref in zip(sums, want_sums, strict=True):
                np.testing.assert_array_equal(got.ztz, ref.ztz)
                np.testing.assert_array_equal(got.zty, ref.zty)
    assert feasible >= 40


def test_ar1_noise_keeps_the_python_path():
    # AR(1) sums are whitened again for each rho: the compiled density is not asked.
    model = dynamic_model("slm", f_hz=60.0, window_s=0.0, noise="ar1")
    evs = _events(False, False)[:1]
    problem = DesignProblem(model, evs, model.default_prior(evs))
    u = problem.prior.project(problem.prior.scale_free()[0])
    called = []
    density = problem._density
    problem._density = lambda *a: called.append(a) or density(*a)
    lp, sums = problem.collapsed(u, np.array([1e4, 1e4, 1.0])[: problem.n_channels],
                                 rho=np.array([0.5, 0.3]))  # fmt: skip
    assert not called and math.isfinite(lp) and sums is not None


def test_the_lowest_voltage_is_the_solves():
    # The thresholds' steps ask the events' lowest load-bus voltage (parts_model's
    # lowest_voltage, compiled): the solve's own, to the bit, and NumPy's load bus's to
    # an ulp (measured: 1.1e-16).
    from loadbayes.models.parts import load_bus
    from loadbayes.models.parts_kernel import event_parts
    from loadbayes.models.parts_sums import _arguments

    model = dynamic_model("cmld-lite", f_hz=60.0, window_s=1 / 60)
    evs = _events(True, True)
    mean, cov, _, _ = model.default_prior(evs).scale_free()
    rng = np.random.default_rng(0)
    for _ in range(10):
        theta = rng.multivariate_normal(mean, 0.3 * cov)
        for ev in evs:
            low = model.lowest_voltage(ev, theta)
            fixed, parts, _ = _arguments(model, ev, theta)
            assert low == event_parts(*fixed[:10], *parts)[1].min()
            keep, _ = model.drive_of(ev)
            kept = ev.take(keep) if keep.size < ev.n else ev
            x = model.feeder_x(kept.p[0], kept.q[0], {"x_fd": np.exp(theta[0])})
            assert abs(low - load_bus(kept, model.rx * x, x).event.v.min()) < 1e-14
