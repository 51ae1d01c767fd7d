"""The archive's catalog: one SQLite file (the standard library's ``sqlite3``).

What ``archive scan`` found and what ``archive fit`` made of it, one table each:

- ``files``: one row per ``.cfg`` (its path, the content hash of ``.cfg`` + ``.dat``,
  station, recorder, revision, data format, encoding, start and trigger times, nominal
  frequency, rate table), with ``status`` ``ok``, ``broken`` (``reason`` says why) or
  ``duplicate`` (the same content as another path);
- ``bays``: per file, each three-phase current set (its bay name, the ``.cfg``'s bay field
  it was read by, the kind the name rules gave it, the channels), ``status`` (``ok``,
  ``skipped``: not a load by the rules, ``broken``) and ``reason``;
- ``events``: per bay, each voltage dip the trigger found (its window in record seconds,
  the sag's start, depth, duration, absolute time), ``usable`` and ``reason``; the id is
  a hash of the file's content, the bay and the dip's place, so a moved file keeps it;
- ``fits``: per event and model, ``done``, ``failed`` (the data or options refused:
  ``reason``) or ``error`` (anything else, fitted again by the next run), the seed, the run's
  draws, phasors per cycle and the model's phasor window (NULL: one cycle), R-hat and ESS
  at their worst, the fit's warnings (JSON) and the NetCDF path;
- ``params``: per fit, each scalar parameter's mean, sd, 2.5 % and 97.5 % quantiles,
  R-hat and bulk ESS.

Each fit is written and committed as it finishes (:func:`record_fit`): a run killed
loses only the fits in flight. :func:`fits_frame` is the table the pooling reads.
"""

from __future__ import annotations

import json
import os
import sqlite3
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

__all__ = [
    "SCHEMA",
    "SCHEMA_VERSION",
    "connect",
    "events_frame",
    "failures_frame",
    "fits_frame",
    "insert_file",
    "record_fit",
    "results_folder",
    "units_frame",
]

SCHEMA_VERSION = "1"

SCHEMA = """
CREATE TABLE IF NOT EXISTS meta (key TEXT PRIMARY KEY, value TEXT);
CREATE TABLE IF NOT EXISTS files (
    file_id INTEGER PRIMARY KEY,
    path TEXT NOT NULL UNIQUE,
    hash TEXT NOT NULL,
    bytes INTEGER,
    status TEXT NOT NULL,
    reason TEXT,
    station TEXT, recorder TEXT, revision TEXT, format TEXT, encoding TEXT,
    start TEXT, trigger_time TEXT, f_nominal_hz REAL, rates TEXT, n_analog INTEGER,
    scanned_at TEXT NOT NULL
);
CREATE INDEX IF NOT EXISTS files_hash ON files (hash);
CREATE TABLE IF NOT EXISTS bays (
    bay_id INTEGER PRIMARY KEY,
    file_id INTEGER NOT NULL REFERENCES files (file_id) ON DELETE CASCADE,
    bay TEXT NOT NULL,
    field TEXT,
    kind TEXT NOT NULL,
    current TEXT NOT NULL,
    voltage TEXT,
    status TEXT NOT NULL,
    reason TEXT
);
CREATE TABLE IF NOT EXISTS events (
    event_id TEXT PRIMARY KEY,
    file_id INTEGER NOT NULL REFERENCES files (file_id) ON DELETE CASCADE,
    bay_id INTEGER NOT NULL REFERENCES bays (bay_id) ON DELETE CASCADE,
    station TEXT, bay TEXT, kind TEXT,
    idx INTEGER, segment INTEGER,
    start_s REAL, stop_s REAL, sag_start_s REAL, recovery_s REAL,
    time TEXT, depth REAL, v1_depth REAL, duration_s REAL, recovered INTEGER,
    usable INTEGER NOT NULL, reason TEXT
);
CREATE TABLE IF NOT EXISTS fits (
    event_id TEXT NOT NULL REFERENCES events (event_id) ON DELETE CASCADE,
    model TEXT NOT NULL,
    status TEXT NOT NULL,
    reason TEXT,
    seed INTEGER, draws INTEGER, burn INTEGER, chains INTEGER, per_cycle INTEGER,
    window_s REAL, rhat_max REAL, ess_min REAL, warnings TEXT, netcdf TEXT,
    seconds REAL, finished_at TEXT,
    PRIMARY KEY (event_id, model)
);
CREATE TABLE IF NOT EXISTS params (
    event_id TEXT NOT NULL,
    model TEXT NOT NULL,
    name TEXT NOT NULL,
    share INTEGER NOT NULL,
    mean REAL, sd REAL, lo REAL, hi REAL, rhat REAL, ess REAL,
    PRIMARY KEY (event_id, model, name),
    FOREIGN KEY (event_id, model) REFERENCES fits (event_id, model) ON DELETE CASCADE
);
"""

#: A share's row is ``ok`` below this R-hat and at or above this bulk ESS (why these:
#: ``pool_data.RHAT_EVENT``, what the pool asks of an event).
RHAT_OK = 1.05
ESS_OK = 100.0


