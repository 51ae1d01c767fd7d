"""ZIP fits: from arrays or DataFrames, and from files read in chunks.

One idea at about 500 lines, the ZIP fit's Python entry: the same checks and defaults for a
table in memory and a file read in chunks, with either likelihood (Gaussian or Student-t,
whose flagged samples are mapped back to the file's rows).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import Any, Literal

import numpy as np

from loadbayes.core.priors import BlockPrior
from loadbayes.core.settings import DataSpec, SamplerSettings
from loadbayes.core.stats import GramAccumulator
from loadbayes.fit.core import CHUNK_ROWS, MAX_OBSERVED, accumulate, fit_gram
from loadbayes.fit.data import bases, data_of
from loadbayes.fit.sampler import check_sampler, sampler_of
from loadbayes.inference.gibbs import Scheme
from loadbayes.io.errors import OptionError
from loadbayes.measurements.units import Wording, option
from loadbayes.posterior import Posterior

__all__ = [
    "add_derived",
    "check_bases",
    "check_likelihood",
    "check_sampler",
    "fit_zip",
    "fit_zip_file",
    "zip_priors",
]

#: Noise models of a ZIP fit.
Likelihood = Literal["normal", "student-t"]


def fit_zip(
    data: Any,
    *,
    v_col: str = "v",
    p_col: str = "p",
    q_col: str | None = "q",
    t_col: str | None = None,
    v0: float = 1.0,
    p0: float | str = "auto",
    q0: float | str = "auto",
    v_base: float | None = None,
    s_base: float | None = None,
    accept_units: bool = False,
    with_q: bool | None = None,
    units: Mapping[str, str] | None = None,
    priors: Mapping[str, BlockPrior] | None = None,
    drop_invalid: bool = False,
    scheme: Scheme = "blocked",
    likelihood: Likelihood = "normal",
    nu: float | Literal["auto"] = "auto",
    v_noise: float | Literal["auto"] | None = None,
    spec: DataSpec | None = None,
    sampler: SamplerSettings | None = None,
    warn: bool = True,
    level: Literal["fixed", "drift"] = "fixed",
    **overrides: Any,
) -> Posterior:
    """Posterior of the ZIP coefficients: the Python twin of ``loadbayes fit zip``.

    Parameters
    ----------
    data : str, path, DataFrame or mapping
        A CSV or Parquet file (read in chunks, as the CLI does), or a table in memory;
        columns other than the ones named below (a timestamp, a label) are ignored.
    v_col, p_col, q_col : str
        Column names (the CLI's ``--v-col`` ...). ``q_col=None`` fits P only; the default
        ``"q"`` is used when present, a Q column named otherwise is required.
    t_col : str, optional
        Time column (seconds, or timestamps; a DataFrame's DatetimeIndex when absent),
        increasing: its first and last values are recorded; a fixed-level fit is checked
        for a level that drifts (a warning); ``level="drift"`` needs it.
    v0, p0, q0 : float or "auto"
        Nominal values, in per unit when bases are given, else in the data's units.
        ``p0``/``q0`` default to ``"auto"`` (estimated, as the CLI does): a number is
        a claim about the load, checked against the data.
    v_base, s_base : float, optional
        Bases that turn the data into per unit (V / v_base, P / s_base, Q / s_base).
    accept_units : bool
        Fit data that do not look like per unit of the nominal point (a warning instead
        of a :class:`DataError`). Files and tables in memory get the same check
        (:func:`loadbayes.measurements.units.check_power_units`), worded with these
        keywords (``v_base=13.8``) where the CLI names its options.
    with_q : bool, optional
        ``False`` fits P only even when there is a Q column.
    units : mapping, optional
        Units of the data's columns, e.g. ``{"v": "kV", "p": "MW", "q": "Mvar"}``: kept
        with the result and written on the report's axes.
    priors : mapping, optional
        ``{"p": BlockPrior, "q": BlockPrior}`` (see :func:`zip_priors`); weak otherwise.
    drop_invalid : bool
        Drop rows with NaN, inf or non-positive voltage instead of refusing the data.
    scheme : {"blocked", "single-site", "exact"}
        Gibbs scheme (:func:`loadbayes.inference.gibbs.sample_block`); Gaussian only.
    likelihood : {"normal", "student-t"}
        Gaussian noise (the paper's), or Student-t noise that discounts bad samples
        (:func:`loadbayes.fit.robust.fit_robust`); the samples it flags are listed in
        ``settings["flagged"]`` (by channel) and ``settings["flagged_rows"]``, as 1-based
        data rows.
    nu : float or "auto"
        Student-t degrees of freedom (``auto``: sampled).
    v_noise : float or "auto", optional
        Noise on V (errors in variables, :mod:`loadbayes.fit.eiv`): the sd of the
        voltage's measurement noise in per unit of ``v0`` (from the instrument class),
        or ``"auto"`` to sample it (needs Q as well as P). A latent true voltage per
        sample removes the bias toward a flat load that noise on V gives the plain fit;
        each iteration then costs O(n). Gaussian likelihood, blocked scheme only.
    spec : DataSpec, optional
        Columns, bases, nominal point and drop policy in one object; the keywords above
        that a call changes from their defaults override its fields
        (:func:`loadbayes.fit.data.data_of`; ``p0``/``q0`` None is ``"auto"``).
    sampler : SamplerSettings, optional
        How the chains run; :data:`loadbayes.fit.core.MODEL_DEFAULTS` (40 000 draws
        including a 5 000 burn-in, the paper's M and m) by default, and
        :data:`loadbayes.fit.eiv.EIV_DEFAULTS` (4 000 and 1 000) with ``v_noise``.
    **overrides
        ``chains``, ``draws``, ``burn``, ``thin``, ``init``, ``seed``: change single
        settings of ``sampler``; ``draws`` counts iterations including burn-in.
    warn : bool
        Issue the fit's warnings as :class:`~loadbayes.posterior.FitWarning` too.
    level : {"fixed", "drift"}
        One nominal level P0 (Q0), or a level that drifts in time as a random walk
        (:func:`loadbayes.fit.drift.fit_zip_drift`; needs ``t_col``; the nominal powers
        are then the level's path, ``p0``/``q0`` unused). Without ``sampler``, 2 chains x
        2,500 iterations (500 burn-in) unless ``chains``, ``draws``, ``burn`` say otherwise.

    Returns
    -------
    Posterior
        Draws of a1, a2, a3 (a4, a5, a6), tau_p (tau_q), and p0 / q0 when ``auto``.
        :meth:`~loadbayes.posterior.Posterior.predict` takes voltages in the data's
        units and returns powers in the data's units.

    Raises
    ------
    DataError
        Bad data, in one line naming the file (``data`` for a table in memory), the
        column and the row: the CLI's messages.
    OptionError
        Bad options (a non-positive base, burn-in not below the draws ...). Both are
        :class:`~loadbayes.io.errors.LoadbayesError` (a ``ValueError``).

    Examples
    --------
    >>> import numpy as np
    >>> from loadbayes import fit_zip
    >>> rng = np.random.default_rng(1)
    >>> v = rng.uniform(0.9, 1.1, 500)
    >>> p = 0.3 * v**2 + 0.2 * v + 0.5 + rng.normal(0, 0.01, 500)
    >>> post = fit_zip({"v": v, "p": p}, draws=2000, burn=500, seed=1)
    >>> round(post.mean()["a1"] + post.mean()["a2"] + post.mean()["a3"], 12)
    1.0
    """
    from loadbayes.io.errors import DataError
    from loadbayes.measurements.frame import is_path, read_frame
    from loadbayes.models.zip import ZIPModel

    v_col, p_col, q_col, t_col, v0, p0, q0, v_base, s_base, drop_invalid, accept_units = (
        data_of(
            spec, fit_zip, v_col=v_col, p_col=p_col, q_col=q_col, t_col=t_col, v0=v0, p0=p0,
            q0=q0, v_base=v_base, s_base=s_base, drop_invalid=drop_invalid,
            accept_units=accept_units,
        )
    )  # fmt: skip
    v_noise = check_v_noise(v_noise, likelihood, scheme)
    if sampler is None and v_noise is not None:
        from loadbayes.fit.eiv import EIV_DEFAULTS

        sampler = EIV_DEFAULTS
    if v_noise is not None and level == "drift":
        raise OptionError("v_noise and level='drift' are not combined: give one of them")
    if level == "drift" and sampler is None:
        from loadbayes.fit.drift import drift_overrides

        overrides = drift_overrides(overrides)
    settings = sampler_of(sampler, overrides, check=True)
    check_bases(v_base, s_base)
    check_likelihood(likelihood, scheme)
    if with_q is False:
        q_col = None
    q_required = q_col is not None and q_col != "q"
    if is_path(data):
        post, _ = fit_zip_file(
            str(data), v_col=v_col, p_col=p_col, q_col=q_col, q_required=q_required, v0=v0,
            p0=p0, q0=q0, v_base=v_base, s_base=s_base, priors=priors,
            drop_invalid=drop_invalid, scheme=scheme, likelihood=likelihood, nu=nu,
            sampler=settings, accept_units=accept_units, v_noise=v_noise,
            t_col=t_col, level=level,
        )  # fmt: skip
        post.settings["units"] = dict(units or {})
    else:
        table = read_frame(
            data,
            [v_col, p_col] + ([q_col] if q_required and q_col else []),
            optional=[q_col] if q_col and not q_required else [],
            positive=[v_col],
            drop_invalid=drop_invalid,
            t_col=t_col,
        )
        cols = {"v": table.data[v_col] / (v_base or 1.0), "p": table.data[p_col] / (s_base or 1.0)}
        if q_col and q_col in table.data:
            cols["q"] = table.data[q_col] / (s_base or 1.0)
        nom = ("auto", "auto") if level == "drift" else (p0, q0)  # drift: the level is P0(t)
        model = ZIPModel(v0=v0, p0=nom[0], q0=nom[1], with_q="q" in cols)  # type: ignore[arg-type]
        names = {"v": v_col, "p": p_col, "q": q_col}
        # the file's unit and V-noise checks, on the whole table, worded for Python
        warnings = data_checks(
            cols, path="data", names=names, accept_units=accept_units, wording="python",
            v0=v0, p0=nom[0], q0=nom[1] if model.with_q else "auto", v_base=v_base,
            s_base=s_base, v_noise=v_noise,
        )  # fmt: skip
        if table.n_dropped:
            warnings.append(
                f"{table.n_dropped} rows with invalid values were dropped (drop_invalid=True)"
            )
        record = {
            "data": "DataFrame" if hasattr(data, "iloc") else "mapping",
            "columns": {"v": v_col, "p": p_col, "q": q_col if model.with_q else None},
            "v0": v0,
            "p0": p0,
            "q0": q0 if model.with_q else None,
            "v_base": v_base,
            "s_base": s_base,
            **bases(v_base, s_base),
            "units": dict(units or {}),
            "n_dropped": table.n_dropped,
            **table.time,
        }
        t = _frame_times(data, t_col, table.rows, level)
        if t is not None:
            from loadbayes.measurements.times import time_facts

            record.update(time_column=t_col, **time_facts(t))
        try:
            if v_noise is not None:
                post = _fit_eiv(
                    model, cols, v_noise=v_noise, priors=priors, sampler=settings,
                    settings=record, warnings=warnings,
                )  # fmt: skip
            elif level == "drift":
                from loadbayes.fit.drift import fit_zip_drift

                if likelihood != "normal":
                    raise OptionError("a drifting level has a Gaussian likelihood only")
                warnings += model.check(accumulate(model, [cols]))
                post = fit_zip_drift(
                    cols, t, v0=v0, chains=settings.chains, draws=settings.draws,
                    burn=settings.burn, thin=settings.thin, seed=settings.seed,
                    settings=record, warnings=warnings,
                )  # fmt: skip
            elif likelihood == "student-t":
                warnings += model.check(accumulate(model, [cols]))
                post = _fit_student_t(
                    model, cols, table.rows, priors=priors, nu=nu, sampler=settings,
                    settings=record, warnings=warnings,
                )  # fmt: skip
            else:
                gram = accumulate(model, [cols])
                post = fit_gram(
                    model,
                    gram,
                    priors=priors or model.default_priors(),
                    observed=cols if gram.n <= MAX_OBSERVED else None,
                    settings=record,
                    warnings=warnings,
                    scheme=scheme,
                    sampler=settings,
                )
        except DataError as exc:
            from loadbayes.measurements.columns import relocate

            names = {"v": v_col, "p": p_col, "q": q_col}
            raise relocate(exc, "data", table.rows, names) from None
        if level == "fixed":
            _said_confounded(add_derived(post, model), model, cols, t)
    if warn:
        post.warn(stacklevel=2)
    return post


def check_v_noise(v_noise: Any, likelihood: str, scheme: str) -> float | str | None:
    """The errors-in-variables option checked: None, a positive sd or "auto"."""
    from loadbayes.fit.eiv import check_v_noise as check

    value = check(v_noise)
    if value is not None and (likelihood != "normal" or scheme != "blocked"):
        raise OptionError(
            "v_noise (errors in variables) has its own Gibbs sampler with the Gaussian "
            "likelihood: leave likelihood at 'normal' and scheme at 'blocked'"
        )
    return value


def _fit_eiv(model, cols, *, v_noise, priors, sampler, settings, warnings):
    """The errors-in-variables fit of columns in memory (:mod:`loadbayes.fit.eiv`)."""
    from loadbayes.fit.eiv import fit_zip_eiv

    if v_noise == "auto" and not model.with_q:
        raise OptionError(
            "v_noise='auto' needs Q as well as P: with P alone the noise on V is not "
            "identified (give the instrument's sd, e.g. v_noise=0.005)"
        )
    warnings = list(warnings) + model.check(accumulate(model, [cols]))
    return fit_zip_eiv(
        model, cols, v_noise=v_noise, priors=priors, sampler=sampler,
        observed=cols if cols["v"].size <= MAX_OBSERVED else None,
        settings=settings, warnings=warnings,
    )  # fmt: skip


def _frame_times(data, t_col, rows, level):
    """Seconds of a table's kept rows from ``t_col`` (or a DatetimeIndex); checked."""
    import pandas as pd

    from loadbayes.measurements.times import check_increasing, parse_times

    values = None
    if t_col is not None and hasattr(data, "keys") and t_col in data.keys():
        values = np.asarray(data[t_col])
    elif isinstance(getattr(data, "index", None), pd.DatetimeIndex):
        values, t_col = np.asarray(data.index), str(data.index.name or "index")
    if values is None:
        if level == "drift":
            raise OptionError("level='drift' needs the time of each sample: give t_col")
        return None
    t = parse_times(values[rows - 1], path="data", column=t_col, rows=rows)
    check_increasing(t, rows, path="data", column=t_col)
    return t


def add_derived(post: Posterior, model: Any) -> Posterior:
    """Attach the model's derived quantities (dP/dV, dQ/dV at v0) to ``post``; returns it."""
    post.derived.update(model.derived(post.draws))
    post.derived_units.update({k: model.DERIVED_UNIT for k in post.derived})
    return post


def check_likelihood(likelihood: str, scheme: str) -> None:
    """A known likelihood, and the Student-t one with its own (the blocked) scheme."""
    if likelihood not in ("normal", "student-t"):
        raise OptionError(f"likelihood must be 'normal' or 'student-t', got {likelihood!r}")
    if likelihood == "student-t" and scheme != "blocked":
        raise OptionError(
            f"scheme {scheme!r} is a Gaussian-likelihood scheme; the Student-t sampler has "
            "its own (leave scheme at 'blocked')"
        )


def check_bases(v_base: float | None, s_base: float | None) -> None:
    """Bases must be positive and finite (``OptionError`` in one line)."""
    for name, base in (("v_base", v_base), ("s_base", s_base)):
        if base is not None and not (np.isfinite(base) and base > 0):
            raise OptionError(f"{name} must be positive, got {base}")


def zip_priors(
    *,
    p0: float | str = 1.0,
    q0: float | str = 1.0,
    mean: float = 0.0,
    sd: float = 10.0,
    per_coef: Mapping[str, tuple[float, float]] | None = None,
    shape: float = 1e-3,
    rate: float = 1e-9,
    conjugate: bool = False,
) -> dict[str, BlockPrior]:
    """Priors of the P and Q blocks from plain options (the CLI's ``--prior`` flags).

    ``per_coef`` maps a1, a2 (P) and a4, a5 (Q) to (mean, sd); the others take
    (``mean``, ``sd``). With ``auto`` nominal power the block is (P0, d1, d2) and takes
    a flat-ish prior; per-coefficient priors then need a known nominal power.
    """
    per_coef = dict(per_coef or {})
    unknown = set(per_coef) - {"a1", "a2", "a4", "a5"}
    if unknown:
        raise ValueError(
            f"priors can be set on a1, a2, a4, a5 (a3 and a6 follow from the sum); got "
            f"{', '.join(sorted(unknown))}"
        )
    out: dict[str, BlockPrior] = {}
    for ch, nom, names in (("p", p0, ("a1", "a2")), ("q", q0, ("a4", "a5"))):
        if nom == "auto":
            if any(n in per_coef for n in names):
                raise ValueError(f"a prior on {'/'.join(names)} needs a known {ch}0, not 'auto'")
            out[ch] = BlockPrior.weak(3, sd=1e4, shape=shape, rate=rate, conjugate=conjugate)
            continue
        ms = [per_coef.get(n, (mean, sd)) for n in names]
        out[ch] = BlockPrior.weak(
            2,
            mean=[m for m, _ in ms],
            sd=[s for _, s in ms],
            shape=shape,
            rate=rate,
            conjugate=conjugate,
        )
    return out


def fit_zip_file(
    path: str,
    *,
    v_col: str = "v",
    p_col: str = "p",
    q_col: str | None = "q",
    q_required: bool = False,
    v0: float = 1.0,
    p0: float | str = "auto",
    q0: float | str = "auto",
    v_base: float | None = None,
    s_base: float | None = None,
    priors: Mapping[str, BlockPrior] | None = None,
    drop_invalid: bool = False,
    chunk_rows: int = CHUNK_ROWS,
    progress: Callable[[int], None] | None = None,
    accept_units: bool = False,
    scheme: Scheme = "blocked",
    likelihood: Likelihood = "normal",
    nu: float | Literal["auto"] = "auto",
    spec: DataSpec | None = None,
    sampler: SamplerSettings | None = None,
    wording: Wording = "python",
    v_noise: float | Literal["auto"] | None = None,
    t_col: str | None = None,
    level: Literal["fixed", "drift"] = "fixed",
    **overrides: Any,
):
    """Fit ZIP to a CSV or Parquet file read in chunks (memory independent of its size).

    Parameters
    ----------
    path : str
        CSV or Parquet file (by extension), or ``"-"`` for CSV on standard input.
    v_col, p_col, q_col : str
        Column names; ``q_col=None`` fits P only. A missing Q column is an error only
        with ``q_required``; otherwise P alone is fitted.
    v0, p0, q0 : float or "auto"
        Nominal values, in per unit when bases are given, else in the data's units
        (``p0``/``q0``: estimated by default, as in the CLI and :func:`fit_zip`).
    v_base, s_base : float, optional
        Bases that turn the data into per unit (V / v_base, P / s_base, Q / s_base).
    priors : mapping, optional
        ``{"p": BlockPrior, "q": BlockPrior}`` (see :func:`zip_priors`).
    drop_invalid : bool
        Drop rows with NaN, inf or non-positive voltage instead of refusing the file.
    chunk_rows : int
        Rows read at a time.
    progress : callable, optional
        Called with the number of rows of each chunk.
    accept_units : bool
        Fit data that do not look like per unit of the nominal point (a warning instead
        of a :class:`DataError`; see :mod:`loadbayes.measurements.units`).
    scheme, likelihood, nu
        As :func:`fit_zip`. The Student-t sampler visits every sample at every
        iteration: its data are read into memory, and its unit and V-noise checks look
        at the whole file.
    spec : DataSpec, optional
        Columns, bases, nominal point and drop policy in one object; the keywords above
        that a call changes from their defaults override its fields
        (:func:`loadbayes.fit.data.data_of`; ``p0``/``q0`` None is ``"auto"``).
    sampler : SamplerSettings, optional
        How the chains run (:data:`loadbayes.fit.core.MODEL_DEFAULTS` by default).
    wording : {"python", "cli"}
        Whose names the messages give for a fix: these keywords, or the CLI's options
        (``loadbayes fit zip`` passes ``"cli"``).
    v_noise : float or "auto", optional
        Errors in variables (as :func:`fit_zip`): the file is read into memory (the
        latent voltages are visited at every iteration) and checked whole.
    t_col : str, optional
        Time column (numbers of seconds or ISO timestamps), increasing: the data are
        then read into memory, the fixed-level fit is checked for a level that drifts
        (:func:`loadbayes.fit.drift.confounding_warnings`), and ``level="drift"`` can run.
    level : {"fixed", "drift"}
        One nominal level (the paper's model), or a level that drifts in time
        (:func:`loadbayes.fit.drift.fit_zip_drift`; needs ``t_col``).
    **overrides
        ``chains``, ``draws``, ``burn``, ``thin``, ``init``, ``seed``.

    Returns
    -------
    (Posterior, ZIPModel)

    Notes
    -----
    The unit check and the check for noise on V look at the first chunk only (up to
    ``chunk_rows`` rows), before the rest of the file is read: a unit mix-up is a
    property of the whole file, and a refusal should not wait for the last row.
    """
    from loadbayes.io.errors import DataError
    from loadbayes.measurements.columns import power_chunks
    from loadbayes.models.zip import ZIPModel

    v_col, p_col, q_col, v0, p0, q0, v_base, s_base, drop_invalid, accept_units = data_of(
        spec, fit_zip_file, v_col=v_col, p_col=p_col, q_col=q_col, v0=v0, p0=p0, q0=q0,
        v_base=v_base, s_base=s_base, drop_invalid=drop_invalid, accept_units=accept_units,
    )  # fmt: skip
    v_noise = check_v_noise(v_noise, likelihood, scheme)
    settings = sampler_of(sampler, overrides)
    check_likelihood(likelihood, scheme)
    read = dict(
        v_col=v_col, p_col=p_col, q_col=q_col, q_required=q_required, v_base=v_base,
        s_base=s_base, drop_invalid=drop_invalid, chunk_rows=chunk_rows,
    )  # fmt: skip
    nominal = dict(v0=v0, p0=p0, q0=q0)
    if level not in ("fixed", "drift"):
        raise OptionError(f"level must be 'fixed' or 'drift', got {level!r}")
    if level == "drift" and t_col is None:
        raise OptionError("a drifting level needs the time of each sample: give the time column")
    if t_col is not None and v_noise is None:
        return _fit_file_timed(
            path, read=read, nominal=nominal, priors=priors, nu=nu, sampler=settings,
            progress=progress, accept_units=accept_units, t_col=t_col, level=level,
            scheme=scheme, likelihood=likelihood,
        )  # fmt: skip
    if likelihood == "student-t" or v_noise is not None:
        return _fit_file_student_t(
            path, read=read, nominal=nominal, priors=priors, nu=nu, sampler=settings,
            progress=progress, accept_units=accept_units, wording=wording, v_noise=v_noise,
        )  # fmt: skip
    state: dict[str, Any] = {"dropped": 0}
    names = {"v": v_col, "p": p_col, "q": q_col}
    keep_obs: dict[str, list[np.ndarray]] = {"v": [], "p": [], "q": []}

    def chunks():
        for part in power_chunks(path, **read):  # type: ignore[arg-type]
            state["dropped"] += part.n_dropped
            cols = part.cols
            if "model" not in state:
                state["model"] = ZIPModel(**nominal, with_q="q" in cols)  # type: ignore[arg-type]
            if "first_warnings" not in state and cols["v"].size:
                # the first chunk with rows (one whose rows were all dropped says nothing)
                state["first_warnings"] = data_checks(
                    cols, path=path, names=names, accept_units=accept_units,
                    v_base=v_base, s_base=s_base, wording=wording, whole=False, **nominal,
                )  # fmt: skip
            if sum(a.size for a in keep_obs["v"]) <= MAX_OBSERVED:
                for k, a in cols.items():
                    keep_obs[k].append(a)
            yield cols

    it = chunks()
    first = next(it, None)
    if first is None:
        raise DataError("no valid rows", path=str(path))
    model: ZIPModel = state["model"]
    acc = GramAccumulator(model.gram_columns)
    for chunk in _chain_first(first, it):
        rows = model.rows(chunk)
        acc.update(rows)
        if progress is not None:
            progress(rows.shape[0])
    gram = acc.result()
    warnings = list(state.get("first_warnings", []))
    if state["dropped"]:
        warnings.append(
            f"{state['dropped']} rows with invalid values were dropped "
            f"({option('drop-invalid', wording=wording).removesuffix('=...')})"
        )
    observed = None
    if gram.n <= MAX_OBSERVED:
        observed = {k: np.concatenate(v) for k, v in keep_obs.items() if v}
    try:
        post = fit_gram(
            model,
            gram,
            priors=priors or model.default_priors(),
            observed=observed,
            settings=_file_record(path, model, read, nominal, state["dropped"]),
            warnings=warnings,
            scheme=scheme,
            sampler=settings,
        )
    except DataError as exc:
        column = {"v": v_col, "p": p_col, "q": q_col}.get(exc.column or "", exc.column)
        raise DataError(exc.message, path=str(path), column=column, row=exc.row) from None
    return _said_confounded(add_derived(post, model), model), model


def _fit_file_timed(path, *, read, nominal, priors, nu, sampler, progress, accept_units,
                    t_col, level, scheme, likelihood):  # fmt: skip
    """A file with a time column: read whole, its time checked, then fitted.

    A fixed level is checked for confounding with the voltage; a drifting level is fitted
    by :func:`loadbayes.fit.drift.fit_zip_drift`.
    """
    from loadbayes.fit.drift import fit_zip_drift
    from loadbayes.io.errors import DataError
    from loadbayes.measurements.columns import read_power_columns, relocate
    from loadbayes.measurements.times import check_increasing, read_times, time_facts
    from loadbayes.models.zip import ZIPModel

    if level == "drift":
        # the level's path is the nominal power: nothing to check P0, Q0 against
        nominal = dict(nominal, p0="auto", q0="auto")
    pc = read_power_columns(path, progress=progress, **read)
    t = read_times(str(path), t_col, pc.rows)
    check_increasing(t, pc.rows, path=str(path), column=t_col)
    model = ZIPModel(**nominal, with_q="q" in pc.cols)
    names = {"v": read["v_col"], "p": read["p_col"], "q": read["q_col"]}
    warnings = data_checks(
        pc.cols, path=path, names=names, accept_units=accept_units,
        v_base=read["v_base"], s_base=read["s_base"], **nominal,
    )  # fmt: skip
    if pc.n_dropped:
        warnings.append(f"{pc.n_dropped} rows with invalid values were dropped (--drop-invalid)")
    record = _file_record(path, model, read, nominal, pc.n_dropped)
    record.update(time_column=t_col, **time_facts(t))
    try:
        if level == "drift":
            if likelihood != "normal":
                raise OptionError("a drifting level has a Gaussian likelihood only")
            warnings += model.check(accumulate(model, [pc.cols]))
            post = fit_zip_drift(
                pc.cols, t, v0=nominal["v0"], chains=sampler.chains, draws=sampler.draws,
                burn=sampler.burn, thin=sampler.thin, seed=sampler.seed, settings=record,
                warnings=warnings,
            )  # fmt: skip
            return post, model
        warnings += model.check(accumulate(model, [pc.cols]))
        if likelihood == "student-t":
            post = _fit_student_t(
                model, pc.cols, pc.rows, priors=priors, nu=nu, sampler=sampler,
                settings=record, warnings=warnings,
            )  # fmt: skip
        else:
            post = fit_gram(
                model, accumulate(model, [pc.cols]), priors=priors or model.default_priors(),
                observed=pc.cols if pc.rows.size <= MAX_OBSERVED else None, settings=record,
                warnings=warnings, scheme=scheme, sampler=sampler,
            )  # fmt: skip
    except DataError as exc:
        raise relocate(exc, path, pc.rows, names) from None
    return _said_confounded(add_derived(post, model), model, pc.cols, t), model


def _said_confounded(post, model, cols=None, t=None):
    """Add the confounded-level warning (dP/dV < 0, or residuals that drift with time)."""
    from loadbayes.fit.drift import confounding_warnings

    for w in confounding_warnings(post, cols or {}, t, model):
        if w not in post.warnings:
            post.warnings.append(w)
    return post


def _file_record(path, model, read, nominal, n_dropped) -> dict[str, Any]:
    """The data settings a ZIP fit of a file records (``post.settings``)."""
    return {
        "data": str(path),
        "columns": {
            "v": read["v_col"],
            "p": read["p_col"],
            "q": read["q_col"] if model.with_q else None,
        },
        "v0": nominal["v0"],
        "p0": nominal["p0"],
        "q0": nominal["q0"] if model.with_q else None,
        "v_base": read["v_base"],
        "s_base": read["s_base"],
        **bases(read["v_base"], read["s_base"]),
        "n_dropped": n_dropped,
    }


def _fit_file_student_t(
    path, *, read, nominal, priors, nu, sampler, progress, accept_units, wording, v_noise=None
):
    """The Student-t or errors-in-variables ZIP of a file: read into memory, checked whole.

    The samples the Student-t fit flags are given as file rows.
    """
    from loadbayes.io.errors import DataError
    from loadbayes.measurements.columns import read_power_columns, relocate
    from loadbayes.models.zip import ZIPModel

    pc = read_power_columns(path, progress=progress, **read)
    model = ZIPModel(**nominal, with_q="q" in pc.cols)
    names = {"v": read["v_col"], "p": read["p_col"], "q": read["q_col"]}
    warnings = data_checks(
        pc.cols, path=path, names=names, accept_units=accept_units,
        v_base=read["v_base"], s_base=read["s_base"], wording=wording, v_noise=v_noise,
        **nominal,
    )  # fmt: skip
    if pc.n_dropped:
        drop = option("drop-invalid", wording=wording).removesuffix("=...")
        warnings.append(f"{pc.n_dropped} rows with invalid values were dropped ({drop})")
    try:
        if v_noise is not None:
            post = _fit_eiv(
                model, pc.cols, v_noise=v_noise, priors=priors, sampler=sampler,
                settings=_file_record(path, model, read, nominal, pc.n_dropped),
                warnings=warnings,
            )  # fmt: skip
            return post, model
        warnings += model.check(accumulate(model, [pc.cols]))
        post = _fit_student_t(
            model, pc.cols, pc.rows, priors=priors, nu=nu, sampler=sampler,
            settings=_file_record(path, model, read, nominal, pc.n_dropped), warnings=warnings,
        )  # fmt: skip
    except DataError as exc:
        raise relocate(exc, path, pc.rows, names) from None
    return _said_confounded(add_derived(post, model), model), model


def _fit_student_t(model, cols, rows, *, priors, nu, sampler, settings, warnings):
    """:func:`fit_robust` on columns in memory; flagged samples as 1-based data rows.

    ``rows`` are the data rows of the samples (of the file, or of the table); the result
    lists the flagged ones under ``flagged`` (by channel) and ``flagged_rows``, in the
    settings and in the JSON.
    """
    from loadbayes.fit.robust import fit_robust

    post = fit_robust(
        model,
        cols,
        priors=priors,
        nu=nu,
        observed=cols if rows.size <= MAX_OBSERVED else None,
        warnings=warnings,
        settings=settings,
        sampler=sampler,
    )
    # 0-based sample indices -> 1-based data rows of the input
    by_channel = {ch: [int(rows[i]) for i in idx] for ch, idx in post.settings["flagged"].items()}
    st = post.settings
    st["flagged"] = by_channel
    st["flagged_rows"] = sorted({r for rs in by_channel.values() for r in rs})
    st["flagged_are"] = "1-based data rows of the input (header excluded)"
    post.extra_json.update(
        likelihood="student-t",
        flagged=list(st["flagged_rows"]),
        flagged_by_channel=dict(st["flagged"]),
        flag_rule=st["flag_rule"],
    )
    return post


def data_checks(
    cols,
    *,
    path,
    names,
    accept_units,
    wording="cli",
    v_noise=None,
    eiv=True,
    whole=True,
    f0=None,
    **nominal,
) -> list[str]:
    """The unit check (refuse, or warn with ``accept_units``) and the V-noise check.

    ``wording`` names the fixes as the CLI's options or as Python's keywords; with
    ``v_noise`` (the noise on V modelled) the V-noise check has nothing to say;
    ``eiv=False``: the fit has no such option (the exponential one), not offered.
    ``whole=False``: ``cols`` are the first chunk of a longer file, so a power that is 0
    there may not be 0 throughout (the model's Gram check refuses it then). ``f0``: the
    nominal frequency an ``f`` column is read against (the exponential model's ``kpf``).
    """
    from loadbayes.diagnostics import voltage_noise_warning
    from loadbayes.measurements.units import (
        check_frequency,
        check_power_units,
        nominal_level_warnings,
        refuse,
        require_power,
    )

    if whole:
        require_power(cols.get("p"), cols.get("q"), path=str(path), names=names, wording=wording)
    problems = check_power_units(
        cols["v"], cols.get("p"), cols.get("q"), wording=wording, **nominal
    )
    if f0 is not None and cols.get("f") is not None:
        problems += check_frequency(cols["f"], f0, wording=wording)
    if not accept_units:
        refuse(problems, path=str(path), names=names)
    out = [f"units: {pr}" for pr in problems]
    if not problems:  # a given P0 (Q0) inside the unit check's range but off (on the
        # first chunk of a long file: its rows are the load's too)
        out += nominal_level_warnings(
            cols["v"], cols.get("p"), cols.get("q"), wording=wording, **nominal
        )
    p = cols.get("p")
    if p is not None and p.size and float(np.median(p)) < 0:
        # Fitted as it is (a negative load: the shares are fractions of a negative P0),
        # but said: a sign convention the other way round reads as generation.
        out.append(
            f"P has median {float(np.median(p)):.4g} < 0: the bus exports power (generation, "
            "or a meter that counts the other way); the shares are fractions of the exported "
            "P0, a negative load. Give P as the power into the load if that is what is meant"
        )
    noise = voltage_noise_warning(cols["v"], wording=wording, eiv=eiv) if v_noise is None else None
    return out + ([noise] if noise else [])


def _chain_first(first, rest):
    yield first
    yield from rest
