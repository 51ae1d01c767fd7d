"""A signal that lands in a callback Python cannot raise from still stops the run quietly."""

from __future__ import annotations

import gc
import signal
import sys
import weakref

import pytest

from loadbayes.commands import signals as output


class _Obj:
    pass


def _unraisable_from_a_finaliser(exc: BaseException) -> None:
    # A weakref callback's exception is "unraisable": Python hands it to sys.unraisablehook
    # and goes on, as when SIGTERM arrives during garbage collection.
    obj = _Obj()

    def callback(_ref, exc=exc):
        raise exc

    ref = weakref.ref(obj, callback)
    del obj
    gc.collect()
    del ref


def test_a_swallowed_signal_is_silent_and_still_stops_the_run(capsys):
    before = sys.unraisablehook
    output.install_signal_handlers()
    previous = output._STOP["previous_unraisable"]
    try:
        output._STOP["signal"] = signal.SIGTERM  # what _on_signal records first
        _unraisable_from_a_finaliser(output.Terminated())
        assert capsys.readouterr().err == ""  # no "Exception ignored in ..." traceback
        with pytest.raises(output.Terminated):
            output.stop_if_signalled()
        # Any other unraisable exception is still reported by the previous hook.
        seen = []
        output._STOP["previous_unraisable"] = lambda args: seen.append(args.exc_type)
        _unraisable_from_a_finaliser(ValueError("boom"))
        assert seen == [ValueError]
    finally:
        output._STOP["signal"] = None
        output._STOP["previous_unraisable"] = previous
        output.restore_signal_handlers()
    assert sys.unraisablehook is before
