"""The quick start and ``loadbayes report`` end to end, as a newcomer runs them (issue 15).

The quick start (``example zip``, the drift fit) runs as processes, as a newcomer types
it; the other commands here run in this process through Click's runner (``cli``): what
they check is the command's output, exit code and one-line errors, which are the same in
or out of a process (the process boundary itself, the entry point's exit codes and
output, is tests/integration/test_cli_exit_clean.py's), and each process would pay the
imports again (about 4 s of CPU each, 17 processes).
"""

from __future__ import annotations

import re
import subprocess
import sys
import warnings

import numpy as np
import pytest

from cli_here import cli_here
from loadbayes.core.settings import DataSpec, SamplerSettings

pytestmark = pytest.mark.integration

EXE = [sys.executable, "-m", "loadbayes"]
FAST = ["--draws", "1200", "--burn", "200", "--chains", "2"]


def run(*args, cwd, stdout=None):
    return subprocess.run([*EXE, *map(str, args)], cwd=cwd, capture_output=stdout is None,
                          stdout=stdout, text=True, timeout=300)  # fmt: skip


def cli(*args, cwd):
    """The command run in this process from ``cwd``: returncode, stdout, stderr as ``run``."""
    return cli_here(*args, cwd=cwd)


@pytest.fixture(scope="module")
def quick_start(tmp_path_factory):
    """The README quick start: `loadbayes example zip > bus.csv`, a drift fit, no --json."""
    root = tmp_path_factory.mktemp("quick")
    with open(root / "bus.csv", "w") as fh:
        assert run("example", "zip", cwd=root, stdout=fh).returncode == 0
    res = run("fit", "zip", "bus.csv", "--v-base", "11", "--s-base", "5", "--t-col", "time",
              "--level", "drift", *FAST, "--netcdf", "fit.nc", cwd=root)  # fmt: skip
    assert res.returncode == 0, res.stderr
    return root, res


def test_the_example_fits_as_written_and_prints_an_80_column_table(quick_start):
    root, res = quick_start
    lines = res.stdout.splitlines()
    assert lines[0].startswith("zip posterior from bus.csv")
    assert max(len(line) for line in lines) <= 80, res.stdout
    rows = {line.split()[0]: line.split() for line in lines[2:]}
    assert set(rows) == {"a1", "a2", "a3", "a4", "a5", "a6", "tau_p", "tau_q", "drift_p",
                         "drift_q"}  # fmt: skip
    # The shipped example's true slopes (data/README.md: dP/dV = 2 a1 + a2 = 0.85, dQ/dV =
    # 1.30) lie in their intervals; the day determines them, not the shares one by one.
    for name, true in (("dP/dV", 0.85), ("dQ/dV", 1.30)):
        said = re.search(rf"{name} = (\S+) \(sd \S+, 95% (\S+) to (\S+);", res.stderr)
        assert said, res.stderr
        assert float(said[2]) <= true <= float(said[3]), (name, said[0])
        # Three significant digits, no exponent: '0.786', not '0.78634' or '7.86e-01'.
        assert re.fullmatch(r"-?\d\.\d{2,3}", said[1]), said[0]
    assert not any("the load level changes" in line for line in res.stderr.splitlines())
    assert "summarising the draws" in res.stderr
    assert not (root / "post.json").exists()


def test_report_from_netcdf_has_summary_figures_and_truth_flags(quick_start, tmp_path):
    root, _ = quick_start
    # A one-level fit of the same day (confounded, and said so) draws all four figures,
    # the load curves P(V), Q(V) among them.
    res = cli("fit", "zip", "bus.csv", "--v-base", "11", "--s-base", "5", "--p0", "1",
              "--q0", "0.4", *FAST, "--quiet", "--netcdf", tmp_path / "plain.nc",
              cwd=root)  # fmt: skip
    assert res.returncode == 0, res.stderr
    # a1 = 20 lies far outside the fit's interval of a1; a4 = 0.6 inside.
    res = cli("report", tmp_path / "plain.nc", "--out", "r.html", "--truth", "a1=20",
              "--truth", "a4=0.6", cwd=root)  # fmt: skip
    assert res.returncode == 0, res.stderr
    html = (root / "r.html").read_text()
    assert (
        html.index("id='summary'") < html.index("class='contents'") < html.index("id='parameters'")
    )
    assert html.count("<figure>") >= 4
    assert html.count("<figure>") == html.count("<figcaption>Figure ") == html.count(" alt='")
    assert not re.search(r"(src|href)=['\"]?(https?:)?//", html)  # nothing fetched
    # a1 = 20 is flagged in the summary; a4 = 0.6 is not.
    assert "1 of 2 true values lie outside their 95% interval: a1." in html
    assert html.count("OUTSIDE the interval") == 1
    assert "Warnings (" in html or "No warnings" in html
    assert "the load level changes over the record" in html  # the one level is confounded


def test_report_of_the_quick_start_drift_fit(quick_start):
    # The README's third line: the drift fit's report has the marginals, pairs and traces
    # (no load curves: a drifting level has no single P0 to draw P(V) at) and no
    # confounding warning.
    root, _ = quick_start
    res = cli("report", "fit.nc", "--out", "report.html", "--truth", "a1=0.3", cwd=root)
    assert res.returncode == 0, res.stderr
    html = (root / "report.html").read_text()
    assert html.count("<figure>") == html.count("<figcaption>Figure ") >= 3
    assert "Marginal posteriors" in html and "Pair plots" in html
    assert "the load level changes over the record" not in html
    assert "OUTSIDE the interval" not in html  # the true a1 = 0.3 lies in its wide interval


