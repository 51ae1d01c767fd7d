"""A model of parts (``slm``, ``cmld-lite``) as the WECC composite load holds it.

A fit of a model of parts (:mod:`loadbayes.models.parts_model`) names its draws by part:
the series impedance ``x_fd, r_fd`` (p.u. on the load's own base, ``|S|`` of the recorded
bus at event 0's first sample), each motor's ``rs, x_open, x_prime, t_prime_s, h_s, t0``
(suffix ``_a``, ``_b`` for ``cmld-lite``'s motors A and B, none for ``slm``'s one motor),
the shares of the load bus's P (``f_m_a``, ``f_m_b`` or ``f_m``, ``f_d``, ``f_el``,
``f_s``), the static P's ZIP split ``a1, a2, a3``, and per event the load bus's ``p0, q0``
and the static Q's terms ``cq2, cq1, cq0`` (event 0 without a suffix is exported). The
fixed fields (motor classes and their torque laws, ``rx``, motor D's constants, the
electronics' ``vd1, vd2, frcel``) are in the fit's ``settings.model_options``.

:func:`parts_load` turns one parameter set and those options into a :class:`PartsLoad`:

- **The recorded bus's power** (the power flow's load): the load bus draws
  ``S_L = p0 + j q0`` and the series impedance, ``z = (r_fd + j x_fd) / s`` in system p.u.
  with ``s = |S|`` at the recorded bus, adds ``z s^2 / V^2``; so ``S = S_L + c s`` with
  ``c = (r_fd + j x_fd) / V^2``, and ``s`` is the positive root of
  ``(1 - |c|^2) s^2 - 2 Re(S_L conj c) s - |S_L|^2 = 0``.
- **The record's MVA base** is that ``s`` (in MVA): the impedance's p.u. values are then
  the fit's numbers exactly. The series impedance is transformer + feeder lumped; the
  WECC model's transformer is a reactance (``Xxf``) and its feeder ``Rfdr + j Xfdr``:
  the resistance goes to the feeder, with a feeder X equal to its R (X/R = 1, as the
  WECC typical feeder, Rfdr = Xfdr = 0.04), and the rest of the X to the transformer:
  ``Rfdr = r_fd, Xfdr = min(x_fd, r_fd), Xxf = x_fd - Xfdr``. With no compensation
  between them (``Bss = 0``, ``Fb = 0``: the fit's capacitors are at the load bus) and a
  fixed tap of 1 (no LTC) the two are one series impedance, as fitted.
- **The motors' loading factor** ``LFm`` is the motor's own-base P at its steady state at
  the load bus's first voltage (so its rating is ``f_m p0 / LFm``, the fit's ``mva``).
- **The static Q** is the load bus's whole ``q0`` (the fit compensates each dynamic part's
  Q at the first sample by a capacitor; the WECC model's initialisation computes that
  capacitor, the feeder's B, the same way); ``PFs`` carries its sign, and its ZIP split is
  ``cq2 / q0, cq1 / q0`` (constant impedance, constant current; the rest constant Q).
- **Fractions**: the record's static fraction is what the others leave (CMLDBLU2 has no
  field for it), so with marginal medians it is ``1 - sum`` of the others' medians, not
  the median of ``f_s``: both are in the notes.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

__all__ = ["PARTS_MODELS", "PartsLoad", "parts_load", "parts_names", "rebuild_model"]

#: The models of parts the exports take (``settings.model`` of a ``fit composite``).
PARTS_MODELS = ("slm", "cmld-lite")
_MOTOR_KEYS = ("rs", "x_open", "x_prime", "t_prime_s", "h_s", "t0")


@dataclass
class PartsLoad:
    """One parameter set of a model of parts, as the WECC composite load's fields need.

    Powers in MW and Mvar (``s_base_mva`` times the fit's system p.u.); impedances in p.u.
    of ``mva_base``; ``motors`` maps the WECC letter (``A``, ``B``) to its fields
    (``rs, ls, lp, tpo, h, etrq, lfm``); ``fractions`` maps ``A, B, D, el, s`` to shares
    of the load bus's P summing to 1.
    """

    model: str
    p_mw: float
    q_mvar: float
    v0: float
    v_load: float
    p_load_mw: float
    q_load_mvar: float
    mva_base: float
    r_fd: float
    x_fd: float
    fractions: dict[str, float]
    motors: dict[str, dict[str, float]]
    zip_p: tuple[float, float, float]
    zip_q: tuple[float, float, float]
    options: Mapping[str, Any]
    notes: list[str] = field(default_factory=list)


def _tags(options: Mapping[str, Any]) -> list[tuple[str, str]]:
    motors = list(options.get("motors") or [])
    if not motors:
        raise ValueError("settings.model_options.motors is missing: not a model of parts' fit")
    if len(motors) > 2:
        raise ValueError(f"{len(motors)} motors: the export maps at most two (WECC A and B)")
    tags = [""] if len(motors) == 1 else [f"_{m}" for m in motors]
    return list(zip("AB", tags, strict=False))


def parts_names(options: Mapping[str, Any]) -> list[str]:
    """The parameters an export of this model of parts reads."""
    names = ["p0", "q0", "v0", "cq2", "cq1", "cq0", "a1", "a2", "f_s"]
    if options.get("feeder", True):
        names += ["x_fd", "r_fd"]
    for _, t in _tags(options):
        names += [k + t for k in _MOTOR_KEYS] + ["f_m" + t]
    names += ["f_d"] * bool(options.get("motor_d")) + ["f_el"] * bool(options.get("electronics"))
    return names


def _recorded(p0: float, q0: float, r: float, x: float, v: float) -> tuple[complex, float]:
    """The recorded bus's ``S`` and the load bus's ``|V|`` (see the module docstring)."""
    s_l = complex(p0, q0)
    c = complex(r, x) / v**2
    a = 1.0 - abs(c) ** 2
    b = (s_l * c.conjugate()).real
    s = (b + math.sqrt(b * b + a * abs(s_l) ** 2)) / a
    s_rec = s_l + c * s
    z = complex(r, x) / s if s > 0 else 0j
    v_l = abs(v - z * (s_rec / v).conjugate())
    return s_rec, v_l


def _lfm(vals: Mapping[str, float], t: str, torque, f_hz: float, v_load: float) -> float:
    from loadbayes.models.motor_kernel import steady_state

    rs, xo, xp, tp, t0 = (vals[k + t] for k in ("rs", "x_open", "x_prime", "t_prime_s", "t0"))
    a, b, c = (float(x) for x in torque)
    p = steady_state(rs, xp, xo - xp, tp, 2 * math.pi * f_hz, v_load, t0, a, b, c)[3]
    if not (math.isfinite(p) and p > 0):
        raise ValueError(
            f"motor{t or ''} has no steady state at the load bus's {v_load:.4g} p.u. with "
            f"t0{t} = {t0:.4g}: no loading factor to write"
        )
    return float(p)


def parts_load(values: Mapping[str, float], *, model: str, options: Mapping[str, Any]) -> PartsLoad:
    """One parameter set of a model of parts as the WECC composite load's quantities.

    Parameters
    ----------
    values : mapping of str to float
        The fit's named draws (one value each: a median, the mean or one draw).
    model : {"slm", "cmld-lite"}
        The model (``settings.model``).
    options : mapping
        ``model_options`` (the fit's ``settings.model_options``), ``s_base_mva`` (MVA per
        p.u., default 1) and ``f_hz`` (default the model's).

    Returns
    -------
    PartsLoad

    Raises
    ------
    ValueError
        For missing parameters, shares off their simplex, or a motor with no steady state.
    """
    if model not in PARTS_MODELS:
        raise ValueError(f"model {model!r} is not a model of parts ({', '.join(PARTS_MODELS)})")
    mo = options.get("model_options")
    if not isinstance(mo, Mapping):
        raise ValueError("settings.model_options is missing: the fit's parts cannot be rebuilt")
    # Thresholds the fit sampled (``fit_thresholds``) are the parameter set's own.
    fitted = {k: float(values[k]) for k in ("vstall", "tstall", "vd1", "vd2") if k in values}
    if fitted:
        d = {**(mo.get("motor_d_params") or {})}
        d.update({k: fitted[k] for k in ("vstall", "tstall") if k in fitted})
        mo = {**mo, **{k: fitted[k] for k in ("vd1", "vd2") if k in fitted},
              "motor_d_params": d}  # fmt: skip
    missing = [n for n in parts_names(mo) if n not in values]
    if missing:
        raise ValueError(f"a {model} parameter set needs {', '.join(missing)}: missing")
    sbase = float(options.get("s_base_mva") or 1.0)
    f_hz = float(mo.get("f_hz") or options.get("f_hz") or 60.0)
    v0 = float(values["v0"])
    p0, q0 = float(values["p0"]), float(values["q0"])
    if not (p0 > 0 and v0 > 0):
        raise ValueError(
            f"the load bus draws p0 = {p0:.6g} at v0 = {v0:.4g}: a load needs both > 0"
        )
    r_fd = float(values.get("r_fd", 0.0))
    x_fd = float(values.get("x_fd", 0.0))
    s_rec, v_load = _recorded(p0, q0, r_fd, x_fd, v0)
    classes = mo.get("motor_classes") or {}
    motors: dict[str, dict[str, float]] = {}
    fractions: dict[str, float] = {}
    for (letter, t), name in zip(_tags(mo), mo["motors"], strict=True):
        torque = (classes.get(name) or {}).get("torque")
        if torque is None:
            raise ValueError(f"settings.model_options.motor_classes has no torque law of {name!r}")
        a, b, _ = (float(x) for x in torque)
        motors[letter] = {
            "rs": values["rs" + t], "ls": values["x_open" + t], "lp": values["x_prime" + t],
            "tpo": values["t_prime_s" + t], "h": values["h_s" + t],
            "etrq": 2.0 * a + b,  # T0 w^Etrq: exact for constant (0) and speed-squared (2)
            "lfm": _lfm(values, t, torque, f_hz, v_load), "t0": values["t0" + t],
        }  # fmt: skip
        fractions[letter] = float(values["f_m" + t])
    if mo.get("motor_d"):
        fractions["D"] = float(values["f_d"])
    if mo.get("electronics"):
        fractions["el"] = float(values["f_el"])
    others = sum(fractions.values())
    fractions["s"] = 1.0 - others
    bad = [f"{k} = {v:.4g}" for k, v in fractions.items() if not 0.0 <= v <= 1.0]
    if bad:
        raise ValueError(f"fractions off [0, 1] ({', '.join(bad)}): not a load of parts")
    a1, a2 = float(values["a1"]), float(values["a2"])
    zip_p = (a1, a2, 1.0 - a1 - a2)
    cq = [float(values[k]) for k in ("cq2", "cq1", "cq0")]
    if abs(q0) < 1e-9 * abs(p0):
        raise ValueError("q0 is 0: the static Q's split cq2/q0, cq1/q0 has no value (PFs = 1)")
    zip_q = (cq[0] / q0, cq[1] / q0, cq[2] / q0)
    notes = [
        f"{model}: the recorded bus draws {s_rec.real * sbase:.6g} MW, {s_rec.imag * sbase:.6g} "
        f"Mvar at v0 = {v0:.6g} (the load bus {p0 * sbase:.6g} MW, {q0 * sbase:.6g} Mvar at "
        f"{v_load:.6g} p.u., the series impedance's losses between)",
        f"series impedance r_fd + j x_fd = {r_fd:.6g} + j {x_fd:.6g} p.u. on the load's "
        f"{abs(s_rec) * sbase:.6g} MVA (|S| at event 0's first sample)",
    ]
    if abs(fractions["s"] - float(values["f_s"])) > 1e-9:
        notes.append(
            f"static fraction {fractions['s']:.6g} = 1 - the other fractions (CMLDBLU2 has "
            f"no field for it); the posterior's f_s is {float(values['f_s']):.6g} (marginal "
            "statistics of shares do not sum to 1)"
        )
    return PartsLoad(
        model=model, p_mw=s_rec.real * sbase, q_mvar=s_rec.imag * sbase, v0=v0,
        v_load=v_load, p_load_mw=p0 * sbase, q_load_mvar=q0 * sbase,
        mva_base=abs(s_rec) * sbase, r_fd=r_fd, x_fd=x_fd, fractions=fractions,
        motors=motors, zip_p=zip_p, zip_q=zip_q, options=mo, notes=notes,
    )  # fmt: skip


def rebuild_model(settings: Mapping[str, Any]):
    """The fit's model of parts rebuilt from its ``settings`` (None for any other fit).

    ``settings.model`` names it and ``settings.model_options`` holds every field
    (``PartsModel.options``); ``motor_classes`` is what the classes meant, not a field.

    Raises
    ------
    ValueError
        When the options are missing or do not build the model.
    """
    import dataclasses

    from loadbayes.models.dynamic import DYNAMIC_MODELS, dynamic_model

    name = settings.get("model")
    if name not in PARTS_MODELS:
        return None
    mo = settings.get("model_options")
    if not isinstance(mo, Mapping):
        raise ValueError(
            f"a {name} fit without settings.model_options: its parts cannot be rebuilt"
        )
    known = {f.name for f in dataclasses.fields(DYNAMIC_MODELS[name])}
    kw = {k: v for k, v in mo.items() if k in known}
    kw.setdefault("fit_thresholds", False)  # a fit made before they were sampled
    if "motors" in kw:
        kw["motors"] = tuple(kw["motors"])
    if "priors" in kw:
        kw["priors"] = {k: tuple(v) for k, v in kw["priors"].items()}
    try:
        return dynamic_model(name, **kw)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"settings.model_options do not build the {name} model: {exc}") from None
