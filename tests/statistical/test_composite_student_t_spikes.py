"""Student-t noise on a composite event with recorder spikes, and on a clean one."""

from __future__ import annotations

import numpy as np
import pytest

from loadbayes.cases.composite_sim import simulate_event
from loadbayes.core.settings import SamplerSettings
from loadbayes.fit.composite.driver import fit_composite
from loadbayes.models.zip_motor import CompositeModel

pytestmark = pytest.mark.statistical


def _event():
    return simulate_event(
        "small_industrial", depth=0.4, noise=0.01, seed=3, t_end_s=2.5, fs=60.0, duration_s=0.2
    )


def _interval(post, name):
    return np.percentile(post.draws[name], [2.5, 97.5])


def _fit(ev, likelihood):
    # 4 chains: with 2 x 2,500 kept the Student-t fit's T' (a long right tail, 95%
    # interval 0.37-3.14 s from 4 x 14,500) came out with a median of 1.28 s on seed 1
    # against 0.71-0.80 on seeds 2-3 and the long run, and its interval missed the truth.
    run = SamplerSettings(draws=4000, burn=1500, chains=4, seed=1)
    return fit_composite(CompositeModel(window_s=0, likelihood=likelihood), [ev], sampler=run)


def test_spikes_bias_the_gaussian_fit_and_the_student_t_fit_covers_the_truth():
    ev, truth = _event()
    # A recorder glitch: 3 one-sided spikes of -0.6 p.u. (60 noise sds) on P and Q during
    # the sag, 2% of the 151 samples.
    spikes = np.array([33, 37, 41])
    ev.p[spikes] -= 0.6
    ev.q[spikes] -= 0.6
    gauss = _fit(ev, "normal").posterior
    robust = _fit(ev, "student-t").posterior
    # Fixed seeds, so the outcome is deterministic. Measured (truth f_m 0.5): Gaussian
    # median 0.378, 95% interval 0.188-0.571 (the spikes inflate its noise, so the
    # interval is wide enough to hold the truth while the estimate is pulled off);
    # Student-t median 0.469, 0.423-0.505. An earlier version asserted that the
    # Gaussian interval misses: it did at 2 x 1,500 iterations and did not once the
    # model placed the sag's step (its chains disagreed); the bias and the lost
    # precision are what the spikes do whatever the run length.
    g_lo, g_mid, g_hi = np.percentile(gauss.draws["f_m"], [2.5, 50, 97.5])
    r_lo, r_mid, r_hi = np.percentile(robust.draws["f_m"], [2.5, 50, 97.5])
    assert r_lo <= truth["f_m"] <= r_hi, (r_lo, r_hi)
    assert abs(g_mid - truth["f_m"]) > 2 * abs(r_mid - truth["f_m"]), (g_mid, r_mid)
    assert g_hi - g_lo > 2 * (r_hi - r_lo), (g_lo, g_hi, r_lo, r_hi)
    lo, hi = _interval(robust, "t_prime_s")
    assert lo <= truth["t_prime_s"] <= hi, (lo, hi)
    flagged = robust.settings["flagged"]
    assert set(spikes) <= set(flagged["p"]) and set(spikes) <= set(flagged["q"])
    assert "nu_p" in robust.draws and np.median(robust.draws["nu_p"]) < 10
    assert robust.settings["likelihood"] == "student-t"


def test_on_clean_data_the_student_t_fit_agrees_with_the_gaussian():
    ev, _ = _event()
    gauss = _fit(ev, "normal").posterior
    robust = _fit(ev, "student-t").posterior
    for name in ("f_m", "p0", "q0"):
        g, r = gauss.draws[name], robust.draws[name]
        # Posterior means within half a posterior sd (Monte Carlo error of these short
        # runs is ~0.1 sd); nu is then large (the data look Gaussian).
        assert abs(g.mean() - r.mean()) < 0.5 * g.std(), name
    assert np.median(robust.draws["nu_p"]) > 10
