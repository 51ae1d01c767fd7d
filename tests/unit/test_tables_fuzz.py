"""Random CSV text and Parquet tables: clean float64 data or a DataError, nothing else."""

from __future__ import annotations

import gzip
from decimal import Decimal

import numpy as np
import pyarrow as pa
import pyarrow.compute as pc
import pyarrow.parquet as pq
import pytest
from hypothesis import event, given, settings
from hypothesis import strategies as st

from loadbayes.io.cells import _parse_cell
from loadbayes.io.errors import DataError
from loadbayes.io.tables import iter_chunks, read_columns

NAMES = ["v", "p", "q", "t", "V", " v", "v ", "x", "", "v.1", "é", "a,b", '"v"']
ODD_CELLS = [
    "", " ", "nan", "NaN", "-nan", "inf", "-inf", "Infinity", "1e999", "-1e999", "1e-400",
    "4.9e-324", "1.7976931348623157e308", "NA", "null", "None", " 1.5 ", "\t2", "True",
    "1,5", "abc", "1_000", "\u0663", "\u00bd", '"', '"1"', "0", "-0", "+.5e3", "nan(1)",
    "0x10", "1e", ".", "-", "1.5\x00", "\u200b1",
]  # fmt: skip

cells = st.one_of(
    st.floats().map(repr),
    st.floats(min_value=1e-3, max_value=1e3).map(repr),
    st.integers(-(10**25), 10**25).map(str),
    st.sampled_from(ODD_CELLS),
    st.text(max_size=6),
)

# Which columns to ask for, and how: (required, optional, positive).
REQUESTS = st.sampled_from(
    [
        (["v"], [], []),
        (["v"], ["p", "q"], ["v"]),
        (["v", "p"], ["t"], ["v", "t"]),
        (["p"], ["v"], []),
    ]
)
CHUNK_ROWS = st.sampled_from([1, 3, 1000])


def outcome(path, request, drop_invalid, chunk_rows):
    """The data read, or the error message; checks what either must satisfy."""
    required, optional, positive = request
    try:
        chunks = list(
            iter_chunks(
                path,
                required,
                optional=optional,
                positive=positive,
                chunk_rows=chunk_rows,
                drop_invalid=drop_invalid,
            )
        )
    except DataError as err:
        text = str(err)
        assert "\n" not in text and "\r" not in text
        assert text.startswith(str(path))
        return text
    assert chunks
    for chunk in chunks:
        assert set(required) <= set(chunk.data) <= set(required + optional)
        assert chunk.n_rows_read <= chunk_rows
        for col, values in chunk.data.items():
            assert values.dtype == np.float64 and values.ndim == 1
            assert values.flags.c_contiguous
            assert len(values) == chunk.n_rows
            assert np.isfinite(values).all()
            if col in positive:
                assert (values > 0).all()
        if not drop_invalid:
            assert chunk.n_dropped == 0
    return {col: np.concatenate([c.data[col] for c in chunks]) for col in chunks[0].data}, sum(
        c.n_dropped for c in chunks
    )


def check(path, request, drop_invalid, chunk_rows):
    first = outcome(path, request, drop_invalid, chunk_rows)
    # Shown by --hypothesis-show-statistics: the fuzz must reach both outcomes.
    event("error" if isinstance(first, str) else "data" if first[1] == 0 else "data, dropped")
    # Another chunk size, and the whole-file reader, give the same data or error.
    other = outcome(path, request, drop_invalid, 1000 if chunk_rows != 1000 else 1)
    required, optional, positive = request
    try:
        whole = read_columns(
            path, required, optional=optional, positive=positive, drop_invalid=drop_invalid
        )
    except DataError as err:
        whole = str(err)
    for result in (other, whole):
        if isinstance(first, str):
            assert result == first
        else:
            assert not isinstance(result, str), result
            assert result[1] == first[1]
            assert result[0].keys() == first[0].keys()
            for col in first[0]:
                np.testing.assert_array_equal(result[0][col], first[0][col])


CLEAN = st.one_of(
    st.floats(min_value=1e-3, max_value=1e3).map(repr),
    st.floats(min_value=1e-300, max_value=1e300).map(str),
    st.integers(1, 10**20).map(str),
)
INVALID = st.sampled_from(["", "nan", "NA", "inf", "-1e999", "-1", "0", " "])


@st.composite
def csv_files(draw):
    names = st.sampled_from(NAMES)
    # Mostly clean files, some with missing or invalid values, some with anything.
    kind = draw(st.sampled_from(["clean", "invalid", "dirty"]))
    header = draw(st.permutations(["v", "p", "q", "t"]))
    if kind == "dirty" or draw(st.booleans()):
        header = draw(st.lists(names, min_size=1, max_size=5))
    width = len(header)
    cell = {"clean": CLEAN, "invalid": st.one_of(CLEAN, CLEAN, INVALID), "dirty": cells}[kind]
    row = st.lists(cell, min_size=width, max_size=width)
    if kind == "dirty":
        row = st.one_of(row, st.lists(cell, min_size=0, max_size=width + 2))  # ragged
    rows = draw(st.lists(row, max_size=12))
    sep = draw(st.sampled_from([",", ",", ";", "\t"]))
    newline = draw(st.sampled_from(["\n", "\r\n"]))
    text = newline.join(sep.join(r) for r in [header, *rows])
    text += draw(st.sampled_from(["", newline, newline * 2]))
    encodings = ["utf-8", "utf-8-sig", "latin-1"] + (["utf-16"] if kind == "dirty" else [])
    encoding = draw(st.sampled_from(encodings))
    data = text.encode(encoding, errors="replace")
    if kind == "dirty" and draw(st.booleans()):
        at = draw(st.integers(0, len(data)))
        data = data[:at] + draw(st.binary(max_size=6)) + data[at:]
    return data


