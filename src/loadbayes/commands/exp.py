"""``loadbayes fit exp``, and the reader of V, P, Q (f, t) columns the newer commands share."""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass, field
from typing import Any

import click
import numpy as np

from loadbayes.cli import fit
from loadbayes.commands.common import (
    Progress,
    UserError,
    check_outputs,
    estimate_rows,
    nominal,
    output_options,
    sampler_options,
    user_errors,
    write_outputs,
)


# ------------------------------------------------------------------ shared reader
@dataclass
class PowerColumns:
    """Columns read for a load model, in per unit, with their 1-based data row numbers."""

    cols: dict[str, np.ndarray]
    rows: np.ndarray
    n_dropped: int = 0
    extra: dict[str, np.ndarray] = field(default_factory=dict)


def power_chunks(
    path: str,
    *,
    v_col: str,
    p_col: str,
    q_col: str | None,
    q_required: bool,
    f_col: str | None = None,
    t_col: str | None = None,
    extra: tuple[str, ...] = (),
    v_base: float | None = None,
    s_base: float | None = None,
    drop_invalid: bool = False,
    chunk_rows: int = 1 << 18,
) -> Iterator[PowerColumns]:
    """Read ``v``, ``p`` (``q``, ``f``, ``t`` and optional ``extra`` columns) in chunks.

    Column names are the user's; the chunks use ``v, p, q, f, t``. A Q column named by
    default (``q``) is optional, a Q column named by the user is required, ``None``
    skips it; ``f_col`` and ``t_col`` are read when given (``t_col`` only if present).
    Voltages are divided by ``v_base``, powers by ``s_base``.
    """
    from loadbayes.io.tables import iter_chunks

    for name, base in (("--v-base", v_base), ("--s-base", s_base)):
        if base is not None and not (np.isfinite(base) and base > 0):
            raise ValueError(f"{name} must be positive, got {base}")
    vs, ss = v_base or 1.0, s_base or 1.0
    required = (
        [v_col, p_col] + ([q_col] if q_col and q_required else []) + ([f_col] if f_col else [])
    )
    optional = ([q_col] if q_col and not q_required else []) + ([t_col] if t_col else [])
    optional += [c for c in extra if c not in required + optional]
    for chunk in iter_chunks(
        path,
        required,
        optional=optional,
        positive=[v_col],
        chunk_rows=chunk_rows,
        drop_invalid=drop_invalid,
    ):
        d = chunk.data
        cols = {"v": d[v_col] / vs, "p": d[p_col] / ss}
        if q_col and q_col in d:
            cols["q"] = d[q_col] / ss
        if f_col:
            cols["f"] = d[f_col]
        if t_col and t_col in d:
            cols["t"] = d[t_col]
        ext = {c: d[c] for c in extra if c in d}
        yield PowerColumns(cols, chunk.rows, chunk.n_dropped, ext)


def read_power_columns(path: str, *, progress=None, **kw: Any) -> PowerColumns:
    """All of :func:`power_chunks` in memory (for samplers that visit every sample)."""
    from loadbayes.io.errors import DataError

    parts = []
    for part in power_chunks(path, **kw):
        parts.append(part)
        if progress is not None:
            progress(part.rows.size)
    if not parts or sum(p.rows.size for p in parts) == 0:
        raise DataError("no valid rows", path=str(path))
    cols = {k: np.concatenate([p.cols[k] for p in parts]) for k in parts[0].cols}
    extra = {k: np.concatenate([p.extra[k] for p in parts]) for k in parts[0].extra}
    rows = np.concatenate([p.rows for p in parts])
    return PowerColumns(cols, rows, sum(p.n_dropped for p in parts), extra)


def relocate(exc: Exception, path: str, rows: np.ndarray, names: dict[str, str | None]):
    """A DataError from in-memory arrays, re-located to the file's column and row."""
    from loadbayes.io.errors import DataError

    row = exc.row  # type: ignore[attr-defined]
    if row is not None and 1 <= row <= rows.size:
        row = int(rows[row - 1])
    column = names.get(exc.column or "", exc.column)  # type: ignore[attr-defined]
    return DataError(exc.message, path=str(path), column=column, row=row)  # type: ignore[attr-defined]


