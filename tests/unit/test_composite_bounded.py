"""Bounded static shares, coefficient priors, the run-until-converged loop and the
residual check of the composite fit (fit/composite/bounded.py, until.py, residuals.py).

The bivariate-normal quadrant and the truncated draws are checked against plain Monte
Carlo (400,000 draws: the tolerances are about 5 Monte Carlo sds); the fits are short.
"""

import math

import numpy as np
import pytest

from loadbayes.cases.composite_sim import simulate_event
from loadbayes.core.settings import SamplerSettings
from loadbayes.fit.composite import fit_composite
from loadbayes.fit.composite.bounded import (
    _log_quadrant,
    draw_gamma,
    posterior_moments_3,
    shares_of,
    transform,
)
from loadbayes.fit.composite.residuals import residual_warning
from loadbayes.io.errors import OptionError
from loadbayes.models.composite_prior import CoefficientPrior, named_coefficients
from loadbayes.models.zip_motor import CompositeModel


def test_quadrant_probability_matches_monte_carlo():
    rng = np.random.default_rng(0)
    for _ in range(5):
        a = rng.normal(size=(3, 3))
        cov = a @ a.T + 0.1 * np.eye(3)
        mu = 1.5 * rng.normal(size=3)
        x = rng.multivariate_normal(mu, cov, size=400_000)
        mc = np.mean((x[:, 0] > 0) & (x[:, 2] > 0))
        sd = math.sqrt(mc * (1 - mc) / x.shape[0])
        assert abs(math.exp(_log_quadrant(mu, cov)) - mc) < 5 * sd + 1e-6


def test_bounded_draws_are_the_quadrant_truncated_conditional():
    rng = np.random.default_rng(1)
    a = np.array([0.2, 0.3, 0.5, 0.6, 0.3, 0.1])
    t = transform(a)
    z = rng.normal(size=(2, 50, 7))
    y = rng.normal(size=(2, 50))
    ztz, zty = np.einsum("gni,gnj->gij", z, z), np.einsum("gni,gn->gi", z, y)
    tau, p0 = np.array([0.5, 0.8]), np.array([0.1, 0.1, 0.1])
    beta = draw_gamma(ztz, zty, tau, a, p0, rng, 20_000)
    gamma = beta @ np.linalg.pinv(t.T)
    assert np.all(gamma[:, 0] > 0) and np.all(gamma[:, 2] > 0)
    # beta keeps the shares: cp / sum(cp) = a1..a3, cq / sum(cq) = a4..a6.
    named = named_coefficients(beta)
    for i in range(6):
        assert np.allclose(named[f"a{i + 1}"], a[i])
    zz = np.einsum("ji,gjk,kl->gil", t, ztz, t)
    zy = np.einsum("ji,gj->gi", t, zty)
    mu, cov, _, _ = posterior_moments_3(zz, zy, tau, p0)
    x = rng.multivariate_normal(mu, cov, size=400_000)
    x = x[(x[:, 0] > 0) & (x[:, 2] > 0)]
    se = x.std(0) / math.sqrt(20_000)
    assert np.all(np.abs(gamma.mean(0) - x.mean(0)) < 5 * se)
    assert np.allclose(gamma.std(0), x.std(0), rtol=0.05)


def test_share_coordinates_cover_the_simplex():
    z = np.random.default_rng(2).normal(scale=3, size=(100, 4))
    a = shares_of(z)
    assert np.all(a >= 0) and np.all(a <= 1)
    assert np.allclose(a[:, :3].sum(1), 1) and np.allclose(a[:, 3:].sum(1), 1)


def test_coefficient_prior_factor():
    f = CoefficientPrior(normal=(("f_m", 0.4, 0.1),))
    beta = np.array([[0.1, 0.2, 0.3, 0.1, 0.1, 0.1, 0.4], [-0.4, 0.0, 0.0, 0.1, 0.1, 0.1, 0.4]])
    lr = f.log_factor(beta)
    assert lr[0] == pytest.approx(-0.5 * ((0.4 / 1.0 - 0.4) / 0.1) ** 2)
    assert lr[1] == -math.inf  # P0 = 0: f_m is not a number
    with pytest.raises(ValueError, match="no prior on"):
        CoefficientPrior(normal=(("a7", 0.1, 0.1),))


