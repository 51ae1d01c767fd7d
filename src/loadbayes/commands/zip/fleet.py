"""``loadbayes fit zip DATA --by BUS_COLUMN ...``: a whole fleet of buses in one run.

The options live here and are attached to ``fit zip`` by :func:`fleet_options`;
``fit zip`` hands over to :func:`run_fleet_command` when ``--by`` is given. The
single-bus options that make sense for a fleet (columns, nominal values, bases, priors,
sampler settings, ``--drop-invalid``, ``--quiet``, ``--force``) keep their meaning.
"""

from __future__ import annotations

import contextlib
import os
from pathlib import Path
from typing import TYPE_CHECKING, Any

import click

from loadbayes.commands.options import nominal, q_column
from loadbayes.commands.output import Progress, UserError, check_outputs

if TYPE_CHECKING:
    from loadbayes.core.settings import SamplerSettings

__all__ = ["fleet_options", "fleet_sampler_defaults", "run_fleet_command"]

#: Fleet defaults where the single-bus ones would be too costly for thousands of buses.
FLEET_DRAWS = 2_500
FLEET_BURN = 500


def fleet_options(func):
    """--by --class-col --out --pool --scheduler --workers --dashboard --max-seconds and so on."""
    opts = [
        click.option(
            "--by",
            metavar="COLUMN",
            help="Fit a fleet: the column (or hive folder key) naming each row's bus. "
            "DATA may then be a table, a folder of Parquet/CSV files, or a glob.",
        ),
        click.option(
            "--class-col",
            metavar="COLUMN",
            help="Column (or hive folder key) of each bus's class, for --pool class.",
        ),
        click.option(
            "--out",
            "fleet_out",
            type=click.Path(dir_okay=False),
            help="Fleet result: Parquet table, a row per bus and parameter (needs --by).",
        ),
        click.option(
            "--pool",
            type=click.Choice(["none", "class"]),
            default="none",
            show_default=True,
            help="Per-bus fits, or a hierarchical model pooled within each class.",
        ),
        click.option(
            "--scheduler",
            metavar="ADDRESS",
            help="Run on an existing Dask cluster (tcp://host:8786).",
        ),
        click.option(
            "--workers",
            type=click.IntRange(min=1),
            help="Run on a local Dask cluster of this many worker processes.",
        ),
        click.option(
            "--dashboard",
            is_flag=True,
            help="With --workers: serve Dask's dashboard on 127.0.0.1 (its address is "
            "printed); off by default.",
        ),
        click.option(
            "--max-seconds",
            type=click.FloatRange(min=0),
            default=300.0,
            show_default=True,
            help="--pool class: continue the chains until every class R-hat < 1.01 and "
            "bulk ESS >= 400, or this time budget would run out (0: one round of --draws).",
        ),
        click.option(
            "--netcdf-dir",
            type=click.Path(file_okay=False),
            help="Also write each bus's draws to DIR/<bus>.nc (--pool none).",
        ),
    ]
    for opt in reversed(opts):
        func = opt(func)
    return func


def _refuse_single_bus_options(p: dict[str, Any]) -> None:
    for key, flag in (("json_out", "--json"), ("netcdf_out", "--netcdf"), ("plot_out", "--plot")):
        if p.get(key):
            raise UserError(f"{flag} is for one bus; a fleet writes --out (and --netcdf-dir)")
    if p.get("scheme", "blocked") != "blocked":
        raise UserError("a fleet is fitted with the blocked sampler; drop --scheme")
    if p.get("likelihood", "normal") != "normal":
        raise UserError("a fleet is fitted with the Gaussian likelihood; drop --likelihood")
    if p.get("conjugate"):
        raise UserError("--conjugate is not available for fleets")
    if p.get("v_noise") is not None and p.get("level", "fixed") != "drift":
        raise UserError("--v-noise is for one bus or --level drift (a fleet of fixed level "
                        "keeps no rows to visit)")  # fmt: skip


def fleet_sampler_defaults(values: dict[str, Any], options: dict[str, Any]) -> dict[str, Any]:
    """With ``--by``, the fleet's draws and burn-in where the user gave none.

    The ``adjust`` of ``fit zip``'s :func:`~loadbayes.commands.settings.sampler_settings`.
    """
    if not options.get("by"):
        return values
    ctx = click.get_current_context()
    draws, burn = values["draws"], values["burn"]
    src = click.core.ParameterSource.DEFAULT
    if ctx.get_parameter_source("draws") == src:
        draws = FLEET_DRAWS
    if ctx.get_parameter_source("burn") == src:
        burn = min(FLEET_BURN, draws - 1)
    return {**values, "draws": draws, "burn": burn}


