"""COMTRADE reading: every revision and format round-trips; malformed files name file and line."""

import math

import numpy as np
import pytest

from loadbayes.io.errors import DataError
from loadbayes.recordings.comtrade import parse_cfg, read_comtrade
from loadbayes.recordings.synth import sag_profile, write_comtrade, zip_waveforms

FS = 1600.0  # 32 samples per 50 Hz cycle
CASES = [
    ("1991", "ASCII"),
    ("1991", "BINARY"),
    ("1999", "ASCII"),
    ("1999", "BINARY"),
    ("2013", "ASCII"),
    ("2013", "BINARY"),
    ("2013", "BINARY32"),
    ("2013", "FLOAT32"),
]


def _waves(seconds=0.2):
    t = np.arange(int(seconds * FS)) / FS
    v, i = zip_waveforms(t, sag_profile(t, [(0.05, 0.05, 0.3)]), (0.3, 0.2, 0.5, 0.6, 0.1, 0.3))
    return t, v, i


@pytest.mark.parametrize(("revision", "fmt"), CASES)
def test_round_trip_every_revision_and_format(tmp_path, revision, fmt):
    t, v, i = _waves()
    ratio = None if revision == "1991" else (230_000.0, 110.0)
    cfg, _ = write_comtrade(tmp_path / "rec", t, v, i, revision=revision, fmt=fmt, ratio=ratio)
    w = read_comtrade(cfg)
    # Quantisation: 16-bit binary keeps ~4.5 significant digits of the channel's peak.
    rel = 1e-4 if fmt == "BINARY" else 1e-6
    assert w.rate_hz == pytest.approx(FS)
    assert w.f_nominal == 50.0
    np.testing.assert_allclose(w.t_s, t, atol=1e-9)
    np.testing.assert_allclose(w.v, v, atol=rel * np.abs(v).max())
    np.testing.assert_allclose(w.i, i, atol=rel * np.abs(i).max())
    assert w.channels == {"va": "VA", "vb": "VB", "vc": "VC", "ia": "IA", "ib": "IB", "ic": "IC"}


def test_secondary_side_divides_by_the_ratio(tmp_path):
    t, v, i = _waves()
    cfg, _ = write_comtrade(tmp_path / "rec", t, v, i, revision="1999", ratio=(230_000.0, 110.0))
    prim = read_comtrade(cfg)
    sec = read_comtrade(cfg, side="secondary")
    np.testing.assert_allclose(sec.v * 230_000.0 / 110.0, prim.v, rtol=1e-12)
    np.testing.assert_allclose(sec.i, prim.i)  # currents were written as primary values


def test_channels_by_name(tmp_path):
    t, v, i = _waves()
    names = ("U1", "U2", "U3", "J1", "J2", "J3")
    cfg, _ = write_comtrade(tmp_path / "rec", t, v, i, names=names)
    w = read_comtrade(cfg, voltage=["U1", "U2", "U3"], current=["J1", "J2", "J3"])
    np.testing.assert_allclose(w.v[1], v[1], atol=1e-6 * np.abs(v).max())
    with pytest.raises(DataError, match="no analog channel 'X1'"):
        read_comtrade(cfg, voltage=["X1", "U2", "U3"])


def _rewrite(cfg, line_no, new):
    lines = cfg.read_text().splitlines()
    lines[line_no - 1] = new
    cfg.write_text("\r\n".join(lines) + "\r\n")


@pytest.fixture
def rec(tmp_path):
    t, v, i = _waves()
    return write_comtrade(tmp_path / "rec", t, v, i, revision="1999", fmt="BINARY")


def _error(cfg, *needles):
    with pytest.raises(DataError) as err:
        read_comtrade(cfg)
    msg = str(err.value)
    assert "\n" not in msg
    for needle in needles:
        assert needle in msg, msg
    return msg


def test_unknown_revision(rec):
    cfg, _ = rec
    _rewrite(cfg, 1, "station,device,2005")
    _error(cfg, str(cfg), "line 1", "unknown COMTRADE revision '2005'")


