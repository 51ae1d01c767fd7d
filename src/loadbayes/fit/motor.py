"""Induction-motor fits from the motor's states (the paper's IM study).

Its length is one idea: the motor fit, through its entries (arrays with :func:`fit_im`,
files read in chunks with :func:`fit_im_file`, both down to one Gram matrix), which
share the priors and the checks, such as that a record starts in a steady state.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Mapping
from typing import Any

import numpy as np

from loadbayes.core.priors import BlockPrior
from loadbayes.core.settings import DataSpec, SamplerSettings
from loadbayes.core.stats import Gram, GramAccumulator
from loadbayes.fit.core import (
    CHUNK_ROWS,
    MAX_OBSERVED,
    accumulate,
    prior_settings,
)
from loadbayes.fit.data import bases
from loadbayes.fit.sampler import MODEL_DEFAULTS, new_spelling
from loadbayes.inference import bilinear
from loadbayes.inference.gibbs import Scheme
from loadbayes.inference.linear import sample_blocks
from loadbayes.io.errors import DataError, OptionError
from loadbayes.io.tables import iter_chunks
from loadbayes.measurements.columns import relocate
from loadbayes.measurements.frame import is_path, read_frame
from loadbayes.measurements.units import check_motor_units
from loadbayes.measurements.wording import Wording, refuse
from loadbayes.models.motor import COEFFICIENT_NAMES
from loadbayes.models.motor_fit import DATA_COLUMNS, InductionMotorModel
from loadbayes.posterior import Posterior

__all__ = ["fit_im", "fit_im_file", "im_priors"]


def im_priors(
    *,
    mean: float = 0.0,
    sd: float = 100.0,
    per_coef: Mapping[str, tuple[float, float]] | None = None,
    shape: float = 1e-3,
    rate: float = 1e-9,
    conjugate: bool = False,
) -> dict[str, BlockPrior]:
    """Priors of the motor's flux, speed and current blocks from plain options.

    ``per_coef`` maps any of b1, b2, b3, ab, ac to (mean, sd); the others take
    (``mean``, ``sd``). Each block's precision gets ``Gamma(shape, rate)``.
    """
    per_coef = dict(per_coef or {})
    unknown = set(per_coef) - set(COEFFICIENT_NAMES)
    if unknown:
        raise ValueError(
            f"priors can be set on {', '.join(COEFFICIENT_NAMES)}; got {', '.join(sorted(unknown))}"
        )
    out = {}
    for block, names in (("flux", ("b1", "b2")), ("speed", ("b3",)), ("current", ("ab", "ac"))):
        ms = [per_coef.get(n, (mean, sd)) for n in names]
        out[block] = BlockPrior.weak(
            len(names),
            mean=[m for m, _ in ms],
            sd=[s for _, s in ms],
            shape=shape,
            rate=rate,
            conjugate=conjugate,
        )
    return out


def _fit_im_gram(
    model,
    gram: Gram,
    first: Mapping[str, float],
    *,
    t0: float | None = None,
    priors: Mapping[str, BlockPrior] | None = None,
    scheme: Scheme = "blocked",
    sampler: SamplerSettings,
    observed: Mapping[str, np.ndarray] | None = None,
    settings: Mapping[str, Any] | None = None,
    warnings: Iterable[str] = (),
):
    """Sample the motor from its Gram matrix (either form); return (Posterior, model)."""
    if not np.all(np.isfinite(gram.matrix)):
        raise DataError("the data hold NaN or infinite values (or values too large to square)")
    priors = dict(priors or model.default_priors())
    for block, k in (("flux", 2), ("speed", 1), ("current", 2)):
        if block not in priors or priors[block].k != k:
            raise ValueError(f"priors need a '{block}' block with {k} coefficient(s)")
    if t0 is not None:
        model = model.with_t0(t0)
    warn = list(warnings) + model.check(gram)
    full = dict(settings or {})
    # The motor's states are per unit of its own base: no kV or MVA to record.
    full.update(bases(None, None, model.f_hz))
    full.update(
        n=gram.n,
        currents=model.currents,
        f_hz=model.f_hz,
        wb=model.wb,
        t0_source="given" if t0 is not None else "first sample",
        scheme=scheme,
        chains=sampler.chains,
        draws=sampler.draws,
        burn=sampler.burn,
        thin=sampler.thin,
        init=sampler.init,
        seed=sampler.seed,
        priors=prior_settings(priors),
    )
    if model.currents == "measured":
        if model.t0 is None:
            model = model.with_t0(model.resolve_t0(gram, first))
        raw = sample_blocks(
            model.complete(gram), model.blocks, priors, scheme=scheme, settings=sampler
        )
        full["t0"] = model.t0
    else:
        if scheme == "exact":
            raise ValueError(
                "scheme 'exact' needs the measured-currents form (currents='measured') and a "
                "conjugate prior; the coupled form has no closed-form posterior"
            )
        if model.t0 is None:
            model.resolve_t0(gram, first)  # refuses a first row that is not motoring
        stats = model.bilinear_stats(gram, first)
        v_ls, v_cov, _ = model.current_estimate(gram)
        # Through the module: the SBC test plants a wrong sign in bilinear.sample_bilinear.
        raw = bilinear.sample_bilinear(
            stats,
            [priors["flux"], priors["speed"]],
            priors["current"],
            tau_shape=[priors[b].shape for b in ("flux", "speed", "current")],
            tau_rate=[priors[b].rate for b in ("flux", "speed", "current")],
            scheme=scheme,  # type: ignore[arg-type]
            v_start=(v_ls, v_cov),
            settings=sampler,
        )
        if model.t0 is None:
            k1, k2 = stats.t0_k  # type: ignore[misc]
            t0_draws = raw["ab"] * k1 + raw["ac"] * k2
            full["t0"] = float(np.mean(t0_draws))
            full["t0_sd"] = float(np.std(t0_draws))
            model = model.with_t0(full["t0"])
        else:
            full["t0"] = model.t0
    post = Posterior(
        model.transform(raw),
        model=model.name,
        method=f"gibbs-{scheme}" if scheme != "exact" else "exact",
        coefficients=model.coefficients,
        free=model.free,
        observed=observed,
        constant={"gram": gram.matrix},
        settings=full,
        warnings=warn,
    )
    n_nan = int(np.isnan(post.draws["xm"]).sum())
    if n_nan:
        post.warnings.append(
            f"{n_nan} draws have X (X - X') < 0: the closure Xs = Xr has no real solution "
            "there and xs, xm, xr, rr are NaN for them."
        )
    return post, model


@new_spelling(data=("drop_invalid", "accept_units"))
def fit_im(
    data: Any,
    *,
    t0: float | None = None,
    f_hz: float = 60.0,
    currents: str = "modelled",
    priors: Mapping[str, BlockPrior] | None = None,
    scheme: Scheme = "blocked",
    spec: DataSpec | None = None,
    sampler: SamplerSettings | None = None,
    warn: bool = True,
) -> Posterior:
    """Posterior of the induction-motor coefficients: the Python twin of ``loadbayes fit im``.

    Parameters
    ----------
    data : str, path, DataFrame or mapping
        A CSV or Parquet file, or a table in memory, with columns ``ud, uq, ed, eq, w,
        id, iq, ded, deq, dw`` (per unit; derivatives per second), e.g. from
        :func:`loadbayes.cases.motor_sim.simulate`; other columns are ignored.
    t0 : float, optional
        Load-torque coefficient T0; by default from the first sample, taken as a steady
        state (:class:`loadbayes.models.motor_fit.InductionMotorModel`).
    f_hz : float
        Nominal frequency (the slip terms carry ``wb = 2 pi f_hz``).
    currents : {"modelled", "measured"}
        ``modelled`` (default): the coupled form, whose flux and speed regressors use the
        model's currents, so noisy measured currents are only targets. ``measured``: the
        paper's three independent blocks with the measured currents as regressors
        (biased by errors in variables when the currents are noisy).
    priors : mapping, optional
        ``{"flux": BlockPrior(2), "speed": BlockPrior(1), "current": BlockPrior(2)}``;
        weak defaults otherwise (:func:`im_priors`).
    scheme : {"blocked", "single-site", "exact"}
        Gibbs scheme.
    spec : DataSpec, optional
        Its ``drop_invalid`` (drop rows with NaN or inf instead of refusing the data)
        and ``accept_units`` (fit states that do not look like per unit: a warning
        instead of a :class:`DataError`, the CLI's check on files and tables alike); the
        motor's columns are fixed.
    sampler : SamplerSettings, optional
        How the chains run (:data:`loadbayes.fit.sampler.MODEL_DEFAULTS` by default;
        ``draws`` counts iterations including burn-in, the paper's M).
    warn : bool
        Issue the fit's warnings as :class:`~loadbayes.posterior.FitWarning` too.

    Returns
    -------
    Posterior
        Draws of b1, b2, b3, ab, ac, tau_e, tau_w, tau_i and the physical rs, xp, x,
        tp_s, h_s, xs, xm, xr, rr (Xs = Xr closure).

    Raises
    ------
    DataError, OptionError
        Bad data (file or ``data``, column, row) or options, in one line, as the CLI.

    Examples
    --------
    >>> from loadbayes.cases.motor_sim import simulate
    >>> df = simulate("small_industrial", noise=0.05, seed=1)  # doctest: +SKIP
    >>> post = fit_im(df, sampler=SamplerSettings(draws=4000, burn=1000))  # doctest: +SKIP
    >>> round(post.mean()["b3"], 2)  # doctest: +SKIP
    -0.71
    """
    spec = spec if spec is not None else DataSpec()
    smp = sampler if sampler is not None else MODEL_DEFAULTS
    if is_path(data):
        post, _ = fit_im_file(str(data), t0=t0, f_hz=f_hz, currents=currents, priors=priors,
                              spec=spec, scheme=scheme, sampler=smp)  # fmt: skip
        if warn:
            post.warn(stacklevel=3)  # past new_spelling's wrapper: the caller's line
        return post
    table = read_frame(data, list(DATA_COLUMNS[1:]), optional=[DATA_COLUMNS[0]],
                       drop_invalid=spec.drop_invalid)  # fmt: skip
    cols = table.data
    try:
        model = InductionMotorModel(f_hz=f_hz, currents=currents)  # type: ignore[arg-type]
    except ValueError as exc:
        raise OptionError(str(exc)) from None
    problems = check_motor_units(cols, wording="python")
    if not spec.accept_units:
        refuse(problems, path="data")
    warnings = [f"units: {pr}" for pr in problems]
    if table.n_dropped:
        warnings.append(f"{table.n_dropped} rows with invalid values were dropped")
    n = table.rows.size
    try:
        gram = accumulate(model, [cols])
        observed = {k: cols[k] for k in DATA_COLUMNS if k in cols} if n <= MAX_OBSERVED else None
        post, _ = _fit_im_gram(
            model,
            gram,
            model.first_row(cols),
            t0=t0,
            priors=priors,
            observed=observed,
            settings={
                "data": "DataFrame" if hasattr(data, "iloc") else "mapping",
                "n_dropped": table.n_dropped,
            },  # fmt: skip
            warnings=warnings,
            scheme=scheme,
            sampler=smp,
        )
    except DataError as exc:
        raise relocate(exc, "data", table.rows, {}) from None
    if warn:
        post.warn(stacklevel=3)  # past new_spelling's wrapper: the caller's line
    return post


@new_spelling(data=("drop_invalid", "accept_units"))
def fit_im_file(
    path: str,
    *,
    t0: float | None = None,
    f_hz: float = 60.0,
    currents: str = "modelled",
    priors: Mapping[str, BlockPrior] | None = None,
    chunk_rows: int = CHUNK_ROWS,
    progress: Callable[[int], None] | None = None,
    scheme: Scheme = "blocked",
    spec: DataSpec | None = None,
    sampler: SamplerSettings | None = None,
    wording: Wording = "python",
):
    """Fit the induction motor to a CSV or Parquet file read in chunks.

    Parameters
    ----------
    path : str
        CSV or Parquet file (by extension), or ``"-"`` for CSV on standard input; columns
        ``t_s, ud, uq, ed, eq, w, id, iq, ded, deq, dw`` (others are ignored).
    t0, f_hz, currents, priors
        As :func:`fit_im`.
    chunk_rows : int
        Rows read at a time (memory does not grow with the file).
    progress : callable, optional
        Called with the number of rows of each chunk.
    scheme : {"blocked", "single-site", "exact"}
        Gibbs scheme.
    spec : DataSpec, optional
        Its ``drop_invalid`` and ``accept_units``, as :func:`fit_im` (see
        :func:`loadbayes.measurements.units.check_motor_units`).
    sampler : SamplerSettings, optional
        How the chains run (:data:`loadbayes.fit.sampler.MODEL_DEFAULTS` by default).
    wording : {"python", "cli"}
        Whose names the unit check's message gives (``loadbayes fit im`` passes "cli").

    Returns
    -------
    (Posterior, InductionMotorModel)
        The model comes back with T0 resolved, ready for the baselines.

    Raises
    ------
    DataError
        Bad data; states not in per unit; or, without ``t0``, a record whose first rows
        are not a steady state (:func:`steady_start_problem`), since T0 comes from row 1.
    """
    spec = spec if spec is not None else DataSpec()
    drop_invalid, accept_units = spec.drop_invalid, spec.accept_units
    smp = sampler if sampler is not None else MODEL_DEFAULTS
    model = InductionMotorModel(f_hz=f_hz, currents=currents)  # type: ignore[arg-type]
    acc = GramAccumulator(model.gram_columns)
    state: dict[str, Any] = {"dropped": 0}
    keep: dict[str, list[np.ndarray]] = {c: [] for c in DATA_COLUMNS}
    kept = 0
    for chunk in iter_chunks(
        path, list(DATA_COLUMNS), chunk_rows=chunk_rows, drop_invalid=drop_invalid
    ):
        state["dropped"] += chunk.n_dropped
        if chunk.n_rows == 0:
            continue
        if "first" not in state:
            state["first"] = model.first_row(chunk.data)
            state["first_row"] = chunk.row_of(0)
            state["unit_notes"] = _first_chunk_checks(
                chunk.data, path=str(path), t0=t0, accept_units=accept_units,
                row=state["first_row"], wording=wording,
            )  # fmt: skip
        rows = model.rows(chunk.data)
        acc.update(rows)
        if kept <= MAX_OBSERVED:
            for c in DATA_COLUMNS:
                keep[c].append(chunk.data[c])
            kept += chunk.n_rows
        if progress is not None:
            progress(rows.shape[0])
    gram = acc.result()
    warnings = list(state.get("unit_notes", []))
    if state["dropped"]:
        warnings.append(
            f"{state['dropped']} rows with invalid values were dropped (--drop-invalid)"
        )
    if t0 is None and state.get("first_row", 1) != 1:
        warnings.append(
            f"row 1 was dropped: T0 comes from row {state['first_row']}, taken as a steady state"
        )
    observed = None
    if gram.n <= MAX_OBSERVED:
        observed = {c: np.concatenate(v) for c, v in keep.items() if v}
    try:
        return _fit_im_gram(
            model,
            gram,
            state["first"],
            t0=t0,
            priors=priors,
            observed=observed,
            settings={"data": str(path), "n_dropped": state["dropped"]},
            warnings=warnings,
            scheme=scheme,
            sampler=smp,
        )
    except DataError as exc:
        raise DataError(exc.message, path=str(path), column=exc.column, row=exc.row) from None
    except np.linalg.LinAlgError as exc:
        # A record the checks let through whose equations are still singular: said with
        # its file, not as the solver's bare message.
        raise DataError(
            f"the motor's equations are singular on this record ({exc}): a column that is "
            "constant or a copy of another?",
            path=str(path),
        ) from None


#: The first rows are a steady state when their derivatives are below this share of the
#: record's largest, or within 10 times its quiet (20th-percentile) level.
STEADY_SHARE = 0.1


def steady_start_problem(data: Mapping[str, np.ndarray], *, head: int = 5) -> str | None:
    """Why the first rows of a motor record are not a steady state, or None.

    Parameters
    ----------
    data : mapping
        Columns ``dw``, ``ded``, ``deq`` (derivatives per second), in row order.
    head : int
        Rows at the start that must be steady.

    Returns
    -------
    str or None
        A plain-words reason naming the derivative and its size.

    Notes
    -----
    T0 is taken from row 1 as a steady state (``dw = 0``). A record that starts inside
    a disturbance gives a wrong T0 with a narrow interval (b3 = -0.051 for a true -0.714
    in issue 14). The rule: the median ``|x|`` of the first ``head`` rows, for each
    derivative ``x``, must be below 10% of the record's largest ``|x|`` or below 10
    times its 20th percentile (its level where the motor is quiet, noise included). With
    Gaussian noise alone the second bound is 2.5 sd, passed by chance with probability
    about 2e-5.
    """
    for name in ("dw", "ded", "deq"):
        if name not in data:
            continue
        x = np.abs(np.asarray(data[name], dtype=float))
        x = x[np.isfinite(x)]
        if x.size < 4 * head:
            continue
        start, peak = float(np.median(x[:head])), float(x.max())
        quiet = float(np.quantile(x, 0.2))
        if start > STEADY_SHARE * peak and start > 10 * quiet:
            return (
                f"the record does not start in a steady state (|{name}| = {start:.3g} over "
                f"the first {head} rows, {100 * start / peak:.0f}% of its largest, "
                f"{start / max(quiet, 1e-300):.3g} times its quiet level): T0 taken from "
                "row 1 would be wrong; give --t0, or start the record before the disturbance"
            )
    return None


def _first_chunk_checks(data, *, path, t0, accept_units, row, wording="cli") -> list[str]:
    problems = check_motor_units(data, wording=wording)
    if not accept_units:
        refuse(problems, path=path)
    if t0 is None:
        why = steady_start_problem(data)
        if why:
            raise DataError(why, path=path, row=row)
    return [f"units: {pr}" for pr in problems]
