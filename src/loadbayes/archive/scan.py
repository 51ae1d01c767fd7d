"""``loadbayes archive scan``: a folder tree of COMTRADE records into the catalog.

Each ``.cfg`` (any case of the suffix, any depth) is read by the package's COMTRADE reader
(:mod:`loadbayes.recordings.comtrade`: every revision, data format, encoding and rate
layout it takes). Recorded per file: station and recorder as the ``.cfg`` writes them,
revision, format, encoding, start and trigger times, nominal frequency, the rate table and
the content hash (SHA-256 of the ``.cfg`` and ``.dat`` bytes). Per bay (each three-phase
current set, named by its bay field): its kind by the name rules (:mod:`.names`) and the
voltage dips found in it. A file the reader refuses is recorded as ``broken`` with the
reader's one line; a scan never stops on one.

The dips are found as a disturbance recorder's trigger finds them: on each phase's RMS
voltage, one estimate per cycle (:func:`~loadbayes.recordings.record.record_table`), a dip
starts when the lowest phase falls below :data:`TRIGGER` (0.96) of its median in the
waveform segment and ends when it is back above ``TRIGGER + HYSTERESIS``. So the shallow
faults of 5-10 % count, which ``loadbayes events``'s 0.9 (IEEE 1159's sag) misses.

A rescan hashes every file again and reads only the new or changed ones (a changed file's
old rows, and the fits of its events, are replaced); a file moved keeps its rows, and a
second copy of a file is recorded as a ``duplicate`` of the first.
"""

from __future__ import annotations

import datetime as dt
import hashlib
import json
import os
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from loadbayes.archive.catalog import connect, insert_file
from loadbayes.archive.names import bay_kind, is_load, read_rules
from loadbayes.io.errors import DataError

__all__ = ["HYSTERESIS", "TRIGGER", "ScanSummary", "read_file", "scan"]

#: A dip starts when the lowest phase's RMS voltage is under this share of its median.
TRIGGER = 0.96
#: ... and ends when it is back above TRIGGER + HYSTERESIS.
HYSTERESIS = 0.01
#: Shorter dips are ignored (s); seconds kept before the dip and after its recovery.
MIN_DURATION_S = 0.015
PRE_S = 0.2
POST_S = 1.0
#: A usable event has this many cycles before the dip.
PRE_CYCLES = 2.0


@dataclass
class ScanSummary:
    """What a scan did: files by outcome, and the events found."""

    new: int = 0
    changed: int = 0
    unchanged: int = 0
    moved: int = 0
    broken: int = 0
    duplicates: int = 0
    events: int = 0
    usable: int = 0
    broken_files: list[tuple[str, str]] = field(default_factory=list)

    def line(self) -> str:
        """The scan in one line."""
        return (
            f"{self.new} new, {self.changed} changed, {self.unchanged} unchanged, "
            f"{self.moved} moved, {self.duplicates} duplicate, {self.broken} broken file(s); "
            f"{self.events} event(s) found, {self.usable} usable"
        )


def _hash(cfg: Path) -> tuple[str, int]:
    from loadbayes.recordings.comtrade_dat import find_dat

    h = hashlib.sha256()
    size = 0
    data = cfg.read_bytes()
    h.update(data)
    size += len(data)
    h.update(b"\0")
    try:
        dat = find_dat(cfg, str(cfg))
    except DataError:
        dat = None
    if dat is not None:
        with open(dat, "rb") as fh:
            for chunk in iter(lambda: fh.read(1 << 20), b""):
                h.update(chunk)
                size += len(chunk)
    return h.hexdigest(), size


def _event_id(digest: str, bay: str, segment: int, sag_start_s: float) -> str:
    key = f"{digest}|{bay}|{segment}|{sag_start_s:.6f}"
    return hashlib.sha256(key.encode("utf-8")).hexdigest()[:16]


