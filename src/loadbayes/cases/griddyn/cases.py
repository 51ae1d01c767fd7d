"""GridDyn cases of the WECC composite load (CMLDBLU1): the independent simulator of issue 36.

GridDyn (LLNL, BSD; ``griddyn`` 0.13.0) needs Python >= 3.13, so it runs in its own
environment (``make test`` builds ``.venv-griddyn``; ``LOADBAYES_GRIDDYN_PYTHON`` names
another interpreter) and each case in a child process (``run_case.py``). Nothing here
imports the rest of loadbayes (its fits and models): the harness only writes GridDyn's
input from its own description of the load (``cmld.py``) and reads GridDyn's output
(``tests/unit/test_layout.py`` checks the imports).

The case: a classical machine (GENCLS, large) behind a line to a fault bus, a second line
to the measured bus (where a recorder would sit), and there one CMLDBLU1 record in
GridDyn's form ``IBUS 'CMLDBLU1' ID <132 CONs> /``: substation transformer (fixed tap),
feeder, motors A and B (three-phase, single-cage: Lpp = Lp, Tppo = 0), motor D (the
single-phase compressor performance model), electronic load and static part. A shunt
fault at the fault bus, its impedance found by the child so that the measured bus sags
by the depth asked for (``1 - median V during the fault / V before``).

The load, its record and its truth are in ``cmld.py``.

Results: :func:`run_case` returns the measured bus's t_s, v, angle_rad, p, q (system per
unit) resampled to a recorder's phasor rate, and the truth. Runs are cached on disk
(``LOADBAYES_GRIDDYN_CACHE``, default a folder under the system temp dir), keyed by a
hash of everything that defines them, so repeated tests do not rerun GridDyn.
"""

from __future__ import annotations

import hashlib
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np
import pandas as pd

from loadbayes.cases.griddyn.cmld import F_HZ, S_BASE_MVA, V_BASE_KV, Cmld, Motor3, MotorD

__all__ = ["F_HZ", "S_BASE_MVA", "V_BASE_KV", "Cmld", "Motor3", "MotorD", "run_case"]

HERE = Path(__file__).resolve().parent
REPO = HERE.parents[3]  # src/loadbayes/cases/griddyn: the checkout (an editable install)
RUNNER = HERE / "run_case.py"

# Sags at the measured bus. Deep is 46%: in GridDyn 0.13.0 motor D's stall is not
# monotone in depth (with these defaults 44-45% leave it running with the feeder end at
# 0.46 pu, far below Vstall 0.6; 46% stalls it), so the deep case is where it does stall.
DEPTHS = {"shallow": 0.13, "medium": 0.25, "deep": 0.46}

# Buses and objects as GridDyn names them from the .raw below.
MEASURED_BUS = "LOAD"
FEED_LINK = "FAULT_to_LOAD"
FAULT_LOAD = "FAULT::FAULT_load_1"
LOAD_END_BUS = "cmpldw_2_1_load_end"
CMLD_LOAD = "cmpldw_2_1"


def griddyn_python() -> Path | None:
    """The GridDyn environment's interpreter, or None when there is none."""
    named = os.environ.get("LOADBAYES_GRIDDYN_PYTHON")
    path = Path(named) if named else REPO / ".venv-griddyn" / "bin" / "python"
    return path if path.exists() else None


def skip_reason() -> str | None:
    """One line saying why GridDyn cases cannot run here, or None when they can."""
    python = griddyn_python()
    if python is None:
        named = os.environ.get("LOADBAYES_GRIDDYN_PYTHON")
        if named:
            return f"GridDyn missing: LOADBAYES_GRIDDYN_PYTHON={named} does not exist"
        return "GridDyn missing: no .venv-griddyn (make test builds it when python3.13 exists)"
    probe = subprocess.run(
        [str(python), "-c", "import griddyn"], capture_output=True, text=True, timeout=60
    )
    if probe.returncode != 0:
        last = (probe.stderr.strip().splitlines() or ["no message"])[-1]
        return f"GridDyn does not import in {python}: {last}"
    return None


def _cache_dir() -> Path:
    named = os.environ.get("LOADBAYES_GRIDDYN_CACHE")
    path = Path(named) if named else Path(tempfile.gettempdir()) / "loadbayes-griddyn-cache"
    path.mkdir(parents=True, exist_ok=True)
    return path


def _resample(rows: np.ndarray, rate_hz: float, window_s: float) -> np.ndarray:
    """Rows at ``k / rate_hz``: the mean over ``window_s`` centred on the stamp (0: points)."""
    t = rows[:, 0]
    half = window_s / 2.0
    stamps = np.arange(np.ceil(half * rate_hz), np.floor((t[-1] - half) * rate_hz) + 1) / rate_hz
    if window_s <= 0.0:
        values = [np.interp(stamps, t, column) for column in rows[:, 1:].T]
    else:
        # Exact means of the piecewise-linear output over each window (trapezoid sums).
        steps = (rows[1:, 1:] + rows[:-1, 1:]) / 2 * np.diff(t)[:, None]
        cum = np.concatenate([np.zeros((1, rows.shape[1] - 1)), np.cumsum(steps, axis=0)])
        values = [
            (np.interp(stamps + half, t, column) - np.interp(stamps - half, t, column)) / window_s
            for column in cum.T
        ]
    return np.column_stack([stamps, *values])


