"""Several outputs as one (issue 14): all or none, and never a temporary file left."""

from __future__ import annotations

import os
import signal
import threading

import pytest

from loadbayes.io.errors import DataError
from loadbayes.io.transaction import OutputSet


def _names(folder):
    return sorted(p.name for p in folder.iterdir())


def test_commit_renames_all_together(tmp_path):
    targets = {"--json": tmp_path / "a.json", "--plot": tmp_path / "a.png"}
    with OutputSet(targets) as out:
        out.temp("--json").write_text("{}")
        out.temp("--plot").write_bytes(b"png")
        assert out.temp("--plot").suffix == ".png"  # writers pick the format from it
        assert not (tmp_path / "a.json").exists()
        out.commit()
    assert _names(tmp_path) == ["a.json", "a.png"]


@pytest.mark.parametrize("exc", [KeyboardInterrupt, RuntimeError])
def test_an_interruption_leaves_nothing(tmp_path, exc):
    (tmp_path / "a.json").write_text("old")
    targets = {"--json": tmp_path / "a.json", "--netcdf": tmp_path / "a.nc"}
    with pytest.raises(exc), OutputSet(targets, force=True) as out:
        out.temp("--json").write_text("new")
        out.temp("--netcdf")
        raise exc()
    assert _names(tmp_path) == ["a.json"] and (tmp_path / "a.json").read_text() == "old"


def test_refused_before_any_work(tmp_path):
    (tmp_path / "a.json").write_text("old")
    with pytest.raises(DataError, match="--json: exists"):
        OutputSet({"--json": tmp_path / "a.json"})
    with pytest.raises(DataError, match="does not exist"):
        OutputSet({"--json": tmp_path / "no" / "a.json"})


def test_a_target_that_appears_meanwhile_is_not_overwritten(tmp_path):
    with OutputSet({"--json": tmp_path / "a.json"}) as out:
        out.temp("--json").write_text("new")
        (tmp_path / "a.json").write_text("someone else's")
        with pytest.raises(DataError, match="exists"):
            out.commit()
    assert _names(tmp_path) == ["a.json"]
    assert (tmp_path / "a.json").read_text() == "someone else's"


def _signal_through_another_thread(sig=signal.SIGINT) -> None:
    """Send ``sig`` to a thread other than the main one, as the kernel may (any thread
    that does not block it gets a process-directed signal: BLAS, Arrow, numba pools)."""
    ready, go = threading.Event(), threading.Event()

    def pool_thread():
        # A thread started before the commit (as the pools are): the signal not blocked.
        signal.pthread_sigmask(signal.SIG_UNBLOCK, {sig})
        ready.set()
        go.wait()

    helper = threading.Thread(target=pool_thread, daemon=True)
    helper.start()
    ready.wait()
    signal.pthread_kill(helper.ident, sig)
    go.set()
    helper.join()


def _fire_at_rename(monkeypatch, n: int, sig=signal.SIGINT) -> None:
    """Make the ``n``-th os.replace (1-based) signal the process right after it renames."""
    real, calls = os.replace, []

    def replace(src, dst):
        real(src, dst)
        calls.append(dst)
        if len(calls) == n:
            _signal_through_another_thread(sig)

    monkeypatch.setattr(os, "replace", replace)


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM])
def test_a_signal_in_the_middle_of_the_commit_waits_for_every_rename(tmp_path, monkeypatch, sig):
    # The red-team's H1: the renames ran under pthread_sigmask, which holds only in the
    # thread that set it; the signal went to another thread, and Python ran the handler in
    # the main thread mid-loop: 1 of 4 outputs renamed, the other 3 deleted as temporaries.
    from loadbayes.commands.signals import (
        Terminated,
        install_signal_handlers,
        restore_signal_handlers,
    )

    targets = {f"--o{k}": tmp_path / f"o{k}.txt" for k in range(4)}
    install_signal_handlers()
    try:
        with pytest.raises(KeyboardInterrupt) as err, OutputSet(targets) as out:
            for label in targets:
                out.temp(label).write_text(label)
            _fire_at_rename(monkeypatch, 1, sig)
            out.commit()
    finally:
        restore_signal_handlers()
    assert isinstance(err.value, Terminated) == (sig == signal.SIGTERM)
    assert out.committed
    assert _names(tmp_path) == [f"o{k}.txt" for k in range(4)]  # all, and no temporary


def test_held_signals_holds_in_every_thread_and_delivers_once_after():
    # With Python's own SIGINT handler (no command running): KeyboardInterrupt, once,
    # right after the block, not inside it.
    from loadbayes.io.atomic import held_signals

    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    done = []
    try:
        with pytest.raises(KeyboardInterrupt):
            with held_signals():
                _signal_through_another_thread()
                _signal_through_another_thread()
                for k in range(1000):  # many bytecodes: the handler would have run by now
                    done.append(k)
        assert len(done) == 1000
        assert signal.getsignal(signal.SIGINT) is signal.default_int_handler
    finally:
        signal.signal(signal.SIGINT, previous)
