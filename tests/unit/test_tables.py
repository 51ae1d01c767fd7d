"""Measurement readers and writers: each bad input gives a located DataError."""

from __future__ import annotations

import gc
import gzip
import io
import itertools
import os
import pickle
import sys
import warnings
from decimal import Decimal
from pathlib import Path

import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.compute as pc
import pyarrow.parquet as pq
import pytest

from loadbayes.io import sources
from loadbayes.io.atomic import atomic_write
from loadbayes.io.cells import _parse_cell
from loadbayes.io.errors import DataError
from loadbayes.io.tables import Chunk, iter_chunks, read_columns, write_table


def write(folder: Path, name: str, content: str | bytes) -> Path:
    path = folder / name
    if isinstance(content, str):
        content = content.encode("utf-8")
    path.write_bytes(content)
    return path


def write_parquet(folder: Path, name: str, table: pa.Table, **kw) -> Path:
    path = folder / name
    pq.write_table(table, path, **kw)
    return path


def error_of(path, columns=("v", "p"), **kw) -> DataError:
    with pytest.raises(DataError) as info:
        read_columns(path, list(columns), **kw)
    err = info.value
    text = str(err)
    assert "\n" not in text
    assert Path(os.fspath(path)).name in text
    return err


# --- DataError ------------------------------------------------------------------------


def test_data_error_formats_one_line_and_omits_missing_parts():
    err = DataError("non-numeric value 'abc'", "bus18.csv", "v", 17)
    assert str(err) == "bus18.csv: column 'v', row 17: non-numeric value 'abc'"
    assert (err.path, err.column, err.row, err.message) == (
        "bus18.csv",
        "v",
        17,
        "non-numeric value 'abc'",
    )
    assert str(DataError("empty file", "a.csv")) == "a.csv: empty file"
    assert str(DataError("bad", row=3)) == "row 3: bad"
    assert str(DataError("bad\nthing", "we\nird.csv")) == "we\\nird.csv: bad\\nthing"
    assert isinstance(err, ValueError)


def test_data_error_survives_pickling():
    err = pickle.loads(pickle.dumps(DataError("bad", "a.csv", "v", 2)))
    assert (err.path, err.column, err.row, str(err)) == (
        "a.csv",
        "v",
        2,
        "a.csv: column 'v', row 2: bad",
    )


# --- good files -----------------------------------------------------------------------


def test_csv_and_parquet_read_the_same(tmp_path):
    frame = pd.DataFrame({"t": [0.0, 0.5, 1.0], "v": [1.0, 0.98, 1.02], "p": [3, 2, 1]})
    csv_path = tmp_path / "a.csv"
    frame.to_csv(csv_path, index=False)
    pq_path = tmp_path / "a.parquet"
    frame.to_parquet(pq_path, index=False)
    for path in (csv_path, pq_path, str(csv_path)):
        data, n_dropped = read_columns(path, ["v", "p"], optional=["t", "q"])
        assert list(data) == ["v", "p", "t"]
        assert n_dropped == 0
        for col, values in data.items():
            assert values.dtype == np.float64
            np.testing.assert_array_equal(values, frame[col].to_numpy(float))


def test_csv_dialects(tmp_path):
    cases = {
        "crlf.csv": "v,p\r\n1,2\r\n3,4\r\n",
        "bom.csv": "\ufeffv,p\n1,2\n3,4\n",
        "quoted.csv": '"v","p"\n"1","2"\n3,"4"\n',
        "spaces.csv": "v,p\n 1 ,\t2\n3 , 4\n",
        "semicolon.txt": "v;p\n1;2\n3;4\n",
        "tabs.txt": "v\tp\n1\t2\n3\t4\n",
        "blank_lines.csv": "v,p\n1,2\n\n3,4\n\n",
        "no_final_newline.csv": "v,p\n1,2\n3,4",
        "extra.csv": "x,v,y,p,z\nA,1,B,2,C\nD,3,E,4,F\n",
    }
    for name, content in cases.items():
        data, _ = read_columns(write(tmp_path, name, content), ["v", "p"])
        np.testing.assert_array_equal(data["v"], [1.0, 3.0], err_msg=name)
        np.testing.assert_array_equal(data["p"], [2.0, 4.0], err_msg=name)


