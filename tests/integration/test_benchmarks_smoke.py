"""Every benchmark script still runs: each with ``--quick``, in this process.

Each runs as ``python SCRIPT --quick --output FILE`` would run it (``runpy`` as
``__main__``, its folder first on ``sys.path``, from an empty folder, warnings shown
rather than raised, the environment restored after): a smoke test of the scripts, not of
processes, and a Python start with the package's imports fewer each (about 2-3 s of CPU a
script; the scripts that time processes, ``bench_cli.py``, start their own).

Peers that are not installed (PyMC, NumPyro, emcee: the ``bench`` extra) are skipped by
the scripts themselves and reported as such. Times and targets are not checked here:
that is the benchmarks' job (``make bench``), not the tests'.
"""

import importlib.util
import json
import os
import runpy
import sys
import warnings
from pathlib import Path

import pytest

pytestmark = pytest.mark.integration

BENCH = Path(__file__).resolve().parents[2] / "benchmarks"
SCRIPTS = [
    "bench_zip.py", "bench_stream.py", "bench_powerflow.py", "bench_im.py", "bench_cli.py",
    "bench_drift.py", "bench_fleet.py", "bench_archive_pool.py", "bench_composite.py",
    "bench_rest.py",
]  # fmt: skip


def _run_all():
    spec = importlib.util.spec_from_file_location("run_all", BENCH / "run_all.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _run_here(path: Path, argv: list[str], cwd: Path, monkeypatch) -> int | None:
    """The exit code of ``python PATH ARGV`` from ``cwd``, run in this process."""
    monkeypatch.chdir(cwd)
    monkeypatch.setattr(sys, "argv", [str(path), *argv])
    monkeypatch.setattr(sys, "path", [str(path.parent), *sys.path])
    env = dict(os.environ)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("default")
            runpy.run_path(str(path), run_name="__main__")
    except SystemExit as exc:
        return exc.code
    finally:
        os.environ.clear()
        os.environ.update(env)
    return 0


@pytest.mark.parametrize("script", SCRIPTS)
def test_script_runs_quick(script, tmp_path, monkeypatch, capsys):
    path = BENCH / script
    if not path.exists():
        pytest.skip(f"{script} not written yet")
    opts = _run_all().script_options(path)
    if "--quick" not in opts:
        pytest.skip(f"{script} has no --quick option")
    out = tmp_path / "result.json"
    out_opt = "--output" if "--output" in opts else "--out"
    code = _run_here(path, ["--quick", out_opt, str(out)], tmp_path, monkeypatch)
    captured = capsys.readouterr()
    assert code in (0, None), captured.out[-2000:] + captured.err[-2000:]
    info = json.loads(out.read_text())
    assert info.get("results"), "no results written"
    if script == "bench_zip.py":
        rows = {r["sampler"]: r for r in info["results"]}
        assert rows["loadbayes-blocked"]["check"] == "ref"
        for name, module in (
            ("pymc-nuts", "pymc"),
            ("numpyro-nuts", "numpyro"),
            ("emcee", "emcee"),
        ):
            if importlib.util.find_spec(module) is None:
                assert "not installed" in rows[name]["skipped"]
            else:
                assert rows[name]["check"] in ("ok", "low ESS"), rows[name]
    if script == "bench_composite.py":
        rows = {r["sampler"]: r for r in info["results"]}
        # The move is the package's default, whatever it is: named in the row.
        fits = [k for k in rows if k.startswith("loadbayes-")]
        assert sum(k.endswith("-ramp") for k in fits) == 1 and len(fits) == 2, fits
        for name, module in (("emcee", "emcee"), ("numpyro-nuts-diffrax", "numpyro")):
            if importlib.util.find_spec(module) is None:
                assert "not installed" in rows[name]["skipped"]
        (event,) = info["events"]
        assert event["seeds"] == 1 and event["defaults_wall_max_s"] > 0
        assert len(info["targets"]) == 2  # NUTS and emcee, each met, missed or not measured
    if script == "bench_stream.py":
        assert info["bit_identical"]
    if script == "bench_fleet.py":
        stages = {(r["stage"], r["engine"]) for r in info["results"]}
        assert {("pooled fit", "inproc"), ("pooled fit", "2")} <= stages
        assert "Identical tables across engines: True" in info["notes"][0]
    if script == "bench_cli.py":
        cases = {r["case"] for r in info["results"]}
        assert {"fit zip, cold cache (compiles)", "fit zip, warm cache"} <= cases
        assert info["machine"]["load_average_at_start"] is not None
        parts = {p["part"]: p["seconds"] for p in info["where_the_time_goes"]}
        assert parts["import arviz (should be absent)"] == 0.0  # fit zip never loads ArviZ


def test_readme_is_written_from_results(tmp_path):
    run_all = _run_all()
    (tmp_path / "zip.json").write_text(
        json.dumps(
            {
                "date": "2025-01-01T00:00:00+00:00",
                "machine": {"cpu": "test cpu", "cpu_count": 2},
                "versions": {"numpy": "2"},
                "results": [{"sampler": "emcee", "n": 1000, "skipped": "emcee not installed"}],
                "targets": [{"target": "t", "measured": "m", "met": False}],
            }
        )
    )
    (tmp_path / "im.json").write_text(json.dumps({"n": 10, "fit": {"best_s": 1.5}}))
    readme = tmp_path / "README.md"
    run_all.write_readme(tmp_path, readme)
    text = readme.read_text()
    assert "test cpu" in text and "**not met**" in text and "emcee not installed" in text
    assert "best_s 1.50" in text


def test_readme_keeps_its_hand_written_tail(tmp_path):
    run_all = _run_all()
    readme = tmp_path / "README.md"
    # A token no section writes ("old" was one: bench_rest.py's title says "holding").
    stale = "stale-generated-part-7f3c"
    readme.write_text(f"{stale}\n{run_all.HAND_WRITTEN}\n\n## by hand\n\nkept\n")
    run_all.write_readme(tmp_path, readme)
    text = readme.read_text()
    assert stale not in text.split(run_all.HAND_WRITTEN)[0]
    assert text.count(run_all.HAND_WRITTEN) == 1 and text.endswith("## by hand\n\nkept\n")
