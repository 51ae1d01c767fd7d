"""``loadbayes simulate im``: a motor driven by a voltage disturbance, written as CSV."""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import click

from loadbayes.commands.options import MOTOR_NAMES, OneLineCommand
from loadbayes.commands.output import UserError, check_outputs, sidecar, user_errors

DISTURBANCES = ("sag", "ramp", "walk", "file")
_PARAM_FIELDS = {"rs", "xs", "xm", "rr", "xr", "h_s", "a", "b", "c", "name", "f_hz"}
_PARAM_REQUIRED = ("rs", "xs", "xm", "rr", "xr", "h_s")


def _load_params(path: str):
    from loadbayes.models.motor import MotorParams

    try:
        raw = json.loads(Path(path).read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError) as exc:
        raise UserError(f"{path}: cannot read: {exc}") from None
    except json.JSONDecodeError as exc:
        raise UserError(f"{path}: not JSON: {exc.msg} (line {exc.lineno})") from None
    if not isinstance(raw, dict):
        raise UserError(f"{path}: expected a JSON object of motor parameters")
    unknown = set(raw) - _PARAM_FIELDS
    if unknown:
        raise UserError(
            f"{path}: unknown field(s) {', '.join(sorted(unknown))}; expected "
            f"{', '.join(sorted(_PARAM_FIELDS))}"
        )
    missing = [k for k in _PARAM_REQUIRED if k not in raw]
    if missing:
        raise UserError(f"{path}: missing field(s) {', '.join(missing)}")
    for k, v in raw.items():
        if k != "name" and (isinstance(v, bool) or not isinstance(v, (int, float))):
            raise UserError(f"{path}: field {k!r} must be a number, got {v!r}")
    try:
        return MotorParams(**{"name": Path(path).stem, **raw})
    except ValueError as exc:
        raise UserError(f"{path}: {exc}") from None


def _disturbance(kind: str, *, start: float | None, duration: float | None, **o):
    """Build the voltage profile from the command's options (defaults per kind)."""
    from loadbayes.cases import motor_sim

    if kind == "sag":
        return motor_sim.sag(
            o["depth"],
            0.5 if start is None else start,
            0.15 if duration is None else duration,
            o["recovery"],
            v0_pu=o["v0"],
        )
    if kind == "ramp":
        return motor_sim.ramp(
            o["v_end"],
            0.5 if start is None else start,
            1.0 if duration is None else duration,
            v0_pu=o["v0"],
        )
    if kind == "walk":
        return motor_sim.random_walk(
            o["walk_sd"],
            o["walk_seed"],
            step_s=o["walk_step"],
            t_end_s=o["t_end"],
            start_s=0.5 if start is None else start,
            v0_pu=o["v0"],
        )
    from loadbayes.io.tables import read_columns

    path = o["voltage_file"]
    data, _ = read_columns(path, ["t_s", "v_pu"], positive=["v_pu"])
    if data["t_s"].size < 2:
        raise UserError(f"{path}: need at least two rows (t_s, v_pu)")
    try:
        return motor_sim.from_file(path)
    except ValueError as exc:
        raise UserError(f"{path}: {exc}") from None


