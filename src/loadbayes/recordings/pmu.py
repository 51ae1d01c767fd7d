"""Read PMU historian CSVs: C37.118 phasors (positive sequence or per phase) to V, P, Q, f.

One idea at about 460 lines, a historian's table into the package's V, P, Q: the column
mapping, the time column in every form historians write (text, epoch in s to ns, zones),
and the checks each row gets.

A column mapping says which CSV column holds what. It comes from a small TOML file
(``--map``), from options, or both (options win)::

    [columns]
    time = "Timestamp"                  # ISO 8601 text, or epoch seconds (time.format)
    v_mag = "V1 Mag"                    # one name (positive sequence) or three (a, b, c)
    v_ang = "V1 Ang"
    i_mag = "I1 Mag"
    i_ang = "I1 Ang"
    freq = "Freq"                       # optional, Hz
    rocof = "ROCOF"                     # optional, Hz/s (kept as a column)

    [units]
    angle = "deg"                       # or "rad"
    voltage = "kV"                      # V or kV, phase-to-neutral RMS magnitudes
    current = "A"                       # A or kA

    [time]
    format = "iso"                      # or "epoch"
    timezone = "UTC"                    # the zone of timestamps written without one

    [base]
    v_kv = 230.0                        # line-to-line kV; omitted: the first sample's V
    s_mva = 100.0                       # three-phase MVA; omitted: the first sample's |S|

Power: positive sequence, ``S = 3 V1 conj(I1)``; per phase, ``S = sum_k V_k conj(I_k)``
(V1 then from the symmetrical-component transform). Timestamps with an offset
(``+02:00``, ``Z``) are honoured; naive ones are read in ``time.timezone``. Rows out of
time order are sorted, duplicate timestamps keep their first row, and both are reported,
as are gaps longer than 1.5 reporting intervals.
"""

from __future__ import annotations

import math
import os
import tomllib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from loadbayes.io.encoding import SNIFF_BYTES, detect_encoding
from loadbayes.io.errors import DataError

__all__ = ["PmuMap", "PmuRecord", "load_map", "read_pmu"]

_A = np.exp(2j * np.pi / 3)
# A time of day followed by a UTC offset or Z: the timestamp carries its zone.
_OFFSET = r"[T ]\d{1,2}:\d{2}(?::\d{2}(?:\.\d+)?)?\s*(?:Z|[+-]\d{2}(?::?\d{2})?)$"
_V_UNITS = {"V": 1.0, "kV": 1e3}
_I_UNITS = {"A": 1.0, "kA": 1e3}


@dataclass
class PmuMap:
    """Which column holds what, and in which units (see the module docstring)."""

    time: str = "timestamp"
    v_mag: list[str] = field(default_factory=lambda: ["v1_mag"])
    v_ang: list[str] = field(default_factory=lambda: ["v1_ang"])
    i_mag: list[str] = field(default_factory=lambda: ["i1_mag"])
    i_ang: list[str] = field(default_factory=lambda: ["i1_ang"])
    freq: str | None = None
    rocof: str | None = None
    angle: str = "deg"
    voltage: str = "V"
    current: str = "A"
    time_format: str = "iso"
    timezone: str = "UTC"
    v_kv: float | None = None
    s_mva: float | None = None

    def check(self, where: str) -> None:
        """Refuse inconsistent settings with a message naming ``where``."""
        counts = {len(self.v_mag), len(self.v_ang), len(self.i_mag), len(self.i_ang)}
        if counts not in ({1}, {3}):
            raise DataError(
                "v_mag, v_ang, i_mag, i_ang must each name 1 column (positive sequence) "
                "or 3 (phases a, b, c)",
                where,
            )
        for key, allowed in (
            ("angle", ("deg", "rad")),
            ("voltage", tuple(_V_UNITS)),
            ("current", tuple(_I_UNITS)),
            ("time_format", ("iso", "epoch")),
        ):
            if getattr(self, key) not in allowed:
                raise DataError(f"{key} must be one of {', '.join(allowed)}", where)
        for key in ("v_kv", "s_mva"):
            val = getattr(self, key)
            if val is not None and not (math.isfinite(val) and val > 0):
                raise DataError(f"base {key} must be a positive number", where)


def _names(value: Any, key: str, where: str) -> list[str]:
    if isinstance(value, str):
        return [s.strip() for s in value.split(",")] if "," in value else [value]
    if isinstance(value, list) and all(isinstance(s, str) for s in value):
        return list(value)
    raise DataError(f"columns.{key} must be a column name or a list of names", where)