def _bay_events(w, digest: str, bay: str, start: dt.datetime | None) -> list[dict]:
    """The dips of one bay's record, each with its window and whether it can be fitted."""
    from loadbayes.recordings.record import phasor_rows, record_table, sags_by_segment

    rows = phasor_rows(record_table(w, per_cycle=1).columns)
    seg = np.asarray(rows["segment"], dtype=np.int64)
    phases = np.vstack([np.asarray(rows[c], dtype=float) for c in ("va", "vb", "vc")])
    trigger = np.min(phases, axis=0)
    cols = {"t_s": np.asarray(rows["t_s"], dtype=float), "v": trigger, "segment": seg}
    ok = np.isfinite(trigger) & np.isfinite(cols["t_s"])
    cols = {k: v[ok] for k, v in cols.items()}
    v1 = np.asarray(rows["v"], dtype=float)[ok]
    p = np.asarray(rows["p"], dtype=float)[ok]
    seg = cols["segment"]
    t = cols["t_s"]
    out = []
    windows = sags_by_segment(
        cols, threshold=TRIGGER, hysteresis=HYSTERESIS, min_duration_s=MIN_DURATION_S,
        pre_s=PRE_S, post_s=POST_S,
    )  # fmt: skip
    for ev in windows:
        k = int(seg[ev.start])
        in_seg = seg == k
        lo, hi = ev.start, ev.stop
        before = t[lo:hi] < ev.sag_start_s - 0.5 / w.f_nominal
        p_pre = p[lo:hi][before]
        reason = ""
        if not ev.recovered:
            reason = "the voltage does not recover before the waveform record ends"
        elif ev.sag_start_s - t[lo] < PRE_CYCLES / w.f_nominal:
            reason = (
                f"fewer than {PRE_CYCLES:g} cycles before the dip: no pre-fault operating point"
            )
        elif p_pre.size == 0 or not np.all(np.isfinite(p_pre)):
            reason = "no finite P before the dip"
        elif np.median(p_pre) <= 0:
            reason = "the bay exports power before the dip (P < 0): not a load"
        at = start + dt.timedelta(seconds=ev.sag_start_s) if start else None
        v1_ref = float(np.median(v1[in_seg]))
        out.append(
            {
                "event_id": _event_id(digest, bay, k, ev.sag_start_s),
                "idx": ev.index,
                "segment": k,
                "start_s": float(t[lo]),
                "stop_s": float(t[hi - 1]),
                "sag_start_s": ev.sag_start_s,
                "recovery_s": ev.recovery_s if ev.recovered else None,
                "time": at.isoformat() if at else None,
                "depth": ev.depth,
                "v1_depth": 1.0 - float(np.min(v1[lo:hi])) / v1_ref if v1_ref > 0 else None,
                "duration_s": ev.duration_s,
                "recovered": int(ev.recovered),
                "usable": int(not reason),
                "reason": reason or None,
            }
        )
    return out


