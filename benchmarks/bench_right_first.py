"""Issue 35's "right first", before and after: each case rebuilt and fitted at the defaults.

Usage::

    python benchmarks/bench_right_first.py [--quick] [--output PATH] [--fan-dir DIR]
        [--record CFG] [--reference-iterations 64000] [--keep DIR]

Each case under the issue's "Why: right first" is rebuilt from the repository's own
generators (none of them loadbayes's model code: SciPy in tests/, ANDES 2.0) and fitted as
a user fits it, ``loadbayes fit composite FILES --json OUT`` in a fresh process with no
other option, so the sample reading (points or window means) is the run's own choice and
the run says which and why. Printed per case and quantity: the truth, the 95% interval
the issue stated (:data:`BEFORE`), the interval now, whether it covers, the R-hat, the
process's wall and CPU seconds, and the reading. The cases:

- ``fan``: the large fan motor, two sags (30% for 0.2 s, 45% for 0.12 s, 20 ms ramps,
  point samples at 60/s, 0.5% noise), fitted jointly; the SciPy generator and call of
  tests/statistical/test_composite_fan.py (P and Q on one base). The finding's own CSVs
  (P/P0, Q/Q0 with Q0 = 0.72 P0) are fitted too when ``--fan-dir`` or
  ``$LOADBAYES_FAN_FINDING`` names their folder (with its ``truth.json``);
- ``andes_ieee14``: ANDES's IEEE 14-bus case, a ZIP + Motor3 (small_industrial, T'
  0.498 s, f_m 0.4) on bus 9 through three faults there (10, 25, 40% dips), resampled at
  60/s with 0.5% noise, fitted jointly (``loadbayes.cases.andes.grid``);
- ``recorder_chain``: tests/recorder_chain.py's 13.8 kV feeder event written as
  COMTRADE, then ``read comtrade`` -> ``events`` -> ``fit composite``;
- ``andes_motor5``: a ZIP + Motor5 (ANDES's double cage, the calibration study's second
  cage) through a 46% five-cycle fault starting between samples, point samples at 60/s,
  0.5% noise on P and Q, 0.05% on V (the newcomer's event, rebuilt with the
  repository's ANDES generator: its built-in one-bus case, not the IEEE 14-bus case);
- ``real``: the real record's first fault (``$LOADBAYES_REAL_RECORD`` or
  ``shared/real/xtz.cfg`` above; ``--record``), read at 4 phasors per cycle at bay
  1号主变, fitted at the defaults and by a long reference (4 chains x
  ``--reference-iterations``, 4,000 burn-in, seed 100, as docs/composite.md's); both
  intervals of f_m, T', H and the static shares, and a two-sample KS p-value per
  marginal with each side's bulk ESS as its sample size.

``--quick``: the fan's first sag alone, pinned to 2 x 1,500 iterations (a smoke run; not
the defaults). Writes ``benchmarks/results/right_first.json``. Wall times on a shared
machine measure the other users too: the load average is recorded.
"""

from __future__ import annotations

import argparse
import datetime
import json
import math
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent / "tests"))

#: The intervals issue 35 states under "Why: right first" (95%, at the defaults of the
#: week it was filed); None where it gives no number.
BEFORE = {
    ("fan", "f_m"): (0.315, 0.371),
    ("fan", "t_prime_s"): None,
    # The fan numbers came from the finding's own files, the case ``fan_finding``.
    ("fan_finding", "f_m"): (0.315, 0.371),
    ("fan_finding", "t_prime_s"): None,
    ("andes_ieee14", "f_m"): None,  # "f_m and the ZIP shares are covered"
    ("andes_ieee14", "t_prime_s"): (1.81, 7.96),
    ("recorder_chain", "f_m"): (0.387, 0.420),
    ("recorder_chain", "t_prime_s"): (0.104, 0.117),
    ("andes_motor5", "f_m"): (0.359, 0.395),
    ("andes_motor5", "t_prime_s"): None,
}
QUANTITIES = ("f_m", "t_prime_s")
#: The issue says the ANDES case's ZIP shares were covered: its P shares are shown too (its
#: Q shares are not comparable: the ANDES case has no shunt, loadbayes sizes one).
SHOWN = {"andes_ieee14": (*QUANTITIES, "a1", "a2", "a3")}
REAL_QUANTITIES = ("f_m", "t_prime_s", "h_s", "a1", "a2", "a3", "a4", "a5", "a6")
FAN_SAGS = ((0.30, 0.20), (0.45, 0.12))
CAGE2 = (0.18, 0.10)  # loadbayes.studies.calibration.composite_generators.CAGE2


