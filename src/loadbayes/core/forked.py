"""Chains run in forked processes: for chains whose Python holds the GIL.

Chains that run the Python iteration spend much of their time in Python, which holds the
GIL: on a short event two threads run them slower than one, on a long one a little faster
(docs/composite.md, "Models of parts on one thread"). Two processes run them side by side.

:func:`run_forked` is :func:`~loadbayes.core.parallel.run_chains` in processes. Each round
forks one process per lane from the caller's memory as it is, so the chains' state, the
problem and the compiled kernels need no transfer on the way out. A lane runs its chains
(chain ``i`` in lane ``i % lanes``, as the threads do) and sends back each chain's result
and its new state (``state[i]``), pickled, where the caller holds them for the next round.
Objects both sides hold (the problem, the model, the events, the stop flag, the progress
relay: ``shared``) travel by reference, not by value. The draws are the threads' to the
bit: each chain draws only from its own generator, whose state comes back too.

The rest is what the threads do:

- **Stop.** The stop flag is a :class:`SharedFlag`, in memory both sides see. A failed
  chain sets it, and so does a signal in the caller (``signals_at_checks``); every chain
  ends at its next check. The processes ignore SIGINT and SIGTERM (the caller's handler
  decides), and die with the caller (``PR_SET_PDEATHSIG``).
- **Progress.** A :class:`Relay` the chains call sends its counts to the caller, which
  passes them on while it waits.
- **Errors.** The first is raised in the caller, an interrupt before any other; a process
  that ends without a result is an error that says so.

Only from the main thread of a process that runs no other thread (a fork copies one
thread and whatever locks the others held), and only on Linux: :func:`can_fork`.
"""

from __future__ import annotations

import ctypes
import io
import mmap
import multiprocessing
import multiprocessing.connection
import os
import pickle
import signal
import sys
import threading
from collections.abc import Callable, Sequence
from typing import Any, TypeVar

import numpy as np

from loadbayes.core.parallel import ChainsStopped, _first_error, signals_at_checks

__all__ = ["Relay", "SharedFlag", "can_fork", "cpu_seconds", "run_forked"]

T = TypeVar("T")


class SharedFlag:
    """A stop flag in shared memory: ``set``, ``clear``, ``is_set`` as ``threading.Event``'s.

    One byte of an anonymous shared mapping, which a forked process shares with its
    parent (no file, no ``/dev/shm``, no lock: one byte is written whole).
    """

    def __init__(self) -> None:
        self._byte = mmap.mmap(-1, 1)

    def set(self) -> None:  # noqa: D102
        self._byte[0] = 1

    def clear(self) -> None:  # noqa: D102
        self._byte[0] = 0

    def is_set(self) -> bool:  # noqa: D102
        return self._byte[0] != 0


class Relay:
    """The chains' progress: calls in a forked lane reach the caller's ``target``."""

    def __init__(self, target: Callable[[int], None]) -> None:
        self.target = target
        self.send: Callable[[int], None] | None = None  # set in a lane

    def __call__(self, n: int) -> None:  # noqa: D102
        (self.target if self.send is None else self.send)(n)


def can_fork() -> bool:
    """Whether :func:`run_forked` may run here: Linux, the main thread, no other thread.

    (macOS has ``fork`` too, but its system libraries do not promise to work in a forked
    child that does not exec.)
    """
    return (
        sys.platform.startswith("linux")
        and hasattr(os, "fork")
        and threading.current_thread() is threading.main_thread()
        and threading.active_count() == 1
    )


def cpu_seconds() -> float:
    """CPU seconds of this process and of every child it has reaped: the chains' lanes.

    ``time.process_time`` counts this process alone, so a benchmark of a fit whose chains
    ran in lanes would miss their CPU. (Any other child reaped counts too.)
    """
    t = os.times()
    return t.user + t.system + t.children_user + t.children_system


