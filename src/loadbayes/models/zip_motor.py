"""The ``zip+motor`` composite as a model object: its options, checked once, and its sizes.

:class:`CompositeModel` is the :class:`~loadbayes.models.base.DynamicLoadModel` of a static
ZIP part and one third-order induction motor (the physics is
:mod:`loadbayes.models.composite`, the prior :mod:`loadbayes.models.composite_prior`). It
is a frozen object holding how the model is read (the torque law, the steps, the shares,
the noise and its likelihood, the phasor window, the frequency and the priors set by
name); its constructor checks every option once, with errors in Python's words
(:class:`~loadbayes.io.errors.OptionError`, a ``ValueError``), so that
:func:`loadbayes.fit.composite.fit_composite` and ``loadbayes fit composite`` (which maps
its flags onto these fields, ``commands/settings.py: COMPOSITE_FLAGS``) check nothing again.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, fields, replace
from types import MappingProxyType
from typing import Any, ClassVar

import numpy as np
from numpy.typing import NDArray

from loadbayes.measurements.record import EventRecord
from loadbayes.models.base import ModelOptionError as _Err
from loadbayes.models.composite import (
    BETA_NAMES,
    SCALE_FREE_MATRIX,
    SCALE_FREE_NAMES,
    THETA_NAMES,
    composition,
    design,
    motor_physical,
    motor_response,
)
from loadbayes.models.composite_prior import (
    COEFFICIENT_PRIOR_NAMES,
    THETA_PRIOR,
    CompositePrior,
)
from loadbayes.models.motor_kernel import H_MAX_S

__all__ = ["MOTOR_PRIOR_NAMES", "QUANTITIES", "CompositeModel"]

#: Log-normal priors by name (``priors={"h_s": (median, sd_log)}``, ``--prior h_s=...``)
#: -> the sampled log-parameter they set.
MOTOR_PRIOR_NAMES: Mapping[str, str] = MappingProxyType(
    {
        "rs": "log_rs",
        "x_prime": "log_x_prime",
        "dx": "log_dx",
        "t_prime_s": "log_t_prime",
        "h_s": "log_h",
        "t0": "log_t0",
    }
)

_PU_SYS, _PU_MOTOR = "p.u. system base", "p.u. motor base"
#: Every named draw's unit and meaning in words (the protocol's ``quantities``; an event's
#: suffix ``_e{k}`` and each step's number are added by ``report/composite_names.describe``).
#: "Motor base" is the motor's own rating (``mva_m``), whose size comes from the prior of
#: T0 (terminal data fix only their product).
QUANTITIES: Mapping[str, tuple[str, str]] = MappingProxyType(
    {
        "p0": (_PU_SYS, "load P at v0"),
        "q0": (_PU_SYS, "load Q at v0"),
        "v0": ("p.u.", "voltage at the first sample"),
        "f_m": ("-", "motor's share of p0"),
        "a1": ("-", "static P: constant-impedance share"),
        "a2": ("-", "static P: constant-current share"),
        "a3": ("-", "static P: constant-power share"),
        "a4": ("-", "static Q: constant-impedance share"),
        "a5": ("-", "static Q: constant-current share"),
        "a6": ("-", "static Q: constant-power share"),
        "mva_m": (_PU_SYS, "motor rating (MVA)"),
        "q_c": (_PU_SYS, "shunt Q (motor Q0)"),
        "rs": (_PU_MOTOR, "stator resistance Rs"),
        "xs": (_PU_MOTOR, "stator leakage reactance Xs (= Xr)"),
        "xm": (_PU_MOTOR, "magnetising reactance Xm"),
        "rr": (_PU_MOTOR, "rotor resistance Rr"),
        "xr": (_PU_MOTOR, "rotor leakage reactance Xr"),
        "h_s": ("s, motor base", "inertia constant H"),
        "a": ("-", "load torque share A (of A w^2 + B w + C)"),
        "b": ("-", "load torque share B (of A w^2 + B w + C)"),
        "c": ("-", "load torque share C (of A w^2 + B w + C)"),
        "t0": (_PU_MOTOR, "initial load torque T0"),
        "x_prime": (_PU_MOTOR, "transient reactance X'"),
        "x_open": (_PU_MOTOR, "open-circuit X"),
        "t_prime_s": ("s", "transient time constant T'"),
        "f_hz": ("Hz", "nominal frequency (the motor's time base)"),
        "tau_p": ("1/(p.u.)^2", "noise precision of P"),
        "tau_q": ("1/(p.u.)^2", "noise precision of Q"),
        "nu_p": ("-", "Student-t degrees of freedom of P's noise"),
        "nu_q": ("-", "Student-t degrees of freedom of Q's noise"),
        "log_rs": ("log p.u.", "log Rs (sampled)"),
        "log_x_prime": ("log p.u.", "log X' (sampled)"),
        "log_dx": ("log p.u.", "log (X - X') (sampled)"),
        "log_t_prime": ("log s", "log T' (sampled)"),
        "log_h": ("log s", "log H (sampled)"),
        "log_t0": ("log p.u.", "log T0 (sampled)"),
        "log_a_over_c": ("-", "log(A/C), torque (sampled)"),
        "log_b_over_c": ("-", "log(B/C), torque (sampled)"),
        "t_step": ("s", "instant of voltage step {j} (event clock)"),
    }
)

_CHOICES = {
    "shares": ("free", "bounded"),
    "noise": ("white", "ar1"),
    "likelihood": ("normal", "student-t"),
}


def _torque(value: Any) -> tuple[float, float, float] | str:
    if isinstance(value, str):
        if value.strip().lower() == "estimate":
            return "estimate"
        raise _Err(f"{{torque}} {value!r}: expected (A, B, C) or 'estimate'")
    try:
        a, b, c = (float(x) for x in value)
    except (TypeError, ValueError):
        raise _Err(f"{{torque}} {value!r}: expected (A, B, C) or 'estimate'") from None
    if not all(math.isfinite(x) for x in (a, b, c)) or abs(a + b + c - 1) > 1e-9:
        raise _Err(f"{{torque}} {value!r}: A + B + C must be 1")
    return a, b, c


def _nu(likelihood: str, nu: Any) -> float | str:
    auto = isinstance(nu, str) and nu.strip().lower() == "auto"
    if likelihood != "student-t" and not auto:
        raise _Err("{nu} needs {likelihood} 'student-t'")
    if auto:
        return "auto"
    try:
        value = float(nu)
    except (TypeError, ValueError):
        raise _Err(f"{{nu}} {nu!r}: a positive number or 'auto'") from None
    if not (value > 0 and math.isfinite(value)):
        raise _Err(f"{{nu}} {nu!r}: a positive number or 'auto'")
    return value


#: A motor prior's median (in its unit) and sd of the log: beyond these the draws of
#: ``exp(log median + sd_log z)`` overflow (h_s=1e300 was two raw overflow warnings and a
#: fit), and no motor parameter is a millionth or a million of its unit.
MEDIAN_RANGE = (1e-6, 1e6)
MAX_SD_LOG = 5.0
#: A normal prior's smallest sd: a narrower one pins the quantity, its factor underflows
#: to 0 at every starting point (sd 1e-300 overflowed, then "no starting coefficients").
MIN_SD = 1e-6
#: The quantities that ``shares="bounded"`` holds in [0, 1].
SHARES = ("a1", "a2", "a3", "a4", "a5", "a6", "f_m")


def _pair(name: str, value: Any, *, log_normal: bool, bounded: bool = False) -> tuple[float, float]:
    what = "(MEDIAN, SD_LOG)" if log_normal else "(MEAN, SD)"
    try:
        a, b = (float(x) for x in value)
    except (TypeError, ValueError):
        raise _Err(f"{{priors}} {name}={value!r}: expected {what}") from None
    if log_normal and not (a > 0 and math.isfinite(a) and b > 0 and math.isfinite(b)):
        raise _Err(f"{{priors}} {name}: MEDIAN and SD_LOG must be positive and finite")
    if not log_normal and not (math.isfinite(a) and b > 0 and math.isfinite(b)):
        raise _Err(f"{{priors}} {name}: MEAN must be finite and SD positive")
    lo, hi = MEDIAN_RANGE
    if log_normal and not lo <= a <= hi:
        raise _Err(f"{{priors}} {name}: MEDIAN {a:g} is outside [{lo:g}, {hi:g}]")
    if log_normal and b > MAX_SD_LOG:
        raise _Err(f"{{priors}} {name}: SD_LOG {b:g} is above {MAX_SD_LOG:g} (a factor of "
                   f"e^{MAX_SD_LOG:g} either way is no prior knowledge)")  # fmt: skip
    if not log_normal and b < MIN_SD:
        raise _Err(f"{{priors}} {name}: SD {b:g} is below {MIN_SD:g} (so narrow a prior "
                   "pins it: no starting point meets it)")  # fmt: skip
    if bounded and name in SHARES and not 0 <= a <= 1:
        raise _Err(f"{{priors}} {name}: MEAN {a:g} is outside [0, 1], where {{shares}} "
                   f"bounded holds {name}")  # fmt: skip
    return a, b


@dataclass(frozen=True)
class CompositeModel:
    """ZIP + one induction motor at a bus, and how its events are read.

    Parameters
    ----------
    f_hz : float
        Nominal frequency, 10-1000 Hz (the motor's time base).
    torque : (A, B, C) or "estimate"
        Load torque ``T0 (A w^2 + B w + C)`` with ``A + B + C = 1``, or estimated under a
        Dirichlet(1, 1, 1) prior (:mod:`loadbayes.fit.composite.torque`).
    h_max : float
        RK4 sub-step of the motor kernel (s).
    steps : bool
        Each voltage step between two samples is a step at an unknown instant inside its
        interval (``models/composite_steps.py``); False reads it as a ramp across it.
    window_s : float, optional
        The recorder's phasor window (s, 0-1; default one cycle of ``f_hz``); 0: point
        samples, each the value at its instant.
    shares : {"free", "bounded"}
        ``"bounded"`` holds every static share in [0, 1] (and so ``f_m`` in (0, 1)).
    noise : {"white", "ar1"}
        Noise on P and Q independent from sample to sample, or AR(1) in each channel.
    likelihood : {"normal", "student-t"}
        The noise's law; Student-t adds latent weights.
    nu : float or "auto"
        Student-t degrees of freedom, fixed or sampled (only with "student-t").
    priors : mapping of str to (float, float)
        Log-normal priors ``{name: (median, sd_log)}`` of the motor (names in
        :data:`MOTOR_PRIOR_NAMES`) and normal priors ``{name: (mean, sd)}`` of every
        event's ``a1..a6, f_m, p0, q0`` (a factor on the coefficients).
    prior : CompositePrior, optional
        A whole prior instead of the default (not with motor priors by name).

    Raises
    ------
    loadbayes.io.errors.OptionError
        An option no fit can run with; the message names the field as Python spells it.
    """

    #: The model's name in the registry (``models/dynamic.py``) and in ``--model``.
    name: ClassVar[str] = "zip+motor"
    #: The model's log-parameters, and the scale-free coordinates the data inform (the
    #: first ``len(SCALE_FREE_NAMES)`` rows of ``SCALE_FREE_MATRIX``; the last row is the
    #: scale, ``log T0``, which only the prior sets).
    theta_names: ClassVar[tuple[str, ...]] = THETA_NAMES
    free_coordinates: ClassVar[tuple[str, ...]] = SCALE_FREE_NAMES
    scale_free: ClassVar[NDArray[np.float64]] = SCALE_FREE_MATRIX
    #: Each event's linear coefficients, in the order of :meth:`design`'s columns.
    beta_names: ClassVar[tuple[str, ...]] = BETA_NAMES
    #: Every named draw's unit and meaning in words (:data:`QUANTITIES`).
    quantities: ClassVar[Mapping[str, tuple[str, str]]] = QUANTITIES

    f_hz: float = 60.0
    torque: tuple[float, float, float] | str = (1.0, 0.0, 0.0)
    h_max: float = H_MAX_S
    steps: bool = True
    window_s: float | None = None
    shares: str = "free"
    noise: str = "white"
    likelihood: str = "normal"
    nu: float | str = "auto"
    priors: Mapping[str, tuple[float, float]] = field(default_factory=dict)
    prior: CompositePrior | None = None

    def __post_init__(self) -> None:
        set_ = object.__setattr__  # frozen: the checked, normalised values
        if not (isinstance(self.f_hz, (int, float)) and 10 <= self.f_hz <= 1000):
            raise _Err(f"{{f_hz}} {self.f_hz}: the nominal frequency must be 10-1000 Hz")
        set_(self, "torque", _torque(self.torque))
        if not (isinstance(self.h_max, (int, float)) and 0 < self.h_max < 1):
            raise _Err(f"{{h_max}} {self.h_max}: the RK4 sub-step must be in (0, 1) s")
        w = self.window_s
        if w is not None and not (isinstance(w, (int, float)) and math.isfinite(w) and 0 <= w <= 1):
            raise _Err(f"{{window_s}} {w}: the phasor window must be 0-1 s")
        for name, allowed in _CHOICES.items():
            value = getattr(self, name)
            if value not in allowed:
                raise _Err(f"{{{name}}} {value!r}: one of {', '.join(allowed)}")
        set_(self, "nu", _nu(self.likelihood, self.nu))
        if self.noise == "ar1" and self.likelihood != "normal":
            raise _Err("{noise} ar1 works with {likelihood} normal only")
        if self.shares == "bounded" and self.likelihood != "normal":
            raise _Err("{shares} bounded works with {likelihood} normal only (for now)")
        checked = {}
        for name, value in dict(self.priors or {}).items():
            if name in COEFFICIENT_PRIOR_NAMES:
                checked[name] = _pair(name, value, log_normal=False,
                                      bounded=self.shares == "bounded")  # fmt: skip
            elif name in MOTOR_PRIOR_NAMES:
                checked[name] = _pair(name, value, log_normal=True)
            else:
                raise _Err(
                    f"{{priors}} {name!r}: NAME must be one of {', '.join(MOTOR_PRIOR_NAMES)} "
                    f"(log-normal) or {', '.join(COEFFICIENT_PRIOR_NAMES)} (normal)"
                )
        set_(self, "priors", MappingProxyType(checked))
        if self.prior is not None and self.motor_priors:
            raise _Err("give either {prior} (a whole CompositePrior) or {priors} (by name)")

    # --- what the fit reads -------------------------------------------------------------

    @property
    def estimate_torque(self) -> bool:
        """Whether the torque shares are sampled (``torque="estimate"``)."""
        return self.torque == "estimate"

    @property
    def fixed_torque(self) -> tuple[float, float, float]:
        """The torque the problem is built with: the given one, or the prior's centre."""
        return (1 / 3, 1 / 3, 1 / 3) if self.estimate_torque else self.torque  # type: ignore[return-value]

    @property
    def motor_priors(self) -> dict[str, tuple[float, float]]:
        """The log-normal priors set by name (``{name: (median, sd_log)}``)."""
        return {n: v for n, v in self.priors.items() if n in MOTOR_PRIOR_NAMES}

    @property
    def coefficient_priors(self) -> dict[str, tuple[float, float]]:
        """The normal priors on every event's ``a1..a6, f_m, p0, q0`` (``{name: (mean, sd)}``)."""
        return {n: v for n, v in self.priors.items() if n in COEFFICIENT_PRIOR_NAMES}

    @property
    def n_free(self) -> int:
        """How many scale-free motor coordinates the sampler moves."""
        return len(self.free_coordinates)

    @property
    def n_beta(self) -> int:
        """How many linear coefficients each event has."""
        return len(self.beta_names)

    def replace(self, **changes: Any) -> CompositeModel:
        """A copy with some options changed (checked again)."""
        return replace(self, **changes)

    def options(self) -> dict[str, Any]:
        """The options as plain values (for provenance and the flag table's tests)."""
        return {f.name: getattr(self, f.name) for f in fields(self)}

    # --- the protocol: prior, response, design, composition -----------------------------

    def default_prior(self, events: Sequence[EventRecord]) -> CompositePrior:
        """The prior of ``events``: ``prior`` when given, else the default.

        The default reads the events' levels, with the motor's priors set by name
        (log-normal, ``(median, sd_log)``).
        """
        if self.prior is not None:
            return self.prior
        prior = CompositePrior.default(events)
        if not self.motor_priors:
            return prior
        mean, sd = prior.theta_mean.copy(), prior.theta_sd.copy()
        for name, (median, sd_log) in self.motor_priors.items():
            i = THETA_NAMES.index(MOTOR_PRIOR_NAMES[name])
            mean[i], sd[i] = math.log(median), sd_log
        return CompositePrior(mean, sd, prior.beta_sd, prior.tau_shape, prior.tau_rate)

    def response(self, event: EventRecord, theta: NDArray[np.float64], **kw: Any):
        """The motor's own-base P, Q of one event (``models.composite.motor_response``)."""
        kw.setdefault("window_s", 1.0 / self.f_hz if self.window_s is None else self.window_s)
        return motor_response(
            event, theta, f_hz=self.f_hz, torque=self.fixed_torque, h_max=self.h_max, **kw
        )

    design = staticmethod(design)
    composition = staticmethod(composition)

    def physical(self, theta: NDArray[np.float64]) -> dict[str, NDArray]:
        """The motor's physical parameters of log-parameters ``theta`` (..., 6)."""
        return motor_physical(theta, f_hz=self.f_hz)


#: The prior's default medians and spreads, for the docs and the flag table's help.
DEFAULT_MOTOR_PRIOR = MappingProxyType(dict(THETA_PRIOR))
