"""A recorder archive written here, not by the package: COMTRADE files of known loads.

Each station's recorder writes one record per fault on its network: the bus's three phase
voltages and, per bay, three phase currents. The load behind each bay is a ZIP part and a
third-order induction motor (SciPy's ``solve_ivp``, the equations of Kundur 7.9 written out
here) driving a load torque ``T0 w^2`` (a fan or a pump; the paper's ``A = 1``, the law
``zip+motor`` fits unless told another: the archive's check is of the model the fit
assumes, and a constant torque, which this generator had at first, is another model: it
read the motor share 6% high, see tests/statistical/test_archive_end_to_end.py); the
motor's share of the bay's power follows a seasonal curve of the station (a
peak in summer, air conditioning) with event-to-event noise. The voltage dips by 5-30 % for
80-150 ms, then recovers; the waveforms are sampled at 1200 Hz (24 per 50 Hz cycle) with
0.2 % noise.

The files come in the forms real archives hold: COMTRADE 1991, 1999 and 2013; ASCII,
BINARY, BINARY32 and FLOAT32 data; one rate or two; station names in ASCII, Latin-1
(``Umspannwerk Größe``, whose 'öß' is one GB18030 ideograph) and GB18030 (``城东变电站``).
``specials`` adds a record with no dip, a ``.cfg`` with a malformed line, a truncated
binary ``.dat`` and a ``.cfg`` without its ``.dat``.

``write_archive`` returns the truth: one row per record and bay (station, bay, file, time,
the motor share, the dip's depth), and the special files with what is wrong with them.
"""

from __future__ import annotations

import datetime as dt
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy.integrate import solve_ivp
from scipy.optimize import brentq

F0 = 50.0
RATE = 1200.0
V_LL_KV = 110.0


@dataclass(frozen=True)
class Station:
    name: str
    encoding: str
    bays: tuple[str, ...]
    base: float  # the motor share's yearly mean
    amp: float  # its seasonal swing (peak at day 200, summer)
    bay_offset: tuple[float, ...]
    mva: tuple[float, ...]


STATIONS = (
    Station("城东变电站", "gb18030", ("1号主变_高压侧", "10kV出线1"), 0.35, 0.15, (0.0, -0.05),
            (40, 12)),
    Station("Riverside 132kV", "ascii", ("TX1 HV", "Feeder 2"), 0.25, 0.10, (0.0, 0.05),
            (30, 10)),
    Station("Umspannwerk Größe", "latin-1", ("Trafo 1", "Abgang Süd"), 0.45, 0.12, (0.0, -0.1),
            (35, 8)),
)  # fmt: skip

#: The motor (Kundur's Table 7.x values, per unit on its own base).
RS, XS, XM, RR, XR, H = 0.031, 0.10, 3.2, 0.018, 0.18, 0.7
X = XS + XM
XP = XS + XM * XR / (XM + XR)
T0P = (XR + XM) / (2 * math.pi * F0 * RR)
LOADING = 0.6


def motor_share(station: Station, bay: int, day: float) -> float:
    """The true mean motor share of a bay on a day of the year (before the event's noise)."""
    return (
        station.base
        + station.bay_offset[bay]
        + station.amp * math.cos(2 * math.pi * (day - 200) / 365.25)
    )


def _steady(p_target: float):
    def power(s):
        zr = complex(RR / s, XR)
        z = complex(RS, XS) + (1j * XM * zr) / (1j * XM + zr)
        return (1.0 / np.conj(z)).real - p_target

    s0 = brentq(power, 1e-6, 0.3)
    zr = complex(RR / s0, XR)
    z = complex(RS, XS) + (1j * XM * zr) / (1j * XM + zr)
    i0 = 1.0 / z
    e0 = 1.0 - complex(RS, XP) * i0
    return s0, e0, i0


