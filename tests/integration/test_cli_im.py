"""The ``loadbayes simulate im``, ``fit im`` and ``reproduce im`` commands, end to end."""

from __future__ import annotations

import json
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from click.testing import CliRunner

from loadbayes.models.motor_library import MOTORS

pytestmark = pytest.mark.integration

FAST = ["--draws", "1500", "--burn", "300", "--chains", "2", "--quiet"]


def run(*args: str, cwd: Path) -> subprocess.CompletedProcess:
    """The real command line, in a fresh interpreter."""
    return subprocess.run(
        [
            sys.executable,
            "-c",
            "from loadbayes.cli import main; main(prog_name='loadbayes')",
            *args,
        ],
        cwd=cwd,
        capture_output=True,
        text=True,
        timeout=300,
    )


def cli(*args: str, cwd: Path, monkeypatch) -> CliResult:
    """The same command in this process (for the many error cases: no start-up cost)."""
    from loadbayes.cli import main

    monkeypatch.chdir(cwd)
    res = CliRunner().invoke(main, list(args), prog_name="loadbayes")
    return CliResult(res.exit_code, res.stdout, res.stderr)


@dataclass
class CliResult:
    returncode: int
    stdout: str
    stderr: str


def one_line_error(res) -> str:
    assert res.returncode == 2, res.stderr
    lines = res.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("loadbayes: error: "), res.stderr
    assert "Traceback" not in res.stderr
    return lines[0]


@pytest.fixture(scope="module")
def record(tmp_path_factory) -> Path:
    d = tmp_path_factory.mktemp("im")
    res = run("simulate", "im", "--out", "d.csv", "--motor", "krause_3hp", "--seed", "3", cwd=d)
    assert res.returncode == 0, res.stderr
    return d / "d.csv"


def test_simulate_then_fit_follows_the_contract(record, monkeypatch) -> None:
    d = record.parent
    side = json.loads((d / "d.json").read_text())
    assert side["coefficients"] == MOTORS["krause_3hp"].coefficients()
    assert len(pd.read_csv(record)) == 3001
    res = run("fit", "im", "d.csv", "--json", "o.json", *FAST, cwd=d)
    assert res.returncode == 0, res.stderr
    out = json.loads((d / "o.json").read_text())
    for key in ("model", "method", "n", "parameters", "correlation", "warnings", "settings"):
        assert key in out
    assert out["model"] == "im" and out["n"] == 3001
    expected = "b1 b2 b3 ab ac tau_e tau_w tau_i rs xp x tp_s h_s xs xm xr rr".split()
    assert list(out["parameters"]) == expected
    assert out["settings"]["f_hz"] == 60.0 and out["settings"]["currents"] == "modelled"
    params = MOTORS["krause_3hp"]
    truth = {
        **params.coefficients(),
        **{k: getattr(params, k) for k in ("rs", "xp", "x", "tp_s", "h_s")},
    }
    for k, true in truth.items():
        p = out["parameters"][k]
        assert abs(p["mean"] / true - 1) < 0.06, k
        sd = p["sd"]
        assert p["mean"] - 5 * sd < true < p["mean"] + 5 * sd, k
    # Overwriting needs --force; the data's sidecar is never an output.
    mp = {"cwd": d, "monkeypatch": monkeypatch}
    again = cli("fit", "im", "d.csv", "--json", "o.json", *FAST, **mp)
    assert "exists; use --force" in one_line_error(again)
    clash = cli("fit", "im", "d.csv", "--json", "d.json", *FAST, **mp)
    assert "overwrite the input" in one_line_error(clash)
    resim = cli("simulate", "im", "--out", "d.csv", **mp)
    assert "exists; use --force" in one_line_error(resim)


def test_fit_refuses_bad_data_in_one_line(record, tmp_path, monkeypatch) -> None:
    mp = {"cwd": tmp_path, "monkeypatch": monkeypatch}
    df = pd.read_csv(record)
    df.drop(columns=["dw"]).to_csv(tmp_path / "nodw.csv", index=False)
    msg = one_line_error(cli("fit", "im", "nodw.csv", "--json", "o.json", *FAST, **mp))
    assert "nodw.csv" in msg and "dw" in msg
    bad = df.astype(object)
    bad.loc[6, "ed"] = "abc"
    bad.to_csv(tmp_path / "text.csv", index=False)
    msg = one_line_error(cli("fit", "im", "text.csv", "--json", "o.json", *FAST, **mp))
    assert "'ed'" in msg and "row 7" in msg and "abc" in msg
    df.iloc[:3].to_csv(tmp_path / "short.csv", index=False)
    msg = one_line_error(cli("fit", "im", "short.csv", "--json", "o.json", *FAST, **mp))
    assert "at least 4" in msg
    steady = df.copy()
    for k in ("ud", "uq", "ed", "eq", "w"):
        steady[k] = steady[k].iloc[0]
    steady.to_csv(tmp_path / "steady.csv", index=False)
    msg = one_line_error(cli("fit", "im", "steady.csv", "--json", "o.json", *FAST, **mp))
    assert "no excitation" in msg
    msg = one_line_error(cli("fit", "im", "none.csv", "--json", "o.json", *FAST, **mp))
    assert "not found" in msg
    msg = one_line_error(
        cli("fit", "im", str(record), "--json", "o.json", "--scheme", "exact", *FAST, **mp)
    )
    assert "--conjugate" in msg
    assert not (tmp_path / "o.json").exists()


