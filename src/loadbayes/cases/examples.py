"""The example inputs of ``loadbayes example``: small files whose answer is known.

Every file the README's usage block reads is made here, by the package's own
simulators and writers, in the units a user's data come in (kV, MW, Mvar, amperes):

- ``day``: a day at an 11 kV bus whose ZIP shares drift and jump
  (:func:`loadbayes.cases.scenarios.composition_path`), for ``track zip``;
- ``composite``: two voltage sags at a load of ZIP + induction motor
  (:func:`loadbayes.cases.composite_sim.simulate_event`), for ``fit composite``;
- ``fleet``: a folder of Parquet files, one row per sample of many buses in three
  customer classes (:mod:`loadbayes.fleet.generate`), for ``fit zip --by``;
- ``comtrade``: a disturbance recorder's ``.cfg``/``.dat`` pair of three-phase
  waveforms with two sags (:mod:`loadbayes.recordings.synth`), for ``read comtrade``;
- ``pmu``: a PMU historian CSV of positive-sequence phasors with one sag, and the
  ``map.toml`` that names its columns, for ``read pmu``.

Each builder returns ``{file name: content}`` (text or bytes), so that the command can
write all of them into a folder, or none.
"""

from __future__ import annotations

import math
import tempfile
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pandas as pd

__all__ = [
    "BUS_KV",
    "BUS_MVA",
    "KINDS",
    "composite_files",
    "comtrade_files",
    "day_frame",
    "fleet_files",
    "pmu_files",
]

#: The example bus: 11 kV line to line, powers per unit of 5 MVA.
BUS_KV = 11.0
BUS_MVA = 5.0
#: The ZIP load behind the COMTRADE and PMU recordings (a1..a6).
RECORDING_ZIP = (0.40, 0.30, 0.30, 0.60, 0.20, 0.20)

Content = str | bytes


