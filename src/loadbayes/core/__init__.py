"""The shared vocabulary below models and samplers: no physics, no sampling.

``blocks`` (a model's conjugate regression blocks), ``priors`` (their priors), ``stats``
(chunk-invariant sufficient statistics), ``parallel`` (threads and per-chain seeds) and
``display`` (numbers as a reader wants them, a fit's summary rows and notebook view).
Models and samplers both import from here and never from each other.
"""
