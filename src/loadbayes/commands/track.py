"""``loadbayes track zip``: the ZIP coefficients after every sample, streamed."""

from __future__ import annotations

import click
import numpy as np

from loadbayes.commands.options import (
    OneLineCommand,
    accept_units_option,
    data_options,
    distinct_columns,
    nominal,
    nominal_note,
    nominal_options,
    q_column,
)
from loadbayes.commands.output import (
    Progress,
    UserError,
    check_outputs,
    estimate_rows,
    user_errors,
)
from loadbayes.commands.signals import stop_if_signalled

_PLOT_MAX_POINTS = 20_000


@click.command("zip", cls=OneLineCommand)
@click.argument("data", type=str)
@click.option(
    "--out",
    "out",
    type=click.Path(dir_okay=False),
    required=True,
    help="CSV of t and a1_mean, a1_low, a1_high, ... after every sample.",
)
@click.option(
    "--forgetting",
    type=float,
    default=None,
    help="Forgetting factor in (0, 1] (default 0.999 when no other memory is "
    "given); memory about 1/(1 - forgetting) samples.",
)
@click.option(
    "--window",
    type=click.IntRange(min=1),
    default=None,
    help="Sliding window of the last N samples instead of forgetting.",
)
@click.option(
    "--drift",
    type=click.FloatRange(min=0, min_open=True),
    default=None,
    help="Random-walk drift of the coefficients per sample, in units of the "
    "noise variance, instead of forgetting.",
)
@data_options(chunk_rows=100_000, q_help="Reactive-power column, or 'none' to track P only.")
@click.option(
    "--t-col",
    default="t",
    show_default=True,
    help="Time column (seconds, or ISO timestamps as seconds from the first), increasing; "
    "copied to the output when present (else the row number).",
)
@nominal_options()
@accept_units_option
@click.option(
    "--prob",
    type=click.FloatRange(0, 1, min_open=True, max_open=True),
    default=0.95,
    show_default=True,
    help="Probability of the intervals.",
)
@click.option(
    "--prior-sd",
    type=click.FloatRange(min=0, min_open=True),
    default=10.0,
    show_default=True,
    help="Prior scale of each ZIP coefficient.",
)
@click.option(
    "--noise-sd",
    type=click.FloatRange(min=0, min_open=True),
    default=0.05,
    show_default=True,
    help="Prior guess of the noise sd, per unit of P0 (Q0).",
)
@click.option(
    "--plot",
    "plot_out",
    type=click.Path(dir_okay=False),
    help="Figure of the tracks (with a1_true.. columns of the data when present).",
)
@click.option("--quiet", is_flag=True, help="No progress on stderr.")
@click.option("--force", is_flag=True, help="Overwrite existing outputs.")
@user_errors
def track_zip_cmd(
    data,
    out,
    forgetting,
    window,
    drift,
    v_col,
    p_col,
    q_col,
    t_col,
    v0,
    p0,
    q0,
    v_base,
    s_base,
    prob,
    prior_sd,
    noise_sd,
    drop_invalid,
    chunk_rows,
    accept_units,
    plot_out,
    quiet,
    force,
):
    """Track the ZIP coefficients of a load over time (online Bayes, O(1) per sample).

    Reads DATA (CSV or Parquet, or CSV on stdin with DATA = '-') in chunks and writes,
    for every sample, the posterior mean and central interval of a1, a2, a3 (and a4, a5,
    a6 with Q) under exponential forgetting, a sliding window or a random-walk drift.
    """
    check_outputs({"--out": out, "--plot": plot_out}, [data], force)
    if sum(x is not None for x in (forgetting, window, drift)) > 1:
        raise UserError("give only one of --forgetting, --window and --drift")
    if forgetting is not None and not 0 < forgetting <= 1:
        raise UserError(f"--forgetting must be in (0, 1], got {forgetting}")
    if window is None and drift is None and forgetting is None:
        forgetting = 0.999
    if not (np.isfinite(v0) and v0 > 0):
        raise UserError(f"--v0 must be a finite positive number, got {v0}")
    distinct_columns(v_col=v_col, p_col=p_col, q_col=q_col, t_col=t_col)
    q_name, q_required = q_column(q_col)
    note = nominal_note(p0, q0, with_q=q_name is not None)
    p0, q0 = nominal(p0, "--p0"), nominal(q0, "--q0")
    if not str(out).lower().endswith((".csv", ".txt")):
        raise UserError(f"{out}: --out must be a .csv or .txt file")

    import pandas as pd

    from loadbayes.fit.track import TRUTH_COLUMNS, track_zip
    from loadbayes.io.transaction import OutputSet

    track = track_zip(
        data,
        v_col=v_col,
        p_col=p_col,
        q_col=q_name,
        q_required=q_required,
        t_col=t_col,
        extra=TRUTH_COLUMNS if plot_out else (),
        v0=v0,
        p0=p0,
        q0=q0,
        v_base=v_base,
        s_base=s_base,
        drop_invalid=drop_invalid,
        chunk_rows=chunk_rows,
        forgetting=forgetting,
        window=window,
        drift=drift,
        prob=prob,
        prior_sd=prior_sd,
        noise_sd=noise_sd,
        accept_units=accept_units,
    )
    keep_plot: list[pd.DataFrame] = []
    progress = Progress("tracking", estimate_rows(data), quiet)
    files = {"--out": out} | ({"--plot": plot_out} if plot_out else {})
    try:
        with (
            OutputSet(files, force=force) as outputs,
            open(outputs.temp("--out"), "w", encoding="utf-8", newline="") as fh,
        ):
            first = True
            for frame, extra in track:
                if first and note and not quiet:
                    est = ", ".join(
                        f"{k.upper()}0 = {v:.5g}"
                        for k, v in (("p", track.p0), ("q", track.q0))
                        if (k == "p" or track.with_q) and isinstance(v, float)
                    )
                    click.echo(
                        f"loadbayes: note: {note}: {est} from the first {track.head_rows} rows "
                        "(at V = V0, by least squares), then held fixed",
                        err=True,
                    )
                stop_if_signalled()
                frame.to_csv(
                    fh, header=first, index=False, float_format="%.10g", lineterminator="\n"
                )
                first = False
                progress(len(frame))
                if plot_out:
                    for c, a in extra.items():
                        frame[c] = a
                    keep_plot.append(frame)
            fh.flush()
            if plot_out:
                _plot(pd.concat(keep_plot, ignore_index=True), outputs.temp("--plot"),
                      track.has_t, prob, t_col)  # fmt: skip
            stop_if_signalled()
            outputs.commit()
    finally:
        progress.close()
    n_total, n_dropped = track.n_rows, track.n_dropped
    if n_total == 0:
        raise UserError(f"{data}: no valid rows")
    for w in track.unit_notes:
        click.echo(f"loadbayes: warning: {w}", err=True)
    if n_dropped:
        click.echo(
            f"loadbayes: warning: {n_dropped} rows with invalid values were dropped "
            "(--drop-invalid)",
            err=True,
        )
    if not quiet:
        memory = (
            f"window {window}"
            if window
            else f"drift {drift:g}"
            if drift
            else f"forgetting {forgetting:g}"
        )
        click.echo(f"tracked {n_total} samples ({memory}) into {out}", err=True)


