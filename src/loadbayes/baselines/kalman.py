"""A Kalman filter whose state is a block's coefficients.

Measurement model (one scalar equation per sample and equation): ``r_t = z_t' b_t + v_t``,
``v_t ~ N(0, R)``; state model: ``b_t = b_{t-1} + w_t``, ``w_t ~ N(0, Q)``. With ``Q = 0``
the filter is recursive least squares for constant coefficients; with ``Q > 0`` the state
is a random walk and the filter tracks drifting ones (the paper's claim that the KF "only
works with time-invariant parameters" holds only for ``Q = 0``).

Defaults, documented because the paper's tuning (its reference [26]) is not given:
``b_0 = 0``, ``P_0 = 100 I`` (diffuse next to coefficients of order one), ``Q = 0``, and
``R`` estimated as the least-squares residual variance of the same data (a filter tuned
to the true noise level, which favours the KF).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
from numba import njit

from loadbayes.posterior import Posterior, gaussian_draws

__all__ = ["KalmanResult", "kalman", "kalman_block"]


@dataclass(frozen=True)
class KalmanResult:
    """Final state and (optionally) its path.

    Attributes
    ----------
    mean : ndarray, shape (k,)
        Final state estimate.
    cov : ndarray, shape (k, k)
        Final state covariance.
    measurement_var : float
        The measurement variance R used.
    path_mean, path_sd : ndarray, shape (n, k), optional
        State mean and standard deviation after each measurement.
    """

    mean: np.ndarray
    cov: np.ndarray
    measurement_var: float
    path_mean: np.ndarray | None = None
    path_sd: np.ndarray | None = None


@njit(cache=True, nogil=True)
def _filter(z, r, x0, p0, q, rvar, keep, path_mean, path_sd):  # pragma: no cover - compiled
    n, k = z.shape
    x = x0.copy()
    p = p0.copy()
    pz = np.empty(k)
    gain = np.empty(k)
    a = np.empty((k, k))
    for t in range(n):
        for i in range(k):
            for j in range(k):
                p[i, j] += q[i, j]
        s = rvar
        innov = r[t]
        for i in range(k):
            acc = 0.0
            for j in range(k):
                acc += p[i, j] * z[t, j]
            pz[i] = acc
            s += z[t, i] * acc
            innov -= z[t, i] * x[i]
        for i in range(k):
            gain[i] = pz[i] / s
            x[i] += gain[i] * innov
        # Joseph form: P = (I - K z') P (I - K z')' + K R K', symmetric and PSD by design.
        for i in range(k):
            for j in range(k):
                a[i, j] = (1.0 if i == j else 0.0) - gain[i] * z[t, j]
        tmp = a @ p
        p = tmp @ a.T
        for i in range(k):
            for j in range(k):
                p[i, j] += gain[i] * rvar * gain[j]
        if keep:
            for i in range(k):
                path_mean[t, i] = x[i]
                path_sd[t, i] = np.sqrt(max(p[i, i], 0.0))
    return x, p


def kalman_block(
    z: np.ndarray,
    r: np.ndarray,
    *,
    measurement_var: float | None = None,
    process_noise: float | np.ndarray = 0.0,
    x0: np.ndarray | None = None,
    p0: float | np.ndarray = 100.0,
    return_path: bool = False,
) -> KalmanResult:
    """Filter the scalar measurements ``r_t = z_t' b + v_t`` in order.

    Parameters
    ----------
    z : ndarray, shape (n, k)
        Regressors, one row per measurement.
    r : ndarray, shape (n,)
        Measurements.
    measurement_var : float, optional
        R; by default the least-squares residual variance of ``(z, r)``.
    process_noise : float or ndarray
        Q: a scalar (times the identity) or a (k, k) matrix, per measurement.
    x0 : ndarray, optional
        Initial state (zeros by default).
    p0 : float or ndarray
        Initial covariance: a scalar (times the identity) or a (k, k) matrix.
    return_path : bool
        Keep the state mean and sd after every measurement.
    """
    z = np.ascontiguousarray(z, dtype=float)
    r = np.ascontiguousarray(r, dtype=float).reshape(-1)
    n, k = z.shape
    if r.size != n:
        raise ValueError(f"z has {n} rows, r has {r.size}")
    if measurement_var is None:
        coef = np.linalg.lstsq(z, r, rcond=None)[0]
        res = r - z @ coef
        measurement_var = float(res @ res / max(n - k, 1))
    if not measurement_var > 0:
        measurement_var = 1e-300  # noise-free data: the filter becomes exact elimination
    q = np.asarray(process_noise, dtype=float)
    q = q * np.eye(k) if q.ndim == 0 else q
    p0m = np.asarray(p0, dtype=float)
    p0m = p0m * np.eye(k) if p0m.ndim == 0 else p0m
    x0v = np.zeros(k) if x0 is None else np.asarray(x0, dtype=float)
    path_mean = np.empty((n if return_path else 0, k))
    path_sd = np.empty((n if return_path else 0, k))
    x, p = _filter(
        z, r, x0v, p0m.copy(), q, float(measurement_var), return_path, path_mean, path_sd
    )
    return KalmanResult(
        x,
        (p + p.T) / 2,
        float(measurement_var),
        path_mean if return_path else None,
        path_sd if return_path else None,
    )


def kalman(
    model: Any,
    data: Mapping[str, np.ndarray],
    *,
    process_noise: float = 0.0,
    measurement_var: Mapping[str, float] | None = None,
    p0: float = 100.0,
    chains: int = 4,
    draws: int = 2000,
    seed: int | None = 0,
    settings: Mapping[str, Any] | None = None,
) -> Posterior:
    """Run the filter on every block of ``model`` and return its final state as a Posterior.

    The draws come from the final Gaussian state (mean, covariance), transformed like the
    Gibbs draws; ``settings["estimate"]`` has the exact filtered values.
    """
    rows = model.rows(data)
    names = tuple(model.gram_columns)
    rng = np.random.default_rng(seed)
    raw: dict[str, np.ndarray] = {}
    estimate: dict[str, float] = {}
    used_r: dict[str, float] = {}
    for block in model.blocks:
        z, r = block.equations_of(rows, names)
        res = kalman_block(
            z,
            r,
            measurement_var=(measurement_var or {}).get(block.name),
            process_noise=process_noise,
            p0=p0,
        )
        used_r[block.name] = res.measurement_var
        x = gaussian_draws(res.mean, res.cov, chains, draws, rng)
        for i, name in enumerate(block.coef_names):
            raw[name] = x[..., i]
            estimate[name] = float(res.mean[i])
        raw[block.tau_name] = np.full((chains, draws), 1.0 / res.measurement_var)
        estimate[block.tau_name] = 1.0 / res.measurement_var
    point = model.transform({k: np.asarray(v).reshape(1, 1) for k, v in estimate.items()})
    full = {
        "n": rows.shape[0],
        "scheme": "kalman",
        "process_noise": process_noise,
        "p0": p0,
        "measurement_var": used_r,
        "seed": seed,
    }
    full.update(settings or {})
    full["estimate"] = {k: float(np.asarray(v).reshape(-1)[0]) for k, v in point.items()}
    return Posterior(
        model.transform(raw),
        model=model.name,
        method="kalman",
        coefficients=model.coefficients,
        free=getattr(model, "free", None),
        settings=full,
    )