@click.command("im", cls=OneLineCommand)
@click.option("--out", required=True, type=click.Path(dir_okay=False), help="Output CSV.")
@click.option(
    "--motor",
    type=click.Choice(MOTOR_NAMES),
    help="A documented motor (docs/motor.md) [default: small_industrial].",
)
@click.option(
    "--params",
    "params_file",
    type=click.Path(exists=True, dir_okay=False),
    help="Motor parameters as JSON: rs, xs, xm, rr, xr, h_s (p.u., s); a, b, c, f_hz optional.",
)
@click.option(
    "--disturbance",
    type=click.Choice(DISTURBANCES),
    default="sag",
    show_default=True,
    help="Terminal-voltage disturbance.",
)
@click.option("--depth", type=float, default=0.25, show_default=True, help="Sag depth (fraction).")
@click.option("--start", type=float, help="Start of sag/ramp/walk in s [0.5].")
@click.option("--duration", type=float, help="Sag [0.15] or ramp [1.0] duration in s.")
@click.option("--recovery", type=float, default=0.0, show_default=True, help="Sag recovery (s).")
@click.option("--v-end", type=float, default=0.9, show_default=True, help="Ramp end voltage.")
@click.option("--v0", type=float, default=1.0, show_default=True, help="Pre-disturbance voltage.")
@click.option("--walk-sd", type=float, default=0.05, show_default=True, help="Walk p.u./sqrt(s).")
@click.option("--walk-step", type=float, default=0.01, show_default=True, help="Walk knots (s).")
@click.option("--walk-seed", type=int, help="Seed of the walk [--seed].")
@click.option(
    "--voltage-file",
    type=click.Path(exists=True, dir_okay=False),
    help="CSV with t_s, v_pu (for --disturbance file).",
)
@click.option("--t-end", type=float, default=3.0, show_default=True, help="Record length (s).")
@click.option("--dt", type=float, default=0.001, show_default=True, help="Sample spacing (s).")
@click.option(
    "--noise",
    type=click.FloatRange(min=0),
    default=0.05,
    show_default=True,
    help="Noise sd as a fraction of each channel's RMS (the paper's 5%).",
)
@click.option(
    "--noise-on-regressors",
    is_flag=True,
    help="Also put noise on ed, eq, w, ud, uq (the paper puts it on the targets only).",
)
@click.option("--t0", type=float, help="Load torque T0 (p.u.) [0.6 unless --slip/--p-pu].")
@click.option("--slip", type=float, help="Initial slip instead of T0.")
@click.option("--p-pu", type=float, help="Initial active power instead of T0.")
@click.option("--f-hz", type=float, help="Override the motor's nominal frequency.")
@click.option("--seed", type=int, default=0, show_default=True)
@click.option("--quiet", is_flag=True, help="Print nothing on success.")
@click.option("--force", is_flag=True, help="Overwrite existing outputs.")
@user_errors
def simulate_im_cmd(
    out,
    motor,
    params_file,
    disturbance,
    depth,
    start,
    duration,
    recovery,
    v_end,
    v0,
    walk_sd,
    walk_step,
    walk_seed,
    voltage_file,
    t_end,
    dt,
    noise,
    noise_on_regressors,
    t0,
    slip,
    p_pu,
    f_hz,
    seed,
    quiet,
    force,
):
    """Simulate a third-order induction motor through a voltage disturbance (CSV + JSON)."""
    if motor and params_file:
        raise UserError("give --motor or --params, not both")
    if not out.lower().endswith(".csv"):
        raise UserError(f"{out}: --out must end in .csv (the settings go to a .json beside it)")
    if disturbance == "file" and not voltage_file:
        raise UserError("--disturbance file needs --voltage-file")
    if voltage_file and disturbance != "file":
        raise UserError("--voltage-file needs --disturbance file")
    if sum(x is not None for x in (t0, slip, p_pu)) > 1:
        raise UserError("give at most one of --t0, --slip, --p-pu")
    if not (t_end > 0 and dt > 0 and dt <= t_end):
        raise UserError("need --t-end > 0 and 0 < --dt <= --t-end")
    if t_end / dt > 5e7:
        raise UserError(f"--t-end / --dt gives {t_end / dt:.3g} samples; at most 5e7")
    inputs = [p for p in (params_file, voltage_file) if p]
    check_outputs({"--out": out, "--out (settings)": str(sidecar(out))}, inputs, force)

    from loadbayes.cases import motor_sim
    from loadbayes.models.motor_library import MOTORS

    params = _load_params(params_file) if params_file else MOTORS[motor or MOTOR_NAMES[0]]
    dist = _disturbance(
        disturbance,
        depth=depth,
        start=start,
        duration=duration,
        recovery=recovery,
        v_end=v_end,
        v0=v0,
        walk_sd=walk_sd,
        walk_step=walk_step,
        walk_seed=seed if walk_seed is None else walk_seed,
        voltage_file=voltage_file,
        t_end=t_end,
    )
    from loadbayes.models.motor import steady_state

    # The loading is checked before any message, so that a bad one is a one-line error.
    loading = {k: v for k, v in {"t0": t0, "slip": slip, "p_pu": p_pu}.items() if v is not None}
    steady_state(
        params if f_hz is None else replace(params, f_hz=f_hz),
        v_pu=float(dist(0.0)),
        **(loading or {"t0": motor_sim.DEFAULT_T0}),
    )
    if not quiet and t_end / dt > 1e5:
        click.echo(f"simulating {params.name or 'motor'} for {t_end:g} s ...", err=True)
    df = motor_sim.simulate(
        params,
        disturbance=dist,
        t_end_s=t_end,
        dt_s=dt,
        f_nominal_hz=f_hz,
        t0=t0,
        slip=slip,
        p_pu=p_pu,
        noise=noise,
        noise_on_regressors=noise_on_regressors,
        seed=seed,
    )
    csv_path, json_path = motor_sim.write_csv(df, out)
    if not quiet:
        a = df.attrs
        op = a["steady_state"]
        click.echo(f"{csv_path}: {len(df)} samples, {a['motor']['name']}, {dist.info['kind']}")
        click.echo(
            f"steady state: T0 = {a['t0']:.6g}, slip = {op['slip']:.5g}, "
            f"P = {op['p']:.4g}, Q = {op['q']:.4g} p.u."
        )
        coefs = ", ".join(f"{k} = {v:.6g}" for k, v in a["coefficients"].items())
        click.echo(f"true coefficients: {coefs}")
        click.echo(f"settings: {json_path}")
