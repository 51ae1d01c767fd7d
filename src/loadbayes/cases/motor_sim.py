"""Induction-motor scenarios: documented motors, voltage disturbances, simulated records.

The simulator integrates the third-order model of :mod:`loadbayes.models.motor` (time in
seconds, ``wb = 2 pi f``) from its steady state through a terminal-voltage disturbance,
and returns the quantities the paper's estimator takes as measured (section "IM Model":
states, their derivatives and the currents), with the paper's noise added.

Motors: ``MOTORS`` (documented in :mod:`loadbayes.models.motor_library`).

Regression coefficients at 60 Hz (b1, b2, b3 in 1/s; ab, ac in p.u.)::

    motor              b1        b2        b3       ab       ac
    small_industrial   -2.0076   -6.0823   -0.7143  0.4184   3.6501
    large_industrial   -0.8546   -3.1086   -0.3333  0.2456   4.3392
    krause_3hp        -11.4427  -13.4378   -0.7077  3.9199  13.3983
    krause_2250hp      -0.6252   -2.5427   -0.7396  0.4532   7.0032

Output columns of :func:`simulate` (all p.u.; derivatives per second)
----------------------------------------------------------------------
``t_s, ud, uq, ed, eq, w, id, iq, ded, deq, dw, p, q`` then the noiseless copies
``<name>_true`` of every column that can carry noise (``ded, deq, dw, id, iq`` always;
``ed, eq, w, ud, uq`` only with ``noise_on_regressors=True``; the copies are always
present so the schema does not change). ``ded, deq, dw`` are the right-hand side of the
ODE at the samples (exact), not finite differences. ``p`` and ``q`` are computed from
the noiseless voltages and currents.

One idea at about 480 lines, the reference simulation of a motor through a disturbance:
the profiles it is driven by (constant, sag, ramp, random walk, from a file), the
integration, and the record's CSV with its settings sidecar that ``fit im`` reads back.
"""

from __future__ import annotations

import json
import math
import os
import tempfile
from bisect import bisect_left, bisect_right
from dataclasses import dataclass, field, replace
from functools import cached_property
from pathlib import Path
from typing import Any, Literal

import numpy as np
import pandas as pd
from numpy.typing import ArrayLike, NDArray
from scipy.integrate import solve_ivp

from loadbayes.models.motor import (
    MotorParams,
    currents,
    derivatives,
    power,
    steady_state,
)
from loadbayes.models.motor_library import MOTORS

__all__ = [
    "COLUMNS",
    "DEFAULT_T0",
    "MOTORS",
    "Disturbance",
    "constant",
    "default_disturbance",
    "from_file",
    "ramp",
    "random_walk",
    "read_csv",
    "sag",
    "simulate",
    "write_csv",
]

COLUMNS: tuple[str, ...] = tuple("t_s ud uq ed eq w id iq ded deq dw p q".split())
_TARGETS = ("ded", "deq", "dw", "id", "iq")
_REGRESSORS = ("ed", "eq", "w", "ud", "uq")
DEFAULT_T0 = 0.6
"""Default load-torque coefficient (p.u. at synchronous speed) when no loading is given."""


"""Documented motors (module docstring gives the sources)."""


