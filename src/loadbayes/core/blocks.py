"""A model's conjugate regression blocks, as the samplers read them off a Gram matrix.

A model describes its parameters as :class:`LinearBlock` objects: each block has its own
coefficients and noise precision, and one or more equations (design columns, target
column) that share them (the motor's two flux equations share ``b1, b2`` and ``tau_E``).
"""

from __future__ import annotations

from dataclasses import dataclass

from loadbayes.core.stats import Gram, RegressionStats

__all__ = ["LinearBlock"]


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

    def stats(self, gram: Gram) -> RegressionStats:
        """Sufficient statistics of the stacked equations."""
        parts = [gram.regression(d, t) for d, t in self.equations]
        out = parts[0]
        for p in parts[1:]:
            out = out + p
        return out