def read_file(cfg: str | os.PathLike[str], digest: str, rules: Sequence[tuple[str, str]] = ()):
    """One record: the file's row, its bays and their events (nothing written).

    Returns ``(file_row, [(bay_row, [event_row, ...]), ...])``; a file the reader
    refuses has ``status`` ``broken`` and its ``reason``, and no bays.
    """
    from loadbayes.recordings.comtrade import read_comtrade
    from loadbayes.recordings.comtrade_cfg import parse_cfg
    from loadbayes.recordings.comtrade_channels import current_sets
    from loadbayes.recordings.comtrade_dat import find_dat
    from loadbayes.recordings.record_file import comtrade_time

    path = os.fspath(cfg)
    row: dict = {"status": "ok", "reason": None}
    try:
        info = parse_cfg(path)
        if find_dat(Path(path), path) is None:
            raise DataError(f"data file {Path(path).with_suffix('.dat').name} not found", path)
    except Exception as exc:  # noqa: BLE001 - a file that cannot be read is never fatal
        return {"status": "broken", "reason": _line(exc, path)}, []
    # 1991 writes mm/dd/yy (the comtrade package reads the samples so).
    start = comtrade_time(info.start, month_first=info.revision == "1991")
    trigger = comtrade_time(info.trigger, month_first=info.revision == "1991")
    row.update(
        station=info.station, recorder=info.device, revision=info.revision,
        format=info.format, encoding=info.encoding,
        start=start.isoformat() if start else None,
        trigger_time=trigger.isoformat() if trigger else None,
        f_nominal_hz=info.f_nominal, rates=json.dumps(info.rates), n_analog=len(info.analog),
    )  # fmt: skip
    sets = current_sets(info)
    if not sets:
        why = "no three-phase current set: no bay whose load could be fitted"
        return {**row, "status": "broken", "reason": why}, []
    bays = []
    for name, trio in sets:
        words = " ".join([name, *(ch.name for ch in trio)])
        kind = bay_kind(words, rules)
        current = [str(ch.n) for ch in trio]
        field = trio[0].ccbm.strip() or None
        bay_row = {"bay": name, "field": field, "kind": kind, "current": json.dumps(current),
                   "voltage": None, "status": "ok", "reason": None}  # fmt: skip
        events: list[dict] = []
        if not is_load(kind):
            bay_row.update(status="skipped", reason=f"a {kind} bay by the name rules: not a load")
            bays.append((bay_row, events))
            continue
        try:
            w = read_comtrade(path, current=current, bay=field)
            bay_row["voltage"] = json.dumps(
                [w.channels[f"v{p}"] for p in "abc"], ensure_ascii=False
            )
            events = _bay_events(w, digest, name, start)
        except Exception as exc:  # noqa: BLE001 - a file that cannot be read is never fatal
            bay_row.update(status="broken", reason=_line(exc, path))
        if bay_row["status"] == "ok" and not events:
            bay_row["reason"] = "no voltage dip of 4 % or more"
        bays.append((bay_row, events))
    if all(b["status"] == "broken" for b, _ in bays):
        row.update(status="broken", reason=bays[0][0]["reason"])
    return row, bays


def _line(exc: BaseException, path: str = "") -> str:
    """The error in one line, without the ``.cfg``'s own path (the row names it).

    The reader's errors (:class:`DataError`, ``OSError``) are said as they are; anything
    else a malformed file provokes deeper down is said with its type, never raised.
    """
    text = " ".join(str(exc).split())
    if not isinstance(exc, (DataError, OSError, ValueError)):
        text = f"cannot be read ({type(exc).__name__}: {text})"
    return text[len(path) + 2 :] if path and text.startswith(path + ": ") else text


def _cfgs(root: Path) -> list[Path]:
    found = []
    for folder, dirs, files in os.walk(root):
        dirs.sort()
        found += [Path(folder) / f for f in sorted(files) if f.lower().endswith(".cfg")]
    return found


def scan(
    root: str | os.PathLike[str],
    catalog: str | os.PathLike[str],
    *,
    rules: str | os.PathLike[str] | Sequence[tuple[str, str]] | None = None,
    progress: Callable[[int, int, str], None] | None = None,
    workers: int | None = None,
) -> ScanSummary:
    """Scan a folder tree of COMTRADE records into the catalog (made if missing).

    Parameters
    ----------
    root : str or os.PathLike
        The folder (walked at every depth) or one ``.cfg``.
    catalog : str or os.PathLike
        The SQLite catalog (``archive.db``).
    rules : path or list of (pattern, kind), optional
        Bay name rules tried before the defaults (:mod:`loadbayes.archive.names`).
    progress : callable, optional
        ``progress(done, total, path)`` after each new or changed file.
    workers : int, optional
        Read the files in this many processes (the catalog is written by this one).

    Returns
    -------
    ScanSummary

    Raises
    ------
    DataError
        When ``root`` does not exist, or the rules file or the catalog cannot be read.
    """
    top = Path(root)
    if not top.exists():
        raise DataError("folder not found", os.fspath(root))
    user_rules = (
        read_rules(rules) if rules is None or isinstance(rules, (str, os.PathLike)) else list(rules)
    )
    cfgs = [top] if top.is_file() else _cfgs(top)
    out = ScanSummary()
    with connect(catalog, create=True) as conn:
        known = {
            r[0]: (r[1], r[2])
            for r in conn.execute("SELECT path, file_id, hash FROM files").fetchall()
        }
        by_hash = {
            r[0]: (r[1], r[2])
            for r in conn.execute(
                "SELECT hash, file_id, path FROM files WHERE status != 'duplicate'"
            ).fetchall()
        }
        plan = []
        for cfg in cfgs:
            path = str(cfg.resolve())
            digest, size = _hash(cfg)
            old = known.get(path)
            if old is not None and old[1] == digest:
                out.unchanged += 1
            else:
                plan.append((path, digest, size, old))
        # The files to read: one per new content (a copy or a move is not read again).
        fresh = list({d: p for p, d, _, _ in reversed(plan) if d not in by_hash}.items())[::-1]
        reads = _read_all(fresh, user_rules, workers)
        done = out.unchanged
        for path, digest, size, old in plan:
            _store(conn, out, path, digest, size, old, by_hash, reads)
            done += 1
            if progress is not None:
                progress(done, len(cfgs), path)
        rows = conn.execute(
            "SELECT path, reason FROM files WHERE status = 'broken' ORDER BY path"
        ).fetchall()
        out.broken_files = [(r[0], r[1]) for r in rows]
    return out


