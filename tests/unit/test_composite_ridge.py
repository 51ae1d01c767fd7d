"""Points along the composite posterior's ridge in log T' (fit/composite/ridge.py, issue 35).

The event is made by tests/independent_composite.py (SciPy, no loadbayes code): the large
slow motor (T' 0.70 s), f_m 0.4, a 30% sag held 0.2 s with 20 ms ramps, point samples at
60/s, 0.5% noise, 3 s: T' is weakly determined there, so the profile runs out along it
(on the 10 s event of issue 35 its T' 0.157 s point fell within 0.12 of the 4 x 64,000
reference's mean of the draws below 0.2 s in every coordinate).
"""

from __future__ import annotations

import numpy as np
import pytest

from independent_composite import Sag, simulate_event
from loadbayes.fit.composite.api import read
from loadbayes.fit.composite.nls import _project, nls, penalty
from loadbayes.fit.composite.problem import CompositeProblem
from loadbayes.fit.composite.ridge import RIDGE_DROP, RIDGE_POINTS, RIDGE_STEP, ridge_points
from loadbayes.models.zip_motor import CompositeModel

TP = 3  # log T' in u


@pytest.fixture(scope="module")
def fitted():
    df, _ = simulate_event(motor="large_slow", f_m=0.4, sags=(Sag(1.0123, 0.3, 0.2, 0.02, 0.02),),
                           rate_hz=60.0, t_end_s=3.0, seed=0)  # fmt: skip
    events = read(df)
    model = CompositeModel(window_s=0.0)
    problem = CompositeProblem(events, model.default_prior(events), f_hz=60.0,
                               torque=model.fixed_torque, steps=model.steps,
                               window_s=0.0)  # fmt: skip
    start = nls(problem)
    return problem, start, ridge_points(problem, start)


def _cost(problem, start, u):
    mean, _, white, _, _ = penalty(problem)
    r = np.concatenate([_project(problem, u, 1.0 / start.sigma)[0], white @ (u - mean)])
    return 0.5 * float(r @ r)


def test_ridge_points_are_spaced_along_log_t_prime_both_ways(fitted):
    problem, start, (points, covs) = fitted
    sd = np.sqrt(start.cov[TP, TP])
    steps = np.round((points[:, TP] - start.u[TP]) / (RIDGE_STEP * sd), 9)
    below, above = steps[steps < 0], steps[steps > 0]
    assert len(below) >= 2 and len(above) >= 2  # the ridge runs out both ways
    for side in (-below, above):  # 1, 2, 3 ... steps, at most RIDGE_POINTS
        np.testing.assert_allclose(side, np.arange(1, len(side) + 1))
        assert len(side) <= RIDGE_POINTS
    assert covs.shape == (len(points), problem.dim, problem.dim)
    for c in covs:  # a proposal's covariance: symmetric, positive definite
        np.testing.assert_allclose(c, c.T, atol=1e-12)
        assert np.linalg.eigvalsh(c).min() > 0


def test_each_ridge_point_is_the_profile_optimum_within_the_drop(fitted):
    """At its log T' each point has the lowest penalised cost: no step of 0.1 Laplace sd
    in any other coordinate lowers it (by more than rounding); and no point is more than
    RIDGE_DROP above the optimum."""
    problem, start, (points, _) = fitted
    c0 = _cost(problem, start, start.u)
    sd = np.sqrt(np.diag(start.cov[: problem.dim, : problem.dim]))
    for u in points:
        c = _cost(problem, start, u)
        assert 0 <= c - c0 <= RIDGE_DROP
        for i in (i for i in range(problem.dim) if i != TP):
            for way in (-1, 1):
                v = u.copy()
                v[i] += way * 0.1 * sd[i]
                if i >= problem.n_free and not 0 <= v[i] <= 1:
                    continue  # a step's fraction stays in [0, 1]
                assert _cost(problem, start, v) >= c - 1e-6


def test_the_short_first_round_is_zip_motors_alone(monkeypatch, tmp_path):
    """The ridge's t's are the plain model's: ``fit composite`` left at its default runs a
    first round of 6,000 for ``zip+motor`` and 16,000 for a model of parts; a given
    --draws is taken as it is (and run exactly)."""
    from click.testing import CliRunner

    import loadbayes.fit.composite.driver as drv
    from loadbayes.cli import main
    from loadbayes.fit.composite import COMPOSITE_DEFAULTS

    got = []

    def fake(model, events, *, sampler=None, **kw):
        got.append((model.name, sampler.draws, sampler.burn, sampler.until_converged))
        raise KeyboardInterrupt

    monkeypatch.setattr(drv, "fit_composite", fake)
    df, _ = simulate_event(motor="large_slow", f_m=0.4, sags=(Sag(1.0123, 0.3, 0.2, 0.02, 0.02),),
                           rate_hz=60.0, t_end_s=3.0, seed=0)  # fmt: skip
    ev = tmp_path / "ev.csv"
    df.to_csv(ev, index=False)
    for extra in (["--window-s", "0"], ["--model", "slm"], ["--model", "slm", "--draws", "6000"]):
        res = CliRunner().invoke(main, ["fit", "composite", str(ev), "--json",
                                        str(tmp_path / "a.json"), "--quiet", *extra])  # fmt: skip
        assert "interrupted" in res.output, res.output  # at the fit, not before
    assert got == [("zip+motor", 6000, 4000, True), ("slm", 16000, 4000, True),
                   ("slm", 6000, 4000, False)]  # fmt: skip
    assert (COMPOSITE_DEFAULTS.draws, drv.PARTS_DEFAULTS.draws) == (6000, 16000)


def test_the_ridge_is_profiled_once_per_problem(fitted, monkeypatch):
    """The cost probe samples the problem twice before the run does: each call of the
    sampler profiled the ridge anew (6 CPU s a time on an ANDES Motor5 event, most of
    its 27 s, and the probe read that as a start-up of every round of chains: "about 29
    min" for a run of 42 s)."""
    import loadbayes.fit.composite.ridge as ridge
    import loadbayes.fit.composite.sampler as sampler

    problem, start, (points, _) = fitted
    calls = []
    real = ridge.ridge_points
    monkeypatch.setattr(ridge, "ridge_points", lambda p, s: calls.append(1) or real(p, s))
    problem.__dict__.pop("_ridge_cache", None)
    # A short burn-in places no ridge (RIDGE_MIN_BURN: the profile would cost as much as
    # the run), so no profile at all ...
    sampler.sample(problem, start=start, draws=40, burn=20, chains=1, seed=0, workers=1)
    assert calls == []
    # ... and a long one profiles it once, however often the problem is sampled.
    monkeypatch.setattr(sampler, "RIDGE_MIN_BURN", 20)
    for draws in (40, 60):
        sampler.sample(problem, start=start, draws=draws, burn=20, chains=1, seed=0, workers=1)
    assert len(calls) == 1
    np.testing.assert_array_equal(ridge.cached_ridge_points(problem, start)[0], points)
