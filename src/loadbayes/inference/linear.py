"""Independent conjugate blocks read off one Gram matrix, sampled together.

A model describes its parameters as :class:`LinearBlock` objects: each block has its own
coefficients and noise precision, and one or more equations (design columns, target
column) that share them (the motor's two flux equations share ``b1, b2`` and ``tau_E``).
This module knows nothing about power systems: it turns a Gram matrix and priors into
draws.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from loadbayes.inference.gibbs import Scheme, sample_block
from loadbayes.inference.priors import BlockPrior
from loadbayes.inference.stats import Gram, RegressionStats

__all__ = ["LinearBlock", "sample_blocks"]


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


def sample_blocks(
    gram: Gram,
    blocks: Sequence[LinearBlock],
    priors: Mapping[str, BlockPrior],
    *,
    scheme: Scheme = "blocked",
    chains: int = 4,
    draws: int = 40_000,
    burn: int = 5_000,
    thin: int = 1,
    init: str = "prior",
    seed: int | np.random.SeedSequence | None = 0,
) -> dict[str, np.ndarray]:
    """Sample every block and return named draws shaped (chain, draw).

    Each block gets its own child of ``seed`` (``SeedSequence.spawn``), so adding a block
    (say Q next to P) leaves the draws of the others unchanged.
    """
    seq = seed if isinstance(seed, np.random.SeedSequence) else np.random.SeedSequence(seed)
    children = seq.spawn(len(blocks))
    out: dict[str, np.ndarray] = {}
    for block, child in zip(blocks, children, strict=True):
        res = sample_block(
            block.stats(gram),
            priors[block.name],
            scheme=scheme,
            chains=chains,
            draws=draws,
            burn=burn,
            thin=thin,
            init=init,  # type: ignore[arg-type]
            rng=child,
        )
        for i, name in enumerate(block.coef_names):
            out[name] = res.coef[..., i]
        out[block.tau_name] = res.tau
    return out