def run_fleet_command(params: dict[str, Any], sampler: SamplerSettings) -> None:
    """Run the fleet fit from the parsed options of ``fit zip`` (a dict by option name).

    ``sampler`` holds the fleet's defaults already (:func:`fleet_sampler_defaults`).
    """
    p = params
    _refuse_single_bus_options(p)
    if not p.get("fleet_out"):
        raise UserError("--by needs --out FILE.parquet for the fleet table")
    if not str(p["fleet_out"]).lower().endswith((".parquet", ".pq")):
        raise UserError(f"{p['fleet_out']}: --out must end in .parquet")
    if p.get("dashboard") and not p.get("workers"):
        raise UserError("--dashboard is for a local cluster: give --workers N")
    if p["pool"] == "class" and p.get("netcdf_dir"):
        raise UserError("--netcdf-dir is for --pool none (pooled draws stay together)")
    check_outputs({"--out": p["fleet_out"]}, [p["data"]], p["force"])
    if p.get("level") == "drift":  # every bus's rows, fitted one by one
        from loadbayes.commands.zip.drift_fleet import run_drift

        res = run_drift(p, sampler)
        _refuse_if_none_fitted(res.table, p["data"])
        _commit(res.table, p["fleet_out"], p["force"], _NetcdfStaging(None, False), res.settings)
        _report(res, p["fleet_out"], p["quiet"])
        return
    p0, q0 = nominal(p["p0"], "--p0"), nominal(p["q0"], "--q0")
    from loadbayes.commands.options import parse_coef_priors
    from loadbayes.fit import zip_priors
    from loadbayes.fleet.engine import Engine
    from loadbayes.fleet.hierarchical import HierPrior
    from loadbayes.fleet.partitions import ReadSpec
    from loadbayes.fleet.run import one_process_note, run_fleet

    q_name, q_required = q_column(p["q_col"])
    spec = ReadSpec(
        by=p["by"],
        class_col=p.get("class_col"),
        v_col=p["v_col"],
        p_col=p["p_col"],
        q_col=q_name,
        q_required=q_required,
        v_base=p["v_base"],
        s_base=p["s_base"],
        drop_invalid=p["drop_invalid"],
        chunk_rows=p["chunk_rows"],
        t_col=p.get("t_col"),
    )
    priors = zip_priors(
        p0=p0,
        q0=q0,
        mean=p["prior_mean"],
        sd=p["prior_sd"],
        per_coef=parse_coef_priors(p["coef_priors"]),
        shape=p["tau_shape"],
        rate=p["tau_rate"],
    )
    quiet = p["quiet"]
    files = Progress("files", None, True)  # the bar that matters is over buses
    buses: dict[str, Progress] = {}

    def bus_progress(n: int) -> None:
        if "bar" not in buses:
            files.close()
            buses["bar"] = Progress("buses", result_size["buses"], quiet, eta=True)
        buses["bar"](n)

    result_size: dict[str, int] = {}

    def file_progress(n: int) -> None:
        files(n)

    nc = _NetcdfStaging(p.get("netcdf_dir"), p["force"])

    def stats_hook(stats) -> None:
        result_size["buses"] = int(stats.buses.size)
        nc.check(stats.buses)
        if stats.n_dropped:  # as for one bus, whatever --quiet says
            click.echo(
                f"loadbayes: warning: {stats.n_dropped} rows with invalid values were "
                "dropped (--drop-invalid)",
                err=True,
            )
        if not quiet:  # the size of the work before it starts; the bar then says the time left
            click.echo(
                f"loadbayes: note: {result_size['buses']} buses x {sampler.chains} chains x "
                f"{sampler.draws} iterations (pool {p['pool']})",
                err=True,
            )

    try:
        engine_args = {"scheduler": p.get("scheduler"), "workers": p.get("workers")}
        with Engine(**engine_args, dashboard=bool(p.get("dashboard"))) as engine:
            if engine.dashboard_link:  # asked for: said whatever --quiet says
                click.echo(f"loadbayes: note: dashboard at {engine.dashboard_link}", err=True)
            res = run_fleet(
                p["data"],
                spec,
                pool=p["pool"],
                v0=p["v0"],
                p0=p0,
                q0=q0,
                priors=priors,
                hyper=HierPrior(tau_shape=p["tau_shape"], tau_rate=p["tau_rate"]),
                sampler=sampler,
                engine=engine,
                netcdf_dir=nc.staging,
                force=p["force"],
                accept_units=bool(p.get("accept_units")),
                progress_files=file_progress,
                progress_buses=bus_progress,
                on_stats=stats_hook,
                max_seconds=p.get("max_seconds") if p["pool"] == "class" else None,
            )
            _refuse_if_none_fitted(res.table, p["data"])
            note = one_process_note(engine)
            if note and not quiet:
                click.echo(f"loadbayes: note: {note}", err=True)
        _commit(res.table, p["fleet_out"], p["force"], nc, res.settings)
    finally:
        files.close()
        if "bar" in buses:
            buses["bar"].close()
        nc.clean_up()
    _report(res, p["fleet_out"], quiet)


def _refuse_if_none_fitted(table, data) -> None:
    """No table when not one bus could be fitted (kV and MW without bases, say): exit 2."""
    bus_rows = table[table["level"] == "bus"]
    if len(bus_rows) and bus_rows["parameter"].isna().all():
        first = bus_rows.iloc[0]
        raise UserError(
            f"{data}: none of the {bus_rows['bus'].nunique()} buses could be fitted, "
            f"e.g. {first['bus']}: {first['warnings']}"
        )


