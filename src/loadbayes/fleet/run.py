"""The fleet pipeline: find files -> statistics map-reduce -> per-bus or pooled fits -> table.

One idea needs these 758 lines: the fleet pipeline end to end (files, statistics,
per-bus or pooled fits, the table with its notes and checks).
"""

from __future__ import annotations

import os
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field, replace

import numpy as np
import pandas as pd
import pyarrow.parquet as pq

from loadbayes.core.priors import BlockPrior
from loadbayes.core.settings import SamplerSettings
from loadbayes.fleet import hierarchical as hier
from loadbayes.fleet.engine import Engine
from loadbayes.fleet.partitions import Partition, ReadSpec, display, find_partitions, id_kinds
from loadbayes.fleet.perbus import check_netcdf_targets, fit_buses
from loadbayes.fleet.stats import FleetStats, finish, merge, partition_stats
from loadbayes.fleet.summary import concat
from loadbayes.io.errors import DataError
from loadbayes.models.zip import ZIPModel

__all__ = ["FleetResult", "fit_fleet", "fleet_statistics", "one_process_note", "run_fleet"]


def one_process_note(engine: Engine) -> str:
    """After a run on ``--workers N``: a sentence when one process would have been faster.

    Measured, not estimated: the tasks' own CPU seconds ``W`` (each task's thread time on
    its worker, the statistics pass and the fits), against what the cluster cost, its
    start-up plus the wall time spent waiting for those tasks. One process runs the same
    tasks in at most ``W`` seconds (one after another; a large pooled fit's chains run on
    every core there), so when ``W`` is less than that cost, one process would have
    finished sooner. The converse is not claimed: the note is silent otherwise.
    """
    workers = engine.workers or 0
    if not workers or not engine.map_seconds:
        return ""
    cost = engine.startup_seconds + engine.map_seconds
    work = engine.task_cpu_seconds
    if not work < cost:
        return ""
    return (
        f"this fleet is small: its tasks took {work:.1f} s of CPU in all, which one process "
        f"runs in about that time, while {workers} worker{'s' if workers > 1 else ''} took "
        f"{engine.map_seconds:.1f} "
        f"s for them and {engine.startup_seconds:.1f} s to start; one process (no --workers) "
        "would have been faster"
    )


#: Buses fitted per task: large enough to amortise a task, small enough for memory
#: (4 chains x 2,500 draws x 8 parameters x 8 bytes = 640 kB per bus). Each bus's
#: summary is computed on its own series, so results do not depend on the batches.
BATCH_BUSES = 256


@dataclass
class FleetResult:
    """The fleet table and what produced it."""

    table: pd.DataFrame
    stats: FleetStats
    files: int
    engine: str
    settings: dict = field(default_factory=dict)


def _has_column(part: Partition, col: str) -> bool:
    if part.path.lower().endswith((".parquet", ".pq")):
        try:
            return col in pq.ParquetFile(part.path).schema_arrow.names
        except Exception:  # noqa: BLE001 - the reader reports an unreadable file by name
            return False
    import csv
    import gzip

    opener = gzip.open if part.path.lower().endswith(".gz") else open
    try:
        with opener(part.path, "rt", encoding="utf-8-sig", errors="replace") as fh:
            line = fh.readline().rstrip("\r\n")
    except OSError:
        return False
    sep = next((c for c in ",\t;" if c in line), ",")
    return col in next(csv.reader([line], delimiter=sep), [])


def _refuse_copies(parts, partials) -> None:
    """Refuse a file whose rows are another's (a copy left in the folder, a glob twice).

    Its buses' rows would be added twice: every such bus seen twice over, its intervals
    narrower by sqrt 2 as if it had been measured again. Two files hold the same rows of
    the same buses exactly when their exact sums, counts and bus ids are equal.
    """
    import hashlib

    seen: dict[bytes, str] = {}
    for part, stats in zip(parts, partials, strict=True):
        if not stats.buses.size:
            continue
        digest = hashlib.sha256()
        digest.update("\0".join(map(str, stats.buses)).encode())
        digest.update(np.ascontiguousarray(stats.n).tobytes())
        digest.update(np.ascontiguousarray(stats.digits).tobytes())
        key = digest.digest()
        if key in seen:
            raise DataError(
                f"the same rows as {seen[key]} (every bus, count and sum equal): a copy would "
                "count each of its buses twice and narrow their intervals; remove one",
                part.path,
            )
        seen[key] = part.path


