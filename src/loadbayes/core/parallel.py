"""Threads and per-chain random generators: the one copy every sampler uses.

:func:`run_chains` runs one closure per chain on its own generator; :func:`run_threads`
runs a list of callables (row blocks of a compiled kernel).

Chains and row blocks run in plain threads because the compiled kernels release the GIL;
each chain draws from its own generator spawned from the caller's seed, so the draws do
not depend on the number of threads.
"""

from __future__ import annotations

import os
import threading
from collections.abc import Callable, Sequence
from typing import TypeVar

import numpy as np

T = TypeVar("T")

__all__ = ["chain_generators", "num_threads", "run_chains", "run_threads"]


def num_threads() -> int:
    """Threads to use: ``LOADBAYES_NUM_THREADS`` or the CPUs available to this process."""
    env = os.environ.get("LOADBAYES_NUM_THREADS", "").strip()
    if env:
        try:
            return max(int(env), 1)
        except ValueError:
            raise ValueError(f"LOADBAYES_NUM_THREADS must be an integer, got {env!r}") from None
    try:
        return max(len(os.sched_getaffinity(0)), 1)
    except AttributeError:  # pragma: no cover - not on Linux
        return max(os.cpu_count() or 1, 1)


def run_threads(tasks: Sequence[Callable[[], None]]) -> None:
    """Run callables concurrently: the first in this thread, the others in new threads.

    Meant for compiled kernels that release the GIL. Threads are started per call (tens
    of microseconds), which keeps this safe after ``fork`` and from any thread. The first
    exception raised by a task is re-raised here once all have finished.
    """
    if len(tasks) == 1:
        tasks[0]()
        return
    errors: list[BaseException] = []

    def guarded(task: Callable[[], None]) -> None:
        try:
            task()
        except BaseException as exc:  # noqa: BLE001 - re-raised in the caller
            errors.append(exc)

    threads = [threading.Thread(target=guarded, args=(t,), daemon=True) for t in tasks[1:]]
    for th in threads:
        th.start()
    guarded(tasks[0])
    for th in threads:
        th.join()
    if errors:
        raise errors[0]


def chain_generators(
    rng: np.random.Generator | int | np.random.SeedSequence | None, chains: int
) -> list[np.random.Generator]:
    """One independent generator per chain, derived from ``rng`` (a seed or a Generator)."""
    if isinstance(rng, np.random.Generator):
        return list(rng.spawn(chains))
    seq = rng if isinstance(rng, np.random.SeedSequence) else np.random.SeedSequence(rng)
    return [np.random.default_rng(s) for s in seq.spawn(chains)]


def run_chains(
    chain: Callable[[int, np.random.Generator], T],
    generators: Sequence[np.random.Generator],
    *,
    workers: int | None = None,
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
                out[i] = chain(i, generators[i])

        return run

    if workers <= 1:
        lane(0)()
    else:
        run_threads([lane(k) for k in range(workers)])
    return out
