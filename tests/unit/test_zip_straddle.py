"""A ZIP fit of an event file leaves out the rows its record flags as straddling a step
(issue 40: one such row put every share of the README's COMTRADE sag outside its interval).

The sag is built: ZIP (0.4, 0.3, 0.3) with 0.01 % noise, a step from 1.0 to 0.7 p.u. and
back, and at each edge one row whose window mixes the two sides (the mean of their V and
of their P, which no ZIP load gives), flagged in ``straddle`` as ``events`` writes it.
"""

import warnings

import numpy as np
import pandas as pd

from loadbayes import SamplerSettings, fit_zip
from loadbayes.posterior import FitWarning


def _sag(path, flag=True):
    rng = np.random.default_rng(0)
    v = np.r_[np.full(40, 1.0), np.full(40, 0.7), np.full(40, 1.0)]
    v = v * (1 + 0.002 * rng.standard_normal(v.size))
    p = 0.4 * v**2 + 0.3 * v + 0.3
    q = 0.6 * v**2 + 0.2 * v + 0.2
    straddle = np.zeros(v.size, dtype=bool)
    for i in (40, 80):  # the window holds half of each side
        v[i], p[i], q[i] = (v[i - 1] + v[i + 1]) / 2, (p[i - 1] + p[i + 1]) / 2, q[i]
        straddle[i] = flag
    p = p * (1 + 1e-4 * rng.standard_normal(v.size))
    q = q * (1 + 1e-4 * rng.standard_normal(v.size))
    t = np.arange(v.size) * 0.02
    pd.DataFrame({"t_s": t, "v": v, "p": p, "q": q, "straddle": straddle}).to_csv(path, index=False)
    return str(path)


def _fit(path):
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        post = fit_zip(path, sampler=SamplerSettings(draws=2000, burn=500, chains=2, seed=1))
    return post, [str(w.message) for w in caught if issubclass(w.category, FitWarning)]


def _miss(post):
    # How far dP/dV's posterior mean is from the true 1.1, in posterior sds.
    x = 2 * post["a1"] + post["a2"]
    return abs(float(x.mean()) - 1.1) / float(x.std())


def test_straddling_rows_are_left_out_and_said(tmp_path):
    post, said = _fit(_sag(tmp_path / "event.csv"))
    assert post.settings["n"] == 118  # the two flagged rows left out
    assert any("straddles a voltage step" in w and "41, 81" in w for w in said), said
    assert _miss(post) < 3.0
    # Unflagged, the same rows bias dP/dV by dozens of its sds: what the flag prevents.
    plain, said = _fit(_sag(tmp_path / "plain.csv", flag=False))
    assert plain.settings["n"] == 120 and _miss(plain) > 10.0
    assert not any("straddles" in w for w in said)
