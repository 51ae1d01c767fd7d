"""The Parquet reader: the schema's column types, batches of rows, and its errors.

Yields validated pieces (:class:`~loadbayes.io.cells._Piece`) of 65,536 rows.
"""

from __future__ import annotations

import os
from collections.abc import Iterator

import pyarrow as pa
import pyarrow.parquet as pq

from loadbayes.io.cells import (
    _is_numeric,
    _is_text,
    _one_line,
    _Piece,
    select_columns,
    validate_batch,
)
from loadbayes.io.errors import DataError
from loadbayes.io.sources import _open_file

# Parquet rows per batch: what is validated at a time, independent of ``chunk_rows`` so
# the same first bad row is found for any chunk size.
_PARQUET_BATCH_ROWS = 1 << 16


def _parquet_pieces(
    path: str | os.PathLike[str],
    name: str,
    required: list[str],
    extra: list[str],
    positive: frozenset[str],
    drop_invalid: bool,
) -> Iterator[_Piece]:
    try:
        with _open_file(path) as probe:
            if not probe.read(1):
                raise DataError("empty file", name)
        # pre_buffer (Arrow's default) would read all the columns asked for into memory
        # before the first batch; without it memory stays at about one row group.
        parquet = pq.ParquetFile(path, pre_buffer=False)
    except OSError as err:
        raise DataError(f"cannot open: {err.strerror or _one_line(err)}", name) from None
    except pa.ArrowException as err:
        raise DataError(f"not a readable Parquet file: {_one_line(err)}", name) from None
    with parquet:
        schema = parquet.schema_arrow
        present = select_columns(schema.names, required, extra, name)
        for col, i in present.items():
            _check_arrow_type(schema.field(i).type, name, col)
        start = 1
        batches = parquet.iter_batches(batch_size=_PARQUET_BATCH_ROWS, columns=list(present))
        while True:
            try:
                batch = next(batches)
            except StopIteration:
                break
            except (pa.ArrowException, OSError) as err:
                raise DataError(
                    f"corrupt Parquet file, read up to row {start - 1}: {_one_line(err)}", name
                ) from None
            if batch.num_rows:
                columns = {col: batch.column(col) for col in present}
                yield validate_batch(columns, start, positive, drop_invalid, name)
                start += batch.num_rows


def _check_arrow_type(kind: pa.DataType, name: str, col: str) -> None:
    value = kind.value_type if pa.types.is_dictionary(kind) else kind
    if not (_is_numeric(value) or _is_text(value)):
        raise DataError(f"has type {kind}, expected numbers", name, col)