@pytest.fixture(scope="module")
def inadmissible_event():
    # A load whose static P is all constant current and power and Q all impedance: the
    # free fit's shares wander outside [0, 1] on one short sag.
    ev, truth = simulate_event(t_end_s=1.5, fs=60, seed=3, zip_p=(0.0, 0.2, 0.8),
                               zip_q=(0.9, 0.1, 0.0))  # fmt: skip
    return ev, truth


@pytest.fixture(scope="module")
def bounded_fit(inadmissible_event):
    """The bounded fit of that event (seed 5), which two tests read."""
    ev, _ = inadmissible_event
    run = SamplerSettings(draws=400, burn=200, chains=2, seed=5)
    return fit_composite(CompositeModel(window_s=0, shares="bounded"), [ev], sampler=run)


def test_bounded_fit_keeps_every_share_in_the_unit_interval(inadmissible_event, bounded_fit):
    ev, truth = inadmissible_event
    run = SamplerSettings(draws=400, burn=200, chains=2, seed=5)
    free = fit_composite(CompositeModel(window_s=0), [ev], sampler=run)
    assert any("--shares bounded" in w for w in free.posterior.warnings)
    fit = bounded_fit
    d = fit.posterior.draws
    for n in ("a1", "a2", "a3", "a4", "a5", "a6", "f_m"):
        assert np.all(d[n] >= 0) and np.all(d[n] <= 1), n
    assert np.allclose(d["a1"] + d["a2"] + d["a3"], 1)
    assert fit.posterior.settings["coefficient_prior"]["shares"] == "bounded"
    assert not any("--shares bounded" in w for w in fit.posterior.warnings)


def test_a_prior_on_a_share_pulls_it(inadmissible_event, bounded_fit):
    # The data put a1 near 0 (truth 0); a tight prior at 0.6 must move it most of the way.
    ev, _ = inadmissible_event
    run = SamplerSettings(draws=400, burn=200, chains=2, seed=5)
    plain = bounded_fit.posterior.draws["a1"]
    model = CompositeModel(window_s=0, shares="bounded", priors={"a1": (0.6, 0.02)})
    fit = fit_composite(model, [ev], sampler=run)
    pulled = fit.posterior.draws["a1"]
    assert float(np.mean(plain)) < 0.2
    assert float(np.mean(pulled)) > 0.45
    assert fit.posterior.settings["coefficient_prior"]["normal"] == {"a1": [0.6, 0.02]}


def test_bad_share_and_budget_options_are_refused():
    # Refused when the model and the settings are built, in Python's words (the CLI's
    # flags are its own: commands/options.py).
    with pytest.raises(OptionError, match="shares"):
        CompositeModel(window_s=0, shares="loose")
    with pytest.raises(ValueError, match="max_seconds"):
        SamplerSettings(draws=200, burn=100, max_seconds=-1)
    with pytest.raises(OptionError, match="normal only"):
        CompositeModel(window_s=0, shares="bounded", likelihood="student-t")


def test_a_run_out_of_time_says_so(inadmissible_event):
    ev, _ = inadmissible_event
    run = SamplerSettings(draws=200, burn=100, chains=2, seed=1, until_converged=True,
                          max_seconds=0.01)  # fmt: skip
    fit = fit_composite(CompositeModel(window_s=0), [ev], sampler=run)
    rec = fit.posterior.settings["until_converged"]
    assert rec["stopped_by_budget"] is True
    assert any("time budget" in w and "not converged" in w for w in fit.posterior.warnings)


def test_residuals_that_run_in_stretches_are_reported():
    ev, _ = simulate_event(t_end_s=1.5, fs=60, seed=4)
    # Something the model does not have: a slow oscillation on P (2 Hz, 4 % of P0).
    from dataclasses import replace

    bad = replace(ev, p=ev.p + 0.04 * np.sin(2 * np.pi * 2.0 * ev.t))
    model, run = CompositeModel(window_s=0), SamplerSettings(draws=300, burn=150, chains=2, seed=2)
    fit = fit_composite(model, [bad], sampler=run)
    lag = fit.posterior.settings["residuals"]["lag1_autocorrelation"]
    assert lag["p"] > 0.5
    assert any("run in stretches" in w for w in fit.posterior.warnings)
    good = fit_composite(model, [ev], sampler=run)
    assert abs(good.posterior.settings["residuals"]["lag1_autocorrelation"]["p"]) < 0.3
    assert residual_warning({"p": 0.1, "q": 0.05}) is None


