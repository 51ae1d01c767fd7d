"""`loadbayes fit zip` end to end, as a user runs it.

The commands run in-process (``cli_here``): their subject is files, exit codes and
one-line errors, not the process; ``python -m loadbayes.cli`` runs as a process.
"""

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from cli_here import cli_here

pytestmark = pytest.mark.integration

FAST = ["--draws", "1500", "--burn", "300", "--chains", "2", "--quiet"]


def run(*args, cwd):
    return cli_here(*args, cwd=cwd)


def _write(path: Path, n=300, seed=0, **overrides):
    rng = np.random.default_rng(seed)
    v = rng.uniform(0.85, 1.08, n)
    df = pd.DataFrame(
        {
            "v": v,
            "p": 0.3 * v**2 + 0.2 * v + 0.5 + rng.normal(0, 0.01, n),
            "q": 0.6 * v**2 + 0.1 * v + 0.3 + rng.normal(0, 0.01, n),
        }
    )
    for k, val in overrides.items():
        df[k] = val
    if path.suffix == ".parquet":
        df.to_parquet(path)
    else:
        df.to_csv(path, index=False)
    return df


def _one_line_error(res, *needles):
    assert res.returncode == 2, res.stderr
    assert "Traceback" not in res.stderr
    lines = [ln for ln in res.stderr.splitlines() if ln.strip()]
    err = [ln for ln in lines if "error" in ln]
    assert len(err) == 1, res.stderr
    for needle in needles:
        assert needle in err[0], err[0]
    return err[0]


def test_fit_writes_json_netcdf_plot(tmp_path):
    _write(tmp_path / "bus.csv")
    res = run(
        "fit",
        "zip",
        "bus.csv",
        *FAST,
        "--json",
        "o.json",
        "--netcdf",
        "o.nc",
        "--plot",
        "o.png",
        cwd=tmp_path,
    )
    assert res.returncode == 0, res.stderr
    d = json.loads((tmp_path / "o.json").read_text())
    assert d["model"] == "zip" and d["n"] == 300 and d["scheme"] == "blocked"
    # P0, Q0 not given: estimated (issue 14), so they are parameters too
    assert set(d["parameters"]) == {"a1", "a2", "a3", "a4", "a5", "a6", "tau_p", "tau_q"} | {
        "p0",
        "q0",
    }
    assert d["settings"]["seed"] == 0 and d["loadbayes_version"]
    a = {k: v["mean"] for k, v in d["parameters"].items()}
    assert a["a1"] + a["a2"] + a["a3"] == pytest.approx(1.0)
    assert (tmp_path / "o.nc").stat().st_size > 0 and (tmp_path / "o.png").stat().st_size > 0
    # same seed, same numbers
    res2 = run("fit", "zip", "bus.csv", *FAST, "--json", "o2.json", cwd=tmp_path)
    assert res2.returncode == 0, res2.stderr
    d2 = json.loads((tmp_path / "o2.json").read_text())
    assert d2["parameters"] == d["parameters"]


def test_existing_output_not_overwritten_without_force(tmp_path):
    _write(tmp_path / "bus.csv")
    (tmp_path / "o.json").write_text("keep me")
    res = run("fit", "zip", "bus.csv", *FAST, "--json", "o.json", cwd=tmp_path)
    _one_line_error(res, "o.json", "--force")
    assert (tmp_path / "o.json").read_text() == "keep me"
    res = run("fit", "zip", "bus.csv", *FAST, "--json", "o.json", "--force", cwd=tmp_path)
    assert res.returncode == 0 and json.loads((tmp_path / "o.json").read_text())["model"] == "zip"


def test_p_only_auto_nominal_and_parquet(tmp_path):
    df = _write(tmp_path / "bus.parquet")
    res = run(
        "fit",
        "zip",
        "bus.parquet",
        *FAST,
        "--q-col",
        "none",
        "--p0",
        "auto",
        "--json",
        "o.json",
        cwd=tmp_path,
    )
    assert res.returncode == 0, res.stderr
    d = json.loads((tmp_path / "o.json").read_text())
    assert set(d["parameters"]) == {"a1", "a2", "a3", "tau_p", "p0"}
    assert d["parameters"]["p0"]["mean"] == pytest.approx(1.0, abs=0.01)
    assert len(df) == d["n"]


def test_units_with_bases(tmp_path):
    rng = np.random.default_rng(4)
    v = rng.uniform(0.9, 1.1, 400)
    p = 0.3 * v**2 + 0.2 * v + 0.5 + rng.normal(0, 0.005, 400)
    pd.DataFrame({"vkv": v * 12.66, "pmw": p * 10}).to_csv(tmp_path / "kv.csv", index=False)
    res = run(
        "fit",
        "zip",
        "kv.csv",
        *FAST,
        "--v-col",
        "vkv",
        "--p-col",
        "pmw",
        "--v-base",
        "12.66",
        "--s-base",
        "10",
        "--json",
        "o.json",
        cwd=tmp_path,
    )
    assert res.returncode == 0, res.stderr
    a = json.loads((tmp_path / "o.json").read_text())["parameters"]
    assert a["a3"]["hdi_low"] < 0.5 < a["a3"]["hdi_high"]


