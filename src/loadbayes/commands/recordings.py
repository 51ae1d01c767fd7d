"""``loadbayes read comtrade|pmu`` and ``loadbayes events``: recordings to per-unit events.

Standalone click objects (this module does not import :mod:`loadbayes.cli`); ``cli.py``
attaches them. Heavy imports stay inside the commands.
"""

from __future__ import annotations

import math
from pathlib import Path

import click

from loadbayes.commands.options import OneLineCommand
from loadbayes.commands.output import (
    Progress,
    UserError,
    check_outputs,
    output_transaction,
    user_errors,
)

#: A read of more phasor windows (both passes) than this is timed first: a short probe of
#: the same fit (red-team M9: a fixed 3e-4 s per window was 20x low at --per-cycle 64).
PROBE_FROM_WINDOWS = 1000
#: The probe fits this share of the record's cycles, at least PROBE_MIN_CYCLES of them.
PROBE_SHARE = 0.03
PROBE_MIN_CYCLES = 3.0
#: The cost is said, and the bar shows the time left, above this many seconds.
SAY_COST_S = 2.0


def estimate_seconds(w, per_cycle: int, dc: str, windows: int, clock=None) -> float | None:
    """The read's cost: two probes of the phasor fit on the record's first cycles, scaled.

    The probes fit ``PROBE_SHARE`` of the cycles (at least ``PROBE_MIN_CYCLES``, plus the
    cycles the decay test reads past a window), then twice that, at the requested
    ``per_cycle`` and ``dc``. Their difference is the cost per window, what the shorter
    took beyond it the fixed cost (evenly spaced samples share one least-squares fit
    between windows, so one probe alone over-states a long read threefold); the estimate
    is ``fixed + per_window x windows``. None for a short read (fewer than
    :data:`PROBE_FROM_WINDOWS` windows) or a probe that fitted nothing.
    """
    import time

    from loadbayes.recordings.record import probe_windows

    if windows < PROBE_FROM_WINDOWS:
        return None
    clock = clock or time.perf_counter
    cycles = max(PROBE_MIN_CYCLES, PROBE_SHARE * windows / (2.0 * per_cycle))
    n1, s1 = probe_windows(w, per_cycle, dc, cycles + 2.0, clock)
    n2, s2 = probe_windows(w, per_cycle, dc, 2.0 * cycles + 2.0, clock)
    if n1 == 0 or n2 == 0:
        return None
    if n2 <= n1 or s2 <= s1:  # the record ended, or the clock was noisier than the work
        return s2 / n2 * windows
    per_window = (s2 - s1) / (n2 - n1)
    return max(s1 - per_window * n1, 0.0) + per_window * windows


__all__ = ["events_cmd", "read_group"]


#: The bases a network can have: 1 V to 2000 kV, 1 VA to 1 TVA (1e308 kV was said to be
#: "a dead or unscaled VT", 1e-308 MVA wrote overflowed powers).
BASE_RANGE = {"--v-base": (1e-3, 2000.0, "kV"), "--s-base": (1e-6, 1e6, "MVA")}


def _positive(value: float | None, name: str) -> float | None:
    if value is not None and not (math.isfinite(value) and value > 0):
        raise click.BadParameter("must be a positive finite number", param_hint=name)
    lo, hi, unit = BASE_RANGE[name]
    if value is not None and not lo <= value <= hi:
        raise UserError(f"{name} {value:g}: outside [{lo:g}, {hi:g}] {unit}, no network's base")
    return value


def _write(table: dict, out: str, force: bool) -> None:
    from loadbayes.io.tables import write_table

    write_table(table, out, force=force)


@click.group("read")
def read_group() -> None:
    """Read a recording (COMTRADE, PMU CSV) into a per-unit t_s, v, p, q, f table."""


#: Output suffixes a table can be written as (checked before any work).
TABLE_SUFFIXES = (".csv", ".txt", ".csv.gz", ".txt.gz", ".parquet", ".pq")


def _table_out(out: str) -> None:
    if out == "-":
        raise UserError("--out -: a record table is written to a file, not standard output")
    if not out.lower().endswith(TABLE_SUFFIXES):
        suffix = Path(out).suffix or "(no extension)"
        raise UserError(
            f"{out}: --out must be a .csv or .parquet file (by extension), not {suffix}"
        )


