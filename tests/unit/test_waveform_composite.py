"""The recorder-file generator (tests/waveform_composite.py) checked on its own, without loadbayes.

The file is read back by hand (the ``.cfg`` lines, the ``.dat`` integers times each
channel's multiplier) and a plain one-cycle DFT of the samples must give the
trajectory's V, P and Q in steady state, to the noise the generator adds.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from independent_composite import Sag
from waveform_composite import trajectory_samples, write_event

A = np.exp(2j * np.pi / 3)


@pytest.mark.parametrize("f_hz", [60.0, 50.0])
def test_the_file_holds_the_trajectory_s_phasors(tmp_path, f_hz):
    cfg, truth, traj = write_event(
        tmp_path / "ev", f_hz=f_hz, t_end_s=1.0, sags=(Sag(0.5123, 0.35, 0.15, 0.0, 0.0),)
    )
    lines = cfg.read_text(encoding="ascii").splitlines()
    assert lines[0].endswith(",1999") and lines[1] == "6,6A,0D"
    chans = [ln.split(",") for ln in lines[2:8]]
    assert [c[1] for c in chans] == ["Va", "Vb", "Vc", "Ia", "Ib", "Ic"]
    assert [c[4] for c in chans] == ["V"] * 3 + ["A"] * 3
    rate, n = float(lines[10].split(",")[0]), int(lines[10].split(",")[1])
    assert float(lines[8]) == f_hz and rate == 64 * f_hz and lines[13] == "ASCII"
    dat = np.loadtxt(cfg.with_suffix(".dat"), delimiter=",", dtype=np.int64)
    assert dat.shape == (n, 8) and np.array_equal(dat[:, 0], np.arange(1, n + 1))
    # Whole microseconds from 0 at the nominal rate.
    assert np.abs(dat[:, 1] - np.arange(n) * 1e6 / rate).max() <= 0.5
    x = dat[:, 2:].T * np.array([float(c[5]) for c in chans])[:, None]

    # One-cycle DFT of the first 20 cycles (before the sag at 0.5123 s).
    k = 64
    m = 20
    win = x[:, : m * k].reshape(6, m, k)
    ph = win @ (np.exp(-2j * np.pi * np.arange(k) / k) * math.sqrt(2) / k)
    v1 = (ph[0] + A * ph[1] + A**2 * ph[2]) / 3
    s = np.sum(ph[:3] * np.conj(ph[3:]), axis=0)
    centre = (np.arange(m) + 0.5) / f_hz
    v_pu, _, p_pu, q_pu = trajectory_samples(traj, centre)
    v_base = truth["v_base_kv"] * 1e3 / math.sqrt(3)
    s_base = truth["s_base_mva"] * 1e6
    # Noise: 0.2% of the voltage peak and 1% of the current peak per sample, over 64
    # samples and three phases: about 1e-3 on P, Q and 2e-4 on V (bounds 4 sd).
    assert np.abs(np.abs(v1) / v_base - v_pu).max() < 1e-3
    assert np.abs(s.real / s_base - p_pu).max() < 4e-3
    assert np.abs(s.imag / s_base - q_pu).max() < 4e-3
    assert truth["f_m"] == 0.4 and p_pu[0] == pytest.approx(0.8, abs=1e-9)