def _warn_empty_files(partials) -> None:
    """Say which files had no data rows: skipped, since they hold no bus.

    Before, one header-only file in a folder stopped the whole fleet (issue 24's
    red-team); one file given alone is still refused.
    """
    import warnings

    empty = [f for p in partials for f in p.empty_files]
    if not empty:
        return
    shown = ", ".join(display(f) for f in empty[:5]) + (", ..." if len(empty) > 5 else "")
    warnings.warn(
        f"{len(empty)} file{'s' if len(empty) != 1 else ''} with no data rows skipped (no bus "
        f"in {'them' if len(empty) != 1 else 'it'}): {shown}",
        UserWarning,
        stacklevel=2,
    )


def _warn_mixed_ids(parts: list[Partition], col: str) -> None:
    """Say so when the files store the bus ids as different types (they merge as text)."""
    import warnings

    kinds = id_kinds(parts, col)
    if len(set(kinds.values())) < 2:
        return
    first: dict[str, str] = {}
    for path, kind in kinds.items():
        first.setdefault(kind, path)
    shown = ", ".join(f"{kind} in {display(path)}" for kind, path in sorted(first.items()))
    warnings.warn(
        f"bus ids in column {col!r} are stored as {shown}: they are matched as text, so 1 "
        "and 1.0 (Parquet) are the same bus as '1', while '1.0' in a CSV is another; "
        "store them with one type to be sure which buses merge",
        UserWarning,
        stacklevel=2,
    )


def _warn_spaced_ids(spaced: tuple[str, ...], col: str) -> None:
    """Say which bus ids were read without the spaces around them (and so merged)."""
    import warnings

    if not spaced:
        return
    as_read: dict[str, list[str]] = {}
    for raw in spaced:
        as_read.setdefault(raw.strip(), []).append(raw)
    shown = "; ".join(
        f"{' and '.join(map(repr, raws))} {'are' if len(raws) > 1 else 'is'} bus {bus!r}"
        for bus, raws in list(as_read.items())[:3]
    )
    warnings.warn(
        f"bus ids in column {col!r} are read without the spaces around them: {shown}"
        f"{' ...' if len(as_read) > 3 else ''} (rename them to keep them apart)",
        UserWarning,
        stacklevel=2,
    )


def fleet_statistics(
    data: str,
    spec: ReadSpec,
    *,
    v0: float = 1.0,
    p0: float | str = 1.0,
    q0: float | str = 1.0,
    engine: Engine | None = None,
    progress: Callable[[int], None] | None = None,
) -> tuple[FleetStats, ZIPModel, int]:
    """The map-reduce: exact per-bus statistics of every file under ``data``.

    Returns the statistics, the model (with Q if the first file has the Q column) and
    the number of files.
    """
    parts = find_partitions(data)
    _warn_mixed_ids(parts, spec.by)
    with_q = bool(spec.q_col) and (spec.q_required or _has_column(parts[0], spec.q_col))
    model = ZIPModel(v0=v0, p0=p0, q0=q0, with_q=with_q)  # type: ignore[arg-type]
    eng = engine or Engine()
    partials = eng.map(
        partition_stats,
        parts,
        spec,
        model,
        done=(lambda i, r: progress(1)) if progress else None,
    )
    _refuse_copies(parts, partials)
    if all(p.empty_files for p in partials):
        one_file = len(parts) == 1 and os.path.isfile(data)
        raise DataError("no data rows" + ("" if one_file else " in any file"), data)
    _warn_empty_files(partials)
    merged = merge(partials)
    _warn_spaced_ids(merged.spaced, spec.by)
    if not merged.buses.size:
        raise DataError("no valid rows in any file", data)
    return finish(merged), model, len(parts)