def _channels(value: str | None, opt: str) -> list[str] | None:
    """Three channels by name or 1-based number (names may hold spaces)."""
    if value is None:
        return None
    names = [s.strip() for s in value.split(",")]
    if len(names) != 3 or not all(names):
        raise click.BadParameter(
            f"expected three channels A,B,C (names or 1-based numbers), got {value!r}",
            param_hint=opt,
        )
    return names


@read_group.command("comtrade", cls=OneLineCommand)
@click.argument("cfg", type=click.Path(dir_okay=False))
@click.option("--out", required=True, type=click.Path(dir_okay=False),
              help="CSV or Parquet; the metadata go to OUT.meta.json beside it.")  # fmt: skip
@click.option("--voltage", help="Phase a, b, c voltage channels: names or 1-based numbers.")
@click.option("--current", help="Phase a, b, c current channels: names or 1-based numbers.")
@click.option("--bay", help="The bay (text in the channels' bay field or name) whose currents "
              "(and voltages; the bus's when it has none) are read.")  # fmt: skip
@click.option("--encoding", help="The .cfg's text encoding (default: UTF-8, GB18030 or "
              "Latin-1, detected).")  # fmt: skip
@click.option("--per-cycle", type=click.IntRange(1, 64), default=1, show_default=True,
              help="Phasor estimates per cycle (one-cycle windows, 1/N cycle apart).")  # fmt: skip
@click.option("--dc", type=click.Choice(["auto", "on", "off"]), default="auto",
              show_default=True, help="Decaying-DC rejection (mimic filter) where a test "
              "finds an offset, in every window, or never.")  # fmt: skip
@click.option(
    "--side",
    type=click.Choice(["primary", "secondary"]),
    default="primary",
    show_default=True,
    help="Scale to the transformer's primary or secondary side (the .cfg's ratio).",
)
@click.option("--v-base", type=float, help="Voltage base, line-to-line kV (default: first row).")
@click.option("--s-base", type=float, help="Power base, 3-phase MVA (default: first row |S1|).")
@click.option("--quiet", is_flag=True)
@click.option("--force", is_flag=True, help="Overwrite the output.")
@user_errors
def read_comtrade_cmd(
    cfg, out, voltage, current, bay, encoding, per_cycle, dc, side, v_base, s_base, quiet, force
):
    """Positive-sequence V, P, Q, f and more from a COMTRADE record, per phasor window.

    Waveform segments become rows of least-squares phasors over one-cycle windows
    (decaying DC rejected), N per cycle; a recorder's amplitude segments become rows of
    per-phase magnitudes with no P or Q. Columns and metadata: docs/formats.md.
    """
    _table_out(out)
    _positive(v_base, "--v-base")
    _positive(s_base, "--s-base")
    vnames, inames = _channels(voltage, "--voltage"), _channels(current, "--current")
    if bay is not None and not bay.strip():
        raise click.BadParameter("is empty", param_hint="--bay")
    from loadbayes.recordings.record_file import meta_path

    side_file = str(meta_path(out))
    dat = str(Path(cfg).with_suffix(".dat"))
    check_outputs({"--out": out, "--out's metadata": side_file}, [cfg, dat], force)
    from loadbayes.io.errors import DataError
    from loadbayes.recordings.comtrade import read_comtrade
    from loadbayes.recordings.plausible import check_table
    from loadbayes.recordings.record import phasor_windows, record_table
    from loadbayes.recordings.record_file import record_metadata, write_record

    w = read_comtrade(cfg, voltage=vnames, current=inames, bay=bay, side=side, encoding=encoding)
    windows = phasor_windows(w, per_cycle)
    seconds = None if quiet else estimate_seconds(w, per_cycle, dc, windows)
    long = seconds is not None and seconds > SAY_COST_S
    if long:  # the cost first, when it is felt
        click.echo(
            f"loadbayes: note: {cfg}: {w.t_s.size} samples, about {windows // 2} phasor "
            f"windows at --per-cycle {per_cycle}: about {seconds:.0f} s on this machine "
            "(timed on the record's first cycles)",
            err=True,
        )
    bar = Progress("phasor windows", windows, quiet, eta=long)
    try:
        rec = record_table(
            w, per_cycle=per_cycle, dc=dc, v_base_kv=v_base, s_base_mva=s_base, source=cfg,
            progress=bar,
        )  # fmt: skip
    except ValueError as exc:
        if isinstance(exc, DataError):
            raise
        raise UserError(f"{cfg}: {exc}") from None
    finally:
        bar.close()
    rec.notes = [*w.notes, *rec.notes, *check_table(w, rec, cfg)]
    meta = record_metadata(w, rec, source=cfg, per_cycle=per_cycle, dc=dc, side=side, bay=bay)
    # The table and its sidecar: one transaction, which user_errors knows of (what a
    # signal left is said truly: both files, or neither).
    with output_transaction({"--out": out, "metadata": side_file}, force=force) as tx:
        write_record(rec, meta, out, force=force, outputs=tx)
    for line in rec.notes:
        click.echo(f"loadbayes: note: {cfg}: {line}", err=True)
    if not quiet:
        c = rec.columns
        phasor = int((c["kind"] == "phasor").sum())
        click.echo(
            f"{out}: {phasor} phasor rows ({per_cycle} per cycle at {w.f_nominal:g} Hz "
            f"nominal) and {rec.rows - phasor} amplitude rows from {len(w.segments)} "
            f"segment(s); v base {rec.v_base_kv:.6g} kV l-l, s base {rec.s_base_mva:.6g} "
            "MVA; channels "
            + ", ".join(f"{k}={v}" for k, v in w.channels.items())
            + f"; metadata in {side_file}",
            err=True,
        )


