"""Current channels get checks as the voltages do (red-team M4).

A channel's declared unit against the role it is named for, a zero-sequence channel
never taken as a phase, a corrupt sample (1e6 times its channel's median) refused with
the channel and the sample, and a current phase 1000 times smaller than another refused
(3 times smaller: said, since an unbalanced load can be real).
"""

from __future__ import annotations

import numpy as np
import pytest

from loadbayes.io.errors import DataError
from loadbayes.recordings.comtrade import read_comtrade
from loadbayes.recordings.synth import sag_profile, write_comtrade, zip_waveforms

NAMES = ("VA", "VB", "VC", "IA", "IB", "IC")


def _record(folder, *, fmt="ASCII", revision="1999", names=NAMES, edit=None):
    t = np.arange(1920) / 3200.0
    v, i = zip_waveforms(
        t, sag_profile(t, [(0.2, 0.2, 0.3)], recovery_s=0.05), (0.3, 0.3, 0.4, 0.5, 0.2, 0.3)
    )
    if edit is not None:
        edit(i)
    cfg, _ = write_comtrade(folder / "rec", t, v, i, revision=revision, fmt=fmt, names=names)
    return cfg


def test_a_current_named_as_voltage_and_a_voltage_as_current_are_refused(tmp_path):
    cfg = _record(tmp_path)
    with pytest.raises(DataError, match=r"line \d+: channel 'IA' is in 'A', a current's unit"):
        read_comtrade(cfg, voltage=["IA", "IB", "IC"], current=["VA", "VB", "VC"])
    with pytest.raises(DataError, match=r"line \d+: channel 'VA' is in 'kV', a voltage's unit"):
        read_comtrade(cfg, current=["VA", "VB", "VC"])


def test_a_zero_sequence_channel_is_never_a_phase(tmp_path):
    cfg = _record(tmp_path, names=("VA", "VB", "VC", "IA", "IB", "3I0"))
    with pytest.raises(DataError, match=r"line \d+: channel '3I0' .*zero-sequence"):
        read_comtrade(cfg, voltage=["VA", "VB", "VC"], current=["IA", "IB", "3I0"])


def test_a_corrupt_current_sample_is_refused_with_its_row(tmp_path):
    def spike(i):
        i[1, 700] = 3e30

    cfg = _record(tmp_path, fmt="FLOAT32", revision="2013", edit=spike)
    with pytest.raises(DataError, match=r"current channel 'IB', sample 701: 3e\+30 is") as err:
        read_comtrade(cfg)
    assert "\n" not in str(err.value)


def test_a_current_phase_scaled_far_down_is_refused_a_little_down_is_said(tmp_path):
    def tiny(i):
        i[2] *= 1e-30

    (tmp_path / "a").mkdir()
    cfg = _record(tmp_path / "a", fmt="FLOAT32", revision="2013", edit=tiny)
    with pytest.raises(DataError, match=r"line \d+: current channel 'IC' is \S+e\+29 times"):
        read_comtrade(cfg)

    def quarter(i):
        i[2] *= 0.25

    (tmp_path / "b").mkdir()
    w = read_comtrade(_record(tmp_path / "b", edit=quarter))
    assert any("'IC' is 3.91 times smaller" in n for n in w.notes), w.notes
