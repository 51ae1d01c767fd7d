"""Find a fleet's input files and read them as chunks of rows tagged with their bus.

Inputs (``loadbayes fit zip DATA --by bus_id``):

- one CSV or Parquet table with a bus column;
- a folder, searched recursively, of Parquet and CSV files, including hive-partitioned
  layouts such as ``bus_id=17/part-0.parquet`` (the bus, and a class, may then come
  from the folder name rather than a column);
- a glob pattern such as ``'meters/*.csv'``.

Each file is one partition of the map-reduce. The numeric columns are read and checked
by :func:`loadbayes.io.tables.iter_chunks` (so a malformed file is refused by name,
column and row as everywhere in loadbayes); the bus and class columns, which may be
text, are read alongside with Arrow, in step with the same rows.
"""

from __future__ import annotations

import glob
import os
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.compute as pc
import pyarrow.csv as pacsv
import pyarrow.parquet as pq

from loadbayes.io.encoding import detect_encoding
from loadbayes.io.errors import DataError
from loadbayes.io.tables import CSV_SUFFIXES, PARQUET_SUFFIXES, iter_chunks

_HEADER_BYTES = 1 << 20

__all__ = ["BusChunk", "Partition", "ReadSpec", "find_partitions", "id_kinds", "read_partition"]


@dataclass(frozen=True)
class Partition:
    """One input file, and the ``key=value`` pairs of its hive folders."""

    path: str
    hive: dict[str, str] = field(default_factory=dict)


@dataclass(frozen=True)
class ReadSpec:
    """Which columns to read and how (the options of ``fit zip``)."""

    by: str = "bus_id"
    class_col: str | None = None
    v_col: str = "v"
    p_col: str = "p"
    q_col: str | None = "q"
    q_required: bool = False
    v_base: float | None = None
    s_base: float | None = None
    drop_invalid: bool = False
    chunk_rows: int = 1 << 18
    #: Time column (seconds or ISO timestamps): read and checked increasing within a bus
    #: and a file; the sums do not use it.
    t_col: str | None = None


@dataclass(frozen=True)
class BusChunk:
    """Consecutive valid rows of one file, with the bus (and class) of each row."""

    cols: dict[str, np.ndarray]  # "v", "p", maybe "q", in per unit
    bus: pa.Array  # strings
    cls: pa.Array | None  # strings, or None without a class column
    rows: np.ndarray  # 1-based data rows of the file
    n_dropped: int
    spaced: tuple[str, ...] = ()  # bus ids as written with spaces around them (a few)


def _is_data_file(name: str, *, text: bool = True) -> bool:
    low = name.lower()
    suffixes = CSV_SUFFIXES + PARQUET_SUFFIXES
    if not text:
        suffixes = tuple(s for s in suffixes if not s.startswith(".txt"))
    return low.endswith(suffixes) and not Path(name).name.startswith((".", "_"))


def _hive(path: Path, root: Path) -> dict[str, str]:
    out = {}
    for part in path.relative_to(root).parts[:-1]:
        key, sep, value = part.partition("=")
        if sep:
            out[key] = value
    return out


def find_partitions(data: str) -> list[Partition]:
    """List the input files of a fleet, sorted by path (the order does not matter).

    Parameters
    ----------
    data : str
        A file, a folder (searched recursively for ``.csv``, ``.csv.gz``, ``.parquet``
        and ``.pq``; hidden and ``_``-prefixed files such as ``_SUCCESS``, and ``.txt``
        notes, are skipped) or a glob pattern.

    Returns
    -------
    list of Partition

    Raises
    ------
    DataError
        If nothing readable is found.
    """
    p = Path(data)
    if p.is_dir():
        # A folder's .txt files are notes (README.txt), not data: a .txt table is read
        # when named, or matched by a glob.
        files = sorted(f for f in p.rglob("*") if f.is_file() and _is_data_file(f.name, text=False))
        if not files:
            raise DataError("no CSV or Parquet files in this folder", data)
        return [Partition(str(f), _hive(f, p)) for f in files]
    if p.is_file():
        return [Partition(str(p))]
    if any(c in data for c in "*?["):
        files = sorted(f for f in glob.glob(data, recursive=True) if _is_data_file(f))
        if not files:
            raise DataError("no CSV or Parquet files match this pattern", data)
        return [Partition(f) for f in files]
    raise DataError("no such file or folder", data)