@read_group.command("pmu", cls=OneLineCommand)
@click.argument("csv", type=click.Path(dir_okay=False))
@click.option("--out", required=True, type=click.Path(dir_okay=False), help="CSV or Parquet.")
@click.option("--map", "map_file", type=click.Path(dir_okay=False), help="TOML column mapping.")
@click.option("--time-col", help="Timestamp column.")
@click.option("--v-mag", help="Voltage magnitude column(s): one (positive sequence) or a,b,c.")
@click.option("--v-ang", help="Voltage angle column(s).")
@click.option("--i-mag", help="Current magnitude column(s).")
@click.option("--i-ang", help="Current angle column(s).")
@click.option("--freq-col", help="Frequency column (Hz).")
@click.option("--rocof-col", help="ROCOF column (Hz/s).")
@click.option("--angles", type=click.Choice(["deg", "rad"]), help="Angle unit.")
@click.option("--voltage-unit", type=click.Choice(["V", "kV"]), help="Voltage magnitude unit.")
@click.option("--current-unit", type=click.Choice(["A", "kA"]), help="Current magnitude unit.")
@click.option("--epoch", is_flag=True, default=None, help="Timestamps are epoch seconds.")
@click.option("--tz", help="Time zone of timestamps written without an offset (default UTC).")
@click.option("--v-base", type=float, help="Voltage base, line-to-line kV (default: first row).")
@click.option("--s-base", type=float, help="Power base, MVA (default: first row |S|).")
@click.option("--quiet", is_flag=True)
@click.option("--force", is_flag=True, help="Overwrite the output.")
@user_errors
def read_pmu_cmd(
    csv, out, map_file, time_col, v_mag, v_ang, i_mag, i_ang, freq_col, rocof_col, angles,
    voltage_unit, current_unit, epoch, tz, v_base, s_base, quiet, force,
):  # fmt: skip
    """Per-unit V, P, Q (and f, ROCOF) from a PMU historian CSV of phasors.

    Duplicate timestamps (first kept), rows out of order (sorted) and gaps are reported
    on stderr.
    """
    check_outputs({"--out": out}, [csv] + ([map_file] if map_file else []), force)
    from loadbayes.recordings.pmu import load_map, read_pmu

    mapping = load_map(
        map_file, time=time_col, v_mag=v_mag, v_ang=v_ang, i_mag=i_mag, i_ang=i_ang,
        freq=freq_col, rocof=rocof_col, angle=angles, voltage=voltage_unit,
        current=current_unit, time_format="epoch" if epoch else None, timezone=tz,
        v_kv=_positive(v_base, "--v-base"), s_mva=_positive(s_base, "--s-base"),
    )  # fmt: skip
    rec = read_pmu(csv, mapping)
    _write(rec.data, out, force)
    for line in rec.report:
        click.echo(f"loadbayes: warning: {csv}: {line}", err=True)
    if not quiet:
        click.echo(
            f"{out}: {len(rec.data['t_s'])} rows from {rec.start}; v base "
            f"{rec.v_base_kv:.6g} kV l-l, s base {rec.s_base_mva:.6g} MVA",
            err=True,
        )


