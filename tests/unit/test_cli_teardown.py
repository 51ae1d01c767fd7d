"""A command that asks for it ends without the interpreter's teardown (``cli.py``).

``fit composite`` asks (its outputs are all written and closed when it returns): the
teardown of the modules a fit loaded cost 0.3-0.4 CPU s. The exit must still flush what
the command printed and run the atexit handlers, and a failed run keeps the normal exit.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

SRC = Path(__file__).resolve().parents[2] / "src"

SCRIPT = """
import atexit, sys, click
from loadbayes import cli
from loadbayes.commands.output import end_without_teardown

class Noisy:
    def __del__(self):
        sys.stderr.write("teardown\\n")

KEEP = Noisy()  # a module global: freed only by the interpreter's teardown

@click.command("done")
@click.option("--fail", is_flag=True)
def done(fail):
    end_without_teardown()
    click.echo("x" * 100_000)  # buffered on a pipe: it must reach it whole
    if fail:
        raise SystemExit(3)

atexit.register(lambda: sys.stdout.write("atexit\\n"))
cli.main.add_command(done)
sys.argv = ["loadbayes", "done", *sys.argv[1:]]
cli.main(prog_name="loadbayes")
"""


def _run(*args: str) -> subprocess.CompletedProcess:
    env = {**os.environ, "PYTHONPATH": str(SRC)}
    return subprocess.run([sys.executable, "-c", SCRIPT, *args], capture_output=True,
                          text=True, env=env, timeout=120)  # fmt: skip


def test_a_command_that_asks_ends_without_the_teardown_and_loses_nothing():
    res = _run()
    assert res.returncode == 0, res.stderr
    assert res.stdout == "x" * 100_000 + "\natexit\n"
    assert "teardown" not in res.stderr


def test_a_failed_run_keeps_the_normal_exit():
    res = _run("--fail")
    assert res.returncode == 3
    assert res.stdout == "x" * 100_000 + "\natexit\n"
    assert "teardown" in res.stderr
