"""The README's usage lines run as written, in order, in an empty folder.

The lines are the fenced blocks that follow a ``<!-- readme-usage`` marker in README.md;
a line ending in a backslash continues on the next. Each runs in bash with ``loadbayes``
standing for ``sys.executable -m loadbayes`` (PYTHONPATH from the environment), and a
line that exits with a code other than 0 fails the test, named with its stderr.

The fast test runs every line but those of :data:`SLOW` (the composite fit and the
exports that read it, the motor fit, the ANDES simulation, the example archive's scan,
fit, pool and report), which ``make validate`` runs after the ``loadbayes example`` lines
that write their inputs (51 s on a fresh clone beside the other test worker, moved out of
``make test`` on 29 Nov 2026 for its 12 minutes: each of those commands has its own CLI
tests there, the README's spelling of them is what only this test checks); a static check sees
that no two lines write the same file (which would stop a run of the whole block in one
folder). Measured on the shared 2-core machine at a load average of 6 to 11: 200 s for
the whole block line by line, 100-120 s of it in the fast lines.
"""

from __future__ import annotations

import os
import re
import shlex
import subprocess
import sys
from pathlib import Path

import pytest

from cli_here import cli_here

README = Path(__file__).resolve().parents[2] / "README.md"
MARKER = "<!-- readme-usage"
#: Lines left to the statistical tier (slow), by their start.
SLOW = (
    "loadbayes fit composite",
    "loadbayes export comp.json",
    "loadbayes simulate im",
    "loadbayes simulate andes",
    "loadbayes playback",
    "loadbayes archive",  # scan, fit and pool of the example archive (9 fits)
    "loadbayes report archive.db",
)


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


def simple_command(line: str) -> tuple[list[str], str | None] | None:
    """``(args, stdout file)`` of ``loadbayes ARGS [> FILE] [# note]``; None for any other line.

    bash reads such a line as those words (quotes and comments as :func:`shlex.split`
    reads them) with stdout sent to FILE; a line with any other shell syntax (``&&``,
    pipes, ``$``, globs, other redirections) is not of this form and runs in bash.
    """
    words = shlex.split(line, comments=True)
    out = None
    if len(words) >= 2 and words[-2] == ">":
        words, out = words[:-2], words[-1]
    if not words or words[0] != "loadbayes" or re.search(r"[|&;<>$`*?(){}\[\]]", " ".join(words)):
        return None
    return words[1:], out


def run_lines(lines: list[str], folder: Path) -> None:
    """Run each line from ``folder``; a line that exits other than 0 fails, named.

    A line of the simple form (:func:`simple_command`) runs in this process through Click's
    runner (``tests/cli_here.py``: the words bash would pass, stdout to the named file),
    which saves each line a Python start and the package's imports (about 4 s of CPU); the
    README's lines are about what a command writes, not about processes. Any other line
    runs in bash with ``loadbayes`` standing for ``sys.executable -m loadbayes``.
    """
    prelude = f'loadbayes() {{ {shlex.quote(sys.executable)} -m loadbayes "$@"; }}\n'
    env = dict(os.environ)
    for line in lines:
        simple = simple_command(line)
        if simple is not None:
            args, out = simple
            proc = cli_here(*args, cwd=folder)
            if out is not None and proc.returncode == 0:
                (folder / out).write_text(proc.stdout, encoding="utf-8")
        else:
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
    for kind in ("zip", "day", "composite", "fleet", "comtrade", "pmu", "archive"):
        assert any(line.startswith(f"loadbayes example {kind}") for line in lines), kind
    assert all("\\" not in line for line in lines)


def test_parser_joins_continuations_and_skips_comments():
    text = f"x\n{MARKER} -->\n```sh\n# a note\na --b \\\n    --c d  # e\n\nf\n```\nafter\n"
    assert usage_lines(text) == ["a --b --c d  # e", "f"]


