"""SIGINT and SIGTERM while chains run: they stop at their checks, then the signal raises.

``core.parallel.signals_at_checks``: a ``KeyboardInterrupt`` raised at an arbitrary
bytecode of the main thread crashed the process when it landed in numba's unboxing of a
``numpy.random.Generator`` (the first test shows that crash, in a child process).
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import threading

import pytest

from loadbayes.core import parallel
from loadbayes.core.parallel import ChainsStopped, chain_generators, check_stop, run_chains


@pytest.fixture
def python_sigint():
    # Python's own SIGINT handler for the test (a runner may have set another), restored.
    before = signal.signal(signal.SIGINT, signal.default_int_handler)
    parallel.clear_stop()
    yield
    signal.signal(signal.SIGINT, before)
    parallel.clear_stop()


def test_numba_dereferences_a_failed_ctypes_cast_when_unboxing_a_generator():
    # Why the handlers are held back: an exception inside ctypes.cast (where a signal's
    # handler can run) during the unboxing of a Generator argument is read as an object.
    code = (
        "import ctypes, numba, numpy as np\n"
        "f = numba.njit(lambda g: g.random())\n"
        "g = np.random.default_rng(0)\n"
        "f(g)\n"
        "def cast(obj, typ):\n"
        "    raise KeyboardInterrupt\n"
        "ctypes.cast = cast\n"
        "try:\n"
        "    f(g)\n"
        "except KeyboardInterrupt:\n"
        "    print('raised')\n"
    )
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
    assert r.returncode == -signal.SIGSEGV, (
        "numba now survives an exception in its generator's unboxing "
        f"(exit {r.returncode}, {r.stdout!r}): signals_at_checks may no longer be needed"
    )


def _busy() -> float:
    # A Python call that takes most of a chain's time: where a raised signal would land.
    total = 0.0
    for k in range(2_000):
        total += k * 0.5
    return total


def _chains(send_at: int, *, sig: int = signal.SIGINT, check: bool = True):
    inside: list[int] = []
    stop = threading.Event()

    def chain(i, rng) -> int:
        for k in range(200_000):
            try:
                _busy()
            except KeyboardInterrupt:
                inside.append(k)
                raise
            if i == 0 and k == send_at:
                os.kill(os.getpid(), sig)
            if check:
                check_stop(stop)
            elif k > send_at + 50:
                return k
        return -1

    return chain, stop, inside


def test_a_signal_stops_the_chains_at_their_checks_then_raises(python_sigint):
    chain, stop, inside = _chains(20)
    with pytest.raises(KeyboardInterrupt) as info:
        run_chains(chain, chain_generators(0, 2), workers=2, stop=stop)
    assert inside == []  # never raised inside the chain's own calls
    assert type(info.value) is KeyboardInterrupt  # Python's handler, after the chains
    assert isinstance(info.value.__context__, ChainsStopped)  # ... stopped at a check
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler
    assert not parallel._ALL_STOP.is_set()  # a later run in this process is not stopped


def test_a_signal_the_chains_ended_before_noticing_still_raises(python_sigint):
    chain, stop, inside = _chains(20, check=False)
    with pytest.raises(KeyboardInterrupt) as info:
        run_chains(chain, chain_generators(0, 1), workers=1, stop=stop)
    assert inside == [] and info.value.__context__ is None


def test_the_clis_handler_is_held_back_and_then_says_the_signal(python_sigint):
    from loadbayes.commands import signals as cli_signals

    cli_signals.install_signal_handlers()
    try:
        chain, stop, inside = _chains(20, sig=signal.SIGTERM)
        with pytest.raises(cli_signals.Terminated) as info:
            run_chains(chain, chain_generators(0, 2), workers=2, stop=stop)
        assert inside == [] and isinstance(info.value.__context__, ChainsStopped)
        assert cli_signals._STOP["signal"] == signal.SIGTERM
        assert parallel._ALL_STOP.is_set()  # the CLI's handler asks every chain to stop
        assert signal.getsignal(signal.SIGTERM) is cli_signals._on_signal
    finally:
        cli_signals.restore_signal_handlers()


def test_without_a_stop_flag_or_outside_the_main_thread_the_handlers_stay(python_sigint):
    seen = []

    def look(i, rng):
        seen.append(signal.getsignal(signal.SIGINT))

    run_chains(look, chain_generators(0, 1), workers=1)  # no stop flag
    out: list = []
    t = threading.Thread(target=lambda: out.append(
        run_chains(look, chain_generators(0, 1), workers=1, stop=threading.Event())))  # fmt: skip
    t.start()
    t.join()
    assert seen == [signal.default_int_handler] * 2 and out == [[None]]
