"""Published ranges of the parts' parameters, as the priors of the models built from parts.

Each three-phase motor class has a log-normal prior per parameter, ``(median, sd of the
log)``, on the motor's own base, centred on the WECC composite load model's typical data
(WECC MVWG, "WECC Composite Load Model Specifications", 2015, and the default CMLDBLU2
records in PNNL's load-model data tool, LMDT: motor A a compressor with constant torque,
Rs 0.04, Ls 1.8, Lp 0.12, Tpo 0.095 s, H 0.1 s; motor B a fan or pump with torque rising
with speed squared, Rs 0.03, Ls 1.8, Lp 0.19, Tpo 0.2 s, H 0.5 s; a loading factor of
about 0.75). The spreads are wide enough to hold the classes' published ranges (Rs 0.01
to 0.1, X' 0.08 to 0.3, H 0.05 to 1.5 s) and narrow enough that a 0.4 s window does not
let them run outside: the prior's 2.5 % and 97.5 % quantiles are printed by
:func:`prior_ranges` and tested to lie inside those ranges. The ``slm`` motor (the
synthesis load model of Chinese practice, one lumped motor) takes the union of A and B.
Beside the log-normal priors, each motor is held in its physical region by hard limits
(Rs <= 0.1, H >= 0.05 s and :data:`X_PRIME_RANGE` on its own base), the ``slm`` motor
too: motors in parallel, each in that region on its own base, make one whose X' on the
sum of their ratings is a rating-weighted harmonic mean of theirs, in the same region.

The feeder (the substation transformer and the feeder as one series impedance): X on
the load's own base (``|S|`` at the event's first sample), median 0.10 (WECC's default
transformer reactance 0.08 plus feeder reactance 0.04 at about Fb 0.75), a factor 1.65
either way, with ``R = rx X`` (``rx`` 0.35 by default: WECC's feeder R 0.04 against
transformer plus feeder X 0.12).

The shares of P among the parts and of the static part among Z, I and P are uniform on
their simplex (Dirichlet(1, ..., 1)): every share in [0, 1], none favoured.
:class:`PartsPrior` is the whole prior in the sampled coordinates.

One idea needs these lines: the published ranges and the one prior they make
(:class:`PartsPrior`, whose density the sampler asks of every state, so it keeps its
terms by their coordinates).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from types import MappingProxyType
from typing import Any

import numpy as np

from loadbayes.models.part_scale import ScaleMap
from loadbayes.models.parts_state import prior_log_u, theta_of

__all__ = [
    "FEEDER_X",
    "MOTOR_CLASSES",
    "MOTOR_KEYS",
    "THRESHOLD_COORDS",
    "THRESHOLD_PRIORS",
    "THRESHOLD_RANGES",
    "VD_GAP",
    "X_PRIME_RANGE",
    "PartsPrior",
    "draw_thresholds",
    "parts_prior",
    "prior_ranges",
]

#: A motor's parameters, in the order of the sampled coordinates' source values.
MOTOR_KEYS = ("rs", "x_prime", "dx", "t_prime_s", "h_s", "t0")

#: Each motor class: its torque law ``(A, B, C)`` of ``T0 (A w^2 + B w + C)``, what it
#: stands for, and its log-normal prior ``(median, sd_log)`` per :data:`MOTOR_KEYS`.
MOTOR_CLASSES: Mapping[str, Mapping] = MappingProxyType(
    {
        "a": {
            "torque": (0.0, 0.0, 1.0),
            "meaning": "motor A: compressors (constant torque, low inertia)",
            "prior": {
                "rs": (0.04, 0.45),
                "x_prime": (0.13, 0.3),
                "dx": (1.7, 0.3),
                "t_prime_s": (0.10, 0.45),
                "h_s": (0.12, 0.45),
                "t0": (0.75, 0.25),
            },
        },
        "b": {
            "torque": (1.0, 0.0, 0.0),
            "meaning": "motor B: fans and pumps (torque ~ speed^2, higher inertia)",
            "prior": {
                "rs": (0.03, 0.45),
                "x_prime": (0.19, 0.28),
                "dx": (1.6, 0.3),
                "t_prime_s": (0.20, 0.45),
                "h_s": (0.50, 0.5),
                "t0": (0.75, 0.25),
            },
        },
        "slm": {
            "torque": (0.0, 0.0, 1.0),
            "meaning": "the synthesis load model's lumped motor",
            "prior": {
                "rs": (0.035, 0.5),
                "x_prime": (0.16, 0.35),
                "dx": (1.7, 0.35),
                "t_prime_s": (0.15, 0.6),
                "h_s": (0.25, 0.7),
                "t0": (0.75, 0.25),
            },
        },
    }
)

#: A three-phase motor's transient reactance X' on its own base, as hard limits of its
#: physical region (``PartsModel.x_prime_min, x_prime_max``). Its locked-rotor current is
#: about ``1 / |Rs + Rr + jX'|`` times rated, and published locked-rotor currents bound
#: it: NEMA MG 1 (12.35, the maxima for Designs B, C, D; MG 10 Table 2-1 as the EASA
#: handbook gives it) 6 to 7 times rated for Designs B to D and 8 to 10 for Design E; the
#: code letters' locked-rotor kVA per hp (about the multiple of rated current) run from A
#: (below 3.15, mid-range 1.6) to N (12.5) in use, G to M for standard motors; the
#: locked-rotor power factor is about 0.2 (IEEE Std 141), at most about 0.5 for small
#: motors, so X' carries most of that impedance. The WECC composite load model's motor
#: defaults (WECC MVWG, "WECC Composite Load Model Specifications", 2015; the default
#: CMLDBLU2 records of PNNL's load-model data tool, LMDT) put motor A's Lp at 0.12 and
#: B's at 0.19, at 5 to 8 times rated, inside the classes' published X' of 0.08 to 0.3
#: (the module docstring). Both limits lie a factor of two beyond those ranges, so
#: that no motor a source describes is refused: X' >= 0.04 is a locked-rotor current of
#: at most 20 times rated at a power factor up to 0.5 (0.05 * sqrt(1 - 0.5^2) = 0.043),
#: X' <= 0.65 one of at least about 1.5 times (below code A's mid-range 1.6). They hold
#: the motor classes' priors' 2.5 % and 97.5 % quantiles with room
#: (``tests/unit/test_parts_model.py``).
X_PRIME_RANGE = (0.04, 0.65)

#: The feeder's X on the load's base: (median, sd_log).
FEEDER_X = (0.10, 0.5)


def prior_ranges(cls: str, z: float = 1.959964) -> dict[str, tuple[float, float]]:
    """The central 95 % range of each parameter of motor class ``cls`` under its prior."""
    out = {}
    for key, (median, sd) in MOTOR_CLASSES[cls]["prior"].items():
        out[key] = (median * math.exp(-z * sd), median * math.exp(z * sd))
    return out


# Additive log-ratios of a uniform Dirichlet: each logistic, sd pi/sqrt(3), and any two
# sharing a denominator correlated by var(log E) = pi^2/6 (the NLS start's Gaussian).
_ALR_VAR, _ALR_COV = math.pi**2 / 3, math.pi**2 / 6


@dataclass(frozen=True)
class PartsPrior:
    """The prior of a :class:`PartsModel`: Gaussian coordinates and Dirichlet shares.

    ``mean, cov`` are the Gaussian block of the sampled vector (the feeder's and the
    motors' coordinates, first ``n_gauss`` entries); ``groups`` the index ranges of the
    additive log-ratio coordinates of each simplex (a uniform Dirichlet each).
    """

    mean: np.ndarray
    cov: np.ndarray
    groups: tuple[tuple[int, int], ...]
    beta_sd: np.ndarray
    tau_shape: float = 1e-3
    tau_rate: float = 1e-9
    positive: int | None = 0
    #: Each motor's physical region as hard limits: ``(i, rs_max, h_min, x_min, x_max)``
    #: with ``i`` the index of its first coordinate (``log(Rs T0)``; ``log(X' T0)`` at
    #: ``i + 1``, ``log(H / T0)`` at ``i + 4``, ``log T0`` at ``i + 5``): Rs <= rs_max,
    #: H >= h_min, x_min <= X' <= x_max on the motor's own base (:data:`X_PRIME_RANGE`
    #: says where X's come from). Empty: no limits (the log-normal priors alone).
    limits: tuple[tuple[int, float, float, float, float], ...] = ()
    #: Coordinates held in ``[lo, hi]``: ``(i, lo, hi)`` (the thresholds' physical ranges).
    ranges: tuple[tuple[int, float, float], ...] = ()
    #: ``(i, j, gap)``: ``u[j] <= u[i] - gap`` (the electronics' Vd2 below Vd1).
    order: tuple[tuple[int, int, float], ...] = ()

    def __post_init__(self) -> None:
        n = self.mean.size + sum(b - a for a, b in self.groups)
        # With limits, each motor's log T0 is sampled as z (models/part_scale.py): the
        # Gaussian block is the others' marginal, z a standard normal beside it.
        maps = tuple(ScaleMap(i, self.mean[i : i + 6], self.cov[i : i + 6, i : i + 6], *r)
                     for i, *r in self.limits)  # fmt: skip
        zs = [m.index + 5 for m in maps]
        mean, cov = self.mean.copy(), self.cov.copy()
        mean[zs], cov[zs, :], cov[:, zs] = 0.0, 0.0, 0.0
        cov[zs, zs] = 1.0
        full_mean = np.zeros(n)
        full_mean[: self.mean.size] = mean
        full = np.zeros((n, n))
        full[: self.mean.size, : self.mean.size] = cov
        for a, b in self.groups:
            full[a:b, a:b] = _ALR_COV
            full[range(a, b), range(a, b)] = _ALR_VAR
        object.__setattr__(self, "maps", maps)
        object.__setattr__(self, "_gauss", (mean, np.linalg.inv(cov)))
        object.__setattr__(self, "_full", (full_mean, full))
        object.__setattr__(self, "_prec", np.linalg.inv(self.cov))
        # The compiled prior's constants (models/parts_state.py): one vector's log_u,
        # inside and to_theta are its functions, the compiled density's numbers.
        rows = np.array([m.row for m in maps]).reshape(-1, 12)
        object.__setattr__(self, "packed", (
            np.ascontiguousarray(mean), np.ascontiguousarray(self._gauss[1]), rows,
            np.array(self.ranges, dtype=float).reshape(-1, 3),
            np.array(self.order, dtype=float).reshape(-1, 3),
            np.array(self.groups, dtype=float).reshape(-1, 2),
        ))  # fmt: skip

    def scale_free(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
        """``(mean, cov, gain, sd_cond)``: the Gaussian stand-in of every coordinate."""
        mean, cov = self._full
        return mean, cov, np.zeros(mean.size), 0.0

    def log_u(self, u: np.ndarray) -> float:
        """Log prior density at ``u`` up to a constant (-inf outside the hard limits)."""
        u = np.asarray(u, dtype=float)
        if u.ndim == 1:  # the sampler's one vector: compiled (models/parts_state.py)
            return float(prior_log_u(u, *self.packed))
        return np.apply_along_axis(lambda x: float(prior_log_u(x, *self.packed)), -1, u)

    def inside(self, u: np.ndarray) -> bool:
        """Whether ``u`` lies in the region :attr:`limits`, :attr:`ranges`, :attr:`order` hold.

        ``u`` is the sampled vector: each motor's ``z`` (:meth:`to_theta`) puts its
        ``log T0`` inside the limits, so they hold wherever they leave ``log T0`` some
        prior mass.
        """
        return math.isfinite(self.log_u(np.asarray(u, dtype=float)))

    def to_theta(self, u: np.ndarray) -> np.ndarray:
        """The model's ``theta`` of sampled vector(s) ``u``: each motor's ``z`` made its ``log T0``.

        The identity without limits. ``u`` (..., n) with any leading axes.
        """
        if not self.maps:
            return u
        if np.ndim(u) == 1:
            return theta_of(np.asarray(u, dtype=float), self.packed[2])
        theta = np.array(u, dtype=float)
        for m in self.maps:
            theta[..., m.index + 5] = m.log_t0(u)
        return theta

    def from_theta(self, theta: np.ndarray) -> np.ndarray:
        """The sampled vector of a ``theta`` inside the limits (:meth:`to_theta`'s inverse)."""
        u = np.array(theta, dtype=float)
        for m in self.maps:
            u[..., m.index + 5] = m.z(theta)
        return u

    def project(self, u: np.ndarray, margin: float = 0.05) -> np.ndarray:
        """``u`` moved just inside each motor's physical region (a start for the sampler).

        ``u`` is the sampled vector. A motor whose limits leave its ``log T0`` no room is
        given the ``log T0`` its unlimited prior conditional puts at its ``z`` (``m + s
        z``), moved inside as ``theta`` (the coordinates' wedge) and mapped back; the
        other motors stay as they are.
        """
        if not self.maps:
            return self._project(u, margin)
        u = np.array(u, dtype=float)
        for m, limit in zip(self.maps, self.limits, strict=True):
            if math.isfinite(float(m.log_mass(u))):
                continue
            theta = u.copy()
            theta[m.index + 5] = m._ab(u)[0] + m._sd * u[m.index + 5]
            theta = _project_motor(theta, *limit, margin)
            u[m.index : m.index + 6] = m.project_back(theta)[m.index : m.index + 6]
        return self._project(u, margin, motors=False)

    def _project(self, u: np.ndarray, margin: float, motors: bool = True) -> np.ndarray:
        u = np.array(u, dtype=float)
        for limit in self.limits if motors else ():
            u = _project_motor(u, *limit, margin)
        for i, lo, hi in self.ranges:
            u[i] = min(max(u[i], lo + 1e-3 * (hi - lo)), hi - 1e-3 * (hi - lo))
        for i, j, gap in self.order:
            u[j] = min(u[j], u[i] - gap - 1e-3)
        return u

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready description (for the output's settings)."""
        return {
            "limits": [
                {"coordinate": i, "rs_max": r, "h_min": h, "x_prime_min": xl, "x_prime_max": xh}
                for i, r, h, xl, xh in self.limits
            ],
            "ranges": [{"coordinate": i, "low": lo, "high": hi} for i, lo, hi in self.ranges],
            "order": [{"above": i, "below": j, "gap": g} for i, j, g in self.order],
            "gaussian": {"mean": self.mean.tolist(), "sd": np.sqrt(np.diag(self.cov)).tolist()},
            "simplexes": [list(g) for g in self.groups],
            "beta_sd": self.beta_sd.tolist(),
            "tau": {"shape": self.tau_shape, "rate": self.tau_rate},
        }


def _project_motor(u, i, rs_max, h_min, x_min, x_max, margin):
    # One motor's theta (log T0 at i + 5) moved just inside its limits.
    u = np.array(u, dtype=float)
    u[i] = min(u[i], math.log(rs_max) - margin + u[i + 5])
    u[i + 4] = max(u[i + 4], math.log(h_min) + margin - u[i + 5])
    lo, hi = math.log(x_min) + margin + u[i + 5], math.log(x_max) - margin + u[i + 5]
    u[i + 1] = min(max(u[i + 1], lo), hi)
    return u


#: Priors of motor D's stall voltage and time and the electronics' trip voltages: a fit
#: samples them (``PartsModel.fit_thresholds``); a fault record above them informs them
#: only by ruling out what would have stalled or tripped in it, so a prediction beyond
#: the data (``loadbayes predict``) rests on these. ``(kind, centre, spread)``:
#: ``normal`` (mean, sd) or ``lognormal`` (median, sd of the log). The centres are the
#: WECC composite load model specification's typical values (Vstall 0.6 p.u., Tstall
#: 0.033 s, Vd1 0.7, Vd2 0.5 p.u.); the spreads are this package's choice, not a
#: source's: wide enough that the 95 % range of the stall voltage (0.5 to 0.7 p.u.)
#: spans what tested air conditioners are reported to do (PNNL-17796 found the stall
#: voltage rising with the outdoor temperature), so that a prediction the data do not
#: reach widens instead of resting on one typical number.
THRESHOLD_PRIORS: Mapping[str, tuple[str, float, float]] = MappingProxyType(
    {
        "vstall": ("normal", 0.60, 0.05),
        "tstall": ("lognormal", 0.033, 0.5),
        "vd1": ("normal", 0.70, 0.05),
        "vd2": ("normal", 0.50, 0.05),
    }
)


#: Each threshold's sampled coordinate (the log of the stall time, the others as they are).
THRESHOLD_COORDS: Mapping[str, str] = MappingProxyType(
    {"vstall": "vstall", "tstall": "log_tstall", "vd1": "vd1", "vd2": "vd2"}
)
#: Hard limits of each sampled coordinate: voltages in p.u. a part can have, a stall time
#: from a millisecond to two seconds (its log).
THRESHOLD_RANGES: Mapping[str, tuple[float, float]] = MappingProxyType(
    {
        "vstall": (0.05, 1.0),
        "tstall": (math.log(1e-3), math.log(2.0)),
        "vd1": (0.06, 1.2),
        "vd2": (0.0, 1.15),
    }  # fmt: skip
)
#: The electronics' Vd2 at least this far below Vd1 (p.u.).
VD_GAP = 0.05


def parts_prior(model, events) -> PartsPrior:
    """A ``PartsModel``'s prior: log-normal physical priors in its sampled coordinates.

    The feeder's X and each motor's parameters (:data:`MOTOR_CLASSES`, mapped exactly into
    the scale-free coordinates), the sampled thresholds (:data:`THRESHOLD_PRIORS`, with
    their :data:`THRESHOLD_RANGES` and Vd2 below Vd1), flat shares on their simplexes;
    the user's ``model.priors`` by name over the defaults.
    """
    from loadbayes.models.composite import SCALE_FREE_MATRIX as sf

    means, blocks = [], []
    if model.feeder:
        med, sd = model.priors.get("x_fd", FEEDER_X)
        means.append([math.log(med)])
        blocks.append(np.array([[sd * sd]]))
    for m, t in zip(model.motors, model._tags, strict=True):
        cls = MOTOR_CLASSES[m]["prior"]
        med = np.array([math.log(model.priors.get(k + t, cls[k])[0]) for k in MOTOR_KEYS])
        sd = np.array([model.priors.get(k + t, cls[k])[1] for k in MOTOR_KEYS])
        means.append(sf @ med)
        blocks.append(sf @ np.diag(sd**2) @ sf.T)
    index = {}
    for name in model.thresholds:
        kind, centre, spread = THRESHOLD_PRIORS[name]
        centre, spread = model.priors.get(name, (centre, spread))
        index[name] = sum(b.shape[0] for b in blocks)
        means.append([math.log(centre) if kind == "lognormal" else centre])
        blocks.append(np.array([[spread * spread]]))
    n = model._n_gauss
    cov = np.zeros((n, n))
    i = 0
    for b in blocks:
        cov[i : i + b.shape[0], i : i + b.shape[0]] = b
        i += b.shape[0]
    k = len(model.parts)
    groups = ((n, n + k), (n + k, n + k + 2))
    s = max(float(np.max(np.hypot(e.p, e.q))) for e in events)
    first = 1 if model.feeder else 0
    region = (model.rs_max, model.h_min, model.x_prime_min, model.x_prime_max)
    limits = tuple((first + 6 * j, *region) for j in range(len(model.motors)))
    ranges = tuple((index[k], *THRESHOLD_RANGES[k]) for k in model.thresholds)
    order = ((index["vd1"], index["vd2"], VD_GAP),) if "vd1" in index else ()
    return PartsPrior(np.concatenate(means) if means else np.zeros(0), cov, groups,
                      np.full(4, 10 * s), limits=limits if model.physical_region else (),
                      ranges=ranges, order=order)  # fmt: skip


def draw_thresholds(rng: np.random.Generator, n: int,
                    priors: Mapping[str, tuple[str, float, float]] = THRESHOLD_PRIORS
                    ) -> dict[str, np.ndarray]:  # fmt: skip
    """``n`` draws of each threshold from its prior (Vd2 kept at least 0.05 below Vd1)."""
    out = {}
    for name, (kind, centre, spread) in priors.items():
        z = rng.standard_normal(n)
        out[name] = centre * np.exp(spread * z) if kind == "lognormal" else centre + spread * z
    if "vd1" in out and "vd2" in out:
        out["vd2"] = np.minimum(out["vd2"], out["vd1"] - VD_GAP)
    return out
