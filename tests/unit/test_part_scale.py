"""Each motor's log T0 sampled as its place inside its limits (models/part_scale.py).

Checked against SciPy, not against the package: the map of a standard normal is SciPy's
truncated normal (KS test, fixed seed, false alarm 0.1 %); the prior in the sampled
coordinates is the old joint prior (SciPy's multivariate normal inside the hard limits)
times the map's Jacobian (a numerical derivative), up to one constant; every sampled
vector's motors hold every limit.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import stats

from loadbayes.measurements.record import EventRecord
from loadbayes.models.dynamic import dynamic_model
from loadbayes.models.part_scale import log_mass


def _prior(name="cmld-lite", **kw):
    model = dynamic_model(name, f_hz=50.0, **kw)
    t = np.linspace(0, 0.3, 16)
    ev = EventRecord(t, 1 - 0.2 * (t > 0.1), np.ones(16), 0.3 * np.ones(16), 0 * t, "e")
    return model, model.default_prior([ev])


def _inside_theta(prior, theta) -> bool:
    # The hard limits as the old prior held them, on theta (log T0 at i + 5).
    for i, rs_max, h_min, x_min, x_max in prior.limits:
        if theta[i] - theta[i + 5] > math.log(rs_max) + 1e-12:
            return False
        if theta[i + 4] + theta[i + 5] < math.log(h_min) - 1e-12:
            return False
        if not math.log(x_min) - 1e-12 <= theta[i + 1] - theta[i + 5] <= math.log(x_max) + 1e-12:
            return False
    return True


def test_log_mass_is_scipys_from_either_tail():
    a = np.array([-3.0, -1.0, 0.5, 4.0, 9.0, 30.0, 2.0])
    b = np.array([-2.0, 1.0, 2.0, 6.0, 12.0, 31.0, 2.0])
    with np.errstate(divide="ignore"):
        want = np.log(stats.norm.sf(a) - stats.norm.sf(b))  # 0 and -inf for the empty one
    got = log_mass(a, b)
    assert got[-1] == -math.inf  # an empty interval
    assert np.allclose(got[:-1], want[:-1], rtol=1e-9)
    assert np.isfinite(got[5])  # 30 sd out: still a number, from the upper tail


def test_a_standard_normal_maps_to_the_truncated_conditional_of_log_t0():
    _, prior = _prior("slm")
    m = prior.maps[0]
    rng = np.random.default_rng(3)
    for shift in (0.0, 1.2, -0.8):  # the limit near the centre, binding hard, loose
        u = prior.scale_free()[0].copy()
        u[m.index] += shift  # log(Rs T0) up: Rs <= 0.1 cuts deeper into log T0's range
        mid, a, b = (float(x) for x in m._ab(u))
        draws = np.repeat(u[None], 4000, axis=0)
        draws[:, m.index + 5] = rng.standard_normal(4000)
        t = m.log_t0(draws)
        ref = stats.truncnorm(a, b, loc=mid, scale=m._sd)
        assert stats.kstest(t, ref.cdf).pvalue > 1e-3
        assert np.allclose(m.z(prior.to_theta(draws)), draws[:, m.index + 5], atol=1e-7)


@pytest.mark.parametrize("name", ["slm", "cmld-lite"])
def test_the_sampled_prior_is_the_limited_joint_prior_times_the_jacobian(name):
    # log_u(u) - [log N(theta(u)) inside the limits + log |d log T0 / dz|] is one constant.
    model, prior = _prior(name)
    n = prior.mean.size
    joint = stats.multivariate_normal(prior.mean, prior.cov)
    mean, cov = prior.scale_free()[:2]
    rng = np.random.default_rng(11)
    diffs = []
    while len(diffs) < 40:
        u = rng.multivariate_normal(mean, cov)
        if not prior.inside(u):
            continue
        theta = prior.to_theta(u)
        assert _inside_theta(prior, theta)
        log_jac = 0.0
        for m in prior.maps:
            h = 1e-5
            up, dn = u.copy(), u.copy()
            up[m.index + 5] += h
            dn[m.index + 5] -= h
            log_jac += math.log((m.log_t0(up) - m.log_t0(dn)) / (2 * h))
        old = joint.logpdf(theta[:n])
        shares = 0.0  # the simplexes' uniform Dirichlet in additive log-ratios
        for a, b in prior.groups:
            z = np.append(u[a:b], 0.0)
            shares += z.sum() - z.size * np.logaddexp.reduce(z)
        diffs.append(prior.log_u(u) - (old + shares + log_jac))
    assert np.ptp(diffs) < 1e-5


def test_every_sampled_vector_holds_its_motors_inside_and_an_empty_range_is_refused():
    _, prior = _prior()
    mean, cov = prior.scale_free()[:2]
    rng = np.random.default_rng(5)
    u = rng.multivariate_normal(mean, 4 * cov, size=3000)  # wide: near and past the limits
    ok = np.array([prior.inside(x) for x in u])
    theta = prior.to_theta(u[ok])
    assert ok.mean() > 0.5 and all(_inside_theta(prior, th) for th in theta)
    for m in prior.maps:  # Rs T0 / X' T0 above rs_max / x_min: no log T0 holds both
        bad = mean.copy()
        bad[m.index] = bad[m.index + 1] + math.log(0.1 / 0.04) + 0.2
        assert not prior.inside(bad) and prior.log_u(bad) == -math.inf
        moved = prior.project(bad)
        assert prior.inside(moved) and _inside_theta(prior, prior.to_theta(moved))


def test_without_limits_the_sampled_vector_is_theta_itself():
    _, prior = _prior(physical_region=False)
    u = prior.scale_free()[0] + 0.3
    assert prior.maps == () and prior.to_theta(u) is u


def test_one_vector_takes_the_same_arithmetic_as_many():
    # The sampler's path (one vector, floats) against the vectorised one (the draws').
    _, prior = _prior()
    mean, cov = prior.scale_free()[:2]
    u = np.random.default_rng(2).multivariate_normal(mean, 4 * cov, size=200)
    for m in prior.maps:
        u[0, m.index] = u[0, m.index + 1] + math.log(0.1 / 0.04) + 1.0  # an empty range
        one_t = np.array([m.log_t0(x) for x in u])
        one_mass = np.array([m.log_mass(x) for x in u])
        assert np.allclose(one_t, m.log_t0(u), rtol=0, atol=1e-12, equal_nan=True)
        assert np.allclose(one_mass, m.log_mass(u), rtol=0, atol=1e-12)
        assert np.isnan(one_t[0]) and one_mass[0] == -math.inf
