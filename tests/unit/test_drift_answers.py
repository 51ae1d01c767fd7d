"""``fit zip --level drift`` says when the voltage answers to the load (issue 39).

A generated week at a feeder head (tests/cvr_generator.py: thermostatic loads, taps, the
3% reduction switched at midnight), once with 0.0047 p.u./MW of source impedance and once
with none. The drift fit learns from every move of V, so with the impedance it is biased
and must say so; without it, it must not (the detection is the slope's 95% interval above
zero and a load that moves V by over 0.2%: about a 2.5% false-alarm rate on the interval
alone, fixed seeds).
"""

import sys
from pathlib import Path

import pandas as pd
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from cvr_generator import Feeder, feeder  # noqa: E402
from loadbayes import DataSpec, SamplerSettings, fit_zip  # noqa: E402

SAMPLER = SamplerSettings(draws=800, burn=200, chains=2, seed=1)


@pytest.mark.parametrize("z", [0.0047, 0.0])
def test_the_drift_fit_says_when_the_voltage_answers_to_the_load(z):
    cols, _ = feeder(3, Feeder(days=7, z_pu_per_mw=z, pv_mw=0.0, glitches=False, gaps=False,
                               holidays=()))  # fmt: skip
    df = pd.DataFrame({"time": cols["time"], "v": cols["v_kv"], "p": cols["p_mw"],
                       "q": cols["q_mvar"]})  # fmt: skip
    post = fit_zip(df, spec=DataSpec(v_base=12.47, s_base=10, t_col="time"), level="drift",
                   sampler=SAMPLER, warn=False)  # fmt: skip
    said = [w for w in post.warnings if w.startswith("the voltage answers to the load")]
    assert len(said) == (1 if z else 0), post.warnings
    assert ("voltage_answers_to_load" in post.settings) == bool(z)


def _day_with(glitch):
    # Two days at 1 min written here: a level that wanders, V with taps, a ZIP load
    # (dP/dV 1.1); then a +9% V spike, three hours of stuck P and a +0.5 p.u. P spike.
    import numpy as np

    rng = np.random.default_rng(4)
    n = 2880
    t = np.arange(n) * 60.0
    v = 1.0 + 0.00625 * ((np.arange(n) // 240) % 3) + rng.normal(0, 0.0005, n)
    level = 1 + 0.1 * np.sin(2 * np.pi * t / 86400)
    p = level * (0.4 * v**2 + 0.3 * v + 0.3) + rng.normal(0, 0.002, n)
    q = 0.5 * level * (0.4 * v**2 + 0.3 * v + 0.3) + rng.normal(0, 0.002, n)
    if glitch:
        v[500] *= 1.09
        p[900:1080] = p[900]
        p[1500] += 0.5
    return pd.DataFrame({"time": t, "v": v, "p": p, "q": q})


def test_the_drift_fit_leaves_glitches_out_and_counts_them():
    # Issue 39: "stuck values, spikes in V and P, found and left out, with a count, in the
    # drift fit as in the others" (loadbayes cvr's rule, fit/cvr_data.find_glitches).
    spec = DataSpec(t_col="time")
    bad = fit_zip(_day_with(True), spec=spec, level="drift", sampler=SAMPLER, warn=False)
    g = bad.settings["glitches"]
    assert (g["spikes_v"], g["spikes_p"], g["stuck"]) == (1, 1, 180)
    assert g["rows"][0] == 501 and 1501 in g["rows"]  # 1-based data rows
    said = [w for w in bad.warnings if w.startswith("glitches left out of the fit")]
    assert len(said) == 1 and "1 V spike(s), 1 P spike(s), 180 stuck" in said[0]
    clean = fit_zip(_day_with(False), spec=spec, level="drift", sampler=SAMPLER, warn=False)
    assert "glitches" not in clean.settings
    assert not any(w.startswith("glitches") for w in clean.warnings)
    # left out, the glitches do not move dP/dV: within 2 posterior sd of the clean fit's
    d_bad = 2 * bad.draws["a1"] + bad.draws["a2"]
    d_clean = 2 * clean.draws["a1"] + clean.draws["a2"]
    assert abs(d_bad.mean() - d_clean.mean()) < 2 * d_clean.std(), (d_bad.mean(), d_clean.mean())
