"""Benchmark: the motor kernel holding a motor at rest (``motor_kernel.REST_TOL``).

Where the input holds one value and the motor has settled, the kernel holds the state
instead of stepping RK4 (docs/composite.md, "The motor at rest is not integrated"). This
script times one motor integration (``motor_kernel.integrate``) of a 20 s record at
60/s (a 30 % sag at 1.0123 s held 0.2 s, 20 ms ramps: the independent 20 s event's
voltage of docs/composite.md) on three voltages:

- **held**: the voltage exact, as a simulator writes it (flat before and after the sag);
- **noisy**: 0.08 % noise on V (a recorder's): never holds a value;
- **quantised**: the same noise rounded to 1e-3 p.u.: holds a value over four samples
  now and then, while the motor never settles (the case ``REST_NEAR`` is for).

Each against the same voltage **nudged** (every sample after the first 0.5 s moved by
1-7 parts in 1e15, so that no two neighbours are equal and nothing is held: the kernel
integrates throughout, as before the change), for two motors (the generator's large slow
motor, T' 0.7 s, H 1.2 s, and the library's ``small_industrial``), read as point samples
and as one-cycle window means. Reported: microseconds per integration (best of five
rounds of a fixed count, one thread, after a warm-up call), held / nudged as a speed-up,
and the largest difference in P and Q between the two (p.u., motor base).

Run: ``python benchmarks/bench_rest.py [--quick] [--output PATH]``.
"""

from __future__ import annotations

import argparse
import datetime
import json
import os
import sys
from functools import partial
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
from bench_online import _best  # noqa: E402  (one copy: the best of repeated runs)
from bench_zip import machine  # noqa: E402  (one copy: the machine's description)

OUT = HERE / "results" / "rest.json"
#: The held output against the integrated one (p.u., motor base): the kernel's own
#: error is 1e-4 (docs/composite.md, "The compiled kernel and its accuracy").
TARGET_DIFF = 1e-9
#: A held record's integration at least this many times cheaper; a noisy one's no dearer
#: than 1 / TARGET_NOISY times its nudged twin's (timing noise included). Against the
#: kernel before the change (a4e3c79) on a like quantised voltage (``REST_NEAR``'s
#: comment in models/motor_kernel.py): 249 and 345 us before, 247 and 320 after.
TARGET_HELD = 3.0
TARGET_NOISY = 0.9


def _voltages(fs: float = 60.0, t_end: float = 20.0) -> tuple[np.ndarray, dict]:
    t = np.arange(0.0, t_end, 1.0 / fs)
    v = np.interp(t, [0, 1.0123, 1.0323, 1.2123, 1.2323, t_end], [1, 1, 0.7, 0.7, 1, 1])
    rng = np.random.default_rng(0)
    noisy = v + 0.0008 * rng.standard_normal(t.size)
    return t, {"held": v, "noisy": noisy, "quantised": np.round(noisy, 3)}


def _nudged(t: np.ndarray, v: np.ndarray) -> np.ndarray:
    w = v.copy()
    after = t > 0.5
    w[after] *= 1.0 + 1e-15 * (1 + np.arange(after.sum()) % 7)
    return w


def _motors() -> dict:
    from loadbayes.models.motor_library import MOTORS

    m = MOTORS["small_industrial"]
    return {
        "large slow (T' 0.7 s, H 1.2 s)": dict(
            rs=0.01, xp=0.1777, dx=3.41, tp_s=0.7, h_s=1.2, t0=0.7
        ),  # fmt: skip
        f"small_industrial (T' {m.tp_s:.3f} s, H {m.h_s} s)": dict(
            rs=m.rs, xp=m.xp, dx=m.x - m.xp, tp_s=m.tp_s, h_s=m.h_s, t0=0.6
        ),
    }