def _cpu() -> float:
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


def cli(*args, check: bool = True) -> tuple[subprocess.CompletedProcess, float, float]:
    """``loadbayes ARGS`` in a fresh process: the result, its wall and CPU seconds."""
    cpu, wall = _cpu(), time.perf_counter()
    res = subprocess.run([sys.executable, "-m", "loadbayes", *map(str, args)],
                         capture_output=True, text=True)  # fmt: skip
    wall, cpu = time.perf_counter() - wall, _cpu() - cpu
    if check and res.returncode != 0:
        raise RuntimeError(f"loadbayes {' '.join(map(str, args))}: {res.stderr[-2000:]}")
    return res, wall, cpu


def fit(files: list, out: Path, *extra) -> dict:
    """``loadbayes fit composite FILES --json OUT [EXTRA]``: its JSON, output and times."""
    res, wall, cpu = cli("fit", "composite", *files, "--json", out, *extra)
    return {"json": json.loads(out.read_text()), "output": res.stdout + res.stderr,
            "wall_s": wall, "cpu_s": cpu}  # fmt: skip


# -- the cases -------------------------------------------------------------------------


def fan_events(folder: Path, quick: bool = False) -> tuple[list[Path], dict]:
    from independent_composite import Motor, Sag, simulate_event

    fan = Motor(rs=0.013, xs=0.067, xm=3.8, rr=0.009, xr=0.17, h_s=1.5, name="fan")
    files, truth = [], {}
    for k, (depth, duration) in enumerate(FAN_SAGS[:1] if quick else FAN_SAGS):
        df, truth = simulate_event(motor=fan, t0=0.7, f_m=0.4, q0=0.3,
                                   shares=(0.3, 0.2, 0.5, 0.4, 0.3, 0.3),
                                   sags=(Sag(1.0, depth, duration, 0.02, 0.02),), rate_hz=60.0,
                                   noise=0.005, seed=k, t_end_s=2.5)  # fmt: skip
        files.append(folder / f"fan_sag{k + 1}.csv")
        df.to_csv(files[-1], index=False)
    return files, truth


def fan_finding(folder: Path | None) -> tuple[list[Path], dict] | None:
    if folder is None or not (folder / "truth.json").is_file():
        return None
    files = sorted(folder.glob("fan_sag*.csv"))
    return (files, json.loads((folder / "truth.json").read_text())) if files else None


def _noisy(df, truth: dict, seed: int, noise_v: float = 0.0):
    rng = np.random.default_rng(seed)
    sd = 0.005 * math.hypot(truth["p0"], truth["q0"])
    df = df.copy()
    df["p"] += rng.normal(0.0, sd, len(df))
    df["q"] += rng.normal(0.0, sd, len(df))
    if noise_v:
        df["v"] += rng.normal(0.0, noise_v * float(df["v"].iloc[0]), len(df))
    return df


def andes_ieee14_events(folder: Path) -> tuple[list[Path], dict]:
    import andes

    from loadbayes.cases.andes.grid import simulate_in_case

    case = andes.get_case("ieee14/ieee14_full.xlsx")
    files, truths = [], []
    for k, depth in enumerate((0.10, 0.25, 0.40)):
        ev = simulate_in_case(case, 9, "small_industrial", f_m=0.4, sag_depth=depth)
        df = ev.resample(60.0)[["t_s", "v", "p", "q", "angle_rad"]]
        truths.append(ev.truth)
        files.append(folder / f"ieee14_dip{round(100 * depth)}.csv")
        _noisy(df, ev.truth, seed=k).to_csv(files[-1], index=False)
    return files, {**truths[0], "depths": [t.get("depth") for t in truths]}


