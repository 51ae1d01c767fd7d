"""The ZIP fit's two entries: :func:`fit_zip` (a table or a file) and :func:`fit_zip_file`.

Each checks its options, reads the data once (:mod:`.read`) and hands the columns to one
variant of :data:`.variants.VARIANTS`; a file fitted with the Gaussian likelihood and no
time column is the exception, fitted from its Gram matrix chunk by chunk.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import Any, Literal

from loadbayes.core.priors import BlockPrior
from loadbayes.core.settings import DataSpec, SamplerSettings
from loadbayes.fit.core import CHUNK_ROWS, accumulate, fit_gram
from loadbayes.fit.drift import DRIFT_DEFAULTS
from loadbayes.fit.eiv import EIV_DEFAULTS
from loadbayes.fit.sampler import MODEL_DEFAULTS, new_spelling
from loadbayes.fit.zip.checks import (
    Likelihood,
    add_derived,
    check_likelihood,
    check_v_noise,
    said_confounded,
)
from loadbayes.fit.zip.read import (
    ZipData,
    file_gram,
    file_record,
    nominal_of,
    read_file,
    read_table,
)
from loadbayes.fit.zip.variants import run, variant_of
from loadbayes.inference.gibbs import Scheme
from loadbayes.io.errors import DataError, OptionError
from loadbayes.measurements.columns import relocate
from loadbayes.measurements.frame import is_path
from loadbayes.measurements.wording import Wording
from loadbayes.models.zip import ZIPModel
from loadbayes.posterior import Posterior

__all__ = ["fit_zip", "fit_zip_file"]

#: The data keywords the entries took before :class:`DataSpec` (refused, with the fix).
_DATA_KEYWORDS = (
    "v_col", "p_col", "q_col", "t_col", "v0", "p0", "q0", "v_base", "s_base",
    "drop_invalid", "accept_units", "q_required",
)  # fmt: skip


def _check_level(level: str) -> None:
    if level not in ("fixed", "drift"):
        raise OptionError(f"level must be 'fixed' or 'drift', got {level!r}")


def _fitted(name: str, data: ZipData, *, source: str, **options) -> Posterior:
    """Variant ``name`` on ``data``, a sampler's DataError re-located to the input."""
    try:
        return run(name, data.model, data.cols, data.rows, data.t, source=source,
                   record=data.record, warnings=data.warnings, **options)  # fmt: skip
    except DataError as exc:
        raise relocate(exc, data.where, data.rows, data.names) from None


