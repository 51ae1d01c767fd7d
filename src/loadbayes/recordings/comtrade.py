"""Read COMTRADE recordings (IEEE C37.111 1991, 1999, 2013): validated, then scaled.

The ``.dat`` samples are decoded by the ``comtrade`` package (PyPI, 0.2): it reads the
1991, 1999 and 2013 revisions and the four data formats (ASCII, BINARY, BINARY32,
FLOAT32), vectorised with NumPy. Checked in its source before choosing it, it does not:

- apply the primary/secondary ratio (values come out in the channel's own ``P``/``S``
  side); this module scales them (:func:`read_comtrade`, ``side=``);
- locate errors: a malformed ``.cfg`` raises a bare ``ValueError`` with no line, and an
  unknown revision is only a warning;
- notice a truncated binary ``.dat``: it reads the whole records present and leaves the
  rest of the preallocated arrays at zero, silently;
- keep times in double precision unless asked (``use_double_precision``).

So the ``.cfg`` is parsed first, line by line, with every field checked
(:mod:`~loadbayes.recordings.comtrade_cfg`), and the ``.dat`` is checked against it
(file present, record count, binary record size, ASCII field count) before the package
reads it. Any problem is a
:class:`~loadbayes.io.errors.DataError` naming the file and the line (``.cfg``), line
(ASCII ``.dat``) or record (binary ``.dat``). Units ``V``/``kV``/``A``/``kA`` (and
``mV``, ``MV``, ``mA``) are converted to volts and amperes.

What a real recorder file adds, and how it is read:

- **Text encoding**: the ``.cfg`` is decoded as given (``encoding=``) or detected
  (UTF-8, GB18030 when the text holds CJK characters, else Latin-1).
- **Channels** are chosen by name, by 1-based number, or by bay (``bay=``: the three
  phase channels whose bay field ``ccbm`` or name holds the text). A bay without voltage
  channels (a transformer's currents) takes the first three-phase voltage of the file,
  the bus's, and says so in ``Waveforms.channels``.
- **Several sample rates** (the ``.cfg``'s rate table): each run of samples is a
  :class:`Segment`, ``"waveform"`` when it holds 8 or more samples per nominal cycle,
  ``"amplitude"`` otherwise (a recorder's slow segments hold one magnitude per phase and
  cycle, not waveform samples: :mod:`~loadbayes.recordings.record` keeps them as
  magnitudes and invents no P or Q from them).
- **Time**: the ``.dat`` time stamps (times ``timemult``) are used when they increase
  strictly; the rate table's nominal times otherwise. The stamps are the recorder's
  clock for each sample, and frequency-tracking recorders sample a fixed number of times
  per *actual* cycle, which the nominal rate table cannot say; the largest difference
  between the two is kept in ``Waveforms.clock_note``.
- **Per-channel skews** (microseconds) are returned in ``Waveforms.skew_s`` and applied
  by the phasor estimator (a skew of s seconds turns a phasor by 2 pi f0 s).
"""

from __future__ import annotations

import math
import os
import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from loadbayes.io.errors import DataError
from loadbayes.recordings.comtrade_cfg import AnalogChannel, CfgInfo, parse_cfg

__all__ = ["AnalogChannel", "CfgInfo", "Segment", "Waveforms", "parse_cfg", "read_comtrade"]

#: Fewest samples per nominal cycle for a segment to be read as waveform samples.
MIN_WAVEFORM_PER_CYCLE = 8

_UNIT_SCALE = {"V": 1.0, "kV": 1e3, "KV": 1e3, "MV": 1e6, "mV": 1e-3,
               "A": 1.0, "kA": 1e3, "KA": 1e3, "mA": 1e-3}  # fmt: skip
_PHASES = (("A", "B", "C"), ("R", "S", "T"), ("L1", "L2", "L3"), ("1", "2", "3"))


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