def day_frame(*, seed: int = 2026, minutes: int = 1440) -> pd.DataFrame:
    """A day of 1-minute samples at an 11 kV bus whose load composition changes.

    The shares follow :func:`loadbayes.cases.scenarios.composition_path` (a1 drifts from
    0.15 at night to 0.45 in the evening; a constant-power load switches on 13:00-19:00);
    the nominal load is 4 MW and 1.6 Mvar at 11 kV. The voltage has a daily swing of 2 %,
    a wander of 0.5 %, and steps of 4 % every 20 minutes (a voltage-reduction test, what
    lets a few hours of data tell the shares apart); P and Q carry noise of 0.3 % of
    their nominal values.

    Returns
    -------
    pandas.DataFrame
        ``time`` (ISO), ``t_h`` (hours since midnight), ``v`` (kV), ``p`` (MW), ``q``
        (Mvar) and the true shares ``a1_true .. a6_true`` (ignored by the fits, drawn
        by ``track zip --plot``).
    """
    from loadbayes.cases.scenarios import composition_path

    gen = np.random.default_rng(seed)
    t_h = np.arange(minutes) / 60.0
    swing = 0.02 * np.cos(2 * np.pi * (t_h - 4.0) / 24.0)
    # A voltage-reduction test: the tap changer holds 1.04, 1.00, 0.96 p.u. for 20 minutes
    # each, round the clock (what lets a few hours of data tell the shares apart).
    taps = 0.04 * np.array([1.0, 0.0, -1.0])[(np.arange(minutes) // 20) % 3]
    wander = np.zeros(minutes)
    for k in range(1, minutes):  # AR(1), sd about 0.005, correlated over ~5 minutes
        wander[k] = 0.8 * wander[k - 1] + 0.003 * gen.standard_normal()
    x = 1.0 + swing + taps + wander
    zp, zq = composition_path(t_h)
    p0, q0 = 4.0, 1.6
    p = p0 * (zp[:, 0] * x**2 + zp[:, 1] * x + zp[:, 2])
    q = q0 * (zq[:, 0] * x**2 + zq[:, 1] * x + zq[:, 2])
    p += 0.003 * p0 * gen.standard_normal(minutes)
    q += 0.003 * q0 * gen.standard_normal(minutes)
    time = pd.Timestamp("2026-03-02") + pd.to_timedelta(np.arange(minutes), unit="min")
    frame = pd.DataFrame(
        {
            "time": time.strftime("%Y-%m-%dT%H:%M"),
            "t_h": np.round(t_h, 4),
            "v": np.round(x * BUS_KV, 4),
            "p": np.round(p, 4),
            "q": np.round(q, 4),
        }
    )
    for j, name in enumerate(("a1", "a2", "a3")):
        frame[f"{name}_true"] = np.round(zp[:, j], 4)
    for j, name in enumerate(("a4", "a5", "a6")):
        frame[f"{name}_true"] = np.round(zq[:, j], 4)
    return frame


def composite_files(*, seed: int = 1) -> dict[str, Content]:
    """Two sags (30 % and 50 %) at a composite load: ``sag1.csv``, ``sag2.csv``.

    A small industrial motor carries half of the active power (f_m = 0.5), the rest is a
    ZIP load (a1..a3 = 0.3, 0.3, 0.4); 2 s at 60 samples per second; noise 1 % of |S0|.
    Columns ``t_s``, ``v`` (kV), ``p`` (MW), ``q`` (Mvar): fit with ``--v-base 11
    --s-base 5``.
    """
    from loadbayes.cases.composite_sim import simulate_event

    out: dict[str, Content] = {}
    for k, depth in enumerate((0.3, 0.5)):
        ev, _ = simulate_event("small_industrial", depth=depth, t_end_s=2.0, seed=seed + k)
        frame = pd.DataFrame(
            {
                "t_s": np.round(ev.t, 6),
                "v": np.round(ev.v * BUS_KV, 5),
                "p": np.round(ev.p * BUS_MVA, 5),
                "q": np.round(ev.q * BUS_MVA, 5),
            }
        )
        out[f"sag{k + 1}.csv"] = frame.to_csv(index=False)
    return out


def fleet_files(*, seed: int = 7, buses: int = 24) -> dict[str, Content]:
    """A fleet of ``buses`` buses in three classes, 100 to 1,000 samples each, per unit.

    Written by :func:`loadbayes.fleet.generate.write_fleet` (``part-00000.parquet`` ...,
    columns ``bus_id``, ``customer_class``, ``v``, ``p``, ``q``); the true class mixes are
    :data:`loadbayes.fleet.generate.CLASS_MIXES`.
    """
    from loadbayes.fleet.generate import fleet_truth, write_fleet

    truth = fleet_truth(
        buses, seed=seed, rows=(300, 3000), noise=0.01, spread=(0.04, 0.1), narrow_fraction=0.0
    )
    with tempfile.TemporaryDirectory() as tmp:
        paths = write_fleet(truth, tmp, layout="files", buses_per_file=8)
        return {path.name: path.read_bytes() for path in paths}


def comtrade_files(*, seed: int = 3) -> dict[str, Content]:
    """A recorder's COMTRADE pair ``event.cfg``/``event.dat``: 8 s, 50 Hz, two sags.

    Three-phase waveforms at 1 kHz (20 samples a cycle) of the ZIP load
    :data:`RECORDING_ZIP` (5 MW, 2 Mvar at 11 kV) through sags of 30 % at 1 s and 45 %
    at 5 s (far enough apart for ``loadbayes events`` to cut them apart), each with a
    0.5 s recovery ramp, written by :func:`loadbayes.recordings.synth.write_comtrade`
    (1999, ASCII, voltages in kV).
    """
    from loadbayes.recordings.synth import sag_profile, write_comtrade, zip_waveforms

    t = np.arange(8000) / 1000.0
    v_pu = sag_profile(t, [(1.0, 0.15, 0.30), (5.0, 0.10, 0.45)], recovery_s=0.5)
    v_pu = v_pu * (1.0 + 0.002 * np.random.default_rng(seed).standard_normal(t.size))
    v, i = zip_waveforms(
        t, v_pu, RECORDING_ZIP, p0=1.0, q0=0.4, v_base=BUS_KV * 1e3 / math.sqrt(3),
        s_base=BUS_MVA * 1e6, f_hz=50.0,
    )  # fmt: skip

    with tempfile.TemporaryDirectory() as tmp:
        files = write_comtrade(Path(tmp) / "event", t, v, i, f_nominal=50.0)
        return {path.name: path.read_bytes() for path in files}


def pmu_files(*, seed: int = 4) -> dict[str, Content]:
    """A PMU historian CSV ``historian.csv`` and its column map ``map.toml``.

    Two minutes at 30 frames per second of positive-sequence phasors at an 11 kV bus
    (``V1 Mag`` in kV phase to neutral, ``I1 Mag`` in A, angles in degrees, ``Freq`` in
    Hz, ISO timestamps with an offset): the ZIP load :data:`RECORDING_ZIP` (5 MW,
    2 Mvar) through one sag of 25 % at 60 s with a 1 s recovery; noise 0.1 %.
    """
    from loadbayes.recordings.synth import sag_profile

    gen = np.random.default_rng(seed)
    n = 120 * 30
    t = np.arange(n) / 30.0
    x = sag_profile(t, [(60.0, 0.2, 0.25)], recovery_s=1.0)
    x = x * (1.0 + 0.001 * gen.standard_normal(n))
    a1, a2, a3, a4, a5, a6 = RECORDING_ZIP
    p = BUS_MVA * (a1 * x**2 + a2 * x + a3) * 1e6
    q = 0.4 * BUS_MVA * (a4 * x**2 + a5 * x + a6) * 1e6
    freq = 50.0 + 0.01 * np.sin(2 * np.pi * t / 40.0) + 0.002 * gen.standard_normal(n)
    ang_v = np.degrees(np.cumsum(2 * np.pi * (freq - 50.0) / 30.0))
    v_ln = x * BUS_KV * 1e3 / math.sqrt(3)
    s = (p + 1j * q) / 3.0
    i1 = np.conj(s / (v_ln * np.exp(1j * np.radians(ang_v))))
    i1 = i1 * (1.0 + 0.001 * gen.standard_normal(n))
    stamps = pd.Timestamp("2026-03-02T14:00:00+00:00") + pd.to_timedelta(t, unit="s")
    frame = pd.DataFrame(
        {
            "Timestamp": stamps.strftime("%Y-%m-%dT%H:%M:%S.%f").str[:-3] + "+00:00",
            "V1 Mag": np.round(v_ln / 1e3, 5),
            "V1 Ang": np.round((ang_v + 180.0) % 360.0 - 180.0, 4),
            "I1 Mag": np.round(np.abs(i1), 3),
            "I1 Ang": np.round(np.degrees(np.angle(i1)), 4),
            "Freq": np.round(freq, 4),
        }
    )
    mapping = (
        "# Columns of historian.csv (loadbayes read pmu --map map.toml; docs/formats.md)\n"
        "[columns]\n"
        'time = "Timestamp"\nv_mag = "V1 Mag"\nv_ang = "V1 Ang"\n'
        'i_mag = "I1 Mag"\ni_ang = "I1 Ang"\nfreq = "Freq"\n\n'
        '[units]\nangle = "deg"\nvoltage = "kV"\ncurrent = "A"\n\n'
        f"[base]\nv_kv = {BUS_KV:g}\ns_mva = {BUS_MVA:g}\n"
    )
    return {"historian.csv": frame.to_csv(index=False), "map.toml": mapping}


#: Folder kinds: name -> builder of ``{file name: content}``.
KINDS: dict[str, Callable[[], dict[str, Content]]] = {
    "composite": composite_files,
    "fleet": fleet_files,
    "comtrade": comtrade_files,
    "pmu": pmu_files,
}
