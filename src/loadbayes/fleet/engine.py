"""Where the fleet's tasks run: in this process, or on Dask workers.

- neither ``scheduler`` nor ``workers``: in this process, one task after another (the
  embedded default; Dask is not even imported);
- ``workers=N``: a :class:`dask.distributed.LocalCluster` of ``N`` worker processes
  (one thread each: the compiled kernels and NumPy already use the cores they are given),
  started here and shut down at the end; every one of its sockets listens on loopback
  only, and its dashboard is off unless asked for (``dashboard=True``, on loopback too:
  it lists the workers and the tasks to whoever reaches it);
- ``scheduler="tcp://host:8786"``: a :class:`dask.distributed.Client` connected to an
  existing cluster.

Every task is a pure function of its inputs and seeds, so the results do not depend on
where or in what order tasks run. If a worker dies, Dask re-runs its unfinished tasks on
another worker (up to ``distributed.scheduler.allowed-failures`` times); results are
collected by task, in submission order, so a bus is neither lost nor counted twice.
"""

from __future__ import annotations

import logging
import os
from collections.abc import Callable, Sequence
from typing import Any

__all__ = ["Engine"]


#: Where a local cluster's scheduler, workers and dashboard listen.
_LOOPBACK = "127.0.0.1"
#: The scheduler's only HTTP route when the dashboard is off.
_HEALTH = ["distributed.http.health"]

#: Times a task lost with a dying worker is submitted again before giving up.
_ATTEMPTS = 3


#: Dask's own log lines (timestamped ``distributed.*`` warnings when a worker is lost or
#: the run is interrupted) are kept from the user's terminal below this level; what they
#: report reaches the user as loadbayes' one-line messages (a task lost is re-run, an
#: interrupted run says what was written).
_DASK_LOG_LEVEL = logging.CRITICAL


def _quiet_dask() -> None:
    """Raise the level of Dask's loggers, here and in the worker processes started."""
    # Read by dask's config when a worker process imports it (they inherit the environ).
    os.environ.setdefault("DASK_LOGGING__DISTRIBUTED", logging.getLevelName(_DASK_LOG_LEVEL))
    for name in ("distributed", "tornado", "bokeh"):
        logging.getLogger(name).setLevel(_DASK_LOG_LEVEL)


