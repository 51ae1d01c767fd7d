"""A disturbance record's table on disk: the columns, a metadata sidecar, its events.

``loadbayes read comtrade`` writes every column of
:class:`~loadbayes.recordings.record.RecordTable` to CSV or Parquet, and what was decided
reading it (station, channels, record start and trigger times, encoding, which clock was
trusted, whether the amplitude segments held peak or RMS values, bases, ``per_cycle``) to
a sidecar JSON beside it, ``<table>.meta.json``. A sidecar rather than Parquet schema
metadata: the same for CSV and Parquet, and readable without a Parquet library.

``loadbayes events`` on such a table (:func:`record_events`) cuts one event per waveform
segment's sag, never across the gap between two of a recorder's waveform windows
(:func:`~loadbayes.recordings.record.sags_by_segment` on the phasor rows), and carries
the metadata to each event's row of the event index: station, bay, channels and the
absolute time of the event's first sample.
"""

from __future__ import annotations

import datetime as dt
import json
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from loadbayes.io.errors import DataError

__all__ = [
    "META_SUFFIX",
    "RecordEvents",
    "meta_path",
    "read_record_meta",
    "record_events",
    "record_metadata",
    "write_record",
]

#: Suffix of the metadata sidecar, appended to the table's name.
META_SUFFIX = ".meta.json"
#: The sidecar's ``format`` key.
FORMAT = "loadbayes record table 1"
#: Columns of the phasor rows an event file keeps (``kind`` is "phasor" in all of them).
EVENT_COLUMNS = (
    "t_s", "v", "angle_rad", "p", "q", "f", "p_total", "q_total", "v2", "i2",
    "unbalanced", "residual", "straddle", "dc_filtered", "va", "vb", "vc", "ia", "ib", "ic",
    "segment", "v2_re", "v2_im", "i2_re", "i2_im",
)  # fmt: skip


def meta_path(table: str | os.PathLike[str]) -> Path:
    """The sidecar of a record table: ``xtz.parquet`` -> ``xtz.parquet.meta.json``."""
    return Path(os.fspath(table) + META_SUFFIX)


def comtrade_time(stamp: str, *, month_first: bool = False) -> dt.datetime | None:
    """A ``.cfg`` time stamp ``dd/mm/yyyy,hh:mm:ss.ffffff`` as a datetime (None if blank).

    COMTRADE 1999 and later write the day first; 1991 the month (``month_first``, as the
    ``comtrade`` package reads it); a two-digit year is 19xx/20xx. The recorder's clock
    has no zone in the file: the datetime is naive.
    """
    if not stamp or "," not in stamp:
        return None
    date, time = stamp.split(",", 1)
    if not date or not time:
        return None
    try:
        d, m, y = (int(x) for x in date.split("/"))
        if month_first:
            d, m = m, d
        if y < 100:
            y += 2000 if y < 70 else 1900
        hh, mm, ss = time.split(":")
        sec = float(ss)
        whole = int(sec)
        return dt.datetime(y, m, d, int(hh), int(mm), whole) + dt.timedelta(
            microseconds=round((sec - whole) * 1e6)
        )
    except ValueError:
        return None


def record_metadata(
    w, rec, *, source: str, per_cycle: int, dc: str, side: str, bay: str | None = None
) -> dict:
    """What the sidecar holds, from the waveforms read and the table made of them."""
    start = comtrade_time(w.start)
    trigger = comtrade_time(w.trigger)
    segs = []
    t = np.asarray(rec.columns["t_s"])
    seg_col = np.asarray(rec.columns["segment"])
    for k, s in enumerate(w.segments):
        rows = np.flatnonzero(seg_col == k)
        segs.append(
            {
                "segment": k,
                "kind": s.kind,
                "samples": [s.start + 1, s.stop],
                "rate_hz": s.rate_hz,
                "rows": int(rows.size),
                "t_s": [float(w.t_s[s.start]), float(w.t_s[s.stop - 1])],
                "first_row_t_s": float(t[rows[0]]) if rows.size else None,
            }
        )
    return {
        "format": FORMAT,
        "source": os.path.basename(source),
        "station": w.station,
        "encoding": w.encoding,
        "start": w.start,
        "start_iso": start.isoformat() if start else None,
        "trigger": w.trigger,
        "trigger_t_s": (trigger - start).total_seconds() if start and trigger else None,
        "clock": "the recorder's clock, zone not given in the file",
        "f_nominal_hz": w.f_nominal,
        "channels": dict(w.channels),
        "channel_choice": w.choice,
        "side": side,
        "bay": bay,
        "clock_note": w.clock_note,
        "amplitude_note": rec.amplitude,
        "v_base_kv": rec.v_base_kv,
        "s_base_mva": rec.s_base_mva,
        "per_cycle": per_cycle,
        "dc": dc,
        "segments": segs,
        "notes": list(rec.notes),
    }


