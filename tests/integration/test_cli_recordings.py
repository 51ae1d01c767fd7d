"""The recordings chain as a user runs it: read comtrade -> events -> fit zip -> export.

The commands are the user's, word for word, run in this process through Click's runner
from the test's folder (``run``): what is checked is each command's files, exit code and
one-line errors, the same in or out of a process (the entry point's own exit codes and
output are tests/integration/test_cli_exit_clean.py's). Fourteen processes here paid the
imports again, about 4 s of CPU each (pandapower's for the export more).
"""

import json

import numpy as np
import pandas as pd
import pytest
from click.testing import CliRunner

from cli_here import cli_here
from loadbayes.cli import main
from loadbayes.recordings.synth import sag_profile, write_comtrade, zip_waveforms

pytestmark = pytest.mark.integration

FAST = ["--draws", "1200", "--burn", "200", "--chains", "2", "--quiet"]
COEFS = (0.3, 0.2, 0.5, 0.6, 0.1, 0.3)


def run(*args, cwd):
    """The command run from ``cwd``: returncode, stdout and stderr, as a process gives them."""
    return cli_here(*args, cwd=cwd)


def one_line_error(res, *needles):
    assert res.returncode == 2, res.stderr
    assert "Traceback" not in res.stderr
    lines = [ln for ln in res.stderr.splitlines() if ln.strip()]
    assert len(lines) == 1, res.stderr
    for needle in needles:
        assert needle in lines[0], lines[0]


def _record(path, revision, fmt, f_hz=50.0):
    fs = 1600.0  # 32 samples per cycle
    t = np.arange(int(9.0 * fs)) / fs
    # Two sags with slow recoveries: the voltage sweeps 0.6..1, which separates Z, I, P.
    v_pu = sag_profile(t, [(1.0, 0.3, 0.4), (5.0, 0.3, 0.3)], recovery_s=1.0)
    v, i = zip_waveforms(t, v_pu, COEFS, p0=0.8, q0=0.3, f_hz=f_hz, harmonics=[(5, 0.02)])
    ratio = None if revision == "1991" else (230_000.0, 110.0)
    return write_comtrade(path, t, v, i, revision=revision, fmt=fmt, ratio=ratio)


@pytest.mark.parametrize(("revision", "fmt"), [("1991", "ASCII"), ("2013", "BINARY")])
def test_read_events_fit_recovers_the_zip(tmp_path, revision, fmt):
    _record(tmp_path / "rec", revision, fmt, f_hz=50.2)
    res = run("read", "comtrade", "rec.cfg", "--out", "rec.parquet", "--v-base", "230",
              "--s-base", "100", cwd=tmp_path)  # fmt: skip
    assert res.returncode == 0, res.stderr
    assert "v base 230 kV" in res.stderr
    rec = pd.read_parquet(tmp_path / "rec.parquet")
    # The six columns the fits read come first; the record table's others follow.
    assert list(rec.columns)[:6] == ["t_s", "v", "angle_rad", "p", "q", "f"]
    assert {"v2", "unbalanced", "straddle", "segment", "kind"} <= set(rec.columns)
    assert (tmp_path / "rec.parquet.meta.json").is_file()
    assert len(rec) == 450  # 9 s of 50 Hz cycles
    # The angle in the frame rotating at the nominal 50 Hz turns at 2 pi (50.2 - 50):
    # what fit composite integrates f into when there is no angle.
    turn = np.diff(rec["angle_rad"].to_numpy()) / np.diff(rec["t_s"].to_numpy())
    assert np.median(turn) == pytest.approx(2 * np.pi * 0.2, rel=1e-3)
    # Off nominal with a harmonic: within 2e-4 Hz, except a few mHz in the cycles that
    # straddle an abrupt (one-cycle) sag edge, where the window sees two phasors.
    err = np.abs(rec["f"].to_numpy() - 50.2)
    assert np.median(err) < 2e-4 and err.max() < 1e-2
    assert np.sum(err > 2e-3) <= 4
    res = run("events", "rec.parquet", "--out", "ev", "--post", "1.5", cwd=tmp_path)
    assert res.returncode == 0, res.stderr
    index = pd.read_csv(tmp_path / "ev" / "events.csv")
    assert list(index["file"]) == ["event_001.csv", "event_002.csv"]
    assert index["depth"].to_numpy() == pytest.approx([0.4, 0.3], abs=2e-3)
    assert "angle_rad" in pd.read_csv(tmp_path / "ev" / "event_001.csv").columns
    res = run("fit", "zip", "ev/event_001.csv", "--p0", "auto", "--q0", "auto", *FAST,
              "--json", "post.json", cwd=tmp_path)  # fmt: skip
    assert res.returncode == 0, res.stderr
    post = json.loads((tmp_path / "post.json").read_text())["parameters"]
    # The gap to the truth is the phasor estimate's (ramp cycles, off-nominal harmonic
    # leakage), not noise: a deterministic bound, not a statistical one.
    for name, truth in zip(("a1", "a2", "a3", "a4", "a5", "a6"), COEFS, strict=True):
        assert post[name]["mean"] == pytest.approx(truth, abs=0.03), name
    assert post["p0"]["mean"] == pytest.approx(0.8, abs=2e-3)
    assert post["q0"]["mean"] == pytest.approx(0.3, abs=2e-3)