@click.command("events", cls=OneLineCommand)
@click.argument("record", type=click.Path(dir_okay=False))
@click.option("--out", required=True, type=click.Path(file_okay=False), help="Output folder.")
@click.option("--threshold", type=float, default=0.9, show_default=True,
              help="A sag starts below threshold x v_ref.")  # fmt: skip
@click.option("--hysteresis", type=float, default=0.02, show_default=True,
              help="It recovers above (threshold + hysteresis) x v_ref.")  # fmt: skip
@click.option("--min-duration", type=float, default=0.02, show_default=True,
              help="Shorter sags are ignored (s).")  # fmt: skip
@click.option("--pre", type=float, default=0.5, show_default=True, help="Seconds kept before.")
@click.option("--post", type=float, default=2.0, show_default=True,
              help="Seconds kept after the recovery.")  # fmt: skip
@click.option("--v-ref", type=float, help="Reference voltage (default: the record's median).")
@click.option("--format", "fmt", type=click.Choice(["csv", "parquet"]), default="csv",
              show_default=True)  # fmt: skip
@click.option("--quiet", is_flag=True)
@click.option("--force", is_flag=True, help="Overwrite event files already in the folder.")
@user_errors
def events_cmd(record, out, threshold, hysteresis, min_duration, pre, post, v_ref, fmt, quiet,
               force):  # fmt: skip
    """Find the voltage sags in a long t_s, v, p, q[, f] record; write one file per event.

    Writes OUT/event_001.csv ... (t_s from each event's start) and OUT/events.csv, the
    list of events (window, sag start, recovery, depth), as one transaction: all of them
    or none. With --force, event files of an earlier run that this run does not write are
    removed, so that the folder holds exactly the events events.csv lists.
    """
    import numpy as np

    from loadbayes.commands.output import stop_if_signalled
    from loadbayes.io.cells import DROP_HINT
    from loadbayes.io.errors import DataError
    from loadbayes.io.tables import read_columns, write_table
    from loadbayes.measurements.events import NO_DROP
    from loadbayes.recordings.events import cut_events, find_sags
    from loadbayes.recordings.record_file import record_events

    for opt, value in (("--threshold", threshold), ("--hysteresis", hysteresis),
                       ("--min-duration", min_duration), ("--pre", pre), ("--post", post),
                       ("--v-ref", v_ref)):  # fmt: skip
        if value is not None and not math.isfinite(value):
            raise UserError(f"{opt} {value}: must be a finite number")
        if opt in ("--min-duration", "--pre", "--post") and value < 0:
            raise UserError(f"{opt} {value:g}: must be a finite number >= 0")
    if out.strip() in ("", "-"):  # '' wrote into the working folder, '-' into a folder '-'
        raise UserError(f"--out {out!r}: give the folder to write to")
    folder = Path(out)
    if folder.exists() and not folder.is_dir():
        raise UserError(f"{out}: --out is a file, expected a folder")
    if not folder.parent.exists():
        raise UserError(f"{out}: folder {folder.parent} does not exist")
    # A `read comtrade` table: one event per sag inside a waveform segment, with its
    # station, bay and absolute time (recordings/record_file.py).
    found = record_events(
        record, threshold=threshold, hysteresis=hysteresis, min_duration_s=min_duration,
        pre_s=pre, post_s=post, v_ref=v_ref,
    )  # fmt: skip
    if found is not None:
        data, windows = found.data, found.windows
    else:
        # v may be 0 (an interruption in a long record): not refused here.
        try:
            data, _ = read_columns(
                record, ["t_s", "v", "p", "q"],
                optional=["angle_rad", "f", "rocof", "v2_re", "v2_im", "i2_re", "i2_im"],
            )  # fmt: skip
        except DataError as exc:  # the record is read whole: --drop-invalid is not offered
            raise DataError(exc.message.replace(DROP_HINT, NO_DROP), exc.path, exc.column,
                            exc.row) from None  # fmt: skip
        t = data["t_s"]
        back = np.flatnonzero(~(np.diff(t) > 0))
        if back.size:
            k = int(back[0]) + 1  # 0-based index of the offending sample = data row k + 1
            raise DataError(
                f"t_s must be strictly increasing (t = {t[k]:g} s after {t[k - 1]:g} s)",
                record,
                "t_s",
                k + 1,
            )
        try:
            windows = find_sags(
                t, data["v"], threshold=threshold, hysteresis=hysteresis,
                min_duration_s=min_duration, pre_s=pre, post_s=post, v_ref=v_ref,
            )  # fmt: skip
        except ValueError as exc:
            raise UserError(f"{record}: {exc}") from None
    names = [folder / f"event_{ev.index:03d}.{fmt}" for ev in windows]
    index = folder / "events.csv"
    stale = _stale_events(folder, set(names)) if force else []
    source = Path(record).resolve()
    for path in [*names, index, *stale]:
        if path.resolve() == source:
            raise UserError(f"{path}: --out {out} would overwrite the input record")
        if path.exists() and not force:
            raise UserError(f"{path}: exists; use --force to overwrite")
    made = not folder.exists()
    folder.mkdir(exist_ok=True)
    rows = [ev.as_row() | {"file": p.name} for ev, p in zip(windows, names, strict=True)]
    cols = ["index", "file", "start", "stop", "sag_start_s", "recovery_s", "duration_s",
            "v_min", "depth", "recovered", "n_sags"]  # fmt: skip
    if found is not None:  # the record's metadata, carried to each event's row
        rows = [r | x for r, x in zip(rows, found.extra, strict=True)]
        cols += list(found.extra[0]) if found.extra else []
    import pandas as pd

    targets = {p.name: str(p) for p in names} | {"events.csv": str(index)}
    try:
        with output_transaction(targets, force=force) as tx:
            for path, table in zip(names, cut_events(data, windows), strict=True):
                write_table(table, tx.temp(path.name), force=True)
                stop_if_signalled()
            write_table(pd.DataFrame(rows, columns=cols), tx.temp("events.csv"), force=True)
        _remove(stale)
    except BaseException:
        if made and not any(folder.iterdir()):
            folder.rmdir()  # the folder this run made, left empty: gone too
        raise
    if not quiet:
        click.echo(f"{record}: {len(windows)} event(s) written to {out}", err=True)
        shown = windows if len(windows) <= _LISTED else windows[: _LISTED // 2]
        for ev in shown:
            rec = f"recovered at {ev.recovery_s:.4g} s" if ev.recovered else "not recovered"
            click.echo(
                f"  event {ev.index}: sag at {ev.sag_start_s:.4g} s, depth {ev.depth:.3f}, "
                f"{ev.duration_s:.4g} s, {rec}",
                err=True,
            )
        if len(shown) < len(windows):
            click.echo(f"  ... and {len(windows) - len(shown)} more (listed in {index})", err=True)


#: More events than this are summarised on stderr (events.csv lists them all).
_LISTED = 20


def _stale_events(folder: Path, keep: set[Path]) -> list[Path]:
    # Event files of an earlier run (event_NNN.csv / .parquet) that this run does not write.
    import re

    if not folder.is_dir():
        return []
    pattern = re.compile(r"event_\d{3,}\.(csv|parquet)")
    return sorted(p for p in folder.iterdir() if pattern.fullmatch(p.name) and p not in keep)


def _remove(paths: list[Path]) -> None:
    # After the commit, with SIGINT/SIGTERM held back in every thread (a mask of this
    # thread alone let another thread take the signal, and the removal stop midway): the
    # folder then lists exactly the events of events.csv; a signal is delivered after.
    import contextlib

    from loadbayes.io.atomic import held_signals

    with held_signals():
        for p in paths:
            with contextlib.suppress(FileNotFoundError):
                p.unlink()