def _commit(table, out_path: str, force: bool, nc: _NetcdfStaging, settings=None) -> None:
    """The fleet table and the per-bus NetCDF files, renamed into place together."""
    from loadbayes.commands.signals import _STOP, stop_if_signalled
    from loadbayes.fleet.summary import write_parquet
    from loadbayes.io.atomic import held_signals
    from loadbayes.io.transaction import OutputSet

    stop_if_signalled()
    with OutputSet({"--out": out_path}, force=force) as out:
        _STOP["outputs"] = out
        write_parquet(table, out.temp("--out"), atomic=False, settings=settings)
        stop_if_signalled()
        moves = nc.moves()
        with held_signals():
            out.commit()
            for staged, target in moves:
                os.replace(staged, target)
            _STOP["committed"] = True


class _NetcdfStaging:
    """``--netcdf-dir`` as part of the run's transaction: every file, or none.

    The fits write into a hidden folder inside DIR (the same file system, so the final
    renames are atomic); the files are renamed into DIR with the fleet table at the
    end. An error or a signal removes the hidden folder, and DIR itself if this run
    created it, so nothing is left half-done.
    """

    def __init__(self, folder: str | None, force: bool) -> None:
        self.folder = Path(folder) if folder else None
        self.force = force
        self.staging: str | None = None
        self.created = False
        self.buses = None
        if self.folder is None:
            return
        import tempfile

        from loadbayes.io.atomic import held_signals

        if self.folder.exists() and not self.folder.is_dir():
            raise UserError(f"{folder}: --netcdf-dir is not a folder")
        with held_signals():
            self.created = not self.folder.exists()
            try:
                self.folder.mkdir(parents=True, exist_ok=True)
                self.staging = tempfile.mkdtemp(
                    dir=self.folder, prefix=".loadbayes-", suffix=".tmp"
                )
            except OSError as exc:
                raise UserError(
                    f"{folder}: --netcdf-dir cannot be written ({exc.strerror})"
                ) from None

    def check(self, buses) -> None:
        """Before the fits: every id a safe file name, no file in the way without --force."""
        if self.folder is None:
            return
        from loadbayes.fleet.perbus import check_netcdf_targets

        check_netcdf_targets(buses, self.folder, force=self.force)
        self.buses = buses

    def moves(self) -> list[tuple[Path, Path]]:
        """(staged file, target) for every bus written; targets checked again."""
        if self.folder is None or self.staging is None:
            return []
        from loadbayes.fleet.perbus import check_netcdf_targets

        staged = {f.name: f for f in Path(self.staging).iterdir()}
        buses = self.buses if self.buses is not None else []
        targets = check_netcdf_targets(buses, self.folder, force=self.force)
        return [(staged[t.name], t) for t in targets if t.name in staged]

    def clean_up(self) -> None:
        """Remove the hidden folder (empty after a commit), and DIR if created and empty."""
        if self.staging is None:
            return
        import shutil

        from loadbayes.io.atomic import held_signals

        with held_signals():
            shutil.rmtree(self.staging, ignore_errors=True)
            self.staging = None
            if self.created:
                with contextlib.suppress(OSError):
                    self.folder.rmdir()  # only if empty: nothing was committed


def _report(res, out: str, quiet: bool) -> None:
    t = res.table
    bus_rows = t[t["level"] == "bus"]
    failed = bus_rows[bus_rows["parameter"].isna()]
    warned = bus_rows[(bus_rows["warnings"] != "") & bus_rows["parameter"].notna()]
    n_bus = bus_rows["bus"].nunique()
    if len(failed):
        click.echo(
            f"loadbayes: warning: {len(failed)} of {n_bus} buses not fitted "
            f"(see the 'warnings' column), e.g. {failed['bus'].iloc[0]}: "
            f"{failed['warnings'].iloc[0]}",
            err=True,
        )
    # convergence, in words, whatever --quiet says: a result not to be trusted yet
    for line in res.settings.get("warnings", []):
        click.echo(f"loadbayes: warning: {line}", err=True)
    if quiet:
        return
    stop = res.settings.get("stop")
    if stop and res.settings.get("pool") == "class":
        click.echo(f"loadbayes: note: chains {stop}", err=True)
    click.echo(
        f"{n_bus} buses from {res.files} files ({res.engine}); "
        f"{n_bus - len(failed)} fitted, {warned['bus'].nunique()} with warnings -> {out}"
    )
    cls = t[t["level"] == "class"]
    if len(cls):
        hp = res.settings.get("hdi_prob", 0.95)
        click.echo(f"class means and spreads (mean [{100 * hp:.0f}% interval], R-hat):")
        for name, rows in cls.groupby("class", sort=True):
            click.echo(f"  {name} ({int(rows['n'].iloc[0])} buses)")
            for _, r in rows.iterrows():
                flag = "" if r["converged"] else "  not converged"
                click.echo(
                    f"    {r['parameter']:<6} {r['mean']:7.3f} [{r['hdi_low']:7.3f}, "
                    f"{r['hdi_high']:7.3f}]  R-hat {r['r_hat']:.3f}{flag}"
                )
