"""``loadbayes archive pool`` through click: outputs, --force, one-line errors (exit 2).

The command is invoked on its own (the lead attaches it to the ``archive`` group); the
catalog's reader is replaced by the generator's frame (tests/pool_generator.py), so
these tests do not depend on the catalog's format.
"""

import json
import sys
from pathlib import Path

import pytest
from click.testing import CliRunner

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from loadbayes.commands import archive_pool  # noqa: E402
from pool_generator import archive  # noqa: E402

pytestmark = pytest.mark.integration


@pytest.fixture
def catalog(tmp_path, monkeypatch):
    frame, _ = archive(2, events=10)
    path = tmp_path / "archive.db"
    path.write_bytes(b"stand-in")
    monkeypatch.setattr(archive_pool, "read_catalog", lambda p: frame)
    return path, frame


def _run(*args):
    return CliRunner().invoke(archive_pool.pool_cmd, [str(a) for a in args])


def test_pool_writes_the_json_and_the_figure(catalog, tmp_path):
    path, _ = catalog
    out, fig = tmp_path / "pool.json", tmp_path / "pool.png"
    r = _run("--catalog", path, "--draws", 100, "--chains", 2, "--out", out, "--plot", fig)
    assert r.exit_code == 0, r.output
    d = json.loads(out.read_text())
    assert d["left_out"] == {
        "fit failed": 4,
        "share outside [0, 1]": 0,
        "chains disagree on the share (R-hat >= 1.05)": 3,
        "too few effective draws of the share (ESS < 100)": 0,
        "no R-hat recorded": 0,
    }
    assert d["events"] == {"rows": 67, "pooled": 60}
    assert len(d["parts"]["f_m"]["monthly"]) == 12 * 7
    assert fig.read_bytes()[:4] == b"\x89PNG"
    assert (
        "60 of 67 fitted event shares pooled; left out: fit failed 4, chains disagree "
        "on the share (R-hat >= 1.05) 3"
    ) in r.output
    assert "alike within 0.1 (groups)" in r.output
    r = _run("--catalog", path, "--draws", 60, "--chains", 2, "--by-bay", "--out", "-")
    assert r.exit_code == 0, r.output
    assert "population / T1" in r.output
    assert json.loads(r.stdout)["settings"]["by_bay"] is True


def test_nothing_is_overwritten_without_force(catalog, tmp_path):
    path, _ = catalog
    out = tmp_path / "pool.json"
    out.write_text("kept")
    r = _run("--catalog", path, "--draws", 60, "--out", out)
    assert r.exit_code == 2
    assert r.output.strip().splitlines() == [
        f"loadbayes: error: {out}: exists; use --force to overwrite"
    ]
    assert out.read_text() == "kept"
    r = _run("--catalog", path, "--draws", 60, "--chains", 2, "--out", out, "--force", "--quiet")
    assert r.exit_code == 0, r.output
    assert json.loads(out.read_text())["settings"]["draws"] == 60


def test_bad_input_is_one_line_with_exit_2(catalog, tmp_path, monkeypatch):
    path, frame = catalog
    temps = tmp_path / "temps.csv"
    temps.write_text("station,time,temp\nA,2025-01-01,3.0\n")
    r = _run("--catalog", path, "--temperature", temps, "--draws", 60)
    assert r.exit_code == 2
    errors = [ln for ln in r.output.splitlines() if ln.startswith("loadbayes: error:")]
    assert len(errors) == 1 and f"{temps}: column 'temperature'" in errors[0], r.output
    temps.write_text("station,time,temperature\nA,2025-01-01,3.0\nA,2025-01-02,warm\n")
    r = _run("--catalog", path, "--temperature", temps, "--draws", 60)
    assert r.exit_code == 2
    assert r.output.strip().splitlines()[-1] == (
        f"loadbayes: error: {temps}: column 'temperature', row 2: 'warm' is not a temperature"
    )
    broken = frame.copy()
    broken.loc[5, "sd"] = 0.0
    monkeypatch.setattr(archive_pool, "read_catalog", lambda p: broken)
    r = _run("--catalog", path, "--draws", 60)
    assert r.exit_code == 2
    assert (
        r.output.strip()
        .splitlines()[-1]
        .startswith(f"loadbayes: error: {path}: column 'sd', row 6:")
    )


def test_a_file_that_is_no_catalog(tmp_path):
    pytest.importorskip("loadbayes.archive.catalog")
    path = tmp_path / "archive.db"
    path.write_bytes(b"not a database at all\n" * 100)
    r = _run("--catalog", path, "--draws", 60)
    assert r.exit_code == 2
    assert len(r.output.strip().splitlines()) == 1, r.output
