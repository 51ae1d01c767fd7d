"""ZIP fits: from arrays or DataFrames, and from files read in chunks."""

from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import Any

import numpy as np

from loadbayes.core.priors import BlockPrior
from loadbayes.core.stats import GramAccumulator
from loadbayes.fit.core import CHUNK_ROWS, MAX_OBSERVED, accumulate, fit_gram
from loadbayes.inference.gibbs import Scheme
from loadbayes.io.errors import OptionError
from loadbayes.posterior import Posterior

__all__ = ["check_bases", "check_sampler", "fit_zip", "fit_zip_file", "zip_priors"]


def fit_zip(
    data: Any,
    *,
    v_col: str = "v",
    p_col: str = "p",
    q_col: str | None = "q",
    t_col: str | None = None,
    v0: float = 1.0,
    p0: float | str = 1.0,
    q0: float | str = 1.0,
    v_base: float | None = None,
    s_base: float | None = None,
    with_q: bool | None = None,
    units: Mapping[str, str] | None = None,
    priors: Mapping[str, BlockPrior] | None = None,
    drop_invalid: bool = False,
    scheme: Scheme = "blocked",
    chains: int = 4,
    draws: int = 40_000,
    burn: int = 5_000,
    thin: int = 1,
    init: str = "prior",
    seed: int = 0,
    warn: bool = True,
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
        Timestamp column of a DataFrame (or its DatetimeIndex): its first and last values
        are recorded with the result, it is not fitted.
    v0, p0, q0 : float or "auto"
        Nominal values, in per unit when bases are given, else in the data's units.
    v_base, s_base : float, optional
        Bases that turn the data into per unit (V / v_base, P / s_base, Q / s_base).
    with_q : bool, optional
        ``False`` fits P only even when there is a Q column.
    units : mapping, optional
        Units of the data's columns, e.g. ``{"v": "kV", "p": "MW", "q": "Mvar"}``: kept
        with the result and written on the report's axes.
    priors : mapping, optional
        ``{"p": BlockPrior, "q": BlockPrior}`` (see :func:`zip_priors`); weak otherwise.
    drop_invalid : bool
        Drop rows with NaN, inf or non-positive voltage instead of refusing the data.
    scheme, chains, draws, burn, thin, init, seed
        Sampler settings (:func:`loadbayes.inference.gibbs.sample_block`); ``draws``
        counts iterations including burn-in, as the paper's M.
    warn : bool
        Issue the fit's warnings as :class:`~loadbayes.posterior.FitWarning` too.

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

    check_sampler(draws=draws, burn=burn, chains=chains, thin=thin)
    check_bases(v_base, s_base)
    if with_q is False:
        q_col = None
    q_required = q_col is not None and q_col != "q"
    sampler = dict(scheme=scheme, chains=chains, draws=draws, burn=burn, thin=thin, init=init,
                   seed=seed)  # fmt: skip
    if is_path(data):
        post, _ = fit_zip_file(
            str(data), v_col=v_col, p_col=p_col, q_col=q_col, q_required=q_required, v0=v0,
            p0=p0, q0=q0, v_base=v_base, s_base=s_base, priors=priors,
            drop_invalid=drop_invalid, **sampler,
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
        model = ZIPModel(v0=v0, p0=p0, q0=q0, with_q="q" in cols)  # type: ignore[arg-type]
        warnings = []
        if table.n_dropped:
            warnings.append(
                f"{table.n_dropped} rows with invalid values were dropped (drop_invalid=True)"
            )
        try:
            gram = accumulate(model, [cols])
            post = fit_gram(
                model,
                gram,
                priors=priors or model.default_priors(),
                observed=cols if gram.n <= MAX_OBSERVED else None,
                settings={
                    "data": "DataFrame" if hasattr(data, "iloc") else "mapping",
                    "columns": {"v": v_col, "p": p_col, "q": q_col if model.with_q else None},
                    "v0": v0,
                    "p0": p0,
                    "q0": q0 if model.with_q else None,
                    "v_base": v_base,
                    "s_base": s_base,
                    "units": dict(units or {}),
                    "n_dropped": table.n_dropped,
                    **table.time,
                },
                warnings=warnings,
                **sampler,
            )
        except DataError as exc:
            from loadbayes.measurements.columns import relocate

            names = {"v": v_col, "p": p_col, "q": q_col}
            raise relocate(exc, "data", table.rows, names) from None
    if warn:
        post.warn(stacklevel=2)
    return post


def check_sampler(*, draws: int, burn: int, chains: int, thin: int) -> None:
    """The CLI's checks of the sampler settings, as ``OptionError`` in one line."""
    for name, value, low in (("draws", draws, 1), ("chains", chains, 1), ("thin", thin, 1),
                             ("burn", burn, 0)):  # fmt: skip
        if int(value) != value or value < low:
            raise OptionError(f"{name} must be an integer >= {low}, got {value!r}")
    if burn >= draws:
        raise OptionError(f"burn ({burn}) must be smaller than draws ({draws})")


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
    p0: float | str = 1.0,
    q0: float | str = 1.0,
    v_base: float | None = None,
    s_base: float | None = None,
    priors: Mapping[str, BlockPrior] | None = None,
    drop_invalid: bool = False,
    chunk_rows: int = CHUNK_ROWS,
    progress: Callable[[int], None] | None = None,
    accept_units: bool = False,
    **sampler: Any,
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
        Nominal values, in per unit when bases are given, else in the data's units.
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
    **sampler
        ``scheme``, ``chains``, ``draws``, ``burn``, ``thin``, ``init``, ``seed``.

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
    from loadbayes.io.tables import iter_chunks
    from loadbayes.models.zip import ZIPModel

    for name, base in (("--v-base", v_base), ("--s-base", s_base)):
        if base is not None and not (np.isfinite(base) and base > 0):
            raise ValueError(f"{name} must be positive, got {base}")
    vs, ss = v_base or 1.0, s_base or 1.0
    optional = [q_col] if q_col and not q_required else []
    required = [v_col, p_col] + ([q_col] if q_col and q_required else [])
    state: dict[str, Any] = {"dropped": 0}
    names = {"v": v_col, "p": p_col, "q": q_col}
    keep_obs: dict[str, list[np.ndarray]] = {"v": [], "p": [], "q": []}

    def chunks():
        for chunk in iter_chunks(
            path,
            required,
            optional=optional,
            positive=[v_col],
            chunk_rows=chunk_rows,
            drop_invalid=drop_invalid,
        ):
            state["dropped"] += chunk.n_dropped
            # Divide only when a base is given: each division copies the chunk.
            cols = {"v": chunk.data[v_col], "p": chunk.data[p_col]}
            if q_col and q_col in chunk.data:
                cols["q"] = chunk.data[q_col]
            if v_base is not None:
                cols["v"] = cols["v"] / vs
            if s_base is not None:
                for key in ("p", "q"):
                    if key in cols:
                        cols[key] = cols[key] / ss
            if "model" not in state:
                state["model"] = ZIPModel(v0=v0, p0=p0, q0=q0, with_q="q" in cols)  # type: ignore[arg-type]
            if "first_warnings" not in state and cols["v"].size:
                # the first chunk with rows (one whose rows were all dropped says nothing)
                state["first_warnings"] = data_checks(
                    cols, path=path, names=names, accept_units=accept_units,
                    v0=v0, p0=p0, q0=q0, v_base=v_base, s_base=s_base,
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
            f"{state['dropped']} rows with invalid values were dropped (--drop-invalid)"
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
            settings={
                "data": str(path),
                "columns": {"v": v_col, "p": p_col, "q": q_col if model.with_q else None},
                "v0": v0,
                "p0": p0,
                "q0": q0 if model.with_q else None,
                "v_base": v_base,
                "s_base": s_base,
                "n_dropped": state["dropped"],
            },
            warnings=warnings,
            **sampler,
        )
    except DataError as exc:
        column = {"v": v_col, "p": p_col, "q": q_col}.get(exc.column or "", exc.column)
        raise DataError(exc.message, path=str(path), column=column, row=exc.row) from None
    return post, model


def data_checks(cols, *, path, names, accept_units, **nominal) -> list[str]:
    """The unit check (refuse, or warn with ``accept_units``) and the V-noise check."""
    from loadbayes.diagnostics import voltage_noise_warning
    from loadbayes.measurements.units import check_power_units, refuse

    problems = check_power_units(cols["v"], cols.get("p"), cols.get("q"), **nominal)
    if not accept_units:
        refuse(problems, path=str(path), names=names)
    out = [f"units: {pr}" for pr in problems]
    noise = voltage_noise_warning(cols["v"])
    return out + ([noise] if noise else [])


def _chain_first(first, rest):
    yield first
    yield from rest
