"""The CSV reader: header, separator, Arrow's streaming reader, and its errors.

Yields validated pieces (:class:`~loadbayes.io.cells._Piece`) of about 1 MiB of text.
"""

from __future__ import annotations

import contextlib
import csv
import gzip
import os
import re
import stat
import zlib
from collections.abc import Iterator
from typing import Any

import pyarrow as pa
import pyarrow.csv as pacsv

from loadbayes.io.cells import _one_line, _Piece, _show, select_columns, validate_batch
from loadbayes.io.encoding import SNIFF_BYTES, detect_encoding
from loadbayes.io.errors import DataError
from loadbayes.io.sources import STDIN, _open_binary

# CSV bytes per Arrow batch: what is validated at a time, independent of ``chunk_rows``
# so the same first bad row is found for any chunk size.
_CSV_BLOCK_BYTES = 1 << 20
_HEADER_MAX_BYTES = 1 << 20


def _read_header(fh: Any, name: str) -> tuple[list[str], str]:
    """Read and split the first line; leave ``fh`` at the first data row."""
    try:
        line = fh.readline(_HEADER_MAX_BYTES + 1)
    except (OSError, EOFError, zlib.error) as err:
        raise DataError(f"cannot read: {_one_line(err)}", name) from None
    if not line:
        raise DataError("empty file", name)
    if len(line) > _HEADER_MAX_BYTES:
        raise DataError("first line longer than 1 MiB: not a CSV file?", name)
    if line.startswith((b"\xff\xfe", b"\xfe\xff")):
        raise DataError("UTF-16 text (a spreadsheet's 'Unicode text'): save it as UTF-8 CSV", name)
    if b"\0" in line:
        raise DataError("header contains NUL bytes: a binary file, not CSV text?", name)
    text = _decode_header(line, _sniff(fh, line), name)
    text = text.rstrip("\r\n")
    if not text.strip():
        raise DataError("first line is empty; expected a header with the column names", name)
    if "\r" in text:
        raise DataError("lines end in a bare CR; save the file with LF or CRLF endings", name)
    sep = next((c for c in ",\t;" if c in text), ",")
    try:
        header = next(csv.reader([text], delimiter=sep))
    except csv.Error as err:
        raise DataError(f"cannot parse the header: {err}", name) from None
    return header, sep


def _sniff(fh: Any, line: bytes) -> tuple[bytes, bool]:
    """The header and the bytes after it (up to 1 MiB), ``fh`` left where it was.

    Returns the sample and whether it is the whole file. Standard input cannot be
    rewound: the header alone is the sample there.
    """
    try:
        if not fh.seekable():
            return line, False
        pos = fh.tell()
        try:
            more = fh.read(SNIFF_BYTES)
        finally:
            fh.seek(pos)
    except (OSError, EOFError, zlib.error, ValueError, AttributeError):
        return line, False
    return line + more, len(more) < SNIFF_BYTES


def _decode_header(line: bytes, sniffed: tuple[bytes, bool], name: str) -> str:
    """The header's text: UTF-8, or GB18030 when the file's first bytes are (CJK names).

    Latin-1 is not guessed: it decodes any byte, so a binary file or a file in another
    code page would pass with garbled names; the message says what it would read as.
    """
    try:
        return line.decode("utf-8-sig")
    except UnicodeDecodeError as err:
        byte = line[err.start]
    sample, complete = sniffed
    if b"\0" not in sample and detect_encoding(sample, complete=complete) == "gb18030":
        return line.decode("gb18030").lstrip("\ufeff")
    shown = line.decode("latin-1").rstrip("\r\n")
    readable = shown.isprintable() and b"\0" not in sample
    hint = (
        f" (as Latin-1 it reads {_show(shown)}: save the file as UTF-8)"
        if readable
        else ": a binary file, or saved in another encoding?"
    )
    raise DataError(f"header is not UTF-8 text (byte {byte:#04x}){hint}", name)