def test_simulate_options_and_errors(tmp_path, monkeypatch) -> None:
    mp = {"cwd": tmp_path, "monkeypatch": monkeypatch}
    params = {"rs": 0.02, "xs": 0.08, "xm": 3.0, "rr": 0.02, "xr": 0.08, "h_s": 0.5}
    (tmp_path / "m.json").write_text(json.dumps(params))
    pd.DataFrame({"t_s": [0.0, 0.2, 0.2, 0.3], "v_pu": [1.0, 1.0, 0.85, 0.85]}).to_csv(
        tmp_path / "v.csv", index=False
    )
    ok = cli(
        "simulate", "im", "--out", "f.csv", "--params", "m.json", "--disturbance", "file",
        "--voltage-file", "v.csv", "--t-end", "0.5", "--noise", "0", "--quiet", **mp,
    )  # fmt: skip
    assert ok.returncode == 0, ok.stderr
    df = pd.read_csv(tmp_path / "f.csv")
    assert len(df) == 501 and df["ud"].iloc[-1] == pytest.approx(0.85)
    for args in (["--disturbance", "ramp", "--v-end", "0.9"], ["--disturbance", "walk"]):
        res = cli(
            "simulate",
            "im",
            "--out",
            "r.csv",
            "--t-end",
            "1",
            "--force",
            "--quiet",
            *args,
            **mp,
        )
        assert res.returncode == 0, res.stderr
    (tmp_path / "bad.json").write_text(json.dumps({**params, "xm": -1}))
    msg = one_line_error(cli("simulate", "im", "--out", "b.csv", "--params", "bad.json", **mp))
    assert "bad.json" in msg and "xm" in msg
    msg = one_line_error(cli("simulate", "im", "--out", "b.csv", "--t0", "9", **mp))
    assert "breakdown" in msg
    msg = one_line_error(cli("simulate", "im", "--out", "b.txt", **mp))
    assert ".csv" in msg
    assert not (tmp_path / "b.csv").exists()


def test_reproduce_writes_results_and_its_report_section(tmp_path, monkeypatch) -> None:
    report = tmp_path / "res" / "report.html"
    report.parent.mkdir()
    report.write_text(
        "<html><body><!-- loadbayes:section zip -->ZIP<!-- /loadbayes:section zip --></body></html>"
    )
    # In this process (the subject is the files and the section, not a process: a
    # fresh interpreter costs about 4 s of CPU; `simulate` and `fit` above run as one).
    mp = {"cwd": tmp_path, "monkeypatch": monkeypatch}
    res = cli("reproduce", "im", "--out", "res", "--quick", "--motor", "krause_3hp", **mp)
    assert res.returncode == 0, res.stderr
    assert "Table I" in res.stdout and "Table III" in res.stdout
    im = tmp_path / "res" / "im"
    names = "summary.json table1.csv table3.csv physical.csv eiv.csv fig6_coefficients.png"
    for name in [*names.split(), "physical.png", "data_krause_3hp.csv", "section.html"]:
        assert (im / name).stat().st_size > 0, name
    t1 = pd.read_csv(im / "table1.csv")
    assert list(t1.coefficient) == ["b1", "b2", "b3", "ab", "ac"]
    assert (t1.gs_err_pct.abs() < 6).all()
    assert {"paper_true", "paper_mean", "paper_err_pct", "measured_err_pct"} <= set(t1.columns)
    t3 = pd.read_csv(im / "table3.csv")
    assert {"gs", "ls", "gs_measured", "ls_measured", "kf_measured", "true"} <= set(t3.columns)
    np.testing.assert_allclose(t3.gs, t3.ls, rtol=2e-3)
    html = report.read_text()
    assert "ZIP" in html and html.count('<section id="im">') == 1
    assert "data:image/png;base64," in html and "slip 7" in html
    again = cli("reproduce", "im", "--out", "res", "--quick", "--motor", "krause_3hp", **mp)
    assert "exists; use --force" in one_line_error(again)


def test_report_section_is_replaced_not_duplicated(tmp_path) -> None:
    from loadbayes.studies.im_paper import update_report

    path = tmp_path / "report.html"
    update_report(path, "<section id='im'>one</section>")
    text = path.read_text()
    assert text.startswith("<!DOCTYPE html>") and "one" in text
    path.write_text(text.replace("</body>", "<section id='zip'>ZIP</section></body>"))
    update_report(path, "<section id='im'>two</section>")
    text = path.read_text()
    assert "two" in text and "one" not in text and "ZIP" in text
    assert text.count("loadbayes:section im -->") == 2  # one opening, one closing marker
