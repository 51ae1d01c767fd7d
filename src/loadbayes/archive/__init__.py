"""An archive of recorder files: its fits pooled per station (``pool``)."""

from loadbayes.archive.pool import PoolResult, pool

__all__ = ["PoolResult", "pool"]
