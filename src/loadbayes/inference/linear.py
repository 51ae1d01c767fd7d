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
from loadbayes.core.settings import SamplerSettings
from loadbayes.core.stats import Gram
from loadbayes.inference.gibbs import Scheme, sample_block

__all__ = ["DEFAULTS", "sample_blocks"]

#: The settings of :func:`sample_blocks` when none are given: the paper's M and m, seed 0.
DEFAULTS = SamplerSettings(draws=40_000, burn=5_000, chains=4, seed=0)


def sample_blocks(
    gram: Gram,
    blocks: Sequence[LinearBlock],
    priors: Mapping[str, BlockPrior],
    *,
    scheme: Scheme = "blocked",
    settings: SamplerSettings | None = None,
) -> dict[str, np.ndarray]:
    """Sample every block and return named draws shaped (chain, draw).

    ``settings`` (:data:`DEFAULTS` when not given) are those of every block, except that
    each block gets its own child of ``settings.seed`` (``SeedSequence.spawn``), so adding
    a block (say Q next to P) leaves the draws of the others unchanged.
    """
    settings = DEFAULTS if settings is None else settings
    seed = settings.seed
    seq = seed if isinstance(seed, np.random.SeedSequence) else np.random.SeedSequence(seed)
    children = seq.spawn(len(blocks))
    out: dict[str, np.ndarray] = {}
    for block, child in zip(blocks, children, strict=True):
        res = sample_block(
            block.stats(gram),
            priors[block.name],
            scheme=scheme,
            settings=settings.with_(seed=child),
        )
        for i, name in enumerate(block.coef_names):
            out[name] = res.coef[..., i]
        out[block.tau_name] = res.tau
    return out
