"""Issue 14, case by case: units, nominal values, one-line errors, the run as one transaction.

Error cases run in-process (CliRunner: no start-up cost); signals run the real command
line in a subprocess and watch its output folder, so a signal lands during the writes
without any hook in the code.
"""

from __future__ import annotations

import json
import re
import signal
import subprocess
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from click.testing import CliRunner

from loadbayes.core.settings import DataSpec, SamplerSettings

pytestmark = pytest.mark.integration

FAST = ["--draws", "1500", "--burn", "300", "--chains", "2", "--quiet"]
EXE = [sys.executable, "-m", "loadbayes"]


@dataclass
class Res:
    returncode: int
    stdout: str
    stderr: str


def cli(*args, cwd: Path, monkeypatch) -> Res:
    from loadbayes.cli import main

    monkeypatch.chdir(cwd)
    r = CliRunner().invoke(main, [str(a) for a in args], prog_name="loadbayes")
    if r.exception is not None and not isinstance(r.exception, SystemExit):
        raise r.exception
    return Res(r.exit_code, r.stdout, r.stderr)


def one_line(res: Res, *needles: str) -> str:
    assert res.returncode == 2, res.stderr
    lines = res.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("loadbayes: error: "), res.stderr
    for n in needles:
        assert n in lines[0], (n, lines[0])
    return lines[0]


def feeder_day(path: Path, *, kv=12.47, mw=5.0, mvar=2.0, seed=0, n=1440):
    """A day of 1-minute feeder data in kV, MW, Mvar; shares 0.4/0.3/0.3 for P and Q."""
    rng = np.random.default_rng(seed)
    t = np.arange(n)
    x = 1 + 0.04 * np.sin(2 * np.pi * t / n) + 0.002 * np.cumsum(rng.normal(0, 0.05, n))
    shape = 0.4 * x**2 + 0.3 * x + 0.3
    df = pd.DataFrame(
        {
            "t": t,
            "v": kv * x,
            "p": mw * shape * (1 + rng.normal(0, 0.002, n)),
            "q": mvar * shape * (1 + rng.normal(0, 0.002, n)),
        }
    )
    df.to_csv(path, index=False)
    return df


def outputs(folder: Path) -> list[str]:
    return sorted(p.name for p in folder.iterdir() if p.name != "bus.csv")


# ------------------------------------------------------------------- units (1, 2, 9)
def test_mw_with_unit_p0_is_refused_and_nominal_power_is_estimated(tmp_path, monkeypatch):
    feeder_day(tmp_path / "bus.csv")
    res = cli("fit", "zip", "bus.csv", "--v-base", 12.47, "--p0", 1, "--json", "o.json",
              *FAST, cwd=tmp_path, monkeypatch=monkeypatch)  # fmt: skip
    one_line(res, "column 'p'", "--p0 auto")
    # item 9: bases given, Q0 assumed 1 p.u. of the base: refused, naming --q0
    res = cli("fit", "zip", "bus.csv", "--v-base", 12.47, "--s-base", 5, "--p0", 1,
              "--q0", 1, "--json", "o.json", *FAST, cwd=tmp_path,
              monkeypatch=monkeypatch)  # fmt: skip
    one_line(res, "column 'q'", "--q0 auto")
    assert outputs(tmp_path) == []
    # no --p0/--q0: estimated, and said so
    res = cli("fit", "zip", "bus.csv", "--v-base", 12.47, "--s-base", 5, "--json", "o.json",
              "--draws", 3000, "--burn", 500, "--chains", 2, cwd=tmp_path,
              monkeypatch=monkeypatch)  # fmt: skip
    assert res.returncode == 0, res.stderr
    assert "P0 and Q0 not given" in res.stderr
    d = json.loads((tmp_path / "o.json").read_text())
    par = d["parameters"]
    assert par["q0"]["mean"] == pytest.approx(0.4, rel=0.01)  # 2 Mvar on a 5 MVA base
    # what the narrow band determines is the slope 2 a4 + a5 = 1.1 (true shares)
    assert any("2 a4 + a5 (dQ/dV at V0" in w for w in d["warnings"])


def test_kv_without_v_base(tmp_path, monkeypatch):
    feeder_day(tmp_path / "bus.csv", mw=1.0, mvar=1.0)
    res = cli("fit", "zip", "bus.csv", "--json", "o.json", *FAST, cwd=tmp_path,
              monkeypatch=monkeypatch)  # fmt: skip
    one_line(res, "column 'v'", "--v-base 12.47", "--accept-units")
    for cmd in (["fit", "exp"], ["track", "zip"]):
        out = ["--out", "t.csv"] if cmd[0] == "track" else ["--json", "o.json", *FAST]
        res = cli(*cmd, "bus.csv", *out, cwd=tmp_path, monkeypatch=monkeypatch)
        one_line(res, "--v-base 12.47")
    assert outputs(tmp_path) == []
    # accepted on request: a warning, not an error
    res = cli("fit", "zip", "bus.csv", "--json", "o.json", "--accept-units", *FAST,
              cwd=tmp_path, monkeypatch=monkeypatch)  # fmt: skip
    assert res.returncode == 0, res.stderr
    assert "units: V / V0 has median" in res.stderr


