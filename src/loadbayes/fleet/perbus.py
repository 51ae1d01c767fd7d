"""Independent per-bus ZIP fits (``--pool none``): the existing sampler, bus by bus.

Each bus is fitted from its own Gram matrix by
:func:`loadbayes.inference.linear.sample_blocks`, exactly as ``loadbayes fit zip`` fits
one file. Its randomness comes from a seed derived from the run's seed and the bus id
(:func:`bus_seed`), so a bus gets the same draws whichever batch or worker fits it.
"""

from __future__ import annotations

import hashlib
from collections.abc import Mapping
from pathlib import Path
from urllib.parse import quote

import numpy as np
import pandas as pd

from loadbayes.core.priors import BlockPrior
from loadbayes.core.settings import SamplerSettings
from loadbayes.fleet.diagnostics import summarize
from loadbayes.fleet.stats import FleetStats
from loadbayes.fleet.summary import failed_rows, stat_rows
from loadbayes.inference.linear import sample_blocks
from loadbayes.io.errors import DataError
from loadbayes.models.zip import ZIPModel
from loadbayes.posterior import IDENTIFIABILITY_CORR, Posterior

__all__ = ["bus_file_name", "bus_seed", "check_netcdf_targets", "fit_buses"]


def bus_seed(seed: int, bus: object) -> np.random.SeedSequence:
    """The seed of one bus: the run's seed and a hash of the bus id (stable everywhere)."""
    h = int.from_bytes(hashlib.blake2b(str(bus).encode(), digest_size=8).digest(), "little")
    return np.random.SeedSequence(seed, spawn_key=(h,))


#: The longest file name most file systems take (bytes), with ".nc".
_NAME_MAX = 255


def bus_file_name(bus: object) -> str:
    """The NetCDF file name of a bus under ``--netcdf-dir``: its id, made safe.

    Bus ids come from the data, so they must never choose where a file goes: every
    character but letters, digits, ``-``, ``_`` and ``.`` is percent-encoded (``/``
    becomes ``%2F``, ``%`` itself ``%25``), and so is a leading dot, so that no id
    names a parent folder, an absolute path or a hidden file. The encoding is
    one-to-one: two different ids never share a file.

    Raises
    ------
    DataError
        If the encoded name is longer than a file name can be.
    """
    name = quote(str(bus), safe="-_.")
    if name.startswith("."):
        name = "%2E" + name[1:]
    name += ".nc"
    if len(name.encode()) > _NAME_MAX:
        shown = str(bus) if len(str(bus)) <= 40 else str(bus)[:37] + "..."
        raise DataError(
            f"bus id {shown!r} is too long for a file name under --netcdf-dir "
            f"({len(name.encode())} bytes encoded, at most {_NAME_MAX})"
        )
    return name


def check_netcdf_targets(
    buses: np.ndarray, netcdf_dir: str | Path, *, force: bool = False
) -> list[Path]:
    """The NetCDF file of every bus under ``netcdf_dir``, checked before any fit.

    Raises
    ------
    DataError
        If an id cannot be a file name (:func:`bus_file_name`), or a file exists and
        ``force`` is False.
    """
    folder = Path(netcdf_dir)
    paths = [folder / bus_file_name(b) for b in buses]
    if not force:
        for b, path in zip(buses, paths, strict=True):
            if path.exists():
                raise DataError(f"bus {b!s}: exists; use --force to overwrite", str(path))
    return paths


def _free_pairs(model: ZIPModel) -> list[tuple[str, str]]:
    f = model.free
    return [(f[i], f[i + 1]) for i in range(0, len(f), 2)]


def fit_buses(
    stats: FleetStats,
    model: ZIPModel,
    priors: Mapping[str, BlockPrior],
    sampler: SamplerSettings,
    *,
    netcdf_dir: str | None = None,
    force: bool = False,
) -> pd.DataFrame:
    """Fit every bus of ``stats`` on its own and return its rows of the fleet table.

    Parameters
    ----------
    stats : FleetStats
        The buses (a batch of the fleet).
    model : ZIPModel
        The model (its Gram columns are ``stats.names``).
    priors : mapping
        Block priors, as for one bus.
    sampler : SamplerSettings
    netcdf_dir : str, optional
        Write each bus's draws to ``<netcdf_dir>/<bus>.nc``, the id made a safe file
        name by :func:`bus_file_name`.
    force : bool
        Overwrite existing NetCDF files.
    """
    params = model.coefficients + [b.tau_name for b in model.blocks]
    ok: list[int] = []
    warn: list[str] = []
    draws: dict[str, list[np.ndarray]] = {p: [] for p in params}
    failed: list[tuple[int, str]] = []
    for i in range(stats.buses.size):
        if stats.bad[i]:
            failed.append((i, "values too large: their products overflow float64"))
            continue
        gram = stats.bus_gram(i)
        try:
            w = model.check(gram)
        except DataError as exc:
            failed.append((i, f"not fitted: {exc.message}"))
            continue
        raw = sample_blocks(
            gram,
            model.blocks,
            priors,
            settings=sampler.with_(seed=bus_seed(sampler.seed, stats.buses[i])),
        )
        tr = model.transform(raw)
        for p in params:
            draws[p].append(tr[p])
        for a, b in _free_pairs(model):
            r = np.corrcoef(tr[a].ravel(), tr[b].ravel())[0, 1]
            if np.isfinite(r) and abs(r) > IDENTIFIABILITY_CORR:
                w = w + [f"{a} and {b} cannot be told apart (posterior correlation {r:+.3f})"]
        warn.append(" | ".join(w))
        ok.append(i)
        if netcdf_dir:
            post = Posterior(
                tr,
                model=model.name,
                method="gibbs-blocked",
                coefficients=model.coefficients,
                free=model.free,
                constant={"gram": gram.matrix},
                settings={"bus": str(stats.buses[i]), "n": gram.n, "seed": sampler.seed},
                warnings=w,
            )
            post.to_netcdf(Path(netcdf_dir) / bus_file_name(stats.buses[i]), force=force)
    frames = []
    if ok:
        idx = np.array(ok)
        summ = {p: summarize(np.stack(draws[p]), hdi_prob=sampler.hdi_prob) for p in params}
        frames.append(
            stat_rows(
                "bus", stats.buses[idx], stats.classes[idx], stats.n[idx], summ, warnings=warn
            )  # fmt: skip
        )
    if failed:
        idx = np.array([i for i, _ in failed])
        frames.append(
            failed_rows(
                stats.buses[idx], stats.classes[idx], stats.n[idx], [r for _, r in failed]
            )  # fmt: skip
        )
    return pd.concat(frames, ignore_index=True) if frames else failed_rows([], [], [], [])