@new_spelling(data=_DATA_KEYWORDS)
def fit_zip(
    data: Any,
    *,
    spec: DataSpec | None = None,
    sampler: SamplerSettings | None = None,
    with_q: bool | None = None,
    units: Mapping[str, str] | None = None,
    priors: Mapping[str, BlockPrior] | None = None,
    scheme: Scheme = "blocked",
    likelihood: Likelihood = "normal",
    nu: float | Literal["auto"] = "auto",
    v_noise: float | Literal["auto"] | None = None,
    level: Literal["fixed", "drift"] = "fixed",
    warn: bool = True,
) -> Posterior:
    """Posterior of the ZIP coefficients: the Python twin of ``loadbayes fit zip``.

    Parameters
    ----------
    data : str, path, DataFrame or mapping
        A CSV or Parquet file (read in chunks, as the CLI does), or a table in memory;
        columns other than the ones named by ``spec`` (a label) are ignored.
    spec : DataSpec, optional
        Where the data are (:class:`~loadbayes.core.settings.DataSpec`): ``v_col``,
        ``p_col``, ``q_col`` (``None`` fits P only; the default ``"q"`` is used when
        present, a Q column named otherwise is required); ``t_col`` (seconds or
        timestamps, a DataFrame's DatetimeIndex when absent; increasing: recorded, a
        fixed level is checked for drift, ``level="drift"`` needs it); ``v0``, ``p0``,
        ``q0`` (per unit when bases are given, else the data's units; ``p0``/``q0``
        None: estimated, as the CLI does, a number is a claim about the load, checked
        against the data); ``v_base``, ``s_base`` (data / base = per unit);
        ``drop_invalid`` (drop rows with NaN, inf or non-positive voltage instead of
        refusing the data); ``accept_units`` (fit data that do not look per unit of the
        nominal point: a warning instead of a :class:`DataError`, the check of files and
        tables alike, worded with these names, :mod:`loadbayes.measurements.units`).
    sampler : SamplerSettings, optional
        How the chains run; :data:`loadbayes.fit.sampler.MODEL_DEFAULTS` (40 000 draws
        including a 5 000 burn-in, the paper's M and m) by default,
        :data:`loadbayes.fit.eiv.EIV_DEFAULTS` (4 000 and 1 000) with ``v_noise`` and
        :data:`loadbayes.fit.drift.DRIFT_DEFAULTS` (2 chains x 2 500, 500) with
        ``level="drift"``.
    with_q : bool, optional
        ``False`` fits P only even when there is a Q column.
    units : mapping, optional
        Units of the data's columns, e.g. ``{"v": "kV", "p": "MW", "q": "Mvar"}``: kept
        with the result and written on the report's axes.
    priors : mapping, optional
        ``{"p": BlockPrior, "q": BlockPrior}`` (see :func:`zip_priors`); weak otherwise.
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
    level : {"fixed", "drift"}
        One nominal level P0 (Q0), or a level that drifts in time as a random walk
        (:func:`loadbayes.fit.drift.fit_zip_drift`; needs ``t_col``; the nominal powers
        are then the level's path, ``p0``/``q0`` unused).
    warn : bool
        Issue the fit's warnings as :class:`~loadbayes.posterior.FitWarning` too.

    Returns
    -------
    Posterior
        Draws of a1, a2, a3 (a4, a5, a6), tau_p (tau_q), and p0 / q0 when estimated.
        :meth:`~loadbayes.posterior.Posterior.predict` takes voltages in the data's
        units and returns powers in the data's units.

    Raises
    ------
    DataError
        Bad data, in one line naming the file (``data`` for a table in memory), the
        column and the row: the CLI's messages.
    OptionError
        Bad options. Both are :class:`~loadbayes.io.errors.LoadbayesError` (a
        ``ValueError``); a bad ``DataSpec`` or ``SamplerSettings`` is refused when built.
    TypeError
        A keyword this function no longer takes (``draws=``, ``v_col=``), in one line
        that gives the new spelling.

    Examples
    --------
    >>> import numpy as np
    >>> from loadbayes import SamplerSettings, fit_zip
    >>> rng = np.random.default_rng(1)
    >>> v = rng.uniform(0.9, 1.1, 500)
    >>> p = 0.3 * v**2 + 0.2 * v + 0.5 + rng.normal(0, 0.01, 500)
    >>> post = fit_zip({"v": v, "p": p}, sampler=SamplerSettings(draws=2000, burn=500, seed=1))
    >>> round(post.mean()["a1"] + post.mean()["a2"] + post.mean()["a3"], 12)
    1.0
    """
    spec = spec if spec is not None else DataSpec()
    v_noise = check_v_noise(v_noise, likelihood, scheme)
    if v_noise == "auto" and level == "drift":
        raise OptionError("level='drift' takes the instrument's sd as v_noise (0.0005), not 'auto'")
    if sampler is None:
        sampler = (
            DRIFT_DEFAULTS if level == "drift"
            else EIV_DEFAULTS if v_noise is not None else MODEL_DEFAULTS
        )  # fmt: skip
    check_likelihood(likelihood, scheme)
    _check_level(level)
    if with_q is False:
        spec = spec.with_(q_col=None)
    if is_path(data):
        post, _ = fit_zip_file(
            str(data), spec=spec, priors=priors, scheme=scheme, likelihood=likelihood,
            nu=nu, sampler=sampler, v_noise=v_noise, level=level,
        )  # fmt: skip
        post.settings["units"] = dict(units or {})
    else:
        table = read_table(data, spec, drift=level == "drift", v_noise=v_noise,
                           units=dict(units or {}))  # fmt: skip
        post = _fitted(
            variant_of(likelihood, level, v_noise), table, source="table", priors=priors,
            nu=nu, v_noise=v_noise, scheme=scheme, sampler=sampler, likelihood=likelihood,
        )  # fmt: skip
    if warn:
        post.warn(stacklevel=3)  # past new_spelling's wrapper: the caller's line
    return post


