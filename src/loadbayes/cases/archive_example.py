"""``loadbayes example archive``: a year of fault records at three stations, and its truth.

Three stations, two bays each (a transformer and a feeder), 50 records per station spread
over 2025 (fewer, or the transformer alone, by ``records`` and ``bays``): at each fault
the bus voltage dips by 5-30 % for 60-150 ms and recovers over 50-200 ms; each bay's
load is a ZIP part and an induction motor
(:func:`loadbayes.cases.composite_sim.simulate_event`, the library's
``small_industrial`` motor at 50 Hz) whose share of the bay's power follows the station's
seasonal curve, highest in summer (air conditioning), plus event-to-event noise
(sd 0.03). The waveforms are sampled at 1200 Hz (24 per cycle) with 0.2 % noise and
written as COMTRADE 1999 (ASCII or BINARY) with the station's name in its own encoding:
GB18030 (``城东变电站``), ASCII, Latin-1 (``Umspannwerk Größe``). Two files are broken
as archives' files are: a ``.cfg`` whose channel counts disagree with its lines, and a
``.cfg`` without its ``.dat``.

``truth.csv`` beside them: per record and bay the station, bay, file, the dip's time, its
depth, the event's motor share ``f_m`` and the seasonal curve's value ``f_m_mean``.
"""

from __future__ import annotations

import datetime as dt
import io
import math
from dataclasses import dataclass, replace

import numpy as np

__all__ = ["ARCHIVE_STATIONS", "archive_files", "seasonal_share"]

F_HZ = 50.0
RATE_HZ = 1200.0
#: The load is simulated at this rate and interpolated to the waveform's.
SIM_HZ = 200.0
KV = 110.0


@dataclass(frozen=True)
class _Station:
    code: str
    name: str
    encoding: str
    bays: tuple[str, str]
    mva: tuple[float, float]
    mean: tuple[float, float]  # the yearly mean motor share of each bay
    swing: float  # half the summer-winter difference


ARCHIVE_STATIONS = (
    _Station("cd", "城东变电站", "gb18030", ("1号主变", "10kV出线1"), (40.0, 12.0),
             (0.35, 0.30), 0.15),
    _Station("rs", "Riverside 132kV", "ascii", ("TX1", "Feeder 2"), (30.0, 10.0),
             (0.25, 0.30), 0.10),
    _Station("ug", "Umspannwerk Größe", "latin-1", ("Trafo 1", "Abgang 3"), (35.0, 8.0),
             (0.40, 0.30), 0.12),
)  # fmt: skip


def seasonal_share(station: int, bay: int, day_of_year: float) -> float:
    """The true mean motor share of a bay on a day of 2025 (its summer peak at day 200)."""
    st = ARCHIVE_STATIONS[station]
    return st.mean[bay] + st.swing * math.cos(2.0 * math.pi * (day_of_year - 200.0) / 365.25)


def _bay_power(depth, start, dur, rec, f_m, t_end, seed):
    """V and S of one bay at the waveform's rate: the load simulated at 200 per second.

    The motor's integration costs the same per output sample as per step at 1200 per
    second (a sixth of it at 200); S is interpolated between its samples, V is exact.
    """
    from loadbayes.cases.composite_sim import sag_samples, simulate_event
    from loadbayes.models.motor_library import MOTORS

    motor = replace(MOTORS["small_industrial"], f_hz=F_HZ)
    ev, _ = simulate_event(motor, depth=depth, start_s=start, duration_s=dur, recovery_s=rec,
                           t_end_s=t_end, fs=SIM_HZ, f_m=f_m, noise=0.0, seed=seed)  # fmt: skip
    t = np.arange(int(round(t_end * RATE_HZ))) / RATE_HZ
    v = sag_samples(t, depth=depth, start_s=start, duration_s=dur, recovery_s=rec)
    s = np.interp(t, ev.t, ev.p) + 1j * np.interp(t, ev.t, ev.q)
    return t, v, s


