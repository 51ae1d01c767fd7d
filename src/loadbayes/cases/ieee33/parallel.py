"""Running many power flows: fixed-size chunks, a process pool, a progress bar.

The chunk size is fixed, not derived from the worker count, so every number is the same
for any number of workers; workers are forked where the platform allows it.
"""

from __future__ import annotations

import multiprocessing
import sys
from concurrent.futures import ProcessPoolExecutor, as_completed
from typing import Any

import numpy as np

# Experiments per task. Fixed, not derived from the worker count, so that chunk
# boundaries (where the "recycle" engine restarts cold) and hence every number are the
# same for any number of workers.
_CHUNK = 200


def solve_chunks(
    feeder: Any,
    f: np.ndarray,
    zp: np.ndarray,
    zq: np.ndarray,
    *,
    workers: int,
    progress: bool,
) -> tuple[np.ndarray, np.ndarray]:
    """Solve every row of ``f`` with ``feeder``, here or in ``workers`` processes.

    Returns ``(out, ok)``: ``(n, 3)`` of (V p.u., P MW, Q Mvar), NaN where not converged,
    and ``(n,)`` converged flags. A worker rebuilds the feeder from ``feeder._config()``.
    """
    n = f.shape[0]
    out = np.full((n, 3), np.nan)
    ok = np.zeros(n, dtype=bool)
    chunks = [slice(i, min(i + _CHUNK, n)) for i in range(0, n, _CHUNK)]
    workers = int(workers)
    if workers < 1:
        raise ValueError(f"workers must be >= 1, got {workers}")
    if workers == 1 or len(chunks) == 1:
        with _progress(n, progress) as bar:
            for s in chunks:
                out[s], ok[s] = feeder._solve_chunk(f[s], zp[s], zq[s])
                bar(s.stop - s.start)
    else:
        with ProcessPoolExecutor(
            max_workers=min(workers, len(chunks)),
            mp_context=_mp_context(),
            initializer=_worker_init,
            initargs=(type(feeder), feeder._config()),
        ) as pool:
            futures = {pool.submit(_worker_solve, f[s], zp[s], zq[s]): s for s in chunks}
            # The bar (a thread) starts after the workers are forked.
            with _progress(n, progress) as bar:
                for fut in as_completed(futures):
                    s = futures[fut]
                    out[s], ok[s] = fut.result()
                    bar(s.stop - s.start)
    return out, ok


_WORKER: Any = None


def _worker_init(cls: type, config: dict[str, Any]) -> None:
    # The feeder class comes in as an argument, so this module need not import it.
    global _WORKER
    _WORKER = cls(**config)


def _worker_solve(
    factors: np.ndarray, zp: np.ndarray, zq: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    assert _WORKER is not None
    return _WORKER._solve_chunk(factors, zp, zq)


def _mp_context() -> multiprocessing.context.BaseContext:
    methods = multiprocessing.get_all_start_methods()
    return multiprocessing.get_context("fork" if "fork" in methods else "spawn")


class _progress:
    """Context manager giving an ``update(k)`` callable; a tqdm bar if asked and installed."""

    def __init__(self, total: int, enabled: bool) -> None:
        self._bar = None
        if enabled:
            try:
                from tqdm import tqdm
            except ImportError:
                return
            self._bar = tqdm(total=total, unit="pf", file=sys.stderr)

    def __enter__(self):
        return self._bar.update if self._bar is not None else (lambda k: None)

    def __exit__(self, *exc: object) -> None:
        if self._bar is not None:
            self._bar.close()