def test_gzip_csv(tmp_path):
    path = write(tmp_path, "a.csv.gz", gzip.compress(b"v,p\n1,2\n3,4\n"))
    data, _ = read_columns(path, ["v", "p"])
    np.testing.assert_array_equal(data["v"], [1.0, 3.0])


def test_number_syntax_and_correct_rounding(tmp_path):
    cells = {
        "1e5": 1e5,
        "+1.5": 1.5,
        ".5": 0.5,
        "5.": 5.0,
        "1E-3": 1e-3,
        "0.1000000000000000055511151231257827": 0.1,
        "99999999999999999999": 1e20,  # pandas' default parser gives 1.0000000000000002e20
        "9007199254740993": 9007199254740992.0,
        "1e-400": 0.0,
        "2.2250738585072014e-308": 2.2250738585072014e-308,
        "4.9e-324": 5e-324,
    }
    path = write(tmp_path, "a.csv", "v\n" + "\n".join(cells) + "\n")
    data, _ = read_columns(path, ["v"])
    assert data["v"].tolist() == list(cells.values())


def test_random_floats_round_trip_exactly(tmp_path):
    rng = np.random.default_rng(1)
    x = rng.standard_normal(5000) * 10.0 ** rng.integers(-300, 300, 5000)
    path = write(tmp_path, "a.csv", "v\n" + "\n".join(repr(float(a)) for a in x) + "\n")
    np.testing.assert_array_equal(read_columns(path, ["v"])[0]["v"], x)


def test_stdin(monkeypatch):
    stdin = io.TextIOWrapper(io.BytesIO(b"v,p\n1,2\n3,x\n"))
    monkeypatch.setattr(sys, "stdin", stdin)
    with pytest.raises(DataError, match=r"^<stdin>: column 'p', row 2: non-numeric value 'x'$"):
        read_columns("-", ["v", "p"])
    monkeypatch.setattr(sys, "stdin", io.TextIOWrapper(io.BytesIO(b"v\n1\n2\n")))
    assert read_columns("-", ["v"])[0]["v"].tolist() == [1.0, 2.0]


def test_chunks_are_float64_contiguous_writeable(tmp_path):
    path = write(tmp_path, "a.csv", "v,p\n" + "1,2\n" * 10)
    chunks = list(iter_chunks(path, ["v", "p"], chunk_rows=4))
    assert [(c.start_row, c.n_rows_read) for c in chunks] == [(1, 4), (5, 4), (9, 2)]
    for chunk in chunks:
        assert isinstance(chunk, Chunk)
        for values in chunk.data.values():
            assert values.dtype == np.float64
            assert values.flags.c_contiguous and values.flags.writeable


# --- bad CSV: (content, read_columns arguments, what the error must say) ---------------