def run_forked(
    chain: Callable[[int, np.random.Generator], T],
    generators: Sequence[np.random.Generator],
    *,
    lanes: int,
    stop: SharedFlag,
    state: list,
    shared: Sequence[object] = (),
    relay: Relay | None = None,
) -> list[T]:
    """Run ``chain(i, generators[i])`` for every chain in ``lanes`` forked processes.

    ``state[i]``, as ``chain`` leaves it in the lane, comes back with the result and
    replaces the caller's (the module docstring), and ``generators[i]`` is set to where
    the lane left it, as a thread leaves it. ``shared``: objects sent by reference.
    """
    n = len(generators)
    lanes = max(1, min(int(lanes), n))
    refs = [*shared, stop, *(() if relay is None else (relay,))]
    out: list = [None] * n
    errors: list[BaseException] = []
    children: dict[multiprocessing.connection.Connection, int] = {}
    with signals_at_checks(stop):
        try:
            for k in range(lanes):
                read, write = multiprocessing.Pipe(duplex=False)
                pid = os.fork()
                if pid == 0:  # pragma: no cover - the lane (its coverage is not collected)
                    read.close()
                    _lane(k, lanes, chain, generators, state, refs, relay, stop, write)
                write.close()
                children[read] = pid
            while children:
                for conn in multiprocessing.connection.wait(list(children)):
                    if _receive(conn, refs, relay, out, state, generators, errors, stop):
                        conn.close()
                        os.waitpid(children.pop(conn), 0)
        except BaseException as exc:  # an interrupt or error here: stop the lanes, reap them
            errors.append(exc)
            stop.set()
            for conn, pid in children.items():
                conn.close()
                os.waitpid(pid, 0)
    if errors:
        raise _first_error(errors)
    return out


def _receive(conn, refs, relay, out, state, generators, errors, stop) -> bool:
    # One message of a lane; True when the lane is done (its result, an error or its end).
    try:
        kind, payload = _loads(conn.recv_bytes(), refs)
    except EOFError:
        errors.append(RuntimeError("a chains' process ended without a result"))
        stop.set()
        return True
    if kind == "progress":
        relay.target(payload)
        return False
    if kind == "done":
        for i, (result, new_state, drawn) in payload.items():
            out[i], state[i] = result, new_state
            generators[i].bit_generator.state = drawn  # where the lane left it
    else:
        errors.append(payload)
        stop.set()
    return True


def _lane(k, lanes, chain, generators, state, refs, relay, stop, conn) -> None:  # pragma: no cover
    # A forked process: its chains, then their results and states to the caller. It never
    # returns (os._exit: no atexit handler, no inherited buffer flushed twice).
    code = 0
    try:
        signal.signal(signal.SIGINT, signal.SIG_IGN)
        signal.signal(signal.SIGTERM, signal.SIG_IGN)
        _die_with_parent()
        try:
            if relay is not None:
                relay.send = lambda m: conn.send_bytes(_dumps(("progress", m), refs))
            got = {}
            for i in range(k, len(generators), lanes):
                if stop.is_set():
                    raise ChainsStopped()
                got[i] = (chain(i, generators[i]), state[i], generators[i].bit_generator.state)
            conn.send_bytes(_dumps(("done", got), refs))
        except BaseException as exc:  # noqa: BLE001 - sent to the caller, raised there
            stop.set()
            try:
                conn.send_bytes(_dumps(("error", exc), refs))
            except Exception:  # noqa: BLE001 - an exception that does not pickle
                said = RuntimeError(f"{type(exc).__name__}: {exc}")
                conn.send_bytes(_dumps(("error", said), ()))
    except BaseException:  # noqa: BLE001 - nothing may leave the lane; the caller sees EOF
        code = 1
    finally:
        os._exit(code)


def _die_with_parent() -> None:  # pragma: no cover - in a lane
    # Linux's PR_SET_PDEATHSIG: the lane gets SIGKILL when the caller dies.
    try:
        ctypes.CDLL(None, use_errno=True).prctl(1, signal.SIGKILL)
    except (OSError, AttributeError):
        pass


def _dumps(obj: Any, refs: Sequence[object]) -> bytes:
    ids = {id(o): k for k, o in enumerate(refs)}

    class _Pickler(pickle.Pickler):
        def persistent_id(self, o):  # noqa: D102
            return ids.get(id(o))

    buf = io.BytesIO()
    _Pickler(buf, protocol=pickle.HIGHEST_PROTOCOL).dump(obj)
    return buf.getvalue()


def _loads(data: bytes, refs: Sequence[object]) -> Any:
    class _Unpickler(pickle.Unpickler):
        def persistent_load(self, pid):  # noqa: D102
            return refs[pid]

    return _Unpickler(io.BytesIO(data)).load()
