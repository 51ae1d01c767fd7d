"""The composite load (ZIP + induction motor) fitted from disturbance recordings.

One idea a module: ``problem`` (the collapsed log-density of the motor given the events),
``sums`` (its design sums), ``robust`` (the Student-t weights), ``torque`` (estimated
torque shares), ``nls`` (the multi-start least-squares start), ``sampler`` (the
Metropolis-within-Gibbs chains), ``checks`` (what an event must hold), and ``driver``
(:func:`fit_composite`: problem, start, chains, posterior).
"""

from loadbayes.fit.composite.driver import fit_composite

__all__ = ["fit_composite"]
