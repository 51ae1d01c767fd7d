"""The composite load (ZIP + induction motor) fitted from disturbance recordings.

One idea a module: ``problem`` (the collapsed log-density of the motor given the events),
``sums`` (its design sums), ``robust`` (the Student-t weights), ``torque`` (estimated
torque shares), ``nls`` (the multi-start least-squares start), ``sampler`` (the
Metropolis-within-Gibbs chains), ``checks`` (what an event must hold, and the chains'
convergence), ``naming`` (the named draws of the JSON contract), ``identifiability``
(the plain-words report), ``provenance`` (the settings recorded), ``predictive`` (the
posterior band of P and Q), ``table`` (the CLI's table), ``driver`` (problem, start,
chains, posterior) and ``api`` (:func:`fit_composite`: files, tables or events, with the
CLI's options and checks). The prior is the model's: ``loadbayes.models.composite_prior``.
"""

from loadbayes.fit.composite.api import fit_composite
from loadbayes.fit.composite.driver import COMPOSITE_DEFAULTS, CompositeFit
from loadbayes.fit.composite.predictive import predictive_band

__all__ = ["COMPOSITE_DEFAULTS", "CompositeFit", "fit_composite", "predictive_band"]