def test_channel_counts_that_disagree(rec):
    cfg, _ = rec
    _rewrite(cfg, 2, "7,6A,0D")
    _error(cfg, "line 2", "total 7 != 6 analog + 0 status")


def test_more_analog_channels_declared_than_described(rec):
    cfg, _ = rec
    _rewrite(cfg, 2, "7,7A,0D")  # the 7th "channel" is the frequency line
    _error(cfg, "line 9", "analog channel 7")


def test_fewer_analog_channels_declared_than_described(rec):
    cfg, _ = rec
    _rewrite(cfg, 2, "5,5A,0D")  # the 6th channel line is read as the frequency
    _error(cfg, "line 8", "expected the line frequency alone", "line 2")


def test_non_numeric_field(rec):
    cfg, _ = rec
    lines = cfg.read_text().splitlines()
    fields = lines[3].split(",")
    fields[5] = "abc"
    _rewrite(cfg, 4, ",".join(fields))
    _error(cfg, "line 4", "multiplier a 'abc' is not a number")


def test_cfg_cut_short(rec):
    cfg, _ = rec
    cfg.write_text("\r\n".join(cfg.read_text().splitlines()[:9]) + "\r\n")
    _error(cfg, "line 10", "file ends early, expected nrates")


def test_unknown_data_format(rec):
    cfg, _ = rec
    _rewrite(cfg, 14, "BINARY64")
    _error(cfg, "line 14", "unknown data file type 'BINARY64'")


def test_missing_dat(rec):
    cfg, dat = rec
    dat.unlink()
    _error(cfg, str(cfg), "rec.dat not found")


def test_truncated_binary_record(rec):
    cfg, dat = rec
    raw = dat.read_bytes()
    dat.write_bytes(raw[: len(raw) - 5])
    info = parse_cfg(cfg)
    n = info.n_samples
    _error(cfg, str(dat), f"record {n}", "truncated", f"{n - 1} whole records of 20 bytes")


def test_short_ascii_dat_and_bad_cell(tmp_path):
    t, v, i = _waves()
    cfg, dat = write_comtrade(tmp_path / "rec", t, v, i, revision="2013", fmt="ASCII")
    lines = dat.read_text().splitlines()
    dat.write_text("\n".join(lines[:-3]) + "\n")
    _error(cfg, str(dat), f"line {len(lines) - 2}", f"says {len(lines)}")
    bad = list(lines)
    bad[4] = bad[4].replace(",", ",x", 1)
    dat.write_text("\n".join(bad) + "\n")
    _error(cfg, str(dat), "line 5", "not a number")
    bad = list(lines)
    bad[6] = bad[6] + ",7"
    dat.write_text("\n".join(bad) + "\n")
    _error(cfg, str(dat), "line 7", "9 fields, expected 8")


def test_channels_not_found_by_unit(tmp_path):
    t, v, i = _waves()
    cfg, _ = write_comtrade(tmp_path / "rec", t, v, i, names=("a", "b", "c", "d", "e", "f"))
    text = cfg.read_text().replace(",A,", ",N,").replace(",B,", ",N,").replace(",C,", ",N,")
    cfg.write_text(text)
    _error(cfg, "cannot tell which three channels are the phase voltages", "--voltage")


def test_kv_units_scale_to_volts(rec):
    cfg, _ = rec
    w = read_comtrade(cfg)
    # 230 kV line to line: the phase peak is 230e3 * sqrt(2/3) volts before the sag.
    assert np.abs(w.v[0, :20]).max() == pytest.approx(230e3 * math.sqrt(2 / 3), rel=1e-3)


