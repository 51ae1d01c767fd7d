"""Events carry the record's frequency to `fit composite`, from the CLI and from Python.

`loadbayes example comtrade` writes a 50 Hz record; `read comtrade`, then `events`,
write its nominal frequency into events.csv beside the bases (issue 40).
"""

from __future__ import annotations

import json

import pandas as pd
import pytest
from click.testing import CliRunner

from loadbayes.cli import main


def run(*args):
    return CliRunner().invoke(main, [str(a) for a in args], catch_exceptions=False)


@pytest.fixture(scope="module")
def events50(tmp_path_factory):
    d = tmp_path_factory.mktemp("f50")
    for args in (
        ("example", "comtrade", "--out", d / "rec"),
        ("read", "comtrade", d / "rec" / "event.cfg", "--out", d / "r.csv", "--quiet"),
        ("events", d / "r.csv", "--out", d / "ev", "--quiet"),
    ):
        res = run(*args)
        assert res.exit_code == 0, res.output
    return d / "ev"


def test_events_csv_carries_the_nominal_frequency(events50):
    index = pd.read_csv(events50 / "events.csv")
    assert index["f_nominal_hz"].tolist() == [50, 50]


@pytest.mark.usefixtures("no_cost_probe")
def test_fit_composite_takes_the_frequency_from_events_csv(events50, tmp_path):
    # The cost probe ran 926 throw-away iterations for a run of 80 on this event.
    res = run("fit", "composite", events50 / "event_001.csv", "--draws", "80", "--burn", "30",
              "--chains", "1", "--fixed-draws", "--json", tmp_path / "f.json")  # fmt: skip
    assert res.exit_code == 0, res.output
    assert "loadbayes: note: frequency from events.csv: 50 Hz" in res.output
    # The reading is the record's, and the run says so (it printed nothing on it before).
    assert "samples read as one-cycle window means (0.02 s): " in res.output
    assert "events.csv says they are the record's phasors" in res.output
    settings = json.dumps(json.loads((tmp_path / "f.json").read_text()))
    assert '"f_hz": 50.0' in settings


def test_an_f_hz_that_disagrees_with_events_csv_is_refused(events50, tmp_path):
    res = run("fit", "composite", events50 / "event_001.csv", "--f-hz", "60",
              "--json", tmp_path / "g.json")  # fmt: skip
    assert res.exit_code == 2
    lines = res.output.strip().splitlines()
    assert len(lines) == 1 and "--f-hz 60" in lines[0] and "50 Hz" in lines[0], res.output
    assert "events.csv" in lines[0]
    assert not (tmp_path / "g.json").exists()


def test_python_refuses_a_default_60_hz_model_for_50_hz_events(events50):
    import loadbayes
    from loadbayes import CompositeModel, SamplerSettings
    from loadbayes.fit.composite.api import _check_index_frequency
    from loadbayes.io.errors import OptionError

    files = [str(events50 / "event_001.csv")]
    with pytest.raises(OptionError) as err:
        loadbayes.fit_composite(CompositeModel(), files, sampler=SamplerSettings(draws=80, burn=30))
    message = str(err.value)
    assert "\n" not in message and "CompositeModel(f_hz=50" in message
    # The model built as said passes (and the model is never changed silently).
    _check_index_frequency(CompositeModel(f_hz=50), files)
    assert CompositeModel().f_hz == 60


@pytest.mark.usefixtures("no_cost_probe")
def test_a_model_of_parts_says_it_reads_points_from_events_csv(events50, tmp_path):
    # A model of parts reads point samples (window means are zip+motor's): the note said
    # "one-cycle window means" of its events until 2026-12-02, the reading it did not do.
    res = run("fit", "composite", events50 / "event_001.csv", "--model", "slm",
              "--draws", "80", "--burn", "30", "--chains", "1", "--fixed-draws",
              "--json", tmp_path / "s.json")  # fmt: skip
    assert res.exit_code == 0, res.output
    assert "one-cycle window means (0.02 s)" not in res.output
    assert "loadbayes: note: point samples (" in res.output
    assert "a model of parts reads each sample as the load's P and Q at its stamp" in res.output
    options = json.loads((tmp_path / "s.json").read_text())["settings"]["model_options"]
    assert options["window_s"] == 0.0