def run_fleet(
    data: str,
    spec: ReadSpec,
    *,
    pool: str = "none",
    v0: float = 1.0,
    p0: float | str = 1.0,
    q0: float | str = 1.0,
    priors: Mapping[str, BlockPrior] | None = None,
    hyper: hier.HierPrior | None = None,
    sampler: SamplerSettings | None = None,
    engine: Engine | None = None,
    netcdf_dir: str | None = None,
    force: bool = False,
    progress_files: Callable[[int], None] | None = None,
    progress_buses: Callable[[int], None] | None = None,
    on_stats: Callable[[FleetStats], None] | None = None,
    batch_buses: int = BATCH_BUSES,
    accept_units: bool = False,
    max_seconds: float | None = None,
) -> FleetResult:
    """Fit ZIP to every bus of a fleet.

    Parameters
    ----------
    data : str
        A table with a bus column, a folder of files (hive layouts included) or a glob.
    spec : ReadSpec
        Bus, class and measurement columns, units, invalid rows.
    pool : {"none", "class"}
        Independent per-bus fits, or the hierarchical model pooled within classes.
    v0, p0, q0 : float or "auto"
        Nominal values (pooling needs known ``p0``, ``q0``).
    priors : mapping, optional
        Block priors of the per-bus fits (default: the model's weak priors).
    hyper : HierPrior, optional
        Hyperpriors of the pooled model.
    sampler : SamplerSettings, optional
    engine : Engine, optional
        Where to run (default in-process); entered by the caller.
    netcdf_dir : str, optional
        Per-bus NetCDF files (``--pool none`` only).
    force : bool
        Overwrite NetCDF files.
    progress_files, progress_buses : callable, optional
        Called with counts of files read and buses fitted.
    on_stats : callable, optional
        Called with the statistics once the map-reduce is done (before the fits).
    accept_units : bool
        Fit buses whose data do not look per unit instead of refusing them.
    batch_buses : int
        Buses per fitting task (results do not depend on it).
    max_seconds : float, optional
        Pooled fits: continue the chains (each round ``draws - burn`` more sweeps, the
        earlier ones then counted as burn-in) until every class-level R-hat < 1.01, or
        until this budget would be exceeded. None or 0: one round.

    Returns
    -------
    FleetResult
        Its ``settings`` (also in ``table.attrs["loadbayes"]``) say how the chains ran
        and stopped, and hold the fleet-level warnings.
    """
    if pool not in ("none", "class"):
        raise ValueError(f"--pool must be 'none' or 'class', got {pool!r}")
    eng = engine or Engine()
    stats, model, files = fleet_statistics(
        data, spec, v0=v0, p0=p0, q0=q0, engine=eng, progress=progress_files
    )
    if on_stats is not None:
        on_stats(stats)
    table = fit_fleet(
        stats,
        model,
        pool=pool,
        priors=priors,
        hyper=hyper,
        sampler=sampler,
        engine=eng,
        netcdf_dir=netcdf_dir,
        force=force,
        progress_buses=progress_buses,
        batch_buses=batch_buses,
        accept_units=accept_units,
        max_seconds=max_seconds,
    )
    settings = dict(table.attrs.get("loadbayes", {}))
    settings.update({"files": files, "engine": eng.name})
    table.attrs["loadbayes"] = settings
    return FleetResult(table, stats, files, eng.name, settings)


