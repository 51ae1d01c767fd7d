"""Issue 36's checks of the reclose on the shared real record, with the model error said.

The State Grid record (``shared/real``, found as ``studies/real_record.find_record`` does:
``$LOADBAYES_REAL_RECORD`` first), both transformers: ``slm`` fitted on the first fault
at the demo's quick settings (4000 x 2 draws, 2000 burn-in, seed 0, as
``studies/real_record_physical.py``), the reclose predicted from its recorded voltage.
Both took 34 s on 2 shared cores (measured): ``make validate`` (LOADBAYES_VALIDATE=1).

What holds and is asserted (measured 2026-11-29): the band of a new observation covers
the first fault played back through its own fit (95 %, 97 % #1; 98 %, 95 % #2) and the
reclose's P (99 %, 92 %); most of the mean square of the reclose's Q miss (70 %, 84 %) is
error the first fault never showed (``fit/composite/model_error.py``): its AR(1) model
error, fitted there, gives a band that covers 77 % and 63 % of the reclose's Q, no more
than the fit's own. What the issue asks and the record does not give (#1's RMS of P 1.8
against 1.6; Q's band 77 % and 63 % against 85 %) is a strict xfail: it fails today for
the reasons the study measures (a load oscillating by 1 % of P0 before the fault, a
reactive inrush after the reclose, rows past the first fault's reach), and an XPASS says
the check is met and this test should say so.
"""

from __future__ import annotations

import os
from dataclasses import replace
from functools import cache

import numpy as np
import pytest

from loadbayes.core.settings import SamplerSettings
from loadbayes.fit.composite.driver import fit_composite
from loadbayes.fit.composite.model_error import held_out_error
from loadbayes.fit.composite.validate_parts import validate_parts_event
from loadbayes.models.dynamic import dynamic_model
from loadbayes.studies.real_record import events_of, find_record
from loadbayes.studies.real_record_physical import QUICK, _steps

RECORD = find_record()
pytestmark = [
    pytest.mark.statistical,
    pytest.mark.skipif(os.environ.get("LOADBAYES_VALIDATE") != "1",
                       reason="two real-record fits (34 s): make validate"),
    pytest.mark.skipif(RECORD is None, reason="the shared real record is not found"),
]  # fmt: skip

#: The issue's checks: RMS of the reclose (fraction of P0), P and Q, per transformer.
RMS_MAX = {"1号主变": (0.016, 0.024), "2号主变": (0.022, 0.040)}
COVER_MIN = (0.90, 0.85)


@cache
def _scored(bay: str):
    events, flags, info = events_of(RECORD, bay)
    f = info["f_hz"]
    model = dynamic_model("slm", f_hz=f, window_s=1.0 / f)
    straddle = [np.asarray(fl["straddle"], bool) for fl in flags[:2]]
    draws, burn = QUICK
    sampler = SamplerSettings(draws=draws, burn=burn, chains=2, seed=0)
    first = replace(events[0], straddle=straddle[0])
    post = fit_composite(model, [first], sampler=sampler).posterior
    own = validate_parts_event(post, model, events[0], exclude=straddle[0], seed=0)
    held = validate_parts_event(post, model, events[1], exclude=straddle[1], seed=0)
    return own, held, held_out_error(own, held, _steps(straddle[0], events[0].t)[0])


@pytest.mark.parametrize("bay", sorted(RMS_MAX))
def test_the_band_holds_the_first_fault_and_the_reclose_p(bay, record_property):
    own, held, form = _scored(bay)
    record_property("own_coverage", (own.coverage_p, own.coverage_q))
    record_property("reclose", (held.rms_p, held.rms_q, held.coverage_p, held.coverage_q))
    assert own.coverage_p >= 0.9 and own.coverage_q >= 0.9
    assert held.coverage_p >= COVER_MIN[0]
    # The first fault's model error supports no band that holds the reclose's Q: most of
    # that miss is error the first fault never showed.
    assert form["q"]["split"]["beyond"] >= 0.5
    assert form["q"]["coverage"] < COVER_MIN[1]


@pytest.mark.xfail(strict=True, reason="not met by the record (see the module docstring)")
@pytest.mark.parametrize("bay", sorted(RMS_MAX))
def test_issue_36_reclose_checks(bay):
    _, held, _ = _scored(bay)
    rms_p, rms_q = RMS_MAX[bay]
    assert held.rms_p <= rms_p and held.rms_q <= rms_q
    assert held.coverage_p >= COVER_MIN[0] and held.coverage_q >= COVER_MIN[1]
