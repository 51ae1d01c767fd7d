"""The ZIP fit's reader: a table in memory or a file, into the columns every variant fits.

:func:`read_table` (a DataFrame or a mapping) and :func:`read_file` (a CSV or Parquet
file read whole) return the same :class:`ZipData`: the columns in per unit, their 1-based
data rows and times, the model of the nominal point, the settings recorded and the data's
warnings. :func:`file_gram` is the one path that keeps no columns: a file's Gram matrix
built chunk by chunk (the Gaussian fit of a file of any size).

A file cut from a recorder's record (``read comtrade`` -> ``events``) flags in its
``straddle`` column the rows whose phasor window straddles a voltage step: they mix the
two sides of the step, and one of them biased a sag's ZIP fit beyond its interval (dP/dV
1.094 [1.090, 1.097] for a true 1.10, every share outside its interval). Both file
readers leave those rows out and say so (:func:`straddling_rows`).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
import pandas as pd

from loadbayes.core.settings import DataSpec
from loadbayes.core.stats import Gram, GramAccumulator
from loadbayes.fit.core import MAX_OBSERVED
from loadbayes.fit.data import bases
from loadbayes.fit.zip.checks import data_checks
from loadbayes.io.errors import DataError, OptionError
from loadbayes.measurements.columns import power_chunks, read_power_columns
from loadbayes.measurements.frame import read_frame
from loadbayes.measurements.times import (
    check_increasing,
    parse_times,
    read_times,
    time_facts,
)
from loadbayes.measurements.wording import Wording, option
from loadbayes.models.zip import ZIPModel

__all__ = ["STRADDLE_COL", "ZipData", "file_gram", "nominal_of", "read_file", "read_table",
           "straddling_rows"]  # fmt: skip

#: The record table's column flagging a row whose phasor window straddles a step.
STRADDLE_COL = "straddle"


def straddling_rows(path: str) -> np.ndarray | None:
    """The file's :data:`STRADDLE_COL` as a boolean per data row, or None without one."""
    from loadbayes.measurements.times import read_text_column

    try:
        text = read_text_column(str(path), STRADDLE_COL)
    except Exception:  # the file's own reader says what is wrong with it
        # (a corrupt or empty Parquet raised pyarrow's ArrowInvalid here, before the
        # reader that names the file and the column: the error lost its location)
        return None
    flags = text.astype(str).str.strip().str.lower().isin(("true", "1", "1.0", "yes"))
    return flags.to_numpy() if flags.any() else None


def _straddle_note(n: int, rows: np.ndarray) -> str:
    shown = ", ".join(str(int(r)) for r in rows[:5]) + (" ..." if rows.size > 5 else "")
    return (
        f"{n} row(s) whose phasor window straddles a voltage step were left out (the "
        f"record's '{STRADDLE_COL}' column; data rows {shown}): each mixes the two sides "
        "of the step and biases the fit beyond what its interval admits"
    )


def _keep(flags: np.ndarray | None, rows: np.ndarray) -> np.ndarray | None:
    # The rows to keep (None: all), from the flags of the file's 1-based data rows.
    if flags is None:
        return None
    idx = np.asarray(rows, dtype=np.int64) - 1
    hit = np.zeros(idx.size, dtype=bool)
    ok = (idx >= 0) & (idx < flags.size)
    hit[ok] = flags[idx[ok]]
    return ~hit if hit.any() else None


@dataclass
class ZipData:
    """Columns in memory, ready for a variant of :mod:`.variants`.

    ``where`` (``"data"`` or the file) and ``names`` (the user's column of ``v``, ``p``,
    ``q``) re-locate a sampler's :class:`DataError` to the input's column and row.
    """

    cols: dict[str, np.ndarray]
    rows: np.ndarray
    t: np.ndarray | None
    model: ZIPModel
    record: dict[str, Any]
    warnings: list[str]
    where: str
    names: dict[str, str | None]


def nominal_of(spec: DataSpec) -> dict[str, Any]:
    """``v0``, ``p0``, ``q0`` of ``spec`` as the model takes them (None: ``"auto"``)."""
    auto = {None: "auto"}
    return {"v0": spec.v0, "p0": auto.get(spec.p0, spec.p0), "q0": auto.get(spec.q0, spec.q0)}


def _names(spec: DataSpec) -> dict[str, str | None]:
    return {"v": spec.v_col, "p": spec.p_col, "q": spec.q_col}


