"""The ZIP (constant impedance, current, power) static load model.

With ``x = V / V0`` and ``y = P / P0`` (the paper's section "ZIP Model")::

    y = a1 x^2 + a2 x + a3 + e,   a1 + a2 + a3 = 1,   e ~ N(0, 1 / tau_p)
    =>  y - 1 = a1 (x^2 - 1) + a2 (x - 1) + e

a linear regression in (a1, a2); a3 = 1 - a1 - a2 is a transformed draw. Reactive power
has the same form with a4, a5, a6 and tau_q.

When the nominal power is not known (``p0="auto"``), the model is written as::

    P = P0 + d1 (x^2 - 1) + d2 (x - 1) + e,     d1 = P0 a1,  d2 = P0 a2

a regression in (P0, d1, d2) with the same design columns plus a constant (P0 is the
power at V = V0). The ZIP shares are then a1 = d1 / P0, a2 = d2 / P0, a3 = 1 - a1 - a2,
computed draw by draw. Use a known P0 (the rated or pre-disturbance power) when there is
one: it fixes one degree of freedom and narrows the intervals. Use ``auto`` when the
recording has no reliable nominal point, e.g. a bus whose load level is unknown; then the
noise enters in the units of P (per unit of the power base), not of P0.

Columns are computed as ``x^2 - 1 = (x - 1)(x + 1)`` to keep precision near ``x = 1``.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Literal

import numpy as np
import pandas as pd

from loadbayes.core.blocks import LinearBlock
from loadbayes.core.priors import BlockPrior
from loadbayes.core.stats import Gram
from loadbayes.io.errors import DataError

__all__ = ["ZIPModel"]

Nominal = float | Literal["auto"]

#: Largest |V / v0| or |P / P0| accepted: beyond it the data are in the wrong units.
MAX_RATIO = 1e6

#: Relative voltage span below which the data are called a narrow band in the warnings.
NARROW_BAND = 0.02


@dataclass(frozen=True)
class ZIPModel:
    """ZIP load model for P and, optionally, Q.

    Parameters
    ----------
    v0 : float
        Nominal voltage, in the units of the voltage data (per unit by default).
    p0, q0 : float or "auto"
        Nominal active / reactive power at ``V = v0``, in the units of the power data;
        ``"auto"`` estimates it (see the module notes).
    with_q : bool
        Fit reactive power too (a4, a5, a6, tau_q).
    """

    v0: float = 1.0
    p0: Nominal = 1.0
    q0: Nominal = 1.0
    with_q: bool = True

    def __post_init__(self) -> None:
        if not (np.isfinite(self.v0) and self.v0 > 0):
            raise ValueError(f"v0 must be positive, got {self.v0}")
        for name in ("p0", "q0"):
            val = getattr(self, name)
            if val != "auto" and not (isinstance(val, (int, float)) and np.isfinite(val)):
                raise ValueError(f"{name} must be a number or 'auto', got {val!r}")
            if val != "auto" and val == 0:
                raise ValueError(f"{name} must be non-zero (it divides the data)")

    # ------------------------------------------------------------ structure
    name = "zip"
    #: Likelihood pieces (:mod:`loadbayes.models.base`): conjugate linear blocks.
    pieces = "linear"

    def _channels(self) -> list[tuple[str, Nominal, tuple[str, str, str]]]:
        out = [("p", self.p0, ("a1", "a2", "a3"))]
        if self.with_q:
            out.append(("q", self.q0, ("a4", "a5", "a6")))
        return out

    @property
    def gram_columns(self) -> tuple[str, ...]:
        """Columns of the augmented matrix whose Gram the sampler needs."""
        cols = ["z1", "z2", "1"]
        cols += [f"r{ch}" if nom != "auto" else ch for ch, nom, _ in self._channels()]
        return tuple(cols)

    @property
    def blocks(self) -> list[LinearBlock]:
        """The conjugate blocks: one per power channel."""
        out = []
        for ch, nom, (c1, c2, _) in self._channels():
            if nom == "auto":
                out.append(
                    LinearBlock(
                        ch,
                        (f"{ch}0", f"d_{c1}", f"d_{c2}"),
                        f"tau_{ch}",
                        ((("1", "z1", "z2"), ch),),
                    )
                )
            else:
                out.append(LinearBlock(ch, (c1, c2), f"tau_{ch}", ((("z1", "z2"), f"r{ch}"),)))
        return out

    @property
    def free(self) -> list[str]:
        """The shares that vary freely (a3, a6 follow from the sum-to-one constraint)."""
        return [c for _, _, cs in self._channels() for c in cs[:2]]

    @property
    def coefficients(self) -> list[str]:
        """Every reported ZIP coefficient, in order."""
        return [c for _, _, cs in self._channels() for c in cs]

    def default_priors(
        self, *, sd: float = 10.0, mean: tuple[float, float] = (0.0, 0.0), **kw
    ) -> dict[str, BlockPrior]:
        """Weak priors: a1, a2 (a4, a5) ~ N(mean, sd^2); tau ~ Gamma(1e-3, 1e-9).

        With ``auto`` nominal power the block is (P0, d1, d2) in the units of the data;
        its prior is N(0, (1e4)^2) on each, flat for any per-unit data.
        """
        out = {}
        for block in self.blocks:
            if block.k == 3:
                out[block.name] = BlockPrior.weak(3, sd=1e4, **kw)
            else:
                out[block.name] = BlockPrior.weak(2, sd=sd, mean=mean, **kw)
        return out

    # ----------------------------------------------------------------- data
    def rows(self, data: Mapping[str, np.ndarray]) -> np.ndarray:
        """Rows of the augmented matrix for a chunk with keys ``v``, ``p`` and maybe ``q``."""
        x = np.asarray(data["v"], dtype=float) / self.v0
        dx = x - 1.0
        # An absurd voltage (a unit error) may overflow here; check() refuses it by name.
        with np.errstate(over="ignore"):
            cols = [dx * (x + 1.0), dx, np.ones_like(x)]
        for ch, nom, _ in self._channels():
            y = np.asarray(data[ch], dtype=float)
            cols.append(y if nom == "auto" else y / float(nom) - 1.0)
        return np.column_stack(cols)

    def check(self, gram: Gram, *, v_col: str = "v") -> list[str]:
        """Refuse data that cannot identify the model; return plain-words warnings."""
        n_par = max(b.k for b in self.blocks) + 1
        if gram.n < n_par:
            raise DataError(
                f"{gram.n} valid samples, fewer than the {n_par} parameters of a block "
                "(coefficients and noise precision)",
                column=v_col,
            )
        iz = gram.index("z2")
        lo, hi = gram.col_min[iz] + 1.0, gram.col_max[iz] + 1.0
        # Sums of squares of x^2 overflow or swamp the prior far before float64 does:
        # a voltage a million times v0 is a unit error, not a measurement.
        if hi > MAX_RATIO:
            raise DataError(
                f"voltage up to {hi:.3g} times v0 ({hi * self.v0:.3g}): not per unit of "
                "v0; check the units (--v-base, --v0)",
                column=v_col,
            )
        cols = {"rp": "p", "p": "p", "rq": "q", "q": "q"}
        for name in [c for c in gram.names if c in cols]:
            i = gram.index(name)
            big = max(abs(gram.col_min[i]), abs(gram.col_max[i]))
            if not np.isfinite(gram.matrix[i, i]) or big > MAX_RATIO:
                raise DataError(
                    f"values up to {big:.3g} (per unit of the nominal value): too large "
                    "for their sums of squares; check the units (--s-base, --p0, --q0)",
                    column=cols.get(name, v_col),
                )
        for name in [c for c in ("p", "q") if c in gram.names]:
            i = gram.index(name)
            if gram.col_min[i] == 0.0 == gram.col_max[i]:
                # P (Q) 0 throughout: the shares, fractions of P0 = 0, are 0 / 0.
                raise DataError(
                    f"{name.upper()} is 0 in every row: there is no load to fit (an open "
                    "breaker, a current that was not recorded, or the wrong column?)",
                    column=name,
                )
        if hi == lo:
            raise DataError(
                f"voltage has no spread (every sample is {lo * self.v0:g}): the ZIP "
                "coefficients cannot be identified",
                column=v_col,
            )
        warnings = []
        span = (hi - lo) / 1.0
        if span < NARROW_BAND:
            warnings.append(
                f"voltage spans only {100 * span:.2g}% of v0 ({lo:.4f} to {hi:.4f} p.u. of "
                "v0): the Z, I and P shares are hard to separate on so narrow a band."
            )
        for block in self.blocks:
            st = block.stats(gram)
            scale = np.sqrt(np.diag(st.ztz))
            with np.errstate(divide="ignore", invalid="ignore"):
                cond = np.linalg.cond(st.ztz / np.outer(scale, scale))
            if not np.isfinite(cond) or cond > 1e12:
                warnings.append(
                    f"the {block.name.upper()} data cannot identify "
                    f"{', '.join(block.coef_names)} separately (too few distinct voltage "
                    "levels); the estimates follow the prior along the unidentified direction."
                )
            _, ssr = st.least_squares()
            # Residual RMS below 1e-6 of the signal's: noise-free for any purpose (a
            # tighter threshold is defeated by rounding in r'r - b'Z'r).
            if ssr <= 1e-12 * max(st.rtr, 1e-300):
                warnings.append(
                    f"the {block.name.upper()} data fit the model exactly (no noise): "
                    f"{block.tau_name} is bounded only by its prior and the intervals are "
                    "as narrow as floating point allows."
                )
        return warnings

    # ---------------------------------------------------------- transforms
    def transform(self, draws: Mapping[str, np.ndarray]) -> dict[str, np.ndarray]:
        """Full set of reported parameters (adds a3 / a6, and P0 / Q0 shares for auto)."""
        out: dict[str, np.ndarray] = {}
        for ch, nom, (c1, c2, c3) in self._channels():
            if nom == "auto":
                p0 = draws[f"{ch}0"]
                with np.errstate(divide="ignore", invalid="ignore"):
                    a1 = draws[f"d_{c1}"] / p0
                    a2 = draws[f"d_{c2}"] / p0
            else:
                a1, a2 = draws[c1], draws[c2]
            out[c1], out[c2], out[c3] = a1, a2, 1.0 - a1 - a2
        for ch, nom, _ in self._channels():
            out[f"tau_{ch}"] = draws[f"tau_{ch}"]
            if nom == "auto":
                out[f"{ch}0"] = draws[f"{ch}0"]
        return out

    def derived(self, draws: Mapping[str, np.ndarray]) -> dict[str, np.ndarray]:
        """dP/dV (dQ/dV) at V = v0, draw by draw, in per unit of P0 (Q0) per unit of v0.

        ``d(a1 x^2 + a2 x + a3)/dx`` at ``x = 1`` is ``2 a1 + a2`` (``2 a4 + a5`` for Q):
        the sensitivity a CVR study quotes (1.15 means 1.15% less power for 1% less
        voltage). It is what fast voltage changes determine even when a1 and a2 are not
        separable.
        """
        out = {}
        for ch, _, (c1, c2, _) in self._channels():
            if c1 in draws and c2 in draws:
                out[f"d{ch.upper()}/dV"] = 2.0 * np.asarray(draws[c1]) + np.asarray(draws[c2])
        return out

    #: The unit of :meth:`derived`'s quantities.
    DERIVED_UNIT = "per unit of P0 (Q0) per unit of v0, at V = v0"

    def predict(
        self,
        draws: Mapping[str, np.ndarray],
        v: np.ndarray,
        *,
        hdi_prob: float = 0.95,
        kind: Literal["mean", "observation"] = "mean",
        rng: np.random.Generator | int | None = None,
        max_draws: int = 2000,
    ) -> pd.DataFrame:
        """Posterior-predictive P(V) (and Q(V)) with central bands.

        Parameters
        ----------
        draws : mapping
            Transformed draws (a1.., and p0/q0 with auto), shaped (chain, draw).
        v : array_like
            Voltages (data units) at which to predict.
        hdi_prob : float
            Probability of the central band.
        kind : {"mean", "observation"}
            Band of the load curve itself, or of a new noisy measurement.
        rng : Generator or int, optional
            For thinning the draws and for observation noise.
        max_draws : int
            At most this many draws are used.

        Returns
        -------
        pandas.DataFrame
            Columns ``v``, then ``p_mean``, ``p_low``, ``p_high`` (and the same for q).
        """
        gen = rng if isinstance(rng, np.random.Generator) else np.random.default_rng(rng)
        v = np.asarray(v, dtype=float)
        x = v / self.v0
        first = np.asarray(draws["a1"]).reshape(-1)
        idx = np.arange(first.size)
        if idx.size > max_draws:
            idx = np.sort(gen.choice(idx, max_draws, replace=False))
        out = {"v": v}
        lo_q, hi_q = (1 - hdi_prob) / 2, 1 - (1 - hdi_prob) / 2
        for ch, nom, (c1, c2, c3) in self._channels():
            a = [np.asarray(draws[c]).reshape(-1)[idx][:, None] for c in (c1, c2, c3)]
            scale = np.asarray(draws[f"{ch}0"]).reshape(-1)[idx][:, None] if nom == "auto" else nom
            curve = scale * (a[0] * x**2 + a[1] * x + a[2])
            if kind == "observation":
                tau = np.asarray(draws[f"tau_{ch}"]).reshape(-1)[idx][:, None]
                sd = (1.0 if nom == "auto" else abs(float(nom))) / np.sqrt(tau)
                curve = curve + sd * gen.standard_normal(curve.shape)
            out[f"{ch}_mean"] = curve.mean(axis=0)
            out[f"{ch}_low"] = np.quantile(curve, lo_q, axis=0)
            out[f"{ch}_high"] = np.quantile(curve, hi_q, axis=0)
        return pd.DataFrame(out)
