"""The sag finder and the PMU CSV reader on records with a known answer."""

import math

import numpy as np
import pandas as pd
import pytest

from loadbayes.io.errors import DataError
from loadbayes.recordings.events import cut_events, find_sags
from loadbayes.recordings.pmu import load_map, read_pmu
from loadbayes.recordings.synth import sag_profile

# ------------------------------------------------------------------------- events
T = np.arange(0, 30, 0.02)


def test_two_sags_found_with_their_recovery():
    v = sag_profile(T, [(5.0, 0.5, 0.3), (20.0, 1.0, 0.15)], recovery_s=0.2)
    ev = find_sags(T, v, threshold=0.9, hysteresis=0.02, pre_s=1.0, post_s=2.0)
    assert len(ev) == 2
    a, b = ev
    assert a.sag_start_s == pytest.approx(5.02, abs=0.021)
    assert a.depth == pytest.approx(0.3, abs=1e-9)
    assert a.recovered and b.recovered
    # Recovery: back above 0.92 on the 0.2 s ramp out of the 0.7 sag.
    assert a.recovery_s == pytest.approx(5.5 + 0.2 * (0.22 / 0.3), abs=0.021)
    assert T[a.start] == pytest.approx(a.sag_start_s - 1.0, abs=0.021)
    assert T[a.stop - 1] == pytest.approx(a.recovery_s + 2.0, abs=0.021)
    tables = cut_events({"t_s": T, "v": v}, ev)
    assert tables[0]["t_s"][0] == 0.0
    assert len(tables[1]["v"]) == b.stop - b.start


def test_threshold_duration_and_hysteresis():
    v = sag_profile(T, [(5.0, 0.01, 0.3), (10.0, 0.5, 0.05)])
    # A one-sample dip and a 5% sag: neither is a sag at 0.9 with 40 ms minimum.
    assert find_sags(T, v, min_duration_s=0.04) == []
    assert len(find_sags(T, v, threshold=0.97, hysteresis=0.01)) == 1
    # Noise around the threshold: hysteresis keeps it one sag.
    rng = np.random.default_rng(0)
    w = np.ones_like(T)
    inside = (T > 3) & (T < 6)
    w[inside] = 0.9 + rng.uniform(-0.005, 0.005, inside.sum())
    assert [e.n_sags for e in find_sags(T, w, threshold=0.9, hysteresis=0.02)] == [1]
    flicker = find_sags(T, w, threshold=0.9, hysteresis=0.0, min_duration_s=0.0)
    assert flicker[0].n_sags > 5  # many crossings, merged into one window


def test_close_sags_merge_and_unrecovered_end():
    v = sag_profile(T, [(5.0, 0.5, 0.3), (6.0, 0.5, 0.3), (29.5, 5.0, 0.4)])
    ev = find_sags(T, v, pre_s=0.5, post_s=1.0)
    assert [e.n_sags for e in ev] == [2, 1]
    assert not ev[1].recovered and math.isnan(ev[1].recovery_s)
    assert ev[1].stop == T.size


def test_settings_checked():
    with pytest.raises(ValueError, match="threshold"):
        find_sags(T, np.ones_like(T), threshold=1.2)
    with pytest.raises(ValueError, match="increasing"):
        find_sags(T[::-1], np.ones_like(T))


# ---------------------------------------------------------------------------- PMU
def _pmu_frame(n=50, per_phase=False):
    t = pd.date_range("2024-03-31 00:59:59", periods=n, freq="20ms", tz="Europe/Berlin")
    vm = np.full(n, 132.79)  # kV phase to neutral: 230 kV line to line
    vm[20:30] = 0.8 * 132.79
    s = 60.0 * (0.5 + 0.5 * (vm / 132.79) ** 2)  # MW, half Z half P, unity power factor
    im = s / (3 * vm)  # kA
    df = pd.DataFrame({"timestamp": [x.isoformat() for x in t]})
    if per_phase:
        for k, ph in enumerate("abc"):
            df[f"v{ph}_mag"] = vm
            df[f"v{ph}_ang"] = -120.0 * k + 10.0
            df[f"i{ph}_mag"] = im
            df[f"i{ph}_ang"] = -120.0 * k + 10.0 - 30.0
    else:
        df["v1_mag"], df["v1_ang"], df["i1_mag"], df["i1_ang"] = vm, 10.0, im, -20.0
    df["freq"] = 50.0
    return df, s


