"""``loadbayes simulate andes``: an event simulated by ANDES, ready for ``fit composite``."""

from __future__ import annotations

from pathlib import Path

import click

from loadbayes.commands.options import MOTOR_NAMES, OneLineCommand
from loadbayes.commands.output import UserError, check_outputs, user_errors

#: What a PMU at the load bus records: the angle too, so that a fit sees the phase jumps
#: of the fault (a frequency column cannot hold them; fit/composite/checks.py).
COLUMNS = ("t_s", "v", "angle_rad", "p", "q", "f")


def _triple(text: str, name: str) -> tuple[float, float, float]:
    try:
        parts = tuple(float(x) for x in text.split(","))
    except ValueError:
        raise UserError(f"{name}: expected three numbers 'Z,I,P', got {text!r}") from None
    if len(parts) != 3 or abs(sum(parts) - 1.0) > 1e-6:
        raise UserError(f"{name}: expected three shares 'Z,I,P' summing to 1, got {text!r}")
    return parts  # type: ignore[return-value]


def _in_case(case_file: str, bus: str, motor: str, q_c: float, common: dict):
    if q_c:
        raise UserError("--q-c is not supported with --case")
    import andes

    from loadbayes.cases.andes.grid import simulate_in_case

    path = Path(case_file)
    if not path.is_file():
        try:
            path = Path(andes.get_case(case_file))
        except FileNotFoundError:
            raise UserError(f"{case_file}: no such file, nor a case shipped with ANDES") from None
    idx: int | str = int(bus) if bus.lstrip("-").isdigit() else bus
    try:
        return simulate_in_case(path, idx, motor, **common)
    except (KeyError, IndexError):
        raise UserError(f"{case_file}: no bus with idx {bus!r}") from None


@click.command("andes", cls=OneLineCommand)
@click.option("--out", required=True, type=click.Path(dir_okay=False), help="Event CSV.")
@click.option(
    "--motor",
    type=click.Choice(MOTOR_NAMES),
    default="small_industrial",
    show_default=True,
    help="A documented motor (docs/motor.md).",
)
@click.option("--sag-depth", type=float, default=0.3, show_default=True, help="Sag depth.")
@click.option("--f-m", type=float, default=0.4, show_default=True, help="Motor share of P0.")
@click.option("--t0", type=float, default=0.6, show_default=True, help="Motor load torque.")
@click.option("--p0", type=float, default=1.0, show_default=True, help="Load P at v0 (p.u.).")
@click.option("--q0", type=float, default=0.3, show_default=True, help="Load Q at v0 (p.u.).")
@click.option("--zip-p", default="0.4,0.3,0.3", show_default=True, help="Static P shares Z,I,P.")
@click.option("--zip-q", default="0.5,0.3,0.2", show_default=True, help="Static Q shares Z,I,P.")
@click.option("--q-c", type=float, default=0.0, show_default=True, help="Shunt Q at v0 (p.u.).")
@click.option("--fault-start", type=float, default=0.5, show_default=True, help="Fault time (s).")
@click.option("--fault-duration", type=float, default=0.1, show_default=True, help="Fault (s).")
@click.option("--t-end", type=float, default=3.0, show_default=True, help="Record length (s).")
@click.option("--rate", type=float, default=120.0, show_default=True, help="Samples per second.")
@click.option(
    "--noise",
    type=click.FloatRange(min=0),
    default=0.0,
    show_default=True,
    help="Gaussian noise sd on p and q, as a fraction of each channel's RMS.",
)
@click.option("--seed", type=int, default=0, show_default=True, help="Seed of the noise.")
@click.option(
    "--case",
    "case_file",
    help="An ANDES case file (or a name for andes.get_case, e.g. kundur/kundur_full.xlsx) "
    "to put the load in, instead of the built-in infinite-bus case.",
)
@click.option("--bus", help="With --case: the idx of the bus that gets the load and the fault.")
@click.option("--force", is_flag=True, help="Overwrite existing outputs.")
@user_errors
def simulate_andes_cmd(
    out, motor, sag_depth, f_m, t0, p0, q0, zip_p, zip_q, q_c, fault_start, fault_duration,
    t_end, rate, noise, seed, case_file, bus, force,
) -> None:  # fmt: skip
    """Simulate a ZIP + induction-motor load through a fault in ANDES (independent simulator).

    Writes OUT with columns t_s, v, angle_rad, p, q, f (system p.u., rad, Hz) for ``loadbayes fit
    composite``, and a JSON sidecar (OUT with .json) with the truth in the composite
    naming contract (docs/andes.md). Needs the optional 'andes' extra.
    """
    import json

    import numpy as np

    from loadbayes.io.atomic import atomic_write

    out_path = Path(out)
    sidecar = out_path.with_suffix(".json")
    if sidecar == out_path:
        raise UserError(f"{out}: the event file needs a suffix other than .json (e.g. .csv)")
    check_outputs({"--out": out, "sidecar": str(sidecar)}, [], force)
    if not rate > 0:
        raise UserError(f"--rate must be > 0, got {rate}")
    shares_p, shares_q = _triple(zip_p, "--zip-p"), _triple(zip_q, "--zip-q")
    if not 0 < f_m <= 1:
        raise UserError(f"--f-m must be in (0, 1] (0 < f_m <= 1), got {f_m}")
    if (case_file is None) != (bus is None):
        raise UserError("--bus needs --case" if case_file is None else "--case needs --bus")
    import importlib.util

    if importlib.util.find_spec("andes") is None:
        raise UserError("ANDES is not installed; install the 'andes' extra (pip install andes)")
    from loadbayes.cases.andes import sim as andes_sim
    from loadbayes.models.motor_library import MOTORS

    step = min(andes_sim.default_step(MOTORS[motor]), 1.0 / rate)
    common = {
        "f_m": f_m, "p0": p0, "q0": q0, "zip_p": shares_p, "zip_q": shares_q, "t0": t0,
        "sag_depth": sag_depth, "fault_start_s": fault_start, "fault_s": fault_duration,
        "t_end_s": t_end, "step_s": step,
    }  # fmt: skip
    try:
        if case_file is None:
            event = andes_sim.simulate(motor, q_c=q_c, **common)
        else:
            event = _in_case(case_file, bus, motor, q_c, common)
    except RuntimeError as exc:
        raise UserError(f"ANDES failed: {exc}") from None
    table = event.resample(rate)[list(COLUMNS)]
    rng = np.random.default_rng(seed)
    sds = {}
    for col in ("p", "q"):
        sds[col] = noise * float(np.sqrt(np.mean(table[col].to_numpy() ** 2)))
        table[col] = table[col] + sds[col] * rng.standard_normal(len(table))
    meta = {
        "model": "composite",
        "simulator": event.settings["simulator"],
        "truth": event.truth,
        "settings": event.settings,
        "columns": {
            "t_s": "s",
            "v": "p.u.",
            "angle_rad": "rad",
            "p": "p.u. system",
            "q": "p.u. system",
            "f": "Hz",
        },
        "rate_hz": rate,
        "noise": {"fraction_of_rms": noise, "sd": sds, "seed": seed, "on": ["p", "q"]},
    }
    with atomic_write(out_path, force=force, mode="w") as fh:
        table.to_csv(fh, index=False)
    with atomic_write(sidecar, force=force, mode="w") as fh:
        json.dump(meta, fh, indent=2, sort_keys=True)
    s = event.settings
    click.echo(
        f"wrote {out} ({len(table)} samples, sag {s['sag_depth']:.3f}, f_m "
        f"{event.truth['f_m']:.3f}) and {sidecar}",
        err=True,
    )
