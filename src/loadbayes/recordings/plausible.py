"""Is a record table physically plausible? Refuse what cannot be, say what is odd.

The reader checks every field of a COMTRADE file against the standard; this module checks
the numbers against physics, after the phasors are taken:

- the frequency the voltage turns at must be within 5% of the ``.cfg``'s nominal one
  (a 50 Hz record labelled 60 Hz has one-cycle windows of the wrong length: every phasor,
  P and Q is wrong);
- the positive-sequence voltage must stay below twice its base where the base is the
  first row's (a value far above that is a scaling slip, not a measurement);
- a record whose negative sequence is large before anything happens (the first rows) is
  said, since then the positive-sequence fit sees an unbalanced steady state.
"""

from __future__ import annotations

import numpy as np

from loadbayes.io.errors import DataError

__all__ = ["FREQUENCY_TOLERANCE", "check_table"]

#: Relative difference between the measured and the nominal frequency that is refused.
FREQUENCY_TOLERANCE = 0.05


def check_table(w, rec, source: str) -> list[str]:
    """Refuse an implausible record table (DataError); return notes on odd ones."""
    c = rec.columns
    phasor = np.asarray(c["kind"]) == "phasor"
    f = np.asarray(c["f"], dtype=float)[phasor]
    notes: list[str] = []
    f0 = w.f_nominal
    if f.size >= 3:
        f_med = float(np.median(f))
        if abs(f_med - f0) > FREQUENCY_TOLERANCE * f0:
            raise DataError(
                f"the voltage turns at {f_med:.4g} Hz but the .cfg says {f0:g} Hz nominal: "
                "the line frequency (or the sample rate) in the .cfg is wrong, and every "
                "one-cycle window with it",
                source,
            )
    v = np.asarray(c["v"], dtype=float)[phasor]
    if v.size and np.nanmax(v) > 2.0:
        k = int(np.nanargmax(v))
        notes.append(
            f"the positive-sequence voltage reaches {v[k]:.3g} p.u. (t = "
            f"{float(np.asarray(c['t_s'])[phasor][k]):.4g} s) of a base taken from the first "
            "row: check the scaling of the voltage channels"
        )
    v2 = np.asarray(c["v2"], dtype=float)[phasor][:3]
    if v2.size and float(np.median(v2)) > 0.05:
        notes.append(
            f"the first rows already have a negative-sequence voltage of "
            f"{float(np.median(v2)):.0%} of the positive: the record starts unbalanced"
        )
    return notes