def load_map(path: str | os.PathLike[str] | None, **overrides: Any) -> PmuMap:
    """Build a :class:`PmuMap` from a TOML file and option overrides.

    Parameters
    ----------
    path : str or os.PathLike, optional
        The TOML mapping file.
    **overrides
        Fields of :class:`PmuMap` set from the command line (None leaves them).

    Returns
    -------
    PmuMap
        The mapping, checked.

    Raises
    ------
    DataError
        If the file is missing, is not TOML, or has unknown keys or bad values.
    """
    m = PmuMap()
    where = os.fspath(path) if path is not None else "options"
    if path is not None:
        p = Path(path)
        if not p.is_file():
            raise DataError("file not found", where)
        try:
            doc = tomllib.loads(p.read_text(encoding="utf-8"))
        except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
            raise DataError(f"not a valid TOML file: {exc}", where) from None
        known = {"columns", "units", "time", "base"}
        for section in doc:
            if section not in known:
                raise DataError(f"unknown section [{section}] (known: {sorted(known)})", where)
        cols = doc.get("columns", {})
        for key, val in cols.items():
            if key in ("v_mag", "v_ang", "i_mag", "i_ang"):
                setattr(m, key, _names(val, key, where))
            elif key in ("time", "freq", "rocof"):
                setattr(m, key, str(val))
            else:
                raise DataError(f"unknown key columns.{key}", where)
        for key, val in doc.get("units", {}).items():
            if key not in ("angle", "voltage", "current"):
                raise DataError(f"unknown key units.{key}", where)
            setattr(m, key, str(val))
        for key, val in doc.get("time", {}).items():
            if key not in ("format", "timezone"):
                raise DataError(f"unknown key time.{key}", where)
            setattr(m, "time_format" if key == "format" else key, str(val))
        for key, val in doc.get("base", {}).items():
            if key not in ("v_kv", "s_mva") or not isinstance(val, int | float):
                raise DataError(f"base.{key}: expected v_kv or s_mva, a number", where)
            setattr(m, key, float(val))
    for key, val in overrides.items():
        if val is None:
            continue
        if key in ("v_mag", "v_ang", "i_mag", "i_ang"):
            val = _names(val, key, where)
        setattr(m, key, val)
    m.check(where)
    return m


@dataclass
class PmuRecord:
    """A PMU record in per unit, with what was found wrong with its timestamps.

    Parameters
    ----------
    data : dict of str to numpy.ndarray
        ``t_s`` (s from the first sample), ``v``, ``p``, ``q`` (p.u.), ``angle_rad`` (the
        positive-sequence voltage angle, unwrapped), and ``f`` (Hz)
        and ``rocof`` (Hz/s) when mapped.
    start : str
        First timestamp, ISO 8601 in UTC.
    v_base_kv, s_base_mva : float
        The bases used.
    report : list of str
        Duplicates, out-of-order rows and gaps found.
    """

    data: dict[str, np.ndarray]
    start: str
    v_base_kv: float
    s_base_mva: float
    report: list[str]


def _numeric(df, col: str, name: str) -> np.ndarray:
    import pandas as pd

    raw = df[col]
    if df.attrs.get("decimal") == ",":  # a ';'-separated file writes 1,5 for 1.5
        raw = raw.str.replace(",", ".", regex=False)
    vals = pd.to_numeric(raw, errors="coerce").to_numpy(dtype=float)
    bad = np.flatnonzero(~np.isfinite(vals))
    if bad.size:
        cell = str(raw.iloc[bad[0]])[:20]
        raise DataError(f"not a finite number: {cell!r}", name, col, int(bad[0]) + 1)
    return vals


