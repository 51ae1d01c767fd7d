"""The third-order induction motor as a regression: Gram columns, blocks, conditionals.

Physics, time base and sign conventions are those of :mod:`loadbayes.models.motor`
(seconds, ``wb = 2 pi f``; load convention). The five coefficients are
``b1 = -1/T'``, ``b2 = -(X - X')/T'``, ``b3 = -1/(2H)`` (1/s) and
``ab = Rs/(Rs^2 + X'^2)``, ``ac = X'/(Rs^2 + X'^2)`` (p.u.); the paper's section "IM Model"
with its slips fixed (docs/paper.md, slips 3-6: ``A w^2``, ``y_Ed = dEd'/dt``, the Iq
sign, ``T0`` kept).

One idea at about 400 lines: the same five equations in their two forms (measured and
latent currents), which share every helper (Gram columns, blocks, conditionals).

Two forms of the same five equations
------------------------------------
``currents="measured"`` (the paper's form, equation (2))::

    dEd'/dt + wb (w - 1) Eq' = b1 Ed' + b2 Iq                     } tau_e
    dEq'/dt - wb (w - 1) Ed' = b1 Eq' - b2 Id                     }
    dw/dt                    = b3 (T0 w^2 - (Ed' Id + Eq' Iq))      tau_w
    Id = ab (Ud - Ed') + ac (Uq - Eq')                            } tau_i
    Iq = ab (Uq - Eq') - ac (Ud - Ed')                            }

Three independent conjugate blocks, each linear in its coefficients; the measured
currents ``Id, Iq`` are *regressors* of the flux and speed blocks. When the currents
carry noise this is an errors-in-variables regression: b2 and above all b3 are biased
toward zero (b3 by 20-50% at 5% noise on the documented motors; docs/motor.md).

``currents="modelled"`` (the default; a departure from the paper). The currents are
deterministic functions of the states, so in the flux and speed equations they are
replaced by the model's own ``Id = ab dd + ac dq``, ``Iq = ab dq - ac dd`` with
``dd = Ud - Ed'``, ``dq = Uq - Eq'``; the electrical torque becomes
``Ed' Id + Eq' Iq = ab S1 + ac S2`` with ``S1 = Ed' dd + Eq' dq`` and
``S2 = Ed' dq - Eq' dd``, all built from the clean voltages and fluxes::

    dEd'/dt + wb (w - 1) Eq' = b1 Ed' + b2 (ab dq - ac dd)
    dEq'/dt - wb (w - 1) Ed' = b1 Eq' - b2 (ab dd + ac dq)
    dw/dt                    = b3 (T0 w^2 - ab S1 - ac S2)
    Id, Iq                   as above

The noisy measured currents are now only *targets*. Each residual is bilinear: linear
in ``u = (b1, b2, b3)`` given ``v = (ab, ac)`` and linear in ``v`` given ``u``. Writing
``phi = kron([1, u], [1, v])`` (12 monomials), the residual of equation ``e`` is
``X T_e phi`` for a fixed matrix ``T_e`` over the Gram columns ``X``, so its sum of squares
is ``phi' H_g phi`` with ``H_g = sum_e T_e' (X'X) T_e`` summed over the equations of noise
group ``g``. Three 12 x 12 matrices carry all the data: a Gibbs sweep
(``u | v, tau``; ``v | u, tau``; ``tau | u, v``) costs O(1) in the number of samples,
and ``(ab, ac)`` gets information from all five equations.

Load torque T0
--------------
Given (``t0=``), or from the first sample taken as a steady state: ``dw/dt = 0`` there,
so ``T0 = Te(0) / w(0)^2`` with ``Te(0) = ab S1(0) + ac S2(0)`` from the clean voltage
and flux of the first row (the noisy currents of one row would put their noise on T0).
In the modelled form this ``T0`` is recomputed at every draw of ``(ab, ac)`` (it enters
the speed residual bilinearly); the measured form plugs in the least-squares
``(ab, ac)`` of its current block (T0 within ~0.2% at 5% noise, negligible next to the
form's own bias of b3).

Priors (defaults, weak)
-----------------------
Each coefficient ``N(0, 100^2)``: the documented motors' coefficients lie within +-14
(1/s and p.u.) and their posterior sds are below 1% of that, so the prior is flat where
the likelihood is (widen it for a motor with T' well under 0.05 s, where
``|b2| = (X - X')/T'`` approaches 100). Each noise precision ``Gamma(1e-3, 1e-9)``
(shape, rate), close to the scale-free ``1/tau``. The modelled form needs independent
(non-conjugate) priors.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, replace
from typing import Any, Literal

import numpy as np

from loadbayes.core.blocks import BilinearStats, LinearBlock
from loadbayes.core.priors import BlockPrior
from loadbayes.core.stats import Gram
from loadbayes.io.errors import DataError
from loadbayes.models.motor import COEFFICIENT_NAMES, inverse

__all__ = [
    "CURRENTS",
    "DATA_COLUMNS",
    "PHYSICAL_NAMES",
    "InductionMotorModel",
]

Currents = Literal["modelled", "measured"]
CURRENTS: tuple[str, ...] = ("modelled", "measured")
DATA_COLUMNS: tuple[str, ...] = tuple("t_s ud uq ed eq w id iq ded deq dw".split())
"""Columns ``fit im`` reads (``t_s`` is checked, not used by the regression)."""
PHYSICAL_NAMES: tuple[str, ...] = ("rs", "xp", "x", "tp_s", "h_s", "xs", "xm", "xr", "rr")
"""Physical parameters reported as transformed draws (the last four under Xs = Xr)."""
TAU_NAMES: tuple[str, ...] = ("tau_e", "tau_w", "tau_i")
DEFAULT_COEF_SD = 100.0

# Gram columns. ``mdd = -dd`` and ``mid = -id`` are stored so that the paper's blocks are
# plain named-column regressions (the flux-q and current-q equations carry minus signs).
_BASE = tuple("ed eq dd dq mdd id iq mid yed yeq w2 te s1 s2 dw".split())
_U = ("b1", "b2", "b3")  # coefficients linear given v
_V = ("ab", "ac")  # coefficients linear given u
_FLUX = LinearBlock("flux", ("b1", "b2"), "tau_e", ((("ed", "iq"), "yed"), (("eq", "mid"), "yeq")))
_SPEED = LinearBlock("speed", ("b3",), "tau_w", ((("h",), "dw"),))
_MOVING = ("ed", "eq", "dd", "w2")  # no spread in all of these: a steady state
_CURRENT = LinearBlock("current", _V, "tau_i", ((("dd", "dq"), "id"), (("dq", "mdd"), "iq")))


@dataclass(frozen=True)
class InductionMotorModel:
    """Regression model of the third-order induction motor (paper's section "IM Model").

    Parameters
    ----------
    f_hz : float
        Nominal frequency; ``wb = 2 pi f_hz`` multiplies the slip terms (time in seconds).
    t0 : float, optional
        Load-torque coefficient T0 (p.u.). ``None`` until resolved from the first
        sample (:meth:`resolve_t0`); the paper's blocks need it resolved.
    currents : {"modelled", "measured"}
        Which currents enter the flux and speed regressors (module docstring).
    closure : {"xs=xr"}
        The extra equation that splits X and X' into Xs, Xm, Xr (and gives Rr).
    """

    f_hz: float = 60.0
    t0: float | None = None
    currents: Currents = "modelled"
    closure: str = "xs=xr"

    name = "im"

    @property
    def pieces(self) -> str:
        """Likelihood pieces: linear blocks (measured currents) or bilinear (modelled)."""
        return "linear" if self.currents == "measured" else "bilinear"

    def __post_init__(self) -> None:
        if not (np.isfinite(self.f_hz) and self.f_hz > 0):
            raise ValueError(f"f_hz must be positive, got {self.f_hz}")
        if self.t0 is not None and not (np.isfinite(self.t0) and self.t0 > 0):
            raise ValueError(f"t0 must be positive (a motoring load), got {self.t0}")
        if self.currents not in CURRENTS:
            raise ValueError(f"currents must be one of {CURRENTS}, got {self.currents!r}")
        if self.closure != "xs=xr":
            raise ValueError(f"unknown closure {self.closure!r}; only 'xs=xr' is implemented")

    # ------------------------------------------------------------- structure
    @property
    def wb(self) -> float:
        """Base angular frequency ``2 pi f_hz`` (rad/s)."""
        return 2.0 * np.pi * self.f_hz

    @property
    def gram_columns(self) -> tuple[str, ...]:
        """Columns of the Gram matrix; ``h = T0 w^2 - Te`` only once T0 is known."""
        return _BASE + (("h",) if self.t0 is not None else ())

    @property
    def blocks(self) -> list[LinearBlock]:
        """The paper's three conjugate blocks (measured currents as regressors).

        Used by the measured form and by the generic least-squares and Kalman baselines.
        """
        if self.t0 is None:
            raise ValueError("T0 is not resolved: call resolve_t0() and with_t0() first")
        return [_FLUX, _SPEED, _CURRENT]

    @property
    def coefficients(self) -> list[str]:
        """The five regression coefficients."""
        return list(COEFFICIENT_NAMES)

    @property
    def free(self) -> list[str]:
        """Coefficients checked pairwise for identifiability (all five)."""
        return list(COEFFICIENT_NAMES)

    def with_t0(self, t0: float) -> InductionMotorModel:
        """A copy with T0 fixed."""
        return replace(self, t0=float(t0))

    def default_priors(
        self, *, sd: float = DEFAULT_COEF_SD, mean: float = 0.0, **kw: Any
    ) -> dict[str, BlockPrior]:
        """Weak priors: every coefficient ``N(mean, sd^2)``, each precision Gamma(1e-3, 1e-9)."""
        return {
            "flux": BlockPrior.weak(2, sd=sd, mean=mean, **kw),
            "speed": BlockPrior.weak(1, sd=sd, mean=mean, **kw),
            "current": BlockPrior.weak(2, sd=sd, mean=mean, **kw),
        }

    # ------------------------------------------------------------------ data
    def rows(self, data: Mapping[str, np.ndarray]) -> np.ndarray:
        """Rows of the Gram matrix for a chunk with keys ``ud uq ed eq w id iq ded deq dw``."""
        ud, uq, ed, eq, w, id_, iq, ded, deq, dw = (
            np.asarray(data[k], dtype=float) for k in DATA_COLUMNS[1:]
        )
        dd, dq = ud - ed, uq - eq
        w2 = w * w
        te = ed * id_ + eq * iq
        cols = [
            ed,
            eq,
            dd,
            dq,
            -dd,
            id_,
            iq,
            -id_,
            ded + self.wb * (w - 1.0) * eq,
            deq - self.wb * (w - 1.0) * ed,
            w2,
            te,
            ed * dd + eq * dq,
            ed * dq - eq * dd,
            dw,
        ]
        if self.t0 is not None:
            cols.append(self.t0 * w2 - te)
        return np.column_stack(cols)

    @staticmethod
    def first_row(data: Mapping[str, np.ndarray]) -> dict[str, float]:
        """What T0 needs from the first sample: ``S1(0)``, ``S2(0)`` and ``w(0)^2``."""
        ud, uq, ed, eq, w = (float(np.asarray(data[k])[0]) for k in ("ud", "uq", "ed", "eq", "w"))
        dd, dq = ud - ed, uq - eq
        return {"s1": ed * dd + eq * dq, "s2": ed * dq - eq * dd, "w2": w * w}

    def resolve_t0(self, gram: Gram, first: Mapping[str, float]) -> float:
        """T0 from the first sample's steady state, with the LS ``(ab, ac)`` plugged in.

        ``T0 = (ab S1(0) + ac S2(0)) / w(0)^2``; ``ab, ac`` are the least-squares
        estimates of the current block (clean regressors, so unbiased and precise).
        """
        (ab, ac), _ = _CURRENT.stats(gram).least_squares()
        t0 = (ab * first["s1"] + ac * first["s2"]) / first["w2"]
        if not (np.isfinite(t0) and t0 > 0):
            raise DataError(
                f"the first sample is not a motoring steady state (T0 = {t0:.4g} from it); "
                "give the load torque with --t0"
            )
        return float(t0)

    def complete(self, gram: Gram) -> Gram:
        """Add the column ``h = T0 w^2 - te`` to a Gram accumulated before T0 was known.

        ``h`` is a linear combination of columns, so its products follow exactly from the
        Gram: with ``A' = A M``, ``A''A' = M' (A'A) M``.
        """
        if self.t0 is None:
            raise ValueError("T0 is not resolved")
        if "h" in gram.names:
            return gram
        k = len(gram.names)
        m = np.zeros((k, k + 1))
        m[:, :k] = np.eye(k)
        m[gram.index("w2"), k] = self.t0
        m[gram.index("te"), k] = -1.0
        # Bounds of h: not tracked (no check uses them).
        return Gram(
            gram.names + ("h",),
            m.T @ gram.matrix @ m,
            gram.n,
            np.append(gram.col_min, np.nan),
            np.append(gram.col_max, np.nan),
        )

    def check(self, gram: Gram) -> list[str]:
        """Refuse data that cannot identify the motor; return plain-words warnings."""
        if gram.n < 4:
            raise DataError(
                f"{gram.n} valid samples: the motor needs at least 4 (three coefficients and "
                "a precision in the largest block)"
            )
        lo = np.array([gram.col_min[gram.index(c)] for c in _MOVING])
        hi = np.array([gram.col_max[gram.index(c)] for c in _MOVING])
        # Relative spread: an integrated steady state still wanders by ~1e-12.
        if np.all(hi - lo <= 1e-9 * np.maximum(np.maximum(abs(lo), abs(hi)), 1e-300)):
            raise DataError(
                "no excitation: voltage, flux and speed are constant over the record (a "
                "steady state); the motor coefficients need a disturbance (sag, ramp, walk)",
                column="ud",
            )
        names = set(gram.names)
        if {"id", "iq"} <= names and all(
            gram.col_min[gram.index(c)] == 0.0 == gram.col_max[gram.index(c)] for c in ("id", "iq")
        ):
            # No stator current: no motor (a breaker open, a channel not recorded). The
            # equations are then singular and the solver's own message ("SVD did not
            # converge") names nothing.
            raise DataError(
                "the stator current (id, iq) is 0 in every row: there is no motor to fit (an "
                "open breaker, a current that was not recorded, or the wrong columns?)",
                column="id",
            )
        warnings = []
        model = self if self.t0 is not None else self.with_t0(1.0)
        g = model.complete(gram)
        for block in model.blocks:
            st = block.stats(g)
            scale = np.sqrt(np.diag(st.ztz))
            with np.errstate(divide="ignore", invalid="ignore"):
                cond = np.linalg.cond(st.ztz / np.outer(scale, scale))
            if not np.isfinite(cond) or cond > 1e12:
                warnings.append(
                    f"the {block.name} equations cannot identify {', '.join(block.coef_names)} "
                    "separately on this record (too little excitation); the estimates follow "
                    "the prior along the unidentified direction."
                )
        if self.currents == "measured":
            cur = model.blocks[2].stats(g)
            _, ssr = cur.least_squares()
            noise = np.sqrt(ssr / max(cur.n - 2, 1))
            rms = np.sqrt(cur.rtr / cur.n)
            if noise > 1e-4 * rms:
                warnings.append(
                    f"the measured currents carry noise (sd ~ {noise:.3g} p.u., "
                    f"{100 * noise / rms:.2g}% of their RMS) and are regressors in this form: "
                    "b2 and b3 are biased toward zero (errors in variables). The default "
                    "currents='modelled' form does not use them as regressors."
                )
        return warnings

    # ------------------------------------------------------------ transforms
    def transform(self, draws: Mapping[str, np.ndarray]) -> dict[str, np.ndarray]:
        """Coefficients, precisions, and the physical parameters as transformed draws.

        ``rs, xp, x, tp_s, h_s`` are identified; ``xs, xm, xr, rr`` follow under the
        closure Xs = Xr (:func:`loadbayes.models.motor.inverse`); draws where the closure
        has no real solution are NaN.
        """
        out = {k: np.asarray(draws[k], dtype=float) for k in COEFFICIENT_NAMES}
        for k in TAU_NAMES:
            out[k] = np.asarray(draws[k], dtype=float)
        phys = inverse({k: out[k] for k in COEFFICIENT_NAMES}, self.closure, f_hz=self.f_hz)
        for k in PHYSICAL_NAMES:
            out[k] = np.asarray(phys[k], dtype=float)
        return out

    # ---------------------------------------------------- the modelled form
    def bilinear_stats(self, gram: Gram, first: Mapping[str, float] | None = None) -> BilinearStats:
        """The three 12 x 12 matrices ``H_g`` of the modelled form (module docstring).

        Parameters
        ----------
        gram : Gram
            Gram matrix of :attr:`gram_columns` (``h`` not needed).
        first : mapping, optional
            :meth:`first_row` of the record; needed when ``t0`` is None (then
            ``T0 = ab k1 + ac k2`` with ``k1 = S1(0)/w(0)^2``, ``k2 = S2(0)/w(0)^2``).
        """
        ix = {c: gram.index(c) for c in _BASE}
        m = len(gram.names)

        def t(terms: dict[tuple[int, int], dict[str, float]]) -> np.ndarray:
            # Monomial (i, j) is [1, b1, b2, b3][i] * [1, ab, ac][j]: column i*3 + j.
            out = np.zeros((m, 12))
            for (i, j), cols in terms.items():
                for col, val in cols.items():
                    out[ix[col], 3 * i + j] += val
            return out

        flux = [
            # yed - b1 ed - b2 (ab dq - ac dd)
            t({(0, 0): {"yed": 1}, (1, 0): {"ed": -1}, (2, 1): {"dq": -1}, (2, 2): {"dd": 1}}),
            # yeq - b1 eq + b2 (ab dd + ac dq)
            t({(0, 0): {"yeq": 1}, (1, 0): {"eq": -1}, (2, 1): {"dd": 1}, (2, 2): {"dq": 1}}),
        ]
        t0_k: tuple[float, float] | None = None
        if self.t0 is not None:
            # dw - b3 (T0 w2 - ab s1 - ac s2)
            speed = t(
                {(0, 0): {"dw": 1}, (3, 0): {"w2": -self.t0}, (3, 1): {"s1": 1}, (3, 2): {"s2": 1}}
            )
        else:
            if first is None:
                raise ValueError("T0 from the first sample needs first_row()")
            t0_k = (first["s1"] / first["w2"], first["s2"] / first["w2"])
            # dw - b3 (ab (k1 w2 - s1) + ac (k2 w2 - s2)), T0 = ab k1 + ac k2
            speed = t(
                {
                    (0, 0): {"dw": 1},
                    (3, 1): {"w2": -t0_k[0], "s1": 1},
                    (3, 2): {"w2": -t0_k[1], "s2": 1},
                }
            )
        current = [
            t({(0, 0): {"id": 1}, (0, 1): {"dd": -1}, (0, 2): {"dq": -1}}),  # id - ab dd - ac dq
            t({(0, 0): {"iq": 1}, (0, 1): {"dq": -1}, (0, 2): {"dd": 1}}),  # iq - ab dq + ac dd
        ]
        g = gram.matrix
        h = np.stack(
            [
                sum(te.T @ g @ te for te in flux),
                speed.T @ g @ speed,
                sum(te.T @ g @ te for te in current),
            ]
        )
        h = (h + np.transpose(h, (0, 2, 1))) / 2
        return BilinearStats(
            h=h,
            n_eq=np.array([2 * gram.n, gram.n, 2 * gram.n], dtype=float),
            u_names=_U,
            v_names=_V,
            tau_names=TAU_NAMES,
            t0_k=t0_k,
        )

    def current_estimate(self, gram: Gram) -> tuple[np.ndarray, np.ndarray, float]:
        """Least squares of the current equations alone: ``(ab, ac)``, covariance, sigma^2."""
        st = _CURRENT.stats(gram)
        coef, ssr = st.least_squares()
        s2 = max(ssr / max(st.n - 2, 1), 1e-300)
        return coef, s2 * np.linalg.pinv(st.ztz), s2
