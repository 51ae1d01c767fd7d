"""An archive of fault records: scanned into a catalog, fitted event by event, pooled.

- :func:`scan` (:mod:`.scan`): a folder tree of COMTRADE records into the SQLite
  catalog (:mod:`.catalog`), bays matched to loads by name rules (:mod:`.names`);
- :func:`fit` (:mod:`.fit`): every usable event fitted, in one process or on Dask,
  each result committed as it finishes (a rerun resumes);
- :func:`fits_frame`: the fitted shares, one row per event and share; :func:`units_frame`,
  :func:`events_frame`, :func:`failures_frame`: the stations' bays, the events found,
  what failed and why (what ``loadbayes report archive.db`` shows);
- :func:`pool` (:mod:`.pool`): each station's composition over the year, its events'
  fitted shares pooled across stations.
"""

from __future__ import annotations

from loadbayes.archive.catalog import events_frame, failures_frame, fits_frame, units_frame
from loadbayes.archive.fit import fit
from loadbayes.archive.pool import PoolResult, pool
from loadbayes.archive.scan import scan

__all__ = [
    "PoolResult",
    "events_frame",
    "failures_frame",
    "fit",
    "fits_frame",
    "pool",
    "scan",
    "units_frame",
]
