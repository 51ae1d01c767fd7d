"""``loadbayes simulate andes``: one short ANDES event, and its refusals (no ANDES run)."""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest
from click.testing import CliRunner

from loadbayes.cli import main

pytestmark = pytest.mark.integration

CONTRACT = {"p0", "q0", "v0", "a1", "a2", "a3", "a4", "a5", "a6", "f_m", "rs", "xs", "xm"}
CONTRACT |= {"rr", "xr", "h_s", "a", "b", "c", "t0", "mva_m", "q_c", "t_prime_s", "x_prime"}


def _run(tmp_path, *args):
    return CliRunner().invoke(main, ["simulate", "andes", *args], catch_exceptions=False)


def test_writes_an_event_and_the_truth(tmp_path):
    pytest.importorskip("andes", reason="ANDES is in the optional 'andes' extra")
    out = tmp_path / "ev.csv"
    args = ["--out", str(out), "--t-end", "1.2", "--fault-start", "0.3", "--rate", "60"]
    res = _run(tmp_path, *args, "--sag-depth", "0.3", "--noise", "0.01", "--seed", "3")
    assert res.exit_code == 0, res.output
    table = pd.read_csv(out)
    assert list(table.columns) == ["t_s", "v", "angle_rad", "p", "q", "f"]
    assert np.allclose(np.diff(table["t_s"]), 1 / 60) and table["t_s"].iloc[-1] == 1.2
    meta = json.loads(out.with_suffix(".json").read_text())
    assert CONTRACT <= set(meta["truth"])
    assert meta["truth"]["f_m"] == pytest.approx(0.4, abs=1e-5)
    assert abs(meta["settings"]["sag_depth"] - 0.3) <= 0.01
    assert table["v"].min() < 0.75  # the sag is in the samples
    # Noise at 1% of the RMS: the pre-fault p scatters by about that around p0.
    pre = table["p"][table["t_s"] < 0.3]
    assert 0.004 < pre.std() < 0.02


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--zip-p", "1,2"], "--zip-p: expected three shares"),
        (["--rate", "0"], "--rate must be > 0"),
        (["--f-m", "1.5"], "0 < f_m <= 1"),
        (["--bus", "7"], "--bus needs --case"),
        (["--case", "kundur/kundur_full.xlsx"], "--case needs --bus"),
    ],
)
def test_refuses_bad_options_with_exit_2(tmp_path, args, message):
    res = _run(tmp_path, "--out", str(tmp_path / "ev.csv"), *args)
    assert res.exit_code == 2 and message in res.output
    assert not (tmp_path / "ev.csv").exists()


def test_refuses_to_overwrite_without_force(tmp_path):
    out = tmp_path / "ev.csv"
    out.write_text("keep")
    res = _run(tmp_path, "--out", str(out))
    assert res.exit_code == 2 and "exists; use --force" in res.output
    assert out.read_text() == "keep"
