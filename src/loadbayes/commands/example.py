"""``loadbayes example``: write the example inputs the README's usage lines read."""

from __future__ import annotations

from pathlib import Path

import click

from loadbayes.commands.options import OneLineCommand

#: One-file kinds, printed to stdout (or written to --out FILE).
FILES = ("zip", "day", "cvr")
#: Folder kinds (loadbayes.cases.examples.KINDS), written into --out DIR.
FOLDERS = ("composite", "fleet", "comtrade", "pmu", "archive")


def _text(name: str) -> str:
    if name == "zip":  # shipped (cases.examples.zip_day_frame): its numbers are quoted
        from importlib.resources import files

        return files("loadbayes").joinpath("data", "zip_example.csv").read_text(encoding="utf-8")
    if name == "cvr":
        from loadbayes.cases.cvr_example import cvr_frame

        return cvr_frame().to_csv(index=False, lineterminator="\n")
    from loadbayes.cases.examples import day_frame

    return day_frame().to_csv(index=False)


def _write_folder(folder: Path, contents: dict, force: bool) -> list[Path]:
    """Write every file into ``folder`` or none (an existing file needs ``force``)."""
    from loadbayes.commands.output import UserError
    from loadbayes.io.errors import DataError
    from loadbayes.io.transaction import OutputSet

    if folder.exists() and not folder.is_dir():
        raise UserError(f"{folder}: exists and is not a folder")
    if not force:
        for name in contents:
            if (folder / name).exists():
                raise UserError(f"{folder / name}: exists; use --force to overwrite")
    created = not folder.exists()
    try:
        folder.mkdir(parents=True, exist_ok=True)
        with OutputSet({name: folder / name for name in contents}, force=force) as out:
            for name, content in contents.items():
                if isinstance(content, bytes):
                    out.temp(name).write_bytes(content)
                else:
                    out.temp(name).write_text(content, encoding="utf-8")
            return out.commit()
    except DataError as err:
        raise UserError(str(err)) from None
    except OSError as err:
        raise UserError(f"{folder}: {err.strerror}") from None
    finally:
        if created and folder.is_dir() and not any(folder.iterdir()):
            folder.rmdir()


@click.command("example", cls=OneLineCommand)
@click.argument("name", type=click.Choice(FILES + FOLDERS))
@click.argument("folder", required=False, type=click.Path(path_type=Path))
@click.option(
    "--out",
    type=click.Path(dir_okay=True, path_type=Path),
    help="zip, day, cvr: a file instead of stdout. composite, fleet, comtrade, pmu, archive: "
    "the folder to write into (required; created if missing).",
)
@click.option(
    "--records",
    type=click.IntRange(min=1),
    default=50,
    show_default=True,
    help="archive: records per station (each bay has one per record).",
)
@click.option(
    "--bays",
    type=click.IntRange(1, 2),
    default=2,
    show_default=True,
    help="archive: bays per station (1: the transformer alone).",
)
@click.option("--force", is_flag=True, help="Overwrite existing files.")
def example_cmd(name, folder, out, records, bays, force):
    """Write an example input, e.g. loadbayes example zip > bus.csv.

    Each is simulated with a known answer, in the units real data come in (the bus is
    11 kV, 5 MVA: fit with --v-base 11 --s-base 5 where the columns are kV and MW).

    \b
    zip        a SCADA day at an 11 kV bus: time, V (kV), P (MW), Q (Mvar) each
               minute; a daily load profile (3.2-6.8 MW), tap steps, a CVR window,
               an hour missing; ZIP a1..a3 = 0.30, 0.25, 0.45, a4..a6 = 0.60, 0.10,
               0.30, dP/dV = 0.85 (loadbayes fit zip bus.csv --v-base 11 --s-base 5
               --t-col time --level drift)
    day        a day whose ZIP shares drift and jump, with the true shares as
               a1_true.. columns (loadbayes track zip)
    cvr        a 90-day CVR on/off test at a 12.47 kV feeder head every 5 minutes:
               thermostatic heaters, PV, weather, glitches; energy CVR factor 0.66,
               dP/dV 1.16 over the dark hours (loadbayes cvr feeder.csv --v-col v_kv
               --p-col p_mw --q-col q_mvar --v-base 12.47 --s-base 10 --weather-col
               temp_c --holiday-col holiday --pv-col irradiance)
    composite  sag1.csv, sag2.csv: two sags at a ZIP + induction-motor load, motor
               share f_m = 0.5, point samples (loadbayes fit composite --window-s 0)
    fleet      part-*.parquet: 24 buses in three customer classes, per unit
               (loadbayes fit zip DIR --by bus_id --class-col customer_class)
    comtrade   event.cfg, event.dat: 8 s of 50 Hz waveforms with two sags
               (loadbayes read comtrade, then loadbayes events)
    pmu        historian.csv and its map.toml: 2 minutes of 30 frame/s phasors with
               one sag (loadbayes read pmu --map)
    archive    a year of COMTRADE records at 3 stations x 2 bays, the motor share
               seasonal, two files broken, truth.csv beside (loadbayes archive scan
               DIR --catalog archive.db); --records N per station (50, about half a
               minute to write), --bays 1 the transformer alone

    The folder may be given as the second argument instead of --out.
    """  # noqa: D301 (click's \b keeps the table's line breaks)
    from loadbayes.commands.output import UserError

    if name != "archive" and (records != 50 or bays != 2):
        raise UserError(f"--records and --bays are for the archive example, not {name}")
    if folder is not None:
        if out is not None:
            raise UserError(f"give the folder once: {folder} or --out {out}")
        out = folder
    if name in FILES:
        text = _text(name)
        if out is None:
            click.echo(text, nl=False)
            return
        from loadbayes.io.atomic import atomic_write
        from loadbayes.io.errors import DataError

        try:
            with atomic_write(out, force=force, mode="w") as fh:
                fh.write(text)
        except DataError as err:
            raise UserError(str(err)) from None
        click.echo(f"loadbayes: wrote {out}", err=True)
        return
    if out is None:
        raise UserError(f"example {name} writes several files: give the folder with --out DIR")
    if name == "archive":
        from loadbayes.cases.archive_example import archive_files

        written = _write_folder(out, archive_files(records=records, bays=bays), force)
        click.echo(f"loadbayes: wrote {len(written)} files into {out} (truth.csv: the motor "
                   "shares)", err=True)  # fmt: skip
        return
    from loadbayes.cases.examples import KINDS

    written = _write_folder(out, KINDS[name](), force)
    click.echo(f"loadbayes: wrote {', '.join(str(p) for p in written)}", err=True)