@dataclass(frozen=True)
class Waveforms:
    """Three-phase voltage and current waveforms in volts and amperes.

    Parameters
    ----------
    t_s : numpy.ndarray
        Sample times (s) from the first sample, shape (n,).
    v, i : numpy.ndarray
        Phase-to-neutral voltages and line currents, shape (3, n), phases a, b, c.
    f_nominal : float
        Nominal frequency (Hz) from the ``.cfg``.
    rate_hz : float
        Sampling rate (Hz).
    start : str
        First-sample time stamp as written in the ``.cfg``.
    channels : dict of str to str
        Which channels were used (``"va"`` -> channel name ...).
    uniform : bool
        Whether the samples are evenly spaced at ``rate_hz`` (records with several
        rates, or time stamps only, are not: resample them with
        :func:`loadbayes.recordings.phasors.to_cycle_grid`).
    segments : tuple of Segment
        The runs of samples at one rate (one segment for a one-rate file).
    skew_s : numpy.ndarray or None
        Per-channel time skews (s), shape (2, 3): voltages, currents.
    station, trigger, encoding : str
        Station name, trigger time stamp and the ``.cfg``'s text encoding.
    clock_note : str
        Which times were used (time stamps or rate table) and how far they disagree.
    choice : str
        How the channels were chosen (named, by bay, found by unit and phase).
    notes : tuple of str
        What else was decided reading the file (content after the declared samples
        ignored, a current phase that is zero throughout, ...), in plain words.
    """

    t_s: np.ndarray
    v: np.ndarray
    i: np.ndarray
    f_nominal: float
    rate_hz: float
    start: str
    channels: dict[str, str]
    uniform: bool = True
    segments: tuple[Segment, ...] = ()
    skew_s: np.ndarray | None = None
    station: str = ""
    trigger: str = ""
    encoding: str = ""
    clock_note: str = ""
    choice: str = ""
    notes: tuple[str, ...] = ()


# ----------------------------------------------------------------------- the .dat
def _find_dat(cfg: Path, where: str) -> Path | None:
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


def _declared(info: CfgInfo, dat: Path) -> tuple[bytes, int]:
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


def _check_dat(info: CfgInfo, dat: Path) -> None:
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


def _load_samples(info: CfgInfo, cfg: Path, dat: Path, raw: bytes):
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


# ------------------------------------------------------------------ channel choice
def _phase_key(ch: AnalogChannel) -> str | None:
    ph = ch.phase.strip().upper()
    if len(ph) == 2 and ph.endswith("N"):
        ph = ph[0]  # "AN": phase a to neutral
    for trio in _PHASES:
        if ph in trio:
            return "abc"[trio.index(ph)]
    tail = ch.name.strip().upper()
    for suffix in ("-N", "_N", "N"):
        if tail.endswith(suffix) and len(tail) > len(suffix) + 1:
            tail = tail[: -len(suffix)]  # "VA-N", "VAN": phase to neutral
            break
    for trio in _PHASES[:3]:
        for k, tag in enumerate(trio):
            if tail.endswith(tag) and len(tail) > len(tag):
                return "abc"[k]
    return None


def _duplicates(info: CfgInfo) -> dict[str, list[int]]:
    """Channel ids given to more than one analog channel, with their ``.cfg`` lines."""
    lines: dict[str, list[int]] = {}
    for ch in info.analog:
        lines.setdefault(ch.name, []).append(ch.line)
    return {k: v for k, v in lines.items() if len(v) > 1}


def _by_spec(info: CfgInfo, spec: str, kind: str) -> AnalogChannel:
    """A channel by name (``ch_id``) or by its 1-based number."""
    dup = _duplicates(info).get(spec)
    if dup:
        raise DataError(
            f"channel id {spec!r} is on lines {', '.join(map(str, dup))}: name the channel "
            f"by its 1-based number in --{kind}",
            info.path,
        )
    for ch in info.analog:
        if ch.name == spec:
            return ch
    if spec.strip().isdigit():
        for ch in info.analog:
            if ch.n == int(spec):
                return ch
        raise DataError(
            f"no analog channel number {spec} (channels 1 to {len(info.analog)}; --{kind})",
            info.path,
        )
    raise DataError(
        f"no analog channel {spec!r} (channels: {', '.join(ch.name for ch in info.analog)})",
        info.path,
    )