def test_track_zip_auto_nominal(tmp_path, monkeypatch):
    feeder_day(tmp_path / "bus.csv")
    res = cli("track", "zip", "bus.csv", "--out", "t.csv", "--v-base", 12.47, "--s-base", 5,
              "--p0", 1, "--q0", 1, cwd=tmp_path, monkeypatch=monkeypatch)  # fmt: skip
    one_line(res, "--q0 auto")
    res = cli("track", "zip", "bus.csv", "--out", "t.csv", "--v-base", 12.47, "--s-base", 5,
              "--plot", "t.png", cwd=tmp_path, monkeypatch=monkeypatch)  # fmt: skip
    assert res.returncode == 0, res.stderr
    assert re.search(r"Q0 = 0\.(4|399)", res.stderr) and outputs(tmp_path) == ["t.csv", "t.png"]
    tr = pd.read_csv(tmp_path / "t.csv")
    # Q's slope at V0, 2 a4 + a5 = 1.1, not the -14/35/-20 of Q0 = 1 p.u.
    last = tr.iloc[-1]
    assert 2 * last["a4_mean"] + last["a5_mean"] == pytest.approx(1.1, abs=0.05)


def test_motor_in_physical_units_and_mid_disturbance(tmp_path, monkeypatch):
    from loadbayes.cases.motor_sim import simulate, write_csv

    df = simulate("small_industrial", t_end_s=1.2, seed=2)
    write_csv(df.assign(w=df["w"] * 2 * np.pi * 60), tmp_path / "rad.csv")
    res = cli("fit", "im", "rad.csv", "--json", "o.json", *FAST, cwd=tmp_path,
              monkeypatch=monkeypatch)  # fmt: skip
    one_line(res, "rotor speed", "--accept-units")
    # item 10: a record that starts inside the sag; T0 from row 1 would be wrong
    peak = int(np.argmax(np.abs(df["dw"].to_numpy())))
    write_csv(df.iloc[peak + 30 :].reset_index(drop=True), tmp_path / "mid.csv")
    res = cli("fit", "im", "mid.csv", "--json", "o.json", *FAST, cwd=tmp_path,
              monkeypatch=monkeypatch)  # fmt: skip
    one_line(res, "row 1", "steady state", "--t0")


# -------------------------------------------------------- usage errors, one line (8)
@pytest.mark.parametrize(
    ("args", "needles"),
    [
        (["--draws", "0"], ["--draws"]),
        (["--chains", "0"], ["--chains"]),
        (["--hdi-prob", "1"], ["--hdi-prob"]),
        (["--prior", "a1=x"], ["--prior"]),
        (["--p0", "1", "--prior", "a1=0.3,0.1", "--prior", "a1=0.4,0.1"], ["a1 given twice"]),
        (["--p0", "1", "--prior-sd", "1e-300"], ["--prior-sd", "overflows"]),
        (["--draws", "100", "--burn", "99"], ["keep 1 draw", "at least 4"]),
        (["--thin", "2000"], ["keep 0 draw"]),
        (["--draws", "10000000000000"], ["memory", "TiB"]),
        (["--p-col", "v"], ["--p-col v", "already --v-col"]),
        (["--plot", "o.txt"], ["o.txt", "--plot", "'txt'"]),
        (["--plot", "o.bmp"], ["--plot", "'bmp'"]),
        (["--netcdf", "-"], ["--netcdf -"]),
    ],
)
def test_usage_errors_are_one_line_and_come_before_work(tmp_path, monkeypatch, args, needles):
    feeder_day(tmp_path / "bus.csv", kv=1.0, mw=1.0, mvar=1.0, n=200)
    base = ["--json", "o.json", "--draws", "2000", "--burn", "100"]
    res = cli("fit", "zip", "bus.csv", *base, *args, cwd=tmp_path, monkeypatch=monkeypatch)
    one_line(res, *needles)
    assert outputs(tmp_path) == []


def test_json_on_a_directory_is_one_line(tmp_path, monkeypatch):
    feeder_day(tmp_path / "bus.csv", kv=1.0, mw=1.0, mvar=1.0, n=200)
    (tmp_path / "d").mkdir()
    res = cli("fit", "zip", "bus.csv", "--json", "d", cwd=tmp_path, monkeypatch=monkeypatch)
    one_line(res, "d")


