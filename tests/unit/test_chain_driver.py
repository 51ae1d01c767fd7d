"""The Metropolis-within-Gibbs driver (inference/chain.py) on a toy step: what it keeps."""

import numpy as np
import pytest

from loadbayes.core.parallel import ChainsStopped, chain_generators, chain_seeds
from loadbayes.inference.chain import Chain, Field, is_kept, kept_count


def _walk(state, rng, it):
    return state + rng.standard_normal(2)


def _chain(rng, burn=7, thin=3, **kw):
    return Chain(_walk, np.zeros(2), rng, fields={"x": (2,), "it": Field((), np.int64)},
                 record=lambda s: {"x": s, "it": 0}, burn=burn,
                 thin=thin, **kw)  # fmt: skip


def test_kept_count_is_the_kept_rule_counted():
    for burn in (0, 1, 5):
        for thin in (1, 2, 3):
            for start in range(12):
                for end in range(start, 20):
                    want = sum(is_kept(i, burn, thin) for i in range(start, end))
                    assert kept_count(start, end, burn, thin) == want


def test_rounds_give_the_draws_of_one_run():
    one = _chain(np.random.default_rng(1))
    one.run(40)
    split = _chain(np.random.default_rng(1))
    for n in (3, 10, 0, 27):
        split.run(n)
    np.testing.assert_array_equal(one.draws()["x"], split.draws()["x"])
    assert one.draws()["x"].shape == (kept_count(0, 40, 7, 3), 2) == (11, 2)
    assert one.draws()["it"].dtype == np.int64 and split.iteration == 40


def test_kept_draws_are_the_states_at_the_kept_iterations():
    rng = np.random.default_rng(2)
    chain = _chain(np.random.default_rng(2), burn=4, thin=2)
    chain.run(15)
    states, x = [], np.zeros(2)
    for it in range(15):
        x = _walk(x, rng, it)
        if is_kept(it, 4, 2):
            states.append(x)
    np.testing.assert_array_equal(chain.draws()["x"], np.array(states))


def test_streamed_fields_reach_the_sink_in_blocks():
    got = {}

    def sink(start, bufs, count):
        got.setdefault("x", []).append((start, bufs["x"][:count].copy()))

    mem = _chain(np.random.default_rng(3), burn=2, thin=1)
    mem.run(25)
    fields = {"x": Field((2,), streamed=True), "it": Field((), np.int64)}
    streamed = Chain(_walk, np.zeros(2), np.random.default_rng(3), fields=fields,
                     record=lambda s: {"x": s, "it": 0}, burn=2, block=5, sink=sink)  # fmt: skip
    streamed.run(25)
    assert [s for s, _ in got["x"]] == [0, 5, 10, 15, 20] and "x" not in streamed.draws()
    np.testing.assert_array_equal(np.vstack([b for _, b in got["x"]]), mem.draws()["x"])


def test_a_batched_run_stores_where_the_compiled_loop_writes():
    def batch(state, rng, start, m, out, kept0):
        for it in range(start, start + m):
            state = _walk(state, rng, it)
            if is_kept(it, 7, 3):
                out["x"][(it - 7) // 3 - kept0] = state
                out["it"][(it - 7) // 3 - kept0] = 0
        return state

    ref = _chain(np.random.default_rng(4))
    ref.run(50)
    chain = _chain(np.random.default_rng(4))
    chain.run_batched(20, 6, batch)
    chain.run_batched(30, 7, batch)
    np.testing.assert_array_equal(chain.draws()["x"], ref.draws()["x"])


def test_statistics_progress_and_the_stop_flag():
    import threading

    done = []
    chain = _chain(np.random.default_rng(5), stats=lambda: {"acceptance": 0.25},
                   progress=done.append, progress_every=0.0)  # fmt: skip
    chain.run(30)
    assert sum(done) == 30 and chain.sample_stats() == {"acceptance": 0.25}
    stop = threading.Event()
    stop.set()
    with pytest.raises(ChainsStopped):
        _chain(np.random.default_rng(5), stop=stop).run(3)


def test_chain_generators_are_made_from_the_chain_seeds():
    seeds = chain_seeds(8, 3)
    assert [s.spawn_key for s in seeds] == [(0,), (1,), (2,)]
    for g, s in zip(chain_generators(8, 3), seeds, strict=True):
        assert g.standard_normal() == np.random.default_rng(s).standard_normal()