def run_case(
    cmld: Cmld | None = None,
    depth: float = DEPTHS["shallow"],
    *,
    rate_hz: float = F_HZ,
    window_s: float | None = None,
    t_fault_s: float = 0.2075,
    duration_s: float = 0.1,
    t_end_s: float = 2.0,
    dt_s: float = 0.0005,
    fault_x_over_r: float = 10.0,
) -> tuple[pd.DataFrame, dict]:
    """One GridDyn event at the measured bus, and its truth.

    ``depth``: the sag at the measured bus (``1 - median V during the fault / V before``)
    within 0.5 percentage points. ``window_s``: the recorder's phasor window (default one
    cycle at 60 Hz; 0 gives point samples). Returns the frame (t_s, v, angle_rad, p, q; V
    per unit of ``V_BASE_KV``, P and Q per unit of ``S_BASE_MVA``, positive into the load)
    and the truth: :meth:`Cmld.truth` plus ``event`` (the fault and what the run read back:
    ``p0``, ``q0``, ``v0`` at the measured bus after GridDyn's initialisation, and the
    initial state of every bus, link and load).
    """
    cmld = cmld or Cmld()
    window_s = 1.0 / F_HZ if window_s is None else window_s
    spec = {
        "raw": cmld.raw(),
        "dyr": cmld.dyr(),
        "measured_bus": MEASURED_BUS,
        "feed_link": FEED_LINK,
        "fault_load": FAULT_LOAD,
        "load_end_bus": LOAD_END_BUS,
        "cmld_load": CMLD_LOAD,
        "depth": depth,
        "depth_tol": 0.005,
        "y_guess": 2.0 + 100.0 * depth,
        "fault_x_over_r": fault_x_over_r,
        "t_fault_s": t_fault_s,
        "t_clear_s": t_fault_s + duration_s,
        "t_end_s": t_end_s,
        "dt_s": dt_s,
    }
    key = hashlib.sha256(
        (json.dumps(spec, sort_keys=True) + RUNNER.read_text()).encode()
    ).hexdigest()[:24]
    out = _cache_dir() / f"cmld-{key}.npz"
    if not out.exists():
        python = griddyn_python()
        if python is None:
            raise RuntimeError(skip_reason())
        with tempfile.TemporaryDirectory(prefix="griddyn-spec-") as tmp:
            spec_path = Path(tmp) / "spec.json"
            spec_path.write_text(json.dumps(spec))
            done = subprocess.run(
                [str(python), str(RUNNER), str(spec_path), str(out)],
                capture_output=True,
                text=True,
                timeout=300,
            )
        if not out.exists():
            raise RuntimeError(
                f"GridDyn case (depth {depth}) failed, exit {done.returncode}: "
                + (done.stderr.strip().splitlines() or ["no message"])[-1]
            )
    with np.load(out) as saved:
        rows = saved["rows"]
        meta = json.loads(str(saved["meta"]))
    feed = meta["start"]["links"][FEED_LINK]
    truth = cmld.truth()
    truth["event"] = {
        "depth_requested": depth,
        "depth_measured": meta["depth_measured"],
        "fault_y": meta["fault_y"],
        "fault_x_over_r": fault_x_over_r,
        "t_fault_s": t_fault_s,
        "t_clear_s": t_fault_s + duration_s,
        "rate_hz": rate_hz,
        "window_s": window_s,
        "p0": -feed[2],
        "q0": -feed[3],
        "v0": meta["start"]["buses"][MEASURED_BUS][0],
        "initial_state": meta["start"],
        "griddyn_version": meta["griddyn_version"],
        "cache_file": str(out),
    }
    sampled = _resample(rows, rate_hz, window_s)
    truth["event"]["feeder_end"] = {
        name: sampled[:, j].tolist() for name, j in (("t_s", 0), ("v", 5), ("p", 6), ("q", 7))
    }
    frame = pd.DataFrame(sampled[:, :5], columns=["t_s", "v", "angle_rad", "p", "q"])
    return frame, truth


if __name__ == "__main__":  # a quick look: python cases.py [depth]
    frame, info = run_case(depth=float(sys.argv[1]) if len(sys.argv) > 1 else 0.13)
    print(frame.iloc[::6].to_string())
    print({k: v for k, v in info["event"].items() if k not in ("initial_state", "feeder_end")})
    end = info["event"]["feeder_end"]
    print("feeder end v:", np.round(end["v"][::6], 3).tolist())
