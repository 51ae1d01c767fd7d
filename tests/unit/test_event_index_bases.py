"""The bases of per-unit event files, read from the events.csv that `events` writes."""

from loadbayes.measurements.events import index_bases


def _index(folder, rows):
    lines = ["index,file,v_base_kv,s_base_mva"] + [",".join(map(str, r)) for r in rows]
    (folder / "events.csv").write_text("\n".join(lines) + "\n")


def test_bases_found_by_file_name(tmp_path):
    _index(tmp_path, [(1, "event_001.csv", 229.703, 11.3121), (2, "event_002.csv", 229.703,
                                                                 11.3121)])  # fmt: skip
    one = str(tmp_path / "event_001.csv")
    assert index_bases([one]) == (229.703, 11.3121)
    assert index_bases([one, str(tmp_path / "event_002.csv")]) == (229.703, 11.3121)


def test_none_when_absent_missing_or_disagreeing(tmp_path):
    assert index_bases([str(tmp_path / "event_001.csv")]) is None  # no index
    _index(tmp_path, [(1, "event_001.csv", 229.7, 11.3), (2, "event_002.csv", 110.0, 11.3),
                      (3, "event_003.csv", "", 11.3)])  # fmt: skip
    assert index_bases([str(tmp_path / "event_009.csv")]) is None  # no row
    assert index_bases([str(tmp_path / "event_003.csv")]) is None  # a base missing
    both = [str(tmp_path / "event_001.csv"), str(tmp_path / "event_002.csv")]
    assert index_bases(both) is None  # two records' bases: not one load's
