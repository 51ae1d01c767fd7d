"""The composite sampler's fast paths give the plain NumPy arithmetic's numbers, to the bit.

The sampler's per-iteration Python was cut (issue 35) with the draws unchanged for the
same seed: each shortcut below keeps the random stream and the floating-point operations
of the code it replaced. Each test puts the shortcut beside that code, written out here
as it was, on many inputs, and asks for equal bytes (``tobytes``), so a change that
moves one number by one ulp fails. Deterministic: fixed seeds, no tolerance.

The whole runs were checked by sha256 of their draws before and after (the commits say
which); these tests pin the pieces, which a whole run on another machine could not.
"""

from __future__ import annotations

import numpy as np
import pytest

from loadbayes.fit.composite.problem import _T_INV, N_FREE, theta_of
from loadbayes.inference.condlinear import _truncated_standard, draw_tau
from loadbayes.inference.moves.base import RunningCovariance
from loadbayes.inference.moves.mixture import StudentTMixture
from loadbayes.inference.moves.sheared import Shear
from loadbayes.models.composite_prior import CompositePrior


def _same(a, b) -> bool:
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    return a.shape == b.shape and a.tobytes() == b.tobytes()


def test_random_is_uniforms_number_and_stream():
    # rng.uniform() = 0 + 1 d and rng.uniform(0, c) = 0 + c d: the same numbers as
    # rng.random() and c * rng.random(), one double consumed either way.
    a, b = np.random.default_rng(5), np.random.default_rng(5)
    scales = np.random.default_rng(1).random(2000) * np.logspace(-300, 0, 2000)
    for c in scales.tolist():
        assert a.uniform() == b.random()
        assert a.uniform(0.0, c) == c * b.random()
    assert a.random() == b.random()


def test_truncated_standard_keeps_the_uniform_draw():
    def reference(a, rng):  # condlinear._truncated_standard as it was
        from scipy import special

        upper = float(special.ndtr(-a))
        if upper > 1e-300:
            return float(-special.ndtri(max(rng.uniform(0.0, upper), 1e-300)))
        return a + rng.exponential(1.0 / a)

    for a in np.linspace(-8.0, 40.0, 400).tolist():
        r1, r2 = np.random.default_rng(3), np.random.default_rng(3)
        assert reference(a, r1) == _truncated_standard(a, r2)
        assert r1.random() == r2.random()


def test_draw_tau_float_groups_as_broadcast():
    rng = np.random.default_rng(0)
    for _ in range(300):
        n = np.array([76.0, 75.0]) * rng.integers(1, 20)
        ssr = rng.random(2) * 10.0 ** rng.integers(-8, 4)
        r1, r2 = np.random.default_rng(7), np.random.default_rng(7)
        nb, sb = np.broadcast_arrays(n, ssr)  # the general path, as it was
        pairs = zip(nb.ravel().tolist(), sb.ravel().tolist(), strict=True)
        want = np.array([r1.gamma(1e-3 + 0.5 * a, 1.0 / (1e-9 + 0.5 * s)) for a, s in pairs])
        assert _same(draw_tau(ssr, n, 1e-3, 1e-9, r2), want)
        assert r1.random() == r2.random()


def test_theta_of_a_float_scale_as_the_outer_product():
    rng = np.random.default_rng(2)
    for _ in range(500):
        u, t0 = rng.standard_normal(N_FREE) * 3, float(rng.standard_normal() * 2)
        want = u @ _T_INV[:, :N_FREE].T + np.multiply.outer(np.asarray(t0), _T_INV[:, N_FREE])
        assert _same(theta_of(u, t0), want)
        # The kernel's motor: exp(theta_of(u, 0.0)) is exp(u @ T) (log T0 = 0 adds zeros).
        assert _same(np.exp(u @ np.ascontiguousarray(_T_INV[:, :N_FREE].T)),
                     np.exp(theta_of(u, np.float64(0.0))))  # fmt: skip


