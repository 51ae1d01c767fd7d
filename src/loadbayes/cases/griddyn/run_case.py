"""One GridDyn case, run in a child process by the GridDyn environment (Python >= 3.13).

Called as ``python run_case.py SPEC.json OUT.npz`` by :mod:`cases` (never imported by the
test suite: this file imports ``griddyn``, which lives only in that environment). The spec
holds the ``.raw`` and ``.dyr`` texts, the measured bus, the fault bus's zero load and the
sag depth wanted at the measured bus. The child

1. finds the fault admittance giving that depth: short runs to the fault's clearing, a
   secant search on log |Y| (the depth is ``1 - median V during the fault / V before``);
2. runs the whole case at the solver's output step (``dt_s``), reading V, angle and the
   P, Q flowing into the load's transformer at the measured bus (the far end of the line
   that feeds it), and the initial state of every piece of the CMLD network;
3. writes everything to OUT.npz (atomically) and leaves with ``os._exit(0)``: GridDyn's
   extension can crash at interpreter exit, after the work is done.

A run whose re-initialisation after a switching fails (a narrow band of fault impedance
does that) is retried with the admittance nudged by 1%.
"""

import json
import math
import os
import sys
import tempfile
from pathlib import Path

import griddyn as gd
import numpy as np


def _write_case(directory: Path, spec: dict, y_fault: complex, t_end: float) -> Path:
    (directory / "case.raw").write_text(spec["raw"])
    (directory / "case.dyr").write_text(spec["dyr"])
    target = spec["fault_load"]
    t_on, t_off = spec["t_fault_s"], spec["t_clear_s"]
    events = "".join(
        f"<event><target>{target}</target><field>{field}</field>"
        f"<time>{t_on!r},{t_off!r}</time><value>{value!r},0</value></event>\n"
        for field, value in (("yp", y_fault.real), ("yq", y_fault.imag))
    )
    xml = (
        '<?xml version="1.0" encoding="utf-8"?>\n<griddyn name="cmld" version="0.0.1">\n'
        '<import file="case.raw"/>\n<import file="case.dyr"/>\n'
        f"{events}<timestop>{t_end!r}</timestop>\n</griddyn>\n"
    )
    path = directory / "case.xml"
    path.write_text(xml)
    return path


def _initial_state(sim) -> dict:
    """Every bus's V and angle, every link's and load's flows, right after initialisation."""
    return {
        "buses": {b.name: [b.voltage, b.angle] for b in sim.buses},
        "links": {k.name: [k.p1, k.q1, k.p2, k.q2] for k in sim.links},
        "loads": {ld.name: [ld.p, ld.q] for ld in sim.loads},
    }


def _run(spec: dict, y_fault: complex, t_end: float):
    """Run to ``t_end``: rows of t, V, angle, P, Q (measured bus), V, P, Q (feeder end)."""
    with tempfile.TemporaryDirectory(prefix="griddyn-case-") as tmp:
        sim = gd.load(str(_write_case(Path(tmp), spec, y_fault, t_end)))
        domain = sim.time_domain
        domain.initialize()
        start = _initial_state(sim)
        bus = sim.buses[spec["measured_bus"]]
        feed = sim.links[spec["feed_link"]]
        dt = spec["dt_s"]
        n = int(round(t_end / dt))
        end = sim.buses[spec["load_end_bus"]]
        load = sim.loads[spec["cmld_load"]]

        def row(t):
            # P, Q into the load: what the feeding line delivers at its measured-bus end;
            # then motor D's side: the feeder end's V and the composite's own P, Q.
            return (t, bus.voltage, bus.angle, -feed.p2, -feed.q2, end.voltage, load.p, load.q)

        rows = np.empty((n + 1, 8))
        rows[0] = row(0.0)
        for k in range(1, n + 1):
            t = round(k * dt, 9)
            reached = domain.run_until(t)
            if not math.isfinite(reached) or reached < t - 1e-9:
                raise RuntimeError(f"the solver stopped at t = {reached} s before {t} s")
            rows[k] = row(t)
        if not np.all(np.isfinite(rows)):
            raise RuntimeError("the run produced a non-finite value")
        return rows, start


def _depth(rows: np.ndarray, spec: dict) -> float:
    t = rows[:, 0]
    before = rows[t < spec["t_fault_s"], 1]
    during = rows[(t > spec["t_fault_s"] + 0.01) & (t < spec["t_clear_s"]), 1]
    return 1.0 - float(np.median(during)) / float(before[-1])


def _robust_run(spec: dict, y_fault: complex, t_end: float):
    """A run, retried with the fault admittance nudged by 1% if the solver fails."""
    last = None
    for attempt in range(4):
        y = y_fault * (1.01**attempt)
        try:
            rows, start = _run(spec, y, t_end)
            return rows, start, y
        except Exception as exc:  # noqa: BLE001 - GridDyn raises several kinds
            last = exc
    raise RuntimeError(f"GridDyn failed four times around Y = {y_fault}: {last}")


def _calibrate(spec: dict) -> complex:
    """The fault admittance whose sag at the measured bus is ``spec['depth']``."""
    # A shunt R + jX draws P = V^2 R / |z|^2 and Q = V^2 X / |z|^2: GridDyn's yp and yq.
    k = spec["fault_x_over_r"]
    unit = complex(1.0, k) / math.hypot(1.0, k)
    target = spec["depth"]
    t_short = spec["t_clear_s"] - 1e-3
    log_y = [math.log(spec["y_guess"])]
    depths = []
    for _ in range(12):
        rows, _, y_used = _robust_run(spec, math.exp(log_y[-1]) * unit, t_short)
        log_y[-1] = math.log(abs(y_used))
        depths.append(_depth(rows, spec))
        if abs(depths[-1] - target) < spec["depth_tol"]:
            return abs(y_used) * unit
        if len(depths) == 1:
            step = 0.5 if depths[-1] < target else -0.5
            log_y.append(log_y[-1] + step)
        else:
            slope = (depths[-1] - depths[-2]) / (log_y[-1] - log_y[-2])
            step = (target - depths[-1]) / slope if slope > 0 else 0.5
            log_y.append(log_y[-1] + max(-1.5, min(1.5, step)))
    raise RuntimeError(f"no fault admittance gave a sag of {target}: reached {depths}")


def main(spec_path: str, out_path: str) -> None:
    """Run the case ``spec_path`` describes; write ``out_path`` (see the module docstring)."""
    spec = json.loads(Path(spec_path).read_text())
    y_fault = _calibrate(spec)
    rows, start, y_fault = _robust_run(spec, y_fault, spec["t_end_s"])
    meta = {
        "fault_y": [y_fault.real, y_fault.imag],
        "depth_measured": _depth(rows, spec),
        "start": start,
        "griddyn_version": gd.__version__,
    }
    tmp = out_path + ".tmp.npz"
    np.savez(tmp, rows=rows, meta=np.array(json.dumps(meta)))
    os.replace(tmp, out_path)


if __name__ == "__main__":
    try:
        main(sys.argv[1], sys.argv[2])
    except Exception as exc:  # noqa: BLE001 - one line to the parent, then leave
        sys.stderr.write(f"run_case: {type(exc).__name__}: {exc}\n")
        sys.stderr.flush()
        os._exit(1)
    sys.stdout.flush()
    os._exit(0)