def _csv_pieces(
    path: str | os.PathLike[str],
    name: str,
    required: list[str],
    extra: list[str],
    positive: frozenset[str],
    drop_invalid: bool,
) -> Iterator[_Piece]:
    with _open_binary(path, name) as fh:
        header, sep = _read_header(fh, name)
        present = select_columns(header, required, extra, name)
        arrow_names = [f"f{i}" for i in range(len(header))]
        start = 1
        source = reader = None
        try:
            source = _native_stream(path, fh, name)
            # Cells come as raw bytes: decoding and parsing them here is what lets an
            # error name its row (Arrow's own conversion errors do not, when streaming).
            reader = pacsv.open_csv(
                source if source is not None else fh,
                read_options=pacsv.ReadOptions(
                    column_names=arrow_names, block_size=_CSV_BLOCK_BYTES, use_threads=False
                ),
                parse_options=pacsv.ParseOptions(delimiter=sep),
                convert_options=pacsv.ConvertOptions(
                    include_columns=[arrow_names[i] for i in present.values()],
                    column_types={arrow_names[i]: pa.binary() for i in present.values()},
                    null_values=[],
                    strings_can_be_null=False,
                    quoted_strings_can_be_null=False,
                ),
            )
            while True:
                try:
                    batch = reader.read_next_batch()
                except StopIteration:
                    break
                if batch.num_rows:
                    columns = {c: batch.column(arrow_names[i]) for c, i in present.items()}
                    yield validate_batch(columns, start, positive, drop_invalid, name)
                    start += batch.num_rows
        except (pa.ArrowException, OSError, EOFError, zlib.error) as err:
            if isinstance(err, pa.ArrowInvalid) and "Empty CSV file" in str(err):
                return
            raise _csv_read_error(err, start, name) from None
        finally:
            # An error (ours or the caller's, which closes this generator) must not leave
            # Arrow's reader behind: its read-ahead thread holds the file, and if the last
            # reference to a Python file goes during interpreter shutdown, the process
            # aborts ("terminate called without an active exception", exit 134).
            _close_quietly(reader)
            _close_quietly(source)


def _native_stream(path: str | os.PathLike[str], fh: Any, name: str) -> pa.NativeFile | None:
    """An Arrow file positioned where ``fh`` is (after the header); None to read ``fh``.

    Arrow then reads a plain file with no Python object in its I/O thread. Standard
    input and gzip files stay Python file objects (their position or their
    decompression is Python's).
    """
    if os.fspath(path) == STDIN or name.lower().endswith(".gz"):
        return None
    try:
        if not stat.S_ISREG(os.fstat(fh.fileno()).st_mode):
            return None  # a FIFO or a device: not seekable, read it as before
    except (AttributeError, OSError, ValueError):
        return None
    position = fh.tell()
    native = pa.OSFile(os.fspath(path), mode="r")
    try:
        native.seek(position)
    except BaseException:
        native.close()
        raise
    return native


def _close_quietly(resource: Any) -> None:
    if resource is None:
        return
    with contextlib.suppress(Exception):
        resource.close()


# Arrow's message for a row with too many or too few fields. Not an invalid_row_handler:
# Arrow decodes the row for it, and a row that is not UTF-8 then raises inside Arrow.
# Single-threaded reading is what puts the row number (counted from the first data row,
# blank lines skipped) in the message.
_RAGGED = re.compile(r"Row #(\d+): Expected (\d+) columns, got (\d+): (.*)", re.DOTALL)


def _csv_read_error(err: BaseException, start: int, name: str) -> DataError:
    ragged = _RAGGED.search(str(err)) if isinstance(err, pa.ArrowInvalid) else None
    if ragged:
        row, expected, found, text = ragged.groups()
        fields = "field" if found == "1" else "fields"
        message = f"{found} {fields} where the header has {expected}: {_show(text)}"
        return DataError(message, name, row=int(row))
    if isinstance(err, EOFError | zlib.error | gzip.BadGzipFile):
        return DataError(f"corrupt or truncated gzip file, read up to row {start - 1}", name)
    return DataError(f"cannot read as CSV past row {start - 1}: {_one_line(err)}", name)