def _read_all(fresh: list[tuple[str, str]], rules, workers: int | None):
    """``{digest: read_file(...)}`` filled as the reads finish, in order (lazily).

    With ``workers``, the files are read by that many processes (the reading and the
    per-cycle phasors are the scan's cost; the catalog is written here, one file at a
    time); otherwise one after another in this process.
    """

    class Reads(dict):
        def __init__(self, results):
            super().__init__()
            self.results = results
            self.planned = set(digests)

        def get(self, path, digest):  # noqa: D102 - the file's reading, done or done now
            if digest not in self.planned:  # a content whose first copy was changed meanwhile
                return read_file(path, digest, rules)
            while digest not in self:
                d, result = next(self.results)
                self[d] = result
            return self.pop(digest)

    digests = [d for d, _ in fresh]
    if not workers or workers < 2 or len(fresh) < 2:
        gen = ((d, read_file(p, d, rules)) for d, p in fresh)
        return Reads(gen)
    from concurrent.futures import ProcessPoolExecutor

    pool = ProcessPoolExecutor(max_workers=workers)
    results = pool.map(read_file, [p for _, p in fresh], digests, [rules] * len(fresh), chunksize=4)

    def gen():
        try:
            yield from zip(digests, results, strict=True)
        finally:
            pool.shutdown(cancel_futures=True)

    return Reads(gen())


def _store(conn, out: ScanSummary, path, digest, size, old, by_hash, reads) -> None:
    """Read one new or changed file and write its rows, committed at once."""
    now = dt.datetime.now(dt.UTC).isoformat(timespec="seconds")
    same = by_hash.get(digest)
    with conn:
        if old is not None:
            conn.execute("DELETE FROM files WHERE file_id = ?", (old[0],))
            if by_hash.get(old[1], (None,))[0] == old[0]:
                del by_hash[old[1]]
            out.changed += 1
        if same is not None and same[1] != path:
            if not Path(same[1]).exists():  # moved: the rows (and fits) follow it
                conn.execute("UPDATE files SET path = ? WHERE file_id = ?", (path, same[0]))
                by_hash[digest] = (same[0], path)
                out.moved += 1
                return
            conn.execute(
                "INSERT INTO files (path, hash, bytes, status, reason, scanned_at) "
                "VALUES (?, ?, ?, 'duplicate', ?, ?)",
                (path, digest, size, f"the same content as {same[1]}", now),
            )
            out.duplicates += 1
            return
        if old is None:
            out.new += 1
        row, bays = reads.get(path, digest)
        file_id, events, usable = insert_file(conn, path, digest, size, row, bays, now)
        by_hash[digest] = (file_id, path)
        out.broken += row["status"] == "broken"
        out.events += events
        out.usable += usable