@pytest.mark.parametrize("per_phase", [False, True])
def test_pmu_positive_sequence_and_per_phase(tmp_path, per_phase):
    df, s = _pmu_frame(per_phase=per_phase)
    path = tmp_path / "pmu.csv"
    df.to_csv(path, index=False)
    cols = {}
    if per_phase:
        cols = {f"{x}_{k}": ",".join(f"{x[0]}{ph}_{k}" for ph in "abc")
                for x in ("v", "i") for k in ("mag", "ang")}  # fmt: skip
    m = load_map(None, voltage="kV", current="kA", freq="freq", v_kv=230.0, s_mva=100.0, **cols)
    rec = read_pmu(path, m)
    assert rec.report == []
    np.testing.assert_allclose(rec.data["t_s"], np.arange(50) * 0.02, atol=1e-9)
    np.testing.assert_allclose(rec.data["v"][:20], 132.79 / (230 / math.sqrt(3)), rtol=1e-9)
    # 30 degrees between V and I: P = |S| cos 30, Q = |S| sin 30
    np.testing.assert_allclose(rec.data["p"], s / 100 * math.cos(math.pi / 6), rtol=1e-9)
    np.testing.assert_allclose(rec.data["q"], s / 100 * math.sin(math.pi / 6), rtol=1e-9)
    assert rec.start == "2024-03-30T23:59:59.000000000Z"  # Berlin (+01:00) to UTC


def test_pmu_naive_times_zone_duplicates_order_and_gaps(tmp_path):
    df, _ = _pmu_frame()
    naive = pd.date_range("2024-03-31 00:59:59", periods=len(df), freq="20ms")
    df["timestamp"] = [x.strftime("%Y-%m-%d %H:%M:%S.%f") for x in naive]
    df = pd.concat([df.iloc[:10], df.iloc[[5]], df.iloc[12:]])  # a duplicate and a gap
    df = pd.concat([df.iloc[[1]], df.drop(df.index[1])])  # a row out of order
    path = tmp_path / "pmu.csv"
    df.to_csv(path, index=False)
    toml = tmp_path / "map.toml"
    toml.write_text(
        '[columns]\nv_mag = "v1_mag"\nv_ang = "v1_ang"\ni_mag = "i1_mag"\ni_ang = "i1_ang"\n'
        '[units]\nvoltage = "kV"\ncurrent = "kA"\n'
        '[time]\ntimezone = "America/New_York"\n'
    )
    rec = read_pmu(path, load_map(toml))
    text = " | ".join(rec.report)
    assert "1 duplicate timestamps (rows 11); first row kept" in text
    assert "out of time order" in text
    assert "1 gaps in time (2 reports missing at 50/s); longest 0.06 s after row 10" in text
    assert rec.start == "2024-03-31T04:59:59.000000000Z"  # 00:59:59 EDT
    assert np.all(np.diff(rec.data["t_s"]) > 0)
    assert rec.data["v"][0] == 1.0  # the default base: the first sample


def test_pmu_bad_input_named(tmp_path):
    df, _ = _pmu_frame()
    df["v1_mag"] = df["v1_mag"].astype(object)
    df.loc[7, "v1_mag"] = "x"
    path = tmp_path / "pmu.csv"
    df.to_csv(path, index=False)
    with pytest.raises(DataError, match=r"pmu.csv: column 'v1_mag', row 8: not a finite number"):
        read_pmu(path, load_map(None))
    df, _ = _pmu_frame()
    df.loc[3, "timestamp"] = "yesterday"
    df.to_csv(path, index=False)
    with pytest.raises(DataError, match=r"column 'timestamp', row 4: not an ISO 8601"):
        read_pmu(path, load_map(None))
    with pytest.raises(DataError, match=r"no column 'Volts'"):
        read_pmu(path, load_map(None, v_mag="Volts"))
    bad = tmp_path / "map.toml"
    bad.write_text("[columns]\nvoltage = 3\n")
    with pytest.raises(DataError, match=r"map.toml: unknown key columns.voltage"):
        load_map(bad)
    with pytest.raises(DataError, match="1 column .positive sequence. or 3"):
        load_map(None, v_mag="a,b")


