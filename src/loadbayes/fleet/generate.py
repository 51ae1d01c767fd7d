"""Synthetic fleets with a known truth, shared by the tests, the demo and the benchmark.

:func:`fleet_truth` draws the buses: classes with different ZIP mixes, each bus's
coefficients scattered about its class's mix, 20 to 20,000 samples per bus
(log-uniform), and a fraction of buses whose voltage barely moves. :func:`bus_rows`
simulates one bus's measurements from its own seed, so a fleet can be written in any
layout (:func:`write_fleet`) or streamed bus by bus without holding it in memory.
:func:`ieee33_fleet` is the realistic case: pandapower's 33-bus feeder with a ZIP load on
every bus, solved by pandapower's power flow.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

import numpy as np
import pandas as pd

__all__ = ["CLASS_MIXES", "bus_rows", "fleet_truth", "ieee33_fleet", "write_fleet"]

#: (a1, a2) of P and (a4, a5) of Q of each class; the constant-power shares follow.
CLASS_MIXES: dict[str, tuple[float, float, float, float]] = {
    "residential": (0.45, 0.25, 0.60, 0.20),
    "commercial": (0.20, 0.30, 0.35, 0.40),
    "industrial": (0.05, 0.15, 0.10, 0.30),
}


def fleet_truth(
    n_buses: int,
    *,
    seed: int = 0,
    classes: Mapping[str, tuple[float, ...]] | None = None,
    scatter: float = 0.05,
    rows: tuple[int, int] | int = (20, 20_000),
    noise: float = 0.02,
    spread: tuple[float, float] = (0.03, 0.12),
    narrow_fraction: float = 0.1,
    narrow_spread: float = 2e-4,
) -> pd.DataFrame:
    """Draw a fleet: one row per bus with its class, true coefficients and data settings.

    Parameters
    ----------
    n_buses : int
    seed : int
    classes : mapping, optional
        Class name -> (a1, a2, a4, a5); default :data:`CLASS_MIXES`.
    scatter : float
        Within-class sd of each coefficient.
    rows : (int, int) or int
        Samples per bus: log-uniform in the range, or a fixed number.
    noise : float
        Measurement noise sd of P and Q, per unit of P0, Q0.
    spread : (float, float)
        Range of the half-width of each bus's voltage band (per unit).
    narrow_fraction : float
        Fraction of buses whose voltage half-width is ``narrow_spread`` instead.

    Returns
    -------
    pandas.DataFrame
        Columns ``bus_id``, ``customer_class``, ``a1``, ``a2``, ``a4``, ``a5``, ``rows``,
        ``noise``, ``v_spread``, ``seed``.
    """
    classes = dict(classes or CLASS_MIXES)
    rng = np.random.default_rng(seed)
    names = list(classes)
    cls = rng.integers(0, len(names), n_buses)
    mix = np.array([classes[n] for n in names])[cls]
    coef = mix + scatter * rng.standard_normal(mix.shape)
    if isinstance(rows, int):
        n = np.full(n_buses, rows)
    else:
        n = np.exp(rng.uniform(np.log(rows[0]), np.log(rows[1]), n_buses)).astype(int)
    half = rng.uniform(*spread, n_buses)
    half[rng.random(n_buses) < narrow_fraction] = narrow_spread
    width = len(str(n_buses - 1))
    return pd.DataFrame(
        {
            "bus_id": [f"bus{i:0{width}d}" for i in range(n_buses)],
            "customer_class": np.array(names, dtype=object)[cls],
            "a1": coef[:, 0],
            "a2": coef[:, 1],
            "a4": coef[:, 2],
            "a5": coef[:, 3],
            "rows": n,
            "noise": noise,
            "v_spread": half,
            "seed": seed,
        }
    )


def bus_rows(bus: Mapping[str, object], *, index: int = 0) -> dict[str, np.ndarray]:
    """Simulate one bus's V, P, Q (per unit) from its truth row; its own seed.

    The voltage is uniform in ``1 +- v_spread`` about a level drawn near 1; P and Q
    follow the ZIP curve plus Gaussian noise.
    """
    gen = np.random.default_rng(np.random.SeedSequence(int(bus["seed"]), spawn_key=(index,)))
    n = int(bus["rows"])
    half = float(bus["v_spread"])
    centre = 1.0 + gen.uniform(-0.03, 0.03)
    v = centre + half * gen.uniform(-1.0, 1.0, n)
    out = {"v": v}
    for ch, (c1, c2) in (("p", ("a1", "a2")), ("q", ("a4", "a5"))):
        a1, a2 = float(bus[c1]), float(bus[c2])
        y = a1 * v**2 + a2 * v + (1.0 - a1 - a2)
        out[ch] = y + float(bus["noise"]) * gen.standard_normal(n)
    return out


def write_fleet(
    truth: pd.DataFrame,
    folder: str | Path,
    *,
    layout: str = "files",
    buses_per_file: int = 100,
    with_class: bool = True,
) -> list[Path]:
    """Write a fleet's measurements as Parquet.

    Parameters
    ----------
    truth : DataFrame
        From :func:`fleet_truth`.
    folder : str or Path
        Created if missing.
    layout : {"files", "hive", "table"}
        ``files``: ``part-00000.parquet``... with ``buses_per_file`` buses each and a
        ``bus_id`` column; ``hive``: ``bus_id=<id>/part-0.parquet`` without it;
        ``table``: one ``fleet.parquet``.
    with_class : bool
        Write the ``customer_class`` column.

    Returns
    -------
    list of Path
    """
    import pyarrow as pa
    import pyarrow.parquet as pq

    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    written: list[Path] = []

    def table(rows: list[tuple[int, pd.Series]], bus_col: bool) -> pa.Table:
        parts = []
        for i, bus in rows:
            sim = bus_rows(bus, index=i)
            cols = {}
            if bus_col:
                cols["bus_id"] = pa.array([bus["bus_id"]] * sim["v"].size, pa.string())
            if with_class:
                cols["customer_class"] = pa.array(
                    [bus["customer_class"]] * sim["v"].size, pa.string()
                )
            cols.update({k: pa.array(v) for k, v in sim.items()})
            parts.append(pa.table(cols))
        return pa.concat_tables(parts)

    items = list(truth.iterrows())
    if layout == "hive":
        for i, bus in items:
            sub = folder / f"bus_id={bus['bus_id']}"
            sub.mkdir(exist_ok=True)
            pq.write_table(table([(i, bus)], False), sub / "part-0.parquet")
            written.append(sub / "part-0.parquet")
    elif layout == "files":
        for f, start in enumerate(range(0, len(items), buses_per_file)):
            path = folder / f"part-{f:05d}.parquet"
            pq.write_table(table(items[start : start + buses_per_file], True), path)
            written.append(path)
    elif layout == "table":
        path = folder / "fleet.parquet"
        with pq.ParquetWriter(path, table(items[:1], True).schema) as w:
            for start in range(0, len(items), buses_per_file):
                w.write_table(table(items[start : start + buses_per_file], True))
        written.append(path)
    else:
        raise ValueError(f"layout must be 'files', 'hive' or 'table', got {layout!r}")
    return written


def ieee33_fleet(
    n_experiments: int = 200,
    *,
    seed: int = 0,
    noise: float = 0.01,
    classes: Mapping[str, tuple[float, ...]] | None = None,
) -> tuple[pd.DataFrame, pd.DataFrame]:
    """The 33-bus feeder (pandapower ``case33bw``) with a ZIP load on every loaded bus.

    Each load gets its class's mix (classes assigned in turn along the buses). Each
    experiment draws the source voltage in [0.95, 1.05] p.u. and every load's level in
    [0.5, 1.5] of its nominal, runs pandapower's power flow, and records at each load
    bus V and P, Q per unit of that load's level (a meter's demand), plus noise.

    Returns
    -------
    rows : DataFrame
        ``bus_id``, ``customer_class``, ``v``, ``p``, ``q``; one row per bus and
        converged experiment.
    truth : DataFrame
        ``bus_id``, ``customer_class``, ``a1``, ``a2``, ``a4``, ``a5``.
    """
    import pandapower as pp
    import pandapower.networks as pn

    classes = dict(classes or CLASS_MIXES)
    names = list(classes)
    net = pn.case33bw()
    loads = net.load.index.to_numpy()
    cls = [names[i % len(names)] for i in range(loads.size)]
    mix = np.array([classes[c] for c in cls])
    net.load["const_z_p_percent"] = 100 * mix[:, 0]
    net.load["const_i_p_percent"] = 100 * mix[:, 1]
    net.load["const_z_q_percent"] = 100 * mix[:, 2]
    net.load["const_i_q_percent"] = 100 * mix[:, 3]
    p_nom = net.load.p_mw.to_numpy().copy()
    q_nom = net.load.q_mvar.to_numpy().copy()
    rng = np.random.default_rng(seed)
    buses = net.load.bus.to_numpy()
    out: list[pd.DataFrame] = []
    for _ in range(n_experiments):
        level = rng.uniform(0.5, 1.5, loads.size)
        net.ext_grid["vm_pu"] = rng.uniform(0.95, 1.05)
        net.load["p_mw"] = p_nom * level
        net.load["q_mvar"] = q_nom * level
        e_p = rng.standard_normal(loads.size)
        e_q = rng.standard_normal(loads.size)
        try:
            pp.runpp(net, tolerance_mva=1e-10, numba=False)  # 33 buses: compiling costs more
        except pp.LoadflowNotConverged:
            continue
        out.append(
            pd.DataFrame(
                {
                    "bus_id": [f"bus{b + 1:02d}" for b in buses],
                    "customer_class": cls,
                    "v": net.res_bus.vm_pu.to_numpy()[buses],
                    "p": net.res_load.p_mw.to_numpy() / (p_nom * level) + noise * e_p,
                    "q": net.res_load.q_mvar.to_numpy() / (q_nom * level) + noise * e_q,
                }
            )
        )
    truth = pd.DataFrame(
        {
            "bus_id": [f"bus{b + 1:02d}" for b in buses],
            "customer_class": cls,
            "a1": mix[:, 0],
            "a2": mix[:, 1],
            "a4": mix[:, 2],
            "a5": mix[:, 3],
        }
    )
    return pd.concat(out, ignore_index=True), truth