def test_non_integer_and_multiple_rates_are_resampled(tmp_path):
    from loadbayes.recordings.phasors import cycle_phasors, to_cycle_grid

    coefs = (0.3, 0.2, 0.5, 0.6, 0.1, 0.3)
    # 1 kHz at 60 Hz (16.7 samples per cycle), then 3 kHz: two rate segments.
    t = np.concatenate([np.arange(500) / 1000.0, 0.499 + np.arange(1, 1501) / 3000.0])
    v, i = zip_waveforms(t, np.full(t.size, 0.9), coefs, f_hz=60.0)
    cfg, _ = write_comtrade(tmp_path / "rec", t, v, i, revision="2013", fmt="FLOAT32",
                            f_nominal=60.0, rates=[(1000.0, 500), (3000.0, 2000)])  # fmt: skip
    w = read_comtrade(cfg)
    assert not w.uniform
    np.testing.assert_allclose(w.t_s, t, atol=1e-9)
    tg, vg, ig, rate = to_cycle_grid(w.t_s, w.v, w.i, f0=60.0, rate_hz=w.rate_hz, uniform=False)
    assert rate == 60.0 * 50  # ceil(3000 / 60) samples per cycle
    c = cycle_phasors(tg, vg, ig, f0=60.0, rate_hz=rate)
    vb = 230e3 / math.sqrt(3)
    # Cubic-spline error at 16.7 samples per cycle: ~5e-5 of the amplitude.
    np.testing.assert_allclose(c["v"] / vb, 0.9, rtol=2e-4)
    np.testing.assert_allclose(c["p"] / 100e6, 0.3 * 0.81 + 0.2 * 0.9 + 0.5, rtol=5e-4)
    with pytest.raises(ValueError, match="fewer than 8 per 60 Hz cycle"):
        to_cycle_grid(t[::10], v[:, ::10], i[:, ::10], f0=60.0, rate_hz=100.0, uniform=False)


def test_lenient_on_what_real_files_vary_in(tmp_path):
    t, v, i = _waves()
    names = ("VAN", "VBN", "VCN", "IA", "IB", "IC")
    cfg, _ = write_comtrade(tmp_path / "rec", t, v, i, revision="1999", names=names)
    lines = cfg.read_text().splitlines()
    for k in range(2, 8):
        f = lines[k].split(",")
        f[2] = ""  # no phase field: found from the name (VAN -> a)
        f[4] = f[4].lower()  # "kv", "a"
        lines[k] = ",".join(f[:10])  # the 1991 short form in a 1999 file: ratio 1
    cfg.write_text("\n".join(lines) + "\n")
    w = read_comtrade(cfg)
    assert w.channels["va"] == "VAN" and w.channels["ic"] == "IC"
    np.testing.assert_allclose(w.v, v, atol=1e-6 * np.abs(v).max())


def test_time_stamps_checked_and_a_missing_fraction_accepted(rec):
    cfg, _ = rec
    _rewrite(cfg, 12, "01/02/2024,10:00:00")  # no fraction: the comtrade package crashes
    assert read_comtrade(cfg).t_s.size == 320
    _rewrite(cfg, 13, "01/02/2024,99999999999")
    _error(cfg, "line 13", "time '99999999999' is not hh:mm:ss.ssssss")


def test_a_single_phase_record_says_what_it_lacks(tmp_path):
    # One voltage and one current (a single-phase recorder): no set of three to name.
    t = np.arange(64) / 3200
    va = np.round(1000 * np.sin(2 * math.pi * 50 * t)).astype(int)
    cfg = tmp_path / "one.cfg"
    cfg.write_text(
        "st,dev,1999\n2,2A,0D\n1,VA,A,,V,0.1,0,0,-32767,32767,1,1,P\n"
        "2,IA,A,,A,0.01,0,0,-32767,32767,1,1,P\n50\n1\n3200,64\n"
        "01/02/2024,10:00:00.000000\n01/02/2024,10:00:00.000000\nASCII\n1\n"
    )
    (tmp_path / "one.dat").write_text(
        "".join(f"{k + 1},{round(t[k] * 1e6)},{a},{a}\n" for k, a in enumerate(va))
    )
    _error(cfg, str(cfg), "1 voltage channel ('VA')", "single-phase")


