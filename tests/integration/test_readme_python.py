"""The README's Python block runs as written (issue 40), in an empty folder.

The block is the first fenced ``python`` block of README.md; its input is the README's
own first line, ``loadbayes example zip > bus.csv``. It runs as the README gives it (its
settings are the fits' defaults with a seed), with matplotlib drawing off screen.
"""

from __future__ import annotations

import os
import re
import subprocess
import sys
import warnings
from pathlib import Path

import matplotlib

README = Path(__file__).resolve().parents[2] / "README.md"


def python_block(text: str) -> str:
    """The first fenced python block of the README."""
    found = re.search(r"```python\n(.*?)```", text, flags=re.S)
    assert found, "README.md has no python block"
    return found.group(1)


def test_the_readme_python_block_runs_as_written(tmp_path, monkeypatch, capsys):
    matplotlib.use("Agg")
    env = dict(os.environ)
    with open(tmp_path / "bus.csv", "wb") as out:
        subprocess.run([sys.executable, "-m", "loadbayes", "example", "zip"], stdout=out,
                       check=True, env=env, cwd=tmp_path)  # fmt: skip
    monkeypatch.chdir(tmp_path)
    code = python_block(README.read_text(encoding="utf-8"))
    scope: dict = {}
    with warnings.catch_warnings():
        warnings.simplefilter("default")  # the fits' FitWarnings are part of the output
        exec(compile(code, "README.md", "exec"), scope)
    printed = capsys.readouterr().out
    assert "dP/dV" in printed
    assert "level" in printed  # pointwise_missing() said why the drift fit has no loo
    assert "elpd" in printed.lower()  # the one-level fit's loo ran
    assert {"posterior"} <= set(scope["idata"].groups())
    matplotlib.pyplot.close("all")