def simulate_bay(t, v_of_t, edges, f_m, *, p0=1.0, q0=0.3, zip_p=(0.4, 0.3, 0.3),
                 zip_q=(0.6, 0.2, 0.2)):  # fmt: skip
    """P, Q (per unit of the bay's base) of ZIP + motor under a voltage profile.

    ``v_of_t`` is piecewise constant between ``edges``; the motor is integrated piece by
    piece (no step inside a solver's step). Returns complex S at the times ``t``.
    """
    s0, e0, i0 = _steady(LOADING)
    t0 = (e0 * np.conj(i0)).real / (1.0 - s0) ** 2  # load torque T0 w^2, met at w = 1 - s0
    sm = f_m * p0 / LOADING  # the motor's rating on the bay's base
    qm0 = (1.0 * np.conj(i0)).imag * sm
    w = 2 * math.pi * F0

    def rhs(_t, y, v):
        e = complex(y[0], y[1])
        i = (v - e) / complex(RS, XP)
        de = -1j * w * y[2] * e - (e - 1j * (X - XP) * i) / T0P
        te = (e * np.conj(i)).real
        return [de.real, de.imag, (t0 * (1.0 - y[2]) ** 2 - te) / (2 * H)]

    y = [e0.real, e0.imag, s0]
    s_motor = np.zeros(t.size, dtype=complex)
    bounds = [0.0, *edges, t[-1] + 1e-9]
    for a, b in zip(bounds[:-1], bounds[1:], strict=True):
        v = v_of_t(0.5 * (a + b))
        sol = solve_ivp(rhs, (a, b), y, args=(v,), rtol=1e-8, atol=1e-10, dense_output=True,
                        max_step=2e-3)  # fmt: skip
        m = (t >= a) & (t < b)
        st = sol.sol(t[m])
        e = st[0] + 1j * st[1]
        i = (v - e) / complex(RS, XP)
        s_motor[m] = v * np.conj(i) * sm
        y = sol.y[:, -1]
    vt = np.array([v_of_t(x) for x in t])
    ps = (1 - f_m) * p0 * (zip_p[0] * vt**2 + zip_p[1] * vt + zip_p[2])
    qs = (q0 - qm0) * (zip_q[0] * vt**2 + zip_q[1] * vt + zip_q[2])
    return ps + 1j * qs + s_motor, vt


def _waves(t, vt, s_bays, mva, rng, noise=0.002):
    """Phase voltages (kV) and currents (A) of a balanced bus and its bays."""
    vph = V_LL_KV / math.sqrt(3)  # kV, phase RMS at 1 p.u.
    ang = 2 * math.pi * F0 * t
    shift = np.array([0.0, -2 * math.pi / 3, 2 * math.pi / 3])
    v = math.sqrt(2) * vph * vt[None, :] * np.cos(ang[None, :] + shift[:, None])
    out_i = []
    for s, sb in zip(s_bays, mva, strict=True):
        i_pu = np.conj(s / vt)  # current phasor, angle of V = 0
        ib = sb * 1e3 / (math.sqrt(3) * V_LL_KV)  # A at 1 p.u.
        amp = math.sqrt(2) * ib * np.abs(i_pu)
        out_i.append(amp[None, :] * np.cos(ang[None, :] + np.angle(i_pu)[None, :] + shift[:, None]))
    v = v * (1 + noise * rng.standard_normal(v.shape))
    out_i = [i * (1 + noise * rng.standard_normal(i.shape)) for i in out_i]
    return v, out_i


def _fmt_time(when: dt.datetime, revision: str = "1999") -> str:
    # 1991 writes the month first (mm/dd/yy), 1999 and 2013 the day (dd/mm/yyyy).
    return when.strftime("%m/%d/%Y,%H:%M:%S.%f" if revision == "1991" else "%d/%m/%Y,%H:%M:%S.%f")


