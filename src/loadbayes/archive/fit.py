"""``loadbayes archive fit``: every usable event of the catalog, fitted and kept as it ends.

Each event (a dip in one bay of one record, :mod:`.scan`) is one task: the record read
again for its bay, positive-sequence V, angle, P and Q at ``per_cycle`` phasors a cycle
(:func:`~loadbayes.recordings.record.record_table`), the scan's window cut from its
waveform segment, and the dynamic model fitted to it alone
(:func:`loadbayes.fit.composite.driver.fit_composite`, ``zip+motor`` by default, any
model of ``models/dynamic.py`` by name). The tasks run in this process or on Dask
(:class:`loadbayes.fleet.engine.Engine`: ``workers=N`` a local cluster, ``scheduler=`` an
existing one); each result is written to the catalog and committed as it comes back
(:func:`~loadbayes.archive.catalog.record_fit`), its draws to a NetCDF file in the
results folder beside the catalog. A killed run loses only the fits in flight; a rerun
fits only the events with no result for the model, so none is fitted twice (and those
whose fit stopped on an unforeseen ``error``, which may not recur).

The seed of an event's fit is derived from the run's seed, the model and the event's id
(a hash of its record's content, bay and place), never from its order: the same seed gives
the same draws on any number of workers. A fit that fails (data the fit refuses, a model
that cannot start) is recorded as ``failed`` with its one line, and not tried again
unless ``retry_failed``.
"""

from __future__ import annotations

import hashlib
import json
import os
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass, replace
from pathlib import Path

import numpy as np

from loadbayes.archive.catalog import connect, record_fit, results_folder
from loadbayes.io.errors import DataError, OptionError

__all__ = ["FitRun", "FitTask", "event_seed", "fit", "fit_event"]

#: The sampler's settings per event unless given: the first round of ``zip+motor``'s
#: defaults (``fit/composite/driver.COMPOSITE_DEFAULTS``) for every model, as fixed draws
#: (no run until converged), so that every event costs the same and a run's time can be
#: said in advance. Was 3,000 after 1,000 x 2 chains: on the example archive's 6
#: transformer events (2 records a station) the chains had not mixed on the share in 2 of
#: them (R-hat 1.03-1.08, bulk ESS 25-50; at 1,500 after 500, in 5 of 6), and the pool
#: leaves such events out, the deep dips' most often; at these settings all 6 mixed (R-hat
#: at most 1.012, bulk ESS of the share 480-800), 2.8 s an event on one core. A model of
#: parts mixes slower (its own fit's first round is 16,000 draws, ``cmld-lite``'s 10,000):
#: on one of the example's events ``slm`` had mixed neither at these (R-hat 1.27, 22 s
#: on 2 cores) nor at 16,000 (R-hat 1.21, 54 s), so the default stays the cheaper round
#: and ``--draws`` is the user's to raise.
DRAWS, BURN, CHAINS = 6000, 4000, 4
#: Phasor estimates per cycle of the fitted rows.
PER_CYCLE = 4


@dataclass(frozen=True)
class FitTask:
    """One event to fit: where its record is, its window, and the run's settings."""

    event_id: str
    cfg: str
    current: tuple[str, ...]
    bay: str | None
    segment: int
    start_s: float
    stop_s: float
    model: str
    draws: int
    burn: int
    chains: int
    seed: int
    per_cycle: int
    netcdf: str
    window_s: float | None = None
    #: Threads for the event's chains: 1 on a Dask worker (a core each), None (the fit's
    #: default: the chains across the cores) in this process. The draws are the same.
    threads: int | None = 1


@dataclass
class FitRun:
    """What a run did: fits done, failed, already in the catalog, and its seconds."""

    done: int = 0
    failed: int = 0
    skipped: int = 0
    todo: int = 0
    seconds: float = 0.0
    where: str = "in-process"

    def line(self) -> str:
        """The run in one line."""
        return (
            f"{self.done} fitted, {self.failed} failed, {self.skipped} already in the catalog "
            f"({self.where}, {self.seconds:.1f} s)"
        )


def event_seed(seed: int, model: str, event_id: str) -> int:
    """The seed of one event's fit: from the run's seed, the model and the event's id."""
    key = f"{seed}|{model}|{event_id}".encode()
    return int.from_bytes(hashlib.sha256(key).digest()[:4], "little") >> 1


def _is_share(name: str, unit: str, meaning: str) -> bool:
    return name.startswith("f_") and unit == "-" and "share" in meaning