# ------------------------------------------------------------------------ fit exp
@fit.command("exp")
@click.argument("data", type=str)
@click.option("--v-col", default="v", show_default=True, help="Voltage column.")
@click.option("--p-col", default="p", show_default=True, help="Active-power column.")
@click.option("--q-col", default="q", show_default=True, help="Reactive-power column, or 'none'.")
@click.option("--f-col", default=None, help="Frequency column (fits kpf, kqf); none by default.")
@click.option("--f0", type=float, default=60.0, show_default=True, help="Nominal frequency.")
@click.option("--v0", type=float, default=1.0, show_default=True, help="Nominal voltage.")
@click.option("--p0", default="1.0", show_default=True, help="Nominal P, or 'auto'.")
@click.option("--q0", default="1.0", show_default=True, help="Nominal Q, or 'auto'.")
@click.option("--v-base", type=float, help="Voltage base: data volts / v-base = per unit.")
@click.option("--s-base", type=float, help="Power base: data P, Q / s-base = per unit.")
@click.option(
    "--noise",
    type=click.Choice(["additive", "multiplicative"]),
    default="additive",
    show_default=True,
    help="Additive Gaussian noise on P (Metropolis-within-Gibbs), or relative noise "
    "(log-linear, conjugate, fastest; needs P / P0 > 0).",
)
@sampler_options
@click.option(
    "--exponent-prior",
    default="0,10",
    show_default=True,
    metavar="MEAN,SD",
    help="Normal prior of np and nq.",
)
@click.option(
    "--tau-shape", type=click.FloatRange(min=0, min_open=True), default=1e-3, show_default=True
)
@click.option(
    "--tau-rate", type=click.FloatRange(min=0, min_open=True), default=1e-9, show_default=True
)
@click.option("--drop-invalid", is_flag=True, help="Drop rows with NaN, inf or V <= 0.")
@click.option("--chunk-rows", type=click.IntRange(min=1), default=1 << 18, show_default=True)
@output_options
@user_errors
def fit_exp_cmd(
    data,
    v_col,
    p_col,
    q_col,
    f_col,
    f0,
    v0,
    p0,
    q0,
    v_base,
    s_base,
    noise,
    draws,
    burn,
    chains,
    thin,
    seed,
    init,
    hdi_prob,
    exponent_prior,
    tau_shape,
    tau_rate,
    drop_invalid,
    chunk_rows,
    json_out,
    netcdf_out,
    plot_out,
    quiet,
    force,
):
    """Posterior of the exponential load model P = P0 (V/V0)^np [(1 + kpf df)]."""
    check_outputs({"--json": json_out, "--netcdf": netcdf_out, "--plot": plot_out}, [data], force)
    p0_val, q0_val = nominal(p0, "--p0"), nominal(q0, "--q0")
    if burn >= draws:
        raise UserError(f"--burn ({burn}) must be smaller than --draws ({draws})")
    try:
        e_mean, e_sd = (float(x) for x in exponent_prior.split(","))
        if not (e_sd > 0 and np.isfinite(e_mean) and np.isfinite(e_sd)):
            raise ValueError
    except ValueError:
        raise click.BadParameter(
            f"{exponent_prior!r}: expected MEAN,SD with SD > 0", param_hint="--exponent-prior"
        ) from None
    from loadbayes.core.priors import BlockPrior
    from loadbayes.fit import fit_exp
    from loadbayes.io.errors import DataError
    from loadbayes.models.exponential import ExponentialModel, ExpPriors

    q_name = None if q_col.lower() == "none" else q_col
    progress = Progress("reading", estimate_rows(data), quiet)
    try:
        pc = read_power_columns(
            data,
            v_col=v_col,
            p_col=p_col,
            q_col=q_name,
            q_required=q_col not in ("q", "none"),
            f_col=f_col,
            v_base=v_base,
            s_base=s_base,
            drop_invalid=drop_invalid,
            chunk_rows=chunk_rows,
            progress=progress,
        )
    finally:
        progress.close()
    with_q, with_f = "q" in pc.cols, f_col is not None
    model = ExponentialModel(
        v0=v0, p0=p0_val, q0=q0_val, with_q=with_q, with_f=with_f, f0=f0, noise=noise
    )
    if noise == "additive":
        priors: dict[str, Any] = {}
        for ch, nom, _, _ in model.channels():
            k = (1 if nom == "auto" else 0) + (1 if with_f else 0)
            sd = 1e4 if nom == "auto" else 10.0
            priors[ch] = ExpPriors(
                (e_mean, e_sd), BlockPrior.weak(max(k, 1), sd=sd, shape=tau_shape, rate=tau_rate)
            )
    else:
        priors = {}
        for block in model.blocks:
            means = [e_mean if c in ("np", "nq") else 0.0 for c in block.coef_names]
            sds = [
                e_sd if c in ("np", "nq") else (1e4 if c.startswith("log_") else 10.0)
                for c in block.coef_names
            ]
            priors[block.name] = BlockPrior.weak(
                block.k, mean=means, sd=sds, shape=tau_shape, rate=tau_rate
            )
    warnings = []
    if pc.n_dropped:
        warnings.append(f"{pc.n_dropped} rows with invalid values were dropped (--drop-invalid)")
    names = {"v": v_col, "p": p_col, "q": q_name, "f": f_col}
    try:
        post = fit_exp(
            pc.cols,
            v0=v0,
            p0=p0_val,
            q0=q0_val,
            with_q=with_q,
            with_f=with_f,
            f0=f0,
            noise=noise,
            priors=priors,
            chains=chains,
            draws=draws,
            burn=burn,
            thin=thin,
            init=init,
            seed=seed,
            warnings=warnings,
            settings={
                "data": str(data),
                "columns": names,
                "v_base": v_base,
                "s_base": s_base,
                "n_dropped": pc.n_dropped,
            },
        )
    except DataError as exc:
        raise relocate(exc, data, pc.rows, names) from None
    write_outputs(
        post,
        model=model,
        hdi_prob=hdi_prob,
        json_out=json_out,
        netcdf_out=netcdf_out,
        plot_out=plot_out,
        force=force,
        quiet=quiet,
    )
