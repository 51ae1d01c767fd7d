"""The paper's experiments: the load-factor draws and :func:`generate_experiments`.

The factors and the noise come from separate streams of one seed, so the factors of a
seed do not depend on the noise settings and :func:`draw_factors` rebuilds them alone.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
import pandas as pd

from loadbayes.cases.ieee33.feeder import Feeder33
from loadbayes.cases.ieee33.network import DEFAULT_ZIP, N_FACTORS, ZIP_BUS, Engine

if TYPE_CHECKING:
    from numpy.typing import ArrayLike

#: The paper's range of the per-load factors.
FACTOR_RANGE = (0.1, 4.5)
Seed = int | np.random.SeedSequence | None


def factor_streams(seed: Seed, rng: np.random.Generator | None) -> list[np.random.Generator]:
    """The two generators of one seed: ``[factors, noise]``."""
    # Separate streams for the load factors and the noise: the factors of a seed do not
    # depend on the noise settings, and draw_factors can rebuild them alone.
    if rng is not None:
        return rng.spawn(2)
    return [np.random.default_rng(s) for s in np.random.SeedSequence(seed).spawn(2)]


def draw_factors(
    n: int,
    *,
    seed: Seed = 0,
    rng: np.random.Generator | None = None,
    factor_range: tuple[float, float] = FACTOR_RANGE,
) -> np.ndarray:
    """Draw the load factors of ``n`` experiments.

    Parameters
    ----------
    n : int
        Number of experiments.
    seed : int or numpy.random.SeedSequence, optional
        Seed; ignored when ``rng`` is given.
    rng : numpy.random.Generator, optional
        Generator to spawn the factor stream from.
    factor_range : (float, float)
        Bounds of the uniform distribution of each factor.

    Returns
    -------
    numpy.ndarray
        Shape ``(n, N_FACTORS)``; column ``j`` multiplies ``p_mw`` and ``q_mvar`` of the
        ``j``-th non-ZIP load (``Feeder33.factor_loads``).

    Notes
    -----
    This is the matrix :func:`generate_experiments` and
    :func:`loadbayes.studies.ieee33_validation.validate` use for the same ``seed`` (for
    any ``noise_sd`` and ``workers``). Rows are drawn in order, so the
    first ``k`` rows do not depend on ``n``.
    """
    return draw_factors_from(factor_streams(seed, rng)[0], n, factor_range)


def draw_factors_from(
    gen: np.random.Generator, n: int, factor_range: tuple[float, float]
) -> np.ndarray:
    """``n`` rows of load factors from the factor stream ``gen`` (see :func:`factor_streams`)."""
    lo, hi = check_range(factor_range)
    return gen.uniform(lo, hi, size=(int(n), N_FACTORS))


def check_range(factor_range: tuple[float, float]) -> tuple[float, float]:
    """``factor_range`` as two floats; raise ``ValueError`` unless ``0 <= low <= high``."""
    lo, hi = (float(b) for b in factor_range)
    if not 0.0 <= lo <= hi:
        raise ValueError(f"factor_range must satisfy 0 <= low <= high, got {factor_range}")
    return lo, hi


def generate_experiments(
    n: int,
    *,
    zip_p: ArrayLike = DEFAULT_ZIP,
    zip_q: ArrayLike = DEFAULT_ZIP,
    factor_range: tuple[float, float] = FACTOR_RANGE,
    noise_sd: float = 0.1,
    noise_on_v: float = 0.0,
    seed: Seed = 0,
    rng: np.random.Generator | None = None,
    progress: bool = False,
    workers: int = 1,
    engine: Engine = "newton",
) -> pd.DataFrame:
    """Simulate the paper's ZIP experiments at bus 18.

    Parameters
    ----------
    n : int
        Number of experiments (power flows).
    zip_p, zip_q : array_like
        True ZIP shares of P (a1, a2, a3) and Q (a4, a5, a6).
    factor_range : (float, float)
        Each non-ZIP load is scaled by its own factor from U[low, high].
    noise_sd : float
        Standard deviation of the Gaussian noise on P and Q, as a fraction of the
        nominal P0 and Q0 (i.e. in per unit).
    noise_on_v : float
        Standard deviation of the noise on V, in p.u. (of V0 = 1).
    seed : int or numpy.random.SeedSequence, optional
        Seed of the load factors and the noise; ignored when ``rng`` is given.
    rng : numpy.random.Generator, optional
        Generator to spawn the factor and noise streams from.
    progress : bool
        Progress bar on stderr (needs ``tqdm``).
    workers : int
        Processes; the output is identical for any value.
    engine : {"newton", "recycle", "runpp"}
        Power-flow engine (:class:`Feeder33`).

    Returns
    -------
    pandas.DataFrame
        Columns ``experiment, v_pu, p_true_pu, q_true_pu, p_meas_pu, q_meas_pu,
        v_meas_pu, converged``. Experiments whose power flow did not converge keep their
        row with ``converged=False`` and NaN values. ``attrs`` holds ``n_failed``, the
        settings, ``p0_mw``, ``q0_mvar`` and ``bus`` (paper numbering). The load factors
        are ``draw_factors(n, seed=seed, factor_range=factor_range)``.

    Notes
    -----
    The paper writes the noise as N(0, 0.1) and calls it a 10% error; it is read here as
    a standard deviation of 0.1 p.u. (``noise_sd``), the project's reading of the paper.
    The paper does not say whether V is noisy; ``noise_on_v`` defaults to 0.
    """
    n = int(n)
    if n < 1:
        raise ValueError(f"n must be >= 1, got {n}")
    if noise_sd < 0 or noise_on_v < 0:
        raise ValueError("noise_sd and noise_on_v must be >= 0")
    factor_rng, noise_rng = factor_streams(seed, rng)
    factors = draw_factors_from(factor_rng, n, factor_range)
    # Noise for every row, converged or not, so it does not depend on failures.
    z = noise_rng.standard_normal((n, 3))
    feeder = Feeder33(zip_p=zip_p, zip_q=zip_q, engine=engine)
    res = feeder.run_many(factors, workers=workers, progress=progress)
    df = pd.DataFrame(
        {
            "experiment": np.arange(n, dtype=np.int64),
            "v_pu": res["v_pu"],
            "p_true_pu": res["p_pu"],
            "q_true_pu": res["q_pu"],
            # Departure from the paper's "N(0, 0.1)": 0.1 is a standard deviation here.
            "p_meas_pu": res["p_pu"] + noise_sd * z[:, 0],
            "q_meas_pu": res["q_pu"] + noise_sd * z[:, 1],
            "v_meas_pu": res["v_pu"] + noise_on_v * 1.0 * z[:, 2],  # 1.0 = V0
            "converged": res["converged"],
        }
    )
    df.attrs.update(
        n_failed=int(n - res["converged"].sum()),
        zip_p=feeder.zip_p.tolist(),
        zip_q=feeder.zip_q.tolist(),
        factor_range=list(check_range(factor_range)),
        noise_sd=float(noise_sd),
        noise_on_v=float(noise_on_v),
        seed=seed if isinstance(seed, int) and rng is None else None,
        p0_mw=feeder.p0_mw,
        q0_mvar=feeder.q0_mvar,
        bus=ZIP_BUS + 1,
        engine=engine,
    )
    return df
