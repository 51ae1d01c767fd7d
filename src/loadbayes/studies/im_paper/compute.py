"""The motor study's computation: simulate each motor, fit it five ways, the EIV table.

:func:`run` returns an :class:`~loadbayes.studies.im_paper.study.ImStudy`; nothing here
draws or writes.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np
import pandas as pd

from loadbayes.models.motor import COEFFICIENT_NAMES, MotorParams
from loadbayes.studies.im_paper.study import (
    EIV_MOTOR,
    FULL,
    QUICK,
    SMOKE,
    ImStudy,
    MotorRun,
    _err,
)


def _columns(df: pd.DataFrame) -> dict[str, np.ndarray]:
    from loadbayes.models.motor_fit import DATA_COLUMNS

    return {k: df[k].to_numpy(dtype=float) for k in DATA_COLUMNS}


def _fit_all(params: MotorParams, df: pd.DataFrame, sampler: dict, seed: int) -> dict:
    from loadbayes.baselines.kalman import kalman
    from loadbayes.baselines.least_squares import coupled_least_squares, least_squares
    from loadbayes.fit import accumulate, fit_im
    from loadbayes.fit.sampler import MODEL_DEFAULTS
    from loadbayes.models.motor_fit import InductionMotorModel

    cols = _columns(df)
    f = params.f_hz
    smp = MODEL_DEFAULTS.with_(seed=seed, **sampler)
    fits = {
        "gs": fit_im(cols, f_hz=f, currents="modelled", sampler=smp, warn=False),
        "gs_measured": fit_im(cols, f_hz=f, currents="measured", sampler=smp, warn=False),
    }
    coupled = InductionMotorModel(f_hz=f)
    fits["ls"] = coupled_least_squares(
        coupled, accumulate(coupled, [cols]), first=coupled.first_row(cols), seed=seed
    )
    measured = InductionMotorModel(f_hz=f, currents="measured").with_t0(
        fits["gs_measured"].settings["t0"]
    )
    fits["ls_measured"] = least_squares(measured, accumulate(measured, [cols]), seed=seed)
    fits["kf_measured"] = kalman(measured, cols, seed=seed)
    return fits


def run(
    motors: Sequence[str] | None = None,
    *,
    noise: float = 0.05,
    seed: int = 0,
    quick: bool = False,
    t_end_s: float = 3.0,
    dt_s: float = 1e-3,
    sampler: dict[str, int] | None = None,
    eiv: bool = True,
    progress: Callable[[str], None] | None = None,
    smoke: bool = False,
) -> ImStudy:
    """Simulate each motor, fit it five ways, and run the errors-in-variables check.

    Parameters
    ----------
    motors : sequence of str, optional
        Keys of :data:`loadbayes.models.motor_library.MOTORS`; all by default.
    noise : float
        Noise sd as a fraction of each target channel's RMS (the paper's 5%).
    seed : int
        Seed of the noise and of the samplers.
    quick : bool
        4,000 draws (1,000 burn-in) on 2 chains instead of the paper's 40,000 / 5,000
        (on 4 chains).
    t_end_s, dt_s : float
        Record length and sample spacing (s).
    sampler : dict, optional
        Overrides ``draws``, ``burn``, ``chains``.
    eiv : bool
        Also run the errors-in-variables table (on ``small_industrial`` if studied).
    progress : callable, optional
        Called with a short message before each motor.
    smoke : bool
        :data:`SMOKE` draws: a check of the pipeline, not a result.

    Returns
    -------
    ImStudy
    """
    from loadbayes.cases.motor_sim import default_disturbance, simulate
    from loadbayes.models.motor_library import MOTORS

    motors = list(motors or MOTORS)
    unknown = [m for m in motors if m not in MOTORS]
    if unknown:
        raise ValueError(f"unknown motor(s) {unknown}; documented: {sorted(MOTORS)}")
    smp = dict(SMOKE if smoke else QUICK if quick else FULL)
    smp.update(sampler or {})
    say = progress or (lambda _msg: None)
    runs = {}
    for name in motors:
        say(f"im: {name}: simulating and fitting ...")
        df = simulate(name, noise=noise, seed=seed, t_end_s=t_end_s, dt_s=dt_s)
        runs[name] = MotorRun(name, MOTORS[name], df, _fit_all(MOTORS[name], df, smp, seed))
    eiv_table = pd.DataFrame()
    if eiv:
        target = EIV_MOTOR if EIV_MOTOR in motors else motors[0]
        say(f"im: {target}: errors-in-variables check ...")
        eiv_table = _eiv(target, noise=noise, seed=seed, t_end_s=t_end_s, dt_s=dt_s, sampler=smp)
    first = next(iter(runs.values())).data
    settings = {
        "motors": motors,
        "samples": len(first),
        "t_end_s": float(first.attrs["t_end_s"]),
        "dt_s": dt_s,
        "disturbance": first.attrs["disturbance"],
        "default_disturbance": default_disturbance().info,
        "loading": first.attrs["loading"],
        "noise": noise,
        "noise_on": "targets only (ded, deq, dw, id, iq), sd = noise x channel RMS",
        "seed": seed,
        "sampler": smp,
        "quick": quick,
        "smoke": smoke,
        "priors": "each coefficient N(0, 100^2); each precision Gamma(1e-3, 1e-9)",
        "t0": "from the first sample (steady state)",
        "kalman": "state = block coefficients, Q = 0, P0 = 100 I, R = LS residual variance",
    }
    return ImStudy(settings, runs, eiv_table)


def _eiv(name, *, noise, seed, t_end_s, dt_s, sampler) -> pd.DataFrame:
    from loadbayes.cases.motor_sim import simulate
    from loadbayes.fit import fit_im
    from loadbayes.fit.sampler import MODEL_DEFAULTS
    from loadbayes.models.motor_library import MOTORS

    params = MOTORS[name]
    truth = params.coefficients()
    rows = []
    for on_regressors in (False, True):
        df = simulate(
            name,
            noise=noise,
            seed=seed,
            t_end_s=t_end_s,
            dt_s=dt_s,
            noise_on_regressors=on_regressors,
        )
        for currents in ("modelled", "measured"):
            post = fit_im(_columns(df), f_hz=params.f_hz, currents=currents, warn=False,
                          sampler=MODEL_DEFAULTS.with_(seed=seed, **sampler))  # fmt: skip
            mean = post.mean()
            row = {
                "motor": name,
                "noise_on": "targets and regressors" if on_regressors else "targets only",
                "currents": currents,
            }
            for k in COEFFICIENT_NAMES:
                row[f"{k}_err_pct"] = _err(mean[k], truth[k])
            rows.append(row)
    return pd.DataFrame(rows)
