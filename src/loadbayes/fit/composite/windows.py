"""Grid-code validation errors: pre-fault, fault and post-fault windows of a voltage dip.

IEC 61400-27-2:2020 (Electrical simulation models: model validation; section 6.4.3,
windows error statistics, and 6.4.4, the FRT windows of a voltage dip, after IEC
61400-27-1:2015's validation annex) scores a simulated response against a measured one
in three windows of the dip: before the fault, during it, after its clearing; in each,
the mean error ``ME = mean(sim - meas)``, the mean absolute error ``MAE = mean(|sim -
meas|)`` and the maximum error ``MXE = max(|sim - meas|)``, each per unit of a base
(here the fitted P0, as ``validate``'s RMS). RTE's DyCoV tool scores models against
measured curves the same way.

Departures, said: the windows are found from the voltage (the fault from the first
sample below half the dip's depth to the last one, as ``predict_scope.sag_extent``),
not from the fault's logged instants; the standard's transient sub-windows (the first
instants after the fault's start and clearing, scored apart or left out) are not
separated here; only the scored samples enter (a phasor window straddling a step is
left out, as in the other scores).
"""

from __future__ import annotations

import numpy as np

__all__ = ["dip_windows", "window_errors"]

SOURCE = ("IEC 61400-27-2:2020, 6.4.3-6.4.4: ME, MAE, MXE in the pre-fault, fault and "
          "post-fault windows (no transient sub-windows here)")  # fmt: skip


def dip_windows(t: np.ndarray, v: np.ndarray) -> dict[str, np.ndarray]:
    """Boolean masks of the pre-fault, fault and post-fault samples of one dip."""
    v_pre = float(v[0])
    v_min = float(np.min(v))
    n = t.size
    pre = np.zeros(n, bool)
    fault = np.zeros(n, bool)
    below = np.flatnonzero(v < v_pre - 0.5 * (v_pre - v_min))
    if v_min > v_pre * (1 - 1e-3) or below.size == 0:
        pre[:] = True
        return {"pre_fault": pre, "fault": fault, "post_fault": np.zeros(n, bool)}
    pre[: below[0]] = True
    fault[below[0] : below[-1] + 1] = True
    return {"pre_fault": pre, "fault": fault, "post_fault": ~(pre | fault)}


def window_errors(t, v, measured: dict, simulated: dict, *, scale: float,
                  scored: np.ndarray | None = None) -> dict:  # fmt: skip
    """ME, MAE and MXE of each channel (``p``, ``q``) in each window, per unit of ``scale``."""
    keep = np.ones(t.size, bool) if scored is None else np.asarray(scored, bool)
    out: dict = {"source": SOURCE, "per_unit_of": "the fitted P0"}
    for name, mask in dip_windows(np.asarray(t), np.asarray(v)).items():
        rows = mask & keep
        span = [float(t[mask][0]), float(t[mask][-1])] if mask.any() else None
        w: dict = {"n": int(rows.sum()), "t_s": span}
        for ch in measured:
            if rows.any():
                err = (np.asarray(simulated[ch])[rows] - np.asarray(measured[ch])[rows]) / scale
                w[ch] = {"me": float(np.mean(err)), "mae": float(np.mean(np.abs(err))),
                         "mxe": float(np.max(np.abs(err)))}  # fmt: skip
            else:
                w[ch] = None
        out[name] = w
    return out