def read_table(
    data: Any,
    spec: DataSpec,
    *,
    drift: bool,
    v_noise: Any,
    units: dict[str, str],
) -> ZipData:
    """A DataFrame or mapping: its columns checked (worded for Python) and in per unit."""
    v_col, p_col, q_col = spec.v_col, spec.p_col, spec.q_col
    q_required = q_col is not None and q_col != "q"
    table = read_frame(
        data,
        [v_col, p_col] + ([q_col] if q_required and q_col else []),
        optional=[q_col] if q_col and not q_required else [],
        positive=[v_col],
        drop_invalid=spec.drop_invalid,
        t_col=spec.t_col,
    )
    v_base, s_base = spec.v_base, spec.s_base
    cols = {"v": table.data[v_col] / (v_base or 1.0), "p": table.data[p_col] / (s_base or 1.0)}
    if q_col and q_col in table.data:
        cols["q"] = table.data[q_col] / (s_base or 1.0)
    given = nominal_of(spec)
    nom = ("auto", "auto") if drift else (given["p0"], given["q0"])  # drift: the level is P0(t)
    model = ZIPModel(v0=spec.v0, p0=nom[0], q0=nom[1], with_q="q" in cols)  # type: ignore[arg-type]
    names = _names(spec)
    # the file's unit and V-noise checks, on the whole table, worded for Python
    warnings = data_checks(
        cols, path="data", names=names, accept_units=spec.accept_units, wording="python",
        v0=spec.v0, p0=nom[0], q0=nom[1] if model.with_q else "auto", v_base=v_base,
        s_base=s_base, v_noise=v_noise,
    )  # fmt: skip
    if table.n_dropped:
        warnings.append(
            f"{table.n_dropped} rows with invalid values were dropped (drop_invalid=True)"
        )
    record = {
        "data": "DataFrame" if hasattr(data, "iloc") else "mapping",
        "columns": {"v": v_col, "p": p_col, "q": q_col if model.with_q else None},
        "v0": spec.v0,
        "p0": given["p0"],
        "q0": given["q0"] if model.with_q else None,
        "v_base": v_base,
        "s_base": s_base,
        **bases(v_base, s_base),
        "units": dict(units),
        "n_dropped": table.n_dropped,
        **table.time,
    }
    t = _frame_times(data, spec.t_col, table.rows, drift)
    if t is not None:
        record.update(time_column=spec.t_col, **time_facts(t))
    return ZipData(cols, table.rows, t, model, record, warnings, "data", names)


def _frame_times(data, t_col, rows, drift):
    """Seconds of a table's kept rows from ``t_col`` (or a DatetimeIndex); checked."""
    values = None
    if t_col is not None and hasattr(data, "keys") and t_col in data.keys():
        values = np.asarray(data[t_col])
    elif isinstance(getattr(data, "index", None), pd.DatetimeIndex):
        values, t_col = np.asarray(data.index), str(data.index.name or "index")
    if values is None:
        if drift:
            raise OptionError("level='drift' needs the time of each sample: give t_col")
        return None
    t = parse_times(values[rows - 1], path="data", column=t_col, rows=rows)
    check_increasing(t, rows, path="data", column=t_col)
    return t


def _read_options(spec: DataSpec, chunk_rows: int) -> dict[str, Any]:
    q_required = spec.q_col is not None and spec.q_col != "q"
    return dict(
        v_col=spec.v_col, p_col=spec.p_col, q_col=spec.q_col, q_required=q_required,
        v_base=spec.v_base, s_base=spec.s_base, drop_invalid=spec.drop_invalid,
        chunk_rows=chunk_rows,
    )  # fmt: skip


def file_record(path, model, spec: DataSpec, nominal, n_dropped) -> dict[str, Any]:
    """The data settings a ZIP fit of a file records (``post.settings``)."""
    return {
        "data": str(path),
        "columns": {
            "v": spec.v_col,
            "p": spec.p_col,
            "q": spec.q_col if model.with_q else None,
        },
        "v0": nominal["v0"],
        "p0": nominal["p0"],
        "q0": nominal["q0"] if model.with_q else None,
        "v_base": spec.v_base,
        "s_base": spec.s_base,
        **bases(spec.v_base, spec.s_base),
        "n_dropped": n_dropped,
    }


