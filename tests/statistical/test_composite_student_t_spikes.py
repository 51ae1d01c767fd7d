"""Student-t noise on a composite event with recorder spikes, and on a clean one."""

from __future__ import annotations

import numpy as np
import pytest

from loadbayes.cases.composite_sim import simulate_event
from loadbayes.fit.composite import fit_composite

pytestmark = pytest.mark.statistical


def _event():
    return simulate_event(
        "small_industrial", depth=0.4, noise=0.01, seed=3, t_end_s=2.5, fs=60.0, duration_s=0.2
    )


def _interval(post, name):
    return np.percentile(post.draws[name], [2.5, 97.5])


def _fit(ev, likelihood):
    return fit_composite([ev], draws=1500, burn=600, chains=2, seed=1, likelihood=likelihood)


def test_spikes_bias_the_gaussian_fit_and_the_student_t_fit_covers_the_truth():
    ev, truth = _event()
    # A recorder glitch: 3 one-sided spikes of -0.6 p.u. (60 noise sds) on P and Q during
    # the sag, 2% of the 151 samples.
    spikes = np.array([33, 37, 41])
    ev.p[spikes] -= 0.6
    ev.q[spikes] -= 0.6
    gauss = _fit(ev, "normal").posterior
    robust = _fit(ev, "student-t").posterior
    lo, hi = _interval(gauss, "f_m")
    # Fixed seeds, so the outcome is deterministic; measured: Gaussian 0.172-0.444,
    # Student-t 0.395-0.545 (truth 0.5). Over six other noise seeds with these short runs
    # the Gaussian interval missed 6/6 and the Student-t intervals of f_m and T' missed
    # 3/12 (unconverged short runs: at 2 x 8,000 iterations they covered), so another
    # seed would fail this test with probability about 1/4 (docs/composite.md, Checks).
    assert not lo <= truth["f_m"] <= hi, (lo, hi)
    lo, hi = _interval(robust, "f_m")
    assert lo <= truth["f_m"] <= hi, (lo, hi)
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