@dataclass(frozen=True, eq=False)
class Disturbance:
    """Terminal-voltage magnitude ``V(t)`` in p.u., piecewise linear in time.

    Parameters
    ----------
    t_knots, v_knots : ndarray
        Knots of the piecewise-linear profile; ``V`` is held constant outside them. A
        repeated time is a step (the later value applies from that time on).
    breakpoints : tuple of float
        Times where ``V`` or ``dV/dt`` jumps; the simulator restarts the integrator there.
    info : dict
        JSON-serialisable description, stored in the simulated record's ``attrs``.
    """

    t_knots: NDArray[np.float64]
    v_knots: NDArray[np.float64]
    breakpoints: tuple[float, ...] = ()
    info: dict[str, Any] = field(default_factory=dict)

    def __call__(self, t: ArrayLike) -> NDArray[np.float64]:
        """Return ``V(t)`` (vectorised over ``t``; right-continuous at steps)."""
        return self._eval(t, "right")

    def left_limit(self, t: ArrayLike) -> NDArray[np.float64]:
        """Return ``V(t-)``, the value just before any step at ``t``."""
        return self._eval(t, "left")

    @cached_property
    def _knots(self) -> tuple[list[float], list[float]]:
        return self.t_knots.tolist(), self.v_knots.tolist()

    def _eval_scalar(self, t: float, side: Literal["left", "right"]) -> NDArray[np.float64]:
        # The same arithmetic as _eval on one time (an ODE solver's call), in floats:
        # NumPy's per-call overhead on 0-d arrays cost more than the integration's model.
        tk, vk = self._knots
        k = (bisect_right if side == "right" else bisect_left)(tk, t) - 1
        k = min(max(k, 0), len(tk) - 2)
        span = tk[k + 1] - tk[k]
        frac = (t - tk[k]) / span if span > 0 else 1.0
        v = vk[k] + min(max(frac, 0.0), 1.0) * (vk[k + 1] - vk[k])
        if t < tk[0]:
            v = vk[0]
        if t > tk[-1]:
            v = vk[-1]
        return np.array(v)

    def _eval(self, t: ArrayLike, side: Literal["left", "right"]) -> NDArray[np.float64]:
        if isinstance(t, float) and t == t:  # a finite or infinite float, not NaN
            return self._eval_scalar(t, side)
        t = np.asarray(t, dtype=float)
        # At a repeated knot (a step) side="right" picks the later value, "left" the earlier.
        k = np.clip(np.searchsorted(self.t_knots, t, side=side) - 1, 0, self.t_knots.size - 2)
        t_lo, t_hi = self.t_knots[k], self.t_knots[k + 1]
        v_lo, v_hi = self.v_knots[k], self.v_knots[k + 1]
        span = t_hi - t_lo
        frac = np.where(span > 0, (t - t_lo) / np.where(span > 0, span, 1.0), 1.0)
        v = v_lo + np.clip(frac, 0.0, 1.0) * (v_hi - v_lo)
        v = np.where(t < self.t_knots[0], self.v_knots[0], v)
        return np.where(t > self.t_knots[-1], self.v_knots[-1], v)


def _profile(t: list[float], v: list[float], info: dict[str, Any]) -> Disturbance:
    ta, va = np.asarray(t, dtype=float), np.asarray(v, dtype=float)
    if ta.size < 2 or np.any(np.diff(ta) < 0) or not np.all(np.isfinite(va)):
        raise ValueError("knot times must be non-decreasing (at least two) and V finite")
    return Disturbance(ta, va, tuple(sorted(set(ta.tolist()))), info)


def constant(v_pu: float = 1.0) -> Disturbance:
    """Constant voltage ``V(t) = v_pu`` (the motor stays at its steady state)."""
    return _profile([0.0, 1.0], [v_pu, v_pu], {"kind": "constant", "v_pu": v_pu})


def sag(
    depth: float, start_s: float, duration_s: float, recovery_s: float = 0.0, *, v0_pu: float = 1.0
) -> Disturbance:
    """Voltage sag: a step down by ``depth`` (fraction of ``v0_pu``) held for ``duration_s``.

    Parameters
    ----------
    depth : float
        Fractional drop, in [0, 1]: during the sag ``V = v0_pu (1 - depth)``.
    start_s, duration_s : float
        Start time and length of the sag (s).
    recovery_s : float
        Length of a linear recovery back to ``v0_pu`` after the sag; 0 is a step back.
    v0_pu : float
        Pre-disturbance voltage.

    Returns
    -------
    Disturbance
        The profile ``V(t)``.
    """
    if not (0 <= depth <= 1 and start_s > 0 and duration_s > 0 and recovery_s >= 0):
        raise ValueError("need 0 <= depth <= 1, start_s > 0, duration_s > 0, recovery_s >= 0")
    low, end = v0_pu * (1.0 - depth), start_s + duration_s
    return _profile(
        [0.0, start_s, start_s, end, end + recovery_s, end + recovery_s + 1.0],
        [v0_pu, v0_pu, low, low, v0_pu, v0_pu],
        {
            "kind": "sag",
            "depth": depth,
            "start_s": start_s,
            "duration_s": duration_s,
            "recovery_s": recovery_s,
            "v0_pu": v0_pu,
        },
    )