@contextmanager
def connect(path: str | os.PathLike[str], *, create: bool = False) -> Iterator[sqlite3.Connection]:
    """An open catalog (its schema made when ``create``), closed at the end.

    Raises
    ------
    DataError
        When the file is missing (and not ``create``), or is not a loadbayes catalog.
    """
    from loadbayes.io.errors import DataError

    name = os.fspath(path)
    if not create and not Path(name).is_file():
        raise DataError("catalog not found (make it with loadbayes archive scan)", name)
    try:
        conn = sqlite3.connect(name, timeout=60.0)
        conn.execute("PRAGMA foreign_keys = ON")
        conn.execute("PRAGMA journal_mode = WAL")
        if create:
            conn.executescript(SCHEMA)
            conn.execute("INSERT OR IGNORE INTO meta VALUES ('schema', ?)", (SCHEMA_VERSION,))
            conn.commit()
        version = conn.execute("SELECT value FROM meta WHERE key = 'schema'").fetchone()
    except sqlite3.DatabaseError as exc:
        raise DataError(f"not a loadbayes archive catalog ({exc})", name) from None
    if version is None or version[0] != SCHEMA_VERSION:
        conn.close()
        raise DataError(f"catalog schema {version} is not {SCHEMA_VERSION}", name)
    try:
        yield conn
    finally:
        conn.close()


def results_folder(db_path: str | os.PathLike[str]) -> Path:
    """Where the fits' NetCDF files go: ``archive.results/`` beside ``archive.db``."""
    p = Path(db_path)
    return p.with_name(p.stem + ".results")


def insert_file(conn: sqlite3.Connection, path, digest, size, row, bays, now) -> tuple:
    """Write one scanned file, its bays and their events; ``(file_id, events, usable)``."""
    cur = conn.execute(
        "INSERT INTO files (path, hash, bytes, status, reason, station, recorder, "
        "revision, format, encoding, start, trigger_time, f_nominal_hz, rates, n_analog, "
        "scanned_at) VALUES (?,?,?,?,?,?,?,?,?,?,?,?,?,?,?,?)",
        (
            path, digest, size, row["status"], row["reason"], row.get("station"),
            row.get("recorder"), row.get("revision"), row.get("format"),
            row.get("encoding"), row.get("start"), row.get("trigger_time"),
            row.get("f_nominal_hz"), row.get("rates"), row.get("n_analog"), now,
        ),
    )  # fmt: skip
    file_id = cur.lastrowid
    n = usable = 0
    for bay_row, events in bays:
        cur = conn.execute(
            "INSERT INTO bays (file_id, bay, field, kind, current, voltage, status, reason) "
            "VALUES (?,?,?,?,?,?,?,?)",
            (file_id, bay_row["bay"], bay_row["field"], bay_row["kind"], bay_row["current"],
             bay_row["voltage"], bay_row["status"], bay_row["reason"]),
        )  # fmt: skip
        bay_id = cur.lastrowid
        for e in events:
            conn.execute(
                "INSERT OR REPLACE INTO events VALUES (?,?,?,?,?,?,?,?,?,?,?,?,?,?,?,?,?,?,?)",
                (
                    e["event_id"], file_id, bay_id, row.get("station"), bay_row["bay"],
                    bay_row["kind"], e["idx"], e["segment"], e["start_s"], e["stop_s"],
                    e["sag_start_s"], e["recovery_s"], e["time"], e["depth"], e["v1_depth"],
                    e["duration_s"], e["recovered"], e["usable"], e["reason"],
                ),
            )  # fmt: skip
            n += 1
            usable += e["usable"]
    return file_id, n, usable


def record_fit(conn: sqlite3.Connection, result: dict) -> None:
    """Write one fit's result (done or failed) and commit: it survives a killed run."""
    with conn:
        conn.execute(
            "INSERT OR REPLACE INTO fits VALUES (?,?,?,?,?,?,?,?,?,?,?,?,?,?,?,datetime('now'))",
            (
                result["event_id"], result["model"], result["status"], result.get("reason"),
                result["seed"], result["draws"], result["burn"], result["chains"],
                result["per_cycle"], result.get("window_s"), result.get("rhat_max"),
                result.get("ess_min"),
                json.dumps(result.get("warnings", []), ensure_ascii=False),
                result.get("netcdf"), result.get("seconds"),
            ),
        )  # fmt: skip
        conn.executemany(
            "INSERT OR REPLACE INTO params VALUES (?,?,?,?,?,?,?,?,?,?)",
            [
                (result["event_id"], result["model"], p["name"], int(p["share"]), p["mean"],
                 p["sd"], p["lo"], p["hi"], p["rhat"], p["ess"])
                for p in result.get("params", [])
            ],
        )  # fmt: skip