def fit_fleet(
    stats: FleetStats,
    model: ZIPModel,
    *,
    pool: str = "none",
    priors: Mapping[str, BlockPrior] | None = None,
    hyper: hier.HierPrior | None = None,
    sampler: SamplerSettings | None = None,
    engine: Engine | None = None,
    netcdf_dir: str | None = None,
    force: bool = False,
    progress_buses: Callable[[int], None] | None = None,
    batch_buses: int = BATCH_BUSES,
    accept_units: bool = False,
    max_seconds: float | None = None,
) -> pd.DataFrame:
    """The fits of :func:`run_fleet` from statistics already computed (same options).

    Buses whose data do not look per unit (:func:`loadbayes.measurements.units.check_gram_units`)
    get a warning row instead of a fit, unless ``accept_units``.
    """
    if pool not in ("none", "class"):
        raise ValueError(f"--pool must be 'none' or 'class', got {pool!r}")
    eng = engine or Engine()
    sampler = sampler or SamplerSettings()
    refused, accepted = None, {}
    if netcdf_dir:
        # Before any fit: an id that cannot be a file name, or a file in the way.
        check_netcdf_targets(stats.buses, netcdf_dir, force=force)
    if not accept_units:
        stats, refused = _refuse_unit_errors(stats, model)
    else:  # fitted, but the unit check's words stay on the bus's rows, as for one bus
        accepted = {
            stats.buses[i]: "units: " + "; ".join(w) for i, w in _unit_problems(stats, model)
        }
    info: dict = {}
    frames = _fits(stats, model, pool, priors, hyper, sampler, eng, netcdf_dir, force,
                   progress_buses, batch_buses, max_seconds, info)  # fmt: skip
    table = concat(list(frames) + ([refused] if refused is not None else []))
    # the level words where the unit check had nothing to say (as for one bus)
    _prefix_bus_words(table, _level_notes(stats, model, table, skip=accepted.keys()))
    _prefix_bus_words(table, accepted)
    table.attrs["loadbayes"] = _settings(table, model, pool, hyper, sampler, max_seconds, info)
    return table


def _settings(table, model, pool, hyper, sampler, max_seconds, info) -> dict:
    """What produced the table, and the fleet-level sentences (JSON-able)."""
    from dataclasses import asdict

    def nominal(v):
        return "sampled" if v == "auto" and pool == "class" else v

    warn = list(info.get("warnings", []))
    bus = table[(table["level"] == "bus") & table["parameter"].notna()]
    slow = bus.loc[bus["warnings"].str.contains("not converged", regex=False), "bus"].unique()
    if len(slow):
        shown = ", ".join(map(str, slow[:5])) + (", ..." if len(slow) > 5 else "")
        warn.append(
            f"{len(slow)} of {bus['bus'].nunique()} buses have not converged ({shown}): "
            "see their rows' warnings"
        )
    split = bus.loc[bus["prior_driven"].astype(bool), "bus"].unique()
    if len(split):
        shown = ", ".join(map(str, split[:5])) + (", ..." if len(split) > 5 else "")
        warn.append(
            f"{len(split)} of {bus['bus'].nunique()} buses: a1, a2 (or a4, a5) not determined "
            f"separately by their own data, their split is their class's ({shown}); "
            "dp_dv, dq_dv are what their data fix (see the rows' prior_driven)"
        )
    return {
        "kind": "fleet",
        "model": "zip",
        "pool": pool,
        "v0": model.v0,
        "p0": nominal(model.p0),
        "q0": nominal(model.q0) if model.with_q else None,
        "chains": sampler.chains,
        "draws": sampler.draws,
        "burn": sampler.burn,
        "thin": sampler.thin,
        "seed": sampler.seed,
        "hdi_prob": sampler.hdi_prob,
        "buses": int(table.loc[table["level"] == "bus", "bus"].nunique()),
        "prior": asdict(hyper or hier.HierPrior()) if pool == "class" else None,
        "sweeps": info.get("sweeps", sampler.draws),
        # Rounds run (each as long as all before it); the kept draws are the last
        # round's, one in ``kept_thin`` (``thin`` in a one-round run).
        "rounds": info.get("rounds", 1),
        "kept_thin": info.get("kept_thin", sampler.thin),
        "max_seconds": max_seconds,
        "seconds": info.get("seconds"),
        "converged": info.get("converged"),
        "stop": info.get("stop", ""),
        "draws_bytes": info.get("draws_bytes"),
        "streamed": info.get("streamed"),
        "warnings": warn,
    }


