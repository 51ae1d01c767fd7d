"""``fit composite`` on an event ANDES simulated: the independent check of issue 11 (b).

ANDES (a ZIP load and a ``Motor3`` through a fault, docs/andes.md) writes the terminal
``t_s, v, p, q, f`` with noise; ``loadbayes fit composite`` must cover ANDES's own
parameters. Only quantities both conventions define alike are compared: the motor's
share ``f_m``, its transient time constant T', the static P shares (by their intervals)
and the operating point ``p0, q0`` (within the two simulators' agreement). The reactive
split differs by convention (loadbayes sizes a shunt to the motor's initial Q, the ANDES
case has none), and the motor's per-unit impedances sit on a base the data cannot fix
(docs/composite.md).

False-alarm rate: five 99% intervals, at most 5% if the sampler is calibrated (a fixed
seed makes the outcome deterministic; this is the chance such a seed fails).
"""

from __future__ import annotations

import json

import pytest
from click.testing import CliRunner

from loadbayes.cli import main

#: The fit's announced-cost probe is skipped (tests/conftest.py: no_cost_probe): no test
#: here checks the announcement, and the draws do not depend on it.
pytestmark = [pytest.mark.integration, pytest.mark.usefixtures("no_cost_probe")]

CHECKED = ("f_m", "t_prime_s", "a1", "a2", "a3")
#: ANDES and loadbayes's motor agree to this in P and Q (docs/andes.md, 1e-3 of the
#: motor's rating): p0 and q0 are pinned far tighter by the data (sd ~1e-4), so they are
#: compared within this agreement, not by their interval (a noise-free ANDES event gives
#: p0 2.4e-4 below ANDES's, 3 posterior sd).
SIMULATOR_AGREEMENT = 1e-3


def test_fit_composite_covers_the_andes_load(tmp_path):
    pytest.importorskip("andes", reason="ANDES is in the optional 'andes' extra")
    ev = tmp_path / "ev.csv"
    res = CliRunner().invoke(
        main,
        ["simulate", "andes", "--out", str(ev), "--sag-depth", "0.35", "--motor",
         "small_industrial", "--f-m", "0.4", "--noise", "0.005", "--seed", "1"],
        catch_exceptions=False,
    )  # fmt: skip
    assert res.exit_code == 0, res.output
    truth = json.loads(ev.with_suffix(".json").read_text())["truth"]
    out = tmp_path / "comp.json"
    res = CliRunner().invoke(
        main,
        ["fit", "composite", str(ev), "--json", str(out), "--hdi-prob", "0.99", "--window-s", "0",
         "--draws", "12000", "--burn", "4000", "--seed", "2", "--quiet"],
        catch_exceptions=False,
    )  # fmt: skip
    assert res.exit_code == 0, res.output
    params = json.loads(out.read_text())["parameters"]
    missed = {
        k: (truth[k], params[k]["hdi_low"], params[k]["hdi_high"])
        for k in CHECKED
        if not params[k]["hdi_low"] <= truth[k] <= params[k]["hdi_high"]
    }
    assert not missed, missed
    # The well-determined ones are also close, not merely inside a wide interval.
    assert abs(params["f_m"]["mean"] - truth["f_m"]) < 0.03
    for k in ("p0", "q0"):
        bound = SIMULATOR_AGREEMENT + 3 * params[k]["sd"]
        assert abs(params[k]["mean"] - truth[k]) < bound, (k, truth[k], params[k])