def _label_batches(part: Partition, col: str, name: str) -> Iterator[pa.Array] | None:
    """Batches of one text-like column as strings, or None if the file lacks it."""
    path = part.path
    if path.lower().endswith(PARQUET_SUFFIXES):
        try:
            pf = pq.ParquetFile(path, pre_buffer=False)
        except (OSError, pa.ArrowException):
            return None  # iter_chunks reports the unreadable file by name
        if col not in pf.schema_arrow.names:
            pf.close()
            return None

        def parquet_batches() -> Iterator[pa.Array]:
            with pf:
                for batch in pf.iter_batches(batch_size=1 << 16, columns=[col]):
                    yield pc.cast(batch.column(0), pa.string())

        return parquet_batches()
    try:
        with pa.input_stream(path, compression="detect") as fh:
            head = fh.read(_HEADER_BYTES)
    except (OSError, pa.ArrowException):
        return None
    # Bus names in a spreadsheet's code page (GB18030) are read as such; any other
    # bytes that are not UTF-8 are refused by row below.
    encoding = detect_encoding(head, complete=len(head) < _HEADER_BYTES)
    encoding = "gb18030" if encoding == "gb18030" else "utf-8"
    codec = "utf-8-sig" if encoding == "utf-8" else encoding
    first = head.split(b"\n", 1)[0].decode(codec, "replace").lstrip("\ufeff").rstrip("\r")
    sep = next((c for c in ",\t;" if c in first), ",")
    import csv

    header = next(csv.reader([first], delimiter=sep), [])
    if col not in header:
        return None

    def csv_batches() -> Iterator[pa.Array]:
        reader = pacsv.open_csv(
            pa.input_stream(path, compression="detect"),
            read_options=pacsv.ReadOptions(block_size=1 << 20),
            parse_options=pacsv.ParseOptions(delimiter=sep),
            convert_options=pacsv.ConvertOptions(
                include_columns=[col],
                column_types={col: pa.binary()},
                strings_can_be_null=True,
            ),
        )
        row = 1
        for batch in reader:
            yield _as_text(batch.column(0), encoding, name, col, row)
            row += batch.num_rows

    return csv_batches()


def _as_text(cells: pa.Array, encoding: str, name: str, col: str, row: int) -> pa.Array:
    """Raw cells as strings in the file's encoding; a cell that is not refused by row."""
    if encoding == "utf-8":
        try:
            return pc.cast(cells, pa.string())
        except pa.ArrowInvalid:
            pass  # find the cell below
    out = []
    for i, cell in enumerate(cells.to_pylist()):
        try:
            out.append(None if cell is None else cell.decode(encoding))
        except UnicodeDecodeError:
            raise DataError(
                f"not {encoding.upper()} text: {cell[:20]!r} (save the file as UTF-8)",
                name,
                col,
                row + i,
            ) from None
    return pa.array(out, pa.string())


class _Aligned:
    """Hands out the labels of consecutive rows, whatever the batches they came in."""

    def __init__(self, batches: Iterator[pa.Array], name: str, col: str) -> None:
        self.batches = batches
        self.buf: list[pa.Array] = []
        self.have = 0
        self.name, self.col = name, col

    def take(self, n: int, first_row: int) -> pa.Array:
        while self.have < n:
            try:
                arr = next(self.batches)
            except StopIteration:
                raise DataError(
                    "fewer rows in this column than in the numeric ones",
                    self.name,
                    self.col,
                    first_row + self.have,
                ) from None
            except (pa.ArrowException, OSError) as err:
                msg = str(err).splitlines()[0] if str(err) else type(err).__name__
                raise DataError(f"cannot read: {msg}", self.name, self.col) from None
            self.buf.append(arr)
            self.have += len(arr)
        joined = pa.concat_arrays(self.buf) if len(self.buf) > 1 else self.buf[0]
        out, rest = joined.slice(0, n), joined.slice(n)
        self.buf = [rest] if len(rest) else []
        self.have = len(rest)
        nulls = out.null_count
        if nulls:
            i = int(np.flatnonzero(out.is_null().to_numpy(zero_copy_only=False))[0])
            raise DataError("missing value", self.name, self.col, first_row + i)
        return out


def _trimmed(labels: pa.Array, spaced: set[str] | None = None) -> pa.Array:
    """Ids without the spaces around them; an id of spaces only is missing.

    A spreadsheet's ' bus07 ' and 'bus07' are one bus: read as written they became two.
    A few ids as written go in ``spaced``, to say what merged (' sp', 'sp ': bus 'sp').
    """
    trimmed = pc.utf8_trim_whitespace(labels)
    if spaced is not None and len(spaced) < 6:  # a few, for the note
        changed = pc.fill_null(pc.not_equal(labels, trimmed), False)
        if pc.any(changed).as_py():
            spaced.update(labels.filter(changed).unique().to_pylist()[:6])
    return pc.if_else(pc.equal(trimmed, ""), pa.scalar(None, pa.string()), trimmed)


def _labels(
    part: Partition, col: str | None, name: str, what: str, spaced: set[str] | None = None
) -> _Aligned | str | None:
    """Labels from a column, else a constant from a hive folder, else None."""
    if col is None:
        return None
    batches = _label_batches(part, col, name)
    if batches is not None:
        return _Aligned((_trimmed(b, spaced) for b in batches), name, col)
    if col in part.hive:
        return part.hive[col]
    have = _columns_said(part.path, col)
    if what == "bus":
        raise DataError(
            f"no column {col!r}{have} and no folder named {col}=...; --by names the bus "
            "column (a file that is not data? name the data files with a glob, "
            "e.g. 'folder/**/*.parquet')",
            name,
        )
    raise DataError(f"no column {col!r}{have} and no folder named {col}=... (--class-col)", name)


