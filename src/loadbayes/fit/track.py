"""The ZIP coefficients after every sample: online Bayes over a file read in chunks.

:func:`track_zip` reads V, P (Q) through :func:`loadbayes.measurements.columns.power_chunks`,
fixes an ``auto`` nominal power from the first rows, and updates one
:class:`~loadbayes.inference.online.OnlineTracker` per channel with the ZIP regressors
of :meth:`loadbayes.models.zip.ZIPModel.rows`; each chunk comes back as a table of the
posterior mean and central interval of a1, a2, a3 (a4, a5, a6) after every sample.
Memory does not grow with the file: a chunk is handed over before the next is read.
"""

from __future__ import annotations

import itertools
from collections.abc import Iterator
from dataclasses import dataclass, field
from typing import Any

import numpy as np

__all__ = ["AUTO_ROWS", "TRUTH_COLUMNS", "ZIPTrack", "track_zip"]

#: Columns of simulated data holding the true coefficients (kept for a figure).
TRUTH_COLUMNS = tuple(f"a{i}_true" for i in range(1, 7))

#: Rows that fix an ``auto`` nominal power and the unit check, whatever the chunking.
AUTO_ROWS = 10_000

#: The ZIP shares as the tracker's two free coefficients: a3 = 1 - a1 - a2.
_CONTRASTS = np.array([[1.0, 0.0], [0.0, 1.0], [-1.0, -1.0]])
_OFFSETS = np.array([0.0, 0.0, 1.0])


@dataclass
class ZIPTrack:
    """A tracking run: iterate it for ``(table, extra)`` per chunk; what it found so far.

    Attributes
    ----------
    p0, q0 : float or "auto"
        The nominal powers, estimated from the first :data:`AUTO_ROWS` rows when
        ``auto`` (known once the first chunk is out).
    head_rows : int
        Rows those estimates (and the unit check) looked at.
    with_q, has_t : bool
        Whether Q is tracked, and whether the time column was there (else the table's
        ``t`` is the data row number).
    unit_notes : list of str
        Unit problems accepted with ``accept_units`` (refused otherwise).
    n_rows, n_dropped : int
        Samples tracked and rows dropped (``drop_invalid``), so far.
    """

    p0: float | str
    q0: float | str
    head_rows: int = 0
    with_q: bool = False
    has_t: bool = False
    unit_notes: list[str] = field(default_factory=list)
    n_rows: int = 0
    n_dropped: int = 0
    _chunks: Iterator[tuple[Any, dict[str, np.ndarray]]] | None = field(default=None, repr=False)

    def __iter__(self) -> Iterator[tuple[Any, dict[str, np.ndarray]]]:
        assert self._chunks is not None
        return self._chunks

    def _no(self, what: str) -> None:
        raise TypeError(
            f"a ZIP track has no {what}: it is a filter's path, given chunk by chunk as you "
            "iterate it (each chunk's table holds the coefficients' means and sds), not "
            "posterior draws; summarise or plot those tables"
        )

    def summary(self) -> None:
        """Refused in one line: a track holds no draws to summarise (iterate it)."""
        self._no("summary()")

    def plot(self) -> None:
        """Refused in one line: ``track zip --plot`` draws the path; iterate it here."""
        self._no("plot()")

    def to_arviz(self) -> None:
        """Refused in one line: no draws, so no ``InferenceData``."""
        self._no("to_arviz()")


