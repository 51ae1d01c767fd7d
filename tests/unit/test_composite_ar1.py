"""AR(1) noise in the composite fit: whitened sums, the rho step, and a fit on an event
whose noise is AR(1) (written here; the package's simulator makes it noise-free)."""

import math
from dataclasses import replace

import numpy as np
import pytest

from loadbayes.cases.composite_sim import simulate_event
from loadbayes.core.settings import SamplerSettings
from loadbayes.fit.composite import fit_composite
from loadbayes.fit.composite.sums import ar_residual_sums, ar_sums_into, design_sums
from loadbayes.inference.ar1 import draw_rho
from loadbayes.measurements.record import EventRecord
from loadbayes.models.composite import design
from loadbayes.models.zip_motor import CompositeModel


def _rows(n=60, seed=0):
    rng = np.random.default_rng(seed)
    x = 1 + 0.1 * rng.standard_normal(n)
    x = x / x[0]  # V / v0, as the kernel is given it
    pm, qm = 1 + 0.2 * rng.standard_normal(n), 0.3 + 0.1 * rng.standard_normal(n)
    p, q = rng.standard_normal(n), rng.standard_normal(n)
    return x, pm, qm, p, q


def test_whitened_sums_are_those_of_the_whitened_design():
    x, pm, qm, p, q = _rows()
    seg = np.zeros(x.size, dtype=bool)
    seg[[0, 25]] = True  # two segments (samples left out between 24 and 25)
    rho = np.array([0.7, -0.3])
    zz, zy, yy = np.zeros((2, 7, 7)), np.zeros((2, 7)), np.zeros(2)
    ar_sums_into(x, pm, qm, p, q, seg, rho, zz, zy, yy)
    ev = EventRecord(np.arange(x.size) * 0.01, x, p, q)
    for g, (z, y) in enumerate(zip(design(ev, pm, qm), (p, q), strict=True)):
        w, v = z.copy(), y.copy()
        for k in range(x.size):
            if seg[k]:
                s = math.sqrt(1 - rho[g] ** 2)
                w[k], v[k] = s * z[k], s * y[k]
            else:
                w[k], v[k] = z[k] - rho[g] * z[k - 1], y[k] - rho[g] * y[k - 1]
        assert np.allclose(zz[g], w.T @ w) and np.allclose(zy[g], w.T @ v)
        assert yy[g] == pytest.approx(v @ v)
    # rho = 0 is the white design's sums.
    ar_sums_into(x, pm, qm, p, q, seg, np.zeros(2), zz, zy, yy)
    ztz, zty, yty = design_sums(x, pm, qm, p, q)
    assert np.allclose(zz, ztz) and np.allclose(zy, zty) and np.allclose(yy, yty)
    stats = ar_residual_sums(x, pm, qm, p, q, seg, np.zeros(7))
    assert stats[0, 3] == 2 and stats[0, 0] == pytest.approx(
        sum(p[k] * p[k - 1] for k in range(1, x.size) if not seg[k])
    )


def test_the_rho_step_leaves_its_conditional_invariant():
    # Residual statistics of a fixed series; the chain of rho must match the exact
    # conditional computed on a grid (mean and sd within 5 Monte Carlo sds).
    rng = np.random.default_rng(3)
    n, r, tau = 80, 0.6, 4.0
    e = np.zeros(n)
    e[0] = rng.normal(0, 1 / math.sqrt(tau * (1 - r * r)))
    for k in range(1, n):
        e[k] = r * e[k - 1] + rng.normal(0, 1 / math.sqrt(tau))
    stats = np.array([e[1:] @ e[:-1], e[:-1] @ e[:-1], e[0] ** 2, 1.0])
    grid = np.linspace(-0.999, 0.999, 20001)
    a = stats[1] - stats[2]
    logd = -0.5 * tau * (a * grid**2 - 2 * stats[0] * grid) + 0.5 * np.log1p(-(grid**2))
    w = np.exp(logd - logd.max())
    w /= w.sum()
    mean, sd = float(grid @ w), float(np.sqrt(((grid - grid @ w) ** 2) @ w))
    rho, out = 0.0, []
    for _ in range(20_000):
        rho, _ = draw_rho(stats, tau, rho, rng)
        out.append(rho)
    out = np.array(out[1000:])
    assert abs(out.mean() - mean) < 5 * sd / math.sqrt(out.size / 2)
    assert out.std() == pytest.approx(sd, rel=0.05)