def test_a_prior_on_the_motor_share_with_free_shares_pulls_it(inadmissible_event):
    # Free shares with a normal factor: the importance-weighted (tilted) path. A tight
    # prior 0.15 below what the data say must move f_m most of the way and be recorded.
    ev, _ = inadmissible_event
    run = SamplerSettings(draws=300, burn=200, chains=2, seed=5)
    plain = float(
        np.mean(fit_composite(CompositeModel(), [ev], sampler=run).posterior.draws["f_m"])
    )
    model = CompositeModel(priors={"f_m": (plain - 0.15, 0.005)})
    fit = fit_composite(model, [ev], sampler=run)
    pulled = float(np.mean(fit.posterior.draws["f_m"]))
    assert pulled < plain - 0.1, (plain, pulled)
    assert fit.posterior.settings["coefficient_prior"] == {
        "shares": "free",
        "normal": {"f_m": [plain - 0.15, 0.005]},
    }


def _reference_term(z, ztz, zty, yty, n, tau, p0_gamma, share_prior):
    # One event's share terms as the Python code wrote them before they were compiled.
    from loadbayes.fit.composite.bounded import log_evidence, log_prior_shares

    a = shares_of(z)
    out = log_prior_shares(z)
    for i, mean, sd in share_prior:
        out -= 0.5 * ((a[i] - mean) / sd) ** 2
    return out + log_evidence(ztz, zty, yty, n, tau, a, p0_gamma)


def _event_sums(rng, n=60):
    # A ZIP + motor design of both channels (x^2, x, 1 per channel; the motor's column),
    # and a response made from shares inside the simplex with noise.
    x = 1.0 - 0.3 * rng.uniform(size=n)
    m = 0.5 + 0.3 * rng.standard_normal(n)
    zs, ys = [], []
    for c in range(2):
        z = np.zeros((n, 7))
        z[:, 3 * c : 3 * c + 3] = np.stack([x**2, x, np.ones(n)], 1)
        z[:, 6] = m
        y = z @ np.array([0.2, 0.3, 0.5, 0.3, 0.3, 0.4, 0.4]) + 0.01 * rng.standard_normal(n)
        zs.append(z)
        ys.append(y)
    zty = np.stack([z.T @ y for z, y in zip(zs, ys, strict=True)])
    return (np.stack([z.T @ z for z in zs]), zty, np.array([y @ y for y in ys]),
            np.array([float(n), float(n)]))  # fmt: skip


def test_written_out_moments_are_numpys_3_x_3_algebra():
    """``gamma_moments`` in closed form against ``T' Z'Z T`` and its inverse by NumPy, on
    well and badly conditioned sums (columns nearly collinear, as x^2, x, 1 are: A's
    condition number up to 1e8), to the rounding that condition allows (forming A
    itself rounds that much: LAPACK's factor was no closer to an exact log|A|, 1e-9
    apart at 7e7); a matrix that is not positive definite raises as ``cholesky`` did."""
    from loadbayes.fit.composite.bounded import transform
    from loadbayes.fit.composite.bounded_kernel import gamma_moments

    rng = np.random.default_rng(11)
    eps = np.finfo(float).eps
    for spread in (1.0, 1e-3, 1e-6):
        x = 1.0 - spread * rng.uniform(size=(80, 1))
        for _ in range(5):
            z = np.hstack([x**2, x, np.ones_like(x), x**2, x, np.ones_like(x),
                           rng.normal(size=(80, 1))])  # fmt: skip
            ztz = np.stack([z.T @ z, 2.0 * z.T @ z])
            zty = rng.normal(size=(2, 7))
            tau, p0 = np.array([3e3, 2e3]), np.array([0.01, 0.02, 0.01])
            a = rng.dirichlet(np.ones(3), size=2).ravel()
            mu, cov, h, logdet = gamma_moments(a, ztz, zty, tau, p0)
            t = transform(a)
            big = sum(tau[g] * t.T @ ztz[g] @ t for g in range(2)) + np.diag(p0)
            want_h = sum(tau[g] * t.T @ zty[g] for g in range(2))
            tol = 64 * eps * np.linalg.cond(big)
            assert tol < 1e-5
            np.testing.assert_allclose(h, want_h, rtol=1e-12)
            want_cov = np.linalg.inv(big)
            np.testing.assert_allclose(cov, want_cov, rtol=tol, atol=tol * np.abs(want_cov).max())
            want_mu = np.linalg.solve(big, want_h)
            np.testing.assert_allclose(mu, want_mu, rtol=tol, atol=tol * np.abs(want_mu).max())
            assert abs(logdet - np.linalg.slogdet(big)[1]) <= tol * max(1.0, abs(logdet))
            assert np.array_equal(cov, cov.T)
    bad = np.zeros((2, 7, 7))
    with pytest.raises(np.linalg.LinAlgError):
        gamma_moments(np.full(6, 1 / 3), bad, np.zeros((2, 7)), np.array([1.0, 1.0]),
                      np.array([-1.0, 1.0, 1.0]))  # fmt: skip


