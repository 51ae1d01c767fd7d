"""A model's conjugate regression blocks, as the samplers read them off a Gram matrix.

A model describes its parameters as :class:`LinearBlock` objects: each block has its own
coefficients and noise precision, and one or more equations (design columns, target
column) that share them (the motor's two flux equations share ``b1, b2`` and ``tau_E``).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from loadbayes.core.stats import Gram, RegressionStats

__all__ = ["BilinearStats", "LinearBlock", "PowerLawBlock"]


@dataclass(frozen=True)
class LinearBlock:
    """One conjugate block: ``target_e = design_e b + noise`` for each equation ``e``.

    Parameters
    ----------
    name : str
        Block name (``"p"``, ``"q"``, ``"flux"``, ...).
    coef_names : tuple of str
        Names of the coefficients ``b``.
    tau_name : str
        Name of the shared noise precision.
    equations : tuple of (tuple of str, str)
        For each equation, the Gram columns of its design and of its target.
    """

    name: str
    coef_names: tuple[str, ...]
    tau_name: str
    equations: tuple[tuple[tuple[str, ...], str], ...]

    @property
    def k(self) -> int:
        """Number of coefficients."""
        return len(self.coef_names)

    def equations_of(
        self, rows: np.ndarray, names: tuple[str, ...]
    ) -> tuple[np.ndarray, np.ndarray]:
        """Regressors and targets of the block from raw rows, its equations interleaved in time."""
        zs, rs = [], []
        for design, target in self.equations:
            zs.append(rows[:, [names.index(c) for c in design]])
            rs.append(rows[:, names.index(target)])
        z = np.stack(zs, axis=1).reshape(-1, self.k)
        r = np.stack(rs, axis=1).reshape(-1)
        return z, r

    def stats(self, gram: Gram) -> RegressionStats:
        """Sufficient statistics of the stacked equations."""
        parts = [gram.regression(d, t) for d, t in self.equations]
        out = parts[0]
        for p in parts[1:]:
            out = out + p
        return out


@dataclass(frozen=True, eq=False)
class PowerLawBlock:
    """One block ``y = x^theta (o + U c) + e``, ``e ~ N(0, 1/tau)``: linear given ``theta``.

    Parameters
    ----------
    name : str
        Block name (``"p"``, ``"q"``).
    exponent_name : str
        Name of ``theta``.
    coef_names : tuple of str
        Names of the linear coefficients ``c`` (columns of ``design``); may be empty.
    tau_name : str
        Name of the noise precision.
    log_x, design, target : numpy.ndarray
        ``log x`` (n,), ``U`` (n, k) and ``y`` (n,), C-contiguous.
    offset : float
        ``o``: 1 when the scale is known (``y`` in per unit of it), 0 when it is the
        first linear coefficient.
    """

    name: str
    exponent_name: str
    coef_names: tuple[str, ...]
    tau_name: str
    log_x: np.ndarray
    design: np.ndarray
    target: np.ndarray
    offset: float


@dataclass(frozen=True)
class BilinearStats:
    """Sufficient statistics of a model whose residuals are bilinear in two blocks.

    The residual vector of every equation of noise group ``g`` is ``X T phi`` with
    ``phi = kron([1, u], [1, v])``; ``h[g] = sum T' X'X T`` so that the group's sum of
    squares is ``phi' h[g] phi``.

    Attributes
    ----------
    h : ndarray, shape (G, p, p)
        One matrix per noise group, ``p = (len(u) + 1) (len(v) + 1)``.
    n_eq : ndarray, shape (G,)
        Scalar equations per group (rows times equations).
    u_names, v_names, tau_names : tuple of str
        Names of the two coefficient blocks and of the G precisions.
    t0_k : tuple of float, optional
        Motor only: ``(k1, k2)`` with ``T0 = ab k1 + ac k2`` when T0 is not given.
    """

    h: np.ndarray
    n_eq: np.ndarray
    u_names: tuple[str, ...]
    v_names: tuple[str, ...]
    tau_names: tuple[str, ...]
    t0_k: tuple[float, float] | None = None

    def ssr(self, u: Sequence[float], v: Sequence[float]) -> np.ndarray:
        """Sum of squared residuals of each group at ``(u, v)``."""
        phi = np.kron(np.r_[1.0, u], np.r_[1.0, v])
        return np.maximum(np.einsum("i,gij,j->g", phi, self.h, phi), 0.0)

    def conditional(
        self, which: str, other: Sequence[float], tau: Sequence[float]
    ) -> tuple[np.ndarray, np.ndarray]:
        """Data precision ``L`` and linear term ``c`` of block ``which`` given the other.

        The log-likelihood in that block is ``-x'Lx/2 + c'x`` (plus a constant).
        """
        q1, q2 = len(self.u_names) + 1, len(self.v_names) + 1
        o = np.r_[1.0, other]
        h4 = self.h.reshape(-1, q1, q2, q1, q2)
        if which == "u":
            q = np.einsum("g,j,k,gijlk->il", np.asarray(tau, float), o, o, h4)
        else:
            q = np.einsum("g,i,l,gijlk->jk", np.asarray(tau, float), o, o, h4)
        return q[1:, 1:], -q[1:, 0]
