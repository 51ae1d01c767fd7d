"""``loadbayes steps``: voltage steps in a long record, and the ZIP fit from their windows."""

from __future__ import annotations

import json

import click
import numpy as np

from loadbayes.commands.options import (
    OneLineCommand,
    accept_units_option,
    data_options,
    distinct_columns,
    q_column,
)
from loadbayes.commands.output import (
    Progress,
    UserError,
    check_outputs,
    estimate_rows,
    user_errors,
)
from loadbayes.commands.settings import sampler_settings

STEP_DRAWS, STEP_BURN = 6_000, 1_000


@click.command("steps", cls=OneLineCommand)
@click.argument("data", type=str)
@data_options()
@accept_units_option
@click.option("--t-col", default=None, help="Time column: seconds, or ISO timestamps "
              "(gaps, the drift's slope, the table); the row number if not given.")  # fmt: skip
@click.option("--v0", type=float, default=1.0, show_default=True, help="Nominal voltage.")
@click.option("--window", type=click.IntRange(min=3), default=5, show_default=True,
              help="Samples on each side of a step (the fit's windows).")  # fmt: skip
@click.option("--k", "k_sd", type=click.FloatRange(min=1), default=6.0, show_default=True,
              help="A step exceeds K noise sd of V, and each side stays within K sd.")  # fmt: skip
@click.option("--min-step", type=click.FloatRange(min=0, min_open=True), default=0.004,
              show_default=True, help="Smallest step of V in per unit.")  # fmt: skip
@click.option("--out", "table_out", type=click.Path(dir_okay=False),
              help="The steps table (CSV): time, row, V before, dV, dP, dQ, "
              "sensitivities.")  # fmt: skip
@click.option("--json", "json_out", type=click.Path(dir_okay=False),
              help="The fit from the steps' windows (the JSON of fit zip, with 'steps' and "
              "'derived': dP/dV, dQ/dV at V0).")  # fmt: skip
@sampler_settings(draws=STEP_DRAWS, burn=STEP_BURN)
@click.option("--quiet", is_flag=True, help="No progress bar and no tables.")
@click.option("--force", is_flag=True, help="Overwrite existing outputs.")
@user_errors
def steps_cmd(
    data, v_col, p_col, q_col, v_base, s_base, drop_invalid, chunk_rows, accept_units, t_col,
    v0, window, k_sd, min_step, table_out, json_out, sampler, quiet, force,
):  # fmt: skip
    """Voltage steps (taps, capacitors, CVR) in a long record, and the ZIP fit from them.

    Each step's dP against its dV, with the slow load drift on both sides removed, is
    the load's voltage dependence (the field method; docs/zip.md).
    """
    check_outputs({"--out": table_out, "--json": json_out}, [data], force,
                  stdout_ok=("--json", "--out"))  # fmt: skip
    distinct_columns(v_col=v_col, p_col=p_col, q_col=q_col, t_col=t_col)
    if t_col and data == "-":
        raise UserError("--t-col needs a file (standard input is read once)")
    q_name, q_required = q_column(q_col)

    from loadbayes.fit.steps import fit_steps
    from loadbayes.measurements.columns import read_power_columns
    from loadbayes.measurements.steps import find_steps, steps_table
    from loadbayes.measurements.units import check_power_units
    from loadbayes.measurements.wording import refuse

    progress = Progress("reading", estimate_rows(data), quiet)
    try:
        pc = read_power_columns(
            data, v_col=v_col, p_col=p_col, q_col=q_name, q_required=q_required,
            v_base=v_base, s_base=s_base, drop_invalid=drop_invalid, chunk_rows=chunk_rows,
            progress=progress,
        )  # fmt: skip
    finally:
        progress.close()
    names = {"v": v_col, "p": p_col, "q": q_name}
    cols = pc.cols
    problems = check_power_units(cols["v"], cols["p"], cols.get("q"), v0=v0, p0="auto",
                                 q0="auto", v_base=v_base, s_base=s_base)  # fmt: skip
    if not accept_units:
        refuse(problems, path=data, names=names)
    warnings = [f"units: {pr}" for pr in problems]
    if pc.n_dropped:
        warnings.append(f"{pc.n_dropped} rows with invalid values were dropped (--drop-invalid)")
    secs, labels = (None, None) if not t_col else read_times(data, t_col, pc.rows)
    x = cols["v"] / v0
    found, info = find_steps(x, cols["p"], cols.get("q"), t=secs, window=window, k=k_sd,
                             min_step=min_step)  # fmt: skip
    table = steps_table(found, time=labels if labels is not None else pc.rows)
    # the row of the file (1-based, header excluded), not the position among kept rows
    table["row"] = [int(pc.rows[s.index]) for s in found]
    table = table.drop(columns="index")
    if not quiet:
        click.echo(
            f"loadbayes: {len(found)} voltage step(s) found (noise sd of V "
            f"{info['noise_sd']:.2g} p.u.; {info['candidates']} candidates, "
            f"{info['not_steady']} not steady, {info['too_close']} too close or at a gap)",
            err=True,
        )
    post = None
    if len(found) >= 2:
        post = fit_steps(x, cols["p"], cols.get("q"), steps=found, t=secs, v0=1.0,
                         sampler=sampler, warnings=warnings,
                         settings={"data": str(data), "columns": names, "v0": v0,
                                   "v_base": v_base, "s_base": s_base, "window": window,
                                   "k": k_sd, "min_step": min_step})  # fmt: skip
        post.extra_json["steps"] = json.loads(table.to_json(orient="records"))
        post.extra_json["step_search"] = info
    elif json_out:
        raise UserError(
            f"{len(found)} voltage step(s) found in {data}: a fit from steps needs at "
            "least two (lower --min-step or --k, or fit the record with fit zip)"
        )
    _write(post, table, table_out=table_out, json_out=json_out, hdi_prob=sampler.hdi_prob,
           force=force, quiet=quiet)  # fmt: skip