def _unit_problems(stats: FleetStats, model: ZIPModel) -> list[tuple[int, list[str]]]:
    """(bus number, the unit check's sentences) of every bus whose data do not look per unit."""
    from loadbayes.measurements.units import check_gram_units

    nominal = {"p": model.p0, **({"q": model.q0} if model.with_q else {})}
    out = []
    for i in range(stats.buses.size):
        if stats.bad[i] or stats.n[i] < 3:
            continue  # refused with their own reasons by the fits
        problems = check_gram_units(stats.bus_gram(i), v0=model.v0, nominal=nominal)
        if problems:
            out.append((i, problems))
    return out


def _prefix_bus_words(table: pd.DataFrame, words: dict) -> None:
    """Put ``{bus: words}`` in front of those buses' rows' ``warnings`` (in place)."""
    if not words:
        return
    note = table["bus"].map(words)
    _prefix(table, note.notna() & (table["level"] == "bus"), note)


def _prefix(table: pd.DataFrame, rows, words) -> None:
    """``words`` (a string, or a Series by row) in front of ``rows``' ``warnings``."""
    note = words[rows] if isinstance(words, pd.Series) else words
    old = table.loc[rows, "warnings"]
    table.loc[rows, "warnings"] = np.where(old == "", note, note + " | " + old)


def _level_notes(stats: FleetStats, model: ZIPModel, table: pd.DataFrame, skip=()) -> dict:
    """``{bus: words}`` for fitted buses whose data put the given P0 (Q0) off their level.

    ``measurements.units.nominal_level_warnings_gram``: inside the unit check's range, but
    more than 5% and 4 standard errors off, where the shares take up the difference.
    Buses in ``skip`` (those the unit check already spoke of) get none.
    """
    from loadbayes.measurements.units import nominal_level_warnings_gram

    nominal = {"p": model.p0, **({"q": model.q0} if model.with_q else {})}
    if all(v == "auto" for v in nominal.values()):
        return {}
    fitted = set(table.loc[(table["level"] == "bus") & table["parameter"].notna(), "bus"])
    fitted -= set(skip)
    out = {}
    for i in range(stats.buses.size):
        if stats.buses[i] not in fitted or stats.bad[i] or stats.n[i] < 4:
            continue
        words = nominal_level_warnings_gram(stats.bus_gram(i), nominal=nominal)
        if words:
            out[stats.buses[i]] = "; ".join(words)
    return out


def _refuse_unit_errors(stats: FleetStats, model: ZIPModel):
    """Buses whose data do not look per unit get a warning row instead of a fit."""
    from loadbayes.fleet.summary import failed_rows

    bad, reasons = [], []
    for i, problems in _unit_problems(stats, model):
        bad.append(i)
        reasons.append("not fitted: " + "; ".join(problems) + " (or --accept-units)")
    if not bad:
        return stats, None
    keep = np.setdiff1d(np.arange(stats.buses.size), bad)
    idx = np.asarray(bad)
    rows = failed_rows(stats.buses[idx], stats.classes[idx], stats.n[idx], reasons)
    return stats.subset(keep), rows