def write_record(rec, meta: dict, out: str, *, force: bool, outputs=None) -> None:
    """Write the table and its sidecar as one transaction: both files, or neither.

    Each goes to a temporary beside its target (:class:`~loadbayes.io.transaction.OutputSet`)
    and they are renamed together; an error or a signal before that leaves neither, for
    every suffix (``.csv.gz`` too). ``outputs``: an open set with the labels ``"--out"``
    and ``"metadata"`` (a command's ``output_transaction``, which commits it and so knows
    what a signal left); only the temporaries are written then.
    """
    from loadbayes.io.transaction import OutputSet

    text = json.dumps(meta, indent=1, ensure_ascii=False, allow_nan=False) + "\n"
    if outputs is not None:
        _write_temps(rec, text, out, outputs)
        return
    with OutputSet({"--out": out, "metadata": meta_path(out)}, force=force) as files:
        _write_temps(rec, text, out, files)
        files.commit()


def _write_temps(rec, text: str, out: str, files) -> None:
    import shutil
    import tempfile

    from loadbayes.io.tables import write_table

    target = files.temp("--out")
    if out.lower().endswith(".gz"):
        # The temporary's suffix (.tmp.gz) would not say csv.gz: the table is written
        # under its own name in a private folder beside it, then moved onto the temporary.
        folder = tempfile.mkdtemp(dir=target.parent, prefix=f".{Path(out).name}.")
        try:
            inner = Path(folder) / Path(out).name
            write_table(rec.columns, inner, force=True)
            os.replace(inner, target)
        finally:
            shutil.rmtree(folder, ignore_errors=True)
    else:
        write_table(rec.columns, target, force=True)
    files.temp("metadata").write_text(text, encoding="utf-8")


def read_record_meta(table: str | os.PathLike[str]) -> dict | None:
    """The sidecar of a record table, or None when the table has none."""
    side = meta_path(table)
    if not side.is_file():
        return None
    try:
        meta = json.loads(side.read_text(encoding="utf-8"))
    except (OSError, ValueError) as exc:
        raise DataError(f"not a readable record metadata file ({exc})", str(side)) from None
    fmt = meta.get("format") if isinstance(meta, dict) else None
    if fmt != FORMAT:
        said = "no 'format' key" if fmt is None else f"format {str(fmt)[:40]!r}, not {FORMAT!r}"
        raise DataError(f"not a loadbayes record metadata file ({said})", str(side))
    return meta


@dataclass
class RecordEvents:
    """The events of a record table: the phasor rows, the windows and each event's row.

    Parameters
    ----------
    data : dict of str to numpy.ndarray
        The phasor rows (what the event files are cut from).
    windows : list of SagWindow
        One per sag, inside one waveform segment each, numbered in time order.
    extra : list of dict
        Per window, the columns the event index adds: station, bay, absolute start time.
    """

    data: dict
    windows: list
    extra: list


def _read_table(path: str) -> dict[str, np.ndarray]:
    import pandas as pd

    try:
        if str(path).lower().endswith((".parquet", ".pq")):
            df = pd.read_parquet(path)
        else:
            df = pd.read_csv(path)
    except Exception as exc:  # noqa: BLE001 - any reader failure is the file's
        raise DataError(f"cannot be read as a record table ({exc})", str(path)) from None
    missing = [c for c in ("t_s", "v", "p", "q", "kind", "segment") if c not in df.columns]
    if missing:
        raise DataError(f"has a record metadata sidecar but no column {missing[0]!r}", str(path))
    return {c: df[c].to_numpy() for c in df.columns}