def test_compiled_owens_t_is_scipys():
    """The kernels call SciPy's own compiled Owen's T: the same numbers, bit for bit."""
    from scipy import special

    from loadbayes.fit.composite.bounded_kernel import owens_t

    rng = np.random.default_rng(3)
    h = np.concatenate([rng.normal(0, 3, 500), [0.0, 1e-12, -40.0, 40.0]])
    a = np.concatenate([rng.normal(0, 5, 500), [1.0, 1e6, -1e-9, 0.5]])
    assert [owens_t(x, y) for x, y in zip(h, a, strict=True)] == list(special.owens_t(h, a))


def test_compiled_share_terms_match_the_python_ones():
    """``bounded_terms`` (and the quadrant, its tail branch included) against the Python
    code it replaced, to rounding (the order of the 3 x 3 sums differs)."""
    from loadbayes.fit.composite.bounded_kernel import _log_quadrant as compiled_quadrant
    from loadbayes.fit.composite.bounded_kernel import bounded_terms, stacked
    from loadbayes.inference.condlinear import GroupSums

    rng = np.random.default_rng(4)
    for _ in range(20):
        b = rng.normal(size=(3, 3))
        cov = b @ b.T + 0.1 * np.eye(3)
        mu = 4.0 * rng.normal(size=3)
        assert math.isclose(compiled_quadrant(mu, cov), _log_quadrant(mu, cov), rel_tol=1e-12,
                            abs_tol=1e-12)  # fmt: skip
    groups = [GroupSums(*_event_sums(rng)) for _ in range(3)]
    tau, p0 = np.array([2e3, 3e3]), np.array([0.01, 0.02, 0.01])
    prior = ((0, 0.3, 0.1), (4, 0.2, 0.05))
    args = (*stacked(groups), tau, p0, np.array([0, 4]), np.array([0.3, 0.2]),
            np.array([0.1, 0.05]))  # fmt: skip
    for _ in range(50):
        z = rng.normal(0, 2, (3, 4))
        ref = sum(_reference_term(z[e], g.ztz, g.zty, g.yty, g.n, tau, p0, prior)
                  for e, g in enumerate(groups))  # fmt: skip
        assert math.isclose(bounded_terms(z, *args), ref, rel_tol=1e-9)


def test_compiled_share_steps_take_the_python_loops_path():
    """Drawing from the same generator, the compiled steps take the Python loop's draws
    (four normals, then a uniform, per step and event), accept and reject as the loop
    over the reference terms does, adapt the scale the same way, and leave the generator
    where the loop leaves it."""
    from loadbayes.fit.composite.bounded_kernel import share_steps, stacked
    from loadbayes.inference.condlinear import GroupSums

    rng = np.random.default_rng(5)
    groups = [GroupSums(*_event_sums(rng)) for _ in range(2)]
    tau, p0 = np.array([2e3, 3e3]), np.array([0.01, 0.02, 0.01])
    steps = 40
    z0 = np.zeros((2, 4))
    z, scale, gen = z0.copy(), np.full(2, 0.3), np.random.default_rng(6)
    share_steps(z, *stacked(groups), tau, p0, np.zeros(0, np.int64), np.zeros(0), np.zeros(0),
                steps, gen, scale, True)  # fmt: skip
    ref_z, ref_scale, accepted, ref_gen = z0.copy(), np.full(2, 0.3), 0, np.random.default_rng(6)
    for _ in range(steps):
        for e, g in enumerate(groups):
            normal, uniform = ref_gen.standard_normal(4), ref_gen.uniform()
            cur = _reference_term(ref_z[e], g.ztz, g.zty, g.yty, g.n, tau, p0, ())
            cand = ref_z[e] + ref_scale[e] * normal
            lc = _reference_term(cand, g.ztz, g.zty, g.yty, g.n, tau, p0, ())
            ok = math.log(uniform) < lc - cur
            if ok:
                ref_z[e], accepted = cand, accepted + 1
            ref_scale[e] *= math.exp(0.02 * (float(ok) - 0.3))
    assert 0 < accepted < 2 * steps  # both kinds of decision were taken
    np.testing.assert_allclose(z, ref_z, rtol=0, atol=1e-12)
    np.testing.assert_allclose(scale, ref_scale, rtol=1e-14)
    assert gen.random() == ref_gen.random()