def _fits(stats, model, pool, priors, hyper, sampler, eng, netcdf_dir, force,
          progress_buses, batch_buses, max_seconds=None, info=None):  # fmt: skip
    """The per-bus or pooled fits of the buses that passed the checks (frames)."""
    if pool == "none":
        nb = stats.buses.size
        step = int(batch_buses)
        batches = [np.arange(b0, min(b0 + step, nb)) for b0 in range(0, nb, step)]
        frames = eng.map(
            _fit_batch,
            batches,
            stats,
            model,
            dict(priors or model.default_priors()),
            sampler,
            netcdf_dir,
            force,
            done=(lambda i, r: progress_buses(len(batches[i]))) if progress_buses else None,
        )
    else:
        if netcdf_dir:
            raise ValueError("--netcdf-dir is for --pool none (pooled draws stay together)")
        data_h, failed = hier.prepare(stats, model)
        if not data_h.buses.size:
            frames = [failed]
        else:
            info = info if info is not None else {}
            folder = _draws_folder(data_h, sampler, info)
            try:
                hp = hyper or hier.HierPrior()
                chains = _pooled_chains(data_h, hp, sampler, eng, max_seconds, info, folder)
                table = hier.summarize_chains(data_h, chains, sampler)
                _note_prior_decided(table, data_h.params, hp.mean_sd, info)
                _note_few_buses(table, data_h.params, hp, info)
                frames = [table, failed]
            finally:
                if folder is not None:
                    import shutil

                    shutil.rmtree(folder, ignore_errors=True)
        if progress_buses:
            progress_buses(stats.buses.size)
    return frames


def _note_prior_decided(table: pd.DataFrame, params, mean_sd: float, info: dict) -> None:
    """Warn on the class rows whose mean shares their buses barely inform.

    As :func:`loadbayes.diagnostics.prior_dominance` does for one bus: a class mean whose
    posterior sd is above half the hyperprior's (``mean_sd``) repeats the prior; a class
    whose buses all have flat voltage gave intervals of +/-15 with clean rows.
    """
    from loadbayes.diagnostics import PRIOR_SHARE

    for name, rows, n in _class_rows(table):
        sd = table.loc[rows].set_index("parameter")["sd"]
        weak = [p for p in params if p in sd.index and sd[p] > PRIOR_SHARE * mean_sd]
        if not weak:
            continue
        words = (
            f"the prior decides the class mean of {', '.join(weak)}: posterior sd "
            f"{', '.join(f'{sd[p]:.3g}' for p in weak)} against the prior's {mean_sd:.3g}, "
            f"so the data of its {n} bus{'es' if n != 1 else ''} add little (flat voltage?)"
        )
        _warn_class(table, rows, name, words, info)


def _class_rows(table: pd.DataFrame):
    """``(class, its rows' mask, its buses)`` for each class of the table."""
    is_cls = table["level"] == "class"
    for name in pd.unique(table.loc[is_cls, "class"]):
        rows = is_cls & (table["class"] == name)
        yield name, rows, int(table.loc[rows, "n"].iloc[0])


def _warn_class(table: pd.DataFrame, rows, name, words: str, info: dict) -> None:
    """Put ``words`` before the notes of the ``rows`` and among the run's warnings."""
    _prefix(table, rows, words)
    info.setdefault("warnings", []).append(f"class {str(name)!r}: {words}")


#: A class with fewer buses than this says its spreads are mostly the prior's.
SPREAD_MIN_BUSES = 3


def _note_few_buses(table: pd.DataFrame, params, hp: hier.HierPrior, info: dict) -> None:
    """Warn on the class rows whose spreads one or two buses cannot inform.

    A spread is a variation between buses: one bus holds none of it, so its posterior is
    the hyperprior's (typical value ``spread``, or its learned scale's half-normal), and
    two barely move it. The class mean of such a class is its buses' own estimate, which
    the note does not touch.
    """
    if hp.spread_scale is None:
        typical = f"typical {hp.spread:g}"
    else:
        typical = f"a typical spread half-normal of scale {hp.spread_scale:g}"
    for name, rows, n in _class_rows(table):
        if n >= SPREAD_MIN_BUSES:
            continue
        words = (
            f"only {n} bus{'es' if n != 1 else ''} in this class: its spreads "
            f"({', '.join(f'sd_{p}' for p in params)}) are mostly the prior's ({typical}), "
            "not a measured variation between buses"
        )
        spreads = rows & table["parameter"].astype(str).str.startswith("sd_")
        _warn_class(table, spreads, name, words, info)


#: Above this many bytes of bus-level draws (all chains), they are streamed to disk.
STREAM_BYTES = 256 * 2**20


