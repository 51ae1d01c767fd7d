"""``loadbayes predict`` says when the fit's chains disagree about the fault (issue 37).

On GridDyn's default CMLD load, noise seed 16, the ``cmld-lite`` fit of the shallow fault
alone left its two chains on the feeder's X at 0.207 and 0.150 (R-hat 1.85); at the deep
fault one chain's draws collapsed or failed and the other's played, so the band was one
chain's, held 8 % of GridDyn's P, and nothing in the prediction said so
(``fit/composite/predict_chains.py`` has the numbers; that fit runs in ``make validate``,
``tests/statistical/test_predict_band_average.py``).

Here the same situation is built on data the package did not make: the cmld-lite fit of
one 15 % sag from the tests' SciPy feeder simulator (``tests/conftest.py``'s
``cmld_lite_nc``, one chain of 300), cut into two chains of 150, the second given six
times its feeder's X (``log_x_fd + 1.8``, as ``test_predict_collapse.py`` does draw by
draw). Measured at a 60 % sag, 40 draws: chain 1's 20 all play (20 stalled), chain 2's
13 collapse and 7 play (at 50 %: 6 collapse, too near the rule's edge for a test).
Deterministic (fixed seeds): no false alarm.
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

SAG, DURATION, DRAWS, RATE = 0.6, 0.1, 40, 60.0


def _two_modes(path, shift=1.8):
    post = Posterior.from_netcdf(path)
    assert post.n_chains == 1
    for name, x in list(post.draws.items()):
        x = np.asarray(x)
        post.draws[name] = x.reshape(2, -1, *x.shape[2:]).copy()
    post.draws["log_x_fd"][1] += shift  # chain 2: the feeder's X six times chain 1's
    return post


def test_chains_that_disagree_about_the_fault_are_said(cmld_lite_nc, tmp_path):
    post = _two_modes(cmld_lite_nc)
    pred = predict(post, sag=SAG, duration=DURATION, draws=DRAWS, seed=0, rate_hz=RATE)
    c = pred.chains
    assert c is not None and not c["converged"] and c["disagree"], c
    assert c["r_hat_worst"] == "log_x_fd" and c["r_hat_max"] > 2
    first, second = c["per_chain"]
    assert first["n"] + second["n"] == DRAWS
    # Chain 1 (the fit's own feeder) plays; chain 2 (six times it) mostly collapses.
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