def write_record(path: Path, station: Station, when: dt.datetime, v, currents, *,
                 revision="1999", fmt="ASCII", rates=((RATE, None),)):  # fmt: skip
    """Write ``path`` (.cfg) and its .dat: bus voltages, then three currents per bay."""
    chans = [("U", "kV", p, "母线" if station.encoding == "gb18030" else "Bus", v[k])
             for k, p in enumerate("ABC")]  # fmt: skip
    for bay, cur in zip(station.bays, currents, strict=True):
        chans += [(f"{bay}_I", "A", p, bay, cur[k]) for k, p in enumerate("ABC")]
    n = v.shape[1]
    lines = [f"{station.name},REC1" + ("" if revision == "1991" else f",{revision}")]
    lines.append(f"{len(chans)},{len(chans)}A,0D")
    raws = []
    for k, (name, unit, ph, ccbm, x) in enumerate(chans, start=1):
        peak = float(np.max(np.abs(x))) or 1.0
        if fmt == "FLOAT32":
            a, raw = 1.0, x.astype(np.float32)
        else:
            top = 32000 if fmt in ("ASCII", "BINARY") else 2_000_000_000
            a = peak / top
            raw = np.round(x / a).astype(np.int64)
        raws.append(raw)
        fields = [str(k), f"{name}{ph}", ph, ccbm, unit, f"{a:.9g}", "0", "0", "-32767", "32767"]
        if revision != "1991":
            fields += ["1", "1", "P"]
        lines.append(",".join(fields))
    lines.append(f"{F0:g}")
    ends = []
    for r, end in rates:
        ends.append((r, end if end is not None else n))
    lines.append(str(len(ends)))
    lines += [f"{r:g},{e}" for r, e in ends]
    lines += [_fmt_time(when, revision), _fmt_time(when + dt.timedelta(seconds=0.2), revision), fmt]
    if revision != "1991":
        lines.append("1")
    if revision == "2013":
        lines += ["+8h00,+8h00", "0,0"]
    text = "\r\n".join(lines) + "\r\n"
    enc = "ascii" if station.encoding == "ascii" else station.encoding
    path.write_bytes(text.encode(enc))
    times = _sample_times(ends)
    dat = path.with_suffix(".dat")
    if fmt == "ASCII":
        rows = []
        for j in range(n):
            vals = ",".join(str(int(raw[j])) for raw in raws)
            rows.append(f"{j + 1},{round(times[j] * 1e6)},{vals}")
        dat.write_text("\r\n".join(rows) + "\r\n", encoding="ascii")
    else:
        kind = {"BINARY": "<i2", "BINARY32": "<i4", "FLOAT32": "<f4"}[fmt]
        rec = np.zeros(n, dtype=[("n", "<i4"), ("t", "<i4"), ("x", kind, (len(raws),))])
        rec["n"] = np.arange(1, n + 1)
        rec["t"] = np.round(times * 1e6).astype(np.int64)
        rec["x"] = np.stack(raws, axis=1)
        dat.write_bytes(rec.tobytes())


def _sample_times(ends) -> np.ndarray:
    out, t, last = [], 0.0, 0
    for r, e in ends:
        for _ in range(e - last):
            out.append(t)
            t += 1.0 / r
        last = e
    return np.array(out)


FORMS = (("1999", "ASCII"), ("1991", "ASCII"), ("2013", "BINARY"), ("1999", "BINARY"),
         ("2013", "BINARY32"), ("2013", "FLOAT32"))  # fmt: skip


