"""The composite load fitted to the first fault of a real fault record predicts the second.

The record is the State Grid 220 kV file in ``shared/real`` beside the repository (its
README and licence are there; source: zhangsonggui/comtradeOfPython, Mulan PSL v2). The
events are built here from the reader's library functions: one event per waveform window,
its phasor rows at four per cycle (positive-sequence V, angle, P, Q).

The bound: the README's plain least-squares fit of the same model (ZIP + third-order
motor, first fault) predicts the second fault to 2.2% / 2.7% of P0 RMS (P / Q,
transformer #1) and 4.5% / 5.3% (#2); a static-only fit is 2-3 times worse. The posterior
mean is asked to do as well as that baseline within 25% (its RMS is over the samples not
straddling a step; the baseline's own scoring is not stated): at 1.25 times the baseline
a load without its motor (2-3 times) fails. Measured at these settings: 1.3% / 2.6% (#1),
2.8% / 4.1% (#2). Coverage of the 95% band is reported, not asserted (Q of #2 is about
0.65: the recovery of Q is slower than the model's). 12-40 s on 2 shared cores (measured).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from loadbayes.core.settings import SamplerSettings
from loadbayes.fit.composite import fit_composite
from loadbayes.fit.composite.validate import validate_events
from loadbayes.measurements.events import events_from_arrays
from loadbayes.models.zip_motor import CompositeModel
from loadbayes.recordings.comtrade import read_comtrade
from loadbayes.recordings.record import phasor_rows, record_table

pytestmark = pytest.mark.integration


def _real() -> Path | None:
    for folder in Path(__file__).resolve().parents:
        if (folder / "shared" / "real" / "xtz.cfg").is_file():
            return folder / "shared" / "real" / "xtz.cfg"
    return None


REAL = _real()
BASELINE_PREDICT = {"1号主变": (0.022, 0.027), "2号主变": (0.045, 0.053)}
NAMES = {k: k for k in ("t", "v", "p", "q", "f", "angle", "event")}


@pytest.mark.skipif(REAL is None, reason="shared/real is not beside the repository")
@pytest.mark.parametrize("bay", sorted(BASELINE_PREDICT))
def test_the_first_fault_predicts_the_second(bay, record_property):
    w = read_comtrade(REAL, bay=bay)
    rows = phasor_rows(record_table(w, per_cycle=4).columns)
    events, straddle = [], []
    for seg in (0, 2):  # the two waveform windows: the fault and the reclose onto it
        m = rows["segment"] == seg
        cols = {"t": rows["t_s"][m] - rows["t_s"][m][0], "v": rows["v"][m], "p": rows["p"][m],
                "q": rows["q"][m], "angle": rows["angle_rad"][m]}  # fmt: skip
        (ev,) = events_from_arrays(cols, np.arange(1, m.sum() + 1), path=f"{bay} {seg}",
                                   names=NAMES, f_hz=w.f_nominal)  # fmt: skip
        events.append(ev)
        straddle.append(rows["straddle"][m])
    assert 0.35 < events[0].t[-1] < 0.45  # a short window, accepted
    run = SamplerSettings(draws=4000, burn=2000, chains=4, seed=0)
    fit = fit_composite(CompositeModel(f_hz=w.f_nominal), events[:1], sampler=run)
    assert "short" in fit.posterior.extra_json["identifiability"]["short_window"]
    fitted, predicted = validate_events(fit.posterior, events, exclude=straddle)
    for key in ("rms_p", "rms_q", "coverage_p", "coverage_q", "n_excluded"):
        record_property(f"predict_{key}", getattr(predicted, key))
    print(bay, "fitted", fitted.to_dict(), "predicted", predicted.to_dict())
    bp, bq = BASELINE_PREDICT[bay]
    assert predicted.rms_p < 1.25 * bp and predicted.rms_q < 1.25 * bq
    assert predicted.n_excluded == int(straddle[1].sum()) > 0
    assert 0.0 <= predicted.coverage_p <= 1.0 and 0.0 <= predicted.coverage_q <= 1.0