def recorder_chain_event(folder: Path) -> tuple[list[Path], dict]:
    from recorder_chain import write_chain_event

    cfg, truth, _ = write_chain_event(folder / "chain")
    csv = folder / "chain.csv"
    cli("read", "comtrade", cfg, "--out", csv, "--v-base", 13.8, "--s-base", 10.0, "--quiet")
    cli("events", csv, "--out", folder / "chain_events", "--quiet")
    return [folder / "chain_events" / "event_001.csv"], truth


def andes_motor5_event(folder: Path) -> tuple[list[Path], dict]:
    from loadbayes.cases.andes.sim import simulate

    ev = simulate("small_industrial", f_m=0.4, zip_p=(0.5, 0.2, 0.3), zip_q=(0.6, 0.2, 0.2),
                  sag_depth=0.46, fault_start_s=1.0123, fault_s=5 / 60, t_end_s=2.5,
                  cage2=CAGE2)  # fmt: skip
    df = ev.resample(60.0)[["t_s", "v", "p", "q", "angle_rad"]]
    path = folder / "motor5_fault1.csv"
    _noisy(df, ev.truth, seed=0, noise_v=0.0005).to_csv(path, index=False)
    return [path], {**ev.truth, "depth": ev.settings["sag_depth"]}


def reading_of(fit_json: dict) -> dict:
    """How the run read the samples, and what chose it (the data, or the record's window)."""
    chosen = fit_json["settings"].get("sample_reading")
    if chosen:
        return chosen
    samples = fit_json["settings"].get("samples") or {}
    window = samples.get("window_s", 0.0)
    return {"read_as": "window means" if window else "points", "window_s": window,
            "chosen_by": "the record (events.csv names its phasor window)",
            "loglik_points_minus_window": None, "why": samples.get("read_as", "")}  # fmt: skip


def row(case: str, quantity: str, truth: float, run: dict) -> dict:
    par = run["json"]["parameters"][quantity]
    reading = reading_of(run["json"])
    lo, hi = par["hdi_low"], par["hdi_high"]
    return {
        "case": case, "quantity": quantity, "truth": truth,
        "before": BEFORE.get((case, quantity)), "now": [lo, hi], "mean": par["mean"],
        "covered": bool(lo <= truth <= hi), "r_hat": par.get("r_hat"),
        "wall_s": run["wall_s"], "cpu_s": run["cpu_s"],
        "read_as": reading["read_as"], "chosen_by": reading["chosen_by"],
        "loglik_points_minus_window": reading.get("loglik_points_minus_window"),
    }  # fmt: skip


def reading_line(run: dict) -> str:
    """The run's own sentence on its reading, or, where it printed none, its JSON's."""
    lines = [ln.strip() for ln in run["output"].splitlines() if "read as" in ln]
    if lines:
        return lines[0]
    why = reading_of(run["json"])
    return f"(no line printed; JSON: {why['why']}, chosen by {why['chosen_by']})"


# -- the real record --------------------------------------------------------------------


def real_first_fault(cfg: Path, folder: Path) -> Path:
    table = folder / "xtz.parquet"
    cli("read", "comtrade", cfg, "--bay", "1号主变", "--per-cycle", 4, "--out", table, "--quiet")
    cli("events", table, "--out", folder / "events", "--quiet")
    return folder / "events" / "event_001.csv"


