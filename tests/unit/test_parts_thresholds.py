"""The sampled thresholds of a model of parts: motor D's stall, the electronics' trip.

The likelihood is flat in a threshold its events never reach, so the sampler's own step
(``fit/composite/thresholds.py``) takes prior draws there without solving the model;
where an event reaches it, it solves. Checked on events from the tests' own SciPy
feeder simulator (``tests/feeder_generator.py``) and on hand-made records.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from feeder_generator import simulate
from loadbayes.export.partsload import parts_load
from loadbayes.fit.composite.design import DesignProblem
from loadbayes.fit.composite.predict_scope import fitted_thresholds
from loadbayes.inference.condlinear import GroupSums
from loadbayes.measurements.record import EventRecord
from loadbayes.models.dynamic import dynamic_model
from loadbayes.models.part_priors import THRESHOLD_PRIORS, draw_thresholds


def _event(sag):
    t, v, d, p, q, _ = simulate(sag=sag)
    return EventRecord(t, v, p, q, d, f"sag {sag}")


def _problem(sag):
    model = dynamic_model("cmld-lite", f_hz=50.0)
    ev = _event(sag)
    return DesignProblem(model, [ev], model.default_prior([ev])), model


def test_the_thresholds_are_sampled_coordinates_with_their_priors_and_limits():
    model = dynamic_model("cmld-lite", f_hz=50.0)
    assert model.thresholds == ("vstall", "tstall", "vd1", "vd2")
    assert {"vstall", "log_tstall", "vd1", "vd2"} <= set(model.theta_names)
    fixed = dynamic_model("cmld-lite", f_hz=50.0, fit_thresholds=False)
    assert fixed.thresholds == () and "vstall" not in fixed.theta_names
    assert dynamic_model("slm").thresholds == ()  # no motor D, no electronics
    prior = model.default_prior([_event(0.15)])
    i = {n: model.theta_names.index(n) for n in ("vstall", "log_tstall", "vd1", "vd2")}
    u = prior.scale_free()[0][: len(model.theta_names)].copy()
    u = prior.project(u)
    assert prior.inside(u)
    assert u[i["vstall"]] == pytest.approx(0.60) and u[i["log_tstall"]] == pytest.approx(
        math.log(0.033)
    )
    bad = u.copy()
    bad[i["vd2"]] = bad[i["vd1"]] - 0.01  # Vd2 must lie 0.05 below Vd1
    assert not prior.inside(bad)
    bad = u.copy()
    bad[i["vstall"]] = 1.3  # no stall voltage above 1 p.u.
    assert not prior.inside(bad)
    # A user's prior by name moves the centre.
    mine = dynamic_model("cmld-lite", priors={"vstall": (0.5, 0.02)}).default_prior([_event(0.15)])
    assert mine.mean[i["vstall"]] == pytest.approx(0.5)


def test_a_threshold_changes_the_likelihood_only_where_the_voltage_reaches_it():
    problem, model = _problem(0.5)  # the load bus goes well below 0.6 p.u.
    prior = problem.prior
    u = prior.project(prior.scale_free()[0][: problem.n_free].copy())
    iv = model.theta_names.index("vstall")
    low = problem.conditional_moves().lowest_voltage(u)
    assert low < 0.55
    a = problem.sums(u)
    hi = u.copy()
    hi[iv] = low + 0.05  # stalls (the voltage sits below it for the fault)
    lo = u.copy()
    lo[iv] = max(low - 0.3, 0.06)  # never reached
    lo2 = lo.copy()
    lo2[iv] += 0.1 if lo[iv] + 0.1 < low else 0.0
    s_hi, s_lo, s_lo2 = problem.sums(hi), problem.sums(lo), problem.sums(lo2)
    assert a is not None and s_hi is not None
    # Two values both below the lowest voltage: the same sums; one above: other sums.
    assert np.allclose(s_lo[0].ztz, s_lo2[0].ztz) and np.allclose(s_lo[0].zty, s_lo2[0].zty)
    assert not np.allclose(s_hi[0].zty, s_lo[0].zty)
    assert isinstance(s_hi[0], GroupSums)


def test_over_a_shallow_event_the_step_draws_the_prior_almost_without_solving():
    # Fixed seed 0, 4000 steps: the pair's draws are the prior's (mean within 4 standard
    # errors: false-alarm rate about 6e-5 per check), the model never solved.
    problem, model = _problem(0.1)
    moves = problem.conditional_moves()
    u = problem.prior.project(problem.prior.scale_free()[0][: problem.n_free].copy())
    tau = np.array([1e4, 1e4, 1.0])
    lp, sums = problem.collapsed(u, tau)
    before = problem.evaluations
    rng = np.random.default_rng(0)
    iv = model.theta_names.index("vstall")
    x = []
    for _ in range(4000):
        u, lp, sums = moves(u, lp, sums, lambda c: problem.collapsed(c, tau), rng)
        x.append(u[iv])
    x = np.array(x)
    assert moves.lowest_voltage(u) > 0.8
    # A solve only for the prior's far tail that reaches the event's lowest voltage (Vd1
    # above about 0.85 p.u.: 3 sd out, about 0.15 % of 4000 proposals, 14 measured).
    assert problem.evaluations - before <= 40
    _, c, s = THRESHOLD_PRIORS["vstall"]
    assert abs(x.mean() - c) < 4 * s / math.sqrt(x.size)
    assert 0.9 < x.std() / s < 1.1
    assert lp == pytest.approx(problem.collapsed(u, tau)[0])  # the density it carried is right


def test_a_fitted_parameter_set_exports_its_own_thresholds():
    opts = dynamic_model("cmld-lite", f_hz=50.0).options()
    values = {"p0": 0.8, "q0": 0.2, "v0": 1.0, "cq2": 0.1, "cq1": 0.05, "cq0": 0.05,
              "a1": 0.3, "a2": 0.3, "f_s": 0.4, "x_fd": 0.1, "r_fd": 0.035,
              "f_d": 0.15, "f_el": 0.1, "vstall": 0.55, "tstall": 0.05, "vd1": 0.72,
              "vd2": 0.45}  # fmt: skip
    for t, (rs, xo, xp, tp, h) in {"_a": (0.04, 1.8, 0.12, 0.1, 0.1),
                                   "_b": (0.03, 1.8, 0.19, 0.2, 0.5)}.items():  # fmt: skip
        values |= {"rs" + t: rs, "x_open" + t: xo, "x_prime" + t: xp, "t_prime_s" + t: tp,
                   "h_s" + t: h, "t0" + t: 0.7, "f_m" + t: 0.175}  # fmt: skip
    pl = parts_load(values, model="cmld-lite", options={"model_options": opts})
    assert pl.options["motor_d_params"]["vstall"] == 0.55
    assert pl.options["motor_d_params"]["tstall"] == 0.05
    assert (pl.options["vd1"], pl.options["vd2"]) == (0.72, 0.45)


def _draws(model, n, rng, vstall_sd):
    d = draw_thresholds(rng, n)
    d["vstall"] = 0.6 + vstall_sd * rng.standard_normal(n)
    return {k: np.asarray(v) for k, v in d.items()}


def test_a_users_prior_reweights_a_fitted_threshold_or_says_why_not():
    model = dynamic_model("cmld-lite", f_hz=50.0)
    rng = np.random.default_rng(1)
    n = 4000
    prior = dict(THRESHOLD_PRIORS)
    pick = np.arange(200)
    # Left to the prior (posterior = prior): a nearby prior reweights the draws.
    d = _draws(model, n, rng, 0.05)
    near = prior | {"vstall": ("normal", 0.57, 0.04)}
    p2, th, notes = fitted_thresholds(model, d, pick, {}, near, ["vstall"], rng)
    assert "reweights" in notes[0]
    assert abs(np.mean(th["vstall"]) - 0.575) < 0.02  # product of N(.6,.05) and N(.57,.04)
    # A prior far from every draw: drawn from the prior given, and said.
    far = prior | {"vstall": ("normal", 0.3, 0.01)}
    th0 = draw_thresholds(np.random.default_rng(2), pick.size, far)
    _, th, notes = fitted_thresholds(model, d, pick, dict(th0), far, ["vstall"], rng)
    assert "takes them from the prior given" in notes[0]
    assert np.allclose(th["vstall"], th0["vstall"])
    # Determined by the events (a narrow posterior) and a prior far from it: refused.
    d = _draws(model, n, rng, 0.005)
    with pytest.raises(ValueError, match="the fitted events determine it"):
        fitted_thresholds(model, d, pick, dict(th0), far, [], rng)
    # No prior given: each played draw carries the posterior's own.
    _, th, notes = fitted_thresholds(model, d, pick, dict(th0), prior, [], rng)
    assert notes == [] and np.allclose(th["vstall"], d["vstall"][pick])