def test_json_dash_is_standard_output(tmp_path, monkeypatch):
    feeder_day(tmp_path / "bus.csv", kv=1.0, mw=1.0, mvar=1.0, n=200)
    res = cli("fit", "zip", "bus.csv", "--json", "-", "--p0", 1, "--q0", 1,
              "--draws", 1500, "--burn", 300, "--chains", 2,
              cwd=tmp_path, monkeypatch=monkeypatch)  # fmt: skip
    assert res.returncode == 0, res.stderr
    assert json.loads(res.stdout)["model"] == "zip"  # the table went to stderr
    assert "zip posterior" in res.stderr and outputs(tmp_path) == []


# ----------------------------------------------------------- signals (4, 5), subprocess
#: A SIGTERM during start-up or sampling (no temporary yet; was sent here at 2.0 s) is
#: test_cli_exit_clean's test_a_signal_at_a_random_moment_leaves_no_temporary[1] (SIGTERM
#: at 1.72 s, the same run and the same checks): dropped here as its duplicate. The
#: NetCDF ones stay: test_cli_exit_clean counts them in its leak-detection power.
MOMENTS = [
    ("TERM", ".o.nc."),  # during the NetCDF write (issue item 4)
    ("INT", ".o.nc."),  # Ctrl-C during the NetCDF write (item 5: was ignored)
    ("TERM", ".o.png."),  # during the figure
]


@pytest.mark.parametrize(("sig", "marker"), MOMENTS)
def test_a_signal_at_any_moment_leaves_all_or_nothing(tmp_path, sig, marker):
    feeder_day(tmp_path / "bus.csv", kv=1.0, mw=1.0, mvar=1.0, n=300)
    cmd = [*EXE, "fit", "zip", "bus.csv", "--p0", "1", "--q0", "1", "--draws", "4000",
           "--burn", "100", "--chains", "2", "--quiet", "--json", "o.json",
           "--netcdf", "o.nc", "--plot", "o.png"]  # fmt: skip
    proc = subprocess.Popen(cmd, cwd=tmp_path, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True)  # fmt: skip
    deadline = time.monotonic() + 120
    seen = False
    while not seen and proc.poll() is None and time.monotonic() < deadline:
        seen = any(p.name.startswith(marker) for p in tmp_path.iterdir())
        time.sleep(0.005)
    sent = proc.poll() is None
    if sent:
        proc.send_signal(getattr(signal, f"SIG{sig}"))
    out, err = proc.communicate(timeout=120)
    left = outputs(tmp_path)
    assert not [n for n in left if n.startswith(".")], left  # no temporaries
    assert left in ([], ["o.json", "o.nc", "o.png"]), left  # all or none
    if not (seen and sent):
        pytest.skip("the run ended before the moment came (machine too fast)")
    if proc.returncode == 0 and left == ["o.json", "o.nc", "o.png"]:
        # Sent as the run was ending: from its last step a run ignores signals by design
        # (cli.py: a late one would otherwise kill it after every output was written).
        pytest.skip("the signal came as the run was ending, every output written")
    assert proc.returncode == {"INT": 130, "TERM": 143}[sig], err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("loadbayes: "), err
    assert ("no output was written" in lines[0]) == (left == []), err


# --------------------------------------------------------- noise on V (11), measured
@pytest.mark.statistical
def test_noise_on_v_biases_the_shares_and_is_warned(tmp_path, monkeypatch):
    """Errors in variables: 1% noise on V, the fit treats V as exact.

    Measured (seed 0, n = 3000, V a slow swing of +/-5%): the noise-free fit lands
    within 3 posterior sd of the truth, the noisy one tens of sd away; the warning fires
    on the noisy V and not on the clean one. The seed is fixed; the margins (3 sd vs
    10 sd) make a false alarm at this seed impossible rather than rare.
    """
    from loadbayes import fit_zip

    rng = np.random.default_rng(0)
    n = 3000
    t = np.arange(n)
    x = 1 + 0.05 * np.sin(2 * np.pi * t / 700)
    p = 0.4 * x**2 + 0.3 * x + 0.3 + rng.normal(0, 0.002, n)
    z = {}
    for label, v in (("clean", x), ("noisy", x + rng.normal(0, 0.01, n))):
        post = fit_zip(
            {"v": v, "p": p},
            sampler=SamplerSettings(draws=3000, burn=500, chains=2, seed=1),
            spec=DataSpec(p0=1.0, q0=1.0),
        )
        slope = 2 * post["a1"] + post["a2"]
        z[label] = abs(slope.mean() - 1.1) / slope.std()
        pd.DataFrame({"v": v, "p": p}).to_csv(tmp_path / f"{label}.csv", index=False)
        res = cli("fit", "zip", f"{label}.csv", "--p0", 1, "--json", f"{label}.json", *FAST,
                  cwd=tmp_path, monkeypatch=monkeypatch)  # fmt: skip
        assert res.returncode == 0, res.stderr
        assert ("errors in variables" in res.stderr) == (label == "noisy"), res.stderr
    assert z["clean"] < 3 and z["noisy"] > 10, z