@new_spelling(data=_DATA_KEYWORDS)
def fit_zip_file(
    path: str,
    *,
    spec: DataSpec | None = None,
    sampler: SamplerSettings | None = None,
    priors: Mapping[str, BlockPrior] | None = None,
    chunk_rows: int = CHUNK_ROWS,
    progress: Callable[[int], None] | None = None,
    scheme: Scheme = "blocked",
    likelihood: Likelihood = "normal",
    nu: float | Literal["auto"] = "auto",
    wording: Wording = "python",
    v_noise: float | Literal["auto"] | None = None,
    level: Literal["fixed", "drift"] = "fixed",
) -> tuple[Posterior, ZIPModel]:
    """Fit ZIP to a CSV or Parquet file read in chunks (memory independent of its size).

    Parameters
    ----------
    path : str
        CSV or Parquet file (by extension), or ``"-"`` for CSV on standard input.
    spec : DataSpec, optional
        Columns, bases, nominal point, time column, drop and unit policy, as
        :func:`fit_zip`. A Q column named other than ``q`` is required; ``q_col=None``
        fits P only. With ``t_col`` the file is read into memory, the fixed-level fit
        is checked for a level that drifts
        (:func:`loadbayes.fit.drift.confounding_warnings`), and ``level="drift"`` can
        run.
    sampler : SamplerSettings, optional
        How the chains run (:data:`loadbayes.fit.sampler.MODEL_DEFAULTS` by default).
    priors : mapping, optional
        ``{"p": BlockPrior, "q": BlockPrior}`` (see :func:`zip_priors`).
    chunk_rows : int
        Rows read at a time.
    progress : callable, optional
        Called with the number of rows of each chunk.
    scheme, likelihood, nu, v_noise, level
        As :func:`fit_zip`. The Student-t sampler and errors in variables visit every
        sample at every iteration: their data are read into memory, and the unit and
        V-noise checks look at the whole file.
    wording : {"python", "cli"}
        Whose names the messages give for a fix: the Python names, or the CLI's options
        (``loadbayes fit zip`` passes ``"cli"``).

    Returns
    -------
    (Posterior, ZIPModel)

    Notes
    -----
    The unit check and the check for noise on V look at the first chunk only (up to
    ``chunk_rows`` rows), before the rest of the file is read: a unit mix-up is a
    property of the whole file, and a refusal should not wait for the last row.
    """
    spec = spec if spec is not None else DataSpec()
    v_noise = check_v_noise(v_noise, likelihood, scheme)
    sampler = sampler if sampler is not None else MODEL_DEFAULTS
    check_likelihood(likelihood, scheme)
    _check_level(level)
    if level == "drift" and spec.t_col is None:
        raise OptionError("a drifting level needs the time of each sample: give the time column")
    nominal = nominal_of(spec)
    options = dict(priors=priors, nu=nu, v_noise=v_noise, scheme=scheme, sampler=sampler,
                   likelihood=likelihood)  # fmt: skip
    read = dict(chunk_rows=chunk_rows, progress=progress)
    name = variant_of(likelihood, level, v_noise)
    if level == "drift" and v_noise == "auto":
        raise OptionError("level='drift' takes the instrument's sd as v_noise (0.0005), not 'auto'")
    if spec.t_col is not None and (v_noise is None or level == "drift"):
        if level == "drift":
            # the level's path is the nominal power: nothing to check P0, Q0 against
            nominal = dict(nominal, p0="auto", q0="auto")
        data = read_file(path, spec, nominal=nominal, t_col=spec.t_col, wording="cli", **read)
        if name == "normal":
            # this path has always checked the Gram matrix before the sampler (which checks
            # it again): kept, so that its warnings stay as they were
            try:
                data.warnings += data.model.check(accumulate(data.model, [data.cols]))
            except DataError as exc:
                raise relocate(exc, data.where, data.rows, data.names) from None
        return _fitted(name, data, source="file", **options), data.model
    if name in ("student-t", "eiv"):
        data = read_file(path, spec, nominal=nominal, t_col=None, wording=wording,
                         v_noise=v_noise, **read)  # fmt: skip
        return _fitted(name, data, source="file", **options), data.model
    model, gram, warnings, observed, dropped = file_gram(
        path, spec, nominal=nominal, wording=wording, **read
    )
    try:
        post = fit_gram(
            model,
            gram,
            priors=priors or model.default_priors(),
            observed=observed,
            settings=file_record(path, model, spec, nominal, dropped),
            warnings=warnings,
            scheme=scheme,
            sampler=sampler,
        )
    except DataError as exc:
        column = {"v": spec.v_col, "p": spec.p_col, "q": spec.q_col}.get(
            exc.column or "", exc.column
        )
        raise DataError(exc.message, path=str(path), column=column, row=exc.row) from None
    return said_confounded(add_derived(post, model), model), model
