"""`loadbayes track zip`, `fit exp` and `fit zip --likelihood student-t`, as a user runs them."""

import json
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from cli_here import cli_here

pytestmark = pytest.mark.integration

FAST = ["--draws", "1200", "--burn", "300", "--chains", "2", "--quiet"]
BAD_ROWS = (4, 40, 150)  # 0-based; file rows 5, 41, 151


def run(*args, cwd, stdin=None):
    """The command in-process (``cli_here``): its files, exit code and lines are the subject."""
    return cli_here(*args, cwd=cwd, input=stdin)


def _write(path: Path, n=300, seed=0, bad=True, t=True):
    rng = np.random.default_rng(seed)
    v = rng.uniform(0.85, 1.08, n)
    f = 60 + rng.normal(0, 0.2, n)
    df = pd.DataFrame(
        {
            "v": v,
            "p": 0.3 * v**2 + 0.2 * v + 0.5 + rng.normal(0, 0.01, n),
            "q": 0.6 * v**2 + 0.1 * v + 0.3 + rng.normal(0, 0.01, n),
            "f": f,
            "a1_true": 0.3,
        }
    )
    if t:
        df.insert(0, "t", np.arange(n) * 0.5)
    if bad:
        df.loc[list(BAD_ROWS), "p"] = 0.0
    if path.suffix == ".parquet":
        df.to_parquet(path)
    else:
        df.to_csv(path, index=False)
    return df


def _one_line_error(res, *needles):
    assert res.returncode == 2, res.stderr
    assert "Traceback" not in res.stderr
    err = [ln for ln in res.stderr.splitlines() if "error" in ln]
    assert len(err) == 1, res.stderr
    for needle in needles:
        assert needle in err[0], err[0]


def test_track_zip_file_and_plot(tmp_path):
    _write(tmp_path / "bus.csv", bad=False)
    res = run("track", "zip", "bus.csv", "--out", "tr.csv", "--forgetting", "0.99", "--plot",
              "tr.png", "--quiet", cwd=tmp_path)  # fmt: skip
    assert res.returncode == 0, res.stderr
    out = pd.read_csv(tmp_path / "tr.csv")
    names = [f"a{i}" for i in range(1, 7)]
    assert list(out.columns) == ["t"] + [f"{a}_{s}" for a in names for s in ("mean", "low", "high")]
    assert len(out) == 300 and out["t"].iloc[-1] == pytest.approx(149.5)
    assert np.all(out["a1_low"] <= out["a1_mean"]) and np.all(out["a1_mean"] <= out["a1_high"])
    last = out.iloc[-1]
    assert last["a3_low"] < 0.5 < last["a3_high"]
    assert last["a1_mean"] + last["a2_mean"] + last["a3_mean"] == pytest.approx(1.0)
    assert (tmp_path / "tr.png").stat().st_size > 0


def test_track_zip_stdin_window_p_only(tmp_path):
    df = _write(tmp_path / "bus.csv", bad=False, t=False)
    text = (tmp_path / "bus.csv").read_text()
    res = run("track", "zip", "-", "--out", "w.csv", "--window", "50", "--q-col", "none",
              "--quiet", cwd=tmp_path, stdin=text)  # fmt: skip
    assert res.returncode == 0, res.stderr
    out = pd.read_csv(tmp_path / "w.csv")
    assert list(out.columns[:4]) == ["t", "a1_mean", "a1_low", "a1_high"] and out.shape[1] == 10
    assert out["t"].tolist() == list(range(1, len(df) + 1))  # no t column: data row numbers
    # the same from a Parquet file, in other chunks: identical numbers
    _write(tmp_path / "bus.parquet", bad=False, t=False)
    res = run("track", "zip", "bus.parquet", "--out", "w2.csv", "--window", "50", "--q-col",
              "none", "--chunk-rows", "7", "--quiet", cwd=tmp_path)  # fmt: skip
    assert res.returncode == 0, res.stderr
    pd.testing.assert_frame_equal(out, pd.read_csv(tmp_path / "w2.csv"))