def _columns_said(path: str, col: str) -> str:
    """' (the columns are ...; did you mean ...?)' for a missing column, as for V, P, Q."""
    import csv

    from loadbayes.io.cells import columns_named

    try:
        if path.lower().endswith(PARQUET_SUFFIXES):
            header = list(pq.read_schema(path).names)
        else:
            with pa.input_stream(path, compression="detect") as fh:
                first = fh.read(_HEADER_BYTES).split(b"\n", 1)[0]
            line = first.decode("utf-8", "replace").lstrip("\ufeff").rstrip("\r")
            sep = next((c for c in ",\t;" if c in line), ",")
            header = next(csv.reader([line], delimiter=sep), []) if line.strip() else []
    except (OSError, pa.ArrowException):
        return ""
    if not header:
        return " (the file is empty)"
    return f" ({columns_named(col, header)})"


def _check_folder_key(arr: pa.Array, value: str, name: str, col: str, first_row: int) -> None:
    """A column and the hive folder ``col=value`` above it must name the same bus/class."""
    differs = pc.not_equal(arr, pa.scalar(value, pa.string()))
    if not pc.any(differs).as_py():
        return
    i = int(np.flatnonzero(differs.to_numpy(zero_copy_only=False))[0])
    shown = arr[i].as_py()
    raise DataError(
        f"{shown!r} here, but the file is in folder {col}={value}: which is it? "
        "(rename the folder or fix the column)",
        name,
        col,
        first_row + i,
    )


def id_kinds(parts: list[Partition], col: str) -> dict[str, str]:
    """How each file stores the ids of ``col``: ``integer``, ``float`` or ``text``.

    Ids are compared as text (``1`` and ``1.0`` in Parquet both read as ``'1'``), so
    files that store them differently can merge buses that were meant apart, or keep
    apart ``'1.0'`` in a CSV and ``1`` in a Parquet file. Returns a kind per file (a
    hive folder key and a CSV column are text); a Parquet file that cannot be read is
    left out (the reader refuses it by name).
    """
    kinds: dict[str, str] = {}
    for part in parts:
        kind = "text"
        if part.path.lower().endswith(PARQUET_SUFFIXES):
            try:
                schema = pq.read_schema(part.path)
            except (OSError, pa.ArrowException):
                continue
            if col in schema.names:
                t = schema.field(col).type
                t = t.value_type if pa.types.is_dictionary(t) else t
                kind = (
                    "integer"
                    if pa.types.is_integer(t)
                    else "float"
                    if pa.types.is_floating(t) or pa.types.is_decimal(t)
                    else "text"
                )
        kinds[part.path] = kind
    return kinds


def read_partition(part: Partition, spec: ReadSpec) -> Iterator[BusChunk]:
    """Read one file in chunks of valid rows, each row tagged with its bus and class.

    Raises
    ------
    DataError
        Naming the file, and the column and row where there is one, for any input
        :func:`loadbayes.io.tables.iter_chunks` refuses, a missing bus column, or a
        missing bus id.
    """
    name = part.path
    spaced: set[str] = set()
    bus_src = _labels(part, spec.by, name, "bus", spaced)
    cls_src = _labels(part, spec.class_col, name, "class")
    optional = [spec.q_col] if spec.q_col and not spec.q_required else []
    required = [spec.v_col, spec.p_col] + ([spec.q_col] if spec.q_col and spec.q_required else [])
    for chunk in iter_chunks(
        name,
        required,
        optional=optional,
        positive=[spec.v_col],
        chunk_rows=spec.chunk_rows,
        drop_invalid=spec.drop_invalid,
    ):
        cols = {"v": chunk.data[spec.v_col], "p": chunk.data[spec.p_col]}
        if spec.q_col and spec.q_col in chunk.data:
            cols["q"] = chunk.data[spec.q_col]
        if spec.v_base is not None:
            cols["v"] = cols["v"] / spec.v_base
        if spec.s_base is not None:
            for key in ("p", "q"):
                if key in cols:
                    cols[key] = cols[key] / spec.s_base
        labels = []
        for src, col in ((bus_src, spec.by), (cls_src, spec.class_col)):
            if src is None:
                labels.append(None)
            elif isinstance(src, str):
                labels.append(pa.array([src] * chunk.n_rows, pa.string()))
            else:
                arr = src.take(chunk.n_rows_read, chunk.start_row)
                if col in part.hive:
                    _check_folder_key(arr, part.hive[col], name, col, chunk.start_row)
                if chunk.n_dropped:
                    keep = np.ones(chunk.n_rows_read, bool)
                    keep[chunk.dropped_rows - chunk.start_row] = False
                    arr = arr.filter(pa.array(keep))
                labels.append(arr)
        yield BusChunk(cols, labels[0], labels[1], chunk.rows, chunk.n_dropped, tuple(spaced))


def display(path: str) -> str:
    """The file name as shown in messages (relative to the working folder if inside it)."""
    try:
        return os.path.relpath(path)
    except ValueError:  # another drive
        return path