def default_disturbance() -> Disturbance:
    """Return the default excitation: a 25% sag at 0.5 s for 150 ms, stepping back.

    Large enough to move the rotor speed and flux well away from their steady values, so
    that all five coefficients are identifiable from a 3 s record.
    """
    return sag(0.25, 0.5, 0.15)


def ramp(v_end: float, start_s: float, duration_s: float, *, v0_pu: float = 1.0) -> Disturbance:
    """Linear ramp from ``v0_pu`` (before ``start_s``) to ``v_end`` over ``duration_s``."""
    if not (start_s >= 0 and duration_s > 0):
        raise ValueError("need start_s >= 0 and duration_s > 0")
    return _profile(
        [0.0, start_s, start_s + duration_s, start_s + duration_s + 1.0],
        [v0_pu, v0_pu, v_end, v_end],
        {
            "kind": "ramp",
            "v_end": v_end,
            "start_s": start_s,
            "duration_s": duration_s,
            "v0_pu": v0_pu,
        },
    )


def random_walk(
    sd: float,
    seed: int,
    *,
    step_s: float = 0.01,
    t_end_s: float = 10.0,
    start_s: float = 0.0,
    v0_pu: float = 1.0,
) -> Disturbance:
    """Gaussian random walk of the voltage, linearly interpolated between knots.

    Parameters
    ----------
    sd : float
        Diffusion in p.u. per sqrt(second): each knot step adds ``N(0, sd^2 step_s)``.
    seed : int
        Seed of the walk's own generator.
    step_s, t_end_s, start_s : float
        Knot spacing, horizon (held constant after it) and start of the walk.
    v0_pu : float
        Voltage before ``start_s``.

    Returns
    -------
    Disturbance
        The profile ``V(t)``; it is continuous, so no integrator restarts are needed.
    """
    if not (sd >= 0 and step_s > 0 and t_end_s > start_s >= 0):
        raise ValueError("need sd >= 0, step_s > 0 and t_end_s > start_s >= 0")
    n = int(math.ceil((t_end_s - start_s) / step_s))
    steps = np.random.default_rng(seed).normal(0.0, sd * math.sqrt(step_s), n)
    t = np.concatenate([[0.0], start_s + step_s * np.arange(n + 1)])
    v = np.concatenate([[v0_pu, v0_pu], v0_pu + np.cumsum(steps)])
    d = _profile(
        t.tolist(),
        v.tolist(),
        {
            "kind": "random_walk",
            "sd": sd,
            "seed": seed,
            "step_s": step_s,
            "t_end_s": t_end_s,
            "start_s": start_s,
            "v0_pu": v0_pu,
        },
    )
    return replace(d, breakpoints=(start_s,))


def from_file(path: str | os.PathLike[str]) -> Disturbance:
    """Voltage profile from a CSV file with columns ``t_s`` and ``v_pu``.

    The profile is linearly interpolated and held at the end values outside the file's
    range; ``t_s`` must be non-decreasing (a repeated time is a step).
    """
    table = pd.read_csv(path)
    missing = {"t_s", "v_pu"} - set(table.columns)
    if missing:
        raise ValueError(f"{path}: missing column(s) {sorted(missing)}")
    t, v = table["t_s"].to_numpy(float), table["v_pu"].to_numpy(float)
    d = _profile(t.tolist(), v.tolist(), {"kind": "file", "path": str(path)})
    steps = t[1:][np.diff(t) == 0]
    return replace(d, breakpoints=tuple(sorted(set(steps.tolist()))))


def _resolve_loading(t0: float | None, slip: float | None, p_pu: float | None) -> dict:
    given = {k: v for k, v in {"t0": t0, "slip": slip, "p_pu": p_pu}.items() if v is not None}
    return given or {"t0": DEFAULT_T0}


