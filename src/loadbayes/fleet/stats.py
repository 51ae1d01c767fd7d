"""Per-bus sufficient statistics of the ZIP regression, as a map-reduce over partitions.

Map (:func:`partition_stats`): one file -> for every bus in it, the exact digits of the
Gram matrix ``A'A`` of the model's columns (``z1 = x^2 - 1``, ``z2 = x - 1``, ``1``,
``rp``, ``rq``; see :class:`loadbayes.models.zip.ZIPModel`), its row count and column
ranges. Reduce (:func:`merge`): add the digits of the same bus (integers: exact and
associative). Finish (:func:`finish`): round each entry once to float64.

Why not :class:`~loadbayes.core.stats.GramAccumulator`? It is bit-reproducible for
one stream of rows cut into chunks at any place, because its summation blocks are
aligned to the global row index. A bus's rows in a fleet are spread over files whose
split nobody controls, and the row index of a bus within the fleet is not known to a
worker reading one file. So here each product ``a_i a_j`` is rounded to float64 (which
depends on the row alone) and the products are added exactly (:mod:`.exact`). The result
is identical to the last bit for any partitioning, any order and any number of workers,
and is the correctly rounded sum of the rounded products: at least as accurate as the
single-bus accumulator, though not bit-equal to it.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass, replace

import numpy as np
import pyarrow as pa
import pyarrow.compute as pc

from loadbayes.core.stats import Gram
from loadbayes.fleet import exact
from loadbayes.fleet.partitions import Partition, ReadSpec, read_partition
from loadbayes.io.errors import DataError, NoDataRows
from loadbayes.models.zip import ZIPModel

__all__ = ["FleetStats", "PartialStats", "finish", "merge", "partition_stats"]


@dataclass
class PartialStats:
    """Exact per-bus statistics of some partitions (a map output, or a merge of them).

    Attributes
    ----------
    names : tuple of str
        Gram columns.
    buses : ndarray of str
        Bus ids, sorted.
    classes : ndarray of object
        Class of each bus (None without a class column).
    digits : ndarray of int64, shape (buses, k (k + 1) / 2, DIGITS)
        Normalised exact digits of the upper triangle of each bus's Gram matrix.
    n : ndarray of int64
        Rows per bus.
    col_min, col_max : ndarray, shape (buses, k)
        Column ranges per bus.
    bad : ndarray of bool
        Buses with a product that overflowed float64.
    where : ndarray of object
        ``"file, row r"`` of each bus's first row seen (for messages about a bus).
    n_dropped : int
        Invalid rows dropped (``drop_invalid``).
    empty_files : tuple of str
        Files with no data rows, skipped (a map output's own file; merges do not keep it).
    spaced : tuple of str
        A few bus ids as written with spaces around them (read without: merged).
    """

    names: tuple[str, ...]
    buses: np.ndarray
    classes: np.ndarray
    digits: np.ndarray
    n: np.ndarray
    col_min: np.ndarray
    col_max: np.ndarray
    bad: np.ndarray
    where: np.ndarray
    n_dropped: int = 0
    empty_files: tuple[str, ...] = ()
    spaced: tuple[str, ...] = ()

    @classmethod
    def empty(cls, names: Sequence[str]) -> PartialStats:
        """Statistics of no rows."""
        k = len(names)
        return cls(
            tuple(names),
            np.empty(0, object),
            np.empty(0, object),
            np.zeros((0, k * (k + 1) // 2, exact.DIGITS), np.int64),
            np.zeros(0, np.int64),
            np.zeros((0, k)),
            np.zeros((0, k)),
            np.zeros(0, bool),
            np.empty(0, object),
        )


@dataclass(frozen=True)
class FleetStats:
    """Per-bus Gram matrices of a whole fleet, rounded once from exact sums.

    Attributes
    ----------
    names : tuple of str
        Gram columns.
    buses, classes : ndarray of object
        Bus ids (sorted) and their classes (None without a class column).
    gram : ndarray, shape (buses, k, k)
    n : ndarray of int64
    col_min, col_max : ndarray, shape (buses, k)
    bad : ndarray of bool
    n_dropped : int
    """

    names: tuple[str, ...]
    buses: np.ndarray
    classes: np.ndarray
    gram: np.ndarray
    n: np.ndarray
    col_min: np.ndarray
    col_max: np.ndarray
    bad: np.ndarray
    n_dropped: int = 0

    def bus_gram(self, i: int) -> Gram:
        """The :class:`~loadbayes.core.stats.Gram` of bus number ``i``."""
        return Gram(self.names, self.gram[i], int(self.n[i]), self.col_min[i], self.col_max[i])

    def subset(self, idx: np.ndarray) -> FleetStats:
        """The statistics of some buses."""
        return FleetStats(
            self.names,
            self.buses[idx],
            self.classes[idx],
            self.gram[idx],
            self.n[idx],
            self.col_min[idx],
            self.col_max[idx],
            self.bad[idx],
            self.n_dropped,
        )


def _codes(labels: pa.Array) -> tuple[np.ndarray, list[str]]:
    enc = pc.dictionary_encode(labels)
    return enc.indices.to_numpy(zero_copy_only=False).astype(np.int64), enc.dictionary.to_pylist()


def partition_stats(part: Partition, spec: ReadSpec, model: ZIPModel) -> PartialStats:
    """Map: the exact per-bus statistics of one input file.

    A file with a header and no data rows holds no bus: its statistics are empty and it
    is named in ``empty_files`` (the fleet says it skipped it), where one file as the
    input is refused (:class:`~loadbayes.io.errors.NoDataRows`).

    Parameters
    ----------
    part : Partition
        The file.
    spec : ReadSpec
        Columns and reading options.
    model : ZIPModel
        Builds the Gram columns from V, P (and Q); its ``with_q`` must match the data.

    Raises
    ------
    DataError
        Bad input (named by file, column and row), or a bus given two classes.
    """
    try:
        return _partition_stats(part, spec, model)
    except NoDataRows:
        return replace(PartialStats.empty(model.gram_columns), empty_files=(str(part.path),))


def _partition_stats(part: Partition, spec: ReadSpec, model: ZIPModel) -> PartialStats:
    names = model.gram_columns
    k = len(names)
    nent = k * (k + 1) // 2
    index: dict[str, int] = {}
    cls_of: list[object] = []
    where: list[str] = []
    digits = np.zeros((0, nent, exact.DIGITS), np.int64)
    count = np.zeros(0, np.int64)
    mins = np.zeros((0, k))
    maxs = np.zeros((0, k))
    bad = np.zeros(0, bool)
    since = 0
    dropped = 0
    times = None
    if spec.t_col:
        from loadbayes.measurements.times import read_times

        times = read_times(str(part.path), spec.t_col)
    last_time: dict[str, tuple[float, int]] = {}
    spaced: tuple[str, ...] = ()
    for ch in read_partition(part, spec):
        dropped += ch.n_dropped
        spaced = ch.spaced
        if not ch.rows.size:
            continue
        if times is not None:
            _check_bus_times(times, ch, last_time, str(part.path), spec.t_col)
        if model.with_q and "q" not in ch.cols:
            raise DataError(f"no column {spec.q_col!r} (other files have one)", part.path)
        bus_codes, bus_names = _codes(ch.bus)
        local = np.empty(len(bus_names), np.int64)
        for j, b in enumerate(bus_names):
            if b not in index:
                index[b] = len(index)
                cls_of.append(None)
                first = ch.rows[int(np.argmax(bus_codes == j))]
                where.append(f"{part.path}, row {first}")
            local[j] = index[b]
        if ch.cls is not None:
            _check_classes(ch, bus_codes, bus_names, local, cls_of, part.path, spec.class_col)
        grow = len(index) - count.size
        if grow:
            digits = np.concatenate([digits, np.zeros((grow, nent, exact.DIGITS), np.int64)])
            count = np.concatenate([count, np.zeros(grow, np.int64)])
            mins = np.concatenate([mins, np.full((grow, k), np.inf)])
            maxs = np.concatenate([maxs, np.full((grow, k), -np.inf)])
            bad = np.concatenate([bad, np.zeros(grow, bool)])
        rows = np.ascontiguousarray(model.rows(ch.cols))
        exact.accumulate_rows(rows, local[bus_codes], digits, count, mins, maxs, bad)
        since += rows.shape[0]
        if since >= exact.ROWS_BEFORE_NORMALIZE:
            exact.normalize(digits)
            since = 0
    exact.normalize(digits)
    buses = np.array(list(index), dtype=object)
    order = np.argsort(buses.astype(str), kind="stable")
    return PartialStats(
        names,
        buses[order],
        np.array(cls_of, dtype=object)[order],
        digits[order],
        count[order],
        mins[order],
        maxs[order],
        bad[order],
        np.array(where, dtype=object)[order],
        dropped,
        spaced=tuple(sorted(spaced)),
    )


def _check_bus_times(times, ch, last_time, path, t_col) -> None:
    """Times increase within each bus of a file (across chunks too); DataError names the row."""
    from loadbayes.measurements.times import check_increasing

    t = times[ch.rows - 1]
    codes, names = _codes(ch.bus)
    for j, b in enumerate(names):
        sel = np.flatnonzero(codes == j)
        tb, rb = t[sel], ch.rows[sel]
        if b in last_time:
            t0, r0 = last_time[b]
            tb, rb = np.r_[t0, tb], np.r_[r0, rb]
        check_increasing(tb, rb, path=path, column=t_col)
        last_time[b] = (float(tb[-1]), int(rb[-1]))


def _check_classes(ch, bus_codes, bus_names, local, cls_of, path, col) -> None:
    """Each bus has one class: in this chunk, and the same as seen before."""
    cls_codes, cls_names = _codes(ch.cls)
    nb = len(bus_names)
    lo = np.full(nb, np.iinfo(np.int64).max)
    hi = np.full(nb, -1)
    np.minimum.at(lo, bus_codes, cls_codes)
    np.maximum.at(hi, bus_codes, cls_codes)
    for j in range(nb):
        if lo[j] != hi[j]:
            i = int(np.flatnonzero((bus_codes == j) & (cls_codes != lo[j]))[0])
            raise DataError(
                f"bus {bus_names[j]!r} changes class from {cls_names[lo[j]]!r} to "
                f"{cls_names[cls_codes[i]]!r}; a bus belongs to one class",
                path,
                col,
                int(ch.rows[i]),
            )
        c = cls_names[lo[j]]
        b = local[j]
        if cls_of[b] is None:
            cls_of[b] = c
        elif cls_of[b] != c:
            i = int(np.argmax(bus_codes == j))
            raise DataError(
                f"bus {bus_names[j]!r} is in class {c!r} here but {cls_of[b]!r} earlier",
                path,
                col,
                int(ch.rows[i]),
            )


def merge(parts: Iterable[PartialStats]) -> PartialStats:
    """Reduce: add the statistics of the same bus (exact, in any order or grouping).

    Raises
    ------
    DataError
        If a bus has different classes in different files.
    """
    given = list(parts)
    if not given:
        raise ValueError("merge needs at least one PartialStats")
    parts = [p for p in given if p.buses.size] or given[:1]
    if len(parts) == 1:
        return parts[0]
    names = parts[0].names
    all_buses = np.concatenate([p.buses for p in parts]).astype(str)
    uniq, inv = np.unique(all_buses, return_inverse=True)
    nb = uniq.size
    first = parts[0]
    digits = np.zeros((nb,) + first.digits.shape[1:], np.int64)
    n = np.zeros(nb, np.int64)
    mins = np.full((nb, first.col_min.shape[1]), np.inf)
    maxs = np.full((nb, first.col_min.shape[1]), -np.inf)
    bad = np.zeros(nb, bool)
    classes = np.full(nb, None, dtype=object)
    where = np.full(nb, None, dtype=object)
    pos = 0
    for p in parts:
        idx = inv[pos : pos + p.buses.size]
        pos += p.buses.size
        digits[idx] += p.digits  # buses are unique within a part: no repeated index
        n[idx] += p.n
        mins[idx] = np.minimum(mins[idx], p.col_min)
        maxs[idx] = np.maximum(maxs[idx], p.col_max)
        bad[idx] |= p.bad
        for j, i in enumerate(idx):
            c = p.classes[j]
            if classes[i] is None:
                classes[i] = c
                where[i] = p.where[j]
            elif c is not None and c != classes[i]:
                raise DataError(
                    f"bus {str(uniq[i])!r} is in class {str(c)!r} at {p.where[j]} but in class "
                    f"{str(classes[i])!r} at {where[i]}; a bus belongs to one class"
                )
    exact.normalize(digits)
    return PartialStats(
        names,
        uniq.astype(object),
        classes,
        digits,
        n,
        mins,
        maxs,
        bad,
        where,
        sum(p.n_dropped for p in parts),
        spaced=tuple(sorted({s for p in given for s in p.spaced})),
    )


def finish(part: PartialStats) -> FleetStats:
    """Round the exact sums once: the fleet's per-bus Gram matrices."""
    k = len(part.names)
    upper = exact.to_float(part.digits)  # (buses, entries)
    gram = np.empty((part.buses.size, k, k))
    p = 0
    for i in range(k):
        for j in range(i, k):
            gram[:, i, j] = gram[:, j, i] = upper[:, p]
            p += 1
    gram[part.bad] = np.nan
    return FleetStats(
        part.names,
        part.buses,
        part.classes,
        gram,
        part.n,
        part.col_min,
        part.col_max,
        part.bad,
        part.n_dropped,
    )