def track_zip(
    path: str,
    *,
    v_col: str = "v",
    p_col: str = "p",
    q_col: str | None = "q",
    q_required: bool = False,
    t_col: str | None = "t",
    extra: tuple[str, ...] = (),
    v0: float = 1.0,
    p0: float | str = "auto",
    q0: float | str = "auto",
    v_base: float | None = None,
    s_base: float | None = None,
    drop_invalid: bool = False,
    chunk_rows: int = 100_000,
    forgetting: float | None = None,
    window: int | None = None,
    drift: float | None = None,
    prob: float = 0.95,
    prior_sd: float = 10.0,
    noise_sd: float = 0.05,
    accept_units: bool = False,
) -> ZIPTrack:
    """Track the ZIP coefficients of a load sample by sample (the twin of ``track zip``).

    Parameters
    ----------
    path : str
        CSV or Parquet file, or ``"-"`` for CSV on standard input.
    v_col, p_col, q_col, q_required, t_col, v_base, s_base, drop_invalid, chunk_rows
        As :func:`loadbayes.measurements.columns.power_chunks`; ``q_col=None`` tracks P
        only, ``t_col`` is copied to the tables when present.
    extra : tuple of str
        Further columns handed back with each chunk when present (e.g.
        :data:`TRUTH_COLUMNS`).
    v0, p0, q0 : float or "auto"
        Nominal point; an ``auto`` power is estimated from the first :data:`AUTO_ROWS`
        rows (at V = V0, by least squares), then held fixed.
    forgetting, window, drift : optional
        The tracker's memory (one of them; :class:`~loadbayes.inference.online.OnlineTracker`).
    prob : float
        Probability of the intervals.
    prior_sd, noise_sd : float
        Prior scale of each coefficient and prior guess of the noise sd, per unit of P0.
    accept_units : bool
        Track data that do not look per unit (a note instead of a refusal).

    Returns
    -------
    ZIPTrack
        Iterate it: one ``(table, extra)`` per chunk, ``table`` a DataFrame with ``t``
        and ``a1_mean, a1_low, a1_high, ...``; the last step raises
        :class:`~loadbayes.io.errors.DataError` when the data had no valid rows.
    """
    from loadbayes.measurements.columns import power_chunks

    track = ZIPTrack(p0=p0, q0=q0)
    times = _times_of(path, t_col)
    chunks = power_chunks(
        path, v_col=v_col, p_col=p_col, q_col=q_col, q_required=q_required,
        t_col=t_col if times is None else None, extra=extra, v_base=v_base, s_base=s_base,
        drop_invalid=drop_invalid, chunk_rows=chunk_rows,
    )  # fmt: skip
    if times is not None:
        chunks = _with_times(chunks, times, path=str(path), t_col=t_col)
    opts = dict(
        path=path, names={"v": v_col, "p": p_col, "q": q_col}, v0=v0, v_base=v_base,
        s_base=s_base, accept_units=accept_units, tracker=dict(
            forgetting=forgetting, window=window, drift=drift, prob=prob,
        ), prior_sd=prior_sd, noise_sd=noise_sd,
    )  # fmt: skip
    track._chunks = _tables(track, chunks, **opts)
    return track


def _times_of(path, t_col):
    """The time column in seconds (numbers or ISO timestamps), or None when it is absent.

    Standard input is read once: its time column, if any, is read as numbers with the rest.
    """
    from loadbayes.io.errors import DataError
    from loadbayes.measurements.times import read_times

    if not t_col or str(path) == "-":
        return None
    try:
        return read_times(str(path), t_col)
    except DataError as exc:
        if exc.message.startswith("no column"):
            return None  # the time column is optional here: rows are numbered instead
        raise
    except (OSError, ValueError):
        return None  # unreadable here: the table reader says why, in its words


def _with_times(chunks, times, *, path, t_col):
    """Each chunk with its rows' times, checked increasing across chunks."""
    from loadbayes.measurements.times import check_increasing

    last_t, last_row = None, None
    for part in chunks:
        t = times[part.rows - 1]
        if t.size:
            both_t = t if last_t is None else np.r_[last_t, t]
            both_rows = part.rows if last_row is None else np.r_[last_row, part.rows]
            check_increasing(both_t, both_rows, path=path, column=t_col)
            last_t, last_row = t[-1], part.rows[-1]
        part.cols["t"] = t
        yield part


