"""Short events (0.2 s up to 1 s, as a fault recorder keeps them): accepted when they start
in steady state and the voltage moves; the identifiability text says what they can tell.

The events are written here: a flat voltage, a 15% step down for three cycles and back,
sampled at 200/s (four phasors a 50 Hz cycle, as the shared DFR record's rows).
"""

from __future__ import annotations

import numpy as np
import pytest

from loadbayes.fit.composite.identifiability import identifiability, short_window
from loadbayes.io.errors import DataError
from loadbayes.measurements.events import MIN_SHORT_SPAN_S, MIN_SPAN_S, events_from_arrays
from loadbayes.models.composite_prior import CompositePrior

NAMES = {k: k for k in ("t", "v", "p", "q", "f", "angle", "event")}


def _cols(span_s, *, fault_s=0.1, rate=200.0):
    t = np.arange(0.0, span_s + 1e-9, 1 / rate)
    v = np.where((t >= fault_s) & (t < fault_s + 0.06), 0.85, 1.0)
    return {"t": t, "v": v, "p": 0.9 * v**2, "q": 0.2 * v**2}


def _read(cols):
    return events_from_arrays(cols, np.arange(1, cols["t"].size + 1), path="ev.csv",
                              names=NAMES, f_hz=50.0)  # fmt: skip


def test_a_short_window_that_starts_steady_and_moves_is_accepted():
    (ev,) = _read(_cols(0.4))
    assert ev.n == 81 and ev.t[-1] == pytest.approx(0.4)
    (ev,) = _read(_cols(MIN_SHORT_SPAN_S, fault_s=0.05))
    assert ev.t[-1] == pytest.approx(MIN_SHORT_SPAN_S)


def test_shorter_than_the_minimum_is_refused_with_the_row():
    with pytest.raises(DataError, match=r"lasts 0\.15 s, shorter than the motor's time") as e:
        _read(_cols(0.15, fault_s=0.05))
    assert e.value.column == "t" and e.value.row == 31


def test_a_short_window_cut_inside_the_fault_is_refused():
    # Starts 10 ms before the voltage recovers: no steady state to start the motor from.
    cols = _cols(0.5, fault_s=0.0)
    cols = {k: x[10:] for k, x in cols.items()}
    with pytest.raises(DataError, match="must start in steady state") as e:
        _read(cols)
    assert e.value.column == "v" and e.value.row == 3
    # The same cut, one second long, is taken as before (the long-event rule is unchanged).
    long = _cols(1.2, fault_s=0.0)
    (ev,) = _read({k: x[10:] for k, x in long.items()})
    assert ev.t[-1] - ev.t[0] >= MIN_SPAN_S


def test_a_short_window_whose_voltage_does_not_move_is_refused():
    cols = _cols(0.4, fault_s=1.0)
    with pytest.raises(DataError, match="never changes"):
        _read(cols)


def test_the_identifiability_text_of_a_short_window():
    (ev,) = _read(_cols(0.4))
    prior = CompositePrior.default([ev])
    rng = np.random.default_rng(0)
    theta = prior.theta_mean + 0.05 * rng.standard_normal((2, 50, 6))
    theta[..., 3] = np.log(0.06)  # T' = 60 ms, well under the 0.4 s window
    ident = identifiability(theta, np.full((2, 50), 0.4), prior, 1, span_s=0.4)
    text = ident["short_window"]
    assert text in ident["summary"]
    assert "f_m" in text and "X'" in text and "its decay is seen" in text and "H" in text
    theta[..., 3] = np.log(0.3)  # T' = 0.3 s: not seen settling in 0.4 s
    assert "perhaps not determined" in short_window(0.4, theta)
    # A long event says nothing of the kind.
    assert short_window(MIN_SPAN_S, theta) is None
    assert identifiability(theta, np.full((2, 50), 0.4), prior, 1)["short_window"] is None


def test_times_in_milliseconds_are_refused_in_words():
    # 60 samples/s written in ms: read as seconds, 16.7 s apart and 2,000 s long.
    cols = _cols(2.0, fault_s=0.5, rate=60.0)
    cols["t"] = cols["t"] * 1000
    with pytest.raises(DataError, match=r"samples 16\.67 s apart .*milliseconds") as e:
        _read(cols)
    assert e.value.column == "t" and e.value.path == "ev.csv"
    # 1 kHz in ms: 1 "s" apart and 2,000 "s" long.
    cols = _cols(2.0, fault_s=0.5, rate=1000.0)
    cols["t"] = cols["t"] * 1000
    with pytest.raises(DataError, match="milliseconds"):
        _read(cols)
    # A long record at a recorder's rate: cut it into events first.
    cols = _cols(700.0, fault_s=300.0, rate=4.0)
    with pytest.raises(DataError, match=r"lasts 700 s.*loadbayes events") as e:
        _read(cols)
    assert e.value.row == cols["t"].size


