"""``loadbayes predict`` says when the fit's chains disagree about the fault (issue 37).

On GridDyn's default CMLD load, noise seed 16, the ``cmld-lite`` fit of the shallow fault
alone left its two chains on the feeder's X at 0.207 and 0.150 (R-hat 1.85); at the deep
fault one chain's draws collapsed or failed and the other's played, so the band was one
chain's, held 8 % of GridDyn's P, and nothing in the prediction said so
(``fit/composite/predict_chains.py`` has the numbers; that fit runs in ``make validate``,
``tests/statistical/test_predict_band_average.py``).

Here the same situation is built on data the package did not make: the cmld-lite fit of
one 15 % sag from the tests' SciPy feeder simulator (``tests/conftest.py``'s
``cmld_lite_nc``: frozen draws, one chain), its later half taken twice as two chains,
the second given ten times its feeder's X (``log_x_fd + 2.3``), so that the feeder is
the one thing the chains disagree on (the chains do not overlap in it: R-hat 1.85, the
rank-normalised R-hat's ceiling for two chains of 77 apart). Measured at a 50 % sag, 40
draws: chain 1's 20 all play (stalled), chain 2's 17 collapse and 3 play (at 60 %: 1
and 19 collapse; with six times the feeder, chain 2's 5 of 20 collapsed at 50 %, too few
for the rule). Deterministic (fixed seeds, fixed draws): no false alarm.
"""

from __future__ import annotations

import json

import numpy as np
import pytest
from click.testing import CliRunner

from loadbayes.cli import main
from loadbayes.fit.composite.predict import predict
from loadbayes.posterior import Posterior

pytestmark = pytest.mark.integration

SAG, DURATION, DRAWS, RATE = 0.5, 0.1, 40, 60.0


def _two_modes(path, shift=2.3):
    post = Posterior.from_netcdf(path)
    assert post.n_chains == 1
    # Both chains are the fit's later half, the second given the big feeder: the chains
    # then differ in the feeder's X alone, whatever the one short chain wandered through
    # (a short chain's two halves differed most in motor B's T0 on one machine).
    for name, x in list(post.draws.items()):
        x = np.asarray(x)
        half = x[:, x.shape[1] // 2 :]
        post.draws[name] = np.concatenate([half, half]).copy()
    post.draws["log_x_fd"][1] += shift  # chain 2: the feeder's X ten times chain 1's
    return post


def test_chains_that_disagree_about_the_fault_are_said(cmld_lite_nc, tmp_path):
    post = _two_modes(cmld_lite_nc)
    pred = predict(post, sag=SAG, duration=DURATION, draws=DRAWS, seed=0, rate_hz=RATE)
    c = pred.chains
    assert c is not None and not c["converged"] and c["disagree"], c
    assert c["r_hat_worst"] == "log_x_fd" and c["r_hat_max"] > 1.5
    first, second = c["per_chain"]
    assert first["n"] + second["n"] == DRAWS
    # Chain 1 (the fit's own feeder) plays; chain 2 (ten times it) mostly collapses.
    assert first["collapses"]["n"] == 0 and second["collapses"]["share"] > 0.5, c
    assert any(a["outcome"] == "collapses" and a["chains"] == [1, 2] for a in c["apart"])
    assert c["message"] in pred.warnings
    assert "chains disagree about this fault" in c["message"]
    assert "more than one mode" in c["message"] and "Not an answer" in c["message"]
    # In the JSON and the printed output.
    nc = tmp_path / "two.nc"
    post.to_netcdf(nc)
    out = tmp_path / "p.json"
    args = ["--sag", SAG, "--duration", DURATION, "--draws", DRAWS, "--json", out]
    r = CliRunner().invoke(main, ["predict", str(nc), *map(str, args)])
    assert r.exit_code == 0, r.output
    assert "chains disagree about this fault" in r.output
    assert json.loads(out.read_text())["chains"]["disagree"] is True


def test_a_fit_of_one_chain_is_as_it_was(cmld_lite_nc):
    # R-hat needs two chains: nothing to say, and no "chains" in the JSON.
    pred = predict(cmld_lite_nc, sag=SAG, duration=DURATION, draws=20, seed=0, rate_hz=RATE)
    assert pred.chains is None and "chains" not in pred.to_dict(band=False)
    assert not any("chains" in w for w in pred.warnings)
