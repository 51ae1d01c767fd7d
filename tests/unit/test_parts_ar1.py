"""AR(1) noise for a model of parts: the sums in closed form in rho, kernel = NumPy, rho found.

- :func:`~loadbayes.inference.ar1.whitened` of :func:`~loadbayes.inference.ar1.ar_moments`
  equals the sums of the Prais-Winsten rows formed directly (segments broken at gaps);
- the compiled kernel's AR(1) sums (``parts_kernel.event_sums``) equal NumPy's from the
  channels' arrays, to 1e-9 on random draws, gaps and windows included;
- ``DesignProblem.collapsed(u, tau, rho=...)`` is the white-noise collapsed density of
  the whitened arrays, and ``resum`` gives the same for a new rho without a solve;
- ``draw_rho`` fed by ``residual_stats`` of the closed-form sums recovers the rho of a
  simulated AR(1) residual (seeded; the posterior sd is about 0.02 at 2000 rows, the
  tolerance 0.06).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from test_parts_kernel import _events

from loadbayes.fit.composite.design import ARSums, DesignProblem
from loadbayes.inference.ar1 import ar_moments, draw_rho, residual_stats, whitened
from loadbayes.inference.condlinear import GroupSums
from loadbayes.measurements.record import EventRecord
from loadbayes.models.dynamic import dynamic_model


def _prais_winsten(z, y, first, rho):
    # The whitened rows, formed directly.
    zw, yw = np.empty_like(z), np.empty_like(y)
    s = math.sqrt(1 - rho * rho)
    for k in range(y.size):
        if k == 0 or first[k]:
            zw[k], yw[k] = s * z[k], s * y[k]
        else:
            zw[k], yw[k] = z[k] - rho * z[k - 1], y[k] - rho * y[k - 1]
    return zw, yw


def test_the_whitened_sums_are_a_closed_form_in_rho():
    rng = np.random.default_rng(1)
    z, y = rng.normal(size=(40, 4)), rng.normal(size=40)
    first = np.zeros(40, dtype=bool)
    first[[0, 13, 14, 30]] = True  # a one-row segment too
    zz, zy, yy = ar_moments(z, y, first)
    for rho in (-0.9, 0.0, 0.35, 0.8):
        zw, yw = _prais_winsten(z, y, first, rho)
        assert np.allclose(whitened(zz, rho), zw.T @ zw, rtol=1e-12, atol=1e-12)
        assert np.allclose(whitened(zy, rho), zw.T @ yw, rtol=1e-12, atol=1e-12)
        assert math.isclose(whitened(yy, rho), yw @ yw, rel_tol=1e-12)
    # rho = 0 is the white sums.
    assert np.allclose(whitened(zz, 0.0), z.T @ z)
    # The residual sums draw_rho reads, at any beta.
    beta = rng.normal(size=4)
    e = y - z @ beta
    nxt = np.flatnonzero(~first)
    want = [e[nxt] @ e[nxt - 1], e[nxt - 1] @ e[nxt - 1], e[first] @ e[first], 4.0]
    assert np.allclose(residual_stats(zz, zy, yy, beta, 4.0), want, rtol=1e-10)


@pytest.mark.parametrize(
    ("name", "window", "angle", "negative"),
    [("cmld-lite", 0.0, True, True), ("cmld-lite", 1 / 60, False, False),
     ("slm", 1 / 60, True, True)],
)  # fmt: skip
def test_the_compiled_ar_sums_are_numpys(name, window, angle, negative):
    model = dynamic_model(name, f_hz=60.0, window_s=window, noise="ar1")
    events = _events(angle, negative)
    prior = model.default_prior(events)
    mean, cov, _, _ = prior.scale_free()
    rng = np.random.default_rng(0)
    checked, gapped = 0, 0
    for _ in range(25):
        theta = rng.multivariate_normal(mean, 0.3 * cov)
        for ev in events:
            ch = model.channels(ev, theta)
            got = model.event_sums(ev, theta, ar=True)
            if ch is None or got is None:
                continue
            white, (mzz, mzy, myy, segments) = got
            # The white sums are the white path's, to the bit.
            for a, b in zip(model.event_sums(ev, theta), white, strict=True):
                assert np.array_equal(a, b)
            first = model.first_rows(ev)
            assert segments == np.count_nonzero(first)
            gapped += segments > 1
            for g in range(2):
                zz, zy, yy = ar_moments(ch[g][0], ch[g][1], first)
                for a, b in ((zz, mzz[g]), (zy, mzy[g]), (yy, myy[g])):
                    assert np.allclose(a, b, rtol=1e-9, atol=1e-9)
            checked += 1
    assert checked > 25 and gapped > 0


def test_the_ar_collapsed_density_is_the_whitened_arrays():
    model = dynamic_model("slm", f_hz=60.0, window_s=1 / 60, noise="ar1")
    events = _events(True, True)
    problem = DesignProblem(model, events, model.default_prior(events))
    u = problem.prior.scale_free()[0]
    tau = np.array([4e4, 3e4, 1e3])
    rho = np.array([0.6, -0.3])
    lp, sums = problem.collapsed(u, tau, rho=rho)
    # The same density from the whitened channel arrays, summed as white noise.
    direct = []
    for ev, ch in zip(events, problem.channels(u), strict=True):
        first = model.first_rows(ev)
        zs, ys = [], []
        for g, (z, y) in enumerate(ch):
            if g < 2:
                z, y = _prais_winsten(z, y, first, rho[g])
            zs.append(z)
            ys.append(y)
        direct.append(GroupSums.from_arrays(zs, ys))
    want = problem.log_collapsed(direct, u, tau)
    # The log marginal is ill-conditioned in Z'Z (x^2, x, 1 nearly collinear): the white
    # path's compiled and NumPy sums give densities 4e-9 apart here too.
    assert math.isfinite(lp) and math.isclose(lp, want, rel_tol=2e-8)
    # A new rho without a solve: the same as a fresh call.
    evals = problem.evaluations
    again = problem.resum(sums, np.array([0.2, 0.5]))
    assert problem.evaluations == evals
    lp2, _ = problem.collapsed(u, tau, rho=np.array([0.2, 0.5]))
    assert math.isclose(problem.log_collapsed(again, u, tau), lp2, rel_tol=1e-12)
    # White noise is untouched: rho None is the white sums.
    lpw, _ = problem.collapsed(u, tau)
    assert math.isclose(lpw, problem.log_collapsed(problem.sums(u), u, tau), rel_tol=1e-12)


def test_rho_is_recovered_from_an_ar1_residual():
    rng = np.random.default_rng(11)
    n, rho_true, sd = 2000, 0.7, 0.01
    z = np.column_stack([np.ones(n), np.linspace(0, 1, n)])
    e = np.empty(n)
    e[0] = rng.normal(0, sd)
    for k in range(1, n):
        e[k] = rho_true * e[k - 1] + rng.normal(0, sd * math.sqrt(1 - rho_true**2))
    beta = np.array([1.0, -0.2])
    y = z @ beta + e
    first = np.zeros(n, dtype=bool)
    first[[0, 700]] = True  # two segments
    zz, zy, yy = ar_moments(z, y, first)
    stats = residual_stats(zz, zy, yy, beta, 2.0)
    tau = 1 / (sd**2 * (1 - rho_true**2))  # the innovations' precision
    rho, draws = 0.0, []
    for it in range(3000):
        rho, _ = draw_rho(stats, tau, rho, rng)
        if it >= 500:
            draws.append(rho)
    assert abs(np.mean(draws) - rho_true) < 0.06, np.mean(draws)
    assert 0.005 < np.std(draws) < 0.05


def test_the_threshold_steps_carry_the_ar_density():
    # cmld-lite's own steps (fit/composite/thresholds.py) under AR(1) noise: over a deep
    # sag they solve, and the density and sums they carry are the AR(1) ones at rho.
    from feeder_generator import simulate

    t, v, d, p, q, _ = simulate(sag=0.5)
    ev = EventRecord(t, v, p, q, d, "deep")
    model = dynamic_model("cmld-lite", f_hz=50.0, noise="ar1")
    problem = DesignProblem(model, [ev], model.default_prior([ev]))
    moves = problem.conditional_moves()
    u = problem.prior.project(problem.prior.scale_free()[0][: problem.n_free].copy())
    tau, rho = np.array([1e4, 1e4, 1.0]), np.array([0.5, 0.3])
    lp, sums = problem.collapsed(u, tau, rho=rho)
    rng = np.random.default_rng(0)
    start = u.copy()
    for _ in range(30):
        u, lp, sums = moves(u, lp, sums, lambda c: problem.collapsed(c, tau, rho=rho), rng)
    assert not np.array_equal(u, start)
    assert isinstance(sums, ARSums)
    again, fresh = problem.collapsed(u, tau, rho=rho)
    assert lp == pytest.approx(again)
    assert np.allclose(sums[0].ztz, fresh[0].ztz)


def test_rho_max_bounds_the_draws_and_is_checked():
    # A residual that is nearly a random walk: unbounded, rho runs to it; bounded at 0.9,
    # every draw stays inside and piles at the bound.
    rng = np.random.default_rng(5)
    e = np.cumsum(rng.normal(0, 0.01, 400))
    z = np.ones((400, 1))
    first = np.zeros(400, dtype=bool)
    zz, zy, yy = ar_moments(z, e, first)
    stats = residual_stats(zz, zy, yy, np.zeros(1), 1.0)
    for top, low in ((0.999, 0.95), (0.9, 0.85)):
        rho, draws = 0.0, []
        for _ in range(500):
            rho, _ = draw_rho(stats, 1e4, rho, rng, top)
            draws.append(rho)
        assert max(draws) <= top and np.median(draws[100:]) > low
    with pytest.raises(ValueError, match="rho_max"):
        dynamic_model("slm", noise="ar1", rho_max=1.0)
    model = dynamic_model("slm", noise="ar1", rho_max=0.9)
    assert model.options()["rho_max"] == 0.9
    assert "rho_max" not in dynamic_model("slm").options()  # white: the record as it was
    events = _events(False, False)
    assert DesignProblem(model, events, model.default_prior(events)).rho_max == 0.9
