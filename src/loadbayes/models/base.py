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

A dynamic load (:class:`DynamicLoadModel`: the composite of a static part and motors,
whose response to a recorded voltage is an integrated ODE) is linear in its coefficients
given its nonlinear parameters: each event's P and Q are ``Z_p(theta) beta`` and
``Z_q(theta) beta``. It names its parameters (``theta_names``, the sampled
``free_coordinates`` and the map ``scale_free`` between them, ``beta_names``), gives its
prior for a set of events, the response and the design of one event, and the composition
of a draw (the shares and powers a user reads). :func:`loadbayes.fit.composite.fit_composite`
consumes that, whatever the model; the registry is :mod:`loadbayes.models.dynamic`.
"""

from __future__ import annotations

import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any, Protocol, runtime_checkable

import numpy as np

from loadbayes.core.blocks import LinearBlock
from loadbayes.core.stats import Gram
from loadbayes.io.errors import OptionError

__all__ = ["DynamicLoadModel", "GaussianPrior", "LinearModel", "LoadModel", "ModelOptionError"]


class ModelOptionError(OptionError):
    """A model option no fit can run with, worded for whoever set it.

    The message is a template whose ``{field}`` tokens are the model's field names:
    ``str(err)`` spells them as Python does (``noise ar1 works with likelihood normal
    only``), :meth:`worded` as a command line's flags do (``--noise ar1 works with
    --likelihood normal only``), from one table of field -> flag.
    """

    def __init__(self, template: str) -> None:
        self.template = template
        super().__init__(self.worded({}))

    def worded(self, names: Mapping[str, str]) -> str:
        """The message with each ``{field}`` spelled as ``names`` says (default: the field)."""
        out = self.template
        for field in set(re.findall(r"\{(\w+)\}", out)):
            out = out.replace("{" + field + "}", names.get(field, field))
        return out


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


@runtime_checkable
class DynamicLoadModel(Protocol):
    """A load whose response to a recorded voltage is simulated, linear in ``beta``.

    Attributes
    ----------
    name : str
        The registry's name (``zip+motor``).
    theta_names : tuple of str
        The nonlinear parameters (their logs where positive).
    free_coordinates : tuple of str
        The coordinates the sampler moves: ``scale_free @ theta``'s leading rows (the
        rest, a scale the terminal data never see, is drawn from the prior).
    scale_free : ndarray, shape (len(theta_names), len(theta_names))
        The map from ``theta`` to the free coordinates (then the scale).
    beta_names : tuple of str
        Each event's linear coefficients, in the order of the design's columns.
    quantities : mapping of str to (str, str)
        The unit and the meaning in words of each named draw the model reports (its
        parameters and the composition's quantities).
    """

    name: str
    theta_names: tuple[str, ...]
    free_coordinates: tuple[str, ...]
    scale_free: np.ndarray
    beta_names: tuple[str, ...]
    quantities: Mapping[str, tuple[str, str]]

    def default_prior(self, events: Sequence[Any]) -> Any: ...  # noqa: D102

    def response(self, event: Any, theta: np.ndarray, **kw: Any) -> Any: ...  # noqa: D102

    def design(self, event: Any, *response: np.ndarray) -> tuple[np.ndarray, np.ndarray]: ...  # noqa: D102

    def composition(self, beta: np.ndarray, *response0: np.ndarray) -> dict[str, np.ndarray]: ...  # noqa: D102


@dataclass(frozen=True)
class GaussianPrior:
    """A dynamic model's prior in the form the fit reads: the simplest one.

    Normal ``u ~ N(mean, diag(sd^2))`` of the free coordinates, zero-mean normal
    coefficients of sd ``beta_sd`` (``positive``: the index of one truncated to positive
    values, or None) and Gamma(``tau_shape``, ``tau_rate``) noise precisions. The
    ``zip+motor`` model's own prior (``models/composite_prior.py``) has the same methods.
    """

    mean: np.ndarray
    sd: np.ndarray
    beta_sd: np.ndarray
    tau_shape: float = 1e-3
    tau_rate: float = 1e-9
    positive: int | None = None

    def __post_init__(self) -> None:
        for name in ("mean", "sd", "beta_sd"):
            object.__setattr__(self, name, np.asarray(getattr(self, name), dtype=float))
        if self.mean.shape != self.sd.shape or not (self.sd > 0).all():
            raise ValueError("mean and sd must have one entry per free coordinate, sd > 0")
        if not (self.beta_sd > 0).all():
            raise ValueError("beta_sd must be positive")

    def scale_free(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
        """``(mean, cov, gain, sd_cond)`` as ``CompositePrior.scale_free``: no scale left."""
        return self.mean, np.diag(self.sd**2), np.zeros(self.mean.size), 0.0

    def log_u(self, u: np.ndarray) -> float:
        """Log prior density of the free coordinates up to a constant."""
        z = (np.asarray(u, dtype=float) - self.mean) / self.sd
        return -0.5 * float(z @ z)

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready description (for the output's settings)."""
        return {
            "u": {"mean": self.mean.tolist(), "sd": self.sd.tolist()},
            "beta_sd": self.beta_sd.tolist(),
            "tau": {"shape": self.tau_shape, "rate": self.tau_rate},
        }
