"""The README's usage lines run as written, in order, in an empty folder.

The lines are the fenced blocks that follow a ``<!-- readme-usage`` marker in README.md;
a line ending in a backslash continues on the next. Each runs in bash with ``loadbayes``
standing for ``sys.executable -m loadbayes`` (PYTHONPATH from the environment), and a
line that exits with a code other than 0 fails the test, named with its stderr.

The fast test skips the lines of :data:`SLOW` (the composite fit and the exports that
read it, the ANDES simulation: about a minute together on a busy 2-core machine); the
statistical tier runs the whole block.
"""

from __future__ import annotations

import os
import re
import shlex
import subprocess
import sys
from pathlib import Path

import pytest

README = Path(__file__).resolve().parents[2] / "README.md"
MARKER = "<!-- readme-usage"
#: Lines left to the statistical tier (slow), by their start.
SLOW = ("loadbayes fit composite", "loadbayes export comp.json", "loadbayes simulate andes")


def usage_lines(text: str) -> list[str]:
    """The command lines of every fenced block after a marker, continuations joined."""
    lines: list[str] = []
    for part in text.split(MARKER)[1:]:
        block = re.search(r"^```[^\n]*\n(.*?)^```", part, flags=re.S | re.M)
        assert block is not None, "a readme-usage marker without a fenced block after it"
        joined = re.sub(r"\\\n\s*", "", block.group(1))
        for line in joined.splitlines():
            line = line.strip()
            if line and not line.startswith("#"):
                lines.append(line)
    return lines


def run_lines(lines: list[str], folder: Path) -> None:
    prelude = f'loadbayes() {{ {shlex.quote(sys.executable)} -m loadbayes "$@"; }}\n'
    env = dict(os.environ)
    for line in lines:
        proc = subprocess.run(
            ["bash", "-c", prelude + line], cwd=folder, env=env, capture_output=True,
            text=True, timeout=600,
        )  # fmt: skip
        tail = "\n".join(proc.stderr.strip().splitlines()[-5:])
        assert proc.returncode == 0, f"README line failed ({proc.returncode}): {line}\n{tail}"


def test_usage_block_is_found():
    lines = usage_lines(README.read_text(encoding="utf-8"))
    assert lines[0].startswith("loadbayes example zip > bus.csv")
    # Every kind of example the README's lines read is written by an earlier line.
    for kind in ("zip", "day", "composite", "fleet", "comtrade", "pmu"):
        assert any(line.startswith(f"loadbayes example {kind}") for line in lines), kind
    assert all("\\" not in line for line in lines)


def test_parser_joins_continuations_and_skips_comments():
    text = f"x\n{MARKER} -->\n```sh\n# a note\na --b \\\n    --c d  # e\n\nf\n```\nafter\n"
    assert usage_lines(text) == ["a --b --c d  # e", "f"]


def test_a_failing_line_is_named(tmp_path):
    with pytest.raises(AssertionError, match="README line failed .*loadbayes fit zip nowhere.csv"):
        run_lines(["loadbayes fit zip nowhere.csv"], tmp_path)


def test_readme_usage_runs_fast_lines(tmp_path):
    lines = usage_lines(README.read_text(encoding="utf-8"))
    run_lines([line for line in lines if not line.startswith(SLOW)], tmp_path)
    assert (tmp_path / "report.html").stat().st_size > 0
    assert (tmp_path / "fleet.parquet").exists()
    assert (tmp_path / "events" / "event_002.csv").exists()


@pytest.mark.statistical
def test_readme_usage_runs_every_line(tmp_path):
    run_lines(usage_lines(README.read_text(encoding="utf-8")), tmp_path)
    for name in ("comp.json", "load.json", "load.raw", "case.xlsx", "ev.csv"):
        assert (tmp_path / name).exists(), name
