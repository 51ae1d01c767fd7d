"""A dynamic load built from parts: feeder, motors, motor D, electronics, static ZIP.

One idea needs these lines: :class:`PartsModel`, the one class that maps a sampled
vector to every part's physics and the likelihood's channels (its prior is
``part_priors.parts_prior``, its compiled sums ``parts_kernel``).

:class:`PartsModel` is a :class:`~loadbayes.models.base.DynamicLoadModel` whose load is
assembled from the parts of :mod:`loadbayes.models.parts` behind an optional series
impedance; the named models (``slm``, ``cmld-lite``) are its instances with their parts
chosen (``models/slm.py``, ``models/cmld_lite.py``).

**What is sampled and what is linear.** The shares are physical by construction: the
shares of the load's P among the parts (static, each motor, motor D, electronics) and
of the static P among Z, I and P (and of the static Q) are sampled on their simplex in
additive log-ratio coordinates, under a uniform Dirichlet prior. Each event's linear
coefficients are the load bus's P at its first sample and the static part's Q as
constant-impedance, -current and -power terms, ``beta = (p0, cq2, cq1, cq0)``,
integrated out exactly (the Q terms take either sign: the static part's Q and the
shunt capacitors, a negative constant-impedance term, are one column)::

    P_L(t) = p0 [f_s (a1 x^2 + a2 x + a3) + sum_k f_k p_k(t) / p_k(0)
                 + f_d p_d(t) / p_d(0) + f_e e(t)]
    Q_L(t) = cq2 x^2 + cq1 x + cq0
             + p0 [sum_k f_k (q_k(t) - q_k(0) x^2) / p_k(0) + f_d (...)]

with ``x = V_L / V_L(0)`` the load bus's voltage, ``p_k, q_k`` each motor's own-base
response (``models/motor_kernel``), ``p_d, q_d`` motor D's, ``e`` the electronics'
connected share. Each dynamic part's magnetising Q at the first sample is compensated
by a shunt capacitor (as in ``zip+motor`` and the WECC model), so ``q0 = cq2 + cq1 +
cq0`` is the whole load's Q. The recorded P, Q are ``P_L, Q_L`` plus the feeder's losses
(``parts.load_bus``).

Each motor is sampled in its scale-free coordinates (``log(Rs T0), log(X' T0),
log((X - X') T0), log T', log(H / T0)``: what a positive-sequence record determines)
and ``log T0``, which terminal data never see: a motor of rating S with own-base
impedances Z is Z / S at its terminals in both sequences, so the negative sequence
(a running motor's admittance about S / (Rs + jX')) measures the same combination the
positive sequence sees through ``X' T0``, more sharply; the rating in MVA then rests
on the published range of the own-base X' (tests/statistical/test_parts_negative_sequence.py).
The Gaussian log-normal priors of the physical parameters are mapped exactly into
those coordinates (``part_priors.PartsPrior``).

**The negative sequence as data.** Where an event carries the negative-sequence
phasors ``v2, i2`` (``EventRecord``) and is unbalanced (some ``|V2|`` above
:data:`NEG_SEQ_MIN`), the rows where ``|V2|`` is that large add a third channel:
``I2 = V2_L (p0 Y_p - j q0 / V_L(0)^2)`` with each part's negative-sequence admittance (the
motors at slip ``2 - s`` with their capacitors, the static part and motor D as the
constant impedances of their operating points, the electronics none), behind the same
series impedance, with its own noise precision. Whatever that option, the motors brake
with the load bus's ``|V2_L|`` at those rows (``motor_kernel.brake_torque``,
``parts.brake_drive``): the negative sequence is their physics as well as data.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any, ClassVar

import numpy as np
from numpy.typing import NDArray

from loadbayes.core.kept import Kept, PerObject, token
from loadbayes.measurements.record import EventRecord
from loadbayes.models.base import ModelOptionError
from loadbayes.models.composite import SCALE_FREE_MATRIX, motor_physical, motor_response
from loadbayes.models.composite_steps import FitSamples
from loadbayes.models.part_priors import (
    MOTOR_CLASSES,
    MOTOR_KEYS,
    THRESHOLD_COORDS,
    THRESHOLD_PRIORS,
    X_PRIME_RANGE,
    PartsPrior,
    parts_prior,
)
from loadbayes.models.parts import (
    MOTOR_D_DEFAULTS,
    NEG_SEQ_MIN,
    brake_drive,
    electronics_fraction,
    gaps_of,
    load_bus,
    motor_d,
    motor_y2,
    step_knots,
    step_times,
)
from loadbayes.models.parts_state import feeder_of, lowest_load_bus
from loadbayes.models.parts_sums import (
    KEEP,
    event_arrays,
    model_basis,
    model_constants,
    model_sums,
    threshold_pairs,
)

__all__ = ["NEG_SEQ_MIN", "SHARE_STEPS", "PartsModel"]

#: The sampler's rounds of share-only steps per iteration by default (docs/composite.md,
#: "The shares' own steps": their cost measured against the joint move's).
SHARE_STEPS = 20

# Scale-free motor coordinates from the logs of (Rs, X', X - X', T', H, T0).
_SCALE_FREE = SCALE_FREE_MATRIX  # (Rs T0, X' T0, (X - X') T0, T', H / T0, T0) from the logs
_INV_SCALE_FREE = np.linalg.inv(_SCALE_FREE)
_MOTOR_COORDS = ("log_rs_t0", "log_x_prime_t0", "log_dx_t0", "log_t_prime", "log_h_over_t0",
                 "log_t0")  # fmt: skip


def alr_simplex(z: NDArray) -> NDArray:
    """The shares whose additive log-ratios are ``z`` (last axis; the last share's is 0)."""
    z = np.concatenate([z, np.zeros(z.shape[:-1] + (1,))], axis=-1)
    e = np.exp(z - z.max(axis=-1, keepdims=True))
    return e / e.sum(axis=-1, keepdims=True)


@dataclass(frozen=True)
class PartsModel:
    """A load of parts behind a feeder (see the module docstring)."""

    name: ClassVar[str] = "parts"
    #: The sampler's jumps after burn-in propose from a mixture of t's over this many
    #: regions of the pooled burn-in (as ``zip+motor``'s 10, ``fit/composite/sampler``);
    #: 1: one t. Ten let chains that found different modes jump between them, but moved
    #: the GridDyn check's motor share off its truth (docs/composite.md, "Two modes of
    #: cmld-lite"), so a model of parts keeps one t by default.
    jump_regions: ClassVar[int] = 1
    #: Chains whose burn-in ended in a mode far lower in density than the best chain's
    #: go on from the best chain's state, and the fit says so (``fit/composite/restart.py``).
    restart_modes: ClassVar[bool] = True
    #: Steps of the sampler's block move (every sampled coordinate at once) per iteration,
    #: before the thresholds' and shares' own steps (``fit/composite/sampler.py``). Each
    #: step leaves the posterior invariant, so any number does; a model whose motors'
    #: block diffuses slowly along a flat ridge asks for more (``cmld-lite``).
    block_steps: ClassVar[int] = 1
    #: With several block steps per iteration, how many of them jump (on average) after
    #: burn-in (``sampler.jump_share``); None: the sampler's share of every step.
    jumps_per_iteration: ClassVar[float | None] = None
    motors: tuple[str, ...] = ("slm",)
    feeder: bool = True
    motor_d: bool = False
    electronics: bool = False
    f_hz: float = 60.0
    rx: float = 0.35
    negative_sequence: str = "auto"
    #: The recorder's phasor window (s): each sample read as the motors' mean over it
    #: (0: point samples, as simulators write them).
    window_s: float = 0.0
    #: Hold each motor in the physical region a planner can use (Rs <= ``rs_max``, H >=
    #: ``h_min``, ``x_prime_min`` <= X' <= ``x_prime_max`` on its own base; X' from
    #: published locked-rotor currents, ``part_priors.X_PRIME_RANGE``) as hard limits of
    #: its prior; False: the log-normal priors alone, and a fit outside is only said.
    physical_region: bool = True
    rs_max: float = 0.1
    h_min: float = 0.05
    x_prime_min: float = X_PRIME_RANGE[0]
    x_prime_max: float = X_PRIME_RANGE[1]
    vd1: float = 0.70
    vd2: float = 0.50
    frcel: float = 0.0
    #: Sample motor D's stall voltage and time and the electronics' trip voltages
    #: (``vstall, tstall, vd1, vd2``) under their priors (``part_priors.THRESHOLD_PRIORS``)
    #: with the rest; False: hold them at ``motor_d_params`` and ``vd1, vd2``.
    fit_thresholds: bool = True
    motor_d_params: Mapping[str, float] = field(default_factory=dict)
    #: ``"ar1"``: AR(1) noise on P and Q, one coefficient each (the negative-sequence
    #: current stays white); ``"white"``: independent from row to row.
    noise: str = "white"
    #: AR(1) noise: ``rho_p``, ``rho_q`` uniform on ``(-rho_max, rho_max)``; 0.999 (the
    #: sampler's own bound, ``inference/ar1.RHO_MAX``) leaves them free. On a short record
    #: they can run to a random walk (docs/composite.md, "Known limitations").
    rho_max: float = 0.999
    #: Rounds of the sampler's share-only steps per iteration (``fit/composite/shares.py``:
    #: the shares moved through their basis, no motor solve); 0: none, the joint move alone.
    share_steps: int = SHARE_STEPS
    priors: Mapping[str, tuple[float, float]] = field(default_factory=dict)
    coefficient_priors: Mapping[str, tuple[float, float]] = field(default_factory=dict)

    def __post_init__(self) -> None:
        for m in self.motors:
            if m not in MOTOR_CLASSES:
                raise ModelOptionError(f"{{motors}}: no motor class {m!r} (one of "
                                       f"{', '.join(MOTOR_CLASSES)})")  # fmt: skip
        if not (math.isfinite(self.f_hz) and self.f_hz > 0):
            raise ModelOptionError(f"{{f_hz}} {self.f_hz!r}: a positive frequency")
        if self.negative_sequence not in ("auto", "on", "off"):
            raise ModelOptionError("{negative_sequence}: one of auto, on, off")
        if self.noise not in ("white", "ar1"):
            raise ModelOptionError("{noise}: one of white, ar1")
        if not 0 < self.rho_max <= 0.999:
            raise ModelOptionError(f"{{rho_max}} {self.rho_max!r}: in (0, 0.999]")
        if not (isinstance(self.share_steps, int) and 0 <= self.share_steps <= 10_000):
            raise ModelOptionError(f"{{share_steps}} {self.share_steps!r}: 0 to 10000 rounds")
        if not (math.isfinite(self.window_s) and 0 <= self.window_s <= 1):
            raise ModelOptionError(f"{{window_s}} {self.window_s!r}: 0 to 1 s")
        if not 0 < self.x_prime_min < self.x_prime_max:
            raise ModelOptionError("{x_prime_min} and {x_prime_max}: 0 < x_prime_min < x_prime_max")
        if not 0 <= self.vd2 < self.vd1 <= 1.2:
            raise ModelOptionError("{vd1} and {vd2}: 0 <= vd2 < vd1")
        unknown = set(self.motor_d_params) - set(MOTOR_D_DEFAULTS)
        if unknown:
            raise ModelOptionError(f"{{motor_d_params}}: no parameter {sorted(unknown)[0]!r}")
        if self.coefficient_priors:
            raise ModelOptionError("{coefficient_priors}: the shares of a model of parts are "
                                   "on their simplex already; give priors by name")  # fmt: skip
        tags = [self._tag(m) for m in self.motors]
        parts = [f"m{t}" for t in tags] + ["d"] * self.motor_d + ["el"] * self.electronics
        names: list[str] = ["log_x_fd"] if self.feeder else []
        for t in tags:
            names += [c + t for c in _MOTOR_COORDS]
        thr = []
        if self.fit_thresholds:
            thr = ["vstall", "tstall"] * self.motor_d + ["vd1", "vd2"] * self.electronics
        names += [THRESHOLD_COORDS[k] for k in thr]
        n_gauss = len(names)
        names += [f"lr_{p}" for p in parts]  # log(f_part / f_static)
        names += ["lr_a1", "lr_a2"]
        known = {*MOTOR_KEYS} | {"x_fd"} | set(THRESHOLD_PRIORS)
        for key in self.priors:
            base = key.rsplit("_", 1)[0] if key.rsplit("_", 1)[-1] in ("a", "b") else key
            if base not in known:
                raise ModelOptionError(f"{{priors}}: no parameter {key!r} to set a prior on")
        set_ = object.__setattr__
        set_(self, "theta_names", tuple(names))
        set_(self, "free_coordinates", tuple(names))
        set_(self, "scale_free", np.eye(len(names)))
        set_(self, "beta_names", ("p0", "cq2", "cq1", "cq0"))
        set_(self, "parts", tuple(parts))
        set_(self, "_n_gauss", n_gauss)
        set_(self, "_tags", tuple(tags))
        set_(self, "thresholds", tuple(thr))
        set_(self, "_kept", PerObject())  # drive_of, per event (core/kept.py: not by id)
        set_(self, "_lowest", Kept(4096))
        set_(self, "_of_theta", Kept(64))  # parts_sums._of_theta, _shares_of
        set_(self, "_shares", Kept(64))
        set_(self, "_responses", Kept(64))  # load_columns: each motor's response, kept
        set_(self, "_fixed", PerObject())  # parts_sums._fixed_of, per event
        set_(self, "_solved", Kept(KEEP))  # parts_sums._entry: each event's parts solved
        set_(self, "_threshold_pairs", threshold_pairs(self))
        set_(self, "constants", model_constants(self))  # parts_state.parts_constants' arrays

    def _tag(self, m: str) -> str:
        return "" if len(self.motors) == 1 else f"_{m}"

    # -- the prior ---------------------------------------------------------------------

    def default_prior(self, events: Sequence[EventRecord]) -> PartsPrior:
        """Log-normal physical priors mapped into the sampled coordinates, flat shares."""
        return parts_prior(self, events)

    # -- the physics -------------------------------------------------------------------

    def _split(self, theta: NDArray, shares: bool = True) -> dict[str, Any]:
        # shares False: the parts' own parameters alone (no "f", "a_p": parts_sums).
        th = np.asarray(theta, dtype=float)
        out: dict[str, Any] = {}
        i = 0
        if self.feeder:
            out["x_fd"] = np.exp(th[..., 0])
            i = 1
        inv = _INV_SCALE_FREE
        out["motors"] = []
        for _ in self.motors:
            logs = th[..., i : i + 6] @ inv.T
            out["motors"].append(logs)
            i += 6
        params = {**MOTOR_D_DEFAULTS, **self.motor_d_params}
        fixed = {"vstall": params["vstall"], "tstall": params["tstall"], "vd1": self.vd1,
                 "vd2": self.vd2}  # fmt: skip
        for name in fixed:
            if name in self.thresholds:
                x = th[..., i]
                out[name] = np.exp(x) if THRESHOLD_COORDS[name].startswith("log_") else x
                i += 1
            else:
                out[name] = fixed[name]
        if shares:
            out["f"], out["a_p"] = self._split_shares(th)
        return out

    def _split_shares(self, theta: NDArray) -> tuple[NDArray, NDArray]:
        # The parts' shares of P (static last) and the static P's split, from theta (...,).
        i, k = self._n_gauss, len(self.parts)
        return alr_simplex(theta[..., i : i + k]), alr_simplex(theta[..., i + k : i + k + 2])

    def uses_negative_sequence(self, event: EventRecord) -> bool:
        """Whether ``event``'s negative sequence enters the likelihood (see the docstring)."""
        if self.negative_sequence == "off":
            return False
        v2, i2 = getattr(event, "v2", None), getattr(event, "i2", None)
        if v2 is None or i2 is None:
            if self.negative_sequence == "on":
                raise ModelOptionError(
                    f"{{negative_sequence}} on: event {event.name or ''} has no v2, i2 columns"
                )
            return False
        return int(np.sum(np.abs(v2) >= NEG_SEQ_MIN)) >= 3

    def channels(self, event: EventRecord, theta: NDArray) -> list[tuple[NDArray, NDArray]] | None:
        """Each channel's design on ``beta = (p0, cq2, cq1, cq0)`` and target: P, Q, maybe I2."""
        c = self._split(theta)
        keep, steps = self.drive_of(event)
        recorded = event
        if keep.size < event.n:  # the rows inside a step left out: a gap, stepped across
            event = event.take(keep)
        x_fd = self.feeder_x(event.p[0], event.q[0], c)
        lb = load_bus(event, self.rx * x_fd, x_fd)
        ev = lb.event
        v2 = getattr(event, "v2", None)  # without I2 the feeder's drop of V2 is unknown
        cols = self.load_columns(ev, c, steps, brake_drive(v2, v2 if lb.v2 is None else lb.v2),
                                 kept=(recorded, x_fd))  # fmt: skip
        if cols is None:
            return None
        col_p, col_qp, y2p = cols
        xl = ev.v / ev.v[0]
        zero = np.zeros(ev.n)
        out = [
            (np.column_stack([col_p, zero, zero, zero]), ev.p),
            (np.column_stack([col_qp, xl * xl, xl, np.ones(ev.n)]), ev.q),
        ]
        if self.negative_sequence != "off":
            out.append(self._i2(event, lb, y2p, ev.v[0]))
        for z, y in out:
            # A proposal far outside the physics (a motor with no steady state nearby)
            # can give columns that overflow the sums: infeasible, as a NaN is.
            huge = z.size and np.abs(z).max() > 1e6
            if huge or not (np.isfinite(z).all() and np.isfinite(y).all()):
                return None
        return out

    def kept(self, event: EventRecord) -> NDArray[np.int64]:
        """The samples the likelihood reads: with a phasor window, those outside a step.

        A phasor row whose window straddles a fault's inception or clearing is a mean
        across the step: the event's own ``straddle`` flags where its reader set them,
        else ``models/composite_steps.FitSamples``' edges (as ``zip+motor`` leaves them
        out); point samples (``window_s`` 0) are all kept.
        """
        return self.drive_of(event)[0]

    def drive_of(self, event: EventRecord) -> tuple[NDArray[np.int64], NDArray]:
        """``(kept, steps)``: the kept rows and each gap's step instant (``parts.step_times``)."""
        got = self._kept.get(event)
        if got is None:
            keep = np.arange(event.n)
            if self.window_s > 0:
                if event.straddle is not None:
                    keep = np.flatnonzero(~np.asarray(event.straddle, dtype=bool))
                else:
                    found = FitSamples.find([event.t], [event.v], window_s=self.window_s,
                                            detect=True)  # fmt: skip
                    keep = np.asarray(found.keep[0], dtype=np.int64)
            steps = step_times(event.t, event.v, keep, self.window_s)
            got = self._kept.keep(event, (keep, steps))
        return got

    def event_sums(self, event: EventRecord, theta: NDArray, ar: bool = False):
        """The channels' sums ``(ztz, zty, yty, n)`` at ``theta`` in one compiled call.

        The same numbers as :meth:`channels` summed (``models/parts_sums.py``); None
        where infeasible. With ``ar``, P's and Q's AR(1) sums beside them
        (``parts_sums.model_sums``), the same as :meth:`first_rows` and ``channels``
        give ``inference.ar1.ar_moments``.
        """
        return model_sums(self, event, theta, ar)

    def event_basis(self, event: EventRecord, theta: NDArray, ar: bool = False):
        """The shares' basis sums at ``theta``'s other coordinates (``parts_kernel``).

        ``(bb, by, yy, n)``: each channel's ``B'B, B'y, y'y`` over the weights ``(f_1,
        ..., f_K, f_s a1, f_s a2, f_s a3)`` and three fixed columns, so that
        :meth:`event_sums` at any shares is ``W'(B'B)W, W'(B'y), y'y``
        (``parts_kernel.event_basis``); None where some shares would be infeasible.
        """
        return model_basis(self, event, theta, ar)

    def first_rows(self, event: EventRecord) -> NDArray[np.bool_]:
        """Over the kept rows, True where an AR(1) segment starts: the first, after a gap.

        The noise runs on from row to row except where rows were left out (a phasor
        window across a step) or the record has a hole (``parts.gaps_of``).
        """
        keep, steps = self.drive_of(event)
        gap = gaps_of(np.asarray(event.t, dtype=float)[keep], steps)
        return np.concatenate([[True], gap[: keep.size - 1]])

    def with_thresholds(self, theta: NDArray, values: Mapping[str, NDArray]) -> NDArray:
        """``theta`` (..., k) with the sampled thresholds set to ``values`` (by name)."""
        out = np.array(theta, dtype=float)
        for name in self.thresholds:
            if name in values:
                coord = THRESHOLD_COORDS[name]
                x = np.asarray(values[name], dtype=float)
                col = self.theta_names.index(coord)
                out[..., col] = np.log(x) if coord.startswith("log_") else x
        return out

    def lowest_voltage(self, event: EventRecord, theta: NDArray) -> float:
        """The load bus's lowest voltage over the rows the likelihood reads, at ``theta``.

        Below it no threshold is reached (``fit/composite/thresholds.py``).
        """
        # It depends on theta through the feeder's X alone (theta[0], as _split reads it),
        # which most of the sampler's steps leave as it was: kept per event and value.
        log_x = float(np.asarray(theta, dtype=float)[0]) if self.feeder else 0.0
        key = (token(event), log_x)
        got = self._lowest.get(key)
        if got is None:  # the kept rows' |V_L| as the solve's (parts_kernel.event_parts)
            t, v, delta, _, p, q = event_arrays(self, event)[:6]
            x_fd = feeder_of(math.exp(log_x), p[0], q[0]) if self.feeder else 0.0
            got = self._lowest.keep(key, float(lowest_load_bus(v, delta, p, q, self.rx * x_fd,
                                                               x_fd)))  # fmt: skip
        return got

    def feeder_x(self, p0: float, q0: float, c: dict[str, Any]) -> float:
        """The series X in system p.u. (its draw is on the load's base, ``|S|`` at the start)."""
        return float(c["x_fd"]) / float(np.hypot(p0, q0)) if self.feeder else 0.0

    def load_columns(self, ev: EventRecord, c: dict[str, Any], steps: NDArray | None = None,
                     v2: NDArray | None = None, kept: tuple | None = None):  # fmt: skip
        """At the load bus (``ev``): P's column on ``p0``, Q's on ``p0`` and ``Y2`` per ``p0``.

        ``c`` is :meth:`_split` of one ``theta``; None where a motor has no steady state.
        ``v2``: the motors' braking drive at ``ev``'s rows (``parts.brake_drive``), None
        for none. ``kept``: a key of ``ev`` and ``v2`` (:meth:`channels`': the recorded
        event and the feeder's X), under which each motor's response is kept for the
        next calls (the NLS's differences move one coordinate at a time: most leave a
        motor as it was); None: none kept.
        """
        xl = ev.v / ev.v[0]
        f = c["f"]
        a_p = c["a_p"]
        col_p = f[-1] * (a_p[0] * xl * xl + a_p[1] * xl + a_p[2])
        col_qp = np.zeros(ev.n)
        v0 = ev.v[0]
        y2p = f[-1] / v0**2 + 0j
        drive, real, u2 = ev, None, v2
        if self.window_s > 0:  # window means: across a gap the voltage steps (parts.step_knots)
            gap = gaps_of(ev.t, steps)
            if gap.any():
                t2, vk, d2, real = step_knots(ev.t, ev.v, ev.delta, gap, steps)
                drive = EventRecord(t2, vk, np.zeros(t2.size), np.zeros(t2.size), d2)
                if v2 is not None:  # |V2| steps with V
                    u2 = step_knots(ev.t, v2, None, gap, steps)[1]
        for j, (m, logs) in enumerate(zip(self.motors, c["motors"], strict=True)):
            key = None if kept is None else (token(kept[0]), kept[1], m, logs.tobytes())
            got = None if key is None else self._responses.get(key)
            if got is not None:
                resp = got
            else:
                resp = motor_response(drive, logs, f_hz=self.f_hz, real=real,
                                      torque=MOTOR_CLASSES[m]["torque"],
                                      window_s=self.window_s, v2=u2)  # fmt: skip
                if key is not None:
                    self._responses.keep(key, resp)
            if resp is None:
                return None
            pm, qm = resp
            col_p += f[j] * pm / pm[0]
            col_qp += f[j] * (qm - qm[0] * xl * xl) / pm[0]
            rs, xp, dx, tp = np.exp(logs[:4])
            y2p += f[j] / pm[0] * (motor_y2(rs, xp, dx, tp, self.f_hz) + 1j * qm[0] / v0**2)
        j = len(self.motors)
        if self.motor_d:
            pd, qd = motor_d(ev.t, ev.v, **{**self.motor_d_params, "vstall": c["vstall"],
                                            "tstall": c["tstall"]})  # fmt: skip
            col_p += f[j] * pd / pd[0]
            col_qp += f[j] * (qd - qd[0] * xl * xl) / pd[0]
            y2p += f[j] / v0**2
            j += 1
        if self.electronics:
            col_p += f[j] * electronics_fraction(ev.v, c["vd1"], c["vd2"], self.frcel)
        return col_p, col_qp, y2p

    def _i2(self, event, lb, y2p, v0) -> tuple[NDArray, NDArray]:
        # ``event``: the kept rows only (channels cut the rest).
        if not self.uses_negative_sequence(event):
            return np.zeros((0, len(self.beta_names))), np.zeros(0)
        rows = np.abs(np.asarray(event.v2)) >= NEG_SEQ_MIN
        v2l = lb.v2[rows]
        c1, c2 = v2l * y2p, v2l * (-1j / v0**2)
        i2 = np.asarray(event.i2)[rows]
        z = np.vstack([np.column_stack([c1.real, c2.real, c2.real, c2.real]),
                       np.column_stack([c1.imag, c2.imag, c2.imag, c2.imag])])  # fmt: skip
        return z, np.concatenate([i2.real, i2.imag])

    def options(self) -> dict[str, Any]:
        """Every field, JSON-ready (the fit records it: exports and playback rebuild from it)."""
        return {
            "motors": list(self.motors), "motor_classes": {
                m: {"torque": list(MOTOR_CLASSES[m]["torque"]),
                    "meaning": MOTOR_CLASSES[m]["meaning"]}
                for m in self.motors
            },
            "feeder": self.feeder, "motor_d": self.motor_d, "electronics": self.electronics,
            "f_hz": self.f_hz, "rx": self.rx, "negative_sequence": self.negative_sequence,
            "window_s": self.window_s, "physical_region": self.physical_region,
            "rs_max": self.rs_max, "h_min": self.h_min,
            "x_prime_min": self.x_prime_min, "x_prime_max": self.x_prime_max,
            "vd1": self.vd1, "vd2": self.vd2, "frcel": self.frcel,
            "fit_thresholds": self.fit_thresholds,
            "motor_d_params": {**MOTOR_D_DEFAULTS, **self.motor_d_params},
            "priors": {k: list(v) for k, v in self.priors.items()},
            # Only where it is not white: a white-noise fit's record stays as it was.
            **({"noise": self.noise, "rho_max": self.rho_max} if self.noise != "white" else {}),
            **({"share_steps": self.share_steps} if self.share_steps != SHARE_STEPS else {}),
        }  # fmt: skip

    @property
    def channel_names(self) -> tuple[str, ...]:
        """The likelihood's channels: P, Q and (unless off) the negative-sequence current."""
        return ("p", "q") if self.negative_sequence == "off" else ("p", "q", "i2")

    # -- the protocol's response/design (P and Q only), and what a draw means ----------

    def response(self, event: EventRecord, theta: NDArray) -> tuple | None:  # noqa: D102
        ch = self.channels(event, theta)
        return None if ch is None else tuple(ch)

    def design(self, event: EventRecord, *channels) -> tuple[NDArray, NDArray]:  # noqa: D102
        return channels[0][0], channels[1][0]

    def composition(self, beta: NDArray, *response0: NDArray) -> dict[str, NDArray]:
        """``p0, q0`` at the load bus's first sample and the static Q's terms (system p.u.)."""
        b = np.asarray(beta, dtype=float)
        return {"p0": b[..., 0], "q0": b[..., 1] + b[..., 2] + b[..., 3],
                "cq2": b[..., 1], "cq1": b[..., 2], "cq0": b[..., 3]}  # fmt: skip

    def physical(self, theta: NDArray) -> dict[str, NDArray]:
        """Every part's parameters and share, vectorised over draws."""
        c = self._split(theta)
        out: dict[str, NDArray] = {}
        if self.feeder:
            out["x_fd"] = c["x_fd"]
            out["r_fd"] = self.rx * c["x_fd"]
        for logs, t in zip(c["motors"], self._tags, strict=True):
            for k, v in motor_physical(logs, f_hz=self.f_hz).items():
                out[k + t] = v
        f = c["f"]
        for j, p in enumerate(self.parts):
            out["f_" + p] = f[..., j]
        out["f_s"] = f[..., -1]
        motor_total = sum(f[..., j] for j, p in enumerate(self.parts) if p.startswith("m"))
        out["f_motors"] = np.asarray(motor_total)
        for i, name in enumerate(("a1", "a2", "a3")):
            out[name] = c["a_p"][..., i]
        for name in self.thresholds:
            out[name] = np.asarray(c[name])
        return out

    def ratings(self, event: EventRecord, theta: NDArray, p0: NDArray) -> dict[str, NDArray]:
        """Each motor's rating (system p.u. of MVA) per draw: ``f_k p0 / p_k(0)``."""
        from loadbayes.models.parts_predict import motor_ratings

        return motor_ratings(self, event, theta, p0)

    @property
    def quantities(self) -> dict[str, tuple[str, str]]:
        """Unit and meaning of every named draw (``models/parts_quantities.py``)."""
        from loadbayes.models.parts_quantities import quantities

        return quantities(self)