def test_ar1_fit_recovers_rho_and_widens_what_white_noise_overstates():
    rng = np.random.default_rng(7)
    ev, truth = simulate_event(t_end_s=2.0, fs=60, seed=4, noise=0.0)

    def ar(r, sd):
        e = np.zeros(ev.n)
        e[0] = rng.normal(0, sd / math.sqrt(1 - r * r))
        for k in range(1, ev.n):
            e[k] = r * e[k - 1] + rng.normal(0, sd)
        return e

    bad = replace(ev, p=ev.p + ar(0.8, 0.004), q=ev.q + ar(0.6, 0.004))
    # 2 x 6,000 kept: at 2 x 2,000 the interval widths varied by a third from seed to
    # seed. Converged (4 x 18,000 kept, seeds 2 and 3) the white and AR(1) f_m intervals
    # are 0.074 and 0.117 wide, a ratio of 1.57; this short run gives 1.38 (seed 2). The
    # 0.066 this comment gave for white noise (2 x 9,000, before the jumps of
    # inference.moves.adaptive_metropolis) was short of the converged width, so the old
    # bound of 1.5 sat inside the run-to-run spread; 1.3 still asserts that AR(1) noise
    # widens the interval by nearly a third.
    run = SamplerSettings(draws=8000, burn=2000, chains=2, seed=2)
    white = fit_composite(CompositeModel(window_s=0), [bad], sampler=run)
    assert any("--noise ar1" in w for w in white.posterior.warnings)
    fit = fit_composite(CompositeModel(window_s=0, noise="ar1"), [bad], sampler=run)
    d = fit.posterior.draws
    for name, r in (("rho_p", 0.8), ("rho_q", 0.6)):
        lo, hi = np.percentile(d[name], [2.5, 97.5])
        assert lo < r < hi, (name, lo, hi)
    w_f, a_f = white.posterior.draws["f_m"], d["f_m"]
    assert np.percentile(a_f, 97.5) - np.percentile(a_f, 2.5) > 1.3 * (
        np.percentile(w_f, 97.5) - np.percentile(w_f, 2.5)
    )
    assert fit.posterior.settings["noise"] == "ar1"
    assert not any("run in stretches" in w for w in fit.posterior.warnings)


def test_an_ar1_error_slower_than_the_motor_is_said():
    from loadbayes.fit.composite.residuals import ar1_memory_warning

    rng = np.random.default_rng(0)

    def around(x, n=400):
        return x * (1 + 0.01 * rng.standard_normal((2, n)))

    # The real record's first fault with --noise ar1: rho 0.97 per 5 ms sample, a memory
    # of 0.164 s, and T' 0.026 s.
    slow = {"rho_p": around(0.97), "rho_q": around(0.5), "t_prime_s": around(0.026)}
    said = ar1_memory_warning(slow, 0.005)
    assert said is not None and "P rho 0.970" in said and "0.16" in said
    assert "Q rho" not in said  # Q's memory, 7 ms, is shorter than T'
    # A white-ish error, or a motor slower than the error's memory: nothing to say.
    assert ar1_memory_warning({**slow, "rho_p": around(0.5)}, 0.005) is None
    two = {"rho_p": around(0.97), "t_prime_s_a": around(0.02), "t_prime_s_b": around(0.5)}
    assert ar1_memory_warning(two, 0.005) is None
    assert ar1_memory_warning({"t_prime_s": around(0.026)}, 0.005) is None
