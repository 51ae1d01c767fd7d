"""The composite model's physics, its linear block and the NLS start."""

from __future__ import annotations

import numpy as np
import pytest

from loadbayes.cases.composite_sim import simulate_event
from loadbayes.fit.composite.nls import nls
from loadbayes.fit.composite.problem import CompositeProblem, theta_of
from loadbayes.models.composite import (
    SCALE_FREE_MATRIX,
    composition,
    design,
    motor_physical,
    motor_response,
    predict,
)
from loadbayes.models.composite_prior import CompositePrior
from loadbayes.models.composite_steps import EPS_FRACTION
from loadbayes.models.motor_library import MOTORS


def _theta(name, t0=0.6):
    m = MOTORS[name]
    return np.log([m.rs, m.xp, m.x - m.xp, m.tp_s, m.h_s, t0])


def _beta(truth):
    pz = truth["p0"] * (1 - truth["f_m"])
    return np.array(
        [pz * truth["a1"], pz * truth["a2"], pz * truth["a3"]]
        + [truth["q0"] * truth[a] for a in ("a4", "a5", "a6")]
        + [truth["f_m"] * truth["p0"]]
    )


@pytest.mark.parametrize("name", sorted(MOTORS))
def test_model_reproduces_the_scipy_simulation(name):
    # The independent generator (solve_ivp) and the model (compiled kernel) agree, both
    # driven by the straight line through the samples (the fit's steps=False reading).
    ev, truth = simulate_event(
        name, depth=0.4, noise=0.0, zip_p=(0.6, -0.3, 0.7), t_end_s=2.0, step=False
    )
    p, q = predict(ev, _theta(name), _beta(truth))
    assert np.max(np.abs(p - truth["p_clean"])) < 1e-4
    assert np.max(np.abs(q - truth["q_clean"])) < 1e-4


@pytest.mark.parametrize("name", sorted(MOTORS))
@pytest.mark.parametrize("frac", [0.0, 0.4, 0.93])
def test_a_step_inside_a_sample_interval_is_reproduced_where_it_fell(name, frac):
    # SciPy driven by the continuous sag (a step at start_s, between two samples) against
    # the fit's model with the step placed at the same instant by its fraction phi.
    fs, k = 60.0, 30
    start = (k + frac) / fs
    ev, truth = simulate_event(
        name, depth=0.4, noise=0.0, start_s=start + 1e-9, t_end_s=1.5, fs=fs, recovery_s=0.0
    )
    prob = CompositeProblem([ev], CompositePrior.default([ev]), window_s=0)
    assert prob.n_steps == 2 and prob.grid.k_of.tolist()[0] == k
    eps = EPS_FRACTION
    phis = [((t - left) / w - 1.5 * eps) / (1 - 3 * eps) for t, left, w in zip(
        (truth["t_step0"], truth["t_step1"]), prob.grid.left, prob.grid.width, strict=True
    )]  # fmt: skip
    phis = np.clip(phis, 0.0, 1.0)
    u = np.concatenate([SCALE_FREE_MATRIX[:5] @ _theta(name), phis])
    ((pm, qm),) = prob.responses(u)
    zp, zq = design(ev, pm, qm)
    assert np.max(np.abs(zp @ _beta(truth) - truth["p_clean"])) < 1e-4
    assert np.max(np.abs(zq @ _beta(truth) - truth["q_clean"])) < 1e-4
    # The straight-line reading of the same samples misses by far more (why steps exist).
    p_lin, _ = predict(ev, _theta(name), _beta(truth))
    if name != "krause_2250hp" or frac < 0.9:
        assert np.max(np.abs(p_lin - truth["p_clean"])) > 1e-3


def test_composition_inverts_the_truth():
    ev, truth = simulate_event("large_industrial", depth=0.3, noise=0.0, zip_q=(1.2, -0.5, 0.3))
    pm, qm = motor_response(ev, _theta("large_industrial"))
    comp = composition(_beta(truth), pm[0], qm[0])
    for k in ("p0", "q0", "a1", "a2", "a3", "a4", "a5", "a6", "f_m", "mva_m", "q_c"):
        assert comp[k] == pytest.approx(truth[k], rel=1e-9, abs=1e-12), k


