"""The COMTRADE ``.dat``: checked against its ``.cfg``, decoded, timed, cut into rate segments.

Part of :func:`~loadbayes.recordings.comtrade.read_comtrade` (its module docstring says
what is read how): the file beside the ``.cfg``, its size against the declared samples,
the samples decoded by the ``comtrade`` package, the recorder's time stamps against the
nominal rate table, and each rate segment told as waveform or amplitude samples.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from loadbayes.io.errors import DataError
from loadbayes.recordings.comtrade_cfg import CfgInfo

__all__ = [
    "MIN_WAVEFORM_PER_CYCLE",
    "Segment",
    "check_dat",
    "declared_bytes",
    "find_dat",
    "kind_by_signal",
    "load_samples",
    "sample_times",
    "segment_kind",
    "segments_of",
    "stamp_runs",
    "stamp_segments",
    "stamps_problem",
]


#: Fewest samples per nominal cycle for a segment to be read as waveform samples.
MIN_WAVEFORM_PER_CYCLE = 8


@dataclass(frozen=True)
class Segment:
    """One run of samples at one rate of the ``.cfg``'s rate table.

    Parameters
    ----------
    start, stop : int
        Sample indices ``[start, stop)`` (0-based) of the record.
    rate_hz : float
        The rate table's rate (Hz; 0 when the file has time stamps only).
    kind : {"waveform", "amplitude"}
        Waveform samples (8 or more per nominal cycle), or one magnitude per phase and
        cycle (a recorder's slow segment).
    """

    start: int
    stop: int
    rate_hz: float
    kind: str


def find_dat(cfg: Path, where: str) -> Path | None:
    """The ``.dat`` beside a ``.cfg`` (same stem, any case of the suffix), or None."""
    for suffix in (".dat", ".DAT", ".Dat"):
        cand = cfg.with_suffix(suffix)
        if cand.is_file():
            return cand
        if cand.is_dir():
            raise DataError(f"data file {cand.name} beside it is a folder", where)
        if cand.exists():
            raise DataError(
                f"data file {cand.name} beside it is not a regular file (a pipe or a device)",
                where,
            )
    return None


_BOM = b"\xef\xbb\xbf"


def declared_bytes(info: CfgInfo, dat: Path) -> tuple[bytes, int]:
    """The ``.dat``'s declared samples' bytes, and how many bytes follow them.

    Content after the samples the ``.cfg`` declares is not read (a file padded or
    appended to by a recorder): only its size is, so that it can be reported.
    """
    size = dat.stat().st_size
    if info.format != "ASCII":
        want = info.n_samples * info.record_bytes
        with open(dat, "rb") as fh:
            return fh.read(want), max(0, size - want)
    chunks, lines, used = [], 0, 0
    with open(dat, "rb") as fh:
        while lines < info.n_samples:
            block = fh.read(1 << 20)
            if not block:
                break
            if not chunks and block.startswith(_BOM):  # an editor's UTF-8 mark, not data
                block, used = block[len(_BOM) :], len(_BOM)
            have = block.count(b"\n")
            if lines + have >= info.n_samples:
                cut = -1
                for _ in range(info.n_samples - lines):
                    cut = block.index(b"\n", cut + 1)
                block = block[: cut + 1]
                have = info.n_samples - lines
            chunks.append(block)
            lines += have
            used += len(block)
    raw = b"".join(chunks)
    rest = size - used
    # A last line without its newline is part of the samples, not extra content.
    return raw, rest if lines >= info.n_samples else 0


def check_dat(info: CfgInfo, dat: Path) -> None:
    """Refuse a ``.dat`` whose size or fields do not hold the declared samples."""
    name = str(dat)
    n = info.n_samples
    if info.format == "ASCII":
        want = 2 + len(info.analog) + info.n_status
        with open(dat, "rb") as fh:
            count = 0
            for count, raw in enumerate(fh, start=1):  # noqa: B007
                if count > n:
                    break
                got = raw.count(b",") + 1
                if got != want:
                    raise DataError(
                        f"line {count}: {got} fields, expected {want} (sample number, time, "
                        f"{len(info.analog)} analog, {info.n_status} status per {info.path})",
                        name,
                    )
        if count < n:
            raise DataError(
                f"line {count + 1}: file ends after {count} samples; {info.path} line "
                f"{info.lines['rates'] + len(info.rates)} says {n}",
                name,
            )
        return
    size = dat.stat().st_size
    rec = info.record_bytes
    whole = size // rec
    if whole < n:
        part = f" and {size % rec} bytes of a cut record" if size % rec else ""
        raise DataError(
            f"record {whole + 1}: truncated binary data: {size} bytes hold {whole} whole "
            f"records of {rec} bytes{part}; {info.path} says {n} samples",
            name,
        )


def _locate_ascii_error(dat: Path, n: int) -> DataError:
    with open(dat, "rb") as fh:
        for k, raw in enumerate(fh, start=1):
            if k > n:
                break
            for j, cell in enumerate(raw.decode("latin-1").split(",")):
                cell = cell.strip()
                if cell == "":
                    return DataError(f"line {k}, field {j + 1}: empty cell", str(dat))
                try:
                    float(cell)
                except ValueError:
                    return DataError(
                        f"line {k}, field {j + 1}: {cell[:20]!r} is not a number", str(dat)
                    )
    return DataError("cannot be read as COMTRADE ASCII data", str(dat))


def load_samples(info: CfgInfo, cfg: Path, dat: Path, raw: bytes):
    """Times and scaled analog values decoded by the ``comtrade`` package."""
    import comtrade

    # The array options are read by the constructor (not by load()).
    rec = comtrade.Comtrade(ignore_warnings=True, use_numpy_arrays=True, use_double_precision=True)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            # The checked .cfg text (time stamps normalised) rather than the file.
            if info.format == "ASCII":
                rec.read(info.text, raw.decode("latin-1"))
            else:
                rec.read(info.text, raw)
    except (ValueError, IndexError, TypeError, comtrade.ComtradeError) as exc:
        if info.format == "ASCII":
            raise _locate_ascii_error(dat, info.n_samples) from None
        raise DataError(f"cannot be read: {exc}", str(dat)) from None
    return np.asarray(rec.time, dtype=float), [np.asarray(a, dtype=float) for a in rec.analog]


def _stamps(info: CfgInfo, raw: bytes) -> np.ndarray | None:
    """The ``.dat``'s own time stamps (s), or None where they are missing."""
    n = info.n_samples
    if info.format == "ASCII":
        try:
            cells = [ln.split(b",", 2)[1] for ln in raw.splitlines()[:n]]
            if any(not c.strip() for c in cells):
                return None
            stamps = np.array([float(c) for c in cells])
        except (IndexError, ValueError):
            return None
    else:
        rec = np.frombuffer(raw, dtype=np.uint8, count=n * info.record_bytes)
        stamps = rec.reshape(n, info.record_bytes)[:, 4:8].copy().view("<u4").ravel()
        if np.any(stamps == 0xFFFFFFFF):
            return None
        stamps = stamps.astype(float)
    return stamps * info.timemult * 1e-6


def sample_times(
    info: CfgInfo, raw: bytes, table: np.ndarray
) -> tuple[np.ndarray, str, np.ndarray | None]:
    """Sample times, which were used, and the other time base where they disagree widely.

    The time stamps when they increase and differ from the rate table by more than their
    resolution and less than 5% of the record's length; else the table (exact, where the
    stamps are rounded to whole units). Where both are plausible but disagree by more
    than 5% of the record's length, the third value is the stamps: the caller decides by
    the signal (:func:`kind_by_signal`). See the module docstring.
    """
    stamps = _stamps(info, raw)
    if stamps is None:
        return table, "times from the rate table (the .dat has no time stamps)", None
    stamps = stamps - stamps[0]
    if not np.all(np.diff(stamps) > 0):
        return table, "times from the rate table (the .dat's time stamps do not increase)", None
    has_table = all(r > 0 for r, _ in info.rates)
    if not has_table:
        return stamps, "times from the .dat's time stamps (no rate table)", None
    gap = float(np.max(np.abs(stamps - (table - table[0]))))
    span = float(table[-1] - table[0]) or 1.0
    if gap <= 1.01e-6 * info.timemult:  # agree to the stamps' resolution: the table is exact
        return (
            table,
            "times from the rate table (the time stamps agree to their resolution)",
            None,
        )
    if gap > 0.05 * span:
        return (
            table,
            (f"times from the rate table (the .dat's time stamps differ by up to {gap:.4g} s)"),
            stamps,
        )
    return (
        stamps,
        (
            f"times from the .dat's time stamps (the recorder's clock; they differ from the "
            f"nominal rate table by up to {gap * 1e3:.3g} ms)"
        ),
        None,
    )


def _cycles_hz(t: np.ndarray, x: np.ndarray) -> float:
    """The frequency of a waveform by its upward zero crossings (NaN with fewer than 3)."""
    x = x - np.median(x)
    up = np.flatnonzero((x[:-1] < 0) & (x[1:] >= 0))
    if up.size < 3:
        return float("nan")
    return (up.size - 1) / float(t[up[-1]] - t[up[0]])


#: Spacing ratio between neighbouring samples that starts a new run of the time stamps.
_RUN_JUMP = 1.5
#: More runs of even spacing than this and the stamps are not a recorder's rate segments.
_MAX_RUNS = 64


def stamp_runs(stamps: np.ndarray) -> list[tuple[int, int]]:
    """The stamps' runs of even spacing, ``[start, stop)`` sample indices.

    A run ends where the spacing jumps by more than 1.5x from one sample to the next (a
    recorder's change of rate); a frequency-tracking recorder's slow drift of a few per
    cent stays inside its run.
    """
    d = np.diff(stamps)
    jump = np.flatnonzero(np.abs(np.log(d[1:] / d[:-1])) > np.log(_RUN_JUMP)) + 1
    # d[k] spaces samples k and k+1; as in the rate table, the run whose first spacing is
    # d[k] starts at sample k (a segment's first sample is spaced at the previous rate).
    edges = [0, *(int(k) for k in jump), stamps.size]
    return [(a, b) for a, b in zip(edges[:-1], edges[1:], strict=True) if b > a]


def stamps_problem(stamps: np.ndarray, va: np.ndarray, f0: float) -> str:
    """Why strictly increasing stamps are not a usable time base ("" when they are).

    Usable: a few runs of even spacing (a recorder's rate segments), each waveform run
    putting the phase-a voltage within 5% of the nominal frequency.
    """
    runs = stamp_runs(stamps)
    if len(runs) > _MAX_RUNS:
        return f"their spacing jumps {len(runs) - 1} times (a recorder changes rate a few times)"
    for a, b in runs:
        if b - a < 2 or segment_kind(stamps[a:b], f0) != "waveform":
            continue
        f = _cycles_hz(stamps[a:b], va[a:b])
        if math.isfinite(f) and abs(f - f0) >= 0.05 * f0:
            step = float(np.median(np.diff(stamps[a:b])))
            return (
                f"samples {a + 1}-{b} are {step:.3g} s apart, which puts the phase-a voltage "
                f"at {f:.4g} Hz"
            )
    return ""


def stamp_segments(stamps: np.ndarray, f0: float) -> tuple[Segment, ...]:
    """Rate segments told from the stamps' own runs (rate 0: timed by the stamps)."""
    return tuple(Segment(a, b, 0.0, segment_kind(stamps[a:b], f0)) for a, b in stamp_runs(stamps))


def kind_by_signal(
    info: CfgInfo, table: np.ndarray, stamps: np.ndarray, va: np.ndarray
) -> tuple[np.ndarray, str, bool]:
    """The rate table or the time stamps, decided from the data; whether the stamps won.

    Both are plausible time bases and they disagree by more than 5% of the record. The
    stamps are the recorder's clock for each sample: when they increase strictly in a
    few runs of even spacing and put the voltage at its nominal frequency
    (:func:`stamps_problem`), they are trusted, whatever the table says (a one-sample slip
    in an ``endsamp`` or a rate of 0.001 would otherwise read amplitude samples as
    waveform, or the reverse, and make a sag of them). Else the table is trusted when its
    first waveform run puts the voltage at the nominal frequency; else neither is, and
    the record is refused.
    """
    tt = table - table[0]
    lo = 0
    sl = slice(0, va.size)
    for rate, end in info.rates:  # the first waveform run of the table
        if rate >= MIN_WAVEFORM_PER_CYCLE * info.f_nominal:
            sl = slice(lo, min(end, va.size))
            break
        lo = end
    f_table = _cycles_hz(tt[sl], va[sl])
    f0 = info.f_nominal
    rates = ", ".join(f"{r:g},{e}" for r, e in info.rates)
    line = info.lines["rates"] + 1
    where = f"line {line}" if len(info.rates) == 1 else f"lines {line}-{line + len(info.rates) - 1}"
    said = (
        f"the .cfg's rate table ({where}: {rates}) and the "
        f".dat's time stamps disagree (record length {tt[-1]:.4g} s against "
        f"{stamps[-1]:.4g} s)"
    )
    problem = stamps_problem(stamps, va, f0)
    if not problem:
        runs = len(stamp_runs(stamps))
        return (
            stamps,
            f"{said}: the time stamps are trusted (strictly increasing, {runs} run(s) of even "
            f"spacing, the voltage at its nominal {f0:g} Hz); check the rate table",
            True,
        )
    if abs(f_table - f0) < 0.05 * f0:
        return (
            tt,
            f"{said}: the rate table is trusted (the time stamps are not: {problem})",
            False,
        )
    raise DataError(
        f"{said}: neither is usable: the time stamps are not ({problem}), and the table puts "
        f"the voltage at {f_table:.4g} Hz, not the nominal {f0:g} Hz (line "
        f"{info.lines.get('frequency', '?')})",
        info.path,
    )


def segments_of(info: CfgInfo, t: np.ndarray) -> tuple[Segment, ...]:
    """The rate table's runs of samples, each told as waveform or amplitude samples."""
    out, start = [], 0
    for rate, end in info.rates:
        stop = min(end, t.size)
        if stop <= start:
            continue
        if rate > 0:
            per_cycle = rate / info.f_nominal
        else:
            span = np.diff(t[start:stop])
            per_cycle = 1.0 / (float(np.median(span)) * info.f_nominal) if span.size else 0.0
        kind = "waveform" if per_cycle >= MIN_WAVEFORM_PER_CYCLE - 1e-9 else "amplitude"
        out.append(Segment(start, stop, float(rate), kind))
        start = stop
    return tuple(out)


def segment_kind(t: np.ndarray, f0: float) -> str:
    """``"waveform"`` for 8 or more samples per nominal cycle, else ``"amplitude"``."""
    step = float(np.median(np.diff(t))) if t.size > 1 else np.inf
    return "waveform" if 1.0 / (step * f0) >= MIN_WAVEFORM_PER_CYCLE - 1e-9 else "amplitude"
