"""Threads and per-chain random generators: the one copy every sampler uses.

:func:`run_chains` runs one closure per chain on its own generator; :func:`run_threads`
runs a list of callables (row blocks of a compiled kernel).

Chains and row blocks run in plain threads because the compiled kernels release the GIL;
each chain draws from its own generator spawned from the caller's seed, so the draws do
not depend on the number of threads.

A stop flag ends the chains early: a chain loop calls :func:`check_stop` every iteration,
which raises :class:`ChainsStopped` once its run's flag is set (another chain failed, or
the main thread was interrupted) or :func:`request_stop` was called (the CLI's SIGINT /
SIGTERM handler does). Without it, Ctrl-C took effect only when the running chains ended
(minutes later on a long composite fit).

While chains that check such a flag run, SIGINT and SIGTERM do not raise wherever the main
thread happens to be (:func:`signals_at_checks`): they set the flag, the chains stop at
their next check, and the signal is delivered as before once they have. A
``KeyboardInterrupt`` raised at an arbitrary bytecode crashed the process (SIGSEGV, about
one run in 12-70 of ``tests/integration/test_cli_composite_signals.py``): numba's
unboxing of a ``numpy.random.Generator`` argument calls ``ctypes.cast``, a Python
function, and reads ``.value`` of its result without checking it for NULL, so an
exception raised inside that call (the signal's handler runs there) is dereferenced
(numba 0.65-0.68, ``numba/core/boxing.py``, ``unbox_numpy_random_bitgenerator``;
``tests/unit/test_signals_at_checks.py`` shows it).

:func:`one_blas_thread` runs a function with the BLAS and OpenMP pools held at one thread
(threadpoolctl): the composite fit's least squares are small (a 2,402 x 7 ``lstsq`` cost
15.9 ms of CPU on OpenBLAS's two threads of a loaded machine, 0.10 ms on one), and its
chains are the threads it wants.
"""

from __future__ import annotations

import contextlib
import functools
import os
import signal
import threading
from collections.abc import Callable, Sequence
from typing import TypeVar

import numpy as np
from threadpoolctl import threadpool_limits

T = TypeVar("T")

__all__ = [
    "ChainsStopped",
    "asked_threads",
    "chain_generators",
    "chain_seeds",
    "check_stop",
    "clear_stop",
    "num_threads",
    "one_blas_thread",
    "request_stop",
    "run_chains",
    "run_threads",
    "signals_at_checks",
]

#: Set by :func:`request_stop` (a signal): every running chain stops at its next check.
_ALL_STOP = threading.Event()


class ChainsStopped(KeyboardInterrupt):
    """A chain stopped at its stop flag (a KeyboardInterrupt: the run was interrupted)."""


def one_blas_thread(func: Callable[..., T]) -> Callable[..., T]:
    """``func`` run with the BLAS and OpenMP thread pools at one thread, then restored.

    Around a fit, not a whole command: a big streaming fit elsewhere may want the threads.
    """

    @functools.wraps(func)
    def capped(*args, **kwargs):
        with threadpool_limits(limits=1):
            return func(*args, **kwargs)

    return capped


def request_stop() -> None:
    """Ask every running chain to stop at its next :func:`check_stop` (signal-safe)."""
    _ALL_STOP.set()


def clear_stop() -> None:
    """Forget a :func:`request_stop` (a new command run in the same process)."""
    _ALL_STOP.clear()


def check_stop(stop: threading.Event | None = None) -> None:
    """Raise :class:`ChainsStopped` if ``stop`` is set or :func:`request_stop` was called.

    Cheap (two flag reads): a chain loop calls it every iteration.
    """
    if _ALL_STOP.is_set() or (stop is not None and stop.is_set()):
        raise ChainsStopped()


def asked_threads() -> int | None:
    """The threads ``LOADBAYES_NUM_THREADS`` asks for, or None when it is not set."""
    env = os.environ.get("LOADBAYES_NUM_THREADS", "").strip()
    if not env:
        return None
    try:
        return max(int(env), 1)
    except ValueError:
        raise ValueError(f"LOADBAYES_NUM_THREADS must be an integer, got {env!r}") from None


def num_threads() -> int:
    """Threads to use: ``LOADBAYES_NUM_THREADS`` or the CPUs available to this process."""
    asked = asked_threads()
    if asked is not None:
        return asked
    try:
        return max(len(os.sched_getaffinity(0)), 1)
    except AttributeError:  # pragma: no cover - not on Linux
        return max(os.cpu_count() or 1, 1)


def _first_error(errors: list[BaseException]) -> BaseException:
    # The cause, not the chains it stopped: an interrupt first, then a real error.
    for kind in (lambda e: isinstance(e, KeyboardInterrupt) and not isinstance(e, ChainsStopped),
                 lambda e: not isinstance(e, ChainsStopped)):  # fmt: skip
        for exc in errors:
            if kind(exc):
                return exc
    return errors[0]


def _deferrable(handler) -> bool:
    """Whether :func:`signals_at_checks` holds ``handler`` back.

    Python's own for SIGINT, and any marked ``stops_chains = True`` (the CLI's, which
    raises once it has recorded the signal). Any other is the caller's, and stays.
    """
    return handler is signal.default_int_handler or bool(getattr(handler, "stops_chains", False))