def test_the_file_is_named_once():
    cols = _cols(0.4)
    few = {k: v[:5] for k, v in cols.items()}
    with pytest.raises(DataError) as e:
        _read(few)
    assert str(e.value) == "ev.csv: column 't', row 5: only 5 samples; an event needs at least 20"
    flat = dict(cols, v=np.ones_like(cols["v"]))
    with pytest.raises(DataError) as e:
        _read(flat)
    assert str(e.value).count("ev.csv") == 1


def test_an_event_whose_power_is_zero_is_refused_even_with_accept_units():
    from loadbayes.measurements.record import check_units

    cols = _cols(2.0, fault_s=0.5)
    (ev,) = _read(dict(cols, p=np.zeros_like(cols["p"])))
    for accept in (False, True):
        with pytest.raises(DataError, match="P is 0 in all 401 rows") as e:
            check_units([ev], accept_units=accept, columns={"p": "P_MW"})
        assert e.value.column == "P_MW" and e.value.path == "ev.csv"
    (ev,) = _read(cols)
    assert check_units([ev]) == []


def _event_frame(t0=0.0):
    import pandas as pd

    cols = _cols(2.0, fault_s=0.5, rate=60.0)
    return pd.DataFrame({"t_s": cols["t"] + t0, "v": cols["v"], "p": cols["p"], "q": cols["q"]})


def test_event_ids_as_text_and_times_as_timestamps_are_read(tmp_path):
    import pandas as pd

    from loadbayes.measurements.events import read_events

    # Two events in one file, named in words (they used to be refused as non-numeric).
    deeper = _event_frame().assign(v=lambda d: np.where(d.v < 1, 0.8, 1.0))
    both = pd.concat([_event_frame().assign(event="sag A"), deeper.assign(event="B")])
    both.to_csv(tmp_path / "two.csv", index=False)
    a, b = read_events([str(tmp_path / "two.csv")], f_hz=50.0)
    assert (a.name, b.name) == (
        f"{tmp_path / 'two.csv'}[event=sag A]",
        f"{tmp_path / 'two.csv'}[event=B]",
    )
    assert a.n == b.n == 121
    # Times as ISO timestamps: seconds from the first.
    df = _event_frame()
    df["t_s"] = (pd.Timestamp("2026-01-01 10:00") + pd.to_timedelta(df.t_s, unit="s")).astype(str)
    df.to_csv(tmp_path / "stamps.csv", index=False)
    (ev,) = read_events([str(tmp_path / "stamps.csv")], f_hz=50.0)
    np.testing.assert_allclose(ev.t, _event_frame().t_s.to_numpy(), atol=1e-6)
    # With a comma before the fraction of a second (ISO 8601 allows it), ';' between.
    df.assign(t_s=df["t_s"].str.replace(".", ",", regex=False)).to_csv(
        tmp_path / "comma.csv", index=False, sep=";"
    )
    text = (tmp_path / "comma.csv").read_text()
    assert "10:00:00,016666" in text and "0,9" not in text.splitlines()[1]
    (ev,) = read_events([str(tmp_path / "comma.csv")], f_hz=50.0)
    np.testing.assert_allclose(ev.t, _event_frame().t_s.to_numpy(), atol=1e-6)
    # The same as a Parquet timestamp column.
    df.assign(t_s=pd.to_datetime(df["t_s"])).to_parquet(tmp_path / "stamps.parquet")
    (ev,) = read_events([str(tmp_path / "stamps.parquet")], f_hz=50.0)
    np.testing.assert_allclose(ev.t, _event_frame().t_s.to_numpy(), atol=1e-6)
    # A stray word among numbers is named by its row.
    df = _event_frame().astype({"t_s": object})
    df.loc[7, "t_s"] = "abc"
    df.to_csv(tmp_path / "bad.csv", index=False)
    with pytest.raises(DataError, match=r"bad.csv: column 't_s', row 8: 'abc' is neither"):
        read_events([str(tmp_path / "bad.csv")], f_hz=50.0)


def test_one_recording_given_twice_is_refused(tmp_path):
    from loadbayes.measurements.events import read_events

    df = _event_frame()
    df.to_csv(tmp_path / "a.csv", index=False)
    (tmp_path / "copy.csv").write_bytes(b"\xef\xbb\xbf" + (tmp_path / "a.csv").read_bytes())
    for second in ("a.csv", "copy.csv"):
        said = "this recording is given twice" if second == "a.csv" else "the same recording as"
        with pytest.raises(DataError, match=said) as e:
            read_events([str(tmp_path / "a.csv"), str(tmp_path / second)], f_hz=50.0)
        assert e.value.path == str(tmp_path / second)
    # Two events of one load, the second a different sag: both read.
    other = df.assign(v=np.where(df.v < 1, 0.8, 1.0))
    other.to_csv(tmp_path / "b.csv", index=False)
    assert len(read_events([str(tmp_path / "a.csv"), str(tmp_path / "b.csv")], f_hz=50.0)) == 2