def _record(st: _Station, when: dt.datetime, t, v, powers, rng, fmt: str) -> tuple[bytes, bytes]:
    """The .cfg (in the station's encoding) and .dat of the bus voltages and bay currents."""
    vph = KV / math.sqrt(3.0)
    theta = 2.0 * math.pi * F_HZ * t
    shift = (0.0, -2.0 * math.pi / 3.0, 2.0 * math.pi / 3.0)
    chans = [(f"U{p}", p, "Bus", "kV", math.sqrt(2) * vph * v * np.cos(theta + s))
             for p, s in zip("ABC", shift, strict=True)]  # fmt: skip
    n = len(powers)  # the bays simulated: the transformer's first
    for bay, s_pu, mva in zip(st.bays[:n], powers, st.mva[:n], strict=True):
        i_pu = np.conj(s_pu / v)
        amp = math.sqrt(2) * mva * 1e3 / (math.sqrt(3.0) * KV) * np.abs(i_pu)
        chans += [(f"{bay}_I{p}", p, bay, "A", amp * np.cos(theta + np.angle(i_pu) + s))
                  for p, s in zip("ABC", shift, strict=True)]  # fmt: skip
    lines = [f"{st.name},DFR-{st.code.upper()},1999", f"{len(chans)},{len(chans)}A,0D"]
    raws = []
    for k, (name, ph, ccbm, unit, x) in enumerate(chans, start=1):
        x = x * (1.0 + 0.002 * rng.standard_normal(x.size))
        a = float(np.max(np.abs(x))) / 32000.0
        raws.append(np.round(x / a).astype(np.int64))
        lines.append(f"{k},{name},{ph},{ccbm},{unit},{a:.9g},0,0,-32767,32767,1,1,P")
    stamp = when.strftime("%d/%m/%Y,%H:%M:%S.%f")
    trigger = (when + dt.timedelta(seconds=0.2)).strftime("%d/%m/%Y,%H:%M:%S.%f")
    lines += [f"{F_HZ:g}", "1", f"{RATE_HZ:g},{t.size}", stamp, trigger, fmt, "1"]
    cfg = ("\r\n".join(lines) + "\r\n").encode(st.encoding)
    stamps = np.round(t * 1e6).astype(np.int64)
    if fmt == "ASCII":
        body = np.column_stack([np.arange(1, t.size + 1), stamps, *raws])
        buf = io.StringIO()
        np.savetxt(buf, body, fmt="%d", delimiter=",", newline="\r\n")
        return cfg, buf.getvalue().encode("ascii")
    rec = np.zeros(t.size, dtype=[("n", "<u4"), ("t", "<u4"), ("x", "<i2", (len(raws),))])
    rec["n"] = np.arange(1, t.size + 1)
    rec["t"] = stamps
    rec["x"] = np.stack(raws, axis=1)
    return cfg, rec.tobytes()


def archive_files(
    *, records: int = 50, bays: int = 2, seed: int = 38, year: int = 2025
) -> dict[str, bytes]:
    """The archive's files by name (``<station>_<time>.cfg/.dat``) and ``truth.csv``.

    ``records`` per station (each holds every bay: records per bay); ``bays`` 1 writes the
    transformer's alone (half the simulation, half the fits).
    """
    import pandas as pd

    if records < 1 or bays not in (1, 2):
        raise ValueError(f"records {records} must be at least 1 and bays 1 or 2, not {bays}")
    rng = np.random.default_rng(seed)
    out: dict[str, bytes] = {}
    truth = []
    for si, st in enumerate(ARCHIVE_STATIONS):
        days = np.sort(rng.uniform(0.0, 365.0, records))
        for k, day in enumerate(days):
            when = (dt.datetime(year, 1, 1) + dt.timedelta(days=float(day))).replace(microsecond=0)
            depth, dur = rng.uniform(0.05, 0.30), rng.uniform(0.06, 0.15)
            rec, start = rng.uniform(0.05, 0.2), 0.2 + rng.uniform(0.0, 0.02)
            powers = []
            name = f"{st.code}_{when:%Y%m%d_%H%M%S}"
            for b in range(bays):
                mean = seasonal_share(si, b, float(day))
                f_m = float(np.clip(mean + 0.03 * rng.standard_normal(), 0.05, 0.9))
                t, v, s = _bay_power(depth, start, dur, rec, f_m, 1.1, seed + k)
                powers.append(s)
                truth.append({"station": st.name, "bay": st.bays[b], "time": when +
                              dt.timedelta(seconds=start), "depth": depth, "f_m": f_m,
                              "f_m_mean": mean, "file": name + ".cfg"})  # fmt: skip
            cfg, dat = _record(st, when, t, v, powers, rng, "ASCII" if k % 2 else "BINARY")
            out[name + ".cfg"], out[name + ".dat"] = cfg, dat
    first = next(iter(out))
    bad = out[first].split(b"\r\n")
    bad[1] = b"5,5A,0D"  # the channel counts disagree with the channel lines
    out["broken_counts.cfg"], out["broken_counts.dat"] = b"\r\n".join(bad), out[first[:-4] + ".dat"]
    out["no_data.cfg"] = out[first]  # its .dat was never copied
    frame = pd.DataFrame(truth)
    frame["time"] = frame["time"].map(lambda x: x.isoformat(timespec="milliseconds"))
    out["truth.csv"] = frame.to_csv(index=False, float_format="%.4f").encode("utf-8")
    return out
