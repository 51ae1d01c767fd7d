"""SIGINT and SIGTERM during a command: recorded, raised in the main thread, said once.

:func:`install_signal_handlers` makes both raise (SIGTERM as :class:`Terminated`, a
``KeyboardInterrupt``) so that every clean-up path runs;
:func:`loadbayes.commands.output.user_errors` turns that into one line and exit 130 or
143, with every output or none (:func:`stop_if_signalled` catches a signal whose
exception a library swallowed). :func:`restore_signal_handlers` leaves the process as it
was, for a command run in-process.
"""

from __future__ import annotations

import signal
import sys
from typing import Any

__all__ = [
    "EXIT_SIGNAL",
    "Terminated",
    "install_signal_handlers",
    "restore_signal_handlers",
    "stop_if_signalled",
]

EXIT_SIGNAL = {signal.SIGINT: 130, signal.SIGTERM: 143}


class Terminated(KeyboardInterrupt):
    """SIGTERM, raised like Ctrl-C so every clean-up path that handles one handles both."""


_STOP: dict[str, Any] = {"signal": None, "outputs": None, "committed": False}


def _on_signal(signum, frame) -> None:
    # The first signal stops the run; later ones are ignored so that the clean-up
    # (removing temporary files) is not itself interrupted.
    if _STOP["signal"] is not None:
        return
    _STOP["signal"] = signum
    # The chains running in other threads see this at their next iteration (the
    # exception below reaches only the main thread).
    from loadbayes.core.parallel import request_stop

    request_stop()
    raise Terminated() if signum == signal.SIGTERM else KeyboardInterrupt()


#: Chains that check their stop flag hold this handler back while they run and call it
#: once they have stopped (core.parallel.signals_at_checks: a raise at an arbitrary
#: bytecode could crash the process inside numba's unboxing of a generator).
_on_signal.stops_chains = True


def _unraisable(hook_args) -> None:
    # A signal that lands while Python runs a callback whose exceptions it cannot raise
    # (a weakref finaliser during garbage collection) makes it print "Exception ignored
    # in ..." and a traceback, then go on. The run still stops: the signal is recorded,
    # and stop_if_signalled raises it at the next check (before anything is committed).
    # So that exception is said by the usual one line, not as a traceback.
    if issubclass(hook_args.exc_type, KeyboardInterrupt) and _STOP["signal"] is not None:
        return
    _STOP.get("previous_unraisable", sys.__unraisablehook__)(hook_args)


def install_signal_handlers() -> None:
    """SIGINT and SIGTERM raise in the main thread (no-op elsewhere, or if installed)."""
    import threading

    if threading.current_thread() is not threading.main_thread():
        return
    if signal.getsignal(signal.SIGINT) is _on_signal:
        return
    from loadbayes.core.parallel import clear_stop

    clear_stop()
    _STOP.update(signal=None, outputs=None, committed=False)
    _STOP["previous"] = {s: signal.getsignal(s) for s in EXIT_SIGNAL}
    for s in EXIT_SIGNAL:
        signal.signal(s, _on_signal)
    _STOP["previous_unraisable"] = sys.unraisablehook
    sys.unraisablehook = _unraisable


def restore_signal_handlers() -> None:
    """Put back the handlers :func:`install_signal_handlers` found.

    A command run in-process (by a test or a notebook) leaves the process as it was.
    """
    import threading

    previous = _STOP.pop("previous", None)
    if previous is None or threading.current_thread() is not threading.main_thread():
        return
    for s, h in previous.items():
        signal.signal(s, h if h is not None else signal.SIG_DFL)
    from loadbayes.core.parallel import clear_stop

    clear_stop()
    sys.unraisablehook = _STOP.pop("previous_unraisable", sys.__unraisablehook__)


def stop_if_signalled() -> None:
    """Raise if a signal arrived whose exception a library swallowed (HDF5 writes do)."""
    sig = _STOP["signal"]
    if sig is not None:
        raise Terminated() if sig == signal.SIGTERM else KeyboardInterrupt()
