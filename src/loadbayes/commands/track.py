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
)
from loadbayes.commands.output import (
    Progress,
    UserError,
    check_outputs,
    estimate_rows,
    stop_if_signalled,
    user_errors,
)

TRUTH_COLUMNS = tuple(f"a{i}_true" for i in range(1, 7))
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
    help="Time column, copied to the output when present (else the row number).",
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
    note = nominal_note(p0, q0, with_q=q_col.lower() != "none")
    p0, q0 = nominal(p0, "--p0"), nominal(q0, "--q0")
    if not str(out).lower().endswith((".csv", ".txt")):
        raise UserError(f"{out}: --out must be a .csv or .txt file")

    import pandas as pd

    from loadbayes.inference.online import OnlinePrior, OnlineTracker
    from loadbayes.io.transaction import OutputSet
    from loadbayes.measurements.columns import power_chunks
    from loadbayes.measurements.units import check_power_units, level_at_nominal, refuse

    q_name = None if q_col.lower() == "none" else q_col
    contrasts = np.array([[1.0, 0.0], [0.0, 1.0], [-1.0, -1.0]])
    offsets = np.array([0.0, 0.0, 1.0])
    trackers: dict[str, OnlineTracker] = {}
    keep_plot: list[pd.DataFrame] = []
    progress = Progress("tracking", estimate_rows(data), quiet)
    n_total = n_dropped = 0
    has_t = None
    files = {"--out": out} | ({"--plot": plot_out} if plot_out else {})
    names = {"v": v_col, "p": p_col, "q": q_name}
    unit_notes: list[str] = []
    try:
        with (
            OutputSet(files, force=force) as outputs,
            open(outputs.temp("--out"), "w", encoding="utf-8", newline="") as fh,
        ):
            first = True
            parts, head = _head(
                power_chunks(
                    data,
                    v_col=v_col,
                    p_col=p_col,
                    q_col=q_name,
                    q_required=q_col not in ("q", "none"),
                    t_col=t_col,
                    extra=TRUTH_COLUMNS if plot_out else (),
                    v_base=v_base,
                    s_base=s_base,
                    drop_invalid=drop_invalid,
                    chunk_rows=chunk_rows,
                )
            )
            for part in parts:
                n_dropped += part.n_dropped
                n = part.rows.size
                if not trackers and n:
                    has_t = "t" in part.cols
                    c = head
                    problems = check_power_units(
                        c["v"], c["p"], c.get("q"), v0=v0, p0=p0, q0=q0,
                        v_base=v_base, s_base=s_base,
                    )  # fmt: skip
                    if not accept_units:
                        refuse(problems, path=str(data), names=names)
                    unit_notes = [f"units: {pr}" for pr in problems]
                    # 'auto' here: P0 (Q0) from the first AUTO_ROWS rows (whatever the
                    # chunking), then held fixed: the tracker's shares are linear only
                    # for a known nominal power.
                    x = c["v"] / v0
                    nom = {ch: level_at_nominal(x, c[ch]) for ch in ("p", "q") if ch in c}
                    if p0 == "auto":
                        p0 = nom["p"]
                    if q0 == "auto" and "q" in c:
                        q0 = nom["q"]
                    if note and not quiet:
                        est = ", ".join(
                            f"{k.upper()}0 = {v:.5g}" for k, v in (("p", p0), ("q", q0))
                            if k in c and isinstance(v, float)
                        )  # fmt: skip
                        click.echo(
                            f"loadbayes: note: {note}: {est} from the first {c['v'].size} rows "
                            "(at V = V0, by least squares), then held fixed",
                            err=True,
                        )
                    channels = [("p", p0, ("a1", "a2", "a3"))]
                    if "q" in part.cols:
                        channels.append(("q", q0, ("a4", "a5", "a6")))
                    prior = OnlinePrior.weak(2, coef_sd=prior_sd, noise_sd=noise_sd)
                    for ch, _, _ in channels:
                        trackers[ch] = OnlineTracker(
                            2,
                            forgetting=forgetting,
                            window=window,
                            drift=drift,
                            prior=prior,
                            prob=prob,
                            contrasts=contrasts,
                            offsets=offsets,
                        )
                if n == 0:
                    continue
                stop_if_signalled()
                x = part.cols["v"] / v0
                dx = x - 1.0
                z = np.column_stack([dx * (x + 1.0), dx])
                cols: dict[str, np.ndarray] = {"t": part.cols["t"] if has_t else part.rows}
                for ch, nom, names in channels:
                    res = trackers[ch].update(z, part.cols[ch] / nom - 1.0)
                    for j, name in enumerate(names):
                        cols[f"{name}_mean"] = res.mean[:, j]
                        cols[f"{name}_low"] = res.low[:, j]
                        cols[f"{name}_high"] = res.high[:, j]
                frame = pd.DataFrame(cols)
                frame.to_csv(
                    fh, header=first, index=False, float_format="%.10g", lineterminator="\n"
                )
                first = False
                n_total += n
                progress(n)
                if plot_out:
                    for c, a in part.extra.items():
                        frame[c] = a
                    keep_plot.append(frame)
            if first:
                from loadbayes.io.errors import DataError

                raise DataError("no valid rows", path=str(data))
            fh.flush()
            if plot_out:
                _plot(pd.concat(keep_plot, ignore_index=True), outputs.temp("--plot"), has_t,
                      prob, t_col)  # fmt: skip
            stop_if_signalled()
            outputs.commit()
    finally:
        progress.close()
    if n_total == 0:
        raise UserError(f"{data}: no valid rows")
    for w in unit_notes:
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


#: Rows that fix an ``auto`` nominal power and the unit check, whatever the chunking.
AUTO_ROWS = 10_000


def _head(chunks):
    """The chunks again, and the first AUTO_ROWS rows of V, P, Q gathered from them."""
    import itertools

    it = iter(chunks)
    buffered, got = [], 0
    for part in it:
        buffered.append(part)
        got += part.rows.size
        if got >= AUTO_ROWS:
            break
    keys = buffered[0].cols if buffered else {}
    head = {k: np.concatenate([b.cols[k] for b in buffered])[:AUTO_ROWS] for k in keys}
    return itertools.chain(buffered, it), head


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