def simulate(
    motor: MotorParams | str,
    *,
    disturbance: Disturbance | None = None,
    angle: Disturbance | None = None,
    t_end_s: float = 3.0,
    dt_s: float = 1e-3,
    f_nominal_hz: float | None = None,
    t0: float | None = None,
    slip: float | None = None,
    p_pu: float | None = None,
    noise: float = 0.05,
    noise_on_regressors: bool = False,
    seed: int = 0,
    rtol: float = 1e-9,
    atol: float = 1e-11,
    method: str = "DOP853",
    max_step_s: float | None = None,
) -> pd.DataFrame:
    """Simulate a motor through a voltage disturbance and add measurement noise.

    Parameters
    ----------
    motor : MotorParams or str
        Parameters, or a key of ``MOTORS``.
    disturbance : Disturbance, optional
        ``V(t)``; defaults to :func:`default_disturbance`. ``V(0)`` sets the steady state.
    angle : Disturbance, optional
        Terminal-voltage angle ``theta(t)`` in rad (a :class:`Disturbance` whose values are
        angles), measured in a frame turning at the nominal frequency, as a network
        simulator's bus angle is. The motor then sees ``Ud + j Uq = V e^{j (theta(t) -
        theta(0))}``: a constant angle changes nothing, a moving one is a frequency
        deviation. Default: no angle, ``Uq = 0`` throughout.
    t_end_s, dt_s : float
        Record length and sample spacing (s); samples at ``k dt_s``, ``k = 0..n-1``.
    f_nominal_hz : float, optional
        Overrides the motor's nominal frequency (and so ``wb``).
    t0, slip, p_pu : float, optional
        Loading, at most one (see ``steady_state``); default ``t0 = DEFAULT_T0``.
    noise : float
        Noise sd as a fraction of each channel's RMS (the paper's 5%).
    noise_on_regressors : bool
        Also add noise to ``ed, eq, w, ud, uq`` (the paper adds it to targets only).
    seed : int
        Seed of the noise generator.
    rtol, atol : float
        Integrator tolerances.
    method : str
        ``solve_ivp`` method. The default, DOP853, fits: the Jacobian's eigenvalues lie
        within about 10-200 1/s for the motors here, not stiff at the 1 ms samples.
    max_step_s : float, optional
        Largest integrator step; default ``10 dt_s``. Between breakpoints a smooth
        profile (random walk, file) has kinks the adaptive step could stride over.

    Returns
    -------
    pandas.DataFrame
        Columns as in the module docstring; ``attrs`` holds T0, wb, the motor, the true
        coefficients, the steady state, the disturbance, noise settings and solver.
    """
    params = MOTORS[motor] if isinstance(motor, str) else motor
    if f_nominal_hz is not None:
        params = replace(params, f_hz=float(f_nominal_hz))
    disturbance = default_disturbance() if disturbance is None else disturbance
    if not (t_end_s > 0 and dt_s > 0 and noise >= 0):
        raise ValueError("need t_end_s > 0, dt_s > 0 and noise >= 0")
    loading = _resolve_loading(t0, slip, p_pu)
    op = steady_state(params, v_pu=float(disturbance(0.0)), **loading)

    max_step = 10.0 * dt_s if max_step_s is None else max_step_s
    n = int(math.floor(t_end_s / dt_s + 1e-9)) + 1
    t = dt_s * np.arange(n)
    states = np.empty((3, n))
    cuts = disturbance.breakpoints + (() if angle is None else angle.breakpoints)
    edges = sorted({0.0, t[-1], *(b for b in cuts if 0.0 < b < t[-1])})
    theta0 = 0.0 if angle is None else float(angle(0.0))

    def terminal(tt: ArrayLike, left: bool = False) -> tuple[NDArray, NDArray]:
        # (Ud, Uq) of V e^{j (theta - theta0)}; without an angle, Uq = 0 (as before).
        v = disturbance.left_limit(tt) if left else disturbance(tt)
        if angle is None:
            return v, np.zeros_like(v)
        th = (angle.left_limit(tt) if left else angle(tt)) - theta0
        return v * np.cos(th), v * np.sin(th)

    y = op.state

    states[:, 0] = y
    for a, b in zip(edges[:-1], edges[1:], strict=True):
        # Inside (a, b) V is smooth; at b itself the solver must see V(b-), not a step's
        # new value, or the last step of each segment would straddle the jump.
        def rhs(tt: float, yy: NDArray[np.float64], b: float = b) -> NDArray[np.float64]:
            ud, uq = terminal(tt, left=tt >= b)
            return derivatives(yy, ud, uq, params, t0=op.t0)

        inside = np.flatnonzero((t > a) & (t <= b))
        t_eval = np.append(t[inside], b) if inside.size == 0 or t[inside[-1]] < b else t[inside]
        sol = solve_ivp(
            rhs, (a, b), y, method=method, t_eval=t_eval, rtol=rtol, atol=atol, max_step=max_step
        )
        if not sol.success:
            raise RuntimeError(f"integration failed on [{a}, {b}] s: {sol.message}")
        states[:, inside] = sol.y[:, : inside.size]
        y = sol.y[:, -1]

    ud, uq = terminal(t)
    ed, eq, w = states
    id_, iq = currents(ud, uq, ed, eq, params)
    ded, deq, dw = derivatives(states, ud, uq, params, t0=op.t0)
    p, q = power(ud, uq, id_, iq)
    values = (t, ud, uq, ed, eq, w, id_, iq, ded, deq, dw, p, q)
    true = dict(zip(COLUMNS, values, strict=True))
    df = pd.DataFrame(true, columns=list(COLUMNS))

    # Targets draw first so their noise does not depend on noise_on_regressors.
    rng = np.random.default_rng(seed)
    noisy = _TARGETS + (_REGRESSORS if noise_on_regressors else ())
    sds = {}
    for col in noisy:
        sds[col] = noise * float(np.sqrt(np.mean(true[col] ** 2)))
        df[col] = true[col] + sds[col] * rng.standard_normal(n)
    for col in _TARGETS + _REGRESSORS:
        df[f"{col}_true"] = true[col]

    df.attrs.update(
        {
            "model": "induction_motor_third_order",
            "time_base": "seconds; derivatives in 1/s; slip terms carry wb",
            "f_nominal_hz": params.f_hz,
            "wb": params.wb,
            "t0": op.t0,
            "motor": params.to_dict(),
            "coefficients": params.coefficients(),
            "steady_state": op.to_dict(),
            "loading": loading,
            "disturbance": disturbance.info,
            "angle": None if angle is None else angle.info,
            "noise": noise,
            "noise_on_regressors": noise_on_regressors,
            "noise_sd": sds,
            "seed": seed,
            "solver": {"method": method, "rtol": rtol, "atol": atol, "max_step_s": max_step},
            "dt_s": dt_s,
            "t_end_s": float(t[-1]),
        }
    )
    return df


