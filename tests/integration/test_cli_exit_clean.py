"""Issue 25: the command line ends cleanly, and a signal leaves no temporary of any depth.

- H7 (red-team): early-error paths aborted now and then at interpreter exit ("terminate
  called without an active exception", exit 134): Arrow's read-ahead thread dropped the
  last reference to a Python file object during ``Py_FinalizeEx``. Each path below runs
  many times, two processes at once (the abort needed a loaded machine).
- A SIGTERM during the NetCDF write once left ``.o.nc.XXXX.tmp.nc.YYYY.tmp.nc``: the
  NetCDF writer made a temporary of the transaction's temporary.
- L2: warnings from loadbayes' own code printed ``... (from )``.

Inputs are written by the tests themselves (no generator of the package).
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import tempfile
import time
import warnings
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

pytestmark = pytest.mark.integration

EXE = [sys.executable, "-m", "loadbayes"]
#: `make validate` sets LOADBAYES_VALIDATE=1: the statistical tier's full counts (CI runs
#: fewer to keep `make test` within its budget; the detection rates are stated per test).
FULL = os.environ.get("LOADBAYES_VALIDATE") == "1"
MANY_RUNS = 60
#: make test's 3 (seed 25's first: SIGINT and SIGTERM inside the NetCDF write, SIGINT at
#: 4.9 s) with the parametrized test's 3 (SIGINT inside the write twice, SIGTERM at 1.7 s)
#: are each kind of moment and signal once at least; validate's 40 are the repeats.
SIGNAL_RUNS = 40 if FULL else 3
#: Runs of each early-error path in make test: one pair, two processes at once.
EARLY_RUNS = 2
#: The early errors' repeated runs are `make validate`'s only: `make test` keeps the 4 runs
#: of each path below (their detection rates are stated there). That is 40 interpreter
#: starts fewer, about a minute of the suite on 2 idle cores (4 min on a loaded machine),
#: to keep `make test` within its 12 minutes as the suite grew.
_VALIDATE_ONLY = pytest.mark.skipif(not FULL, reason="the repeated runs are make validate's")
SRC = str(Path(__file__).resolve().parents[2] / "src")


def _env() -> dict[str, str]:
    env = dict(os.environ)
    env["PYTHONPATH"] = SRC + os.pathsep + env.get("PYTHONPATH", "")
    return env


def feeder(
    path: Path, *, kv: float = 11.0, mw: float = 5.0, mvar: float = 2.0, n: int = 600, seed=0
):
    """A day of feeder data in kV, MW and Mvar (shares 0.4/0.3/0.3), written as CSV."""
    rng = np.random.default_rng(seed)
    x = 1 + 0.03 * np.sin(np.linspace(0, 6, n)) + rng.normal(0, 0.002, n)
    shape = 0.4 * x**2 + 0.3 * x + 0.3
    pd.DataFrame(
        {
            "v": kv * x,
            "p": mw * shape * (1 + rng.normal(0, 0.002, n)),
            "q": mvar * shape * (1 + rng.normal(0, 0.002, n)),
        }  # fmt: skip
    ).to_csv(path, index=False)


def short_event(path: Path) -> None:
    """A composite event of 6 samples (an event needs at least 20)."""
    t = np.arange(6) / 60
    v = np.where(t < 0.05, 1.0, 0.7)
    pd.DataFrame({"t_s": t, "v": v, "p": 0.9 * v, "q": 0.4 * v}).to_csv(path, index=False)


#: The early-error paths of the red-team's abort table: (name, arguments, words of the
#: one-line message). Each must exit 2 with exactly that line on stderr.
PATHS = [
    ("units", ["fit", "zip", "kv.csv", "--json", "o.json", "--quiet"], ["column 'v'", "--v-base"]),
    ("header-only", ["fit", "zip", "header.csv", "--json", "o.json", "--quiet"], ["no data rows"]),
    (
        "wrong-p0",
        ["fit", "zip", "kv.csv", "--v-base", "11", "--s-base", "5", "--p0", "-1", "--quiet"],
        ["column 'p'", "--p0"],
    ),
    (
        "short-event",
        ["fit", "composite", "short.csv", "--json", "c.json", "--quiet"],
        ["only 6 samples"],
    ),  # fmt: skip
]


@pytest.fixture(scope="module")
def inputs():
    with tempfile.TemporaryDirectory(prefix="lb-exit-") as d:
        folder = Path(d)
        feeder(folder / "kv.csv")
        (folder / "header.csv").write_text("v,p,q\n")
        short_event(folder / "short.csv")
        yield folder


def _run_many(folder: Path, args: list[str], runs: int) -> list[subprocess.CompletedProcess]:
    """``runs`` runs of one command, two at a time (as on a busy machine)."""

    def one(_):
        return subprocess.run([*EXE, *args], cwd=folder, env=_env(), capture_output=True,
                              text=True, timeout=300)  # fmt: skip

    with ThreadPoolExecutor(2) as pool:
        return list(pool.map(one, range(runs)))


def _check_runs(results, needles) -> None:
    aborts = [r for r in results if r.returncode != 2]
    assert not aborts, (
        f"{len(aborts)} of {len(results)} runs did not exit 2: "
        f"{[(r.returncode, r.stderr[-200:]) for r in aborts[:3]]}"
    )
    for r in results:
        lines = r.stderr.strip().splitlines()
        assert len(lines) == 1 and lines[0].startswith("loadbayes: error: "), r.stderr
        for n in needles:
            assert n in lines[0], (n, lines[0])


@pytest.mark.parametrize(("name", "args", "needles"), PATHS, ids=[p[0] for p in PATHS])
def test_early_errors_exit_2_every_time(inputs, name, args, needles):
    """2 runs of each path, two at once (8 in all, about 10 s; 4 each until 30 Nov 2026).

    What it can detect: before the fix the wrong --p0 path aborted in 17 of 30 runs on
    this (loaded) machine, so 2 runs miss it with probability (13/30)^2 = 19% (4 runs:
    3.5%); a rate of 5% (the red-team's, over all paths) is seen by the 8 runs with
    probability 34% (16 runs: 56%). `make validate` runs each path 60 times more (below),
    where a 5% rate is seen with certainty. A run that does not exit 2 with its one line
    is always a defect: there is no false alarm to budget.
    """
    _check_runs(_run_many(inputs, args, EARLY_RUNS), needles)


@pytest.mark.statistical
@_VALIDATE_ONLY
@pytest.mark.parametrize(("name", "args", "needles"), PATHS, ids=[p[0] for p in PATHS])
def test_early_errors_exit_2_every_time_many_runs(inputs, name, args, needles):
    """60 runs of each path, two at once (240 in all), in `make validate` only.

    A 1% abort rate (over all paths) is seen with probability 91%, a 5% rate with
    certainty; the measured pre-fix rates (1-57% per path) with certainty. False-alarm
    rate: 0 (an abort is a defect). CI ran 20 per path, then 10, and now none: its 8
    runs are the test above (a 5% rate seen with probability 34%).
    """
    _check_runs(_run_many(inputs, args, MANY_RUNS), needles)


# ------------------------------------------------------------- the entry point itself
def test_the_entry_point_keeps_exit_codes_and_output(tmp_path):
    """Success and --help go through LoadbayesGroup.main unchanged (a data error: above)."""
    feeder(tmp_path / "kv.csv", n=200)
    ok = subprocess.run([*EXE, "fit", "zip", "kv.csv", "--v-base", "11", "--s-base", "5",
                         "--draws", "600", "--burn", "100", "--chains", "2", "--quiet",
                         "--json", "-"], cwd=tmp_path, env=_env(), capture_output=True,
                        text=True, timeout=300)  # fmt: skip
    assert ok.returncode == 0, ok.stderr
    assert '"model": "zip"' in ok.stdout
    # A data error's exit 2 and one line through it: the early-error runs above.
    usage = subprocess.run([*EXE, "--help"], env=_env(), capture_output=True, text=True,
                           timeout=120)  # fmt: skip
    assert usage.returncode == 0 and "fit" in usage.stdout


def test_a_reader_abandoned_mid_file_is_closed(tmp_path, monkeypatch):
    """The CSV reader's Arrow stream is closed when its consumer stops early."""
    import gc

    import pyarrow as pa

    from loadbayes.io.tables import iter_chunks

    path = tmp_path / "big.csv"
    rng = np.random.default_rng(1)
    pd.DataFrame({"v": rng.uniform(0.9, 1.1, 200_000), "p": 1.0}).to_csv(path, index=False)
    opened: list = []
    real = pa.OSFile

    def spy(*a, **k):
        f = real(*a, **k)
        opened.append(f)
        return f

    monkeypatch.setattr(pa, "OSFile", spy)
    chunks = iter_chunks(path, ["v", "p"], chunk_rows=1000)
    next(chunks)
    assert opened and not opened[0].closed  # Arrow reads the file natively
    chunks.close()  # what an error in the consumer does to it
    gc.collect()
    assert opened[0].closed


# ------------------------------------------------- no temporary of a temporary (item 2)
def test_netcdf_in_a_transaction_makes_no_temporary_of_its_own(tmp_path, monkeypatch):
    """fit zip --netcdf: the NetCDF goes straight into the transaction's temporary."""
    from click.testing import CliRunner

    from loadbayes.cli import main

    feeder(tmp_path / "bus.csv", kv=1.0, mw=1.0, mvar=1.0, n=200)
    made: list[str] = []
    real = tempfile.mkstemp

    def spy(*a, **k):
        fd, name = real(*a, **k)
        made.append(Path(name).name)
        return fd, name

    monkeypatch.setattr(tempfile, "mkstemp", spy)
    monkeypatch.chdir(tmp_path)
    r = CliRunner().invoke(main, ["fit", "zip", "bus.csv", "--p0", "1", "--q0", "1",
                                  "--draws", "600", "--burn", "100", "--chains", "2",
                                  "--quiet", "--json", "o.json", "--netcdf", "o.nc"])  # fmt: skip
    assert r.exit_code == 0, r.output
    assert sorted(n.split(".")[1] for n in made) == ["o", "o"]  # one each: o.json, o.nc
    nested = [n for n in made if n.count(".tmp") > 1]
    assert not nested, nested
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bus.csv", "o.json", "o.nc"]


def _leftovers(folder: Path) -> list[str]:
    return sorted(p.name for p in folder.iterdir() if p.name != "bus.csv")


def _signal_run(folder: Path, sig: int, marker: str | None, delay: float) -> tuple:
    cmd = [*EXE, "fit", "zip", "bus.csv", "--p0", "1", "--q0", "1", "--draws", "3000",
           "--burn", "100", "--chains", "2", "--quiet", "--json", "o.json",
           "--netcdf", "o.nc", "--plot", "o.png"]  # fmt: skip
    proc = subprocess.Popen(cmd, cwd=folder, env=_env(), stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)  # fmt: skip
    deadline = time.monotonic() + 120
    seen = marker is None
    while not seen and proc.poll() is None and time.monotonic() < deadline:
        seen = any(p.name.startswith(marker) for p in folder.iterdir())
        time.sleep(0.002)
    time.sleep(delay)
    if proc.poll() is None:
        proc.send_signal(sig)
    _, err = proc.communicate(timeout=120)
    return proc.returncode, err, seen


def _check_all_or_none(folder: Path, code: int, err: str, sig: int) -> None:
    left = _leftovers(folder)
    assert not [n for n in left if n.startswith(".")], left  # no temporary, of any depth
    assert left in ([], ["o.json", "o.nc", "o.png"]), left
    if code == 0:
        assert left == ["o.json", "o.nc", "o.png"]
        return
    assert code == {signal.SIGINT: 130, signal.SIGTERM: 143}[sig], err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("loadbayes: "), err
    assert ("no output was written" in lines[0]) == (left == []), err


def _random_moments(seed: int, n: int):
    """(signal, marker, delay): inside the NetCDF write, or at a random time of the run."""
    rng = np.random.default_rng(seed)
    for _ in range(n):
        sig = [signal.SIGTERM, signal.SIGINT][rng.integers(2)]
        if rng.random() < 0.7:
            yield sig, ".o.nc.", float(rng.uniform(0.0, 0.4))  # inside the NetCDF write
        else:
            yield sig, None, float(rng.uniform(1.0, 6.0))  # start-up, sampling, figure


@pytest.mark.parametrize("k", range(3))
def test_a_signal_at_a_random_moment_leaves_no_temporary(tmp_path, k):
    """3 runs (seeds 0-2), each a signal at a random moment; 40 in the statistical tier."""
    feeder(tmp_path / "bus.csv", kv=1.0, mw=1.0, mvar=1.0, n=300)
    ((sig, marker, delay),) = _random_moments(k, 1)
    code, err, _ = _signal_run(tmp_path, sig, marker, delay)
    _check_all_or_none(tmp_path, code, err, sig)


@pytest.mark.statistical
def test_signals_at_random_moments_leave_no_temporary_many_runs(tmp_path):
    """3 runs in CI, 40 in `make validate`, seed 25: signals inside the NetCDF write (70%)
    or anywhere in the run.

    The pre-fix leak was seen once in three runs of a marker-triggered SIGTERM; the 2 runs
    inside the write (CI: one SIGINT, one SIGTERM; 9 of 12 until 29 Nov 2026, 5 of 8 until
    30 Nov, cut to keep `make test` within 12 minutes as the suite grew), with the
    parametrized test's 2 of 3 and test_cli_issue14's 2 (SIGTERM and SIGINT at the
    NetCDF write's first temporary), miss a 1-in-3 leak with probability (2/3)^6 = 8.8%
    (it was (2/3)^9 = 2.6%), 28 (validate) with < 1e-4. False alarms: none (a temporary
    left is always a defect).
    """
    feeder(tmp_path / "bus.csv", kv=1.0, mw=1.0, mvar=1.0, n=300)
    for sig, marker, delay in _random_moments(25, SIGNAL_RUNS):
        code, err, _ = _signal_run(tmp_path, sig, marker, delay)
        _check_all_or_none(tmp_path, code, err, sig)
        for p in tmp_path.iterdir():
            if p.name != "bus.csv":
                p.unlink()


# ------------------------------------------------------------------------ L2: (from )
def test_warnings_name_their_package_or_nothing():
    import click
    from click.testing import CliRunner

    from loadbayes.commands.output import user_errors

    @click.command()
    @user_errors
    def cmd():
        warnings.warn_explicit("own warning", UserWarning, "/x/src/loadbayes/fit/zip.py", 3)
        warnings.warn("a test's warning", UserWarning, stacklevel=1)
        warnings.warn_explicit(
            "overflow encountered", RuntimeWarning,
            "/v/lib/python3.11/site-packages/numpy/core/_methods.py", 9,
        )  # fmt: skip
        warnings.warn_explicit(
            "installed", UserWarning, "/v/lib/python3.11/site-packages/loadbayes/io/x.py", 1
        )

    with warnings.catch_warnings():
        warnings.simplefilter("always")  # pytest turns warnings into errors
        r = CliRunner().invoke(cmd, [])
    lines = r.stderr.strip().splitlines()
    assert lines == [
        "loadbayes: warning: own warning",
        "loadbayes: warning: a test's warning",
        "loadbayes: warning: overflow encountered (from numpy)",
        "loadbayes: warning: installed",
    ], lines


# ------------------------------------------------ a signal once the command has ended
def test_a_signal_after_the_command_is_one_line_not_a_killed_process(tmp_path):
    """SIGTERM right after the command finished (outputs written): exit 143, one line.

    Before, such a signal killed the process in its teardown (exit -15 or -2, no word).
    The signal is sent from inside the process the moment the command returns.
    """
    code = (
        "import os, signal, sys\n"
        "from loadbayes import cli\n"
        "inner = cli.LoadbayesGroup.invoke\n"
        "def invoke(self, ctx):\n"
        "    try:\n"
        "        return inner(self, ctx)\n"
        "    finally:\n"
        "        os.kill(os.getpid(), signal.SIGTERM)\n"
        "cli.LoadbayesGroup.invoke = invoke\n"
        "sys.argv = ['loadbayes', 'example', 'zip']\n"
        "cli.main(prog_name='loadbayes')\n"
    )
    r = subprocess.run([sys.executable, "-c", code], cwd=tmp_path, env=_env(),
                       capture_output=True, text=True, timeout=120)  # fmt: skip
    assert r.returncode == 143, (r.returncode, r.stderr)
    assert r.stderr.strip().splitlines() == [
        "loadbayes: terminated (SIGTERM) after every output was written"
    ], r.stderr
    assert r.stdout.startswith("time,v,p,q")  # the output was complete


def test_a_signal_before_any_command_acts_as_before():
    from loadbayes import cli

    cli._LATE.update(signal=None, finished=False)
    with pytest.raises(KeyboardInterrupt):
        cli._on_late_signal(signal.SIGINT, None)
    cli._LATE.update(finished=True)
    cli._on_late_signal(signal.SIGINT, None)  # recorded, not raised
    assert cli._LATE["signal"] == signal.SIGINT
    cli._LATE.update(signal=None, finished=False)