def _bent_draws(rng, n=800, d=7):
    s = rng.standard_normal(n) * 2
    x = rng.standard_normal((n, d)) * 0.3
    x[:, 0] += s
    x[:, 1] += 0.4 * s**2
    x[:, 2] -= 0.1 * s**3
    return x * np.exp(rng.standard_normal(d)) + rng.standard_normal(d)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_shear_maps_as_numpy(seed):
    rng = np.random.default_rng(seed)
    draws = _bent_draws(rng)
    sh = Shear(draws)
    assert sh.active

    def h(s):  # Shear._h as it was
        s = min(max(s, sh.s_lo), sh.s_hi)
        return (s * s - sh.c2) * sh.coef[0] + s**3 * sh.coef[1]

    for p in draws[rng.integers(len(draws), size=300)] + rng.standard_normal((300, 7)) * 3:
        y = (p - sh.m) / sh.D
        w = y - h(float(y @ sh.e))
        assert _same(sh.forward(p), w)
        assert _same(sh.inverse(w), sh.m + sh.D * (w + h(float(w @ sh.e))))
        assert _same(sh.inverse(p), sh.m + sh.D * (p + h(float(p @ sh.e))))


def test_running_covariance_as_numpy_welford():
    rng = np.random.default_rng(3)
    rc = RunningCovariance(np.eye(7), 100)
    mean, m2 = np.zeros(7), np.zeros((7, 7))
    for n in range(1, 2001):
        x = rng.standard_normal(7) * np.exp(rng.standard_normal(7) * 3) + 100
        rc.update(x)
        delta = x - mean  # RunningCovariance.update as it was
        mean += delta / n
        m2 += np.outer(delta, x - mean)
        assert _same(rc._mean, mean) and _same(rc._m2, m2)


def test_mixture_component_is_numpys_choice():
    rng = np.random.default_rng(3)
    draws = rng.standard_normal((3000, 7))
    draws[:, 0] = np.exp(draws[:, 0])
    mix = StudentTMixture(draws, components=10, inflation=1.5, dof=10.0, power=0.5, broad=0.15,
                          anchors=(draws[:3], np.array([np.eye(7)] * 3)), anchor=0.2)  # fmt: skip
    a, b = np.random.default_rng(1), np.random.default_rng(1)
    for _ in range(20_000):
        assert int(a.choice(mix.components, p=mix.weights)) == mix._component(b)
    assert a.random() == b.random()


def test_prior_kept_scale_free_is_the_cached_one():
    prior = CompositePrior(np.array([-3.9, -1.9, 0.9, -0.7, -0.2, -0.5]),
                           np.array([1.0, 0.7, 0.7, 1.2, 0.6, 0.5]), np.full(7, 10.0))  # fmt: skip
    first = prior.scale_free()
    twin = CompositePrior(prior.theta_mean.copy(), prior.theta_sd.copy(), prior.beta_sd)
    for x, y in zip(first, twin.scale_free(), strict=True):
        assert _same(x, y)
    u = np.random.default_rng(0).standard_normal(5)
    mean, cov, _, _ = first
    d = u - mean
    assert prior.log_u(u) == -0.5 * float(d @ np.linalg.inv(cov) @ d)


def test_log_t0_of_many_rows_is_one_draw_a_row_in_order():
    # The NLS baseline's log T0 (fit/composite/driver._baseline_draws) is drawn for every
    # row at once. The normals are the stream's, in order, to the bit; the sum differs
    # from the row-by-row dot product by rounding alone (a matrix product adds in its own
    # order): terms of size about 1, so a few 1e-16 absolute (measured at most 4.4e-16;
    # relative to a result near zero that can be many ulps). The baseline is not the
    # sampler's chain, which still draws one at a time.
    prior = CompositePrior(np.array([-3.9, -1.9, 0.9, -0.7, -0.2, -0.5]),
                           np.array([1.0, 0.7, 0.7, 1.2, 0.6, 0.5]), np.full(7, 10.0))  # fmt: skip
    u = np.random.default_rng(1).standard_normal((500, 5))
    one = np.random.default_rng(3)
    rows = np.array([prior.draw_log_t0(x, one) for x in u])
    many = np.random.default_rng(3)
    at_once = prior.draw_log_t0s(u, many)
    np.testing.assert_allclose(at_once, rows, rtol=0, atol=32 * np.finfo(float).eps)
    assert one.standard_normal() == many.standard_normal()  # both streams at one place


