"""One ``loadbayes`` command run in the test's process from a folder, as a process gives it.

Tests whose subject is a command's files, exit code and one-line errors (not processes:
signals and exits are ``test_cli_exit_clean``'s) run it here through Click's runner,
which saves each command a Python start and the package's imports (about 4 s of CPU).
"""

from __future__ import annotations

import os
from types import SimpleNamespace

from click.testing import CliRunner

from loadbayes.cli import main


def cli_here(*args, cwd, input=None) -> SimpleNamespace:
    """``returncode``, ``stdout``, ``stderr`` of ``loadbayes ARGS`` run from ``cwd``.

    ``input``, if given, is the command's standard input (text or bytes).

    An exception other than the command's own exit is raised, as a traceback would be.
    """
    here = os.getcwd()
    os.chdir(cwd)
    try:
        res = CliRunner().invoke(main, [str(a) for a in args], input=input)
    finally:
        os.chdir(here)
    if res.exception is not None and not isinstance(res.exception, SystemExit):
        raise res.exception
    return SimpleNamespace(returncode=res.exit_code, stdout=res.stdout, stderr=res.stderr)