def _event_record(task: FitTask):
    """The event as the fit reads it: the scan's window of the bay's phasor rows."""
    from loadbayes.measurements.events import events_from_arrays
    from loadbayes.measurements.record import SEQUENCE_COLUMNS, sequence_phasors
    from loadbayes.recordings.comtrade import read_comtrade
    from loadbayes.recordings.record import phasor_rows, record_table

    w = read_comtrade(task.cfg, current=list(task.current), bay=task.bay)
    rows = phasor_rows(record_table(w, per_cycle=task.per_cycle).columns)
    t = np.asarray(rows["t_s"], dtype=float)
    half = 0.5 / w.f_nominal
    m = (
        (np.asarray(rows["segment"]) == task.segment)
        & (t >= task.start_s - half)
        & (t <= task.stop_s + half)
    )
    if m.sum() < 8:
        raise DataError(
            f"{int(m.sum())} phasor rows in the event's window: too few to fit", task.cfg
        )
    cols = {"t": t[m] - t[m][0], "v": rows["v"][m], "p": rows["p"][m], "q": rows["q"][m],
            "angle": rows["angle_rad"][m]}  # fmt: skip
    cols = {k: np.asarray(v, dtype=float) for k, v in cols.items()}
    seq = {c: np.asarray(rows[c], dtype=float)[m] for c in SEQUENCE_COLUMNS if c in rows}
    if all(np.all(np.isfinite(v)) for v in seq.values()):
        cols |= sequence_phasors(seq, path=task.cfg)
    names = {k: k for k in ("t", "v", "p", "q", "f", "angle", "event")}
    label = f"{task.cfg}[{task.event_id}]"
    (ev,) = events_from_arrays(cols, np.arange(1, int(m.sum()) + 1), path=label, names=names,
                               f_hz=w.f_nominal)  # fmt: skip
    return ev, w.f_nominal


def fit_event(task: FitTask) -> dict:
    """Fit one event; a result for the catalog, ``done`` or ``failed`` (never raises)."""
    import warnings

    t0 = time.perf_counter()
    base = {"event_id": task.event_id, "model": task.model, "seed": task.seed,
            "draws": task.draws, "burn": task.burn, "chains": task.chains,
            "per_cycle": task.per_cycle, "window_s": task.window_s}  # fmt: skip
    try:
        from loadbayes.core.settings import SamplerSettings
        from loadbayes.fit.composite.driver import fit_composite
        from loadbayes.models.dynamic import dynamic_model

        event, f_hz = _event_record(task)
        options = {} if task.window_s is None else {"window_s": task.window_s}
        model = dynamic_model(task.model, f_hz=f_hz, **options)
        run = SamplerSettings(draws=task.draws, burn=task.burn, chains=task.chains,
                              seed=task.seed, threads=task.threads,
                              until_converged=False)  # fmt: skip
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            post = fit_composite(model, [event], sampler=run).posterior
        params = _summary(post, model.quantities)
        Path(task.netcdf).parent.mkdir(parents=True, exist_ok=True)
        post.to_netcdf(task.netcdf, force=True, pointwise=False)
    except Exception as exc:  # noqa: BLE001 - one event's failure is recorded, never fatal
        text = " ".join(str(exc).split())
        status = "failed"  # what the data or the options decide: the same on every run
        if not isinstance(exc, (DataError, OptionError, ValueError)):
            # Anything else may not recur (a compiled cache written by another process
            # at that moment, memory): an "error", fitted again by the next run.
            text, status = f"{type(exc).__name__}: {text}", "error"
        return {**base, "status": status, "reason": text,
                "seconds": time.perf_counter() - t0}  # fmt: skip
    kept = [p for p in params if np.isfinite(p["rhat"])]
    return {
        **base,
        "status": "done",
        "params": params,
        "rhat_max": max((p["rhat"] for p in kept), default=None),
        "ess_min": min((p["ess"] for p in kept), default=None),
        "warnings": list(post.warnings),
        "netcdf": task.netcdf,
        "seconds": time.perf_counter() - t0,
    }


def _summary(post, quantities: dict) -> list[dict]:
    """Mean, sd, 2.5 % and 97.5 % quantiles, R-hat and bulk ESS of each scalar draw."""
    names = [n for n in post.names if np.asarray(post.draws[n]).ndim == 2]
    stats = post.summary(var_names=names)
    out = []
    for n in names:
        x = np.asarray(post.draws[n], dtype=float)
        lo, hi = np.quantile(x, [0.025, 0.975])
        unit, meaning = (tuple(quantities.get(n, ("", ""))) + ("", ""))[:2]
        out.append(
            {
                "name": n,
                "share": _is_share(n, unit, meaning),
                "mean": float(x.mean()),
                "sd": float(x.std(ddof=1)) if x.size > 1 else 0.0,
                "lo": float(lo),
                "hi": float(hi),
                "rhat": float(stats.loc[n, "r_hat"]),
                "ess": float(stats.loc[n, "ess_bulk"]),
            }
        )
    return out