def _draws_folder(data_h, sampler, info) -> str | None:
    """A temporary folder for the chains' draws when holding them would cost too much."""
    import tempfile

    kept = len(range(sampler.burn, sampler.draws, sampler.thin))
    width = 2 * data_h.xy.shape[1] + 2 * data_h.xy.shape[1]  # theta, tau, p0
    size = 4 * kept * data_h.buses.size * width * sampler.chains
    info["draws_bytes"] = int(size)
    info["streamed"] = size > STREAM_BYTES
    if not info["streamed"]:
        return None
    return tempfile.mkdtemp(prefix="loadbayes-draws-")


def _chain_task(job, data_h, prior, sampler, stop=None):
    """One chain's round: ``job`` = (seed or state, NetCDF path or None[, sweeps, thin])."""
    start, store, *more = job
    if not more:
        return hier.run_chain(start, data_h, prior, sampler, store=store, stop=stop)
    sweeps, thin = more
    return hier.run_chain(start, data_h, prior, replace(sampler, thin=thin), sweeps=sweeps,
                          store=store, stop=stop)  # fmt: skip


#: Pooled chains run in threads in process from this many buses (measured, 4 x 1,500
#: sweeps, docs/fleet.md: at 300 buses two threads and one took the same wall time, at
#: 1,000 two were 1.45 times faster, at 3,000 1.8 times; at 200 buses, run on to 40,000
#: sweeps, two threads took 47.6 s and one 29.4 s).
THREADS_MIN_BUSES = 500


def _map_chains(eng, jobs, data_h, prior, sampler):
    """The chains' rounds: on the Dask workers, or in this process one thread per core.

    In process the chains run in ``min(chains, num_threads())`` threads (the sweep's
    compiled loops release the GIL; chain ``i`` runs in thread ``i % threads``), when
    the fleet has at least :data:`THREADS_MIN_BUSES` buses; below that one thread runs
    them, since each sweep's own Python steps (a class's draws) hold the GIL for longer
    than the compiled loops over so few buses run, and two threads then only contend. Each
    chain draws only from its own generator and owns its arrays and its NetCDF file, so
    its draws are the same bits in any thread (``tests/unit/test_fleet_threads.py``).
    """
    import threading

    from loadbayes.core.parallel import num_threads, run_threads

    threads = min(len(jobs), num_threads())
    if data_h.buses.size < THREADS_MIN_BUSES:
        threads = 1
    if eng.client is not None or threads <= 1:
        return eng.map(_chain_task, jobs, data_h, prior, sampler)
    out: list = [None] * len(jobs)
    # set when a chain fails or this thread is interrupted: the others stop within a sweep
    stop = threading.Event()

    def lane(k: int):
        def run() -> None:
            for i in range(k, len(jobs), threads):
                out[i] = _chain_task(jobs[i], data_h, prior, sampler, stop)

        return run

    run_threads([lane(k) for k in range(threads)], stop=stop)
    return out


def classes_converged(r_hat, ess, sampler: SamplerSettings) -> tuple[bool | None, bool]:
    """``(converged, ESS judged)`` of the class-level quantities (None: one chain).

    The rule the class rows' warnings use: every R-hat < 1.01 and bulk ESS >= 400. A
    later round keeps as many draws as the first, so ESS is judged only when those
    draws (all chains) are at least twice the target; with ``--draws`` too small for it,
    R-hat alone decides when to stop (the rows still say which ESS fall short).
    """
    from loadbayes.diagnostics import ESS_MIN, RHAT_MAX

    if sampler.chains < 2:
        return None, False
    kept = sampler.chains * len(range(sampler.burn, sampler.draws, sampler.thin))
    judge_ess = kept >= 2 * ESS_MIN
    r_ok = bool(np.all(np.asarray(r_hat) < RHAT_MAX))
    return r_ok and (not judge_ess or bool(np.all(np.asarray(ess) >= ESS_MIN))), judge_ess