def _write(post, table, *, table_out, json_out, hdi_prob, force, quiet):
    """The steps table and the fit's JSON as one transaction; the tables unless quiet."""
    from loadbayes.diagnostics import fit_warnings
    from loadbayes.io.transaction import OutputSet
    from loadbayes.report.text import summary_table

    summary = None
    if post is not None:
        summary = post.summary(hdi_prob=hdi_prob)
        fit_warnings(post, summary, hdi_prob=hdi_prob)
    files = {k: v for k, v in (("--out", table_out), ("--json", json_out)) if v and v != "-"}
    text = None
    if post is not None and json_out:
        text = json.dumps(post.to_dict(hdi_prob=hdi_prob, summary=summary), indent=2,
                          allow_nan=False)  # fmt: skip
    with OutputSet(files, force=force) as out:
        if table_out and table_out != "-":
            table.to_csv(out.temp("--out"), index=False)
        if text is not None and json_out != "-":
            out.temp("--json").write_text(text + "\n", encoding="utf-8")
        out.commit()
    if table_out == "-":
        click.echo(table.to_csv(index=False), nl=False)
    if json_out == "-" and text is not None:
        click.echo(text)
    if post is not None:
        for w in post.warnings:
            click.echo(f"loadbayes: warning: {w}", err=True)
    if quiet:
        return
    if table_out != "-" and len(table):  # no steps: the count above says it
        click.echo(table.to_string(index=False, float_format=lambda x: f"{x:.4g}"), err=True)
    if post is not None:
        d = post.extra_json["derived"]
        for name, s in d.items():
            click.echo(
                f"{name} at V0 (per unit of the load's level): {s['mean']:.3g} +/- "
                f"{s['sd']:.2g} [{s['hdi_low']:.3g}, {s['hdi_high']:.3g}]",
                err=True,
            )
        click.echo(summary_table(post, hdi_prob=hdi_prob, summary=summary),
                   err=json_out == "-")  # fmt: skip


def read_times(path: str, t_col: str, rows: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The time column of the kept rows: seconds from the first, and the text as written.

    Numbers are seconds; otherwise each cell must be an ISO timestamp. A cell that is
    neither, or a time that does not increase, is one DataError naming the row.
    """
    import pandas as pd

    from loadbayes.io.errors import DataError
    from loadbayes.measurements.times import read_text_column

    # The shared reader: the file's separator (';' too) and a GB18030 header, as the
    # V, P, Q reader takes them (pandas' defaults read neither).
    raw = read_text_column(str(path), t_col)
    raw = raw.iloc[rows - 1].reset_index(drop=True)
    nums = pd.to_numeric(raw, errors="coerce")
    if nums.notna().all():
        secs = nums.to_numpy(dtype=float)
    else:
        # ISO 8601 allows a comma before the fraction of a second (10:00:00,5).
        comma = raw.astype(str).str.replace(r"(\d{2}:\d{2}:\d{2}),(\d)", r"\1.\2", regex=True)
        stamps = pd.to_datetime(comma, errors="coerce", format="ISO8601")
        bad = np.flatnonzero(stamps.isna().to_numpy())
        if bad.size:
            i = int(bad[0])
            raise DataError(f"{raw.iloc[i]!r} is neither a number of seconds nor an ISO "
                            "timestamp", path=str(path), column=t_col,
                            row=int(rows[i]))  # fmt: skip
        secs = (stamps - stamps.iloc[0]).dt.total_seconds().to_numpy(dtype=float)
    back = np.flatnonzero(np.diff(secs) <= 0)
    if back.size:
        i = int(back[0]) + 1
        raise DataError("time does not increase (the rows must be in time order, without "
                        "repeats)", path=str(path), column=t_col, row=int(rows[i]))  # fmt: skip
    return secs, raw.astype(str).to_numpy()