def _plot(df, path, has_t, prob, t_col) -> None:
    from loadbayes.plots.fit import pyplot, save_figure

    plt = pyplot()
    step = max(len(df) // _PLOT_MAX_POINTS, 1)
    df = df.iloc[::step]
    names = [c[:-5] for c in df.columns if c.endswith("_mean")]
    fig, axes = plt.subplots(
        len(names), 1, figsize=(9, 1.9 * len(names)), sharex=True, squeeze=False
    )
    t = df["t"].to_numpy()
    for ax, name in zip(axes[:, 0], names, strict=True):
        ax.fill_between(
            t, df[f"{name}_low"], df[f"{name}_high"], alpha=0.3, lw=0, label=f"{prob:.0%} interval"
        )
        ax.plot(t, df[f"{name}_mean"], lw=0.8, label="posterior mean")
        if f"{name}_true" in df:
            ax.plot(t, df[f"{name}_true"], "k-", lw=1.2, label="truth")
        lo, hi = np.nanpercentile(df[f"{name}_mean"], [1, 99])
        pad = max(hi - lo, 0.5)
        ax.set_ylim(lo - pad, hi + pad)
        ax.set_ylabel(name)
    axes[0, 0].legend(fontsize=7, ncol=3)
    axes[-1, 0].set_xlabel(t_col if has_t else "row")
    fig.tight_layout()
    save_figure(fig, path, force=True)  # a temporary of the run's output set
