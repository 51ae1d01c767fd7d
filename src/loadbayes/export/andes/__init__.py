"""The ANDES adapter.

``conventions`` (loadbayes' motor and ZIP in ANDES's fields), ``case`` (a composite load
added to an ANDES system), ``run`` (time-domain runs) and ``writer`` (the
``export --to andes`` format).
"""
