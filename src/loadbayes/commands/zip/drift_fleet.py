"""``fit zip DATA --level drift --by BUS --out fleet.parquet``: the options into the library call.

The fleet's engine (in process, ``--workers N``, ``--scheduler ADDRESS``), a progress bar
over buses, and :func:`loadbayes.fleet.drift.fit_drift_fleet`; :mod:`.fleet` checks the
outputs first and writes and reports the table after, as for the static fleet.
"""

from __future__ import annotations

from typing import Any

import click

from loadbayes.commands.output import Progress, UserError

__all__ = ["run_drift"]


def run_drift(p: dict[str, Any], sampler) -> Any:
    """The drifting-level fleet of the parsed options ``p`` (``fit zip``'s, by name)."""
    from loadbayes.commands.options import q_column
    from loadbayes.commands.settings import fit_spec
    from loadbayes.fleet.drift import fit_drift_fleet
    from loadbayes.fleet.engine import Engine

    if not p.get("t_col"):
        raise UserError("--level drift needs the time of each sample: give --t-col")
    if p.get("netcdf_dir"):
        raise UserError("--netcdf-dir is for the static fleet; a drifting fleet writes --out")
    v_noise = None
    if p.get("v_noise") is not None:
        from loadbayes.fit.eiv import check_v_noise
        from loadbayes.io.errors import OptionError

        try:
            v_noise = check_v_noise(p["v_noise"])
        except OptionError as exc:
            raise UserError(str(exc).replace("v_noise must be", "--v-noise must be")) from None
        if v_noise == "auto":
            raise UserError("--level drift takes the instrument's sd (--v-noise 0.0005), not auto")
    q_name, _ = q_column(p["q_col"])
    spec = fit_spec(v_col=p["v_col"], p_col=p["p_col"], q_col=q_name, t_col=p["t_col"],
                    v0=p["v0"], v_base=p["v_base"], s_base=p["s_base"],
                    drop_invalid=p["drop_invalid"],
                    accept_units=bool(p.get("accept_units")))  # fmt: skip
    quiet = p["quiet"]
    bar: dict[str, Progress] = {}

    def on_buses(n_bus: int) -> None:  # the size of the work before it starts
        if not quiet:
            click.echo(f"loadbayes: note: {n_bus} buses x {sampler.chains} chains x "
                       f"{sampler.draws} iterations (level drift, pool {p['pool']})",
                       err=True)  # fmt: skip
        bar["b"] = Progress("buses", n_bus, quiet, eta=True)

    try:
        with Engine(scheduler=p.get("scheduler"), workers=p.get("workers"),
                    dashboard=bool(p.get("dashboard"))) as engine:  # fmt: skip
            if engine.dashboard_link:
                click.echo(f"loadbayes: note: dashboard at {engine.dashboard_link}", err=True)
            return fit_drift_fleet(p["data"], by=p["by"], class_col=p.get("class_col"),
                                   spec=spec, sampler=sampler, pool=p["pool"], engine=engine,
                                   hdi_prob=sampler.hdi_prob, v_noise=v_noise,
                                   progress=lambda n: bar["b"](n), on_buses=on_buses)  # fmt: skip
    finally:
        if "b" in bar:
            bar["b"].close()
