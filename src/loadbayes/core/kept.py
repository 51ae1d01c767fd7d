"""A sampler's recent values kept by key: a dict emptied whole when it passes its size.

A Metropolis-within-Gibbs iteration asks the same quantities of one state several times
(the move's proposal, the steps after it, the prior, the support), and most steps leave
most coordinates as they were. The parts models keep such values by the bytes of the
coordinates they depend on. Emptying the store whole when it is full (not evicting the
oldest) keeps a lookup one dict access; a sampler only ever reads back its last few
states, which are stored again at once.
"""

from __future__ import annotations

from typing import Any

__all__ = ["Kept"]


class Kept(dict):
    """A dict whose :meth:`keep` empties it first once it holds more than ``size`` keys."""

    def __init__(self, size: int) -> None:
        super().__init__()
        self.size = size

    def keep(self, key: Any, value: Any) -> Any:
        """Store ``value`` under ``key`` (emptying the store first if full); return it."""
        if len(self) > self.size:
            self.clear()
        self[key] = value
        return value