BAD_CSV = {
    "non-numeric row 3": (
        "v,p\n1,2\n3,4\n5,abc\n",
        {},
        "column 'p', row 3: non-numeric value 'abc'",
    ),
    "text in first row": ("v,p\nx,2\n", {}, "column 'v', row 1: non-numeric value 'x'"),
    "bool": ("v,p\nTrue,2\n", {}, "column 'v', row 1: non-numeric value 'True'"),
    "decimal comma": ("v;p\n1,5;2\n", {}, "column 'v', row 1: non-numeric value '1,5'"),
    "thousands": ("v,p\n1_000,2\n", {}, "column 'v', row 1: non-numeric value '1_000'"),
    "hex": ("v,p\n0x10,2\n", {}, "column 'v', row 1: non-numeric value '0x10'"),
    "arabic digits": ("v,p\n\u0661\u0662,2\n", {}, "column 'v', row 1: non-numeric value"),
    "long value": (
        "v,p\n" + "y" * 60 + ",2\n",
        {},
        "column 'v', row 1: non-numeric value '" + "y" * 20 + "'...",
    ),
    "empty cell": ("v,p\n1,2\n3,\n", {}, "column 'p', row 2: empty cell"),
    "NA": ("v,p\n1,2\nNA,4\n", {}, "column 'v', row 2: missing value 'NA'"),
    "nan": ("v,p\n1,nan\n", {}, "column 'p', row 1: missing value 'nan'"),
    "inf": ("v,p\n1,2\n-inf,3\n", {}, "column 'v', row 2: infinite value '-inf'"),
    "beyond float64": ("v,p\n1e999,2\n", {}, "column 'v', row 1: infinite value '1e999'"),
    "zero": ("v,p\n1,2\n0,2\n", {"positive": ["v"]}, "column 'v', row 2: value '0' is not > 0"),
    "negative": (
        "v,p\n-1.5,2\n",
        {"positive": ["v"]},
        "column 'v', row 1: value '-1.5' is not > 0",
    ),
    "fewer fields": ("v,p\n1,2\n3\n", {}, "row 2: 1 field where the header has 2"),
    "ragged, not UTF-8": (b"v,p\n1,2\n3,\xe9,4\n", {}, "row 2: 3 fields where the header has 2"),
    "more fields": ("v,p\n1,2\n3,4,5\n", {}, "row 2: 3 fields where the header has 2"),
    "missing column": ("x,p\n1,2\n", {}, "column 'v': not found; the columns are 'x', 'p'"),
    "wrong case": (
        "V,p\n1,2\n",
        {},
        "column 'v': not found; the columns are 'V', 'p' (did you mean 'V'?)",
    ),
    "space": (
        " v,p\n1,2\n",
        {},
        "column 'v': not found; the columns are ' v', 'p' (did you mean ' v'?)",
    ),
    "duplicate": ("v,p,v\n1,2,3\n", {}, "column 'v': named 2 times in the header (columns 1, 3)"),
    "duplicate optional": (
        "v,p,t,t\n1,2,3,4\n",
        {"optional": ["t"]},
        "column 't': named 2 times in the header (columns 3, 4)",
    ),
    "header only": ("v,p\n", {}, "no data rows"),
    "header and blank lines": ("v,p\n\n\n", {}, "no data rows"),
    "empty file": ("", {}, "empty file"),
    "blank first line": ("\nv,p\n1,2\n", {}, "first line is empty"),
    "non-UTF-8 cell": (b"v,p\n1,2\n3,\xe94\n", {}, "column 'p', row 2: not UTF-8 text"),
    "non-UTF-8 header": (b"v,p\xe9\n1,2\n", {}, "header is not UTF-8 text"),
    "binary": (b"\x89PNG\r\n\x1a\n\x00\x00\x00\rIHDR", {}, "header is not UTF-8 text"),
    "NUL": (b"v,p\x00\n1,2\n", {}, "header contains NUL bytes"),
    "all dropped": (
        "v,p\n,1\nnan,2\n",
        {"drop_invalid": True},
        "no valid rows: all 2 data rows were dropped",
    ),
    "non-numeric with drop": (
        "v,p\n,1\nx,2\n",
        {"drop_invalid": True},
        "column 'v', row 2: non-numeric",
    ),
}


@pytest.mark.parametrize("case", list(BAD_CSV))
def test_bad_csv(tmp_path, case):
    content, kwargs, expected = BAD_CSV[case]
    path = write(tmp_path, "bus18.csv", content)
    assert str(error_of(path, **kwargs)).startswith(f"{path}: {expected}")


def test_error_attributes(tmp_path):
    path = write(tmp_path, "bus18.csv", "v,p\n1,2\n3,4\n5,abc\n")
    err = error_of(path)
    assert (err.path, err.column, err.row) == (str(path), "p", 3)


