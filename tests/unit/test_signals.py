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


@pytest.mark.parametrize(
    "wrapper",
    [
        lambda: SystemError("CPUDispatcher(...) returned a result with an exception set"),
        # A SIGTERM during an import, inside a class's creation (found by the signal test
        # of tests/integration/test_cli_exit_clean.py in a fresh clone: xarray's import).
        lambda: RuntimeError("Error calling __set_name__ on 'Field' instance"),
        # A SIGINT during a compiled module's import, now that each command imports its
        # libraries as it runs (a fresh clone's test_ctrl_c_during_a_long_run: SciPy's
        # HiGHS, "ImportError: initialization failed", exit 1 with a traceback).
        lambda: ImportError("initialization failed"),
    ],
)
def test_a_signal_wrapped_in_another_exception_is_one_line(wrapper):
    # numba's dispatcher runs Python callbacks (unpickling a constant); a signal landing in
    # one surfaces as "SystemError: ... returned a result with an exception set" whose
    # cause is the KeyboardInterrupt: said as the interrupt, not as a traceback.
    import click
    from click.testing import CliRunner

    from loadbayes.commands.output import user_errors

    @click.command()
    @user_errors
    def cmd():
        output._STOP["signal"] = signal.SIGINT  # what _on_signal records first
        try:
            raise KeyboardInterrupt
        except KeyboardInterrupt as exc:
            raise wrapper() from exc

    @click.command()
    @user_errors
    def other():
        raise type(wrapper())("a real one")

    res = CliRunner().invoke(cmd, [])
    assert res.exit_code == 130
    assert res.output.strip() == "loadbayes: interrupted; no output was written"
    res = CliRunner().invoke(other, [])
    assert isinstance(res.exception, type(wrapper()))  # not a signal: not hidden
