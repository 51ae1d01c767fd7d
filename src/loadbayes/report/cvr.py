"""What ``loadbayes cvr`` prints: the two factors, the design's power and the words."""

from __future__ import annotations

from typing import Any

__all__ = ["cvr_lines"]


def _iv(s: dict[str, float]) -> str:
    return f"{s['mean']:.2f} [{s['low']:.2f}, {s['high']:.2f}]"


def cvr_lines(res: dict[str, Any]) -> list[str]:
    """The lines of a CVR result (the JSON's dict), in the order a reader asks."""
    out = []
    sched = res["schedule"]
    days = res["days"]
    src = sched["source"]
    found = f"{sched.get('steps', sched.get('switches'))} switches" if "steps" in sched else (
        f"{sched['switches']} switches")  # fmt: skip
    out.append(f"on/off periods from the {src}: {found}; {days['kept']} days used "
               f"({res['power']['on_days']} on, {res['power']['off_days']} off; "
               f"left out: {days['short']} short, {days['mixed']} mixed, "
               f"{days['not_positive']} not positive)")  # fmt: skip
    vc = res["voltage_change"]
    out.append(f"the reduction moved the daily voltage by {vc['percent']:.2f}%")
    for ch, name in (("p", "P"), ("q", "Q")):
        if ch in res["energy"]:
            out.append(f"energy CVR factor ({name}, %dE/%dV, 95%): {_iv(res['energy'][ch])}")
    for name, s in res["instantaneous"].items():
        out.append(f"instantaneous {name} at {s['at_v_pu']:.3f} p.u. (the steps' median; 95%, "
                   f"{s['steps']} voltage steps): {_iv(s)}")  # fmt: skip
    lag = next((s.get("recovery_lag_s") for s in res["instantaneous"].values()), None)
    if lag:
        out.append(f"read at each step's instant: a thermostatic recovery with a lag of "
                   f"{lag / 3600:g} h assumed, not fitted (a feeder whose loads recover faster "
                   "reads dP/dV low: docs/zip.md)")  # fmt: skip
    if res.get("why", {}).get("words"):
        out.append(res["why"]["words"])
    out.append(res["power"]["words"])
    g = res["glitches"]
    out.append(f"glitches left out: {g['spikes_v']} V spike(s), {g['spikes_p']} P spike(s), "
               f"{g['stuck']} stuck sample(s)")  # fmt: skip
    imp = res.get("source_impedance") or {}
    if imp:
        out.append(f"the head voltage's sensitivity to the load: {imp['z']:.3g} p.u./MW "
                   f"[{imp['low']:.3g}, {imp['high']:.3g}]")  # fmt: skip
    out += res["notes"]
    return out
