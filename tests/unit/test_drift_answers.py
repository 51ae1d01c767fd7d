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
