"""Noise on V (errors in variables, issue 22): the plain fit's bias, and its correction.

Data from a generator written here (not the package's): a true voltage that swings
slowly by +/-4.5% about 1 p.u. over the record, 1% white noise on the measured V and
1% relative noise on P and Q. The plain fit treats V as exact and pulls the slopes
dP/dV and dQ/dV at V0 (``2 a1 + a2``, ``2 a4 + a5``) toward a flat load by the
attenuation ``var(V_true) / var(V)``; with 1500 samples its interval excludes the truth
by many sd. The errors-in-variables fit (a known sd, or ``auto``) must cover it.

False alarms: fixed seeds, so a run is deterministic. A correct sampler fails a
"within 3.3 posterior sd" check with probability 1e-3 per quantity (seven quantities:
under 1% for the file); the plain fit's bias is about 15 sd, so the "more than 6 sd off"
check cannot pass by chance either.
"""

import numpy as np
import pytest

from loadbayes.core.settings import SamplerSettings
from loadbayes.fit import fit_zip
from loadbayes.io.errors import OptionError

pytestmark = pytest.mark.statistical

SHARES_P = (0.3, 0.4, 0.3)
SHARES_Q = (0.5, 0.3, 0.2)
SLOPE_P = 2 * SHARES_P[0] + SHARES_P[1]  # dP/dV at V0 in units of P0: 1.0
SLOPE_Q = 2 * SHARES_Q[0] + SHARES_Q[1]  # 1.3
FAST = {"chains": 2, "draws": 1500, "burn": 500, "seed": 2}


def _day(n=1500, v_sd=0.01, seed=5):
    rng = np.random.default_rng(seed)
    t = np.arange(n)
    x = 1.0 + 0.03 * np.sin(2 * np.pi * 2 * t / n) + 0.015 * np.sin(2 * np.pi * t / 53)
    p = 4.0 * np.polyval(SHARES_P, x) * (1 + 0.01 * rng.standard_normal(n))
    q = 1.5 * np.polyval(SHARES_Q, x) * (1 + 0.01 * rng.standard_normal(n))
    v = x * (1 + v_sd * rng.standard_normal(n))
    return {"v": v, "p": p, "q": q}


def _slopes(post):
    d = post.draws
    out = {}
    for name, (i, j), truth in (("p", ("a1", "a2"), SLOPE_P), ("q", ("a4", "a5"), SLOPE_Q)):
        if i not in d:
            continue
        s = 2 * d[i] + d[j]
        out[name] = (float(s.mean()), float(s.std()), truth)
    return out


def test_the_plain_fit_is_biased_and_says_what_to_do():
    post = fit_zip(_day(), sampler=SamplerSettings(draws=3000, burn=500, seed=1))
    for mean, sd, truth in _slopes(post).values():
        assert mean < truth and (truth - mean) / sd > 6  # toward a flat load, many sd off
    noise = [w for w in post.warnings if "row to row" in w]
    assert noise and "v_noise=SD" in noise[0] and "v_noise='auto'" in noise[0]


@pytest.mark.parametrize("v_noise", [0.01, "auto"])
def test_the_errors_in_variables_fit_covers(v_noise):
    post = fit_zip(_day(), v_noise=v_noise, sampler=SamplerSettings(**FAST))
    for mean, sd, truth in _slopes(post).values():
        assert abs(mean - truth) < 3.3 * sd
    s = post.summary()
    assert s.loc["p0", "hdi_low"] < 4.0 < s.loc["p0", "hdi_high"]
    assert (s["r_hat"].dropna() < 1.02).all()
    assert post.settings["eiv_acceptance"] > 0.9
    assert not [w for w in post.warnings if "row to row" in w]  # the noise is modelled
    if v_noise == "auto":
        lo, hi = s.loc["sigma_v", "hdi_low"], s.loc["sigma_v", "hdi_high"]
        assert lo < 0.01 < hi and hi - lo < 0.002


def test_a_known_sd_corrects_p_alone():
    data = _day()
    post = fit_zip({"v": data["v"], "p": data["p"]}, v_noise=0.01, sampler=SamplerSettings(**FAST))
    mean, sd, truth = _slopes(post)["p"]
    assert abs(mean - truth) < 3.3 * sd and "a4" not in post.draws


def test_auto_needs_q_and_the_gaussian_likelihood():
    data = _day(n=200)
    with pytest.raises(OptionError, match="needs Q as well as P"):
        fit_zip({"v": data["v"], "p": data["p"]}, v_noise="auto", sampler=SamplerSettings(**FAST))
    with pytest.raises(OptionError, match="Gaussian likelihood"):
        fit_zip(data, v_noise=0.01, likelihood="student-t", sampler=SamplerSettings(**FAST))
    with pytest.raises(OptionError, match="positive sd"):
        fit_zip(data, v_noise=-0.01, sampler=SamplerSettings(**FAST))