def test_compiled_coefficient_draw_is_draw_gamma_bit_for_bit():
    """``draw_gamma_one`` gives ``draw_gamma``'s single draw to the bit and leaves the
    generator where it does, also far in a tail where the rejection takes many tries
    (the motor's coefficient's conditional mean well below zero)."""
    from loadbayes.fit.composite.bounded_kernel import draw_gamma_one

    rng = np.random.default_rng(7)
    for k in range(120):
        ztz, zty, _, _ = _event_sums(rng)
        zty = zty * (-3.0 if k % 3 == 0 else 1.0)  # a third in the tail
        tau = 10 ** rng.uniform(1, 4, 2)
        a = shares_of(rng.normal(0, 2, 4))
        p0 = np.array([0.01, 0.02, 0.01]) * 10 ** rng.uniform(-2, 2)
        ref, gen = np.random.default_rng(k), np.random.default_rng(k)
        want = draw_gamma(ztz, zty, tau, a, p0, ref)[0]
        assert np.array_equal(draw_gamma_one(a, ztz, zty, tau, p0, gen), want)
        assert gen.random() == ref.random()


@pytest.mark.parametrize("shares", ["free", "bounded"])
def test_jumps_are_refitted_between_rounds_with_bounded_shares_only(
    inadmissible_event, shares, monkeypatch
):
    """A round added by ``extend`` continues the run draw for draw with free shares; with
    bounded shares the jumps are refitted to the kept draws first (``REFIT_THIN``), so
    the first round is the same and the added one starts from refitted jumps.

    The refit is counted at ``fit_jumps`` itself: an earlier form asserted that the added
    round's draws differ, which needs one of its jumps accepted, and on this event they
    are accepted 0.5% of the time (no difference in 50 iterations on an AVX2 machine)."""
    from loadbayes.fit.composite.bounded import share_start
    from loadbayes.fit.composite.driver import _append_start
    from loadbayes.fit.composite.nls import nls
    from loadbayes.fit.composite.problem import CompositeProblem
    from loadbayes.fit.composite.sampler import REFIT_THIN, sample
    from loadbayes.inference.moves.adaptive_metropolis import AdaptiveMetropolis

    ev, _ = inadmissible_event
    model = CompositeModel(window_s=0)
    kw = dict(f_hz=model.f_hz, torque=model.fixed_torque, h_max=model.h_max,
              steps=model.steps, window_s=model.window_s)  # fmt: skip
    problem = CompositeProblem([ev], model.default_prior([ev]), **kw)
    start = nls(problem)
    if shares == "bounded":
        problem = CompositeProblem([ev], problem.prior, bounded=True, **kw)
        start = _append_start(start, share_start(start.betas), sd=0.5)
    burn, kept = 600, 260 * REFIT_THIN  # 2 chains x 260 kept u: past JUMP_MIN_DRAWS (500)
    run = dict(start=start, burn=burn, chains=2, seed=11, workers=1)
    whole = sample(problem, draws=burn + kept + 50, **run)
    fitted, real_fit = [], AdaptiveMetropolis.fit_jumps

    def counted(self, u, *args, **kwargs):
        fitted.append(len(u))
        return real_fit(self, u, *args, **kwargs)

    monkeypatch.setattr(AdaptiveMetropolis, "fit_jumps", counted)
    rounds = iter([50, 0])
    split = sample(problem, draws=burn + kept, extend=lambda _: next(rounds), **run)
    # Each chain fits its jumps to the pooled late burn-in; bounded shares refit them to
    # the 2 x 260 kept u before the added round, free shares keep them.
    late = fitted[0]
    assert fitted == [late, late] + ([2 * kept // REFIT_THIN] * 2 if shares == "bounded" else [])
    for a, b in zip(whole, split, strict=True):
        assert np.array_equal(a.theta[:kept], b.theta[:kept])
        if shares == "free":
            assert np.array_equal(a.theta, b.theta)
