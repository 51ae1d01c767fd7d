"""The interface every load model implements, and nothing else.

A model is physics: it knows its parameters, how measurements become its likelihood
pieces, its prediction and its transformed quantities. It never imports a sampler, a fit
driver or :class:`~loadbayes.posterior.Posterior`; the samplers in
:mod:`loadbayes.inference` consume these pieces and know no physics.

Likelihood pieces (a model offers one or more kinds; see docs/architecture.md):

``gram_columns``, ``rows(data)``, ``blocks``
    Conjugate linear-Gaussian blocks read off one Gram matrix of the rows
    (:class:`~loadbayes.core.blocks.LinearBlock`): O(1) per sweep in the number of samples.
``power_law_blocks(data)``, ``from_power_law(...)``
    Blocks ``y = x^theta (o + U c) + e``, linear given one exponent
    (:class:`~loadbayes.core.blocks.PowerLawBlock`), for Metropolis within Gibbs.
``bilinear_stats(gram)``
    Residuals bilinear in two coefficient blocks (:class:`~loadbayes.core.blocks.BilinearStats`).

Every model (:class:`LoadModel`) also has ``name``, ``pieces`` (which of the above it
offers: ``"linear"``, ``"power-law"`` or ``"bilinear"``), ``coefficients`` (reported),
``free`` (checked pairwise for identifiability), ``default_priors()``,
``check(gram) -> warnings`` and ``transform(draws)``. The static models (ZIP,
exponential) also have ``predict(draws, v, ...)``, which :meth:`Posterior.predict
<loadbayes.posterior.Posterior.predict>` calls; the motor has none, so it is not part
of the protocol.

The composite load (:mod:`loadbayes.models.composite`) is not a :class:`LoadModel`: its
response is an integrated ODE, and its collapsed log-density of the nonlinear parameters lives
with its sampler in :mod:`loadbayes.fit.composite.problem`.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Protocol, runtime_checkable

import numpy as np

from loadbayes.core.blocks import LinearBlock
from loadbayes.core.stats import Gram

__all__ = ["LinearModel", "LoadModel"]


@runtime_checkable
class LoadModel(Protocol):
    """What every model offers, whatever its likelihood pieces."""

    name: str

    @property
    def pieces(self) -> str: ...  # noqa: D102

    @property
    def coefficients(self) -> list[str]: ...  # noqa: D102

    @property
    def free(self) -> list[str]: ...  # noqa: D102

    def default_priors(self) -> Mapping[str, object]: ...  # noqa: D102

    def check(self, gram: Gram) -> list[str]: ...  # noqa: D102

    def transform(self, draws: Mapping[str, np.ndarray]) -> dict[str, np.ndarray]: ...  # noqa: D102


@runtime_checkable
class LinearModel(Protocol):
    """What the conjugate samplers need from a model whose likelihood is linear blocks."""

    name: str

    @property
    def gram_columns(self) -> tuple[str, ...]: ...  # noqa: D102

    @property
    def blocks(self) -> list[LinearBlock]: ...  # noqa: D102

    @property
    def coefficients(self) -> list[str]: ...  # noqa: D102

    def rows(self, data: Mapping[str, np.ndarray]) -> np.ndarray: ...  # noqa: D102

    def check(self, gram: Gram) -> list[str]: ...  # noqa: D102

    def transform(self, draws: Mapping[str, np.ndarray]) -> dict[str, np.ndarray]: ...  # noqa: D102
