"""``fit composite --model slm --noise ar1``: AR(1) noise for a model of parts, from the CLI.

Two sags from the tests' own SciPy simulator (``tests/feeder_generator.py``) with white
noise; the run must sample ``rho_p``, ``rho_q``, print them, record the option so the
fit can be rebuilt, and ``--model auto`` refuses ``--noise`` in one line.
"""

from __future__ import annotations

import json

import pytest
from click.testing import CliRunner

from feeder_generator import write_sags
from loadbayes.cli import main

pytestmark = pytest.mark.integration


@pytest.fixture(scope="module")
def sags(tmp_path_factory):
    root = tmp_path_factory.mktemp("ar1")
    paths = write_sags(root)
    return root, [str(p) for p in paths]


def test_slm_samples_ar1_noise_and_says_so(sags):
    root, paths = sags
    out = root / "ar1.json"
    res = CliRunner().invoke(main, ["fit", "composite", *paths, "--model", "slm", "--noise",
                                    "ar1", "--f-hz", "50", "--draws", "400", "--burn", "200",
                                    "--json", str(out)])  # fmt: skip
    assert res.exit_code == 0, res.output
    assert "rho_p" in res.stdout and "AR(1) coefficient of P's noise" in res.stdout
    doc = json.loads(out.read_text())
    assert {"rho_p", "rho_q", "tau_p", "tau_q"} <= set(doc["parameters"])
    assert doc["settings"]["model_options"]["noise"] == "ar1"
    assert "AR(1) noise" in doc["parts"]["residuals"]["noise"]


def test_rho_max_bounds_the_coefficients_and_is_refused_where_it_has_no_use(sags):
    # The noise is white (rho about -0.1 +- 0.1): a bound of 0.02 binds, and is said.
    root, paths = sags
    out = root / "bounded.json"
    res = CliRunner().invoke(main, ["fit", "composite", *paths, "--model", "slm", "--noise",
                                    "ar1", "--rho-max", "0.02", "--f-hz", "50", "--draws",
                                    "300", "--burn", "150", "--json", str(out),
                                    "--quiet"])  # fmt: skip
    assert res.exit_code == 0, res.output
    doc = json.loads(out.read_text())
    assert doc["settings"]["model_options"]["rho_max"] == 0.02
    assert max(doc["parameters"][f"rho_{g}"]["hdi_high"] for g in "pq") <= 0.02
    assert any("sits at its bound 0.02" in w for w in doc["warnings"])
    for extra in (["--model", "slm"], ["--model", "zip+motor", "--noise", "ar1"]):
        res = CliRunner().invoke(main, ["fit", "composite", *paths, *extra, "--rho-max", "0.9",
                                        "--json", str(root / "y.json")])  # fmt: skip
        assert res.exit_code == 2
        assert res.stderr.strip() == ("loadbayes: error: --rho-max is an option of --noise "
                                      "ar1 with --model slm or cmld-lite")  # fmt: skip


def test_model_auto_refuses_noise_in_one_line(sags):
    root, paths = sags
    res = CliRunner().invoke(main, ["fit", "composite", *paths, "--model", "auto", "--noise",
                                    "ar1", "--json", str(root / "x.json")])  # fmt: skip
    assert res.exit_code == 2
    assert res.stderr.strip() == (
        "loadbayes: error: --noise needs a named --model (zip+motor, slm or cmld-lite), not auto"
    )
