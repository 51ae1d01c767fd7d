"""Chains in forked processes (core/forked.py): the threads' results, state, errors and stops.

Chains that run in Python go to one process per CPU (``sampler.chain_processes``):
their Python holds the GIL, so threads run them little faster than one, or slower. The
processes must change nothing but the time: the same draws, each chain's state back in
the caller for the next round, the progress said, an error or a signal
raised as the threads raise it, and no process left behind.
"""

from __future__ import annotations

import os
import signal
import threading
import time

import numpy as np
import pytest

from loadbayes.cases.composite_sim import simulate_event
from loadbayes.core.forked import Relay, SharedFlag, run_forked
from loadbayes.core.parallel import ChainsStopped, chain_generators, check_stop, run_chains
from loadbayes.fit.composite import sampler
from loadbayes.fit.composite.design import DesignProblem
from loadbayes.fit.composite.nls import nls
from loadbayes.models.dynamic import dynamic_model

# (Under pytest-xdist a worker runs a thread beside the tests', so can_fork() is False
# there: these tests fork all the same, and the sampler's are told they may.)
pytestmark = pytest.mark.skipif(not hasattr(os, "fork"), reason="needs os.fork")


class _Walk:
    """A chain's state: a random walk's position and its count of steps."""

    def __init__(self) -> None:
        self.x, self.steps = 0.0, 0


def _walker(state, steps, stop=None, relay=None, fail_at=None):
    def chain(i, rng):
        if state[i] is None:
            state[i] = _Walk()
        walk = state[i]
        for _ in range(steps):
            check_stop(stop)
            if fail_at is not None and i == fail_at[0] and walk.steps == fail_at[1]:
                raise ValueError(f"chain {i} failed at step {walk.steps}")
            walk.x += rng.standard_normal()
            walk.steps += 1
        if relay is not None:
            relay(steps)
        return walk.x

    return chain


def test_two_rounds_in_processes_are_the_threads_two_rounds():
    threads_state, forked_state = [None] * 5, [None] * 5
    gens_t, gens_f = chain_generators(7, 5), chain_generators(7, 5)
    told = []
    relay = Relay(told.append)
    stop = SharedFlag()
    for _ in range(2):  # the second round goes on from the state the first left
        a = run_chains(_walker(threads_state, 50), gens_t, workers=1)
        b = run_forked(_walker(forked_state, 50, relay=relay), gens_f, lanes=2, stop=stop,
                       state=forked_state, relay=relay)  # fmt: skip
        assert a == b
    assert [w.steps for w in forked_state] == [100] * 5
    assert [w.x for w in forked_state] == [w.x for w in threads_state]
    assert told == [50] * 10  # every chain's progress, both rounds, reached the caller
    assert relay.send is None  # the caller's relay is untouched


def test_an_error_in_a_lane_is_raised_here_and_stops_the_others():
    state = [None] * 4
    stop = SharedFlag()
    with pytest.raises(ValueError, match="chain 1 failed at step 30"):
        run_forked(_walker(state, 10**7, stop, fail_at=(1, 30)), chain_generators(0, 4),
                   lanes=2, stop=stop, state=state)  # fmt: skip
    assert stop.is_set()


def test_a_lane_that_dies_is_an_error_that_says_so():
    def chain(i, rng):
        os._exit(3)

    with pytest.raises(RuntimeError, match="ended without a result"):
        run_forked(chain, chain_generators(0, 2), lanes=2, stop=SharedFlag(), state=[None] * 2)


def test_sigint_stops_the_lanes_at_their_checks_and_none_is_left():
    # Python's own handler for the test (an xdist worker ignores SIGINT), and lanes that
    # end by themselves after 30 s, so that a failure fails and does not hang.
    held = signal.signal(signal.SIGINT, signal.default_int_handler)
    stop = SharedFlag()
    before = _children()

    def chain(i, rng):
        t = time.perf_counter()
        while time.perf_counter() - t < 30.0:
            check_stop(stop)
        return i

    timer = threading.Timer(0.5, lambda: os.kill(os.getpid(), signal.SIGINT))
    t0 = time.perf_counter()
    timer.start()
    try:
        with pytest.raises(KeyboardInterrupt) as got:
            run_forked(chain, chain_generators(0, 2), lanes=2, stop=stop, state=[None] * 2)
    finally:
        timer.cancel()
        signal.signal(signal.SIGINT, held)
    assert not isinstance(got.value, ChainsStopped)  # Python's own, raised after the stop
    assert time.perf_counter() - t0 < 5.0
    assert _children() <= before  # every lane reaped (none left, not even a zombie)


def _children() -> set[int]:
    # This process's children, zombies included (Linux's /proc).
    out = set()
    for entry in os.listdir("/proc"):
        if entry.isdigit():
            try:
                with open(f"/proc/{entry}/stat") as fh:
                    fields = fh.read().rsplit(")", 1)[1].split()
            except OSError:
                continue
            if int(fields[1]) == os.getpid():
                out.add(int(entry))
    return out


def _parts_problem(name):
    ev, _ = simulate_event("small_industrial", depth=0.3, t_end_s=1.0, fs=60.0, seed=3)
    model = dynamic_model(name, f_hz=60.0, window_s=0.0)
    problem = DesignProblem(model, [ev], model.default_prior([ev]))
    return problem, nls(problem)