def _tables(track: ZIPTrack, chunks, *, path, names, v0, v_base, s_base, accept_units,
            tracker, prior_sd, noise_sd):  # fmt: skip
    import pandas as pd

    from loadbayes.inference.online import OnlinePrior, OnlineTracker
    from loadbayes.io.errors import DataError
    from loadbayes.measurements.units import (
        check_power_units,
        level_at_nominal,
        require_power,
    )
    from loadbayes.measurements.wording import refuse
    from loadbayes.models.zip import ZIPModel

    parts, head = _head(chunks)
    trackers: dict[str, OnlineTracker] = {}
    channels: list[tuple[str, int, Any, tuple[str, ...]]] = []
    model: ZIPModel | None = None
    for part in parts:
        track.n_dropped += part.n_dropped
        n = part.rows.size
        if not trackers and n:
            track.has_t = "t" in part.cols
            c = head
            problems = check_power_units(
                c["v"], c["p"], c.get("q"), v0=v0, p0=track.p0, q0=track.q0,
                v_base=v_base, s_base=s_base,
            )  # fmt: skip
            if "auto" in (track.p0, track.q0):
                # P0 (Q0) is estimated from these rows and divides every later one.
                auto = {ch: c.get(ch) for ch, nom in (("p", track.p0), ("q", track.q0))}
                require_power(
                    auto["p"] if track.p0 == "auto" else None,
                    auto["q"] if track.q0 == "auto" else None,
                    path=str(path),
                    names=names,
                )
            if not accept_units:
                refuse(problems, path=str(path), names=names)
            track.unit_notes = [f"units: {pr}" for pr in problems]
            # 'auto' here: P0 (Q0) from the first AUTO_ROWS rows (whatever the chunking),
            # then held fixed: the tracker's shares are linear only for a known power.
            x = c["v"] / v0
            nom = {ch: level_at_nominal(x, c[ch]) for ch in ("p", "q") if ch in c}
            if track.p0 == "auto":
                track.p0 = nom["p"]
            if track.q0 == "auto" and "q" in c:
                track.q0 = nom["q"]
            track.head_rows = int(c["v"].size)
            track.with_q = "q" in part.cols
            # The model's rows: dx (x + 1), dx, 1, then P (and Q) as read ('auto'); the
            # tracker's targets are P / P0 - 1 with the P0 held fixed here.
            model = ZIPModel(v0=v0, p0="auto", q0="auto", with_q=track.with_q)
            channels = [("p", 3, track.p0, ("a1", "a2", "a3"))]
            if track.with_q:
                channels.append(("q", 4, track.q0, ("a4", "a5", "a6")))
            prior = OnlinePrior.weak(2, coef_sd=prior_sd, noise_sd=noise_sd)
            for ch, _, _, _ in channels:
                trackers[ch] = OnlineTracker(
                    2, prior=prior, contrasts=_CONTRASTS, offsets=_OFFSETS, **tracker
                )
        if n == 0:
            continue
        assert model is not None
        rows = model.rows(part.cols)
        z = np.ascontiguousarray(rows[:, :2])
        cols: dict[str, np.ndarray] = {"t": part.cols["t"] if track.has_t else part.rows}
        for ch, j_y, nom, coef in channels:
            res = trackers[ch].update(z, rows[:, j_y] / nom - 1.0)
            for j, name in enumerate(coef):
                cols[f"{name}_mean"] = res.mean[:, j]
                cols[f"{name}_low"] = res.low[:, j]
                cols[f"{name}_high"] = res.high[:, j]
        track.n_rows += n
        yield pd.DataFrame(cols), part.extra
    if track.n_rows == 0:
        raise DataError("no valid rows", path=str(path))


def _head(chunks):
    """The chunks again, and the first AUTO_ROWS rows of V, P, Q gathered from them."""
    it = iter(chunks)
    buffered, got = [], 0
    for part in it:
        buffered.append(part)
        got += part.rows.size
        if got >= AUTO_ROWS:
            break
    keys = buffered[0].cols if buffered else {}
    head = {k: np.concatenate([b.cols[k] for b in buffered])[:AUTO_ROWS] for k in keys}
    return itertools.chain(buffered, it), head
