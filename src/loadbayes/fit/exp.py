"""Exponential-load fits: the log-linear Gibbs form and Metropolis within Gibbs."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from loadbayes.core.settings import DataSpec, SamplerSettings
from loadbayes.fit.core import MAX_OBSERVED, fit
from loadbayes.fit.data import bases
from loadbayes.fit.sampler import MODEL_DEFAULTS, new_spelling
from loadbayes.fit.zip import data_checks
from loadbayes.io.errors import DataError, OptionError
from loadbayes.measurements.columns import read_power_columns, relocate
from loadbayes.measurements.frame import is_path, read_frame
from loadbayes.models.exponential import ExponentialModel, Noise, Nominal

__all__ = ["EXP_SPEC", "exp_confounding", "fit_exp"]

#: The data of an exponential fit when no ``spec`` is given: :class:`DataSpec`'s
#: defaults, and a frequency column ``f`` read when present.
EXP_SPEC = DataSpec(f_col="f")

#: The keywords the fit took before :class:`DataSpec` (refused, with the fix).
DATA_KEYWORDS = ("v_col", "p_col", "q_col", "f_col", "t_col", "v0", "p0", "q0", "v_base",
                 "s_base", "drop_invalid", "accept_units")  # fmt: skip


@new_spelling(data=DATA_KEYWORDS)
def fit_exp(
    data: Any,
    *,
    spec: DataSpec | None = None,
    sampler: SamplerSettings | None = None,
    with_q: bool | None = None,
    with_f: bool | None = None,
    f0: float = 60.0,
    noise: Noise = "additive",
    units: Mapping[str, str] | None = None,
    priors: Mapping[str, Any] | None = None,
    settings: Mapping[str, Any] | None = None,
    warnings: list[str] | None = None,
    warn: bool = True,
    unit_check: bool = True,
    times: np.ndarray | None = None,
):
    """Posterior of the exponential load model: the Python twin of ``loadbayes fit exp``.

    Parameters
    ----------
    data : str, path, DataFrame or mapping
        A CSV or Parquet file, or a table in memory; other columns are ignored.
    spec : DataSpec, optional
        Where the data are (:data:`EXP_SPEC` when not given): ``v_col``, ``p_col``,
        ``q_col``, ``f_col`` (Q and f are used when present under the names ``q`` and
        ``f``; named otherwise they are required; ``None`` leaves them out: a spec of
        your own reads f only if it names ``f_col``); ``t_col`` (a timestamp column, or
        a DataFrame's DatetimeIndex: recorded, not fitted); ``v0``, ``p0``, ``q0``
        (``p0``/``q0`` None, as in the CLI, estimates P0 / Q0; per unit when bases are
        given); ``v_base``, ``s_base``; ``drop_invalid``; ``accept_units`` (the unit
        check of ``fit_zip``, on files and tables alike).
    with_q, with_f : bool, optional
        ``False`` leaves Q / the frequency coefficients out even when the column is there.
    f0 : float
        Nominal frequency (``df = (f - f0) / f0``).
    noise : {"additive", "multiplicative"}
        Noise model and sampler (module notes).
    units : mapping, optional
        Units of the data's columns (``{"v": "kV", "p": "MW"}``), for reports.
    priors : mapping, optional
        Per channel: :class:`ExpPriors` (additive) or :class:`BlockPrior` of the
        log-linear block (multiplicative); weak defaults otherwise.
    sampler : SamplerSettings, optional
        How the chains run (:data:`loadbayes.fit.core.MODEL_DEFAULTS` by default).
    settings, warnings
        Recorded with the result.
    warn : bool
        Issue the fit's warnings as :class:`~loadbayes.posterior.FitWarning` too.
    unit_check : bool
        ``False`` skips the unit and V-noise checks: for a caller that has run them on
        the raw file already (``loadbayes fit exp`` does, to word them with its options).
    times : ndarray, optional
        Seconds of each row kept (``loadbayes fit exp --t-col`` reads them); otherwise
        ``spec.t_col`` is read when given. With them the confounding check also asks
        whether the residuals drift in time (:func:`exp_confounding`).

    Returns
    -------
    Posterior
        Draws of np (nq), kpf (kqf) with frequency, p0 (q0) with auto, tau_p (tau_q).

    Raises
    ------
    DataError, OptionError
        Bad data (file or ``data``, column, row) or options, in one line.

    Examples
    --------
    >>> import numpy as np
    >>> rng = np.random.default_rng(0)
    >>> v = rng.uniform(0.85, 1.05, 400)
    >>> p = v**1.5 + rng.normal(0, 0.01, 400)
    >>> post = fit_exp({"v": v, "p": p}, sampler=SamplerSettings(draws=2000, burn=500, chains=2))
    >>> round(post.mean()["np"], 1)
    1.5
    """
    spec = spec if spec is not None else EXP_SPEC
    v_col, p_col, q_col, f_col, t_col = spec.v_col, spec.p_col, spec.q_col, spec.f_col, spec.t_col
    v0, v_base, s_base = spec.v0, spec.v_base, spec.s_base
    p0: Nominal = "auto" if spec.p0 is None else spec.p0
    q0: Nominal = "auto" if spec.q0 is None else spec.q0
    drop_invalid, accept_units = spec.drop_invalid, spec.accept_units
    smp = sampler if sampler is not None else MODEL_DEFAULTS
    if with_q is False:
        q_col = None
    if with_f is False:
        f_col = None
    q_req = q_col is not None and q_col != "q"
    f_req = (f_col is not None and f_col != "f") or bool(with_f)
    if with_f and f_col is None:
        raise DataError("frequency dependence needs a column 'f'")
    required = [v_col, p_col] + ([q_col] if q_req else []) + ([f_col] if f_req else [])
    optional = ([q_col] if q_col and not q_req else []) + ([f_col] if f_col and not f_req else [])
    warn_list = list(warnings or [])
    base = dict(settings or {})
    if is_path(data):
        pc = read_power_columns(
            str(data), v_col=v_col, p_col=p_col, q_col=q_col, q_required=q_req,
            f_col=f_col if f_req else None, extra=(f_col,) if f_col and not f_req else (),
            v_base=v_base, s_base=s_base, drop_invalid=drop_invalid,
        )  # fmt: skip
        cols, rows, dropped = dict(pc.cols), pc.rows, pc.n_dropped
        if f_col and f_col in pc.extra:
            cols["f"] = pc.extra[f_col]
        base.setdefault("data", str(data))
    else:
        table = read_frame(data, required, optional=optional, positive=[v_col],
                           drop_invalid=drop_invalid, t_col=t_col)  # fmt: skip
        d, rows, dropped = table.data, table.rows, table.n_dropped
        cols = {"v": d[v_col] / (v_base or 1.0), "p": d[p_col] / (s_base or 1.0)}
        if q_col and q_col in d:
            cols["q"] = d[q_col] / (s_base or 1.0)
        if f_col and f_col in d:
            cols["f"] = d[f_col]
        base.update(table.time)
        base.setdefault("data", "DataFrame" if hasattr(data, "iloc") else "mapping")
    # The exponential model is near the ZIP one at V0 (P = P0 at V = V0): the same check.
    names = {"v": v_col, "p": p_col, "q": q_col, "f": f_col}
    where = str(data) if is_path(data) else "data"
    if unit_check:
        warn_list += data_checks(
            cols, path=where, names=names, accept_units=accept_units, eiv=False, wording="python",
            v0=v0, p0=p0, q0=q0 if "q" in cols else "auto", v_base=v_base, s_base=s_base,
            f0=f0,
        )  # fmt: skip
    if dropped and not warnings:
        warn_list.append(f"{dropped} rows with invalid values were dropped (drop_invalid=True)")
    base.setdefault("columns", {"v": v_col, "p": p_col, "q": q_col, "f": f_col})
    base.setdefault("v_base", v_base)
    base.setdefault("s_base", s_base)
    for key, val in bases(base["v_base"], base["s_base"], f0 if "f" in cols else None).items():
        base.setdefault(key, val)
    base["units"] = dict(units or base.get("units") or {})
    base.setdefault("n_dropped", dropped)
    with_q = "q" in cols
    with_f = "f" in cols
    try:
        post = _fit_exp_columns(
            cols, v0=v0, p0=p0, q0=q0, with_q=with_q, with_f=with_f, f0=f0, noise=noise,
            priors=priors, sampler=smp, settings=base, warnings=warn_list,
        )  # fmt: skip
    except DataError as exc:
        raise relocate(exc, where, rows, names) from None
    if times is None and t_col is not None:
        times = _times(data, t_col, rows)
    for w in exp_confounding(post, cols, times):
        if w not in post.warnings:
            post.warnings.append(w)
    if warn:
        post.warn(stacklevel=3)  # past new_spelling's wrapper: the caller's line
    return post


def _times(data: Any, t_col: str, rows: np.ndarray) -> np.ndarray | None:
    """Seconds of the rows kept from a file's or a table's time column (None if absent)."""
    from loadbayes.measurements.times import parse_times, read_times

    if is_path(data):
        return read_times(str(data), t_col, rows)
    if hasattr(data, "keys") and t_col in data.keys():
        return parse_times(np.asarray(data[t_col])[rows - 1], path="data", column=t_col,
                           rows=rows)  # fmt: skip
    return None


def exp_confounding(post: Any, cols: Mapping[str, np.ndarray], t: np.ndarray | None) -> list:
    """``fit zip``'s confounding check for the exponential load (one level P0, Q0).

    The same two reasons, in the same words (:data:`loadbayes.fit.drift.CONFOUNDED`): an
    exponent ``np`` below zero (dP/dV at V0 per unit of P0 is ``np``), and, given the
    time of each row, residuals that drift with time
    (:func:`loadbayes.fit.drift.residual_drift`, 0.1% false alarm on a well-fitted record).
    """
    from loadbayes.fit.drift import CONFOUNDED, drift_reason

    reasons = []
    d = post.draws.get("np")
    if d is not None and float(np.mean(d)) < 0:
        reasons.append(f"dP/dV at v0 is negative (np = {float(np.mean(d)):.3g}): no load "
                       "draws less power at a higher voltage")  # fmt: skip
    p0 = post.settings.get("p0")
    if t is not None and d is not None and cols["p"].size >= 20:
        scale = float(np.mean(post.draws["p0"])) if p0 == "auto" else float(p0)
        x = np.asarray(cols["v"], dtype=float) / float(post.settings.get("v0", 1.0))
        resid = np.asarray(cols["p"], dtype=float) - scale * x ** float(np.mean(d))
        if "f" in cols and "kpf" in post.draws:
            f0 = float(post.settings.get("f0") or 60.0)
            df = (np.asarray(cols["f"], dtype=float) - f0) / f0
            resid = np.asarray(cols["p"], dtype=float) - scale * x ** float(np.mean(d)) * (
                1 + float(np.mean(post.draws["kpf"])) * df
            )
        reasons += drift_reason(post, t, resid)
    if not reasons:
        return []
    hint = "" if t is not None else " (the time column: --t-col)"
    text = CONFOUNDED.replace("use --level drift or fit the voltage steps",
                              "fit the voltage steps (loadbayes steps)")  # fmt: skip
    return [f"{text}{hint} ({'; '.join(reasons)})."]


def _fit_exp_columns(
    cols: dict[str, np.ndarray],
    *,
    v0: float,
    p0: Nominal,
    q0: Nominal,
    with_q: bool,
    with_f: bool,
    f0: float,
    noise: Noise,
    priors: Mapping[str, Any] | None,
    sampler: SamplerSettings,
    settings: Mapping[str, Any],
    warnings: list[str],
):
    """The fit itself, on checked columns in per unit."""
    try:
        model = ExponentialModel(
            v0=v0, p0=p0, q0=q0, with_q=with_q, with_f=with_f, f0=f0, noise=noise
        )
    except ValueError as exc:
        raise OptionError(str(exc)) from None
    v = cols["v"]
    if v.size and not np.all(v > 0):
        i = int(np.flatnonzero(~(v > 0))[0])
        raise DataError(f"voltage must be positive, got {v[i]:g}", column="v", row=i + 1)
    keep = ["v", "p"] + (["q"] if with_q else []) + (["f"] if with_f else [])
    observed = {k: cols[k] for k in keep} if v.size <= MAX_OBSERVED else None
    base = dict(settings or {})
    base.update(v0=v0, p0=p0, q0=q0 if with_q else None, f0=f0 if with_f else None, noise=noise)
    warn = list(warnings or [])
    if noise == "additive" and (span := float(np.ptp(v) / v0)) < 0.02:
        warn.append(
            f"voltage spans only {100 * span:.2g}% of v0: the exponent is poorly determined "
            "on so narrow a band."
        )
    # One driver for both forms: the model's pieces (log-linear blocks or power-law
    # blocks) pick the sampler.
    post = fit(
        model,
        cols,
        priors=priors,
        sampler=sampler,
        observed=observed,
        settings=base,
        warnings=warn,
    )
    if noise == "multiplicative":
        post.settings["scheme"] = "blocked (log-linear)"
    return post