def test_simple_lines_are_the_words_bash_passes():
    assert simple_command("loadbayes example zip > bus.csv   # a note") == (
        ["example", "zip"],
        "bus.csv",
    )
    assert simple_command("loadbayes fit zip 'a b.csv' --json x.json") == (
        ["fit", "zip", "a b.csv", "--json", "x.json"],
        None,
    )
    for shell in (
        "loadbayes simulate im --out m.csv && loadbayes fit im m.csv",
        "ls > x",
        "loadbayes fit zip *.csv",
        "loadbayes example zip | head",
        "x=1 loadbayes",
    ):
        assert simple_command(shell) is None, shell


def test_a_failing_line_is_named(tmp_path):
    with pytest.raises(AssertionError, match="README line failed .*loadbayes fit zip nowhere.csv"):
        run_lines(["loadbayes fit zip nowhere.csv"], tmp_path)


def test_readme_usage_runs_fast_lines(tmp_path):
    lines = usage_lines(README.read_text(encoding="utf-8"))
    run_lines([line for line in lines if not line.startswith(SLOW)], tmp_path)
    assert (tmp_path / "report.html").stat().st_size > 0
    assert (tmp_path / "fleet.parquet").exists()
    assert "Buses flagged" in (tmp_path / "fleet.html").read_text(encoding="utf-8")
    assert (tmp_path / "events" / "event_002.csv").exists()


@pytest.mark.statistical
@pytest.mark.skipif(os.environ.get("LOADBAYES_VALIDATE") != "1", reason="make validate's")
def test_readme_usage_runs_slow_lines(tmp_path):
    # The slow lines, in order, after the example lines that write their inputs (the
    # fast test runs the rest; together they run every line).
    lines = usage_lines(README.read_text(encoding="utf-8"))
    run_lines([ln for ln in lines if ln.startswith(SLOW + ("loadbayes example",))], tmp_path)
    for name in ("comp.json", "load.json", "load.raw", "case.xlsx", "im.json", "ev.csv",
                 "playback.png", "archive.db", "pool.json", "archive.html"):  # fmt: skip
        assert (tmp_path / name).exists(), name


def test_no_two_lines_write_the_same_file():
    # Run in one folder, a second writer of a name would stop on "exists; use --force",
    # which the split into a fast and a slow test would not see.
    lines = usage_lines(README.read_text(encoding="utf-8"))
    targets = []
    for line in lines:
        targets += re.findall(r"(?:--out|--json|--netcdf|--plot|>)\s+(\S+)", line)
    assert len(targets) > 20
    assert len(targets) == len(set(t.rstrip("/") for t in targets)), targets


# ------------------------------------------------------------ loadbayes example itself
def _example(*args, cwd):
    # In this process (tests/cli_here.py): these tests are about what the command writes
    # and says, not about a process (7 Python starts fewer, about 3 s of make test).
    return cli_here("example", *args, cwd=cwd)


def test_folder_kinds_need_out_and_never_overwrite(tmp_path):
    proc = _example("pmu", cwd=tmp_path)
    assert proc.returncode == 2
    assert proc.stderr.strip().splitlines() == [
        "loadbayes: error: example pmu writes several files: give the folder with --out DIR"
    ]
    assert list(tmp_path.iterdir()) == []
    (tmp_path / "pmu").mkdir()
    (tmp_path / "pmu" / "map.toml").write_text("mine")
    proc = _example("pmu", "--out", "pmu", cwd=tmp_path)
    assert proc.returncode == 2 and "Traceback" not in proc.stderr
    assert proc.stderr.strip() == (
        "loadbayes: error: pmu/map.toml: exists; use --force to overwrite"
    )
    # Nothing written: neither the other file nor over the user's.
    assert sorted(p.name for p in (tmp_path / "pmu").iterdir()) == ["map.toml"]
    assert (tmp_path / "pmu" / "map.toml").read_text() == "mine"
    assert _example("pmu", "--out", "pmu", "--force", cwd=tmp_path).returncode == 0
    assert sorted(p.name for p in (tmp_path / "pmu").iterdir()) == ["historian.csv", "map.toml"]


