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

__all__ = ["bus_seed", "fit_buses"]


def bus_seed(seed: int, bus: object) -> np.random.SeedSequence:
    """The seed of one bus: the run's seed and a hash of the bus id (stable everywhere)."""
    h = int.from_bytes(hashlib.blake2b(str(bus).encode(), digest_size=8).digest(), "little")
    return np.random.SeedSequence(seed, spawn_key=(h,))


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
        Write each bus's draws to ``<netcdf_dir>/<bus>.nc``.
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
            post.to_netcdf(Path(netcdf_dir) / f"{stats.buses[i]}.nc", force=force)
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
