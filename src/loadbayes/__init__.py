"""loadbayes: Bayesian identification of power-system load models."""

from loadbayes._version import __version__

__all__ = ["__version__"]