def _pooled_chains(data_h, prior, sampler, eng, max_seconds, info, folder=None):
    """The pooled chains, continued until every class R-hat < 1.01 or the budget is spent.

    Each round after the first runs as many sweeps per chain as all rounds before it,
    from where the chain stopped, and keeps only those (the earlier half of the chain
    becomes burn-in, as in Stan's warm-up rule), thinned to as many kept draws as the
    first round's so that the memory stays as in the first round. So R-hat is judged on
    the later half of ever longer chains: the ESS behind it doubles each round (a
    fixed-length window, as before, let a fleet whose spreads mix slowly run on for
    dozens of rounds, each too short to show R-hat < 1.01). The decision to go on
    depends on the draws only, except when the time budget ends it: then (and only
    then) two machines may stop at different rounds.
    """
    from loadbayes.diagnostics import ESS_MIN, RHAT_MAX
    from loadbayes.fleet.summary import convergence_note

    def stores(r):
        if folder is None:
            return [None] * sampler.chains
        return [os.path.join(folder, f"chain{i}-round{r}.nc") for i in range(sampler.chains)]

    t0 = time.monotonic()
    seeds = hier.chain_seeds(sampler.seed, sampler.chains)
    chains = _map_chains(eng, list(zip(seeds, stores(1), strict=True)), data_h, prior, sampler)
    rounds, thin = 1, sampler.thin
    while True:
        summ = hier.class_convergence(data_h, chains, sampler.hdi_prob)
        r_hat = np.nanmax(np.stack([v["r_hat"] for v in summ.values()]), axis=0)
        ess = np.nanmin(np.stack([v["ess_bulk"] for v in summ.values()]), axis=0)
        ok, judge_ess = classes_converged(r_hat, ess, sampler)
        spent = time.monotonic() - t0
        done = int(chains[0].state.sweeps)
        per_round = spent  # the next round runs as many sweeps as all before it
        if ok or ok is None or not max_seconds:
            why = f"every class's R-hat < {RHAT_MAX}" + (
                f" and bulk ESS >= {ESS_MIN}" if judge_ess else ""
            )
            if not ok:
                why = "one round (no time budget to run on: --max-seconds 0)"
            if ok is None:
                why = "one chain: R-hat needs two or more"
            break
        if spent + per_round > max_seconds:
            why = (
                f"the {max_seconds:g} s budget (--max-seconds) would run out before another "
                f"round of {done} sweeps"
            )
            break
        # As many kept draws as the first round (its thinning included), never thinner.
        keep = max(1, len(range(sampler.burn, sampler.draws, sampler.thin)))
        thin = max(sampler.thin, -(-done // keep))
        jobs = [(c.state, st, done, thin) for c, st in zip(chains, stores(rounds + 1), strict=True)]
        chains = _map_chains(eng, jobs, data_h, prior, sampler)
        for old in stores(rounds):
            if old is not None and os.path.exists(old):
                os.remove(old)  # the earlier round is burn-in now
        rounds += 1
    sweeps = chains[0].state.sweeps
    info.update(
        sweeps=int(sweeps),
        rounds=rounds,
        kept_thin=thin,
        seconds=round(time.monotonic() - t0, 3),
        converged=ok,
        stop=f"stopped after {sweeps} sweeps per chain: {why}",
    )
    warn = []
    for j, name in enumerate(data_h.class_names):
        note = convergence_note(summ, j)
        if note:
            warn.append(f"class {str(name)!r} {note}")
    if ok is False:
        warn.append(
            f"the class-level chains have not converged (largest R-hat "
            f"{np.nanmax(r_hat):.3f}, smallest bulk ESS {np.nanmin(ess):.0f}; R-hat < "
            f"{RHAT_MAX} and ESS >= {ESS_MIN} wanted) after {sweeps} sweeps per chain "
            f"({why}): the class means and spreads are not reliable yet; give more "
            "--max-seconds or --draws"
        )
    info["warnings"] = warn
    return chains


def _fit_batch(idx, stats, model, priors, sampler, netcdf_dir, force):
    return fit_buses(stats.subset(idx), model, priors, sampler, netcdf_dir=netcdf_dir, force=force)
