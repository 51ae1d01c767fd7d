"""Issue 23, bad input to ``export``: another fit's file, a cut or relabelled JSON, --out
over the input. Each: exit 2, one line naming the file, nothing written.

The files are written here by hand (or from a hand-built posterior), as a user's tool might.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from loadbayes.cli import main

pytestmark = pytest.mark.integration

COMPOSITE = {
    "p0": 0.9, "q0": 0.3, "v0": 0.97, "a1": 0.35, "a2": 0.25, "a3": 0.4, "a4": 0.55,
    "a5": 0.3, "a6": 0.15, "f_m": 0.45, "rs": 0.031, "xs": 0.10, "xm": 3.2, "rr": 0.018,
    "xr": 0.12, "h_s": 0.7, "a": 1.0, "b": 0.0, "c": 0.0, "t0": 0.6, "mva_m": 0.4,
}  # fmt: skip
ZIP = {"a1": 0.3, "a2": 0.2, "a3": 0.5, "a4": 0.5, "a5": 0.2, "a6": 0.3, "p0": 0.9, "q0": 0.3}
IM = {"rs": 0.03, "xs": 0.1, "xm": 3.0, "rr": 0.02, "xr": 0.1, "h_s": 0.6}


def _json(path: Path, model: str, values: dict, drop=()) -> Path:
    params = {k: {"mean": v, "sd": 0.01} for k, v in values.items() if k not in drop}
    path.write_text(json.dumps({"model": model, "parameters": params,
                                "settings": {"s_base_mva": 10.0, "v_base_kv": 11.0}}))  # fmt: skip
    return path


CASES = {
    "im-fit": lambda d: _json(d / "in.json", "im", IM),
    "composite-relabelled-zip": lambda d: _json(d / "in.json", "zip", COMPOSITE),
    "zip-relabelled-composite": lambda d: _json(d / "in.json", "composite", ZIP),
    "composite-without-t0": lambda d: _json(d / "in.json", "composite", COMPOSITE, ["t0"]),
    "zip-without-a2": lambda d: _json(d / "in.json", "zip", ZIP, ["a2"]),
    # The real record's fit before --shares bounded: f_m's mean 1.42 (the static part a
    # generator); not a load a simulator holds, said in words.
    "motor-share-above-one": lambda d: _json(
        d / "in.json", "composite", {**COMPOSITE, "f_m": 1.42}
    ),
    "track-csv": lambda d: (d / "in.json").write_text("t_s,a1,a2\n0,0.3,0.2\n") and d / "in.json",
}
NEEDLES = {
    "im-fit": "model 'im' cannot be exported",
    "composite-relabelled-zip": "'model' says zip but the parameters include f_m",
    "zip-relabelled-composite": "needs parameters.f_m",
    "composite-without-t0": "needs parameters.t0: missing",
    "zip-without-a2": "needs parameters.a2: missing",
    "track-csv": "not a loadbayes posterior JSON",
    "motor-share-above-one": "f_m is 1.42: a load's motor takes a share in (0, 1]",
}


def _run(tmp_path, monkeypatch, *args):
    monkeypatch.chdir(tmp_path)
    return CliRunner().invoke(main, ["export", *map(str, args)])


def _one_line(r, *needles):
    assert r.exit_code == 2, (r.exit_code, r.output)
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("loadbayes: error: "), r.stderr
    assert "Traceback" not in r.output
    for n in needles:
        assert n in lines[0], (n, lines[0])


@pytest.mark.parametrize("fmt", ["psse", "pandapower"])
@pytest.mark.parametrize("case", list(CASES))
def test_another_fit_or_a_cut_json_is_refused(tmp_path, monkeypatch, case, fmt):
    CASES[case](tmp_path)
    before = sorted(p.name for p in tmp_path.iterdir())
    r = _run(tmp_path, monkeypatch, "in.json", "--to", fmt, "--out", "out.raw")
    _one_line(r, "in.json", NEEDLES[case])
    assert sorted(p.name for p in tmp_path.iterdir()) == before


def test_a_fleet_table_is_refused_as_a_table(tmp_path, monkeypatch):
    # A fleet's Parquet table holds per-bus summaries; it read as "not ... JSON".
    import pandas as pd

    pd.DataFrame({"level": ["bus"], "bus": ["b1"], "parameter": ["a1"], "mean": [0.3]}).to_parquet(
        tmp_path / "fleet.parquet"
    )
    r = _run(tmp_path, monkeypatch, "fleet.parquet", "--to", "pandapower", "--out", "o.json")
    _one_line(r, "fleet.parquet", "but a table", "fit zip on that bus's rows")
    assert not (tmp_path / "o.json").exists()


def test_out_over_the_input_is_refused(tmp_path, monkeypatch):
    from loadbayes.posterior import Posterior

    post = _json(tmp_path / "c.json", "composite", COMPOSITE)
    text = post.read_text()
    for fmt in ("psse", "pandapower"):
        _one_line(_run(tmp_path, monkeypatch, "c.json", "--to", fmt, "--out", "c.json"),
                  "would overwrite the posterior")  # fmt: skip
        _one_line(_run(tmp_path, monkeypatch, "c.json", "--to", fmt, "--out", "./c.json"),
                  "would overwrite the posterior")  # fmt: skip
    assert post.read_text() == text
    # A draw's name landing on the input (p.nc --draws 1 -> p_draw001.nc): refused too.
    draws = {k: np.full((1, 4), v) for k, v in COMPOSITE.items()}
    Posterior(draws, model="composite", method="x").to_netcdf(tmp_path / "p_draw001.nc")
    size = (tmp_path / "p_draw001.nc").stat().st_size
    _one_line(_run(tmp_path, monkeypatch, "p_draw001.nc", "--to", "psse", "--out", "p.nc",
                   "--draws", "1"), "would overwrite the posterior")  # fmt: skip
    assert (tmp_path / "p_draw001.nc").stat().st_size == size
    assert sorted(p.name for p in tmp_path.iterdir()) == ["c.json", "p_draw001.nc"]


@pytest.mark.parametrize("fmt", ["psse", "pandapower", "andes"])
@pytest.mark.parametrize("out", ["", "-"])
def test_an_empty_or_dash_out_is_refused(tmp_path, monkeypatch, fmt, out):
    # Red-team L5: --out - wrote files named -, -.dyr, -.dyd, -.summary.txt; --out '' said
    # "PosixPath('.') has an empty name".
    _json(tmp_path / "c.json", "composite", COMPOSITE)
    r = _run(tmp_path, monkeypatch, "c.json", "--to", fmt, "--out", out)
    _one_line(r, f"--out {out!r}", "a file name")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["c.json"]
