"""Figures of fits.

``fit`` (the panels of a fit's figures, ``--plot`` and the report) and ``composite`` (a
composite fit against its events), ``validation`` (a composite fit against held-out
events).
"""