def read_file(
    path: str,
    spec: DataSpec,
    *,
    nominal: dict[str, Any],
    t_col: str | None,
    chunk_rows: int,
    progress: Callable[[int], None] | None,
    wording: Wording,
    v_noise: Any = None,
) -> ZipData:
    """A file read whole (its time column too with ``t_col``), checked whole."""
    pc = read_power_columns(path, progress=progress, **_read_options(spec, chunk_rows))
    t = None
    if t_col is not None:
        t = read_times(str(path), t_col, pc.rows)
        check_increasing(t, pc.rows, path=str(path), column=t_col)
    keep, straddle = _keep(straddling_rows(path), pc.rows), None
    if keep is not None:
        straddle = _straddle_note(int((~keep).sum()), pc.rows[~keep])
        pc = type(pc)({k: a[keep] for k, a in pc.cols.items()}, pc.rows[keep], pc.n_dropped,
                      {k: a[keep] for k, a in pc.extra.items()})  # fmt: skip
        t = None if t is None else t[keep]
    model = ZIPModel(**nominal, with_q="q" in pc.cols)
    names = _names(spec)
    warnings = data_checks(
        pc.cols, path=path, names=names, accept_units=spec.accept_units,
        v_base=spec.v_base, s_base=spec.s_base, wording=wording, v_noise=v_noise, **nominal,
    )  # fmt: skip
    if pc.n_dropped:
        drop = option("drop-invalid", wording=wording).removesuffix("=...")
        warnings.append(f"{pc.n_dropped} rows with invalid values were dropped ({drop})")
    if straddle:
        warnings.append(straddle)
    record = file_record(path, model, spec, nominal, pc.n_dropped)
    if t is not None:
        record.update(time_column=t_col, **time_facts(t))
    return ZipData(pc.cols, pc.rows, t, model, record, warnings, str(path), names)


def file_gram(
    path: str,
    spec: DataSpec,
    *,
    nominal: dict[str, Any],
    chunk_rows: int,
    progress: Callable[[int], None] | None,
    wording: Wording,
) -> tuple[ZIPModel, Gram, list[str], dict[str, np.ndarray] | None, int]:
    """A file's Gram matrix, chunk by chunk: (model, gram, warnings, observed, dropped).

    The unit and V-noise checks look at the first chunk with rows; the observed columns
    are kept while they stay under :data:`~loadbayes.fit.core.MAX_OBSERVED` samples.
    """
    state: dict[str, Any] = {"dropped": 0}
    names = _names(spec)
    keep_obs: dict[str, list[np.ndarray]] = {"v": [], "p": [], "q": []}
    flags, left_out = straddling_rows(path), []

    def chunks():
        for part in power_chunks(path, **_read_options(spec, chunk_rows)):  # type: ignore[arg-type]
            state["dropped"] += part.n_dropped
            cols = part.cols
            keep = _keep(flags, part.rows)
            if keep is not None:
                left_out.append(part.rows[~keep])
                cols = {k: a[keep] for k, a in cols.items()}
            if "model" not in state:
                state["model"] = ZIPModel(**nominal, with_q="q" in cols)  # type: ignore[arg-type]
            if "first_warnings" not in state and cols["v"].size:
                # the first chunk with rows (one whose rows were all dropped says nothing)
                state["first_warnings"] = data_checks(
                    cols, path=path, names=names, accept_units=spec.accept_units,
                    v_base=spec.v_base, s_base=spec.s_base, wording=wording, whole=False,
                    **nominal,
                )  # fmt: skip
            if sum(a.size for a in keep_obs["v"]) <= MAX_OBSERVED:
                for k, a in cols.items():
                    keep_obs[k].append(a)
            yield cols

    it = chunks()
    first = next(it, None)
    if first is None:
        raise DataError("no valid rows", path=str(path))
    model: ZIPModel = state["model"]
    acc = GramAccumulator(model.gram_columns)
    for chunk in _chain_first(first, it):
        rows = model.rows(chunk)
        acc.update(rows)
        if progress is not None:
            progress(rows.shape[0])
    gram = acc.result()
    warnings = list(state.get("first_warnings", []))
    if state["dropped"]:
        warnings.append(
            f"{state['dropped']} rows with invalid values were dropped "
            f"({option('drop-invalid', wording=wording).removesuffix('=...')})"
        )
    if left_out:
        out = np.concatenate(left_out)
        warnings.append(_straddle_note(out.size, out))
    observed = None
    if gram.n <= MAX_OBSERVED:
        observed = {k: np.concatenate(v) for k, v in keep_obs.items() if v}
    return model, gram, warnings, observed, state["dropped"]


def _chain_first(first, rest):
    yield first
    yield from rest
