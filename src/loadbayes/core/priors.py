"""Priors of a linear-Gaussian block: normal on the coefficients, gamma on the precision."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

__all__ = ["BlockPrior", "DEFAULT_COEF_SD", "DEFAULT_TAU_RATE", "DEFAULT_TAU_SHAPE"]

#: Prior standard deviation of each coefficient by default. Load coefficients are of
#: order one (ZIP shares, motor coefficients in per unit), so sd 10 is weak.
DEFAULT_COEF_SD = 10.0
#: Gamma(shape, rate) on a noise precision by default: close to the scale-free 1/tau,
#: so that it neither favours a noise level nor lets tau reach infinity on noise-free data.
DEFAULT_TAU_SHAPE = 1e-3
DEFAULT_TAU_RATE = 1e-9


@dataclass(frozen=True)
class BlockPrior:
    """Prior of one block ``r = Z b + e``, ``e ~ N(0, 1/tau)``.

    Parameters
    ----------
    mean : array_like, shape (k,)
        Prior mean of the coefficients ``b``.
    precision : array_like, shape (k,) or (k, k)
        Prior precision of ``b`` (a vector means a diagonal matrix).
    shape, rate : float
        Gamma prior of ``tau`` (shape-rate form: mean ``shape / rate``).
    conjugate : bool
        ``False`` (the paper's prior): ``b ~ N(mean, precision^-1)`` independent of
        ``tau``. ``True``: the conjugate normal-gamma prior
        ``b | tau ~ N(mean, (tau precision)^-1)``, whose posterior is known exactly.

    Notes
    -----
    The paper (section "Gibbs in ZIP Model") uses independent normal priors on a1, a2
    and a gamma prior on tau; that is ``conjugate=False``.
    """

    mean: np.ndarray
    precision: np.ndarray
    shape: float = DEFAULT_TAU_SHAPE
    rate: float = DEFAULT_TAU_RATE
    conjugate: bool = False
    names: tuple[str, ...] = field(default=())

    def __post_init__(self) -> None:
        mean = np.atleast_1d(np.asarray(self.mean, dtype=float))
        prec = np.asarray(self.precision, dtype=float)
        if prec.ndim <= 1:
            prec = np.diag(np.broadcast_to(prec, mean.shape).astype(float))
        k = mean.size
        if prec.shape != (k, k):
            raise ValueError(f"prior precision must be ({k},) or ({k}, {k}), got {prec.shape}")
        if not np.all(np.isfinite(mean)) or not np.all(np.isfinite(prec)):
            raise ValueError("prior mean and precision must be finite")
        sym = (prec + prec.T) / 2
        # A diagonal matrix's eigenvalues are its diagonal: the usual prior (``weak``, a
        # vector precision) skips eigvalsh, O(k^3) (10 s of CPU per cvr fit of k ~ 1,500).
        diag = np.diagonal(sym)
        eig = diag if np.count_nonzero(sym) == np.count_nonzero(diag) else np.linalg.eigvalsh(sym)
        if np.any(eig < 0):
            raise ValueError("prior precision must be positive semi-definite")
        if not (self.shape > 0 and self.rate > 0 and np.isfinite(self.shape + self.rate)):
            raise ValueError("gamma prior shape and rate must be positive and finite")
        if self.conjugate and np.any(eig <= 0):
            raise ValueError("the conjugate prior needs a positive-definite precision")
        object.__setattr__(self, "mean", mean)
        object.__setattr__(self, "precision", sym)

    @property
    def k(self) -> int:
        """Number of coefficients."""
        return self.mean.size

    @classmethod
    def weak(
        cls,
        k: int,
        *,
        sd: float | Sequence[float] = DEFAULT_COEF_SD,
        mean: float | Sequence[float] = 0.0,
        shape: float = DEFAULT_TAU_SHAPE,
        rate: float = DEFAULT_TAU_RATE,
        conjugate: bool = False,
    ) -> BlockPrior:
        """Independent normals of standard deviation ``sd`` and a vague gamma."""
        sd_arr = np.broadcast_to(np.asarray(sd, dtype=float), (k,))
        if np.any(sd_arr <= 0) or not np.all(np.isfinite(sd_arr)):
            raise ValueError("prior standard deviations must be positive and finite")
        return cls(
            mean=np.broadcast_to(np.asarray(mean, dtype=float), (k,)).copy(),
            precision=1.0 / sd_arr**2,
            shape=shape,
            rate=rate,
            conjugate=conjugate,
        )