def ks_compare(nc_a: Path, nc_b: Path, names) -> dict:
    """Per marginal: KS D of the two runs' draws, p with each side's bulk ESS as its size."""
    import arviz as az
    from scipy import stats

    a, b = az.from_netcdf(nc_a).posterior, az.from_netcdf(nc_b).posterior
    out = {}
    for k in names:
        if k not in a or k not in b:
            continue
        xa, xb = a[k].values.ravel(), b[k].values.ravel()
        d = stats.ks_2samp(xa, xb).statistic
        ea = float(az.ess(a, var_names=[k])[k].values)
        eb = float(az.ess(b, var_names=[k])[k].values)
        en = ea * eb / (ea + eb)
        mc = math.hypot(xa.std() / math.sqrt(ea), xb.std() / math.sqrt(eb))
        out[k] = {"ks_d": float(d), "ks_p": float(stats.kstwobign.sf(d * math.sqrt(en))),
                  "ess": [ea, eb], "z_mean": float((xa.mean() - xb.mean()) / mc)}  # fmt: skip
    return out


def real_record(cfg: Path, folder: Path, iterations: int) -> dict:
    ev = real_first_fault(cfg, folder)
    default = fit([ev], folder / "real_default.json", "--netcdf", folder / "real_default.nc")
    ref = fit([ev], folder / "real_ref.json", "--netcdf", folder / "real_ref.nc",
              "--chains", 4, "--draws", iterations, "--burn", 4000, "--fixed-draws",
              "--seed", 100, "--max-seconds", 7200, "--quiet")  # fmt: skip
    ks = ks_compare(folder / "real_default.nc", folder / "real_ref.nc", REAL_QUANTITIES)
    rows = []
    for k in REAL_QUANTITIES:
        d, r = default["json"]["parameters"].get(k), ref["json"]["parameters"].get(k)
        if d and r:
            rows.append({"quantity": k, "default": [d["mean"], d["hdi_low"], d["hdi_high"]],
                         "reference": [r["mean"], r["hdi_low"], r["hdi_high"]],
                         "r_hat": [d.get("r_hat"), r.get("r_hat")], **ks.get(k, {})})  # fmt: skip
    return {"record": cfg.name, "event": "event_001.csv (the first fault)",
            "command": "loadbayes fit composite events/event_001.csv --json fit.json",
            "default_output": default["output"], "default_wall_s": default["wall_s"],
            "default_cpu_s": default["cpu_s"], "reference_wall_s": ref["wall_s"],
            "reference_cpu_s": ref["cpu_s"], "reference_iterations": iterations,
            "rows": rows}  # fmt: skip


# -- the tables -------------------------------------------------------------------------


def _iv(x) -> str:
    return "-" if not x else f"[{x[0]:.3f}, {x[1]:.3f}]"


def print_cases(rows: list[dict]) -> None:
    print("| case | quantity | truth | before (issue) | now | covered | R-hat | wall s | CPU s "
          "| reading (log-lik points - windows) |")  # fmt: skip
    print("| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |")
    for r in rows:
        rh = "-" if r["r_hat"] is None else f"{r['r_hat']:.3f}"
        print(f"| {r['case']} | {r['quantity']} | {r['truth']:.3f} | {_iv(r['before'])} "
              f"| {_iv(r['now'])} | {'yes' if r['covered'] else '**no**'} | {rh} "
              f"| {r['wall_s']:.0f} | {r['cpu_s']:.0f} | {r['read_as']} "
              f"({r['loglik_points_minus_window']}) |")  # fmt: skip