_FITS_SQL = """
SELECT e.station, e.bay, e.event_id, e.time, f.model, p.name AS part,
       p.mean, p.sd, p.lo, p.hi, p.rhat, p.ess
FROM params p
JOIN fits f ON f.event_id = p.event_id AND f.model = p.model
JOIN events e ON e.event_id = p.event_id
WHERE p.share = 1 AND f.status = 'done'
ORDER BY e.station, e.bay, e.time, e.event_id, f.model, p.name
"""


def fits_frame(db_path: str | os.PathLike[str]):
    """One row per fitted event and share: what the pooling across events reads.

    Columns ``station, bay, event_id, time`` (datetime64, the sag's start on the
    recorder's clock), ``model``, ``part`` (the share: ``f_m`` for ``zip+motor``'s motor;
    each ``f_...`` share of a model of parts), ``mean, sd, lo, hi`` (2.5 % and 97.5 %
    quantiles), ``rhat, ess`` (bulk) and ``status``: ``ok``; ``unconverged`` (R-hat at or
    above 1.05 or ESS under 100 for this share); ``unphysical`` (its mean outside [0, 1]).

    Returns
    -------
    pandas.DataFrame
    """
    import pandas as pd

    with connect(db_path) as conn:
        df = pd.read_sql_query(_FITS_SQL, conn)
    df["time"] = pd.to_datetime(df["time"], errors="coerce")
    bad_mix = (df["mean"] < 0) | (df["mean"] > 1)
    unconverged = ~(df["rhat"] < RHAT_OK) | ~(df["ess"] >= ESS_OK)
    df["status"] = "ok"
    df.loc[unconverged, "status"] = "unconverged"
    df.loc[bad_mix, "status"] = "unphysical"
    return df


def failures_frame(db_path: str | os.PathLike[str]):
    """What could not be used, and why: broken files, bays and events, failed fits.

    Columns ``what`` (``file``, ``bay``, ``event``, ``fit``), ``path``, ``station``,
    ``bay``, ``event_id``, ``reason``.
    """
    import pandas as pd

    sql = """
    SELECT 'file' AS what, path, station, NULL AS bay, NULL AS event_id, reason
      FROM files WHERE status != 'ok'
    UNION ALL
    SELECT 'bay', f.path, f.station, b.bay, NULL, b.reason
      FROM bays b JOIN files f USING (file_id) WHERE b.status != 'ok'
    UNION ALL
    SELECT 'event', f.path, e.station, e.bay, e.event_id, e.reason
      FROM events e JOIN files f USING (file_id) WHERE e.usable = 0
    UNION ALL
    SELECT 'fit', f.path, e.station, e.bay, e.event_id, x.model || ': ' || x.reason
      FROM fits x JOIN events e USING (event_id) JOIN files f ON f.file_id = e.file_id
      WHERE x.status != 'done'
    """
    with connect(db_path) as conn:
        return pd.read_sql_query(sql, conn)


_UNITS_SQL = """
SELECT f.station, b.bay, b.kind, b.status,
       COUNT(DISTINCT f.file_id) AS files,
       COUNT(e.event_id) AS events,
       COALESCE(SUM(e.usable), 0) AS usable,
       COALESCE(SUM(x.done), 0) AS fitted,
       COALESCE(SUM(x.bad AND NOT x.done), 0) AS fit_failed,
       SUM(e.event_id IS NULL AND b.status = 'ok') AS no_event_files
FROM bays b JOIN files f USING (file_id)
LEFT JOIN events e USING (bay_id)
LEFT JOIN (SELECT event_id, MAX(status = 'done') AS done,
                  MAX(status IN ('failed', 'error')) AS bad
           FROM fits GROUP BY event_id) x ON x.event_id = e.event_id
GROUP BY f.station, b.bay, b.kind, b.status
ORDER BY f.station, b.bay, b.status
"""


def units_frame(db_path: str | os.PathLike[str]):
    """One row per station, bay and bay status: files, events found, usable, fitted.

    Columns ``station, bay, kind, status`` (``ok``, ``skipped``, ``broken``), ``files``,
    ``events``, ``usable``, ``fitted`` (events with a fit ``done``, by any model),
    ``fit_failed`` (events with only ``failed`` or ``error`` fits) and
    ``no_event_files`` (files read whose bay had no dip).
    """
    import pandas as pd

    with connect(db_path) as conn:
        return pd.read_sql_query(_UNITS_SQL, conn)


def events_frame(db_path: str | os.PathLike[str]):
    """One row per event found, usable or not.

    Columns ``station, bay, kind, event_id, time`` (datetime64), ``depth, duration_s,
    usable, reason`` and ``path`` (its record's ``.cfg``).
    """
    import pandas as pd

    sql = """SELECT e.station, e.bay, e.kind, e.event_id, e.time, e.depth, e.duration_s,
             e.usable, e.reason, f.path FROM events e JOIN files f USING (file_id)
             ORDER BY e.station, e.bay, e.time"""
    with connect(db_path) as conn:
        df = pd.read_sql_query(sql, conn)
    df["time"] = pd.to_datetime(df["time"], errors="coerce")
    return df