def _trios(chans: list[AnalogChannel]) -> list[list[AnalogChannel]]:
    """Three-phase sets, in file order: per bay (``ccbm``) a, b, c channels."""
    groups: dict[str, dict[str, AnalogChannel]] = {}
    for ch in chans:
        key = _phase_key(ch)
        if key is not None:
            groups.setdefault(ch.ccbm.strip(), {}).setdefault(key, ch)
    out = [[g["a"], g["b"], g["c"]] for g in groups.values() if len(g) == 3]
    if not out:  # no bay fields: the first a, b, c of the file
        found: dict[str, AnalogChannel] = {}
        for ch in chans:
            key = _phase_key(ch)
            if key is not None and key not in found:
                found[key] = ch
        if len(found) == 3:
            out = [[found["a"], found["b"], found["c"]]]
    return out


def _bays(info: CfgInfo) -> list[str]:
    return list(dict.fromkeys(ch.ccbm.strip() for ch in info.analog if ch.ccbm.strip()))


def _pick(
    info: CfgInfo, names: list[str] | None, kind: str, bay: str | None = None
) -> tuple[list[AnalogChannel], str]:
    """Three phase channels and how they were chosen."""
    if names is not None:
        if len(names) != 3:
            raise DataError(f"--{kind} takes three channel names, got {len(names)}", info.path)
        chans = [_by_spec(info, nm, kind) for nm in names]
        for k, ch in enumerate(chans):
            if ch in chans[:k]:
                raise DataError(
                    f"--{kind} names channel {ch.name!r} (line {ch.line}) twice: one channel "
                    "cannot be two phases",
                    info.path,
                )
        return chans, "named"
    base = "V" if kind == "voltage" else "A"
    cands = [ch for ch in info.analog if ch.unit.strip().upper().endswith(base)]
    cands = [ch for ch in cands if _unit_factor(ch.unit) is not None]
    how = "found by unit and phase"
    if bay is not None:
        in_bay = [ch for ch in cands if bay.lower() in (ch.ccbm + " " + ch.name).lower()]
        if in_bay:
            cands, how = in_bay, f"bay {bay!r}"
        elif kind == "current":
            raise DataError(
                f"bay {bay!r} has no current channels (bays: {', '.join(_bays(info))})",
                info.path,
            )
        else:
            how = f"bay {bay!r} has no voltage channels: the first three-phase voltage"
    trios = _trios(cands)
    dup = _duplicates(info)
    if dup and any(ch.name in dup for t in trios[:1] for ch in t) or (not trios and dup):
        name, lines = next(iter(dup.items()))
        raise DataError(
            f"channel id {name!r} is given to the channels on lines "
            f"{', '.join(map(str, lines))}: name the {kind} channels by their 1-based "
            f"numbers with --{kind} N,N,N",
            info.path,
        )
    if not trios:
        odd = [ch for ch in info.analog if _unit_factor(ch.unit) is None]
        hint = (
            f"; line {odd[0].line}: channel {odd[0].name!r} has unit {odd[0].unit.strip()[:20]!r}"
            f", not one of {', '.join(sorted(set(_UNIT_SCALE)))}"
            if odd
            else ""
        )
        raise DataError(
            f"cannot tell which three channels are the phase {kind}s; name them with "
            f"--{kind} A,B,C (names or 1-based numbers; analog channels: "
            f"{', '.join(ch.name for ch in info.analog)}){hint}",
            info.path,
        )
    if kind == "current" and bay is None and len(trios) > 1:
        raise DataError(
            f"{len(trios)} three-phase current sets ("
            + "; ".join(t[0].ccbm.strip() or t[0].name for t in trios)
            + "): choose one with --bay TEXT or --current A,B,C",
            info.path,
        )
    return trios[0], how