@pytest.mark.parametrize("name", ["slm", "cmld-lite"])
def test_a_model_of_parts_draws_the_same_in_processes(name, monkeypatch):
    monkeypatch.delenv("LOADBAYES_NUM_THREADS", raising=False)
    monkeypatch.setattr(sampler, "num_threads", lambda: 2)
    monkeypatch.setattr(sampler, "can_fork", lambda: True)
    problem, start = _parts_problem(name)
    assert sampler.chain_processes(problem, False, 3, None) == 2
    runs = []
    for workers in (None, 1):  # processes, then one thread
        rounds = iter((80, 40, 0))
        runs.append(sampler.sample(problem, start=start, draws=240, burn=120, chains=3,
                                   seed=2, workers=workers,
                                   extend=lambda out, r=rounds: next(r)))  # fmt: skip
    for a, b in zip(*runs, strict=True):
        assert a.theta.shape[0] == 240
        for field in ("theta", "beta", "tau", "phi"):
            np.testing.assert_array_equal(getattr(a, field), getattr(b, field))


def test_processes_for_chains_run_in_python_where_nothing_was_asked(monkeypatch):
    monkeypatch.delenv("LOADBAYES_NUM_THREADS", raising=False)
    monkeypatch.setattr(sampler, "num_threads", lambda: 2)
    monkeypatch.setattr(sampler, "can_fork", lambda: True)
    problem, _ = _parts_problem("slm")
    assert sampler.chain_processes(problem, False, 4, None) == 2
    assert sampler.chain_processes(problem, False, 1, None) == 0  # one chain
    assert sampler.chain_processes(problem, False, 4, 1) == 0  # workers asked
    assert sampler.chain_processes(problem, True, 4, None) == 0  # compiled: threads
    monkeypatch.setattr(sampler, "num_threads", lambda: 1)
    assert sampler.chain_processes(problem, False, 4, None) == 0  # one CPU
    monkeypatch.setattr(sampler, "num_threads", lambda: 2)
    monkeypatch.setenv("LOADBAYES_NUM_THREADS", "2")
    assert sampler.chain_processes(problem, False, 4, None) == 0  # threads asked
    monkeypatch.delenv("LOADBAYES_NUM_THREADS")
    ev, _ = simulate_event("small_industrial", depth=0.3, t_end_s=6.0, fs=60.0, seed=3)
    model = dynamic_model("slm", f_hz=60.0, window_s=0.0)
    long = DesignProblem(model, [ev], model.default_prior([ev]))
    assert sampler.chain_processes(long, False, 4, None) == 2  # a long event too
    monkeypatch.setattr(sampler, "can_fork", lambda: False)
    assert sampler.chain_processes(problem, False, 4, None) == 0  # not from here


def test_can_fork_only_from_a_lone_main_thread():
    from loadbayes.core.forked import can_fork

    alone = threading.active_count() == 1
    assert can_fork() == alone
    done = threading.Event()
    other = threading.Thread(target=done.wait)
    other.start()
    try:
        assert not can_fork()
    finally:
        done.set()
        other.join()


def test_a_sheared_move_steps_the_same_after_the_trip_back():
    """A lane's state comes back pickled, so a move must step the same when copied. The
    shear's pivot was eigh's strided column: a copy made it contiguous, BLAS summed
    ``e . y`` in another order, and on the real record one chain of four left the
    threads' draws at its 4,008th iteration."""
    import copy
    import pickle

    from loadbayes.inference.moves.sheared import Shear

    rng = np.random.default_rng(5)
    s = rng.standard_normal(4000)
    bent = np.column_stack([s, 0.4 * s**2 + 0.1 * rng.standard_normal(4000),
                            *(0.5 * rng.standard_normal((21, 4000)))])  # fmt: skip
    # Turned so that the pivot spreads over every coordinate, as on a real record.
    turn = np.linalg.qr(rng.standard_normal((23, 23)))[0]
    shear = Shear(bent @ turn)
    assert shear.e.flags.c_contiguous
    for other in (pickle.loads(pickle.dumps(shear)), copy.deepcopy(shear)):
        for x in rng.standard_normal((200, 23)):
            assert other.forward(x).tobytes() == shear.forward(x).tobytes()
            assert other.inverse(x).tobytes() == shear.inverse(x).tobytes()


def test_cpu_seconds_count_the_lanes():
    # A benchmark's CPU of a fit whose chains ran in lanes: process_time alone misses it.
    def chain(i, rng):
        t = time.process_time()
        while time.process_time() - t < 0.3:
            pass
        return i

    from loadbayes.core.forked import cpu_seconds

    c0, p0 = cpu_seconds(), time.process_time()
    run_forked(chain, chain_generators(0, 2), lanes=2, stop=SharedFlag(), state=[None] * 2)
    assert cpu_seconds() - c0 >= 0.5
    assert time.process_time() - p0 < 0.3


def test_the_stop_flag_is_shared_with_a_forked_child():
    flag = SharedFlag()
    assert not flag.is_set()
    pid = os.fork()
    if pid == 0:  # pragma: no cover - the child
        flag.set()
        os._exit(0)
    os.waitpid(pid, 0)
    assert flag.is_set()
    flag.clear()
    assert not flag.is_set()
