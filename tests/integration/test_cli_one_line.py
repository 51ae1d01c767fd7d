"""Every command's usage errors are one line, ``loadbayes: error: ...``, exit 2.

click prints a bad option as three lines (usage, hint, error); loadbayes' commands are
:class:`~loadbayes.commands.options.OneLineCommand`, which say it in one line like every
other error. The first test walks the whole click tree so that a new command cannot
forget it; the second runs a bad integer option through a few of them.
"""

from __future__ import annotations

import click
import pytest
from click.testing import CliRunner

from loadbayes.cli import main
from loadbayes.commands.options import OneLineCommand

pytestmark = pytest.mark.integration


def _commands(group: click.Group, path: str) -> list[tuple[str, click.Command]]:
    out = []
    for name, cmd in sorted(group.commands.items()):
        where = f"{path} {name}"
        if isinstance(cmd, click.Group):
            out += _commands(cmd, where)
        else:
            out.append((where, cmd))
    return out


COMMANDS = _commands(main, "loadbayes")


def test_the_tree_has_every_command():
    names = {n for n, _ in COMMANDS}
    assert len(COMMANDS) >= 14
    assert {"loadbayes fit zip", "loadbayes read pmu", "loadbayes simulate andes"} <= names
    # That each is a OneLineCommand is a layout rule: tests/unit/test_layout.py.
    assert all(isinstance(cmd, OneLineCommand) for _, cmd in COMMANDS)


@pytest.mark.parametrize(
    ("args", "option"),
    [
        (["fit", "zip", "bus.csv", "--draws", "many"], "--draws"),
        (["fit", "composite", "ev.csv", "--json", "c.json", "--draws", "abc"], "--draws"),
        (["fit", "exp", "bus.csv", "--seed", "x"], "--seed"),
        (["track", "zip", "bus.csv", "--out", "o.csv", "--seed", "1.5"], "--seed"),
        (["simulate", "im", "--out", "o.csv", "--seed", "x"], "--seed"),
        (["simulate", "andes", "--out", "o.csv", "--seed", "x"], "--seed"),
        (["reproduce", "zip", "--out", "r", "--seed", "x"], "--seed"),
        (["reproduce", "im", "--out", "r", "--seed", "x"], "--seed"),
        (["reproduce", "all", "--out", "r", "--seed", "x"], "--seed"),
        (["export", "post.json", "--to", "andes", "--seed", "x"], "--seed"),
    ],
)
def test_a_bad_int_option_is_one_line_exit_2(tmp_path, monkeypatch, args, option):
    monkeypatch.chdir(tmp_path)
    res = CliRunner().invoke(main, args, prog_name="loadbayes")
    assert res.exit_code == 2, res.output
    lines = res.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("loadbayes: error: "), res.stderr
    assert option in lines[0] and "Traceback" not in res.stderr
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize(
    "args",
    [
        ["fit", "zip", "bus.csv", "--json", ""],
        ["fit", "zip", "bus.csv", "--netcdf", " "],
        ["steps", "bus.csv", "--out", ""],
    ],
)
def test_an_empty_output_name_is_refused(tmp_path, monkeypatch, args):
    # Red-team L5: an empty output name was taken for "no output": exit 0, nothing written.
    monkeypatch.chdir(tmp_path)
    (tmp_path / "bus.csv").write_text("v,p,q\n1.0,1.0,0.5\n1.01,1.01,0.51\n")
    res = CliRunner().invoke(main, args)
    assert res.exit_code == 2, res.output
    opt = args[args.index("bus.csv") + 1]
    assert res.output.strip() == (
        f"loadbayes: error: {opt} {args[-1]!r}: an empty file name (give one, or leave {opt} out)"
    )
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bus.csv"]