def _atomic_write(path: Path, write: Any) -> None:
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    try:
        with os.fdopen(fd, "w", newline="") as fh:
            write(fh)
        os.chmod(tmp, 0o644)  # mkstemp creates 0600; the record is meant to be shared
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def write_csv(df: pd.DataFrame, path: str | os.PathLike[str]) -> tuple[Path, Path]:
    """Write the record as CSV and its ``attrs`` as a JSON sidecar, each atomically.

    Parameters
    ----------
    df : pandas.DataFrame
        A record from :func:`simulate`.
    path : path-like
        CSV path; the sidecar is ``path.with_suffix('.json')``.

    Returns
    -------
    tuple of Path
        The CSV and JSON paths. Each file is written to a temporary file in the same
        folder, then renamed, so a reader never sees a partial file.
    """
    csv_path = Path(path)
    json_path = csv_path.with_suffix(".json")
    # Default float formatting is repr, which round-trips exactly with read_csv below.
    _atomic_write(csv_path, lambda fh: df.to_csv(fh, index=False))
    _atomic_write(json_path, lambda fh: json.dump(df.attrs, fh, indent=2, sort_keys=True))
    return csv_path, json_path


def read_csv(path: str | os.PathLike[str]) -> pd.DataFrame:
    """Read a record written by :func:`write_csv`, restoring ``attrs`` from the sidecar."""
    csv_path = Path(path)
    df = pd.read_csv(csv_path, float_precision="round_trip")
    sidecar = csv_path.with_suffix(".json")
    if sidecar.exists():
        df.attrs.update(json.loads(sidecar.read_text()))
    return df
