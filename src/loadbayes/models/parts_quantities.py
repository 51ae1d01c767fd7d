"""The unit and meaning of every named draw of a model of parts (its ``quantities``)."""

from __future__ import annotations

from loadbayes.models.part_priors import MOTOR_CLASSES

__all__ = ["quantities"]


def quantities(model) -> dict[str, tuple[str, str]]:
    """Unit and meaning of every named draw."""
    sys_, mb = "p.u. system base", "p.u. motor base"
    q: dict[str, tuple[str, str]] = {
        "p0": (sys_, "load-bus P at the first sample (behind the feeder)"),
        "q0": (sys_, "load-bus Q at the first sample (behind the feeder)"),
        "x_fd": ("p.u. load base", "series X: transformer and feeder"),
        "r_fd": ("p.u. load base", "series R: transformer and feeder"),
        "f_s": ("-", "static part's share of P"),
        "f_motors": ("-", "three-phase motors' share of P, all together"),
        "f_d": ("-", "motor D's (single-phase A/C) share of P"),
        "f_el": ("-", "power electronics' share of P"),
        "a1": ("-", "static P: constant-impedance share"),
        "a2": ("-", "static P: constant-current share"),
        "a3": ("-", "static P: constant-power share"),
        "cq2": (sys_, "static Q and capacitors: constant-impedance term"),
        "cq1": (sys_, "static Q: constant-current term"),
        "cq0": (sys_, "static Q: constant-power term"),
        "tau_p": ("1/(p.u.)^2", "noise precision of P"),
        "tau_q": ("1/(p.u.)^2", "noise precision of Q"),
        "tau_i2": ("1/(p.u.)^2", "noise precision of the negative-sequence current"),
    }
    for m, t in zip(model.motors, model._tags, strict=True):
        what = MOTOR_CLASSES[m]["meaning"]
        q["f_m" + t] = ("-", f"{what}: share of P")
        q["mva" + (t or "_m")] = (sys_, f"{what}: rating (MVA)")
        for k, (unit, meaning) in {
            "rs": (mb, "stator resistance Rs"), "xs": (mb, "stator leakage Xs"),
            "xm": (mb, "magnetising Xm"), "rr": (mb, "rotor resistance Rr"),
            "xr": (mb, "rotor leakage Xr"), "h_s": ("s, motor base", "inertia H"),
            "t0": (mb, "load torque T0"), "x_prime": (mb, "transient X'"),
            "x_open": (mb, "open-circuit X"), "t_prime_s": ("s", "transient T'"),
        }.items():  # fmt: skip
            q[k + t] = (unit, f"{what}: {meaning}")
    q |= {"vstall": ("p.u.", "motor D: stall voltage (at the load bus)"),
          "tstall": ("s", "motor D: time below the stall voltage before it stalls"),
          "vd1": ("p.u.", "electronics: voltage where they start to trip"),
          "vd2": ("p.u.", "electronics: voltage where all have tripped")}  # fmt: skip
    if getattr(model, "noise", "white") == "ar1":
        q |= {"rho_p": ("-", "AR(1) coefficient of P's noise (row to row)"),
              "rho_q": ("-", "AR(1) coefficient of Q's noise (row to row)")}  # fmt: skip
    for name in model.theta_names:
        q.setdefault(name, ("-", "sampled coordinate"))
    return q
