"""Failed writes (issue 40, red-team H2, H3): one line, exit 2, nothing half-written.

A file-size limit (``RLIMIT_FSIZE``, SIGXFSZ ignored as a shell's ``ulimit -f`` leaves
it to the program) stands in for a full disk: ``write(2)`` fails with EFBIG past it, as
with ENOSPC on a full one; ``/dev/full`` gives ENOSPC itself.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

pytestmark = pytest.mark.integration

SRC = str(Path(__file__).resolve().parents[2] / "src")
LIMITED = (
    "import os, resource, signal, sys; signal.signal(signal.SIGXFSZ, signal.SIG_IGN); "
    "n = int(sys.argv[1]); resource.setrlimit(resource.RLIMIT_FSIZE, (n, n)); "
    "os.execv(sys.executable, [sys.executable, '-m', 'loadbayes', *sys.argv[2:]])"
)


#: Commands that print their result: a file's contents, and the JSON of a fit.
PRINTERS = [["example", "zip"], ["fit", "zip", "bus.csv", "--draws", "300", "--burn", "100",
                                 "--quiet", "--json", "-"]]  # fmt: skip
FULL = "loadbayes: error: standard output: No space left on device; what was printed is incomplete"


def run(args, *, cwd, limit=None, stdout=subprocess.PIPE):
    env = dict(os.environ, PYTHONPATH=SRC + os.pathsep + os.environ.get("PYTHONPATH", ""))
    head = [sys.executable, "-c", LIMITED, str(limit)] if limit else [sys.executable, "-m",
                                                                       "loadbayes"]  # fmt: skip
    return subprocess.run([*head, *map(str, args)], cwd=cwd, env=env, stdout=stdout,
                          stderr=subprocess.PIPE, text=True, timeout=300)  # fmt: skip


@pytest.fixture(scope="module")
def bus(tmp_path_factory):
    d = tmp_path_factory.mktemp("bus")
    rng = np.random.default_rng(4)
    v = rng.uniform(0.95, 1.05, 400)
    pd.DataFrame({"v": v, "p": 0.3 * v**2 + 0.2 * v + 0.5 + rng.normal(0, 0.01, 400),
                  "q": 0.4 * v**2 + 0.1 * v + 0.5 + rng.normal(0, 0.01, 400)}).to_csv(
        d / "bus.csv", index=False)  # fmt: skip
    return d


def _one_line(stderr: str) -> str:
    lines = [s for s in stderr.strip().splitlines() if "warning" not in s]
    assert len(lines) == 1, stderr[-3000:]
    return lines[0]


def test_a_netcdf_past_the_file_size_limit_is_one_line_and_leaves_nothing(bus, tmp_path):
    # H2: ~100 lines of h5py tracebacks, then a segmentation fault (exit 139).
    r = run(["fit", "zip", bus / "bus.csv", "--draws", "3000", "--burn", "100", "--quiet",
             "--json", "x.json", "--netcdf", "x.nc"], cwd=tmp_path, limit=64 * 1024)  # fmt: skip
    assert r.returncode == 2, r.stderr[-3000:]
    assert _one_line(r.stderr) == (
        "loadbayes: error: x.nc: --netcdf cannot be written: File too large"
    )
    assert sorted(os.listdir(tmp_path)) == []  # neither output, no temporary


def test_a_fleet_netcdf_dir_past_the_file_size_limit_is_one_line(bus, tmp_path):
    df = pd.read_csv(bus / "bus.csv")
    pd.concat([df.assign(bus_id=f"b{k}") for k in range(2)]).to_parquet(tmp_path / "f.parquet")
    r = run(["fit", "zip", "f.parquet", "--by", "bus_id", "--out", "o.parquet", "--netcdf-dir",
             "nc", "--draws", "3000", "--burn", "100", "--chains", "2", "--quiet"],
            cwd=tmp_path, limit=64 * 1024)  # fmt: skip
    assert r.returncode == 2, r.stderr[-3000:]
    assert _one_line(r.stderr) == "loadbayes: error: nc/b0.nc: cannot be written: File too large"
    assert sorted(os.listdir(tmp_path)) == ["f.parquet"]


@pytest.mark.parametrize("args", PRINTERS)
def test_standard_output_past_the_file_size_limit_is_one_line(bus, args):
    # H3: cut at the limit in the middle of a line, exit 0, nothing said.
    with open(bus / "out.txt", "w") as fh:
        r = run(args, cwd=bus, limit=4096, stdout=fh)
    assert r.returncode == 2, r.stderr[-3000:]
    assert _one_line(r.stderr) == (
        "loadbayes: error: standard output: File too large; what was printed is incomplete"
    )


@pytest.mark.parametrize("args", PRINTERS)
def test_standard_output_on_a_full_device_is_one_line(bus, args):
    # H3: `example zip > /dev/full` was an OSError traceback, exit 1.
    if not os.path.exists("/dev/full"):
        pytest.skip("no /dev/full here")
    with open("/dev/full", "w") as fh:
        r = run(args, cwd=bus, stdout=fh)
    assert r.returncode == 2, r.stderr[-3000:]
    assert _one_line(r.stderr) == FULL


def test_standard_output_that_fits_is_byte_identical(bus, tmp_path):
    with open(tmp_path / "a.csv", "w") as fh:
        r = run(["example", "zip"], cwd=tmp_path, stdout=fh)
    assert r.returncode == 0 and r.stderr == ""
    r = run(["example", "zip", "--out", "b.csv"], cwd=tmp_path)
    assert r.returncode == 0
    assert (tmp_path / "a.csv").read_bytes() == (tmp_path / "b.csv").read_bytes()


CLOSED = "loadbayes: error: standard output is closed (>&-): what it would print is lost"


@pytest.mark.parametrize("args", PRINTERS)
def test_a_closed_standard_output_is_one_line(bus, args):
    # Red-team L10: `example zip >&-` and `fit zip ... --json - >&-` ended 0, nothing
    # written anywhere (Python sets sys.stdout to None and click's echo drops the text).
    env = dict(os.environ, PYTHONPATH=SRC + os.pathsep + os.environ.get("PYTHONPATH", ""))
    before = sorted(p.name for p in bus.iterdir())
    r = subprocess.run([sys.executable, "-m", "loadbayes", *args], cwd=bus, env=env,
                       stderr=subprocess.PIPE, text=True, timeout=300,
                       preexec_fn=lambda: os.close(1))  # fmt: skip
    assert r.returncode == 2, r.stderr[-3000:]
    assert _one_line(r.stderr) == CLOSED
    assert sorted(p.name for p in bus.iterdir()) == before
