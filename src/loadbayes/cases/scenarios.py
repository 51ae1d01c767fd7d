"""Scenarios on the 33-bus data: bad measurements, and a load whose composition changes.

Bad data (:func:`corrupt`)
--------------------------
Three kinds of bad sample, on the power channels (P and Q; the voltage channel is left
clean, so the regressors stay exact as in the paper's experiments):

``spike``
    A gross error: each corrupted sample gets ``+-U[0.5, 1.0]`` p.u. of the nominal
    power added (5-10 noise standard deviations at the paper's 10% noise), sign at
    random, independently on P and Q.
``dropout``
    The power transducer reads zero: P = Q = 0 (V is still measured).
``stuck``
    The transducer freezes: runs of 3-10 consecutive samples repeat the last good
    value. At the paper's noise level a stuck value is hard to tell from a good one
    (the true P moves by about 2% of P0 between experiments, the noise by 10%), so
    this kind is the mildest.
``mixed``
    A third of the bad samples of each kind.

The fraction is the share of samples made bad (2%, 5% and 10% in the studies); the
returned table has a boolean column ``bad``.

Changing composition over a day (:func:`composition_day`)
---------------------------------------------------------
The feeder's other 31 loads follow a daily profile (night valley, morning and evening
peaks) times the paper's random factor ``U[0.1, 4.5]`` drawn afresh for every sample
(the experiment-to-experiment loading that makes the bus-18 voltage move); the ZIP load
at bus 18 keeps its nominal power while its shares drift and jump
(:func:`composition_path`): the constant-impedance share of P grows from morning to
evening (lighting and heating), and a large constant-power load (a drive-fed process)
is on from 13:00 to 19:00, a step of +0.3 in a3 and +0.3 in a6. Every sample is one
power flow with the shares of its time (``Feeder33.run_many`` with per-row shares).
Noise is added afterwards, so the same day can be measured at several noise levels
(:func:`measure`) without new power flows.
"""

from __future__ import annotations

import functools
from typing import Any

import numpy as np
import pandas as pd

__all__ = [
    "BAD_KINDS",
    "SPIKE_PU",
    "STUCK_RUN",
    "composition_day",
    "composition_path",
    "corrupt",
    "daily_profile",
    "measure",
    "paper_data",
]

BAD_KINDS = ("spike", "dropout", "stuck", "mixed")
#: Range of the absolute spike size, in per unit of the nominal power.
SPIKE_PU = (0.5, 1.0)
#: Range of the length of a stuck run, in samples.
STUCK_RUN = (3, 10)
#: Hours at which the constant-power load switches on and off.
JUMP_ON_H, JUMP_OFF_H = 13.0, 19.0


def _seeds(seed: Any, k: int) -> list[np.random.Generator]:
    seq = seed if isinstance(seed, np.random.SeedSequence) else np.random.SeedSequence(seed)
    return [np.random.default_rng(s) for s in seq.spawn(k)]