@pytest.mark.parametrize(
    ("args", "needles"),
    [
        (["--forgetting", "0.9", "--window", "5"], ["only one"]),
        (["--forgetting", "1.5"], ["--forgetting"]),
        (["--p0", "0"], ["--p0"]),  # 'auto' is accepted since issue 14
        (["--out", "bus.csv", "--force"], ["bus.csv"]),
    ],
    ids=["two-memories", "bad-forgetting", "auto-p0", "out-is-input"],
)
def test_track_bad_usage(tmp_path, args, needles):
    _write(tmp_path / "bus.csv", bad=False)
    out = [] if "--out" in args else ["--out", "tr.csv"]
    res = run("track", "zip", "bus.csv", *out, *args, cwd=tmp_path)
    assert res.returncode == 2 and "Traceback" not in res.stderr, res.stderr
    for n in needles:
        assert n in res.stderr
    assert not (tmp_path / "tr.csv").exists()


def test_track_bad_data_one_line_and_no_output(tmp_path):
    text = "v,p\n1.0,0.9\n0.95,0.92\n0.9,abc\n"
    res = run("track", "zip", "-", "--out", "tr.csv", cwd=tmp_path, stdin=text)
    _one_line_error(res, "<stdin>", "'p'", "row 3")
    assert not (tmp_path / "tr.csv").exists()
    (tmp_path / "nov.csv").write_text("x,p\n1,2\n")
    res = run("track", "zip", "nov.csv", "--out", "tr.csv", cwd=tmp_path)
    _one_line_error(res, "nov.csv", "'v'")


def test_fit_exp_json(tmp_path):
    _write(tmp_path / "bus.csv", bad=False)
    res = run("fit", "exp", "bus.csv", *FAST, "--f-col", "f", "--json", "e.json", "--plot",
              "e.png", cwd=tmp_path)  # fmt: skip
    assert res.returncode == 0, res.stderr
    d = json.loads((tmp_path / "e.json").read_text())
    assert d["model"] == "exp" and d["n"] == 300 and d["scheme"] == "metropolis-within-gibbs"
    # P0, Q0 not given: estimated (issue 14)
    assert set(d["parameters"]) == {"np", "kpf", "nq", "kqf", "tau_p", "tau_q", "p0", "q0"}
    # a ZIP load of mostly constant power has a small exponent near V = 1
    assert 0.2 < d["parameters"]["np"]["mean"] < 1.5
    assert (tmp_path / "e.png").stat().st_size > 0


def test_fit_exp_bad_data(tmp_path):
    _write(tmp_path / "bus.csv", bad=True)
    res = run("fit", "exp", "bus.csv", *FAST, "--noise", "multiplicative", "--json", "m.json",
              cwd=tmp_path)  # fmt: skip
    _one_line_error(res, "bus.csv", "'p'", f"row {BAD_ROWS[0] + 1}")
    assert not (tmp_path / "m.json").exists()
    res = run("fit", "exp", "bus.csv", *FAST, "--f-col", "freq", "--json", "m.json", cwd=tmp_path)
    _one_line_error(res, "bus.csv", "'freq'")


def test_fit_zip_student_t_lists_flagged_rows(tmp_path):
    _write(tmp_path / "bus.csv", bad=True)
    res = run("fit", "zip", "bus.csv", *FAST, "--likelihood", "student-t", "--json", "t.json",
              cwd=tmp_path)  # fmt: skip
    assert res.returncode == 0, res.stderr
    d = json.loads((tmp_path / "t.json").read_text())
    assert d["likelihood"] == "student-t" and d["method"] == "gibbs-student-t"
    rows = {i + 1 for i in BAD_ROWS}
    assert rows <= set(d["flagged"]) and rows <= set(d["flagged_by_channel"]["p"])
    assert len(d["flagged"]) <= len(rows) + 6
    assert {"nu_p", "nu_q"} <= set(d["parameters"])
    assert d["parameters"]["a3"]["hdi_low"] < 0.5 < d["parameters"]["a3"]["hdi_high"]


@pytest.mark.parametrize(
    "args",
    [["--nu", "4"], ["--likelihood", "student-t", "--nu", "-1"],
     ["--likelihood", "student-t", "--scheme", "exact", "--conjugate"]],
    ids=["nu-without-t", "negative-nu", "t-with-exact"],
)  # fmt: skip
def test_fit_zip_student_t_bad_usage(tmp_path, args):
    _write(tmp_path / "bus.csv", bad=False)
    res = run("fit", "zip", "bus.csv", *FAST, *args, "--json", "o.json", cwd=tmp_path)
    assert res.returncode == 2 and "Traceback" not in res.stderr, res.stderr
    assert not (tmp_path / "o.json").exists()
