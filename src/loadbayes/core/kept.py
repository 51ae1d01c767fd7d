"""A sampler's recent values kept by key: a dict emptied whole when it passes its size.

A Metropolis-within-Gibbs iteration asks the same quantities of one state several times
(the move's proposal, the steps after it, the prior, the support), and most steps leave
most coordinates as they were. The parts models keep such values by the bytes of the
coordinates they depend on. Emptying the store whole when it is full (not evicting the
oldest) keeps a lookup one dict access; a sampler only ever reads back its last few
states, which are stored again at once.

Values of one event (its arrays, its solves) are kept by the event object itself
(:class:`PerObject`, :func:`token`), never by ``id(event)``: an id is an address, and
Python gives a freed event's address to the next object of its size. Keyed by id, a
model fitted to one event and then to another read the first one's V, P and Q for the
second (reproduced in ``tests/unit/test_kept.py``).
"""

from __future__ import annotations

import itertools
import weakref
from typing import Any

__all__ = ["Kept", "PerObject", "token"]


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

    def __reduce__(self) -> tuple:
        # Pickled or copied empty: its keys may hold :func:`token` numbers, which another
        # process gives to its own objects (a model sent to a Dask worker would have met
        # there the solves of the sender's events under its events' numbers).
        return (Kept, (self.size,))


class PerObject:
    """Values kept per object, by identity, for as long as the object lives.

    A weak mapping: an entry goes when its object is collected, so a model fitted to one
    event after another keeps none of the dead ones' arrays. An object that cannot be
    weakly referenced (a ``SimpleNamespace``) is not kept: :meth:`get` gives None and
    the caller computes again.
    """

    def __init__(self) -> None:
        self._values: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()

    def get(self, obj: Any) -> Any:
        """The value kept for ``obj``, or None."""
        try:
            return self._values.get(obj)
        except TypeError:  # not weakly referable
            return None

    def keep(self, obj: Any, value: Any) -> Any:
        """Keep ``value`` for ``obj`` unless one is kept already; return the kept one."""
        try:
            return self._values.setdefault(obj, value)
        except TypeError:
            return value

    def __len__(self) -> int:
        return len(self._values)

    def __reduce__(self) -> tuple:
        # Pickled or copied empty: the values belong to this process's objects (a model
        # sent to a worker or a process meets other event objects there), and a weak
        # mapping cannot be pickled (a model holding one could not be sent at all).
        return (PerObject, ())


_TOKENS = PerObject()
_NEXT = itertools.count()


def token(obj: Any) -> int:
    """A number that stands for ``obj`` in a key, given to no other object in this process.

    Unlike ``id(obj)``, it is not given again once ``obj`` is freed, so a key holding it
    can go stale but never match another object. An object that cannot be weakly
    referenced gets a new number at every call (its keys never match: computed again).
    """
    got = _TOKENS.get(obj)
    return got if got is not None else _TOKENS.keep(obj, next(_NEXT))