@pytest.fixture(scope="module")
def stepped_problem():
    from loadbayes.cases.composite_sim import simulate_event
    from loadbayes.fit.composite.problem import CompositeProblem
    from loadbayes.models.zip_motor import CompositeModel

    ev, _ = simulate_event(t_end_s=1.0, fs=60, seed=3)
    model = CompositeModel(window_s=0)
    problem = CompositeProblem([ev], model.default_prior([ev]), f_hz=model.f_hz,
                               torque=model.fixed_torque, h_max=model.h_max, steps=True,
                               window_s=model.window_s)  # fmt: skip
    assert problem.n_steps
    return problem


def test_admissible_is_finite_and_in_support(stepped_problem):
    p, rng = stepped_problem, np.random.default_rng(4)
    for _ in range(2000):
        u = rng.standard_normal(p.dim) * 0.7 + 0.5
        if rng.random() < 0.2:
            u[rng.integers(p.dim)] = rng.choice([np.nan, np.inf, -np.inf, 1e308])
        if rng.random() < 0.2:
            u[:] = 1e308  # a sum that overflows with every term finite
        want = bool(np.isfinite(u).all()) and p.in_support(u)
        assert p._admissible(u) == want
        assert p._admissible(u[:N_FREE]) == bool(np.isfinite(u[:N_FREE]).all())


def test_kernel_as_before_and_log_collapsed_as_log_marginal(stepped_problem):
    from loadbayes.fit.composite import problem as pm
    from loadbayes.inference.condlinear import log_marginal
    from loadbayes.models.composite_prior import POSITIVE_BETA

    p, rng = stepped_problem, np.random.default_rng(6)
    g, d = p.grid, p.samples
    tau = np.array([4e4, 3e4])
    u0 = np.concatenate([p.prior.scale_free()[0], np.full(p.n_steps, 0.5)])
    checked = 0
    for _ in range(40):
        u = u0 + np.concatenate([rng.standard_normal(N_FREE) * 0.3,
                                 rng.random(p.n_steps) - 0.5])  # fmt: skip
        k = p.kernel(u, tau)
        # The call as it was: the times filled outside, exp(theta_of(u, 0.0)), zeros.
        n = len(p.events)
        ztz, zty, yty = np.zeros((n, 2, 7, 7)), np.zeros((n, 2, 7)), np.zeros((n, 2))
        pq = np.empty(d.size), np.empty(d.size)
        lp = pm._collapsed(
            u[:N_FREE], np.exp(theta_of(u[:N_FREE], 0.0)), tau, p.phi(u),
            g.times(p.phi(u)), g.pos[:0], g.left[:0], g.width[:0], g.pos_b[:0], g.last[:0],
            g.right[:0], g.v_a[:0], g.v_l[:0], g.v_b[:0], g.v, g.delta, g.starts, p._real,
            d.x, d.p, d.q, d.starts, d.n, p._mean_u, p._prec_u, p.m0, p.p0, POSITIVE_BETA,
            2.0 * np.pi * p.f_hz, *map(float, p.torque), float(p.h_max), p._xsums, False,
            pm._NO_WEIGHTS, *pq, ztz, zty, yty, False, pm._NO_RHO, p.seg, p.window,
        )  # fmt: skip
        if k is None:
            assert not np.isfinite(lp)
            continue
        checked += 1
        assert k.lp == lp and _same(k.ztz, ztz) and _same(k.zty, zty) and _same(k.yty, yty)
        sums = p.group_sums(k)
        want = p.prior.log_u(u[:N_FREE])
        for s in sums:
            want += log_marginal(s, tau, p.m0, p.p0, positive=POSITIVE_BETA)
        assert p.log_collapsed(sums, u, tau) == want
        assert p.log_collapsed(sums, u, tau) == want  # the prior term kept for this u
    assert checked > 20