@settings(max_examples=110, deadline=None)
@given(
    data=csv_files(),
    gz=st.booleans(),
    request=REQUESTS,
    drop_invalid=st.booleans(),
    chunk_rows=CHUNK_ROWS,
)
def test_random_csv(tmp_path_factory, data, gz, request, drop_invalid, chunk_rows):
    folder = tmp_path_factory.getbasetemp()
    path = folder / ("fuzz.csv.gz" if gz else "fuzz.csv")
    path.write_bytes(gzip.compress(data) if gz else data)
    check(path, request, drop_invalid, chunk_rows)


def arrow_columns(n):
    """Strategies for one Parquet column of n rows, of many types."""
    floats = st.one_of(st.floats(), st.floats(min_value=0.1, max_value=10), st.none())
    ints = st.one_of(st.integers(-(2**63), 2**63 - 1), st.none())
    texts = st.one_of(cells, st.none())
    size = {"min_size": n, "max_size": n}
    positive = st.floats(min_value=0.1, max_value=10)
    numeric = st.one_of(
        st.lists(positive, **size).map(lambda x: pa.array(x, pa.float64())),
        st.lists(floats, **size).map(lambda x: pa.array(x, pa.float64())),
        st.lists(floats, **size).map(lambda x: pa.array(x, pa.float32())),
        st.lists(ints, **size).map(lambda x: pa.array(x, pa.int64())),
        st.lists(st.integers(0, 2**64 - 1), **size).map(lambda x: pa.array(x, pa.uint64())),
        st.lists(st.integers(-128, 127), **size).map(lambda x: pa.array(x, pa.int8())),
        st.lists(positive.map(repr), **size).map(lambda x: pa.array(x, pa.large_string())),
    )
    return st.one_of(
        numeric,
        numeric,
        numeric,
        st.lists(texts, **size).map(lambda x: pa.array(x, pa.string())),
        st.lists(texts, **size).map(lambda x: pa.array(x, pa.string()).dictionary_encode()),
        st.lists(st.binary(max_size=4), **size).map(lambda x: pa.array(x, pa.binary())),
        st.lists(st.booleans(), **size).map(lambda x: pa.array(x, pa.bool_())),
        st.lists(st.integers(0, 10**9), **size).map(lambda x: pa.array(x, pa.timestamp("s"))),
        st.lists(st.integers(-999, 999), **size).map(
            lambda x: pa.array([Decimal(i) / 100 for i in x], pa.decimal128(5, 2))
        ),
        st.just(pa.nulls(n)),
    )


@st.composite
def parquet_tables(draw):
    n = draw(st.integers(0, 15))
    names = draw(st.permutations(["v", "p", "q", "t"]))
    if draw(st.booleans()):
        names = draw(st.lists(st.sampled_from(NAMES[:8]), min_size=1, max_size=4))
    arrays = [draw(arrow_columns(n)) for _ in names]
    return pa.Table.from_arrays(arrays, names=names)


@settings(max_examples=70, deadline=None)
@given(
    table=parquet_tables(),
    row_group=st.sampled_from([2, 5, 1000]),
    request=REQUESTS,
    drop_invalid=st.booleans(),
    chunk_rows=CHUNK_ROWS,
)
def test_random_parquet(tmp_path_factory, table, row_group, request, drop_invalid, chunk_rows):
    path = tmp_path_factory.getbasetemp() / "fuzz.parquet"
    pq.write_table(table, path, row_group_size=row_group)
    check(path, request, drop_invalid, chunk_rows)


@settings(max_examples=20, deadline=None)
@given(st.lists(st.text(alphabet="0123456789.eEinfaty+-() _", max_size=10), max_size=30))
def test_cell_grammar_matches_arrow(texts):
    # The fast path (Arrow's cast) and the slow path (_parse_cell) must agree cell by
    # cell, or whether a cell is accepted would depend on its neighbours.
    for text in texts:
        try:
            arrow = pc.cast(pa.array([text]), pa.float64())[0].as_py()
        except pa.ArrowInvalid:
            arrow = None
        mine = _parse_cell(text)
        if arrow is None:
            assert mine is None or text.strip() != text or text == "", text
        else:
            assert mine == arrow or (np.isnan(mine) and np.isnan(arrow)), text


@pytest.mark.parametrize("seed", range(3))
def test_random_bytes_files(tmp_path, seed):
    rng = np.random.default_rng(seed)
    for suffix in (".csv", ".csv.gz", ".parquet"):
        path = tmp_path / f"junk{suffix}"
        path.write_bytes(rng.bytes(int(rng.integers(0, 3000))))
        with pytest.raises(DataError):
            read_columns(path, ["v"])
