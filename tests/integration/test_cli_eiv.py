"""``fit zip --v-noise``: the errors-in-variables fit from the command line (issue 22)."""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest
from click.testing import CliRunner

from loadbayes.cli import main

pytestmark = pytest.mark.integration


def _csv(path, n=400, seed=0):
    rng = np.random.default_rng(seed)
    x = 1.0 + 0.04 * np.sin(np.linspace(0, 6, n))
    pd.DataFrame(
        {
            "V_kV": 13.8 * x * (1 + 0.01 * rng.standard_normal(n)),
            "P_MW": 6.5 * (0.3 * x**2 + 0.4 * x + 0.3) * (1 + 0.01 * rng.standard_normal(n)),
            "Q_Mvar": 2.0 * (0.5 * x**2 + 0.3 * x + 0.2) * (1 + 0.01 * rng.standard_normal(n)),
        }
    ).to_csv(path, index=False)


COLS = ["--v-col", "V_kV", "--p-col", "P_MW", "--v-base", "13.8"]


@pytest.mark.parametrize(
    ("extra", "says"),
    [
        (["--q-col", "none", "--v-noise", "auto"], "--v-noise auto needs Q as well as P"),
        (["--v-noise", "auto", "--likelihood", "student-t"], "drop --likelihood student-t"),
        (["--v-noise", "0"], "--v-noise"),
        (["--v-noise", "0.01", "--by", "bus", "--out", "f.parquet"], "for one bus"),
    ],
)
def test_bad_combinations_are_one_line(tmp_path, extra, says):
    path = tmp_path / "day.csv"
    _csv(path)
    res = CliRunner().invoke(main, ["fit", "zip", str(path), *COLS, *extra])
    assert res.exit_code == 2, res.output
    lines = res.output.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("loadbayes: error:") and says in lines[0]


def test_a_run_records_the_noise_model(tmp_path):
    path = tmp_path / "day.csv"
    _csv(path)
    out = tmp_path / "fit.json"
    args = ["fit", "zip", str(path), *COLS, "--q-col", "Q_Mvar", "--v-noise", "auto",
            "--draws", "600", "--burn", "200", "--chains", "2", "--json", str(out),
            "--quiet"]  # fmt: skip
    res = CliRunner().invoke(main, args)
    assert res.exit_code == 0, res.output
    doc = json.loads(out.read_text())
    assert doc["v_noise"] == "auto" and doc["eiv_acceptance"] > 0.9
    assert "sigma_v" in json.dumps(doc)