def write_archive(root, *, records=4, seed=0, specials=True, year=2025, noise_sd=0.03):
    """Write ``records`` records per station (and the special files); return the truth.

    Returns
    -------
    pandas.DataFrame
        One row per record and bay: ``station, bay, file, time, day, f_m, f_m_mean,
        depth``; then the special files with ``special`` set (``no-dip``, ``bad-cfg``,
        ``short-dat``, ``no-dat``).
    """
    import pandas as pd

    root = Path(root)
    rng = np.random.default_rng(seed)
    rows = []
    n_total = 0
    for si, st in enumerate(STATIONS):
        folder = root / f"station{si + 1}"
        folder.mkdir(parents=True, exist_ok=True)
        days = np.sort(rng.uniform(0, 365, records))
        for k, day in enumerate(days):
            when = dt.datetime(year, 1, 1) + dt.timedelta(days=float(day))
            when = when.replace(microsecond=0)
            depth = float(rng.uniform(0.05, 0.3))
            dur = float(rng.uniform(0.08, 0.15))
            t_f = 0.2 + float(rng.uniform(0, 0.02))
            t = np.arange(int(1.1 * RATE)) / RATE
            edges = [t_f, t_f + dur]
            prof = lambda x, a=t_f, b=t_f + dur, d=depth: 1.0 - d if a <= x < b else 1.0  # noqa: E731
            s_bays, shares = [], []
            for b in range(len(st.bays)):
                f_mean = motor_share(st, b, day)
                f = float(np.clip(f_mean + noise_sd * rng.standard_normal(), 0.02, 0.95))
                s, vt = simulate_bay(t, prof, edges, f)
                s_bays.append(s)
                shares.append((f, f_mean))
            v, cur = _waves(t, vt, s_bays, st.mva, rng)
            revision, fmt = FORMS[n_total % len(FORMS)]
            n_total += 1
            name = folder / f"{when:%Y%m%d_%H%M%S}_{k:03d}.cfg"
            write_record(name, st, when, v, cur, revision=revision, fmt=fmt)
            for b, (f, f_mean) in enumerate(shares):
                rows.append({"station": st.name, "bay": st.bays[b], "file": str(name),
                             "time": when + dt.timedelta(seconds=t_f), "day": day, "f_m": f,
                             "f_m_mean": f_mean, "depth": depth, "revision": revision,
                             "format": fmt, "special": ""})  # fmt: skip
    if specials:
        rows += _specials(root, rng, year)
    return pd.DataFrame(rows)


def _specials(root: Path, rng, year) -> list[dict]:
    st = STATIONS[1]
    folder = root / "special"
    folder.mkdir(parents=True, exist_ok=True)
    two = ((2 * RATE, 240), (RATE, 240 + int(0.5 * RATE)))
    t = _sample_times(two)
    flat = lambda x: 1.0  # noqa: E731
    s_bays = [simulate_bay(t, flat, [], 0.3)[0] for _ in st.bays]
    v, cur = _waves(t, np.ones(t.size), s_bays, st.mva, rng)
    when = dt.datetime(year, 6, 1, 12)
    out = []
    # No dip: a record the recorder wrote for another reason (a manual trigger).
    write_record(folder / "no_dip.cfg", st, when, v, cur, rates=two)
    out.append({"station": st.name, "file": str(folder / "no_dip.cfg"), "special": "no-dip"})
    # A malformed .cfg: a channel count that disagrees with its channel lines.
    write_record(folder / "bad_cfg.cfg", st, when, v, cur)
    text = (folder / "bad_cfg.cfg").read_bytes().split(b"\r\n")
    text[1] = b"7,7A,0D"
    (folder / "bad_cfg.cfg").write_bytes(b"\r\n".join(text))
    out.append({"station": st.name, "file": str(folder / "bad_cfg.cfg"), "special": "bad-cfg"})
    # A binary .dat cut short (a recorder that lost power while writing).
    write_record(folder / "short_dat.cfg", st, when, v, cur, fmt="BINARY")
    dat = folder / "short_dat.dat"
    dat.write_bytes(dat.read_bytes()[: len(dat.read_bytes()) // 2])
    out.append({"station": st.name, "file": str(folder / "short_dat.cfg"), "special": "short-dat"})
    # A .cfg whose .dat was never copied.
    write_record(folder / "no_dat.cfg", st, when, v, cur)
    (folder / "no_dat.dat").unlink()
    out.append({"station": st.name, "file": str(folder / "no_dat.cfg"), "special": "no-dat"})
    return out
