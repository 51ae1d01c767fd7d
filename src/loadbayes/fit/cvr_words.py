"""What a CVR fit says in words: why the two factors differ, and a voltage that follows the load."""

from __future__ import annotations

from typing import Any

import numpy as np

__all__ = ["explain", "impedance_words"]


def explain(energy, inst, e_draws, i_draws) -> dict[str, Any]:
    """Why the energy and instantaneous factors differ, or that they agree.

    The difference's draws pair the two fits' draws (independent fits, so any pairing is
    a draw of the difference). Its 95% interval decides which words are said.
    """
    if not energy or not inst or e_draws is None or i_draws is None:
        return {}
    a = np.asarray(i_draws).reshape(-1)
    b = np.asarray(e_draws).reshape(-1)
    m = min(a.size, b.size)
    d = a[:m] - b[:m]
    lo, hi = (float(v) for v in np.quantile(d, [0.025, 0.975]))
    mean = float(d.mean())
    out: dict[str, Any] = {"difference": {"mean": mean, "low": lo, "high": hi}}
    if lo > 0:
        share = mean / inst["mean"] if inst["mean"] > 0 else float("nan")
        out["words"] = (
            f"the instantaneous factor ({inst['mean']:.2f}) exceeds the energy factor "
            f"({energy['mean']:.2f}) by {mean:.2f} [{lo:.2f}, {hi:.2f}]: about "
            f"{100 * share:.0f}% of the power the load sheds at a voltage step comes back "
            "over the day. Thermostatic loads recover energy: a heater or cooler at a lower "
            "voltage draws less power but runs longer to deliver the same heat, so its "
            "energy does not fall with its power. The saving is the energy factor's."
        )
    elif hi < 0:
        out["words"] = (
            f"the energy factor ({energy['mean']:.2f}) exceeds the instantaneous one "
            f"({inst['mean']:.2f}) by {-mean:.2f} [{-hi:.2f}, {-lo:.2f}]: loads that answer "
            "to the voltage slowly (over hours), or something else that changed with the "
            "schedule; check the days table"
        )
    else:
        out["words"] = (
            f"the two factors agree within their intervals (difference {mean:.2f} "
            f"[{lo:.2f}, {hi:.2f}]): little of the load recovers its energy after a "
            "voltage change (few thermostatic loads, or the test cannot tell)"
        )
    return out


def impedance_words(imp: dict, direct: dict, energy: dict | None) -> str | None:
    """The plain words when the head voltage answers to the feeder's own load."""
    if not imp or not (imp["low"] > 0):
        return None
    text = (
        f"the head voltage answers to the feeder's own load: it falls by {imp['z']:.2g} "
        f"p.u. per MW [{imp['low']:.2g}, {imp['high']:.2g}] (the source impedance), so V "
        "is not an outside cause of P. Both factors are fitted from what moves V from "
        "outside (the on/off switching, the voltage steps), not from V's day-to-day moves"
    )
    if energy:
        text += (
            f"; regressed on the measured daily voltage instead, the energy factor would be "
            f"{direct['mean']:.2f} [{direct['low']:.2f}, {direct['high']:.2f}]"
        )
    return text + "."
