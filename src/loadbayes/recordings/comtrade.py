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

So the ``.cfg`` is parsed here first, line by line, with every field checked, and the
``.dat`` is checked against it (file present, record count, binary record size, ASCII
field count) before the package reads it. Any problem is a
:class:`~loadbayes.io.errors.DataError` naming the file and the line (``.cfg``), line
(ASCII ``.dat``) or record (binary ``.dat``). Units ``V``/``kV``/``A``/``kA`` (and
``mV``, ``MV``, ``mA``) are converted to volts and amperes.
"""

from __future__ import annotations

import math
import os
import warnings
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from loadbayes.io.errors import DataError

__all__ = ["AnalogChannel", "CfgInfo", "Waveforms", "parse_cfg", "read_comtrade"]

REVISIONS = ("1991", "1999", "2001", "2013")
FORMATS = {"ASCII": 0, "BINARY": 2, "BINARY32": 4, "FLOAT32": 4}  # bytes per analog value
_UNIT_SCALE = {"V": 1.0, "kV": 1e3, "KV": 1e3, "MV": 1e6, "mV": 1e-3,
               "A": 1.0, "kA": 1e3, "KA": 1e3, "mA": 1e-3}  # fmt: skip
_PHASES = (("A", "B", "C"), ("R", "S", "T"), ("L1", "L2", "L3"), ("1", "2", "3"))


@dataclass(frozen=True)
class AnalogChannel:
    """One analog channel as the ``.cfg`` describes it.

    Parameters
    ----------
    n : int
        Channel index (1-based) as written in the file.
    name, phase, unit : str
        ``ch_id``, ``ph`` and ``uu`` fields.
    a, b, skew : float
        Value = a * raw + b; time skew in microseconds.
    primary, secondary : float
        Transformer ratio (1999 and later; 1 for 1991).
    pors : str
        ``"P"`` if ``a, b`` give primary values, ``"S"`` if secondary.
    line : int
        Line of the ``.cfg`` (1-based), for error messages.
    """

    n: int
    name: str
    phase: str
    unit: str
    a: float
    b: float
    skew: float
    primary: float
    secondary: float
    pors: str
    line: int


@dataclass(frozen=True)
class CfgInfo:
    """What the ``.cfg`` says, checked.

    Parameters
    ----------
    path : str
        The ``.cfg`` as named by the user.
    revision : str
        ``"1991"``, ``"1999"``, ``"2001"`` or ``"2013"``.
    station, device : str
        Station name and recording device.
    analog : list of AnalogChannel
        Analog channels.
    n_status : int
        Number of status (digital) channels.
    f_nominal : float
        Line frequency (Hz).
    rates : list of (float, int)
        (sample rate in Hz, last sample number) per rate segment; rate 0 means that the
        ``.dat`` time stamps are used.
    format : str
        ``ASCII``, ``BINARY``, ``BINARY32`` or ``FLOAT32``.
    timemult : float
        Time-stamp multiplier.
    start : str
        First-sample time stamp as written.
    lines : dict of str to int
        Line numbers of the key fields (``"counts"``, ``"rates"``, ``"format"``).
    """

    path: str
    revision: str
    station: str
    device: str
    analog: list[AnalogChannel]
    n_status: int
    f_nominal: float
    rates: list[tuple[float, int]]
    format: str
    timemult: float
    start: str
    lines: dict[str, int] = field(default_factory=dict)

    @property
    def n_samples(self) -> int:
        """Samples in the record (the last segment's end sample)."""
        return self.rates[-1][1]

    @property
    def record_bytes(self) -> int:
        """Bytes per binary record: sample number, time stamp, analog values, status words."""
        return 8 + len(self.analog) * FORMATS[self.format] + 2 * math.ceil(self.n_status / 16)


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
    """

    t_s: np.ndarray
    v: np.ndarray
    i: np.ndarray
    f_nominal: float
    rate_hz: float
    start: str
    channels: dict[str, str]


# ----------------------------------------------------------------------- the .cfg
class _Lines:
    """The .cfg's lines, handed out one at a time with their 1-based number."""

    def __init__(self, text: str, path: str) -> None:
        self.lines = [ln.rstrip("\x1a").strip() for ln in text.splitlines()]
        self.path = path
        self.n = 0

    def next(self, what: str) -> tuple[list[str], int]:
        self.n += 1
        if self.n > len(self.lines):
            raise DataError(f"line {self.n}: file ends early, expected {what}", self.path)
        return [c.strip() for c in self.lines[self.n - 1].split(",")], self.n

    def optional(self) -> list[str] | None:
        if self.n >= len(self.lines) or not self.lines[self.n]:
            return None
        return self.next("")[0]


def _num(cell: str, what: str, path: str, line: int, kind=float, default=None):
    if cell == "" and default is not None:
        return default
    try:
        value = kind(cell)
    except ValueError:
        raise DataError(f"line {line}: {what} {cell[:20]!r} is not a number", path) from None
    if kind is float and not math.isfinite(value):
        raise DataError(f"line {line}: {what} {cell!r} is not finite", path)
    return value


def _decode(raw: bytes) -> str:
    try:
        return raw.decode("utf-8-sig")
    except UnicodeDecodeError:
        return raw.decode("latin-1")  # older recorders write Windows code pages


def parse_cfg(path: str | os.PathLike[str]) -> CfgInfo:
    """Parse and check a COMTRADE ``.cfg`` file, field by field.

    Parameters
    ----------
    path : str or os.PathLike
        The ``.cfg`` file.

    Returns
    -------
    CfgInfo
        The configuration.

    Raises
    ------
    DataError
        Naming the file and the line: unknown revision, channel counts that disagree,
        a non-numeric field, a missing line, an unknown data format.
    """
    name = os.fspath(path)
    p = Path(path)
    if not p.is_file():
        raise DataError("file not found" if not p.exists() else "not a file", name)
    if p.suffix.lower() != ".cfg":
        raise DataError("expected a COMTRADE .cfg file", name)
    text = _decode(p.read_bytes())
    if "\0" in text:
        raise DataError("line 1: NUL bytes: a binary file, not a .cfg?", name)
    rd = _Lines(text, name)

    head, ln = rd.next("station_name,rec_dev_id,rev_year")
    if len(head) == 2 or (len(head) == 3 and head[2] == ""):
        revision = "1991"  # the 1991 revision has no year field
    elif len(head) == 3:
        revision = head[2]
        if revision not in REVISIONS:
            raise DataError(
                f"line {ln}: unknown COMTRADE revision {revision[:20]!r} "
                f"(supported: {', '.join(REVISIONS)})",
                name,
            )
    else:
        raise DataError(f"line {ln}: expected station_name,rec_dev_id[,rev_year]", name)

    counts, ln_counts = rd.next("TT,##A,##D")
    if (
        len(counts) != 3
        or not counts[1].upper().endswith("A")
        or not counts[2].upper().endswith("D")
    ):
        raise DataError(f"line {ln_counts}: expected channel counts TT,##A,##D", name)
    total = _num(counts[0], "total channel count", name, ln_counts, int)
    n_a = _num(counts[1][:-1], "analog channel count", name, ln_counts, int)
    n_d = _num(counts[2][:-1], "status channel count", name, ln_counts, int)
    if n_a < 0 or n_d < 0 or total != n_a + n_d:
        raise DataError(
            f"line {ln_counts}: channel counts disagree: total {total} != "
            f"{n_a} analog + {n_d} status",
            name,
        )

    n_fields = 10 if revision == "1991" else 13
    analog = []
    for k in range(n_a):
        f, ln = rd.next(f"analog channel {k + 1} of {n_a}")
        if len(f) < 10 or (revision != "1991" and len(f) < 13):
            raise DataError(
                f"line {ln}: analog channel {k + 1} has {len(f)} fields, expected {n_fields} "
                f"(the counts on line {ln_counts} say {n_a} analog channels)",
                name,
            )
        if not f[0].isdigit():
            raise DataError(
                f"line {ln}: analog channel index {f[0][:20]!r} is not a number "
                f"(the counts on line {ln_counts} say {n_a} analog channels)",
                name,
            )
        a = _num(f[5], "multiplier a", name, ln)
        b = _num(f[6], "offset b", name, ln, default=0.0)
        skew = _num(f[7], "skew", name, ln, default=0.0)
        if revision == "1991":
            primary, secondary, pors = 1.0, 1.0, "P"
        else:
            primary = _num(f[10], "primary", name, ln)
            secondary = _num(f[11], "secondary", name, ln)
            pors = f[12].upper()
            if pors not in ("P", "S"):
                raise DataError(f"line {ln}: PS field {f[12][:20]!r} must be P or S", name)
            if primary <= 0 or secondary <= 0:
                raise DataError(f"line {ln}: primary and secondary must be > 0", name)
        analog.append(
            AnalogChannel(int(f[0]), f[1], f[2], f[4], a, b, skew, primary, secondary, pors, ln)
        )
    for k in range(n_d):
        f, ln = rd.next(f"status channel {k + 1} of {n_d}")
        if len(f) < 3 or not f[0].isdigit():
            raise DataError(
                f"line {ln}: expected status channel {k + 1} of {n_d} "
                f"(the counts on line {ln_counts}), got {len(f)} fields",
                name,
            )

    f, ln = rd.next("line frequency")
    if len(f) != 1:
        raise DataError(
            f"line {ln}: expected the line frequency alone, got {len(f)} fields (do the "
            f"channel counts on line {ln_counts} match the channel lines?)",
            name,
        )
    f_nominal = _num(f[0], "line frequency", name, ln)
    if not 1.0 <= f_nominal <= 1000.0:
        # An analog-channel line here means the counts on line 2 were too small.
        raise DataError(
            f"line {ln}: line frequency {f[0][:20]!r} out of range (is the analog count on "
            f"line {ln_counts} right?)",
            name,
        )
    f, ln_rates = rd.next("nrates")
    nrates = _num(f[0], "nrates", name, ln_rates, int)
    if nrates < 0:
        raise DataError(f"line {ln_rates}: nrates must be >= 0", name)
    rates = []
    for _ in range(max(nrates, 1)):
        f, ln = rd.next("samp,endsamp")
        if len(f) != 2:
            raise DataError(f"line {ln}: expected samp,endsamp", name)
        samp = _num(f[0], "sample rate", name, ln)
        end = _num(f[1], "end sample", name, ln, int)
        if samp < 0 or end < 1 or (rates and end <= rates[-1][1]):
            raise DataError(f"line {ln}: sample rate {samp} / end sample {end} invalid", name)
        rates.append((samp, end))
    start_cells, _ = rd.next("first-sample time stamp")
    rd.next("trigger time stamp")
    f, ln_ft = rd.next("data file type")
    fmt = f[0].upper()
    if fmt not in FORMATS:
        raise DataError(
            f"line {ln_ft}: unknown data file type {f[0][:20]!r} (expected ASCII, BINARY, "
            "BINARY32 or FLOAT32)",
            name,
        )
    timemult = 1.0
    if revision != "1991":
        rest = rd.optional()
        if rest is not None and rest[0]:
            timemult = _num(rest[0], "time multiplier", name, rd.n)
            if timemult <= 0:
                raise DataError(f"line {rd.n}: time multiplier must be > 0", name)
    return CfgInfo(
        path=name,
        revision=revision,
        station=head[0],
        device=head[1],
        analog=analog,
        n_status=n_d,
        f_nominal=f_nominal,
        rates=rates,
        format=fmt,
        timemult=timemult,
        start=",".join(start_cells),
        lines={"counts": ln_counts, "rates": ln_rates, "format": ln_ft},
    )


# ----------------------------------------------------------------------- the .dat
def _find_dat(cfg: Path) -> Path | None:
    for suffix in (".dat", ".DAT", ".Dat"):
        cand = cfg.with_suffix(suffix)
        if cand.is_file():
            return cand
    return None


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
                    continue
                try:
                    float(cell)
                except ValueError:
                    return DataError(
                        f"line {k}, field {j + 1}: {cell[:20]!r} is not a number", str(dat)
                    )
    return DataError("cannot be read as COMTRADE ASCII data", str(dat))


def _load_samples(info: CfgInfo, cfg: Path, dat: Path):
    import comtrade

    # The array options are read by the constructor (not by load()).
    rec = comtrade.Comtrade(ignore_warnings=True, use_numpy_arrays=True, use_double_precision=True)
    encoding = "utf-8"
    try:
        cfg.read_bytes().decode("utf-8")
    except UnicodeDecodeError:
        encoding = "latin-1"
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            rec.load(str(cfg), str(dat), encoding=encoding)
    except (ValueError, IndexError, comtrade.ComtradeError) as exc:
        if info.format == "ASCII":
            raise _locate_ascii_error(dat, info.n_samples) from None
        raise DataError(f"cannot be read: {exc}", str(dat)) from None
    return np.asarray(rec.time, dtype=float), [np.asarray(a, dtype=float) for a in rec.analog]


# ------------------------------------------------------------------ channel choice
def _phase_key(ch: AnalogChannel) -> str | None:
    ph = ch.phase.strip().upper()
    for trio in _PHASES:
        if ph in trio:
            return "abc"[trio.index(ph)]
    tail = ch.name.strip().upper()
    for trio in _PHASES[:3]:
        for k, tag in enumerate(trio):
            if tail.endswith(tag) and len(tail) > len(tag):
                return "abc"[k]
    return None


def _pick(info: CfgInfo, names: list[str] | None, kind: str) -> list[AnalogChannel]:
    by_name = {ch.name: ch for ch in info.analog}
    if names is not None:
        if len(names) != 3:
            raise DataError(f"--{kind} takes three channel names, got {len(names)}", info.path)
        out = []
        for nm in names:
            if nm not in by_name:
                raise DataError(
                    f"no analog channel {nm!r} (channels: {', '.join(by_name)})", info.path
                )
            out.append(by_name[nm])
        return out
    base = "V" if kind == "voltage" else "A"
    cands = [ch for ch in info.analog if ch.unit.strip().upper().endswith(base)]
    cands = [ch for ch in cands if ch.unit.strip() in _UNIT_SCALE]
    found: dict[str, AnalogChannel] = {}
    for ch in cands:
        key = _phase_key(ch)
        if key is not None and key not in found:
            found[key] = ch
    if len(found) != 3:
        raise DataError(
            f"cannot tell which three channels are the phase {kind}s; name them with "
            f"--{kind} A,B,C (analog channels: {', '.join(by_name)})",
            info.path,
        )
    return [found["a"], found["b"], found["c"]]


def _scale(ch: AnalogChannel, values: np.ndarray, side: str, path: str) -> np.ndarray:
    unit = ch.unit.strip()
    if unit not in _UNIT_SCALE:
        raise DataError(
            f"line {ch.line}: channel {ch.name!r} unit {unit[:20]!r} is not one of "
            f"{', '.join(sorted(set(_UNIT_SCALE)))}",
            path,
        )
    ratio = ch.primary / ch.secondary
    factor = _UNIT_SCALE[unit]
    if side == "primary" and ch.pors == "S":
        factor *= ratio
    elif side == "secondary" and ch.pors == "P":
        factor /= ratio
    return values * factor


def read_comtrade(
    cfg_path: str | os.PathLike[str],
    *,
    voltage: list[str] | None = None,
    current: list[str] | None = None,
    side: str = "primary",
) -> Waveforms:
    """Read three-phase voltages and currents from a COMTRADE record.

    Parameters
    ----------
    cfg_path : str or os.PathLike
        The ``.cfg``; the ``.dat`` beside it has the same stem.
    voltage, current : list of str, optional
        Names (``ch_id``) of the phase a, b, c channels. By default they are found from
        the unit (V or A, with a k/M/m prefix) and the phase field or name suffix
        (A/B/C, R/S/T, L1/L2/L3).
    side : {"primary", "secondary"}
        Scale the values to the transformer's primary or secondary side with the
        ``.cfg``'s ratio (1999 and later).

    Returns
    -------
    Waveforms
        Times and phase waveforms (V, A), uniformly sampled.

    Raises
    ------
    DataError
        For a malformed ``.cfg`` (with its line), a missing or short ``.dat``, a
        missing sample in a channel used, or several sampling rates.
    """
    if side not in ("primary", "secondary"):
        raise ValueError(f"side must be 'primary' or 'secondary', not {side!r}")
    cfg = Path(cfg_path)
    info = parse_cfg(cfg)
    dat = _find_dat(cfg)
    if dat is None:
        raise DataError(f"data file {cfg.with_suffix('.dat').name} not found beside it", info.path)
    _check_dat(info, dat)
    vch = _pick(info, voltage, "voltage")
    ich = _pick(info, current, "current")
    t, analog = _load_samples(info, cfg, dat)
    t = t[: info.n_samples]
    if info.rates[0][0] > 0 and len(info.rates) > 1:
        raise DataError(
            f"line {info.lines['rates']}: {len(info.rates)} sampling rates; one rate is "
            "supported (resample the record first)",
            info.path,
        )
    dt = np.diff(t)
    if dt.size == 0 or not np.all(dt > 0):
        raise DataError("sample times are not increasing", str(dat))
    # The .cfg's rate is exact; the times may be rounded to the time base.
    step = 1.0 / info.rates[0][0] if info.rates[0][0] > 0 else float(np.median(dt))
    if np.max(np.abs(dt - step)) > 0.01 * step:
        k = int(np.argmax(np.abs(dt - step)))
        msg = f"sample {k + 2}: uneven sampling ({dt[k]:.3g} s vs {step:.3g} s)"
        raise DataError(msg, str(dat))

    def stack(chans):
        out = []
        for ch in chans:
            idx = info.analog.index(ch)
            vals = analog[idx][: info.n_samples]
            bad = np.flatnonzero(~np.isfinite(vals))
            if bad.size:
                raise DataError(
                    f"channel {ch.name!r}, sample {bad[0] + 1}: missing value", str(dat)
                )
            out.append(_scale(ch, vals, side, info.path))
        return np.vstack(out)

    names = {f"v{p}": ch.name for p, ch in zip("abc", vch, strict=True)}
    names.update({f"i{p}": ch.name for p, ch in zip("abc", ich, strict=True)})
    return Waveforms(
        t_s=t - t[0],
        v=stack(vch),
        i=stack(ich),
        f_nominal=info.f_nominal,
        rate_hz=1.0 / step,
        start=info.start,
        channels=names,
    )