@pytest.mark.parametrize(
    ("content", "needles"),
    [
        ("v,x\n1,2\n", ["bad.csv", "'p'"]),
        ("v,p\n1.0,0.9\n0.9,abc\n1.1,1.0\n", ["bad.csv", "'p'", "row 2"]),
        ("v,p\n1.0,0.9\n0.9,nan\n1.1,1.0\n1.05,1\n", ["bad.csv", "'p'", "row 2"]),
        ("v,p\n1.0,0.9\n0.9,inf\n1.1,1.0\n1.05,1\n", ["bad.csv", "row 2"]),
        ("v,p\n1.0,0.9\n-0.9,0.8\n1.1,1.0\n1.05,1\n", ["bad.csv", "'v'", "row 2"]),
        ("v,p\n1.0,0.9\n0.9,0.8\n", ["bad.csv", "fewer"]),
        ("v,p\n1.0,0.9\n1.0,0.8\n1.0,1.0\n1.0,1.1\n", ["bad.csv", "no spread"]),
        ("", ["bad.csv", "empty"]),
        ("v,p\n", ["bad.csv"]),
        ("v,v,p\n1,1,1\n", ["bad.csv", "'v'"]),
    ],
    ids=[
        "missing-col",
        "non-numeric",
        "nan",
        "inf",
        "negative-v",
        "too-few",
        "no-spread",
        "empty",
        "header-only",
        "duplicate-col",
    ],
)
def test_bad_data_is_one_line_exit_2(tmp_path, content, needles):
    (tmp_path / "bad.csv").write_text(content)
    res = run("fit", "zip", "bad.csv", *FAST, "--json", "o.json", cwd=tmp_path)
    _one_line_error(res, *needles)
    assert not (tmp_path / "o.json").exists()


def test_drop_invalid_reports_count(tmp_path):
    (tmp_path / "d.csv").write_text(
        "v,p\n1.0,0.9\n0.9,nan\n1.1,1.0\n0.95,0.93\n-1,1\n1.05,1.02\n0.92,0.91\n"
    )
    res = run("fit", "zip", "d.csv", *FAST, "--json", "o.json", "--drop-invalid", cwd=tmp_path)
    assert res.returncode == 0, res.stderr
    d = json.loads((tmp_path / "o.json").read_text())
    assert d["n"] == 5 and any("2 rows" in w for w in d["warnings"])


def test_bad_usage_exit_2(tmp_path):
    _write(tmp_path / "bus.csv")
    for args in (
        ["--p0", "zero"],
        ["--scheme", "exact"],
        ["--burn", "5000", "--draws", "100"],
        ["--prior", "a3=1,1"],
        ["--prior", "a1=1"],
    ):
        res = run("fit", "zip", "bus.csv", "--json", "o.json", "--quiet", *args, cwd=tmp_path)
        assert res.returncode == 2, (args, res.stderr)
        assert "Traceback" not in res.stderr
    res = run("fit", "zip", "missing.csv", "--json", "o.json", cwd=tmp_path)
    _one_line_error(res, "missing.csv")
    res = run("fit", "zip", "bus.csv", "--json", "bus.csv", cwd=tmp_path)
    _one_line_error(res, "bus.csv")


def test_exact_scheme_and_informative_prior(tmp_path):
    _write(tmp_path / "bus.csv", n=50)
    res = run(
        "fit",
        "zip",
        "bus.csv",
        *FAST,
        "--scheme",
        "exact",
        "--conjugate",
        "--json",
        "e.json",
        cwd=tmp_path,
    )
    assert res.returncode == 0, res.stderr
    res = run(
        "fit", "zip", "bus.csv", *FAST, "--prior", "a1=0.3,0.001", "--p0", "1", "--q0", "1",
        "--json", "p.json", cwd=tmp_path,
    )  # fmt: skip
    d = json.loads((tmp_path / "p.json").read_text())
    assert d["parameters"]["a1"]["mean"] == pytest.approx(0.3, abs=0.005)


def test_python_m_loadbayes_cli_runs_the_command_too(tmp_path):
    """`python -m loadbayes.cli fit zip ...` imported the module, ran nothing and exited 0."""
    res = subprocess.run([sys.executable, "-m", "loadbayes.cli", "fit", "zip", "missing.csv"],
                         cwd=tmp_path, capture_output=True, text=True, timeout=120)  # fmt: skip
    assert res.returncode == 2 and "missing.csv" in res.stderr