def test_bad_path(tmp_path):
    assert "file not found" in str(error_of(tmp_path / "nope.csv"))
    assert "is a directory" in str(error_of(tmp_path))
    err = error_of(write(tmp_path, "a.xlsx", "v,p\n1,2\n"))
    assert "unsupported file type; expected .csv" in str(err)


@pytest.mark.parametrize("name", ["a.csv", "a.parquet"])
def test_unreadable_file(tmp_path, monkeypatch, name):
    path = write(tmp_path, name, "v,p\n1,2\n")

    def refuse(*args, **kwargs):
        raise PermissionError(13, "Permission denied")

    # chmod 0 does not stop root, who runs some CI containers.
    monkeypatch.setattr(sources, "open", refuse, raising=False)
    assert str(error_of(path)) == f"{path}: cannot open: Permission denied"


def test_bad_gzip(tmp_path):
    err = error_of(write(tmp_path, "a.csv.gz", b"not gzip at all"))
    assert "Not a gzipped file" in str(err)
    whole = gzip.compress(b"v,p\n" + b"1.5,2.5\n" * 200_000)
    err = error_of(write(tmp_path, "b.csv.gz", whole[: len(whole) // 2]))
    assert "corrupt or truncated gzip file" in str(err)


# --- where the error is ---------------------------------------------------------------


def test_bad_row_in_later_chunk_is_named(tmp_path):
    path = write(tmp_path, "a.csv", "v,p\n1,2\n3,4\n5,6\n7,8\n9,oops\n11,12\n")
    with pytest.raises(DataError, match=r"column 'p', row 5: non-numeric value 'oops'"):
        for _ in iter_chunks(path, ["v", "p"], chunk_rows=2):
            pass


def test_blank_lines_are_not_counted(tmp_path):
    path = write(tmp_path, "a.csv", "v\n1\n\n2\nx\n")
    assert "row 3:" in str(error_of(path, ["v"]))


@pytest.mark.parametrize("fmt", ["csv", "parquet"])
def test_bad_row_far_into_the_file(tmp_path, fmt):
    n, bad = 200_000, 177_777  # past several Arrow blocks / Parquet batches
    v = np.arange(1.0, n + 1)
    v[bad - 1] = np.nan
    if fmt == "csv":
        path = tmp_path / "big.csv"
        pd.DataFrame({"v": v}).to_csv(path, index=False)
    else:
        path = write_parquet(tmp_path, "big.parquet", pa.table({"v": v}), row_group_size=50_000)
    for chunk_rows in (1_000, 1_000_000):
        with pytest.raises(DataError, match=f"column 'v', row {bad}: "):
            for _ in iter_chunks(path, ["v"], chunk_rows=chunk_rows):
                pass


def test_ragged_row_far_into_the_file(tmp_path):
    path = write(tmp_path, "a.csv", "v,p\n" + "1,2\n" * 99_999 + "3\n" + "1,2\n" * 10)
    assert "row 100000: 1 field where the header has 2: '3'" in str(error_of(path))


def test_first_offending_row_wins_for_any_chunk_size(tmp_path):
    # A missing value at row 3 (column p) comes before a non-numeric cell at row 5.
    path = write(tmp_path, "a.csv", "v,p\n1,2\n1,2\n1,\n1,2\nx,2\n")
    for chunk_rows in (1, 2, 1000):
        with pytest.raises(DataError, match=r"column 'p', row 3: empty cell"):
            list(iter_chunks(path, ["v", "p"], chunk_rows=chunk_rows))
        # Dropping invalid rows, the non-numeric cell is what is left to refuse.
        with pytest.raises(DataError, match=r"column 'v', row 5: non-numeric"):
            list(iter_chunks(path, ["v", "p"], chunk_rows=chunk_rows, drop_invalid=True))


def test_same_row_earlier_column_wins(tmp_path):
    path = write(tmp_path, "a.csv", "v,p\n1,2\nx,\n")
    assert "column 'v', row 2: non-numeric" in str(error_of(path))


# --- dropping invalid rows --------------------------------------------------------------


def test_drop_invalid_counts_and_names_rows(tmp_path):
    rows = ["1,2", ",2", "3,4", "inf,1", "0,1", "5,6", "7,NA", "8,9"]
    path = write(tmp_path, "a.csv", "v,p\n" + "\n".join(rows) + "\n")
    data, n_dropped = read_columns(path, ["v", "p"], positive=["v"], drop_invalid=True)
    assert n_dropped == 4
    assert data["v"].tolist() == [1.0, 3.0, 5.0, 8.0]
    for chunk_rows in (1, 3, 100):
        chunks = list(
            iter_chunks(path, ["v", "p"], positive=["v"], drop_invalid=True, chunk_rows=chunk_rows)
        )
        assert sum(c.n_dropped for c in chunks) == 4
        assert np.concatenate([c.dropped_rows for c in chunks]).tolist() == [2, 4, 5, 7]
        kept = np.concatenate([c.rows for c in chunks]).tolist()
        assert kept == [1, 3, 6, 8]
        assert [c.row_of(i) for c in chunks for i in range(c.n_rows)] == kept
        assert sum(c.n_rows_read for c in chunks) == 8


def test_drop_invalid_optional_columns(tmp_path):
    path = write(tmp_path, "a.csv", "v,t\n1,0\n2,\n3,2\n")
    data, n_dropped = read_columns(path, ["v"], optional=["t"], drop_invalid=True)
    assert data["t"].tolist() == [0.0, 2.0] and n_dropped == 1
    with pytest.raises(DataError, match="column 't', row 2: empty cell"):
        read_columns(path, ["v"], optional=["t"])


def test_row_of_bounds():
    chunk = Chunk({"v": np.ones(2)}, start_row=5, n_rows_read=3, dropped_rows=np.array([6]))
    assert [chunk.row_of(0), chunk.row_of(1)] == [5, 7]
    assert chunk.rows.tolist() == [5, 7]
    with pytest.raises(IndexError):
        chunk.row_of(2)


# --- chunk invariance -------------------------------------------------------------------


@pytest.mark.parametrize("fmt", ["csv", "parquet"])
@pytest.mark.parametrize("drop_invalid", [False, True])
def test_chunk_size_does_not_change_the_data(tmp_path, fmt, drop_invalid):
    rng = np.random.default_rng(7)
    n = 2_345
    table = {
        "v": np.exp(rng.normal(0, 0.05, n)),
        "p": rng.standard_normal(n) * 10.0 ** rng.integers(-20, 20, n),
        "q": rng.standard_normal(n),
    }
    if drop_invalid:
        table["p"][rng.random(n) < 0.05] = np.nan
        table["v"][rng.random(n) < 0.05] = -1.0
    if fmt == "csv":
        path = tmp_path / "a.csv"
        pd.DataFrame(table).to_csv(path, index=False)
    else:
        path = write_parquet(tmp_path, "a.parquet", pa.table(table), row_group_size=500)
    results = []
    for chunk_rows in (1, 7, 1000):
        chunks = list(
            iter_chunks(
                path,
                ["v", "p"],
                optional=["q"],
                positive=["v"],
                chunk_rows=chunk_rows,
                drop_invalid=drop_invalid,
            )
        )
        assert all(c.n_rows_read == chunk_rows for c in chunks[:-1])
        starts = [c.start_row for c in chunks]
        assert starts == list(range(1, n + 1, chunk_rows))
        joined = {col: np.concatenate([c.data[col] for c in chunks]) for col in ("v", "p", "q")}
        rows = np.concatenate([c.rows for c in chunks])
        results.append((joined, rows))
    for joined, rows in results[1:]:
        for col in joined:
            np.testing.assert_array_equal(joined[col], results[0][0][col])
        np.testing.assert_array_equal(rows, results[0][1])
    keep = np.isfinite(table["p"]) & (table["v"] > 0)
    np.testing.assert_array_equal(results[0][0]["p"], table["p"][keep])
    np.testing.assert_array_equal(results[0][1], np.flatnonzero(keep) + 1)


# --- Parquet ----------------------------------------------------------------------------


def test_parquet_types_that_are_numbers(tmp_path):
    table = pa.table(
        {
            "i8": pa.array([1, 2], pa.int8()),
            "u64": pa.array([2**64 - 1, 3], pa.uint64()),
            "big": pa.array([2**53 + 1, 5], pa.int64()),
            "f32": pa.array([0.5, 1.5], pa.float32()),
            "dec": pa.array([Decimal("1.25"), Decimal("2.50")], pa.decimal128(5, 2)),
            "text": pa.array([" 1.5", "2e3"]),
            "dict": pa.array(["1", "2"]).dictionary_encode(),
            "ldict": pa.array([1.0, 2.0]).dictionary_encode(),
        }
    )
    data, _ = read_columns(write_parquet(tmp_path, "a.parquet", table), table.column_names)
    assert data["i8"].tolist() == [1.0, 2.0]
    assert data["u64"].tolist() == [2.0**64, 3.0]
    assert data["big"].tolist() == [2.0**53, 5.0]
    assert data["f32"].tolist() == [0.5, 1.5]
    assert data["dec"].tolist() == [1.25, 2.5]
    assert data["text"].tolist() == [1.5, 2000.0]
    assert data["dict"].tolist() == [1.0, 2.0]
    assert data["ldict"].tolist() == [1.0, 2.0]


BAD_PARQUET = {
    "string": ({"v": pa.array(["1", "2", "abc"])}, "column 'v', row 3: non-numeric value 'abc'"),
    "bool": ({"v": pa.array([True, False])}, "column 'v': has type bool, expected numbers"),
    "timestamp": (
        {"v": pa.array([0, 1], pa.timestamp("s"))},
        "column 'v': has type timestamp[",
    ),
    "list": ({"v": pa.array([[1.0], [2.0]])}, "column 'v': has type list<"),
    "null": ({"v": pa.array([1.0, None])}, "column 'v', row 2: missing value (null)"),
    "nan": ({"v": pa.array([1.0, np.nan])}, "column 'v', row 2: missing value nan ("),
    "all null type": ({"v": pa.nulls(2)}, "column 'v', row 1: missing value (null)"),
    "inf": ({"v": pa.array([np.inf])}, "column 'v', row 1: infinite value inf"),
    "negative": ({"v": pa.array([-2], pa.int32())}, "column 'v', row 1: value -2 is not > 0"),
    "empty": ({"v": pa.array([], pa.float64())}, "no data rows"),
    "missing": ({"V": pa.array([1.0])}, "column 'v': not found; the columns are 'V' (did you"),
    "invalid utf-8": (
        {"v": pa.array([b"1", b"\xff"], pa.binary())},
        "column 'v', row 2: not UTF-8 text: b'\\xff'",
    ),
}


@pytest.mark.parametrize("case", list(BAD_PARQUET))
def test_bad_parquet(tmp_path, case):
    columns, expected = BAD_PARQUET[case]
    path = write_parquet(tmp_path, "bus18.parquet", pa.table(columns))
    assert str(error_of(path, ["v"], positive=["v"])).startswith(f"{path}: {expected}")


def test_parquet_duplicate_names(tmp_path):
    table = pa.Table.from_arrays([pa.array([1.0]), pa.array([2.0])], names=["v", "v"])
    path = write_parquet(tmp_path, "a.parquet", table)
    assert "column 'v': named 2 times in the header (columns 1, 2)" in str(error_of(path, ["v"]))


def test_parquet_not_parquet(tmp_path):
    assert "not a readable Parquet file" in str(error_of(write(tmp_path, "a.pq", b"PAR1 junk")))
    assert "empty file" in str(error_of(write(tmp_path, "b.parquet", b"")))
    whole = write_parquet(
        tmp_path, "c.parquet", pa.table({"v": np.arange(1e5)}), row_group_size=10_000
    )
    blob = whole.read_bytes()
    broken = write(tmp_path, "d.parquet", blob[: len(blob) // 2] + blob[-2_000:])
    assert "Parquet" in str(error_of(broken, ["v"]))


# --- arguments --------------------------------------------------------------------------


def test_argument_errors(tmp_path):
    path = write(tmp_path, "a.csv", "v\n1\n")
    with pytest.raises(TypeError):
        read_columns(path, "v")
    with pytest.raises(ValueError, match="positive"):
        read_columns(path, ["v"], positive=["p"])
    with pytest.raises(ValueError, match="twice"):
        read_columns(path, ["v"], optional=["v"])
    with pytest.raises(ValueError, match="chunk_rows"):
        next(iter_chunks(path, ["v"], chunk_rows=0))


# --- the number grammar matches Arrow's ---------------------------------------------------


def test_cell_grammar_is_arrows():
    # The fast path (Arrow's cast) and the slow path (_parse_cell) must accept the same
    # cells with the same values, or the chunking would change what is accepted.
    alphabet = "01.eE+-"
    cells = ["".join(t) for n in range(1, 5) for t in itertools.product(alphabet, repeat=n)]
    cells += ["inf", "-Infinity", "INF", "nan", "NaN(1a)", "nan(", "infinit", "1.5 x", "1_0"]
    for cell in cells:
        try:
            arrow = pc.cast(pa.array([cell]), pa.float64())[0].as_py()
        except pa.ArrowInvalid:
            arrow = None
        mine = _parse_cell(cell)
        if arrow is None:
            assert mine is None, cell
        else:
            assert mine is not None and (mine == arrow or (np.isnan(mine) and np.isnan(arrow))), (
                cell
            )


# --- writing ----------------------------------------------------------------------------


@pytest.mark.parametrize("name", ["out.csv", "out.csv.gz", "out.parquet", "out.pq"])
def test_write_table_round_trip(tmp_path, name):
    rng = np.random.default_rng(3)
    table = {"v": rng.standard_normal(100) * 1e-200, "p": rng.integers(1, 9, 100).astype(float)}
    path = write_table(table, tmp_path / name)
    assert path == tmp_path / name
    data, _ = read_columns(path, ["v", "p"])
    for col in table:
        np.testing.assert_array_equal(data[col], table[col])
    with pytest.raises(DataError, match=r"exists; use --force to overwrite$"):
        write_table(table, path)
    write_table(pd.DataFrame({"v": [1.0], "p": [2.0]}), path, force=True)
    assert read_columns(path, ["v", "p"])[0]["v"].tolist() == [1.0]
    assert [p.name for p in tmp_path.iterdir()] == [name]


def test_write_csv_header_is_plain(tmp_path):
    path = write_table({"v": [1.0], "a,b": [2.0]}, tmp_path / "a.csv")
    assert path.read_text().splitlines()[0] == 'v,"a,b"'


def test_write_table_bad_target(tmp_path):
    with pytest.raises(DataError, match="unsupported file type"):
        write_table({"v": [1.0]}, tmp_path / "a.xlsx")
    with pytest.raises(DataError, match="does not exist"):
        write_table({"v": [1.0]}, tmp_path / "missing" / "a.csv")


# --- atomic_write -----------------------------------------------------------------------


@pytest.mark.parametrize("exc", [RuntimeError, KeyboardInterrupt])
def test_atomic_write_keeps_old_file_on_error(tmp_path, exc):
    target = write(tmp_path, "report.json", "old")
    with pytest.raises(exc):
        with atomic_write(target, force=True, mode="w") as fh:
            fh.write("half")
            raise exc
    assert target.read_text() == "old"
    assert [p.name for p in tmp_path.iterdir()] == ["report.json"]
    with pytest.raises(exc):
        with atomic_write(tmp_path / "new.png", force=True) as tmp:
            tmp.write_bytes(b"half")
            raise exc
    assert [p.name for p in tmp_path.iterdir()] == ["report.json"]


def test_atomic_write_modes(tmp_path):
    target = tmp_path / "fig.png"
    with atomic_write(target) as tmp:
        assert tmp.parent == tmp_path and tmp.suffix == ".png" and tmp.name.startswith(".")
        tmp.write_bytes(b"png")
    assert target.read_bytes() == b"png"
    umask = os.umask(0o022)
    os.umask(umask)
    assert target.stat().st_mode & 0o777 == 0o666 & ~umask
    with atomic_write(tmp_path / "a.bin", mode="wb") as fh:
        fh.write(b"\x00")
    assert (tmp_path / "a.bin").read_bytes() == b"\x00"
    with pytest.raises(ValueError):
        with atomic_write(tmp_path / "b.txt", mode="a"):
            pass


def test_atomic_write_refuses_existing_file(tmp_path):
    target = write(tmp_path, "a.txt", "old")
    with pytest.raises(DataError, match=r"a\.txt: exists; use --force to overwrite"):
        with atomic_write(target, mode="w") as fh:
            fh.write("new")
    assert target.read_text() == "old"
    with pytest.raises(DataError, match="is a directory"):
        with atomic_write(tmp_path, mode="w"):
            pass


@pytest.mark.parametrize("name", ["a.csv", "a.csv.gz", "a.parquet"])
def test_abandoned_iteration_closes_the_file(tmp_path, name):
    path = write_table({"v": np.arange(1.0, 101.0)}, tmp_path / name)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # a ResourceWarning would be raised in gc
        chunks = iter_chunks(path, ["v"], chunk_rows=10)
        assert next(chunks).n_rows == 10
        del chunks
        gc.collect()


# --- files in a spreadsheet's code page (red-team cases) ------------------------------


def test_gb18030_header_is_read_by_its_names(tmp_path):
    # A Chinese spreadsheet saves its CSV in GB18030: the names are read as written.
    text = "电压,有功\n1.01,0.5\n0.99,0.48\n"
    path = write(tmp_path, "bus.csv", text.encode("gb18030"))
    cols, n_dropped = read_columns(path, ["电压", "有功"])
    assert n_dropped == 0
    np.testing.assert_array_equal(cols["电压"], [1.01, 0.99])
    # Asked for a name it lacks, the message lists the names as the user wrote them.
    assert "the columns are '电压', '有功'" in str(error_of(path))


def test_latin1_header_is_refused_with_what_it_reads_as(tmp_path):
    # Latin-1 decodes any byte (a binary file too), so it is not guessed; the message
    # shows the header as Latin-1 and says what to do.
    path = write(tmp_path, "bus.csv", "Spannung_µ,p\n1,2\n".encode("latin-1"))
    text = str(error_of(path))
    assert "header is not UTF-8 text (byte 0xb5)" in text
    assert "as Latin-1 it reads 'Spannung_µ,p'" in text and "save the file as UTF-8" in text
    # Latin-1 letters before ASCII ones decode as GB18030 ideographs: still Latin-1.
    path = write(tmp_path, "b2.csv", "Büs,p\n1,2\n".encode("latin-1"))
    assert "as Latin-1 it reads 'Büs,p'" in str(error_of(path))


def test_utf16_is_named(tmp_path):
    path = write(tmp_path, "bus.csv", "v,p\n1,2\n".encode("utf-16"))
    assert "UTF-16 text" in str(error_of(path))


def test_decimal_comma_is_said(tmp_path):
    path = write(tmp_path, "bus.csv", "v;p\n1,5;2\n")
    assert "(a decimal comma: save the file with '.' as the decimal mark)" in str(error_of(path))
    path = write(tmp_path, "b2.csv", "v,p\nabc,2\n")
    assert "decimal comma" not in str(error_of(path))