def test_a_change_of_motor_base_leaves_p_and_q_unchanged():
    # The symmetry the scale-free coordinates rest on: Z * k, T0 / k, H / k.
    ev, _ = simulate_event("small_industrial", depth=0.35, noise=0.0)
    th = _theta("small_industrial")
    k = np.log(2.7)
    th2 = th + np.array([k, k, k, 0.0, -k, -k])
    p1, q1 = motor_response(ev, th)
    p2, q2 = motor_response(ev, th2)
    np.testing.assert_allclose(p1, 2.7 * p2, rtol=1e-9)
    np.testing.assert_allclose(q1, 2.7 * q2, rtol=1e-9)
    z1, z2 = design(ev, p1, q1), design(ev, p2, q2)
    np.testing.assert_allclose(z1[0], z2[0], rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(z1[1], z2[1], rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(SCALE_FREE_MATRIX[:5] @ th, SCALE_FREE_MATRIX[:5] @ th2, atol=1e-12)


def test_theta_of_inverts_the_scale_free_map():
    th = _theta("krause_2250hp", t0=0.45)
    u = (SCALE_FREE_MATRIX @ th)[:5]
    np.testing.assert_allclose(theta_of(u, np.log(0.45)), th, atol=1e-12)


def test_closure_recovers_a_krause_motor():
    m = MOTORS["krause_3hp"]  # Xs = Xr: the closure is exact
    phys = motor_physical(_theta("krause_3hp"), f_hz=60.0)
    for k in ("rs", "xs", "xm", "rr", "xr", "h_s"):
        assert phys[k] == pytest.approx(getattr(m, k), rel=1e-9), k
    assert phys["t_prime_s"] == pytest.approx(m.tp_s)


def test_prior_conditional_of_t0_is_the_gaussian_conditional():
    prior = CompositePrior.default([simulate_event(noise=0.0)[0]])
    rng = np.random.default_rng(3)
    th = prior.theta_mean + prior.theta_sd * rng.standard_normal((20000, 6))
    u = th @ SCALE_FREE_MATRIX.T
    # Regress log T0 on u by least squares: must match the closed-form gain and sd.
    x = np.column_stack([np.ones(len(u)), u[:, :5]])
    coef, res, *_ = np.linalg.lstsq(x, u[:, 5], rcond=None)
    _, _, gain, sd = prior.scale_free()
    np.testing.assert_allclose(coef[1:], gain, atol=0.02)
    assert np.sqrt(res[0] / len(u)) == pytest.approx(sd, rel=0.03)


def test_nls_recovers_the_motor_share_and_the_ratio_b2():
    ev, truth = simulate_event("small_industrial", depth=0.4, noise=0.002, seed=4)
    prob = CompositeProblem([ev], CompositePrior.default([ev]), window_s=0)
    res = nls(prob)
    th = theta_of(res.u[:5], np.log(0.6))
    pm, qm = motor_response(ev, th)
    comp = composition(res.betas[0], pm[0], qm[0])
    assert comp["f_m"] == pytest.approx(truth["f_m"], abs=0.02)
    assert comp["p0"] == pytest.approx(truth["p0"], abs=0.002)
    # (X - X') / T' is what the flux transient shows (b2 of the regression form).
    assert np.exp(th[2] - th[3]) == pytest.approx(
        (truth["x_open"] - truth["x_prime"]) / truth["t_prime_s"], rel=0.15
    )
    assert np.all(res.sigma < 0.003)


def test_compiled_collapsed_density_equals_the_python_path():
    evs = [
        simulate_event("small_industrial", depth=d, seed=i, t_end_s=1.5)[0]
        for i, d in enumerate((0.3, 0.5))
    ]
    prob = CompositeProblem(evs, CompositePrior.default(evs))
    u = (SCALE_FREE_MATRIX @ _theta("small_industrial"))[:5]
    tau = np.array([9000.0, 11000.0])
    lp, sums = prob.collapsed(u, tau)
    want = prob.log_collapsed(prob.sums(u), u, tau)
    assert lp == pytest.approx(want, rel=1e-10)
    np.testing.assert_allclose(sums[1].ztz, prob.sums(u)[1].ztz, rtol=1e-12)
    # No steady state (a motor loaded past its breakdown torque): -inf, no sums.
    bad = u.copy()
    bad[1] += 3.0  # X' T0 twenty times larger
    assert prob.collapsed(bad, tau) == (-np.inf, None)


@pytest.mark.parametrize("n_events", [1, 2])
def test_the_figure_has_no_empty_panel(n_events):
    # One P and one Q panel per event plus three pair plots, each with something drawn:
    # the grid once left blank axes beside a single event.
    from loadbayes.core.settings import SamplerSettings
    from loadbayes.fit.composite import fit_composite, predictive_band
    from loadbayes.models.zip_motor import CompositeModel
    from loadbayes.plots.composite import plot_composite
    from loadbayes.plots.fit import pyplot

    evs = [
        simulate_event("small_industrial", depth=d, t_end_s=1.5, fs=30, seed=k)[0]
        for k, d in enumerate((0.3, 0.45)[:n_events])
    ]
    run = SamplerSettings(draws=120, burn=60, chains=1, seed=0)
    fit = fit_composite(CompositeModel(window_s=0), evs, sampler=run)
    fig = plot_composite(
        fit.posterior, evs, predictive_band(fit.posterior, evs), baseline=fit.baseline
    )
    try:
        assert len(fig.axes) == 2 * n_events + 3
        for ax in fig.axes:
            assert ax.axison and (ax.lines or ax.collections), ax.get_title()
        assert fig.axes[-3].get_xlabel() == "motor share of P0, f_m"
    finally:
        pyplot().close(fig)