@contextlib.contextmanager
def signals_at_checks(stop: threading.Event | None):
    """SIGINT and SIGTERM inside the block stop the chains at their checks, then raise.

    In the main thread, with a raising handler (Python's ``KeyboardInterrupt``, or one
    marked ``stops_chains``) and a ``stop`` flag the chains check: the signal sets
    ``stop`` and :func:`request_stop` instead of raising at whatever bytecode runs (the
    module's notes say why), and the block's end calls the handler it held back, which
    raises there; a signal the chains finished before noticing is raised all the same.
    Elsewhere, or without ``stop``, the handlers stay as they are. The twin of
    :func:`loadbayes.io.atomic.held_signals`, which holds every handler back for a few
    renames; here the chains must also hear of the signal at once (their flags), and a
    handler of the caller's own (not a raising one) is left to run where it lands.
    """
    if stop is None or threading.current_thread() is not threading.main_thread():
        yield
        return
    pending: list[int] = []
    had_stop = _ALL_STOP.is_set()

    def held(signum, frame) -> None:
        if not pending:
            pending.append(signum)
        stop.set()
        _ALL_STOP.set()

    previous = {}
    for s in (signal.SIGINT, signal.SIGTERM):
        h = signal.getsignal(s)
        if _deferrable(h):
            previous[s] = signal.signal(s, held)
    try:
        yield
    finally:
        for s, h in previous.items():
            signal.signal(s, h)
        if pending:
            if not had_stop:  # the handler sets it again if it wants it (the CLI's does)
                _ALL_STOP.clear()
            previous[pending[0]](pending[0], None)


def run_threads(
    tasks: Sequence[Callable[[], None]], *, stop: threading.Event | None = None
) -> None:
    """Run callables concurrently: the first in this thread, the others in new threads.

    Meant for compiled kernels that release the GIL. Threads are started per call (tens
    of microseconds), which keeps this safe after ``fork`` and from any thread. The first
    exception raised by a task is re-raised here once all have finished (an interrupt
    before any other error). When ``stop`` is given it is set as soon as a task fails or
    this thread is interrupted, so tasks that call :func:`check_stop` end within one step
    instead of running to their end.
    """
    with signals_at_checks(stop):
        _run_threads(tasks, stop)


def _run_threads(tasks: Sequence[Callable[[], None]], stop: threading.Event | None) -> None:
    if len(tasks) == 1:
        tasks[0]()
        return
    errors: list[BaseException] = []

    def guarded(task: Callable[[], None]) -> None:
        try:
            task()
        except BaseException as exc:  # noqa: BLE001 - re-raised in the caller
            errors.append(exc)
            if stop is not None:
                stop.set()

    threads = [threading.Thread(target=guarded, args=(t,), daemon=True) for t in tasks[1:]]
    try:
        for th in threads:
            th.start()
        guarded(tasks[0])
        for th in threads:
            th.join()
    except BaseException as exc:  # an interrupt outside a task (in a join, say)
        errors.append(exc)
        if stop is not None:
            stop.set()
        for th in threads:
            if th.ident is not None:  # started
                th.join()
    if errors:
        raise _first_error(errors)


def chain_seeds(
    seed: int | np.random.SeedSequence | None, chains: int
) -> list[np.random.SeedSequence]:
    """One seed per chain, spawned from the run's seed: chain ``i`` gets child ``i``.

    What :func:`chain_generators` makes its generators from; a seed (unlike a generator)
    travels to another process (the fleet's chains under Dask).
    """
    seq = seed if isinstance(seed, np.random.SeedSequence) else np.random.SeedSequence(seed)
    return seq.spawn(chains)


def chain_generators(
    rng: np.random.Generator | int | np.random.SeedSequence | None, chains: int
) -> list[np.random.Generator]:
    """One independent generator per chain, derived from ``rng`` (a seed or a Generator)."""
    if isinstance(rng, np.random.Generator):
        return list(rng.spawn(chains))
    return [np.random.default_rng(s) for s in chain_seeds(rng, chains)]


def run_chains(
    chain: Callable[[int, np.random.Generator], T],
    generators: Sequence[np.random.Generator],
    *,
    workers: int | None = None,
    stop: threading.Event | None = None,
) -> list[T]:
    """Run ``chain(i, generators[i])`` for every chain, in up to ``workers`` threads.

    The one chain runner of every sampler. Each chain draws only from its own generator,
    so the results do not depend on the number of threads. Threads are plain (joined
    before returning, none left running at exit); chain ``i`` runs in thread
    ``i % workers``, the first in the caller's thread.

    Parameters
    ----------
    chain : callable
        ``chain(index, rng) -> result``.
    generators : sequence of Generator
        One per chain (:func:`chain_generators`).
    workers : int, optional
        Threads; default ``min(chains, num_threads())``. 1 runs every chain here.
    stop : threading.Event, optional
        The chains' stop flag: set here when a chain fails or the caller is interrupted;
        a chain that calls ``check_stop(stop)`` every iteration then ends at once (raising
        :class:`ChainsStopped`) and the cause is re-raised.

    Returns
    -------
    list
        The results, in chain order.
    """
    n = len(generators)
    workers = min(n, num_threads()) if workers is None else max(1, min(int(workers), n))
    out: list = [None] * n

    def lane(k: int) -> Callable[[], None]:
        def run() -> None:
            for i in range(k, n, workers):
                check_stop(stop)
                out[i] = chain(i, generators[i])

        return run

    with signals_at_checks(stop):
        if workers <= 1:
            lane(0)()
        else:
            _run_threads([lane(k) for k in range(workers)], stop)
    return out