class Engine:
    """Run tasks in-process or on Dask; use as a context manager.

    Parameters
    ----------
    scheduler : str, optional
        Address of a running Dask scheduler.
    workers : int, optional
        Start a local cluster of this many worker processes.
    client : dask.distributed.Client, optional
        Use this client (tests share one cluster between runs); not closed at the end.
    dashboard : bool, default False
        Serve the local cluster's dashboard (on 127.0.0.1, a free port:
        :attr:`dashboard_link`).
    """

    def __init__(
        self,
        *,
        scheduler: str | None = None,
        workers: int | None = None,
        client: Any = None,
        dashboard: bool = False,
    ) -> None:
        if scheduler and workers:
            raise ValueError("give --scheduler or --workers, not both")
        if workers is not None and workers < 1:
            raise ValueError(f"--workers must be at least 1, got {workers}")
        self.scheduler = scheduler
        self.workers = workers
        self.client = client
        self.dashboard = dashboard
        self._own: list[Any] = []
        #: Seconds it took to start (or reach) the cluster; 0 in process.
        self.startup_seconds = 0.0
        #: On a cluster: the tasks' own CPU seconds (each task's thread time, summed) and
        #: the wall seconds spent waiting for them in :meth:`map` (what the cluster cost).
        self.task_cpu_seconds = 0.0
        self.map_seconds = 0.0

    @property
    def name(self) -> str:
        """Where tasks run, in words (recorded with the results)."""
        if self.client is not None:
            return f"dask ({len(self.client.scheduler_info()['workers'])} workers)"
        return "in-process"

    def __enter__(self) -> Engine:
        if self.client is not None or not (self.scheduler or self.workers):
            return self
        import time

        t0 = time.monotonic()
        _quiet_dask()
        try:
            from dask.distributed import Client, LocalCluster
        except ImportError:  # pragma: no cover - the cluster extra is missing
            raise ValueError(
                "--workers and --scheduler need Dask: pip install 'loadbayes[cluster]'"
            ) from None
        _quiet_dask()  # again: importing distributed sets its loggers' levels from its config
        if self.scheduler:
            try:
                self.client = Client(self.scheduler, timeout="20s")
            except OSError as exc:
                raise ValueError(
                    f"cannot reach the Dask scheduler {self.scheduler}: {exc}"
                ) from None
        else:
            import dask

            # Loopback only: dashboard_address=":0" served the dashboard on 0.0.0.0. The
            # scheduler's HTTP server runs whatever is asked (a free loopback port, not
            # 8787); without the dashboard it answers only /health (no pages that list
            # the workers and tasks).
            routes = {} if self.dashboard else {"distributed.scheduler.http.routes": _HEALTH}
            with dask.config.set(routes):
                cluster = LocalCluster(
                    n_workers=self.workers,
                    threads_per_worker=1,
                    processes=True,
                    host=_LOOPBACK,
                    worker_dashboard_address=None,
                    scheduler_kwargs={
                        "dashboard": self.dashboard,
                        "dashboard_address": f"{_LOOPBACK}:0",
                    },
                    silence_logs=_DASK_LOG_LEVEL,
                )
            self._own.append(cluster)
            self.client = Client(cluster)
        self._own.insert(0, self.client)
        self.startup_seconds = time.monotonic() - t0
        return self

    @property
    def dashboard_link(self) -> str | None:
        """The local cluster's dashboard address (``http://127.0.0.1:PORT/status``), or None."""
        if not self.dashboard or not self._own:
            return None
        return self._own[-1].dashboard_link

    def __exit__(self, *exc: object) -> None:
        for obj in self._own:
            obj.close()
        if self._own:
            self.client = None
        self._own = []

    def map(
        self,
        func: Callable[..., Any],
        items: Sequence[Any],
        *args: Any,
        done: Callable[[int, Any], None] | None = None,
        **kwargs: Any,
    ) -> list[Any]:
        """``[func(item, *args, **kwargs) for item in items]``, on the engine.

        ``done(i, result)`` is called as each task finishes (for a progress bar). The
        first task error is raised here, as it was raised in the task.
        """
        if self.client is None:
            out = []
            for i, item in enumerate(items):
                out.append(func(item, *args, **kwargs))
                if done is not None:
                    done(i, out[-1])
            return out
        import time

        t0 = time.monotonic()
        results: list[Any] = [None] * len(items)
        todo = list(range(len(items)))
        try:
            for _ in range(_ATTEMPTS):
                todo = self._run(func, items, todo, args, kwargs, results, done)
                if not todo:
                    break
            else:
                raise RuntimeError(
                    f"{len(todo)} tasks lost their workers {_ATTEMPTS} times in a row; "
                    "the cluster is not stable enough to finish"
                )
        finally:
            self.map_seconds += time.monotonic() - t0
        return results

    def _run(self, func, items, todo, args, kwargs, results, done) -> list[int]:
        """Submit the items ``todo``; return those lost with a worker (to run again).

        A worker that dies takes its scattered copies and running tasks with it; the
        scheduler then cancels the tasks that needed them ("lost dependencies"). Those are
        submitted again with freshly scattered arguments; every result is stored by its
        item's index, so nothing is lost or counted twice.
        """
        from dask.distributed import as_completed
        from distributed.client import FutureCancelledError
        from distributed.scheduler import KilledWorker

        # Large shared arguments go to the workers once, not once per task.
        # Fresh keys (hash=False): a copy lost with a worker is not confused with a new one.
        shared = [self.client.scatter(a, broadcast=True, hash=False) for a in args]
        kw = {k: self.client.scatter(v, broadcast=True, hash=False) for k, v in kwargs.items()}
        futures = [
            self.client.submit(_timed_call, func, items[i], *shared, pure=False, **kw) for i in todo
        ]
        index = {f.key: i for f, i in zip(futures, todo, strict=True)}
        lost: list[int] = []
        try:
            for fut in as_completed(futures):
                i = index[fut.key]
                try:
                    results[i], cpu = fut.result()
                except (FutureCancelledError, KilledWorker):
                    lost.append(i)
                    continue
                self.task_cpu_seconds += cpu
                if done is not None:
                    done(i, results[i])
        finally:
            for f in futures:
                f.release()
        return sorted(lost)


def _timed_call(func: Callable[..., Any], item: Any, *args: Any, **kwargs: Any) -> tuple:
    """``(func(item, *args, **kwargs), the CPU seconds of the worker thread that ran it)``."""
    import time

    c0 = time.thread_time()
    out = func(item, *args, **kwargs)
    return out, time.thread_time() - c0
