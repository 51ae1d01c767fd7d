"""Coverage of the energy CVR factor over 24 generated feeders (issue 39; `make validate`).

Each feeder is tests/cvr_generator.py's 90-day on/off test (thermostatic loads, PV, gaps,
glitches) with its own seed and a source impedance from 0.002 to 0.005 p.u./MW; the
schedule is found from the voltage (no column given), with the weather, holiday and
irradiance columns. The energy factor's 95% interval must cover the counterfactual truth
on at least 21 of the 24 (the issue's 90%): a calibrated interval fails that with
probability 3.0% (Binomial(24, 0.95)), the test's false-alarm rate. Fixed seeds. About two
minutes on the 2
shared cores, so it runs under `make validate` (LOADBAYES_VALIDATE=1) only; `make test`
runs three feeders (tests/unit/test_cvr.py). The coverage of dP/dV at the instants of its
steps is printed beside it (measured, not asserted).
"""

import os
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from cvr_generator import Feeder, feeder  # noqa: E402
from loadbayes.core.settings import SamplerSettings  # noqa: E402
from loadbayes.fit.cvr import CVR_DEFAULTS, cvr  # noqa: E402

pytestmark = [
    pytest.mark.statistical,
    pytest.mark.skipif(
        os.environ.get("LOADBAYES_VALIDATE") != "1",
        reason="the full count runs under make validate",
    ),  # fmt: skip
]

FEEDERS = 24


def test_the_energy_factor_covers_the_truth_on_24_feeders():
    rows, inst = [], []
    for i in range(FEEDERS):
        z = 0.002 + 0.003 * i / (FEEDERS - 1)
        cols, truth = feeder(1000 + i, Feeder(z_pu_per_mw=z))
        out = cvr(pd.DataFrame(cols), t_col="time", v_col="v_kv", p_col="p_mw", v_base=12.47,
                  s_base=10.0, weather_col="temp_c", holiday_col="holiday",
                  pv_col="irradiance", sampler=CVR_DEFAULTS,
                  step_sampler=SamplerSettings(draws=2000, burn=500, chains=2, seed=i))  # fmt: skip
        e = out["energy"]["p"]
        rows.append((truth["cvr_energy"], e["low"], e["high"]))
        d = out["instantaneous"]["dP/dV"]
        at = np.flatnonzero(truth["kept"])[np.asarray(d["step_rows"]) - 1]
        t_inst = float(np.mean(truth["sens"][at] / truth["p_net"][at]))
        inst.append((t_inst, d["low"], d["high"], d["mean"]))
    covered = sum(lo <= t <= hi for t, lo, hi in rows)
    print(f"energy CVR factor covered on {covered} of {FEEDERS} feeders")
    # measured, not asserted: dP/dV leans a little low on these feeders (the closing note)
    c_inst = sum(lo <= t <= hi for t, lo, hi, _ in inst)
    bias = float(np.mean([m - t for t, _, _, m in inst]))
    print(f"dP/dV covered at its steps on {c_inst} of {FEEDERS} (mean error {bias:+.3f})")
    assert covered >= 21, rows