def test_report_from_json_says_where_the_figures_are(quick_start, tmp_path):
    root, _ = quick_start
    res = cli("fit", "zip", "bus.csv", "--v-base", "11", "--s-base", "5", *FAST, "--quiet",
              "--json", tmp_path / "fit.json", cwd=root)  # fmt: skip
    assert res.returncode == 0, res.stderr
    res = cli("report", tmp_path / "fit.json", "--out", tmp_path / "r.html", "--quiet", cwd=root)
    assert res.returncode == 0 and res.stderr == "", res.stderr
    html = (tmp_path / "r.html").read_text()
    assert "<img" not in html and "--netcdf fit.nc" in html and "a6" in html


def test_report_errors_are_one_line_with_exit_2(quick_start, tmp_path):
    root, _ = quick_start
    (tmp_path / "r.html").write_text("old")
    res = cli("report", "fit.nc", "--out", tmp_path / "r.html", cwd=root)
    assert res.returncode == 2 and "exists; use --force" in res.stderr
    for bad, why in (("missing.nc", "file not found"), ("bus.csv", "not a JSON result")):
        res = cli("report", bad, "--out", tmp_path / "x.html", cwd=root)
        assert res.returncode == 2 and why in res.stderr, res.stderr
        assert len(res.stderr.strip().splitlines()) == 1 and "Traceback" not in res.stderr
    res = cli("report", "fit.nc", "--out", tmp_path / "x.html", "--truth", "zz=1", cwd=root)
    assert res.returncode == 2 and "zz" in res.stderr


def test_reports_of_an_exponential_and_a_motor_fit(tmp_path):
    from loadbayes.cases.motor_sim import simulate
    from loadbayes.fit import fit_exp, fit_im
    from loadbayes.posterior import FitWarning
    from loadbayes.report.fit_report import write_report

    rng = np.random.default_rng(5)
    v = rng.uniform(0.85, 1.05, 300)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", FitWarning)
        exp = fit_exp(
            {"v": v, "p": v**1.3 + rng.normal(0, 0.01, v.size)},
            sampler=SamplerSettings(draws=800, burn=200, chains=2),
            spec=DataSpec(f_col="f", p0=1.0, q0=1.0),
        )
        im = fit_im(
            simulate("krause_3hp", noise=0.02, seed=1, t_end_s=1.0),
            sampler=SamplerSettings(draws=800, burn=200, chains=2),
        )
    for name, post in (("exp", exp), ("im", im)):
        nc = post.to_netcdf(tmp_path / f"{name}.nc")
        html = write_report(nc, tmp_path / f"{name}.html").read_text()
        assert html.count("<figure>") >= 3, name
        if name == "im":
            assert "ac" in html and "third-order induction motor" in html
            assert "Load curves" not in html  # no P(V) for the motor's states
        else:
            assert "Load curves" in html and "exponent of P" in html


def test_report_of_a_parquet_that_is_not_a_fleet_table_exits_2_in_one_line(tmp_path):
    """The fleet's input given for its result, and a fleet table missing a column."""
    assert cli("example", "fleet", "--out", "meters", cwd=tmp_path).returncode == 0
    res = cli("report", "meters/part-00000.parquet", "--out", "r.html", cwd=tmp_path)
    assert res.returncode == 2, res.stderr
    err = [line for line in res.stderr.splitlines() if "error" in line]
    assert err == [
        "loadbayes: error: meters/part-00000.parquet: column 'level': not a loadbayes fleet "
        "table: no such column (it has bus_id, customer_class, v, p, q); write one with "
        "loadbayes fit zip DATA --by BUS --out fleet.parquet"
    ]
    assert "Traceback" not in res.stderr and not (tmp_path / "r.html").exists()
    import pandas as pd

    table = pd.DataFrame({"level": ["bus"], "bus": ["b1"], "class": ["c"], "parameter": ["a1"],
                          "mean": [0.3], "sd": [0.1], "hdi_low": [0.1], "hdi_high": [0.5],
                          "r_hat": [1.0], "n": [100], "warnings": [""]})  # fmt: skip
    table.to_parquet(tmp_path / "f.parquet")
    res = cli("report", "f.parquet", "--out", "r.html", "--quiet", cwd=tmp_path)
    assert res.returncode == 2
    assert res.stderr.startswith("loadbayes: error: f.parquet: column 'ess_bulk': not a loadbayes")
    assert len(res.stderr.strip().splitlines()) == 1, res.stderr
    table.assign(ess_bulk=[900.0]).to_parquet(tmp_path / "ok.parquet")
    res = cli("report", "ok.parquet", "--out", "r.html", "--quiet", cwd=tmp_path)
    assert res.returncode == 0, res.stderr
    res = cli("report", "ok.parquet", "--out", "r.html", "--coords", "meters/part-00001.parquet",
              "--quiet", cwd=tmp_path)  # fmt: skip
    assert res.returncode == 2 and "exists; use --force" in res.stderr
    res = cli("report", "ok.parquet", "--out", "r2.html", "--coords", "meters/part-00001.parquet",
              "--quiet", cwd=tmp_path)  # fmt: skip
    assert res.returncode == 2
    assert res.stderr.strip() == (
        "loadbayes: error: meters/part-00001.parquet: column 'x': no coordinates: expected "
        "columns x and y, or lat and lon"
    )