def test_day_is_the_zip_load_its_truth_columns_say(tmp_path):
    # Checked here from the CSV alone: P = P0 (a1 x^2 + a2 x + a3) with the written
    # shares, x = V / 11 kV, P0 = 4 MW; the residual is the stated 0.3 % noise.
    proc = _example("day", cwd=tmp_path)
    assert proc.returncode == 0
    import io

    import numpy as np
    import pandas as pd

    day = pd.read_csv(io.StringIO(proc.stdout))
    assert len(day) == 1440 and day["time"].is_unique
    x = day["v"].to_numpy() / 11.0
    assert 0.9 < x.min() and x.max() < 1.1 and x.std() > 0.025
    for ch, nom, (c1, c2, c3) in (("p", 4.0, ("a1", "a2", "a3")), ("q", 1.6, ("a4", "a5", "a6"))):
        a = {c: day[f"{c}_true"].to_numpy() for c in (c1, c2, c3)}
        assert np.allclose(a[c1] + a[c2] + a[c3], 1.0, atol=1e-3)
        model = nom * (a[c1] * x**2 + a[c2] * x + a[c3])
        resid = (day[ch].to_numpy() - model) / nom
        assert abs(resid.mean()) < 5e-4 and 0.002 < resid.std() < 0.004


def test_zip_example_is_the_realistic_day_its_readme_states(tmp_path):
    # The shipped file is what its generator writes (regenerated, not edited by hand), and
    # it has the shape data/README.md states: 1-minute rows with an hour missing, 3-7 MW
    # on a daily profile, six 0.625 % taps and a 3 % CVR window of 45 minutes.
    proc = _example("zip", cwd=tmp_path)
    assert proc.returncode == 0
    import io

    import numpy as np
    import pandas as pd

    from loadbayes.cases.examples import zip_day_frame

    assert proc.stdout == zip_day_frame().to_csv(index=False, lineterminator="\n")
    day = pd.read_csv(io.StringIO(proc.stdout), parse_dates=["time"])
    assert list(day.columns) == ["time", "v", "p", "q"] and len(day) == 1380
    gaps = day["time"].diff().dt.total_seconds().to_numpy()[1:]
    assert sorted(set(gaps)) == [60.0, 3660.0]
    assert day["time"][np.argmax(gaps)].strftime("%H:%M") == "09:59"
    assert 3.0 < day["p"].min() < 3.6 and 6.5 < day["p"].max() < 7.2
    jumps = np.diff(day["v"].to_numpy() / 11.0)
    big = jumps[np.abs(jumps) > 0.004]
    assert np.sum(np.abs(np.abs(big) - 0.00625) < 0.0015) == 6
    cvr = np.abs(np.abs(big) - 0.03) < 0.002
    assert cvr.sum() == 2 and big[cvr][0] < 0 < big[cvr][1]
    at = day["time"][1:][np.abs(jumps) > 0.025].dt.strftime("%H:%M").tolist()
    assert at == ["17:00", "17:45"]


def test_pmu_example_is_the_stated_load(tmp_path):
    # The historian's phasors give back 5 MW and 2 Mvar at 11 kV before the sag.
    assert _example("pmu", "--out", "pmu", cwd=tmp_path).returncode == 0
    import numpy as np
    import pandas as pd

    h = pd.read_csv(tmp_path / "pmu" / "historian.csv").iloc[:300]
    v = h["V1 Mag"].to_numpy() * 1e3 * np.exp(1j * np.radians(h["V1 Ang"].to_numpy()))
    i = h["I1 Mag"].to_numpy() * np.exp(1j * np.radians(h["I1 Ang"].to_numpy()))
    s = 3 * v * np.conj(i) / 1e6
    assert abs(np.median(np.abs(v)) * np.sqrt(3) / 1e3 - 11.0) < 0.05
    assert abs(np.median(s.real) - 5.0) < 0.05 and abs(np.median(s.imag) - 2.0) < 0.05


# The README's Python block: tests/integration/test_readme_python.py runs it as written
# after the README's first line, in an empty folder, and checks what it prints (a second
# run here, in a subprocess asserting only that "a1" was printed, left on 30 Nov 2026:
# 37 s of make test under load for a check that file already makes).