def _times(df, m: PmuMap, name: str) -> np.ndarray:
    import pandas as pd

    raw = df[m.time]
    if m.time_format == "epoch":
        return _epoch(_numeric(df, m.time, name), df.attrs, name, m.time)
    text = raw.astype(str).str.strip()
    # ISO 8601 allows a comma before the fraction of a second (14:00:00,033), as
    # historians set to a European locale write it; pandas reads only the point.
    text = text.str.replace(r"(\d{2}:\d{2}:\d{2}),(\d)", r"\1.\2", regex=True)
    leap = text.str.contains(r"[T ]\d{2}:\d{2}:60", regex=True).to_numpy()
    if leap.any():
        k = int(np.flatnonzero(leap)[0])
        raise DataError(
            f"{text.iloc[k][:40]!r} is a leap second (:60): UTC time as computers count it "
            "(POSIX, and so this reader) has no such second; write that second's reports "
            "as the PMU's leap-second flag says (C37.118: repeat 23:59:59 or skip them)",
            name, m.time, k + 1,
        )  # fmt: skip
    if not aware_only(text) and m.timezone:
        _check_zone(m.timezone, name, m.time)
    # Timestamps with an offset (Z, +02:00) go straight to UTC; those without are read in
    # the mapping's zone. Parsed apart: pandas refuses (or warns on) a mix of the two.
    aware = text.str.contains(_OFFSET, regex=True).to_numpy()
    out = np.zeros(len(text), dtype="int64")
    bad = np.zeros(len(text), dtype=bool)
    for part in (aware, ~aware):
        if not part.any():
            continue
        ts = pd.to_datetime(text[part], errors="coerce", utc=part is aware, format="ISO8601")
        bad[part] = ts.isna().to_numpy()
        if part is not aware:
            ts = _localize(ts, part, m.timezone, name, m.time)
        utc = ts.dt.tz_convert("UTC").dt.tz_localize(None)
        out[part] = utc.to_numpy(dtype="datetime64[ns]").astype("int64")
    if bad.any():
        k = int(np.flatnonzero(bad)[0])
        raise DataError(f"not an ISO 8601 timestamp: {text.iloc[k][:40]!r}", name, m.time, k + 1)
    return out


def aware_only(text) -> bool:
    """Whether every timestamp carries its own offset (then the zone is not used)."""
    return bool(text.str.contains(_OFFSET, regex=True).all())


def _check_zone(zone: str, name: str, col: str) -> None:
    import zoneinfo

    try:
        zoneinfo.ZoneInfo(zone)
    except (zoneinfo.ZoneInfoNotFoundError, ValueError):
        raise DataError(
            f"unknown time zone {zone[:40]!r} (expected an IANA name such as Europe/Berlin "
            "or America/New_York)",
            name,
            col,
        ) from None


def _localize(ts, part, zone: str, name: str, col: str):
    """Naive local times to zone-aware ones; a DST-ambiguous or missing hour named by row."""
    import pandas as pd

    local = ts.dt.tz_localize(zone, ambiguous="NaT", nonexistent="NaT")
    lost = (local.isna() & ts.notna()).to_numpy()
    if lost.any():
        j = int(np.flatnonzero(lost)[0])
        row = int(np.flatnonzero(np.asarray(part))[j]) + 1
        value = ts.iloc[j]
        try:
            pd.Series([value]).dt.tz_localize(zone, ambiguous=True, nonexistent="raise")
            what = "happens twice (the hour the clocks go back)"
        except Exception:  # noqa: BLE001 - any failure here is the missing hour
            what = "does not exist (the hour the clocks go forward)"
        raise DataError(
            f"local time {str(value)!r} {what} in {zone}: write the timestamps with an "
            "offset or in UTC",
            name, col, row,
        )  # fmt: skip
    return local


#: Epoch magnitudes (of the median value) that tell the unit, largest first.
_EPOCH_UNITS = ((1e17, 1, "nanoseconds"), (1e14, 1_000, "microseconds"),
                (1e11, 1_000_000, "milliseconds"))  # fmt: skip
#: Largest epoch accepted, in seconds (year 2286; beyond it int64 nanoseconds overflow).
_EPOCH_MAX_S = 1e10


def _epoch(vals: np.ndarray, attrs: dict, name: str, col: str) -> np.ndarray:
    """Epoch values to int64 nanoseconds: the unit told by the median, each row checked.

    Historians write seconds, milliseconds, microseconds or nanoseconds since 1970; a
    present-day time is about 1.7e9 s, 1.7e12 ms, 1.7e15 us or 1.7e18 ns, so the median
    tells the unit. A value out of range is refused by row, not wrapped around int64.
    """
    ns_per, unit = 1_000_000_000, "seconds"
    med = float(np.median(np.abs(vals)))
    for limit, factor, label in _EPOCH_UNITS:
        if med >= limit:
            ns_per, unit = factor, label
            break
    secs = vals * (ns_per / 1e9)
    bad = np.flatnonzero(~(np.abs(secs) <= _EPOCH_MAX_S))
    if bad.size:
        raise DataError(
            f"epoch {vals[bad[0]]:.6g} is out of range (the column reads as {unit} since "
            "1970, and this is beyond the year 2286)",
            name, col, int(bad[0]) + 1,
        )  # fmt: skip
    if unit != "seconds":
        attrs["epoch_note"] = f"epoch times read as {unit} (median value {med:.4g})"
    # Whole units and the fraction apart, in the file's own unit: nanoseconds of 1.7e9 s
    # exceed float64's 15-16 digits.
    whole = np.floor(vals)
    frac = np.round((vals - whole) * ns_per).astype("int64")
    return whole.astype("int64") * ns_per + frac


