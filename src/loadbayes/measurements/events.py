"""Read recorded disturbance events (t, V, P, Q [, f or angle] [, event]) and check them.

One idea needs these 462 lines: event files read into checked recordings (and their
index's bases and frequency), each check naming the file, the column and the row.
One file is one event, or several when it has an event column. Bad input raises
:class:`~loadbayes.io.errors.DataError` naming the file, the column and the row: a time
that does not increase, a gap in the sampling, an event too short for the motor's time
constants, a voltage that never changes, too few samples.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from loadbayes.io.cells import DROP_HINT
from loadbayes.io.errors import DataError
from loadbayes.measurements.record import SEQUENCE_COLUMNS, EventRecord, sequence_phasors
from loadbayes.measurements.units import F_OFF

__all__ = [
    "index_bases",
    "index_f_hz",
    "MIN_DV",
    "MIN_SAMPLES",
    "MIN_SHORT_SPAN_S",
    "MIN_SPAN_S",
    "MAX_GAP",
    "STEADY_DV",
    "STEADY_SAMPLES",
    "events_from_arrays",
    "read_events",
    "refuse_repeats",
]

#: An event this long (s) is taken as it is: about twice the typical motor's T' (0.5 s),
#: so that the flux transient is seen settling.
MIN_SPAN_S = 1.0
#: Shortest event (s) of all. A fault recorder keeps waveforms for only 0.2-0.5 s around
#: each fault; such a window (from MIN_SHORT_SPAN_S up to MIN_SPAN_S) is accepted when it
#: starts in steady state (the motor is initialised there) and the voltage moves. It
#: tells the motor's share and X' (the first cycles after a step), T' and H perhaps not
#: (``fit/composite/identifiability.py`` says so in the fit's report).
MIN_SHORT_SPAN_S = 0.2
#: A short event starts in steady state when its voltage stays within this fraction of
#: the first sample for its first STEADY_SAMPLES samples and one nominal cycle.
STEADY_DV = 0.005
STEADY_SAMPLES = 3
#: Fewest samples per event.
MIN_SAMPLES = 20
#: Smallest voltage excursion (max - min, as a fraction of the first sample's voltage):
#: below it the motor's response is lost in the noise and nothing dynamic is identified.
MIN_DV = 0.01
#: A sampling interval larger than this multiple of the median interval is a gap.
MAX_GAP = 2.5
#: Longest median sampling interval (s): at 2 samples/s the motor's transients (T' of
#: 0.05-1 s, the first cycles after a step) fall between samples. Times in milliseconds
#: read as seconds (16.7 for 60 samples/s) land far above it.
MAX_STEP_S = 0.5
#: Longest event (s): a disturbance and the load's recovery last seconds, not hours; a
#: longer span is a unit error (2 s at 1 kHz in ms spans 2,000) or a whole day's
#: record, whose motor response the fit would integrate at great cost for nothing.
MAX_EVENT_S = 600.0
#: The record's own frequency (median of f, or from the angle's drift) this far off the
#: nominal is another system's frequency (50 Hz data at --f-hz 60 is 17% off), not a
#: disturbance: refused, since the motor's time base would be wrong. The bound of
#: ``fit exp``'s frequency check too (one number for both).
MAX_F_OFF = F_OFF
#: A value further than this from its column's median (in units of the median's size,
#: at least 1) is a corrupt cell, not a measurement (it made the fit's linear algebra
#: singular, with no location).
MAX_OUTLIER = 1e6
#: The remedy for an invalid cell in an event: no reader of events drops rows (an event's
#: samples are read whole), so ``--drop-invalid`` is not one.
NO_DROP = " (every row is read: fill the cell or delete the row)"


def events_from_arrays(
    cols: dict[str, np.ndarray],
    rows: np.ndarray,
    *,
    path: str,
    names: dict[str, str],
    f_hz: float = 60.0,
) -> list[EventRecord]:
    """Split and check in-memory columns ``t, v, p, q`` [``f``, ``angle``, ``event``].

    Parameters
    ----------
    cols : dict of str to ndarray
        Per-unit columns keyed ``t, v, p, q`` and optionally ``f`` (Hz), ``angle`` (rad),
        ``event`` (numbers or text: one event per distinct value, in order of
        appearance), ``v2`` and ``i2`` (complex negative-sequence phasors, per unit:
        :func:`~loadbayes.measurements.record.sequence_phasors`).
    rows : ndarray of int
        The 1-based data row of each sample in the file (for error messages).
    path : str
        The file, for error messages.
    names : dict of str to str
        The user's column names for ``t, v, p, q, f, angle, event``.
    f_hz : float
        Nominal frequency: the frame an ``f`` column's angle is integrated against.

    Returns
    -------
    list of EventRecord
    """
    if "t" not in cols:
        raise DataError("missing column (the event's sample times in seconds)", path, names["t"])
    if "event" in cols:
        ids, first = np.unique(cols["event"], return_index=True)
        order = ids[np.argsort(first)]
        groups = [(f"{path}[event={_fmt(i)}]", cols["event"] == i) for i in order]
    else:
        groups = [(path, np.ones(rows.size, dtype=bool))]
    out = []
    for label, mask in groups:
        sub = {k: v[mask] for k, v in cols.items()}
        out.append(_check(sub, rows[mask], path=path, label=label, names=names, f_hz=f_hz))
    return out


def _in(label: str, path: str) -> str:
    """Say ' in f.csv[event=2]' for one event of several, '' for a file's only one.

    The message already starts with the file.
    """
    return "" if label == path else f" in {label}"


def _fmt(x: float | str) -> str:
    if isinstance(x, str):
        return x
    return str(int(x)) if float(x).is_integer() else f"{x:g}"


def _check(cols, rows, *, path, label, names, f_hz) -> EventRecord:
    t, v = cols["t"], cols["v"]
    where = _in(label, path)
    if t.size < MIN_SAMPLES:
        raise DataError(
            f"only {t.size} sample{'s' * (t.size != 1)}{_in(label, path)}; an event needs "
            f"at least {MIN_SAMPLES}",
            path,
            names["t"],
            int(rows[-1]) if rows.size else None,
        )
    dt = np.diff(t)
    bad = np.flatnonzero(~(dt > 0))
    if bad.size:
        k = int(bad[0]) + 1
        raise DataError(
            f"time does not increase (t = {t[k]:g} s after {t[k - 1]:g} s)"
            + ("" if label == path else f" in {label}"),
            path,
            names["t"],
            int(rows[k]),
        )
    step = float(np.median(dt))
    gaps = np.flatnonzero(dt > MAX_GAP * step)
    if gaps.size:
        k = int(gaps[0]) + 1
        raise DataError(
            f"gap of {dt[k - 1]:g} s in the sampling (median interval {step:g} s); split the "
            "record into events at the gap, or fill it",
            path,
            names["t"],
            int(rows[k]),
        )
    span = float(t[-1] - t[0])
    if step > MAX_STEP_S or span > MAX_EVENT_S:
        what = (
            f"samples {step:.4g} s apart (median)"
            if step > MAX_STEP_S
            else f"an event that lasts {span:g} s"
        )
        raise DataError(
            f"{what}{_in(label, path)}: a disturbance record samples faster than "
            f"{1 / MAX_STEP_S:g}/s and lasts under {MAX_EVENT_S:g} s; is the time in "
            "milliseconds (give seconds), or a long record (cut its sags with "
            "loadbayes events)?",
            path,
            names["t"],
            int(rows[-1]) if span > MAX_EVENT_S else None,
        )
    if span < MIN_SHORT_SPAN_S:
        raise DataError(
            f"the event{_in(label, path)} lasts {span:g} s, shorter than the motor's time "
            "constants "
            f"(at least {MIN_SHORT_SPAN_S:g} s that start in steady state, or "
            f"{MIN_SPAN_S:g} s, is needed)",
            path,
            names["t"],
            int(rows[-1]),
        )
    for key in ("v", "p", "q"):
        x = cols[key]
        med = float(np.median(x))
        far = np.flatnonzero(np.abs(x - med) > MAX_OUTLIER * max(abs(med), 1.0))
        if far.size:
            k = int(far[0])
            raise DataError(
                f"value {x[k]:g} is not a measurement (the column's median is {med:.4g})",
                path,
                names[key],
                int(rows[k]),
            )
    v0 = float(v[0])
    if span < MIN_SPAN_S:
        _check_steady_start(t, v, rows, where=where, path=path, col=names["v"], f_hz=f_hz)
    dv = float(np.max(v) - np.min(v)) / v0
    if dv < MIN_DV:
        raise DataError(
            f"the voltage{_in(label, path)} never changes by more than {100 * MIN_DV:g}% "
            f"(range {100 * dv:.3g}%): there is no disturbance to identify the motor from",
            path,
            names["v"],
            int(rows[int(np.argmax(np.abs(v - v0)))]),
        )
    _check_frequency(cols, rows, dt, path=path, label=label, names=names, f_hz=f_hz)
    delta, source = None, ""
    if "angle" in cols:
        delta, source = np.unwrap(cols["angle"]), "angle"
    elif "f" in cols:
        source = "frequency"
        f = cols["f"]
        if not np.all(np.abs(f / f_hz - 1) < 0.2):
            k = int(np.flatnonzero(~(np.abs(f / f_hz - 1) < 0.2))[0])
            raise DataError(
                f"frequency {f[k]:g} Hz is more than 20% off the nominal {f_hz:g} Hz "
                "(is the column in Hz, and --f-hz right?)",
                path,
                names["f"],
                int(rows[k]),
            )
        # The voltage angle in the frame rotating at f_hz: the integral of 2 pi (f - f_hz).
        w = 2 * math.pi * (f - f_hz)
        delta = np.concatenate([[0.0], np.cumsum(0.5 * (w[1:] + w[:-1]) * dt)])
    return EventRecord(
        t - t[0], v, cols["p"], cols["q"], delta, label, source, cols.get("v2"), cols.get("i2")
    )


def _check_steady_start(t, v, rows, *, where, path, col, f_hz) -> None:
    # A short window is fitted from the motor's steady state at its first sample: the
    # voltage must not have moved yet (a window cut inside the fault has no such state).
    moved = np.flatnonzero(np.abs(v / v[0] - 1.0) > STEADY_DV)
    k = int(moved[0]) if moved.size else t.size
    if k < STEADY_SAMPLES or t[k - 1] - t[0] < 1.0 / f_hz:
        raise DataError(
            f"the event{where} lasts {t[-1] - t[0]:g} s, under {MIN_SPAN_S:g} s, and its "
            f"voltage moves by more than {100 * STEADY_DV:g}% at t = {t[k] - t[0]:g} s, "
            f"before {STEADY_SAMPLES} samples and one cycle of steady state: a short event "
            "must start in steady state (cut it earlier, before the disturbance)",
            path,
            col,
            int(rows[k]),
        )


def _check_frequency(cols, rows, dt, *, path, label, names, f_hz) -> None:
    # The record's own frequency against the nominal: the f column's median, else the
    # angle's drift (an angle in a frame turning at f_hz drifts by 2 pi (f - f_hz) rad/s).
    where = "" if label == path else f" in {label}"
    if "f" in cols:
        f = float(np.median(cols["f"]))
        column, how = names["f"], "its median"
    elif "angle" in cols:
        slope = np.diff(np.unwrap(cols["angle"])) / dt
        f = f_hz + float(np.median(slope)) / (2 * math.pi)
        column, how = names["angle"], "from the angle's drift"
    else:
        return
    if abs(f / f_hz - 1) > MAX_F_OFF:
        raise DataError(
            f"the record's frequency is about {f:.4g} Hz ({how}){where}, not the nominal "
            f"{f_hz:g} Hz: fit composite --f-hz {round(f):g} (f_hz={round(f):g}) if the "
            f"system runs at {round(f):g} Hz",
            path,
            column,
        )


def read_events(
    paths: Sequence[str],
    *,
    t_col: str = "t_s",
    v_col: str = "v",
    p_col: str = "p",
    q_col: str = "q",
    f_col: str | None = None,
    angle_col: str | None = None,
    event_col: str = "event",
    v_base: float | None = None,
    s_base: float | None = None,
    f_hz: float = 60.0,
) -> list[EventRecord]:
    """Read every file's events (CSV or Parquet; columns as named, per unit after bases).

    ``f_col`` and ``angle_col`` default to ``f`` and ``angle_rad`` when present (the angle
    wins when both are); ``event_col`` is used when present; ``v2_re, v2_im, i2_re,
    i2_im`` (all four) give each event its negative sequence
    (:func:`~loadbayes.measurements.record.sequence_phasors`).
    """
    from loadbayes.measurements.columns import read_power_columns
    from loadbayes.measurements.times import parse_times, read_text_column

    out: list[EventRecord] = []
    for path in paths:
        extra = tuple(c for c in (f_col or "f", angle_col or "angle_rad", event_col) if c)
        extra += SEQUENCE_COLUMNS
        # Times as ISO timestamps and event ids as text ('sag1') are read as text, the
        # rest as numbers; first as numbers, the common case, read once.
        as_text: set[str] = set()
        while True:
            try:
                pc = read_power_columns(
                    path,
                    v_col=v_col,
                    p_col=p_col,
                    q_col=q_col,
                    q_required=True,
                    t_col=None if t_col in as_text else t_col,
                    extra=tuple(c for c in extra if c not in as_text),
                    v_base=v_base,
                    s_base=s_base,
                )
                break
            except DataError as exc:
                text = exc.column in (t_col, event_col) and exc.column not in as_text
                stamped = exc.column == t_col and "has type timestamp" in exc.message
                if DROP_HINT in exc.message:  # an event is read whole: no row is dropped
                    msg = exc.message.replace(DROP_HINT, NO_DROP)
                    raise DataError(msg, exc.path, exc.column, exc.row) from None
                if not (text and ("non-numeric" in exc.message or stamped)):
                    raise
                as_text.add(exc.column)  # type: ignore[arg-type]
        cols = dict(pc.cols)
        if t_col in as_text:
            whole = read_text_column(str(path), t_col)
            cols["t"] = parse_times(whole, path=str(path), column=t_col)[pc.rows - 1]
        if event_col in as_text:
            ids = read_text_column(str(path), event_col).to_numpy(dtype=str)
            pc.extra[event_col] = np.char.strip(ids)[pc.rows - 1]
        f_name, a_name = f_col or "f", angle_col or "angle_rad"
        for want, given, key in ((f_col, f_name, "f"), (angle_col, a_name, "angle")):
            if given in pc.extra:
                cols[key] = pc.extra[given]
            elif want:
                raise DataError("missing column", str(path), want)
        if event_col in pc.extra:
            cols["event"] = pc.extra[event_col]
        cols |= sequence_phasors(pc.extra, path=str(path), v_base=v_base, s_base=s_base)
        names = {
            "t": t_col,
            "v": v_col,
            "p": p_col,
            "q": q_col,
            "f": f_name,
            "angle": a_name,
            "event": event_col,
        }
        out += events_from_arrays(cols, pc.rows, path=str(path), names=names, f_hz=f_hz)
    refuse_repeats(out, v_col)
    return out


def refuse_repeats(events: Sequence[EventRecord], v_col: str) -> None:
    """Refuse one recording given twice (the same file, or a copy of it).

    Fitted jointly, each event's evidence is counted once per copy: the intervals come
    out narrower by the square root of the count, as if the load had been seen again.
    """
    import hashlib

    seen: dict[bytes, str] = {}
    for ev in events:
        digest = hashlib.sha256()
        for x in (ev.v, ev.p, ev.q):
            digest.update(np.ascontiguousarray(x, dtype=float).tobytes())
        key = digest.digest()
        if key in seen:
            same = (
                "this recording is given twice"
                if seen[key] == ev.name
                else f"the same recording as {seen[key]}"
            )
            raise DataError(
                f"{same} (every V, P and Q sample equal): fitted "
                "twice, its evidence would count twice and the intervals shrink as if the "
                "load had been seen again; give each event once",
                ev.name or None,
                v_col,
            )
        seen[key] = ev.name or "an earlier event"


def index_bases(paths: Sequence[str]) -> tuple[float, float] | None:
    """The bases of per-unit event files cut by ``loadbayes events``, from their index.

    ``events`` writes each event per unit and the record's bases into ``events.csv``
    beside them (``v_base_kv``, ``s_base_mva`` on the event's row, found by ``file``).
    A fit of those files records the bases, so that its export writes MW and kV.

    Parameters
    ----------
    paths : sequence of str
        The event files.

    Returns
    -------
    (v_base_kv, s_base_mva) or None
        The bases every file's row gives, or None when a file has no index or row, a
        base is missing, or the files disagree.
    """
    found = set()
    for path in paths:
        row = _index_row(path, "v_base_kv", "s_base_mva")
        if row is None:
            return None
        found.add(row[1])
    return found.pop() if len(found) == 1 else None


def _index_row(path: str, *fields: str) -> tuple[str, tuple[float, ...]] | None:
    """``(index, values)``: the positive ``fields`` of ``path``'s row in its ``events.csv``.

    None when the file is the index itself, has no index or row, or a field is missing or
    not a positive number (what ``index_bases`` and ``index_f_hz`` read).
    """
    import csv
    from pathlib import Path

    index = Path(path).with_name("events.csv")
    if Path(path).name == index.name or not index.is_file():
        return None
    try:
        with index.open(encoding="utf-8", newline="") as fh:
            rows = [r for r in csv.DictReader(fh) if r.get("file") == Path(path).name]
        values = tuple(float(rows[0][f]) for f in fields)
    except (OSError, ValueError, KeyError, IndexError, TypeError, UnicodeDecodeError):
        return None
    if not all(math.isfinite(v) and v > 0 for v in values):
        return None
    return str(index), values


def index_f_hz(paths: Sequence[str]) -> tuple[float, str] | None:
    """The nominal frequency of event files cut by ``loadbayes events``, from their index.

    ``events`` writes the record's nominal frequency (``f_nominal_hz``) beside the bases
    in ``events.csv``; a fit of those files takes it as its frequency.

    Returns
    -------
    (f_hz, index) or None
        The frequency every file's row gives and the first index read; None when a file
        has no index, row or frequency (events of a plain table), or the files disagree.
    """
    found, where = set(), ""
    for path in paths:
        row = _index_row(path, "f_nominal_hz")
        if row is None:
            return None
        found.add(row[1][0])
        where = where or row[0]
    return (found.pop(), where) if len(found) == 1 else None