def test_malformed_cfg_exits_2_naming_file_and_line(tmp_path):
    cfg, dat = _record(tmp_path / "rec", "1999", "BINARY")
    lines = cfg.read_text().splitlines()
    lines[1] = "7,6A,0D"
    cfg.write_text("\n".join(lines) + "\n")
    res = run("read", "comtrade", "rec.cfg", "--out", "x.csv", cwd=tmp_path)
    one_line_error(res, "rec.cfg: line 2: channel counts disagree")
    lines[1] = "6,6A,0D"
    cfg.write_text("\n".join(lines) + "\n")
    dat.write_bytes(dat.read_bytes()[:-7])
    res = run("read", "comtrade", "rec.cfg", "--out", "x.csv", cwd=tmp_path)
    one_line_error(res, "rec.dat: record", "truncated binary data")
    dat.unlink()
    res = run("read", "comtrade", "rec.cfg", "--out", "x.csv", cwd=tmp_path)
    one_line_error(res, "rec.cfg: data file rec.dat not found")
    assert not (tmp_path / "x.csv").exists()


def test_read_pmu_reports_and_export_draws(tmp_path):
    t = pd.date_range("2024-06-01 12:00", periods=400, freq="20ms", tz="UTC")
    v = sag_profile(np.arange(400) * 0.02, [(2.0, 0.5, 0.3)], recovery_s=3.0)
    p = 0.6 * v**2 + 0.1 * v + 0.3
    df = pd.DataFrame({"time": [x.isoformat() for x in t], "V": v, "Va": 0.0, "I": p / (3 * v),
                       "Ia": 0.0, "F": 50.0})  # fmt: skip
    df = pd.concat([df.iloc[:100], df.iloc[[50]], df.iloc[100:]])
    df.to_csv(tmp_path / "pmu.csv", index=False)
    res = run("read", "pmu", "pmu.csv", "--out", "pmu.parquet", "--time-col", "time",
              "--v-mag", "V", "--v-ang", "Va", "--i-mag", "I", "--i-ang", "Ia",
              "--freq-col", "F", "--quiet", cwd=tmp_path)  # fmt: skip
    assert res.returncode == 0, res.stderr
    assert "1 duplicate timestamps (rows 101)" in res.stderr
    rec = pd.read_parquet(tmp_path / "pmu.parquet")
    assert len(rec) == 400 and rec["q"].abs().max() < 1e-12
    res = run("fit", "zip", "pmu.parquet", "--q-col", "none", "--p0", "auto", *FAST,
              "--json", "post.json", "--netcdf", "post.nc", cwd=tmp_path)  # fmt: skip
    assert res.returncode == 0, res.stderr
    res = run("export", "post.json", "--to", "psse", "--out", "c.raw", "--stat", "q05",
              cwd=tmp_path)  # fmt: skip
    one_line_error(res, "--stat q05 needs the posterior draws", "NetCDF")
    res = run("export", "post.nc", "--to", "pandapower", "--out", "net.json", "--draws", "3",
              "--seed", "1", "--q-mvar", "0", cwd=tmp_path)  # fmt: skip
    assert res.returncode == 0, res.stderr
    names = sorted(x.name for x in tmp_path.glob("net_draw*"))
    assert names == [f"net_draw00{k}.json{s}" for k in (1, 2, 3) for s in ("", ".summary.txt")]
    side = (tmp_path / "net_draw002.json.summary.txt").read_text()
    assert "exported: posterior draw" in side and "a1:" in side
    res = run("export", "post.nc", "--to", "pandapower", "--out", "net.json", "--draws", "3",
              "--q-mvar", "0", cwd=tmp_path)  # fmt: skip
    one_line_error(res, "net_draw001.json: exists; use --force")


@pytest.mark.parametrize(
    ("args", "needle"),
    [
        (("--v-base", "1e308"), "--v-base 1e+308: outside [0.001, 2000] kV"),
        (("--s-base", "1e-308"), "--s-base 1e-308: outside [1e-06, 1e+06] MVA"),
        (("--v-base", "1e308", "--s-base", "1e-308"), "--v-base 1e+308: outside [0.001, 2000] kV"),
    ],
)
def test_bases_no_network_has_are_refused_by_option(tmp_path, args, needle):
    # Red-team L4: --v-base 1e308 said "the first cycle has no voltage (a dead or unscaled
    # VT)"; --s-base 1e-308 wrote a table of overflowed powers with numpy's warning.
    _record(tmp_path / "rec", "1999", "BINARY")
    res = CliRunner().invoke(main, ["read", "comtrade", str(tmp_path / "rec.cfg"), "--out",
                                    str(tmp_path / "x.csv"), *args])  # fmt: skip
    assert res.exit_code == 2, res.output
    assert res.output.strip().splitlines() == [f"loadbayes: error: {needle}, no network's base"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["rec.cfg", "rec.dat"]