def _has_record_columns(path: str) -> bool:
    """Whether a table has a record table's ``kind`` and ``segment`` columns (header only)."""
    try:
        if str(path).lower().endswith((".parquet", ".pq")):
            import pyarrow.parquet as pq

            names = set(pq.read_schema(path).names)
        else:
            import csv
            import gzip

            opener = gzip.open if str(path).lower().endswith(".gz") else open
            with opener(path, "rt", encoding="utf-8", newline="") as fh:
                names = set(next(csv.reader(fh), []))
    except Exception:  # noqa: BLE001 - not readable here: the plain reader will say why
        return False
    return {"kind", "segment"} <= names


def record_events(record: str, *, v_ref: float | None = None, **settings) -> RecordEvents | None:
    """Sags of a ``read comtrade`` table, one window per sag inside a waveform segment.

    Parameters
    ----------
    record : str
        The table; None is returned when it has no sidecar (any other t_s, v, p, q table:
        the caller finds its sags over the whole record).
    v_ref : float, optional
        Reference voltage; by default each segment's median.
    **settings
        :func:`~loadbayes.recordings.events.find_sags`'s keywords (threshold, hysteresis,
        min_duration_s, pre_s, post_s).

    Returns
    -------
    RecordEvents or None

    Raises
    ------
    DataError
        If the table or its sidecar cannot be read, or a phasor row is not finite.
    """
    from loadbayes.recordings.record import phasor_rows, sags_by_segment

    meta = read_record_meta(record)
    if meta is None:
        if not _has_record_columns(record):
            return None
        meta = {}  # the table without its sidecar: no station, bay or start time
    table = _read_table(record)
    cols = phasor_rows(table)
    if not len(cols["t_s"]):  # events are cut from the phasor rows alone
        kinds = np.unique(table["kind"].astype(str), return_counts=True)
        have = ", ".join(f"{n} {k} rows" for k, n in zip(*kinds, strict=True)) or "no rows"
        raise DataError(f"no phasor rows ({have}): no event to cut", record)
    data = {c: np.asarray(cols[c], dtype=float) for c in EVENT_COLUMNS if c in cols}
    for c in ("t_s", "v", "p", "q"):
        bad = np.flatnonzero(~np.isfinite(data[c]))
        if bad.size:
            raise DataError(f"column {c!r}, phasor row {bad[0] + 1}: not a finite number", record)
    seg = data["segment"].astype(np.int64)
    data["segment"] = seg
    for c in ("unbalanced", "straddle"):
        if c in data:
            data[c] = data[c] > 0.5
    for k in np.unique(seg):
        t = data["t_s"][seg == k]
        if t.size > 1 and not np.all(np.diff(t) > 0):
            raise DataError(f"segment {k}: t_s is not increasing", record)
    try:
        windows = sags_by_segment(data, v_ref=v_ref, **settings)
    except ValueError as exc:
        raise DataError(str(exc), record) from None
    stamp = meta.get("start", "")
    if stamp is not None and not isinstance(stamp, str):
        raise DataError(
            f"key 'start' is {stamp!r}, expected the .cfg's time stamp as text "
            "('dd/mm/yyyy,hh:mm:ss.ffffff')",
            str(meta_path(record)),
        )
    start = comtrade_time(stamp or "")
    extra = []
    for ev in windows:
        t0 = float(data["t_s"][ev.start])
        try:
            at = (start + dt.timedelta(seconds=t0)).isoformat() if start else ""
        except OverflowError:
            raise DataError(
                f"phasor row {ev.start + 1}: t_s = {t0:.6g} s after the start "
                f"{stamp} is past the year 9999",
                record,
                "t_s",
            ) from None
        extra.append(
            {
                "station": meta.get("station", ""),
                "bay": meta.get("bay") or "",
                "segment": int(seg[ev.start]),
                "record_t_s": t0,
                "start_time": at,
                "per_cycle": meta.get("per_cycle"),
                "v_base_kv": meta.get("v_base_kv"),
                "s_base_mva": meta.get("s_base_mva"),
                # The record's nominal frequency: `fit composite` takes it from here.
                "f_nominal_hz": meta.get("f_nominal_hz"),
            }
        )
    return RecordEvents(data, windows, extra)
