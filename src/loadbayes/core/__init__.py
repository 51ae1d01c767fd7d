"""The shared vocabulary below models and samplers: no physics, no sampling.

``blocks`` (a model's conjugate regression blocks), ``priors`` (their priors), ``stats``
(chunk-invariant sufficient statistics) and ``parallel`` (threads and per-chain seeds).
Models and samplers both import from here and never from each other.
"""