def _separator(path: Path) -> tuple[str, str]:
    """',' or ';' (then ',' is the decimal mark), from the header line."""
    with open(path, "rb") as fh:
        head = fh.readline(1 << 16)
    if b";" in head and b"," not in head:
        return ";", ","
    return ",", "."


def _bad_row(head: bytes) -> int | None:
    """The data row (1-based, after the header) of the first byte that is not UTF-8."""
    try:
        head.decode("utf-8")
    except UnicodeDecodeError as exc:
        line = head[: exc.start].count(b"\n")
        return line if line >= 1 else None
    return None


def _not_utf8(head: bytes) -> str:
    if _bad_row(head) is None and b"\n" in head:
        try:
            head.split(b"\n", 1)[1].decode("utf-8")
        except UnicodeDecodeError:
            pass
        else:
            return "header is not UTF-8 text (saved in another encoding?): save it as UTF-8"
    return "not UTF-8 text (saved in another encoding?): save it as UTF-8"


def read_pmu(path: str | os.PathLike[str], mapping: PmuMap) -> PmuRecord:
    """Read a PMU phasor CSV into per-unit ``t_s, v, angle_rad, p, q[, f, rocof]``.

    Per-phase phasors add the negative sequence ``v2_re, v2_im, i2_re, i2_im`` (per
    unit, in the frame of ``angle_rad``; docs/formats.md).

    Parameters
    ----------
    path : str or os.PathLike
        The CSV file.
    mapping : PmuMap
        Column mapping and units (:func:`load_map`).

    Returns
    -------
    PmuRecord
        The record, sorted by time, duplicates removed, and the report of what was done.

    Raises
    ------
    DataError
        Naming the file, column and row: a missing column, a non-numeric cell, an
        unreadable timestamp, fewer than two distinct timestamps.
    """
    import pandas as pd

    name = os.fspath(path)
    p = Path(path)
    if not p.is_file():
        raise DataError("file not found", name)
    sep, decimal = _separator(p)
    with open(p, "rb") as fh:
        head = fh.read(SNIFF_BYTES)
    # A historian export in the Chinese code page (column names in GB18030) is read as
    # such; other bytes that are not UTF-8 are refused below.
    found = detect_encoding(head, complete=len(head) < SNIFF_BYTES)
    encoding = "gb18030" if found == "gb18030" else "utf-8-sig"
    try:
        df = pd.read_csv(
            p,
            dtype=str,
            keep_default_na=False,
            skipinitialspace=True,
            sep=sep,
            encoding=encoding,
        )
    except pd.errors.ParserError as exc:
        import re

        msg = str(exc).splitlines()[0]
        got = re.search(r"Expected (\d+) fields in line (\d+), saw (\d+)", msg)
        if got:
            want, line, saw = (int(x) for x in got.groups())
            raise DataError(
                f"{saw} fields, expected {want} (as in the header)", name, row=line - 1
            ) from None
        raise DataError(f"cannot be read as CSV: {msg}", name) from None
    except UnicodeDecodeError:
        raise DataError(_not_utf8(head), name, row=_bad_row(head)) from None
    except pd.errors.EmptyDataError as exc:
        raise DataError(f"cannot be read as CSV: {str(exc).splitlines()[0]}", name) from None
    df.attrs["decimal"] = decimal
    m = mapping
    wanted = [m.time, *m.v_mag, *m.v_ang, *m.i_mag, *m.i_ang]
    wanted += [c for c in (m.freq, m.rocof) if c]
    missing = [c for c in wanted if c not in df.columns]
    if missing:
        raise DataError(
            f"no column {missing[0]!r} (columns: {', '.join(map(str, df.columns))})", name
        )
    if len(df) < 2:
        raise DataError("fewer than two data rows", name)
    t_ns = _times(df, m, name)
    ang = 1.0 if m.angle == "rad" else np.pi / 180

    def phasors(mags, angs, scale):
        return np.vstack(
            [
                _numeric(df, a, name) * scale * np.exp(1j * ang * _numeric(df, b, name))
                for a, b in zip(mags, angs, strict=True)
            ]
        )

    for col in [*m.v_mag, *m.i_mag]:
        neg = np.flatnonzero(_numeric(df, col, name) < 0)
        if neg.size:
            raise DataError(
                "a phasor magnitude cannot be negative (it would turn P and Q over)",
                name, col, int(neg[0]) + 1,
            )  # fmt: skip
    vph = phasors(m.v_mag, m.v_ang, _V_UNITS[m.voltage])
    iph = phasors(m.i_mag, m.i_ang, _I_UNITS[m.current])
    seq = {}  # the negative sequence, when the phases are given
    if vph.shape[0] == 1:
        v1, s = vph[0], 3 * vph[0] * np.conj(iph[0])
    else:
        v1 = (vph[0] + _A * vph[1] + _A**2 * vph[2]) / 3
        s = np.sum(vph * np.conj(iph), axis=0)
        seq = {"v2": (vph[0] + _A**2 * vph[1] + _A * vph[2]) / 3}
        seq["i2"] = (iph[0] + _A**2 * iph[1] + _A * iph[2]) / 3
    extra = {}
    if m.freq:
        extra["f"] = _numeric(df, m.freq, name)
    if m.rocof:
        extra["rocof"] = _numeric(df, m.rocof, name)

    report = [df.attrs["epoch_note"]] if "epoch_note" in df.attrs else []
    order = np.argsort(t_ns, kind="stable")
    if np.any(order != np.arange(order.size)):
        n_out = int(np.sum(np.diff(t_ns) < 0))
        report.append(f"{n_out} rows out of time order (sorted)")
    t_sorted = t_ns[order]
    dup = np.concatenate([[False], np.diff(t_sorted) == 0])
    if dup.any():
        rows = sorted(int(order[k]) + 1 for k in np.flatnonzero(dup))
        shown = ", ".join(map(str, rows[:5])) + (" ..." if len(rows) > 5 else "")
        report.append(f"{len(rows)} duplicate timestamps (rows {shown}); first row kept")
    keep = order[~dup]
    if keep.size < 2:
        raise DataError("fewer than two distinct timestamps", name, m.time)
    t_ns = t_ns[keep]
    dt = np.diff(t_ns) / 1e9
    step = float(np.median(dt))
    gaps = np.flatnonzero(dt > 1.5 * step)
    if gaps.size:
        big = int(gaps[np.argmax(dt[gaps])])
        missing_n = int(np.sum(np.round(dt[gaps] / step) - 1))
        report.append(
            f"{gaps.size} gaps in time ({missing_n} reports missing at {1 / step:.4g}/s); "
            f"longest {dt[big]:.4g} s after row {int(keep[big]) + 1}"
        )
    v1, s = v1[keep], s[keep]
    extra = {k: val[keep] for k, val in extra.items()}
    seq = {k: val[keep] for k, val in seq.items()}
    v_base = m.v_kv * 1e3 / math.sqrt(3) if m.v_kv else float(np.abs(v1[0]))
    s_base = m.s_mva * 1e6 if m.s_mva else float(np.abs(s[0]))
    if not (v_base > 0 and s_base > 0):
        what = "voltage" if not v_base > 0 else "power (the current is 0)"
        raise DataError(f"first sample has zero {what}; give the bases", name)
    if not np.any(s):
        # Read as asked (the voltage may be all one wants), but a fit of it has no load.
        report.append(
            f"the current ({', '.join(m.i_mag)}) is 0 in every row: P and Q are 0 (an open "
            "breaker, or a channel not recorded?); no load model can be fitted to them"
        )
    data = {
        "t_s": (t_ns - t_ns[0]) / 1e9,
        "v": np.abs(v1) / v_base,
        # A PMU's angle is referred to a UTC-locked cosine at the nominal frequency: the
        # frame the composite fit wants (it keeps a fault's phase jumps, f cannot).
        "angle_rad": np.unwrap(np.angle(v1)),
        "p": s.real / s_base,
        "q": s.imag / s_base,
        **extra,
    }
    if seq:  # V2 per unit of the phase base, I2 of s_base / (3 v_base): docs/formats.md
        i_base = s_base / (3.0 * v_base)
        for key, z, base in (("v2", seq["v2"], v_base), ("i2", seq["i2"], i_base)):
            data[f"{key}_re"], data[f"{key}_im"] = z.real / base, z.imag / base
    start = str(np.datetime64(int(t_ns[0]), "ns")) + "Z"
    return PmuRecord(data, start, v_base * math.sqrt(3) / 1e3, s_base / 1e6, report)
