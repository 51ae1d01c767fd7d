"""Exports of a fitted load model to power-system simulators.

One module per format, ``loadbayes.export.<fmt>`` (``pandapower``, ``psse``, ``andes``),
each exposing ``FORMAT``, ``SUFFIXES`` and
``write(values, out, *, model, header, options) -> list[Path]``; the ``loadbayes export``
command picks the parameter set from a posterior and calls ``write``.
"""