def _time_us(fn, count: int, rounds: int = 5) -> float:
    """Microseconds a call: the best of ``rounds`` rounds of ``count`` calls, after one."""

    def calls():
        for _ in range(count):
            fn()

    fn()
    return _best(calls, rounds) / count * 1e6


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="Smoke sizes (a second).")
    ap.add_argument("--output", default=str(OUT))
    args = ap.parse_args(argv)
    import numba

    from loadbayes.models.motor_kernel import REST_NEAR, REST_TOL, integrate

    info = machine()
    count = 20 if args.quick else 300
    t, voltages = _voltages()
    rows = []
    for motor, kw in _motors().items():
        for reading, window in (("points", 0.0), ("window means", 1.0 / 60.0)):
            for name, v in voltages.items():
                w = _nudged(t, v)
                a = integrate(t, v, None, window_s=window, f_hz=60.0, **kw)
                b = integrate(t, w, None, window_s=window, f_hz=60.0, **kw)
                call = partial(integrate, t, window_s=window, f_hz=60.0, **kw)
                us_a = _time_us(partial(call, v, None), count)
                us_b = _time_us(partial(call, w, None), count)
                diff = max(float(np.max(np.abs(a[0] - b[0]))), float(np.max(np.abs(a[1] - b[1]))))
                rows.append({"motor": motor, "reading": reading, "voltage": name,
                             "us_as_is": round(us_a, 1), "us_nudged": round(us_b, 1),
                             "speed_up": round(us_b / us_a, 2), "max_diff_pu": diff})  # fmt: skip
                print(f"{motor:<34} {reading:<12} {name:<9} {us_a:8.1f} us, nudged "
                      f"{us_b:8.1f} us: x{us_b / us_a:5.2f}; max |dP|, |dQ| {diff:.1e}",
                      flush=True)  # fmt: skip
    held = [r for r in rows if r["voltage"] == "held"]
    other = [r for r in rows if r["voltage"] != "held"]
    worst = max(r["max_diff_pu"] for r in rows)
    targets = [
        {"target": f"held record: an integration >= {TARGET_HELD:g}x cheaper than integrated "
                   "throughout",
         "measured": f"x{min(r['speed_up'] for r in held):.2f} to "
                     f"x{max(r['speed_up'] for r in held):.2f}",
         "met": min(r["speed_up"] for r in held) >= TARGET_HELD},
        {"target": "noisy and quantised records: no dearer than with nothing held (speed-up "
                   f">= {TARGET_NOISY:g}, timing noise included)",
         "measured": f"x{min(r['speed_up'] for r in other):.2f} to "
                     f"x{max(r['speed_up'] for r in other):.2f}",
         "met": min(r["speed_up"] for r in other) >= TARGET_NOISY},
        {"target": f"held output within {TARGET_DIFF:g} p.u. of the integrated",
         "measured": f"{worst:.1e} p.u. at most", "met": worst <= TARGET_DIFF},
    ]  # fmt: skip
    info["load_average_at_end"] = list(os.getloadavg())
    out = {
        "date": datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds"),
        "quick": bool(args.quick),
        "machine": info,
        "versions": {"numpy": np.__version__, "numba": numba.__version__},
        "settings": {
            "REST_TOL": REST_TOL,
            "REST_NEAR": REST_NEAR,
            "calls": count,
            "rounds": 5,
            "record": "20 s at 60/s",
        },  # fmt: skip
        "results": rows,
        "targets": targets,
        "notes": [
            "One thread, the best of five rounds of a fixed number of calls after a warm-up "
            "call, in one process; the machine's load average at start and end is given "
            "(the best-of rounds damp another user's load, not remove it).",
            "Nudged: every sample after 0.5 s moved by 1-7 parts in 1e15, so that no two "
            "neighbours are equal: the kernel integrates throughout, as it did before a "
            "motor at rest was held; the max difference is the held answer's error.",
        ],
    }
    Path(args.output).parent.mkdir(parents=True, exist_ok=True)
    Path(args.output).write_text(json.dumps(out, indent=2) + "\n")
    for tg in targets:
        print(f"{'met' if tg['met'] else 'NOT MET'}: {tg['target']}: {tg['measured']}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
