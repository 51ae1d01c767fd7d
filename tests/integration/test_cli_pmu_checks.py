"""`read pmu` on the red-team's broken historian files (cli-redteam.md, C: M5, M11, L15).

Each file is written here: a 50 reports/s positive-sequence CSV with one defect.
"""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
from click.testing import CliRunner

from loadbayes.cli import main

pytestmark = pytest.mark.integration

MAP = ["--time-col", "time", "--v-mag", "V", "--v-ang", "Va", "--i-mag", "I", "--i-ang", "Ia",
       "--voltage-unit", "kV", "--current-unit", "kA"]  # fmt: skip


def run(tmp_path, frame, *extra, name="pmu.csv", text=None):
    path = tmp_path / name
    if text is not None:
        path.write_text(text)
    else:
        frame.to_csv(path, index=False)
    return CliRunner().invoke(
        main, ["read", "pmu", str(path), *MAP, *extra, "--out", str(tmp_path / "o.csv"), "--force"]
    )


def error(res, *needles):
    assert res.exit_code == 2, res.output
    lines = [ln for ln in res.output.splitlines() if ln.strip()]
    assert len(lines) == 1 and "Traceback" not in res.output, res.output
    for needle in needles:
        assert needle in lines[0], lines[0]


def frame(n=100, t=None):
    t = 1717243200 + np.arange(n) * 0.02 if t is None else t
    return pd.DataFrame(dict(time=t, V=132.79, Va=0.0, I=0.27, Ia=-21.8))


def test_epoch_out_of_range_and_in_milliseconds(tmp_path):
    d = frame()
    d.loc[5, "time"] = 1e300
    error(run(tmp_path, d, "--epoch"), "column 'time', row 6", "out of range")
    ms = frame(t=(1717243200 + np.arange(100) * 0.02) * 1000)
    res = run(tmp_path, ms, "--epoch")
    assert res.exit_code == 0 and "read as milliseconds" in res.output, res.output
    t = pd.read_csv(tmp_path / "o.csv")["t_s"].to_numpy()
    assert np.diff(t) == pytest.approx(0.02, abs=1e-9)


def test_negative_magnitude_is_refused_by_row(tmp_path):
    d = frame()
    d.loc[50, "V"] = -132.79
    error(run(tmp_path, d, "--epoch"), "column 'V', row 51", "cannot be negative")


def test_time_messages_name_the_row_and_say_why(tmp_path):
    iso = pd.date_range("2016-12-31T23:59:59.96", periods=5, freq="20ms")
    d = frame(5, t=[x.strftime("%Y-%m-%dT%H:%M:%S.%f") + "+00:00" for x in iso])
    d.loc[2, "time"] = "2016-12-31T23:59:60.000000+00:00"
    error(run(tmp_path, d), "row 3", "leap second", "2016-12-31T23:59:60.000000+00:00")
    back = pd.date_range("2024-11-03 00:59:58", periods=200, freq="20ms").strftime(
        "%Y-%m-%d %H:%M:%S.%f"
    )
    error(run(tmp_path, frame(200, t=back), "--tz", "America/New_York"),
          "row 101", "happens twice")  # fmt: skip
    fwd = pd.date_range("2024-03-10 01:59:58", periods=200, freq="20ms").strftime(
        "%Y-%m-%d %H:%M:%S.%f"
    )
    error(run(tmp_path, frame(200, t=fwd), "--tz", "America/New_York"),
          "row 101", "does not exist")  # fmt: skip
    error(run(tmp_path, frame(5, t=back[:5]), "--tz", "Mars/Olympus"), "unknown time zone")


def test_semicolon_file_is_read_and_a_ragged_row_named_by_data_row(tmp_path):
    rows = [f"{1717243200 + k * 0.02:.2f};132,79;0;0,27;-21,8" for k in range(50)]
    res = run(tmp_path, None, "--epoch", text="time;V;Va;I;Ia\n" + "\n".join(rows) + "\n")
    assert res.exit_code == 0, res.output
    assert pd.read_csv(tmp_path / "o.csv")["v"].to_numpy() == pytest.approx(1.0)
    lines = ["time,V,Va,I,Ia"] + [
        f"{1717243200 + k * 0.02:.2f},132.79,0,0.27,-21.8" for k in range(60)
    ]
    lines[50] += ",1,2"
    res = run(tmp_path, None, "--epoch", text="\n".join(lines) + "\n", name="r.csv")
    error(res, "r.csv", "row 50", "7 fields, expected 5")