def _tasks(conn, db_path, model, draws, burn, chains, seed, per_cycle, retry_failed,
           window_s=None):  # fmt: skip
    """The usable events with no result for ``model`` (failed ones too when retrying)."""
    skip = "('done')" if retry_failed else "('done', 'failed')"
    rows = conn.execute(
        f"""
        SELECT e.event_id, f.path, b.current, b.field, e.segment, e.start_s, e.stop_s
        FROM events e JOIN bays b USING (bay_id) JOIN files f ON f.file_id = e.file_id
        WHERE e.usable = 1 AND f.status = 'ok' AND NOT EXISTS (
            SELECT 1 FROM fits x WHERE x.event_id = e.event_id AND x.model = ?
            AND x.status IN {skip})
        ORDER BY e.event_id
        """,
        (model,),
    ).fetchall()
    already = conn.execute(
        f"SELECT COUNT(*) FROM fits WHERE model = ? AND status IN {skip}", (model,)
    ).fetchone()[0]
    folder = results_folder(db_path)
    safe = model.replace("+", "_")
    tasks = []
    for event_id, cfg, current, field, segment, start_s, stop_s in rows:
        tasks.append(
            FitTask(
                event_id=event_id,
                cfg=cfg,
                current=tuple(json.loads(current)),
                bay=field,
                segment=int(segment),
                start_s=float(start_s),
                stop_s=float(stop_s),
                model=model,
                draws=draws,
                burn=burn,
                chains=chains,
                seed=event_seed(seed, model, event_id),
                per_cycle=per_cycle,
                netcdf=str(folder / f"{event_id}.{safe}.nc"),
                window_s=window_s,
            )  # fmt: skip
        )
    return tasks, int(already)


def fit(
    catalog: str | os.PathLike[str],
    *,
    model: str = "zip+motor",
    draws: int = DRAWS,
    burn: int = BURN,
    chains: int = CHAINS,
    seed: int = 0,
    per_cycle: int = PER_CYCLE,
    window_s: float | None = None,
    workers: int | None = None,
    scheduler: str | None = None,
    client=None,
    retry_failed: bool = False,
    progress: Callable[[dict, int, int, int], None] | None = None,
    start: Callable[[int, int], None] | None = None,
) -> FitRun:
    """Fit every usable event of the catalog that has no result for ``model``.

    Parameters
    ----------
    catalog : str or os.PathLike
        The catalog ``archive scan`` made.
    model : str
        A dynamic model's name (``zip+motor``, ``slm``, ``cmld-lite``).
    draws, burn, chains, seed : int
        Per event; the event's own seed is :func:`event_seed` of ``seed``.
    per_cycle : int
        Phasor estimates per cycle of the fitted rows.
    window_s : float, optional
        The model's phasor window (s); None: the model's default (one cycle).
    workers, scheduler, client
        Where to run (:class:`loadbayes.fleet.engine.Engine`); in this process by default.
    retry_failed : bool
        Fit again the events whose fit failed before.
    progress : callable, optional
        ``progress(result, done, failed, left)`` after each result is committed.
    start : callable, optional
        ``start(todo, already)`` once the tasks are known, before any fit.

    Returns
    -------
    FitRun
    """
    from loadbayes.fleet.engine import Engine
    from loadbayes.models.dynamic import DYNAMIC_MODELS

    if model not in DYNAMIC_MODELS:
        raise OptionError(f"--model {model}: not a dynamic model ({', '.join(DYNAMIC_MODELS)})")
    for name, value, least in (("draws", draws, 100), ("burn", burn, 0), ("chains", chains, 1)):
        if value < least:
            raise OptionError(f"--{name} {value}: must be at least {least}")
    if seed < 0:
        raise OptionError(f"--seed {seed}: must be >= 0")
    t0 = time.perf_counter()
    out = FitRun()
    with connect(catalog) as conn:
        tasks, out.skipped = _tasks(conn, catalog, model, draws, burn, chains, seed, per_cycle,
                                    retry_failed, window_s)  # fmt: skip
        out.todo = len(tasks)
        if start is not None:
            start(len(tasks), out.skipped)
        if not tasks:
            out.seconds = time.perf_counter() - t0
            return out

        def done(_i: int, result: dict) -> None:
            record_fit(conn, result)
            if result["status"] == "done":
                out.done += 1
            else:
                out.failed += 1
            if progress is not None:
                progress(result, out.done, out.failed, len(tasks) - out.done - out.failed)

        with Engine(workers=workers, scheduler=scheduler, client=client) as engine:
            out.where = engine.name
            if engine.client is None:  # one event at a time here: its chains on the cores
                tasks = [replace(t, threads=None) for t in tasks]
            engine.map(fit_event, tasks, done=done)
    out.seconds = time.perf_counter() - t0
    return out


def task_dict(task: FitTask) -> dict:
    """A task as plain data (for a log or a test)."""
    return asdict(task)
