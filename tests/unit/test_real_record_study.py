"""The demo's real-record section: where the record is looked for, and its absence said."""

from __future__ import annotations

from loadbayes.studies import real_record


def test_the_record_is_found_above_a_folder_or_said_missing(tmp_path, monkeypatch):
    monkeypatch.delenv("LOADBAYES_REAL_RECORD", raising=False)
    real = tmp_path / "shared" / "real"
    real.mkdir(parents=True)
    (real / "xtz.cfg").write_text("x")
    deep = tmp_path / "repo" / "src"
    deep.mkdir(parents=True)
    assert real_record.find_record(deep) == real / "xtz.cfg"
    monkeypatch.setenv("LOADBAYES_REAL_RECORD", str(tmp_path / "absent.cfg"))
    assert real_record.find_record(deep) is None
    study = real_record.run(record=str(tmp_path / "absent.cfg"))
    html = real_record.html_section(study)
    assert '<section id="real-record">' in html and "was not found" in html
    assert "zhangsonggui/comtradeOfPython" in html and "Mulan" in html
    assert "not found" in real_record.text_table(study)