def _unit_factor(unit: str) -> float | None:
    unit = unit.strip()
    if unit in _UNIT_SCALE:
        return _UNIT_SCALE[unit]
    # Case is only meaningful for m/M (milli, mega); "kv", "KV", "a" are plain.
    return {"V": 1.0, "KV": 1e3, "A": 1.0, "KA": 1e3}.get(unit.upper())


def _scale(ch: AnalogChannel, values: np.ndarray, side: str, path: str) -> np.ndarray:
    unit = ch.unit.strip()
    factor = _unit_factor(unit)
    if factor is None:
        raise DataError(
            f"line {ch.line}: channel {ch.name!r} unit {unit[:20]!r} is not one of "
            f"{', '.join(sorted(set(_UNIT_SCALE)))}",
            path,
        )
    ratio = ch.primary / ch.secondary
    if side == "primary" and ch.pors == "S":
        factor *= ratio
    elif side == "secondary" and ch.pors == "P":
        factor /= ratio
    return values * factor


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


def _times(
    info: CfgInfo, raw: bytes, table: np.ndarray
) -> tuple[np.ndarray, str, np.ndarray | None]:
    """Sample times, which were used, and the other time base where they disagree widely.

    The time stamps when they increase and differ from the rate table by more than their
    resolution and less than 5% of the record's length; else the table (exact, where the
    stamps are rounded to whole units). Where both are plausible but disagree by more
    than 5% of the record's length, the third value is the stamps: the caller decides by
    the signal (:func:`_by_signal`). See the module docstring.
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


def _by_signal(
    info: CfgInfo, table: np.ndarray, stamps: np.ndarray, va: np.ndarray
) -> tuple[np.ndarray, str]:
    """The rate table or the time stamps, whichever puts the voltage at its nominal frequency.

    Both are plausible time bases and they disagree by more than 5% of the record; the
    one the phase-a voltage's zero crossings agree with is trusted: a wrong rate table
    would put a 50 Hz system at 16 Hz or 160 Hz, and every phasor window would be wrong.
    """
    tt = table - table[0]
    lo = 0
    sl = slice(0, va.size)
    for rate, end in info.rates:  # the first waveform run of the table
        if rate >= MIN_WAVEFORM_PER_CYCLE * info.f_nominal:
            sl = slice(lo, min(end, va.size))
            break
        lo = end
    f_table, f_stamps = _cycles_hz(tt[sl], va[sl]), _cycles_hz(stamps[sl], va[sl])
    f0 = info.f_nominal
    rates = ", ".join(f"{r:g}/s" for r, _ in info.rates)
    said = (
        f"the .cfg's rate table ({rates}, line {info.lines['rates'] + 1}) and the .dat's time "
        f"stamps disagree (record length {tt[-1]:.4g} s against {stamps[-1]:.4g} s); the "
        f"phase-a voltage crosses zero at {f_table:.4g} Hz by the table and "
        f"{f_stamps:.4g} Hz by the stamps"
    )
    ok_t = abs(f_table - f0) < 0.05 * f0
    ok_s = abs(f_stamps - f0) < 0.05 * f0
    if ok_s and not ok_t:
        return stamps, f"{said}: the time stamps are trusted (nominal {f0:g} Hz)"
    if ok_t:
        return tt, f"{said}: the rate table is trusted (nominal {f0:g} Hz)"
    raise DataError(
        f"{said}: neither agrees with the nominal {f0:g} Hz on line "
        f"{info.lines.get('frequency', '?')}; check the rate table and the line frequency",
        info.path,
    )


def _segments(info: CfgInfo, t: np.ndarray) -> tuple[Segment, ...]:
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


def _kind(t: np.ndarray, f0: float) -> str:
    step = float(np.median(np.diff(t))) if t.size > 1 else np.inf
    return "waveform" if 1.0 / (step * f0) >= MIN_WAVEFORM_PER_CYCLE - 1e-9 else "amplitude"


def read_comtrade(
    cfg_path: str | os.PathLike[str],
    *,
    voltage: list[str] | None = None,
    current: list[str] | None = None,
    bay: str | None = None,
    side: str = "primary",
    encoding: str | None = None,
) -> Waveforms:
    """Read three-phase voltages and currents from a COMTRADE record.

    Parameters
    ----------
    cfg_path : str or os.PathLike
        The ``.cfg``; the ``.dat`` beside it has the same stem.
    voltage, current : list of str, optional
        Names (``ch_id``) or 1-based numbers of the phase a, b, c channels. By default
        they are found from the unit (V or A, with a k/M/m prefix) and the phase field or
        name suffix (A/B/C, R/S/T, L1/L2/L3); several current sets need ``bay``.
    bay : str, optional
        Take the three phase channels of the bay whose ``ccbm`` field or channel name
        holds this text; a bay without voltages takes the first three-phase voltage.
    side : {"primary", "secondary"}
        Scale the values to the transformer's primary or secondary side with the
        ``.cfg``'s ratio (1999 and later).
    encoding : str, optional
        The ``.cfg``'s text encoding; detected by default.

    Returns
    -------
    Waveforms
        Times and phase waveforms (V, A), as sampled (see ``Waveforms.uniform`` and
        ``Waveforms.segments``).

    Raises
    ------
    DataError
        For a malformed ``.cfg`` (with its line), a missing or short ``.dat``, a
        missing sample in a channel used, or times that do not increase.
    """
    if side not in ("primary", "secondary"):
        raise ValueError(f"side must be 'primary' or 'secondary', not {side!r}")
    cfg = Path(cfg_path)
    info = parse_cfg(cfg, encoding=encoding)
    dat = _find_dat(cfg, info.path)
    if dat is None:
        raise DataError(f"data file {cfg.with_suffix('.dat').name} not found beside it", info.path)
    if info.n_samples < 2:
        raise DataError(
            f"line {info.lines['rates'] + len(info.rates)}: {info.n_samples} sample declared; "
            "a record needs at least two cycles",
            info.path,
        )
    _check_dat(info, dat)
    vch, vhow = _pick(info, voltage, "voltage", bay)
    ich, ihow = _pick(info, current, "current", bay)
    raw, extra = _declared(info, dat)
    notes = []
    if extra:
        notes.append(
            f"{dat.name}: {extra} bytes after the {info.n_samples} samples the .cfg declares "
            "were not read"
        )
    t, analog = _load_samples(info, cfg, dat, raw)
    t = t[: info.n_samples]
    dt = np.diff(t)
    if not np.all(dt > 0):
        k = int(np.argmax(dt <= 0))
        raise DataError(
            f"sample {k + 2}: sample times are not increasing (is the data file type "
            f"{info.format} on line {info.lines['format']} of {cfg.name} right?)",
            str(dat),
        )
    t, clock, other = _times(info, raw, t)
    del raw
    dt = np.diff(t)
    segments = _segments(info, t)
    # One rate: the .cfg's rate is exact (the times are rounded to the time base).
    # Several rates, or time stamps only (rate 0): sampled unevenly, resampled later.
    one_rate = len(info.rates) == 1 and info.rates[0][0] > 0
    rate = info.rates[0][0] if one_rate else float(1.0 / np.median(dt))
    uniform = one_rate or bool(np.max(np.abs(dt * rate - 1.0)) < 0.01)

    def stack(chans):
        out = []
        for ch in chans:
            idx = info.analog.index(ch)
            vals = analog[idx][: info.n_samples]
            bad = np.flatnonzero(~np.isfinite(vals))
            if bad.size and math.isfinite(ch.a * 2.0**31 + ch.b):
                raise DataError(
                    f"channel {ch.name!r}, sample {bad[0] + 1}: {_missing(info, ch)}", str(dat)
                )
            with np.errstate(over="ignore", invalid="ignore"):
                scaled = _scale(ch, vals, side, info.path)
            if not np.all(np.isfinite(scaled)):
                raise DataError(
                    f"line {ch.line}: channel {ch.name!r}: its values overflow when scaled "
                    f"(multiplier a = {ch.a:g}, ratio {ch.primary:g}/{ch.secondary:g})",
                    info.path,
                )
            out.append(scaled)
        return np.vstack(out)

    v_arr, i_arr = stack(vch), stack(ich)
    if other is not None:
        t, clock = _by_signal(info, t, other, v_arr[0])
        if t is other:  # the stamps, not the table: their own rate
            dt = np.diff(t)
            rate = float(1.0 / np.median(dt))
            uniform = bool(np.max(np.abs(dt * rate - 1.0)) < 0.01)
            segments = tuple(
                Segment(s.start, s.stop, 0.0, _kind(t[s.start : s.stop], info.f_nominal))
                for s in segments
            )
    notes += _dead_channels(vch, v_arr, ich, i_arr, info.path)
    names = {f"v{p}": ch.name for p, ch in zip("abc", vch, strict=True)}
    names.update({f"i{p}": ch.name for p, ch in zip("abc", ich, strict=True)})
    return Waveforms(
        t_s=t - t[0],
        v=v_arr,
        i=i_arr,
        f_nominal=info.f_nominal,
        rate_hz=rate,
        uniform=uniform,
        start=info.start,
        channels=names,
        segments=segments,
        skew_s=np.array([[ch.skew * 1e-6 for ch in vch], [ch.skew * 1e-6 for ch in ich]]),
        station=info.station,
        trigger=info.trigger,
        encoding=info.encoding,
        clock_note=clock,
        choice=f"voltages: {vhow}; currents: {ihow}",
        notes=tuple(notes),
    )


def _missing(info: CfgInfo, ch: AnalogChannel) -> str:
    """Why a sample is missing, in the words of the standard's markers."""
    if info.format == "BINARY" and info.revision == "1991":
        return (
            "missing value (raw 0xFFFF: COMTRADE 1991 BINARY marks a missing sample so, "
            "though later revisions read it as -1)"
        )
    if info.format == "BINARY":
        return "missing value (raw 0x8000, the BINARY missing-sample marker)"
    if info.format == "BINARY32":
        return "missing value (raw 0x80000000, the BINARY32 missing-sample marker)"
    if info.format == "FLOAT32":
        return "missing value (NaN or infinite, FLOAT32's missing-sample marker)"
    return "missing value (an empty, 99999, NaN or infinite cell)"


