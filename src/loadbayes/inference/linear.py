"""Independent conjugate blocks read off one Gram matrix, sampled together.

A model describes its parameters as :class:`~loadbayes.core.blocks.LinearBlock` objects;
this module knows nothing about power systems: it turns a Gram matrix and priors into
draws.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np

from loadbayes.core.blocks import LinearBlock
from loadbayes.core.priors import BlockPrior
from loadbayes.core.stats import Gram
from loadbayes.inference.gibbs import Scheme, sample_block

__all__ = ["sample_blocks"]


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
