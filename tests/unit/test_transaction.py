"""Several outputs as one (issue 14): all or none, and never a temporary file left."""

from __future__ import annotations

import pytest

from loadbayes.io.errors import DataError
from loadbayes.io.transaction import OutputSet


def _names(folder):
    return sorted(p.name for p in folder.iterdir())


def test_commit_renames_all_together(tmp_path):
    targets = {"--json": tmp_path / "a.json", "--plot": tmp_path / "a.png"}
    with OutputSet(targets) as out:
        out.temp("--json").write_text("{}")
        out.temp("--plot").write_bytes(b"png")
        assert out.temp("--plot").suffix == ".png"  # writers pick the format from it
        assert not (tmp_path / "a.json").exists()
        out.commit()
    assert _names(tmp_path) == ["a.json", "a.png"]


@pytest.mark.parametrize("exc", [KeyboardInterrupt, RuntimeError])
def test_an_interruption_leaves_nothing(tmp_path, exc):
    (tmp_path / "a.json").write_text("old")
    targets = {"--json": tmp_path / "a.json", "--netcdf": tmp_path / "a.nc"}
    with pytest.raises(exc), OutputSet(targets, force=True) as out:
        out.temp("--json").write_text("new")
        out.temp("--netcdf")
        raise exc()
    assert _names(tmp_path) == ["a.json"] and (tmp_path / "a.json").read_text() == "old"


def test_refused_before_any_work(tmp_path):
    (tmp_path / "a.json").write_text("old")
    with pytest.raises(DataError, match="--json: exists"):
        OutputSet({"--json": tmp_path / "a.json"})
    with pytest.raises(DataError, match="does not exist"):
        OutputSet({"--json": tmp_path / "no" / "a.json"})


def test_a_target_that_appears_meanwhile_is_not_overwritten(tmp_path):
    with OutputSet({"--json": tmp_path / "a.json"}) as out:
        out.temp("--json").write_text("new")
        (tmp_path / "a.json").write_text("someone else's")
        with pytest.raises(DataError, match="exists"):
            out.commit()
    assert _names(tmp_path) == ["a.json"]
    assert (tmp_path / "a.json").read_text() == "someone else's"
