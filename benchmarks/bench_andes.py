"""Benchmark: the package's composite load against ANDES, over the motor library and sags.

For each motor of the library, sag depth and motor share, one ANDES event
(``loadbayes.cases.andes.sim.simulate``: a fault at the network bus, 1.3 s) is reproduced
by the package's motor simulator driven by ANDES's load-bus voltage
(``loadbayes.cases.andes.compare``). Recorded per event: the achieved sag depth, ANDES's
step, the largest error of the motor's P, Q (on its rating), of the static part and of the
total (system p.u.), the same without the bus angle (the convention that matters most),
and the CPU time of the ANDES runs and of the reproduction.

Then the same on a bus of two cases ANDES ships (Kundur's two-area system, bus 7; the
IEEE 14-bus system, bus 9), with their machines swinging
(``loadbayes.cases.andes.grid``).

Writes ``benchmarks/results/andes.json`` and prints a table. Needs the ``andes`` extra.

Run: ``python benchmarks/bench_andes.py [--quick] [--output PATH]``.
"""

from __future__ import annotations

import argparse
import datetime
import json
import platform
import sys
import time
from pathlib import Path

MOTORS = ("small_industrial", "large_industrial", "krause_3hp", "krause_2250hp")
SAGS = (0.15, 0.3, 0.5)
SHARES = (0.2, 0.8)
CASES = (("kundur/kundur_full.xlsx", 7), ("ieee14/ieee14_full.xlsx", 9))


def one(motor: str, depth: float, f_m: float, case: tuple | None = None) -> dict:
    """One event and its reproduction (``case``: an ANDES case and bus, else built-in)."""
    from loadbayes.cases.andes.compare import max_errors, reproduce
    from loadbayes.cases.andes.grid import simulate_in_case
    from loadbayes.cases.andes.sim import simulate

    t = time.process_time()
    kw = {"sag_depth": depth, "f_m": f_m, "fault_start_s": 0.3, "t_end_s": 1.3}
    if case is None:
        ev = simulate(motor, **kw)
    else:
        import andes

        ev = simulate_in_case(andes.get_case(case[0]), case[1], motor, **kw)
    t_andes = time.process_time() - t
    t = time.process_time()
    err = max_errors(reproduce(ev, refine=2), ev.truth["mva_m"])
    t_lb = time.process_time() - t
    flat = max_errors(reproduce(ev, use_angle=False, refine=1), ev.truth["mva_m"])
    return {
        "case": "built-in" if case is None else f"{case[0]} bus {case[1]}",
        "motor": motor,
        "sag_target": depth,
        "sag": round(ev.settings["sag_depth"], 4),
        "f_m": f_m,
        "andes_step_s": ev.settings["step_s"],
        "motor_err": max(err["p_motor"], err["q_motor"]),
        "static_err": max(err["p_static"], err["q_static"]),
        "total_err": max(err["p"], err["q"]),
        "motor_err_no_angle": max(flat["p_motor"], flat["q_motor"]),
        "andes_cpu_s": round(t_andes, 2),
        "reproduce_cpu_s": round(t_lb, 2),
    }


def main() -> None:
    """Run the sweep, print the table and write the JSON."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="one motor, one sag")
    here = Path(__file__).resolve().parent
    parser.add_argument("--output", type=Path, default=here / "results" / "andes.json")
    args = parser.parse_args()
    try:
        import andes
    except ImportError:
        print("ANDES is not installed (the 'andes' extra): nothing to measure")
        return
    cases = [("small_industrial", 0.3, 0.4, None)] if args.quick else [
        (m, d, f, None) for m in MOTORS for d in SAGS for f in SHARES
    ] + [("small_industrial", 0.3, 0.4, c) for c in CASES]  # fmt: skip
    rows = []
    head = f"{'case':24s} {'motor':18s} sag    f_m  step      motor    static   total    "
    head += "no-angle  cpu s"
    print(head)
    for motor, depth, f_m, case in cases:
        row = one(motor, depth, f_m, case)
        rows.append(row)
        print(
            f"{row['case'][:24]:24s} {motor:18s} {row['sag']:.3f}  {f_m:.1f}  "
            f"1/{1 / row['andes_step_s']:<6.0f} "
            f"{row['motor_err']:.1e}  {row['static_err']:.1e}  {row['total_err']:.1e}  "
            f"{row['motor_err_no_angle']:.1e}   {row['andes_cpu_s'] + row['reproduce_cpu_s']:.1f}",
            flush=True,
        )
    worst = max(r["motor_err"] for r in rows)
    worst_static = max(r["static_err"] for r in rows)
    out = {
        "date": datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds"),
        "machine": {"platform": platform.platform(), "python": sys.version.split()[0]},
        "versions": {"andes": andes.__version__},
        "results": rows,
        "targets": [
            {
                "target": "motor P, Q within 1e-3 of its rating",
                "measured": worst,
                "met": worst <= 1e-3,
            },
            {
                "target": "static P, Q within 1e-4 p.u.",
                "measured": worst_static,
                "met": worst_static <= 1e-4,
            },
        ],  # fmt: skip
        "notes": [
            "ANDES: implicit trapezoid, fixed step (andes_sim.default_step), Newton to 1e-9.",
            "loadbayes: motor_sim.simulate (DOP853, rtol 1e-9) driven by ANDES's V and angle,"
            " read at ANDES's time points.",
            "motor_err_no_angle: the same with the bus angle ignored (magnitude only).",
        ],
    }
    args.output.parent.mkdir(parents=True, exist_ok=True)
    args.output.write_text(json.dumps(out, indent=2))
    print(f"wrote {args.output}")


if __name__ == "__main__":
    main()
