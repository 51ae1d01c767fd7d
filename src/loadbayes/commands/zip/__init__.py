"""``loadbayes fit zip``: one bus (``bus.py``), or a fleet of buses with ``--by`` (``fleet.py``).

One command in two modules: the single-bus fit hands over to the fleet runner when
``--by`` is given, and both share the single-bus options.
"""

from loadbayes.commands.zip.bus import fit_zip_cmd

__all__ = ["fit_zip_cmd"]