def print_real(real: dict) -> None:
    print(
        f"\nreal record, first fault: default {real['default_wall_s']:.0f} s wall, "
        f"{real['default_cpu_s']:.0f} s CPU; reference 4 x {real['reference_iterations']:,} "
        f"{real['reference_wall_s']:.0f} s wall, {real['reference_cpu_s']:.0f} s CPU"
    )
    print("| quantity | default mean [95%] | reference mean [95%] | R-hat (default) | KS p | z |")
    print("| --- | --- | --- | --- | --- | --- |")
    for r in real["rows"]:
        d, f = r["default"], r["reference"]
        rh = "-" if r["r_hat"][0] is None else f"{r['r_hat'][0]:.3f}"
        ks = f"{r['ks_p']:.3f}" if "ks_p" in r else "-"
        z = f"{r['z_mean']:+.2f}" if "z_mean" in r else "-"
        print(
            f"| {r['quantity']} | {d[0]:.4g} [{d[1]:.4g}, {d[2]:.4g}] "
            f"| {f[0]:.4g} [{f[1]:.4g}, {f[2]:.4g}] | {rh} | {ks} | {z} |"
        )


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="the fan's first sag, 2 x 1,500")
    ap.add_argument("--output", type=Path, default=HERE / "results" / "right_first.json")
    ap.add_argument("--fan-dir", type=Path, default=os.environ.get("LOADBAYES_FAN_FINDING"))
    ap.add_argument("--record", type=Path, help="the real record's .cfg")
    ap.add_argument("--reference-iterations", type=int, default=64_000)
    ap.add_argument("--cases", default="fan,andes_ieee14,recorder_chain,andes_motor5,real")
    ap.add_argument("--keep", type=Path, help="keep the events and fits here")
    args = ap.parse_args()
    load = os.getloadavg()
    started = datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds")
    cases = ["fan"] if args.quick else args.cases.split(",")
    rows, notes, outputs, real = [], {}, {}, None
    with tempfile.TemporaryDirectory() as tmp:
        folder = args.keep or Path(tmp)
        folder.mkdir(parents=True, exist_ok=True)
        builders = {"fan": lambda: fan_events(folder, args.quick),
                    "fan_finding": lambda: fan_finding(args.fan_dir),
                    "andes_ieee14": lambda: andes_ieee14_events(folder),
                    "recorder_chain": lambda: recorder_chain_event(folder),
                    "andes_motor5": lambda: andes_motor5_event(folder)}  # fmt: skip
        if "fan" in cases and not args.quick and args.fan_dir:
            cases.insert(cases.index("fan") + 1, "fan_finding")
        for case in cases:
            if case == "real":
                continue
            built = builders[case]()
            if built is None:
                notes[case] = f"not found: {args.fan_dir}"
                continue
            files, truth = built
            pinned = ("--chains", 2, "--draws", 1500, "--burn", 500, "--fixed-draws")
            extra = pinned if args.quick else ()
            run = fit(files, folder / f"{case}.json", *extra)
            notes[case] = reading_line(run)
            print(f"{case}: {notes[case]}", flush=True)
            outputs[case] = run["output"]
            for k in SHOWN.get(case, QUANTITIES):
                rows.append(row(case, k, float(truth[k]), run))
        if "real" in cases:
            from loadbayes.studies.real_record import find_record

            cfg = args.record or find_record(HERE)
            if cfg is None:
                notes["real"] = "the real record was not found ($LOADBAYES_REAL_RECORD)"
            else:
                try:
                    real = real_record(Path(cfg), folder, args.reference_iterations)
                except (RuntimeError, OSError, KeyError, ValueError) as exc:
                    notes["real"] = f"failed: {exc}"
    print_cases(rows)
    for case, words in notes.items():
        print(f"- {case}: {words}")
    if real:
        print_real(real)
    result = {"started": started, "load_average_at_start": load,
              "load_average_at_end": os.getloadavg(), "quick": args.quick,
              "cpu_count": os.cpu_count(), "rows": rows, "readings": notes, "outputs": outputs,
              "real": real}  # fmt: skip
    args.output.parent.mkdir(parents=True, exist_ok=True)
    text = json.dumps(result, indent=1, default=float)
    # The printed outputs name the files: not this machine's folders.
    for path, name in (
        (folder, "<events>"),
        (args.fan_dir, "<fan-dir>"),
        (args.record, "<record>"),
    ):
        if path:
            text = text.replace(str(Path(path).parent if name == "<record>" else path), name)
    args.output.write_text(text + "\n")
    print(f"\nwritten {args.output}", flush=True)


if __name__ == "__main__":
    main()