def test_a_dat_or_cff_given_for_the_cfg_says_what_to_give(rec):
    cfg, dat = rec
    with pytest.raises(DataError) as err:
        read_comtrade(dat)
    assert str(err.value) == f"{dat}: expected a COMTRADE .cfg file: give its .cfg ({cfg})"
    cff = cfg.with_suffix(".cff")
    cff.write_bytes(cfg.read_bytes())
    with pytest.raises(DataError, match="single-file .cff form of 2013 is not read"):
        read_comtrade(cff)


@pytest.mark.parametrize(
    ("station", "codec"),
    [("Umspannwerk Größe", "latin-1"), ("Weißöl Nord", "latin-1"), ("Poste Sénégal", "latin-1"),
     ("1号主变", "gb18030"), ("线路", "gb18030"), ("Größe主变", "utf-8")],
)  # fmt: skip
def test_the_station_is_read_as_written_whatever_its_encoding(rec, station, codec):
    # 'Größe' in Latin-1 is 0xF6 0xDF: one GB18030 ideograph ('Gr鲞e'), read as such before.
    cfg, _ = rec
    lines = cfg.read_bytes().split(b"\r\n")
    lines[0] = f"{station},rec,1999".encode(codec)
    cfg.write_bytes(b"\r\n".join(lines))
    info = parse_cfg(cfg)
    assert info.station == station
    assert info.encoding == codec


def test_a_latin1_cfg_is_not_taken_for_gb18030_and_lines_split_at_line_breaks_only(rec):
    # M1 (cli-redteam-2): 'Üb' (0xDC 0x62) is a valid GB18030 ideograph: a Latin-1 .cfg
    # was decoded as GB18030 and its names garbled. M2: a cp1252 '…' (0x85, U+0085 in
    # Latin-1), a form feed or 0x1C in a name split its line (str.splitlines).
    cfg, _ = rec
    lines = cfg.read_bytes().split(b"\r\n")
    lines[0] = "BEIHU 220kV,Störschreiber,1999".encode("latin-1")
    for k, name in ((2, "Trafo1_Übertragung…_UA"), (3, "Trafo1_Übertragung\x0c_UB"),
                    (4, "Trafo1_Übertragung\x1c_UC")):  # fmt: skip
        f = lines[k].split(b",")
        f[1] = name.encode("cp1252") if "…" in name else name.encode("latin-1")
        lines[k] = b",".join(f)
    cfg.write_bytes(b"\r\n".join(lines))
    info = parse_cfg(cfg)
    # 0x85 is a control code in Latin-1 and '…' in Windows-1252, which wrote it.
    assert info.encoding == "cp1252"
    assert info.station == "BEIHU 220kV" and info.device == "Störschreiber"
    names = [ch.name for ch in info.analog[:3]]
    assert names == ["Trafo1_Übertragung…_UA", "Trafo1_Übertragung\x0c_UB",
                     "Trafo1_Übertragung\x1c_UC"]  # fmt: skip
    assert info.n_samples == 320


# --------------------------------------------------- the red-team's Lows (cli-redteam-2)
def test_a_unicode_digit_is_not_a_channel_number(rec):
    # L1: '²' passes str.isdigit() but not int(): "invalid literal for int() ...".
    cfg, _ = rec
    with pytest.raises(DataError, match=r"no analog channel '²' \(channels: VA, VB"):
        read_comtrade(cfg, voltage=["²", "2", "3"])
    f = cfg.read_text().splitlines()[2].split(",")
    _rewrite(cfg, 3, ",".join(["²", *f[1:]]))
    _error(cfg, "line 3", "analog channel index '²' is not a number")