def _dead_channels(vch, v, ich, i, path: str) -> list[str]:
    """Refuse a dead or mis-scaled voltage phase; say where a current phase is dead.

    A voltage phase that is constant over the whole record (a multiplier of 0, an open
    VT fuse) puts the positive sequence at 2/3 of the truth; one whose typical magnitude
    differs from the others' by 3x or more has a unit or ratio wrong in the ``.cfg``
    (V among kV). A constant current phase can be real (an open pole): said, not refused.
    """
    notes = []
    spread = np.ptp(v, axis=1)
    for ch, sp in zip(vch, spread, strict=True):
        if sp == 0:
            raise DataError(
                f"line {ch.line}: voltage channel {ch.name!r} is constant over the whole "
                "record (a dead phase, or a multiplier of 0): the positive sequence would be "
                "2/3 of the truth; name another with --voltage",
                path,
            )
    typical = np.median(np.abs(v), axis=1)
    if typical.min() > 0 and typical.max() / typical.min() >= 3.0:
        lo, hi = int(np.argmin(typical)), int(np.argmax(typical))
        ratio = typical[hi] / typical[lo]
        raise DataError(
            f"line {vch[lo].line}: voltage channel {vch[lo].name!r} is {ratio:.3g}"
            f" times smaller than {vch[hi].name!r} over the record: its unit "
            f"({vch[lo].unit.strip()!r}) or ratio is wrong, or the phases are not one set",
            path,
        )
    for ch, sp in zip(ich, np.ptp(i, axis=1), strict=True):
        if sp == 0:
            notes.append(f"current channel {ch.name!r} is constant over the whole record")
    return notes