# ---------------------------------------------------------------------- bad data
def corrupt(
    df: pd.DataFrame,
    *,
    kind: str,
    fraction: float,
    seed: int | np.random.SeedSequence | None = 0,
    columns: tuple[str, ...] = ("p_meas_pu", "q_meas_pu"),
    spike_pu: tuple[float, float] = SPIKE_PU,
    stuck_run: tuple[int, int] = STUCK_RUN,
) -> pd.DataFrame:
    """Corrupt a share of the samples of a measurement table.

    Parameters
    ----------
    df : pandas.DataFrame
        Measurements, e.g. from :func:`loadbayes.cases.ieee33.generate_experiments`.
    kind : {"spike", "dropout", "stuck", "mixed"}
        Kind of bad data (module notes).
    fraction : float
        Share of samples to corrupt, in [0, 0.5].
    seed : int or SeedSequence, optional
        Seed of the positions and sizes.
    columns : tuple of str
        Columns corrupted (the power channels).
    spike_pu : (float, float)
        Range of the absolute spike size.
    stuck_run : (int, int)
        Range of the length of a stuck run.

    Returns
    -------
    pandas.DataFrame
        A copy with the corrupted values and a boolean column ``bad``; ``attrs`` gets
        ``corruption = {kind, fraction, n_bad, seed}``.
    """
    if kind not in BAD_KINDS:
        raise ValueError(f"kind must be one of {BAD_KINDS}, got {kind!r}")
    if not 0.0 <= fraction <= 0.5:
        raise ValueError(f"fraction must be in [0, 0.5], got {fraction}")
    missing = [c for c in columns if c not in df.columns]
    if missing:
        raise ValueError(f"no column(s) {missing} in the table")
    out = df.copy()
    out.attrs = dict(df.attrs)
    n = len(out)
    m = int(round(fraction * n))
    gen_pos, gen_val = _seeds(seed, 2)
    bad = np.zeros(n, dtype=bool)
    vals = {c: out[c].to_numpy(dtype=float).copy() for c in columns}
    if kind == "mixed":
        parts = [m // 3 + (1 if i < m % 3 else 0) for i in range(3)]
        kinds = ("spike", "dropout", "stuck")
    else:
        parts, kinds = [m], (kind,)
    for k, mk in zip(kinds, parts, strict=True):
        if mk == 0:
            continue
        if k == "stuck":
            _stuck(vals, bad, mk, gen_pos, stuck_run)
            continue
        free = np.flatnonzero(~bad)
        idx = np.sort(gen_pos.choice(free, size=min(mk, free.size), replace=False))
        bad[idx] = True
        for c in columns:
            if k == "spike":
                size = gen_val.uniform(*spike_pu, idx.size)
                sign = np.where(gen_val.random(idx.size) < 0.5, -1.0, 1.0)
                vals[c][idx] += sign * size
            else:
                vals[c][idx] = 0.0
    for c in columns:
        out[c] = vals[c]
    out["bad"] = bad
    out.attrs["corruption"] = {
        "kind": kind,
        "fraction": float(fraction),
        "n_bad": int(bad.sum()),
        "seed": seed if isinstance(seed, int) else None,
        "columns": list(columns),
    }
    return out


def _stuck(vals, bad, m, gen, run_range) -> None:
    """Freeze runs of samples at the value before the run until ``m`` samples are bad."""
    n = bad.size
    lo, hi = int(run_range[0]), int(run_range[1])
    done = 0
    tries = 0
    while done < m and tries < 100 * n:
        tries += 1
        length = min(int(gen.integers(lo, hi + 1)), m - done)
        start = int(gen.integers(1, max(n - length, 1) + 1))
        span = slice(start, start + length)
        # the run and the good sample it repeats must all be clean so far
        if start + length > n or bad[start - 1 : start + length].any():
            continue
        for v in vals.values():
            v[span] = v[start - 1]
        bad[span] = True
        done += length


# ------------------------------------------------------------- the paper's data
@functools.lru_cache(maxsize=8)
def _paper_flows(n: int, seed: int) -> pd.DataFrame:
    from loadbayes.cases.ieee33 import generate_experiments

    df = generate_experiments(n, noise_sd=0.0, seed=seed)
    return df[df["converged"]].reset_index(drop=True)


def paper_data(
    n: int,
    *,
    noise_sd: float = 0.1,
    seed: int = 0,
    noise_seed: int | None = None,
) -> pd.DataFrame:
    """The paper's bus-18 experiments with fresh measurement noise.

    The power flows of ``(n, seed)`` are computed once per process and cached; each
    ``noise_seed`` draws new Gaussian noise (sd ``noise_sd`` p.u.) on P and Q, so
    replicates of a study cost no new power flows.

    Returns
    -------
    pandas.DataFrame
        As :func:`loadbayes.cases.ieee33.generate_experiments` (converged rows only).
    """
    base = _paper_flows(int(n), int(seed))
    gen = np.random.default_rng(np.random.SeedSequence([int(seed), 7, noise_seed or 0]))
    out = base.copy()
    out.attrs = dict(base.attrs)
    z = gen.standard_normal((len(out), 2))
    out["p_meas_pu"] = out["p_true_pu"] + noise_sd * z[:, 0]
    out["q_meas_pu"] = out["q_true_pu"] + noise_sd * z[:, 1]
    out.attrs.update(noise_sd=float(noise_sd), noise_seed=noise_seed)
    return out


# ------------------------------------------------------------ changing composition
def daily_profile(t_h: np.ndarray) -> np.ndarray:
    """Relative load level over a day (hours): about 0.5 at night, peaks 0.9 and 1.2."""
    t = np.asarray(t_h, dtype=float) % 24.0
    return (
        0.45
        + 0.45 * np.exp(-0.5 * ((t - 8.0) / 1.5) ** 2)
        + 0.25 * np.exp(-0.5 * ((t - 13.0) / 2.5) ** 2)
        + 0.75 * np.exp(-0.5 * ((t - 19.5) / 2.0) ** 2)
    )


def composition_path(t_h: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """True ZIP shares of P and Q at each time (hours): ``(n, 3)`` each, rows sum to 1.

    a1 drifts from 0.15 (night) to 0.45 (evening), a2 stays near 0.25 with a slow wave;
    the constant-power load on from 13:00 to 19:00 moves 0.3 from a1 and a2 (in equal
    parts) to a3. Q: a4 from 0.5 down to 0.3 over the day, a5 0.2, the same step in a6.
    """
    t = np.asarray(t_h, dtype=float) % 24.0
    day = 0.5 - 0.5 * np.cos(2 * np.pi * (t - 3.0) / 24.0)  # 0 at 03:00, 1 at 15:00
    on = ((t >= JUMP_ON_H) & (t < JUMP_OFF_H)).astype(float)
    a1 = 0.15 + 0.30 * day - 0.15 * on
    a2 = 0.25 + 0.05 * np.sin(2 * np.pi * t / 12.0) - 0.15 * on
    a4 = 0.50 - 0.20 * day - 0.15 * on
    a5 = 0.20 + 0.05 * np.cos(2 * np.pi * t / 24.0) - 0.15 * on
    zp = np.column_stack([a1, a2, 1.0 - a1 - a2])
    zq = np.column_stack([a4, a5, 1.0 - a4 - a5])
    return zp, zq


@functools.lru_cache(maxsize=4)
def day_flows(n: int, seed: int, factor_range: tuple[float, float]) -> pd.DataFrame:
    """The noiseless power flows of :func:`composition_day` (cached per process; do not mutate)."""
    from loadbayes.cases.ieee33 import N_FACTORS, Feeder33

    t_h = np.arange(n) * 24.0 / n
    gen = np.random.default_rng(np.random.SeedSequence([int(seed), 33]))
    rand = gen.uniform(*factor_range, size=(n, N_FACTORS))
    factors = daily_profile(t_h)[:, None] * rand
    zp, zq = composition_path(t_h)
    feeder = Feeder33()
    res = feeder.run_many(factors, zip_p=zp, zip_q=zq)
    df = pd.DataFrame(
        {
            "t_h": t_h,
            "v_pu": res["v_pu"],
            "p_true_pu": res["p_pu"],
            "q_true_pu": res["q_pu"],
            "a1_true": zp[:, 0],
            "a2_true": zp[:, 1],
            "a3_true": zp[:, 2],
            "a4_true": zq[:, 0],
            "a5_true": zq[:, 1],
            "a6_true": zq[:, 2],
            "converged": res["converged"],
        }
    )
    df.attrs.update(
        n_failed=int((~res["converged"]).sum()),
        p0_mw=feeder.p0_mw,
        q0_mvar=feeder.q0_mvar,
        bus=18,
        seed=int(seed),
        factor_range=list(factor_range),
    )
    return df


def composition_day(
    n: int = 1440,
    *,
    noise_sd: float = 0.01,
    seed: int = 0,
    noise_seed: int = 0,
    factor_range: tuple[float, float] = (0.1, 4.5),
) -> pd.DataFrame:
    """A simulated day at bus 18 whose ZIP shares drift and jump (module notes).

    Parameters
    ----------
    n : int
        Samples over 24 h (1440: one a minute).
    noise_sd : float
        Gaussian noise on P and Q, in p.u. of the nominal powers (default 1%, a PMU-grade
        meter; the paper's 10% is :func:`measure` with 0.1).
    seed : int
        Seed of the loading (the power flows, cached per process).
    noise_seed : int
        Seed of the measurement noise.
    factor_range : (float, float)
        Range of the random factor of each other load, times :func:`daily_profile`.

    Returns
    -------
    pandas.DataFrame
        ``t_h, v, p, q`` (measured, p.u.; the names ``loadbayes track zip`` reads by
        default), ``p_true_pu, q_true_pu``, ``a1_true .. a6_true`` and ``converged``;
        rows whose power flow failed are dropped (``attrs["n_failed"]``).
    """
    flows = day_flows(int(n), int(seed), tuple(float(x) for x in factor_range))
    return measure(flows, noise_sd=noise_sd, noise_seed=noise_seed)


def measure(flows: pd.DataFrame, *, noise_sd: float, noise_seed: int = 0) -> pd.DataFrame:
    """Measurements of a :func:`composition_day` power-flow table at a noise level."""
    ok = flows[flows["converged"]].reset_index(drop=True)
    gen = np.random.default_rng(np.random.SeedSequence([int(noise_seed), 34]))
    z = gen.standard_normal((len(ok), 2))
    out = pd.DataFrame(
        {
            "t_h": ok["t_h"],
            "v": ok["v_pu"],
            "p": ok["p_true_pu"] + noise_sd * z[:, 0],
            "q": ok["q_true_pu"] + noise_sd * z[:, 1],
        }
    )
    for c in ok.columns:
        if c not in ("t_h", "v_pu", "converged"):
            out[c] = ok[c]
    out.attrs = dict(flows.attrs)
    out.attrs.update(noise_sd=float(noise_sd), noise_seed=int(noise_seed))
    return out