def test_pmu_mixed_zoned_and_naive_timestamps(tmp_path):
    df, _ = _pmu_frame(n=4)
    # UTC, naive Paris summer time (+02:00), a bare-hour offset, New York (-04:00).
    df["timestamp"] = [
        "2024-06-01T12:00:00Z",
        "2024-06-01 14:00:00.02",
        "2024-06-01T12:00:00.04+00",
        "2024-06-01T08:00:00.06-04:00",
    ]
    df.to_csv(tmp_path / "pmu.csv", index=False)
    rec = read_pmu(tmp_path / "pmu.csv", load_map(None, timezone="Europe/Paris"))
    np.testing.assert_allclose(rec.data["t_s"], [0.0, 0.02, 0.04, 0.06], atol=1e-9)


def test_pmu_names_in_a_spreadsheets_code_page(tmp_path):
    # A historian export with Chinese column names, saved in GB18030: read as written.
    df, s = _pmu_frame()
    df = df.rename(columns={"v1_mag": "电压幅值"})
    path = tmp_path / "pmu.csv"
    path.write_bytes(df.to_csv(index=False).encode("gb18030"))
    m = load_map(None, v_mag="电压幅值", voltage="kV", current="kA", v_kv=230.0, s_mva=100.0)
    rec = read_pmu(path, m)
    np.testing.assert_allclose(rec.data["p"], s / 100 * math.cos(math.pi / 6), rtol=1e-9)
    # Latin-1 is not guessed: one line that says what to do, no traceback.
    df = df.rename(columns={"电压幅值": "Spannung_µ"})
    path.write_bytes(df.to_csv(index=False).encode("latin-1"))
    with pytest.raises(DataError, match=r"pmu.csv: header is not UTF-8 text.*save it as UTF-8"):
        read_pmu(path, load_map(None, v_mag="Spannung_µ"))
    # A bad byte in a row is located.
    df, _ = _pmu_frame()
    df["note"] = "ok"
    df.loc[4, "note"] = "é"
    path.write_bytes(df.to_csv(index=False).encode("latin-1"))
    with pytest.raises(DataError, match=r"pmu.csv: row 5: not UTF-8 text"):
        read_pmu(path, load_map(None))


def test_pmu_a_european_export_with_comma_fractions(tmp_path):
    # ';' between fields, ',' as the decimal mark, and the timestamps' fraction of a
    # second after a comma (ISO 8601 allows it): the timestamps were refused.
    df, s = _pmu_frame()
    text = df.to_csv(index=False, sep=";").replace(".", ",")
    path = tmp_path / "pmu.csv"
    path.write_text(text)
    assert "T00:59:59,020000+01:00" in text
    m = load_map(None, voltage="kV", current="kA", freq="freq", v_kv=230.0, s_mva=100.0)
    rec = read_pmu(path, m)
    np.testing.assert_allclose(rec.data["t_s"], np.arange(50) * 0.02, atol=1e-9)
    np.testing.assert_allclose(rec.data["p"], s / 100 * math.cos(math.pi / 6), rtol=1e-9)


def test_pmu_zero_current_is_said(tmp_path):
    df, _ = _pmu_frame()
    df["i1_mag"] = 0.0
    path = tmp_path / "pmu.csv"
    df.to_csv(path, index=False)
    m = load_map(None, voltage="kV", current="kA", v_kv=230.0, s_mva=100.0)
    rec = read_pmu(path, m)
    assert any("is 0 in every row: P and Q are 0" in r for r in rec.report)
    assert not np.any(rec.data["p"])
    with pytest.raises(DataError, match=r"first sample has zero power \(the current is 0\)"):
        read_pmu(path, load_map(None, voltage="kV", current="kA"))
