"""Calibration of every sampler: the registry of sampler cases and the ``make validate`` run.

The statistical test tier runs the same registry with few replications; ``python -m
loadbayes.studies.calibration`` runs the full counts and writes a report.
"""
