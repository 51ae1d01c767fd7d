"""The COMTRADE ``.cfg`` file (IEEE C37.111 1991, 1999, 2013), parsed and checked line by line.

One idea at about 480 lines: every field of the file checked in order, each with its line.

The ``comtrade`` package parses the ``.cfg`` too, but raises bare ``ValueError`` without a
line and only warns on an unknown revision; this parser checks every field first so that
a malformed file is refused with its name and line (:class:`~loadbayes.io.errors.DataError`).
"""

from __future__ import annotations

import math
import os
import re
from dataclasses import dataclass, field
from pathlib import Path

from loadbayes.io.encoding import has_cjk
from loadbayes.io.errors import DataError

__all__ = ["ENCODINGS", "FORMATS", "REVISIONS", "AnalogChannel", "CfgInfo", "parse_cfg"]

REVISIONS = ("1991", "1999", "2001", "2013")
FORMATS = {"ASCII": 0, "BINARY": 2, "BINARY32": 4, "FLOAT32": 4}  # bytes per analog value


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
    ccbm : str
        The circuit component being monitored (the bay, e.g. a transformer's breaker).
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
    ccbm: str = ""


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
    text : str
        The ``.cfg`` as checked, time stamps normalised (a missing fraction of a second
        written as ``.0``), for the ``comtrade`` package to read.
    trigger : str
        Trigger time stamp as written.
    encoding : str
        The text encoding the ``.cfg`` was read with (given, or detected).
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
    text: str = ""
    trigger: str = ""
    encoding: str = ""

    @property
    def n_samples(self) -> int:
        """Samples in the record (the last segment's end sample)."""
        return self.rates[-1][1]

    @property
    def record_bytes(self) -> int:
        """Bytes per binary record: sample number, time stamp, analog values, status words."""
        return 8 + len(self.analog) * FORMATS[self.format] + 2 * math.ceil(self.n_status / 16)


class _Lines:
    """The .cfg's lines, handed out one at a time with their 1-based number."""

    def __init__(self, text: str, path: str) -> None:
        # \r\n, \n and \r only: str.splitlines() also splits at U+0085, \v, \f and
        # 0x1C-0x1E, which a cp1252 name ("…" is byte 0x85) may hold.
        lines = re.split(r"\r\n|\n|\r", text)
        if lines and lines[-1] == "":
            lines.pop()  # the file's last line break ends a line, not one more
        self.lines = [ln.rstrip("\x1a").strip() for ln in lines]
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


_INDEX = re.compile(r"[0-9]+")
_NUMBER = re.compile(r"[+-]?(?:[0-9]+\.?[0-9]*|\.[0-9]+)(?:[eE][+-]?[0-9]+)?")
_DATE = re.compile(r"\d{1,2}/\d{1,2}/\d{2,4}")
_TIME = re.compile(r"(\d{1,2}):(\d{2}):(\d{1,2})(\.\d{1,12})?")


def _stamp(cells: list[str], line: int, path: str) -> str:
    """Check a ``dd/mm/yyyy,hh:mm:ss.ssssss`` line (either part may be empty); normalise it."""
    if cells == [""]:
        return ""
    if len(cells) != 2:
        raise DataError(f"line {line}: expected a time stamp date,time", path)
    date, time = cells
    if date and not _DATE.fullmatch(date):
        raise DataError(f"line {line}: date {date[:20]!r} is not dd/mm/yyyy", path)
    if date:
        # 1999 and later write dd/mm/yyyy, 1991 mm/dd/yy: either order, but a real day.
        d, m, _ = (int(x) for x in date.split("/"))
        if not (1 <= d <= 31 and 1 <= m <= 31 and min(d, m) <= 12):
            raise DataError(f"line {line}: date {date[:20]!r} is not a calendar date", path)
    m = _TIME.fullmatch(time)
    if time and m is None:
        raise DataError(f"line {line}: time {time[:20]!r} is not hh:mm:ss.ssssss", path)
    if m is not None and m.group(4) is None:
        time += ".0"  # the comtrade package needs a fraction of a second
    return f"{date},{time}"


#: Encodings tried in turn when none is given: UTF-8 (with or without a BOM), strictly;
#: then the Chinese national standard GB18030 (a superset of GBK and GB2312, what State
#: Grid recorders write), kept only when the text holds CJK characters, nearly all its
#: non-ASCII characters are two high bytes (:func:`_mostly_double_byte`), it encodes back
#: to the same bytes, and the high bytes do not read as accented letters inside Western
#: words (:func:`_latin_words`); then Windows-1252 when bytes 0x80-0x9F are present and
#: decode in it, else Latin-1, which decodes any byte (Western recorders' code pages).
ENCODINGS = ("utf-8-sig", "gb18030", "cp1252", "latin-1")


def _decode(raw: bytes, encoding: str | None, path: str) -> tuple[str, str]:
    """The text and the encoding it was read with (``encoding``, or detected)."""
    if encoding is not None:
        try:
            return raw.decode(encoding), encoding
        except LookupError:
            raise DataError(f"unknown text encoding {encoding!r}", path) from None
        except UnicodeDecodeError as exc:
            line = raw[: exc.start].count(b"\n") + 1
            raise DataError(
                f"line {line}: not {encoding} text (byte {exc.start + 1}); give another "
                "--encoding or none to detect it",
                path,
            ) from None
    try:
        return raw.decode("utf-8-sig"), "utf-8"
    except UnicodeDecodeError:
        pass
    try:
        text = raw.decode("gb18030")
        if (
            has_cjk(text)
            and _mostly_double_byte(text)
            and text.encode("gb18030") == raw
            and not _latin_words(raw)
        ):
            return text, "gb18030"
    except UnicodeDecodeError:
        pass
    if re.search(rb"[\x80-\x9f]", raw):
        # Bytes 0x80-0x9F are control codes in Latin-1 and letters and marks in Windows-1252
        # ("…", "€", "Š"), which Western recorders write.
        try:
            return raw.decode("cp1252"), "cp1252"
        except UnicodeDecodeError:
            pass
    return raw.decode("latin-1"), "latin-1"


#: Latin-1's letters (À..ÿ without × and ÷).
_LATIN_LETTERS = frozenset(range(0xC0, 0x100)) - {0xD7, 0xF7}


def _latin_words(raw: bytes) -> bool:
    """Whether every run of high bytes reads as accented letters inside Western words.

    GB18030 pairs two high bytes into one ideograph, and Latin-1 text whose accented
    letters come in pairs ("Größe": 0xF6 0xDF) passes :func:`_mostly_double_byte`. Such
    pairs sit inside a word, between ASCII letters, and are letters themselves; Chinese
    names are runs of several ideographs (four or more bytes: "主变", "高压侧") or sit
    beside digits and separators ("1号", "_I"). A text whose every run of high bytes is at
    most two Latin-1 letters with an ASCII letter on each side is taken as Latin-1.
    """
    runs = list(re.finditer(rb"[\x80-\xff]+", raw))
    if not runs:
        return False
    for m in runs:
        a, b = m.span()
        if b - a > 2 or not all(x in _LATIN_LETTERS for x in raw[a:b]):
            return False
        before, after = raw[a - 1 : a], raw[b : b + 1]
        if not (before.isalpha() and after.isalpha()):
            return False
    return True


def _mostly_double_byte(text: str) -> bool:
    # Chinese names are GB2312 characters, two bytes of 0xA1 and above (the real State
    # Grid record: 1,026 of 1,026). Latin-1 text decodes as GB18030 too where an accented
    # letter precedes an ASCII one ('Üb' -> 0xDC 0x62, an ideograph): such characters,
    # with a byte under 0x80, are few in Chinese text (rare GBK extensions) and most of
    # the non-ASCII ones in Western text. 90%: Chinese text with a few rare characters
    # stays GB18030; Western text needs nearly every accented letter doubled to be taken.
    high = [ch for ch in text if ord(ch) >= 0x80]
    double = sum(min(ch.encode("gb18030")) >= 0x80 for ch in high)
    return double >= 0.9 * len(high)


def _utf16(raw: bytes) -> bool:
    """Whether the bytes look like UTF-16 text: a byte-order mark, or every other byte 0."""
    if raw[:2] in (b"\xff\xfe", b"\xfe\xff"):
        return True
    head = raw[:64]
    return len(head) >= 8 and any(head[k::2].count(0) == len(head[k::2]) for k in (0, 1))


def _time_codes(rd: _Lines, name: str) -> None:
    """The 2013 revision's time_code,local_code and tmq_code,leapsec lines, when given.

    Optional as a pair; the ``comtrade`` package unpacks two fields from each and raised
    "not enough values to unpack" without a line for a cut one.
    """
    codes = rd.optional()
    if codes is None:
        return
    if len(codes) != 2:
        raise DataError(
            f"line {rd.n}: expected time_code,local_code (2013), got {len(codes)} field(s)", name
        )
    f, ln = rd.next("tmq_code,leapsec (2013)")
    if len(f) != 2:
        raise DataError(f"line {ln}: expected tmq_code,leapsec (2013), got {len(f)} field(s)", name)


def parse_cfg(path: str | os.PathLike[str], *, encoding: str | None = None) -> CfgInfo:
    """Parse and check a COMTRADE ``.cfg`` file, field by field.

    Parameters
    ----------
    path : str or os.PathLike
        The ``.cfg`` file.
    encoding : str, optional
        Its text encoding (any Python codec name: ``"gb18030"``, ``"utf-8"``,
        ``"latin-1"``, ...); by default detected (:data:`ENCODINGS`).

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
        hint = ""
        if p.suffix.lower() == ".dat":
            beside = [c for c in (p.with_suffix(".cfg"), p.with_suffix(".CFG")) if c.is_file()]
            hint = f": give its .cfg ({beside[0]})" if beside else ": give its .cfg"
        elif p.suffix.lower() == ".cff":
            hint = ": the single-file .cff form of 2013 is not read (split it into .cfg and .dat)"
        raise DataError("expected a COMTRADE .cfg file" + hint, name)
    raw = p.read_bytes()
    text, used = _decode(raw, encoding, name)
    if "\0" in text:
        if _utf16(raw):
            raise DataError("line 1: NUL bytes: UTF-16 text? read it with --encoding utf-16", name)
        line = len(re.split(r"\r\n|\n|\r", text[: text.index("\0")]))
        raise DataError(f"line {line}: NUL bytes: a binary file, not a .cfg?", name)
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
    if total < 0 or n_a < 0 or n_d < 0:
        raise DataError(
            f"line {ln_counts}: channel counts must be >= 0 (got {total}, {n_a}A, {n_d}D)", name
        )
    if total != n_a + n_d:
        raise DataError(
            f"line {ln_counts}: channel counts disagree: total {total} != "
            f"{n_a} analog + {n_d} status",
            name,
        )

    n_fields = 10 if revision == "1991" else 13
    analog = []
    for k in range(n_a):
        f, ln = rd.next(f"analog channel {k + 1} of {n_a}")
        # 10 fields is the 1991 form; later revisions add primary, secondary, PS. Files
        # labelled 1999 or 2013 with the short form are read as 1991 lines (ratio 1, P).
        if len(f) < 10:
            raise DataError(
                f"line {ln}: analog channel {k + 1} has {len(f)} fields, expected {n_fields} "
                f"(the counts on line {ln_counts} say {n_a} analog channels)",
                name,
            )
        if not _INDEX.fullmatch(f[0]):  # not isdigit(): '²' is a digit to it, not to int()
            raise DataError(
                f"line {ln}: analog channel index {f[0][:20]!r} is not a number "
                f"(the counts on line {ln_counts} say {n_a} analog channels)",
                name,
            )
        a = _num(f[5], "multiplier a", name, ln)
        b = _num(f[6], "offset b", name, ln, default=0.0)
        skew = _num(f[7], "skew", name, ln, default=0.0)
        if revision == "1991" or len(f) < 13:
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
            AnalogChannel(
                int(f[0]), f[1], f[2], f[4], a, b, skew, primary, secondary, pors, ln, f[3]
            )
        )
    for k in range(n_d):
        f, ln = rd.next(f"status channel {k + 1} of {n_d}")
        if len(f) < 3 or not _INDEX.fullmatch(f[0]):
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
    ln_freq = ln
    if 1.0 <= f_nominal < 10.0:
        raise DataError(
            f"line {ln}: line frequency {f[0][:20]} Hz is not a power system's (16.7, 25, "
            "50, 60 or 400 Hz expected): a slip in the .cfg?",
            name,
        )
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
    # A rate count that disagrees with the rate lines shows as a bad rate or time stamp.
    check_count = f"does nrates ({nrates}) on line {ln_rates} match the rate lines?"
    for _ in range(max(nrates, 1)):
        f, ln = rd.next("samp,endsamp")
        if len(f) != 2:
            raise DataError(f"line {ln}: expected samp,endsamp ({check_count})", name)
        try:
            samp = _num(f[0], "sample rate", name, ln)
            end = _num(f[1], "end sample", name, ln, int)
        except DataError as exc:
            raise DataError(f"{exc.message} ({check_count})", name) from None
        if samp < 0 or end < 1 or (rates and end <= rates[-1][1]):
            raise DataError(f"line {ln}: sample rate {samp} / end sample {end} invalid", name)
        if samp == 0 and nrates > 0:
            raise DataError(
                f"line {ln}: sample rate 0 with nrates {nrates} (line {ln_rates}): a record "
                "timed by its .dat time stamps alone has nrates 0 and rate 0",
                name,
            )
        rates.append((samp, end))
    start_cells, ln = rd.next("first-sample time stamp")
    if len(start_cells) == 2 and all(_NUMBER.fullmatch(c) for c in start_cells):
        raise DataError(
            f"line {ln}: expected the first-sample time stamp, got "
            f"{','.join(start_cells)[:30]!r}, a rate line: {check_count}",
            name,
        )
    rd.lines[ln - 1] = _stamp(start_cells, ln, name)
    trig_cells, ln = rd.next("trigger time stamp")
    rd.lines[ln - 1] = _stamp(trig_cells, ln, name)
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
    if revision == "2013":
        _time_codes(rd, name)
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
        lines={"counts": ln_counts, "rates": ln_rates, "format": ln_ft, "frequency": ln_freq},
        text="\n".join(rd.lines) + "\n",
        trigger=",".join(trig_cells),
        encoding=used,
    )