def test_a_missing_channel_lists_twenty_names_at_most(tmp_path):
    # L4: a 10,000-channel .cfg printed a 119 kB line listing every channel.
    from loadbayes.recordings.comtrade_cfg import AnalogChannel, CfgInfo
    from loadbayes.recordings.comtrade_channels import _by_spec

    chans = [AnalogChannel(k, f"CH{k}", "", "V", 1, 0, 0, 1, 1, "P", k + 2) for k in range(1, 501)]
    info = CfgInfo("big.cfg", "1999", "s", "d", chans, 0, 50.0, [(1600.0, 10)], "ASCII", 1.0, "")
    with pytest.raises(DataError) as err:
        _by_spec(info, "nosuch", "voltage")
    msg = str(err.value)
    assert "CH20," in msg and "CH21," not in msg and "and 480 more" in msg and len(msg) < 400


def test_a_2013_cfg_whose_last_line_lacks_a_field_is_located(tmp_path):
    # L1: a last line '0' (tmq_code,leapsec cut) gave "cannot be read: not enough values
    # to unpack (expected 2, got 1)" from the comtrade package, with no line.
    t, v, i = _waves()
    cfg, _ = write_comtrade(tmp_path / "rec", t, v, i, revision="2013", fmt="BINARY")
    lines = cfg.read_text().splitlines()
    n = len(lines)
    cfg.write_text("\r\n".join(lines[:15] + ["+0,+0", "0"]) + "\r\n")
    _error(cfg, str(cfg), "line 17", "expected tmq_code,leapsec")
    cfg.write_text("\r\n".join(lines[:15] + ["+0"]) + "\r\n")
    _error(cfg, str(cfg), "line 16", "expected time_code,local_code")
    cfg.write_text("\r\n".join(lines[:15] + ["+0,+0"]) + "\r\n")
    _error(cfg, str(cfg), "line 17", "file ends early, expected tmq_code,leapsec")
    cfg.write_text("\r\n".join(lines[:15] + ["+0,+0", "F,0"]) + "\r\n")
    assert read_comtrade(cfg).t_s.size == 320 and n >= 15


def test_a_utf16_cfg_is_hinted_and_nul_bytes_are_located(rec):
    # L4: a UTF-16 .cfg read as "line 1: NUL bytes: a binary file" (it reads with
    # --encoding utf-16); 512 NUL bytes after the last line were said to be on line 1.
    cfg, _ = rec
    text = cfg.read_text()
    cfg.write_bytes(text.encode("utf-16"))
    _error(cfg, "line 1", "UTF-16", "encoding utf-16")
    assert parse_cfg(cfg, encoding="utf-16").n_samples == 320
    cfg.write_bytes(text.encode("ascii") + b"\0" * 512)
    _error(cfg, f"line {len(text.splitlines()) + 1}", "NUL bytes")


def test_a_rate_count_that_disagrees_with_the_rate_lines_is_said(rec):
    # L4: nrates 1 with two rate lines read the second as a time stamp ("date '3200' is
    # not dd/mm/yyyy"); nrates 2 with one read the stamp as a rate.
    cfg, _ = rec
    lines = cfg.read_text().splitlines()
    one = list(lines)
    one[10:11] = ["1600,100", "1600,320"]
    cfg.write_text("\r\n".join(one) + "\r\n")
    _error(cfg, "line 12", "a rate line", "nrates (1) on line 10")
    two = list(lines)
    two[9] = "2"
    cfg.write_text("\r\n".join(two) + "\r\n")
    _error(cfg, "line 12", "nrates (2) on line 10")


def test_a_utf8_bom_before_an_ascii_dat_is_skipped(tmp_path):
    # L4: "'ï»¿1' is not a number" for a BOM that an editor put before the first sample.
    t, v, i = _waves()
    cfg, dat = write_comtrade(tmp_path / "rec", t, v, i, revision="1999", fmt="ASCII")
    plain = read_comtrade(cfg)
    dat.write_bytes(b"\xef\xbb\xbf" + dat.read_bytes())
    w = read_comtrade(cfg)
    np.testing.assert_array_equal(w.v, plain.v)
    np.testing.assert_array_equal(w.t_s, plain.t_s)
