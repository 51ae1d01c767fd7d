"""Checks that the samplers are calibrated: SBC, coverage, Geweke, exact large-n sums.

The same code serves the statistical test tier (small, fast, fixed seeds) and
``make validate`` (:mod:`loadbayes.experiments.validate`, larger runs and a report), which
is why it lives in the package rather than under ``tests/``.
"""
