"""Measurements in: the readers of V, P, Q (f, t), events, and the per-unit checks.

``columns`` (the reader of a table's columns, with bases and row numbers for errors),
``frame`` (the Python API's in-memory tables), ``events`` (the event files of the
composite fit), ``record`` (one event's record, ``EventRecord``, and its unit check),
``units`` (per-unit checks on plain arrays).
"""
