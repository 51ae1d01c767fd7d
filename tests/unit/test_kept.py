"""core/kept.py: the bounded store, and values kept per event by the object, not its id.

The parts models keep each event's arrays and solves. Keyed by ``id(event)`` (before),
a model given a second event where Python had put a freed first one read the first
one's voltage for the second: the first test rebuilds that where CPython hands the
freed address to the next event (alone, it always did here) and asserts what makes it
impossible anywhere: nothing of a collected event is held.
"""

from __future__ import annotations

import gc
import types

import numpy as np

from feeder_generator import simulate
from loadbayes.core.kept import Kept, PerObject, token
from loadbayes.measurements.record import EventRecord
from loadbayes.models.dynamic import dynamic_model
from loadbayes.models.parts_sums import _fixed_of


def _at_a_freed_address(make, gone_id: int, tries: int = 500):
    # A new object where a freed one was: CPython reuses a freed block of the same size.
    held = []
    for _ in range(tries):
        obj = make()
        if id(obj) == gone_id:
            return obj
        held.append(obj)
    return None


def test_a_new_event_at_a_freed_events_address_gets_its_own_arrays():
    t, v, d, p, q, _ = simulate(sag=0.2)
    model = dynamic_model("slm", f_hz=50.0)
    first = EventRecord(t, v, p, q, d, "first")
    gone = id(first)
    assert np.array_equal(_fixed_of(model, first)[1], v)
    assert model.kept(first).size > 0 and len(model._fixed) == 1
    v9 = 0.9 * v
    del first
    gc.collect()
    # Nothing of it held on: no later object can be handed its arrays (the id-keyed
    # dicts kept the entry, under a key the next object at that address matched).
    assert len(model._fixed) == 0 and len(model._kept) == 0
    second = _at_a_freed_address(lambda: EventRecord(t, v9, p, q, d, "second"), gone)
    if second is None:  # another thread took the block (xdist's): the address case untried
        second = EventRecord(t, v9, p, q, d, "second")
    assert np.array_equal(_fixed_of(model, second)[1], v9)  # by id: the first's V
    key = (token(second), 0.0)
    assert model.lowest_voltage(second, np.zeros(len(model.theta_names))) == model._lowest[key]


def test_token_is_never_given_again():
    class Obj:
        pass

    a = Obj()
    ta, gone = token(a), id(a)
    assert token(a) == ta  # the same object, the same number
    del a
    gc.collect()
    b = _at_a_freed_address(Obj, gone)
    if b is None:  # another thread took the block (xdist's): the address case untried
        b = Obj()
    assert token(b) != ta  # by id: equal wherever b sits at a's address
    # An object that cannot be weakly referenced: a new number each time (never matched).
    ns = types.SimpleNamespace()
    assert token(ns) != token(ns)


def test_per_object_keeps_the_first_value_and_forgets_the_dead():
    class Obj:
        pass

    store, a = PerObject(), Obj()
    assert store.get(a) is None
    assert store.keep(a, 1) == 1 and store.keep(a, 2) == 1 and store.get(a) == 1
    del a
    gc.collect()
    assert len(store) == 0
    ns = types.SimpleNamespace()
    assert store.keep(ns, 3) == 3 and store.get(ns) is None  # not kept, computed again


def test_kept_empties_whole_past_its_size():
    k = Kept(2)
    for i in range(3):
        k.keep(i, i)
    assert dict(k) == {0: 0, 1: 1, 2: 2}
    k.keep(3, 3)  # past size 2 with three held: emptied, then stored
    assert dict(k) == {3: 3}


def test_a_model_holding_the_stores_still_pickles_and_its_copy_starts_empty():
    # Models go to Dask workers and processes: a weak mapping alone cannot be pickled.
    import copy
    import pickle

    t, v, d, p, q, _ = simulate(sag=0.2)
    model = dynamic_model("cmld-lite", f_hz=60.0)
    event = EventRecord(t, v, p, q, d, "e")
    _fixed_of(model, event)
    model.lowest_voltage(event, np.zeros(len(model.theta_names)))
    assert len(model._lowest) == 1
    for other in (pickle.loads(pickle.dumps(model)), copy.deepcopy(model)):
        # Empty: the numbers of token() in the bounded stores' keys are this process's.
        assert len(other._fixed) == 0 and len(other._kept) == 0 and len(other._lowest) == 0
        assert other._lowest.size == model._lowest.size
        np.testing.assert_array_equal(_fixed_of(other, event)[1], v)
    assert len(model._fixed) == 1
