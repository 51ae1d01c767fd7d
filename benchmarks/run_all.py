"""Run every benchmark script and write ``benchmarks/README.md`` from their results.

Usage::

    python benchmarks/run_all.py                 # full runs (what `make bench` does)
    python benchmarks/run_all.py --quick         # smoke sizes, results in results/quick/
    python benchmarks/run_all.py --readme-only   # rebuild the README from results/*.json

Each script is run as ``python SCRIPT [--quick] --output results/NAME.json`` in its own
process, its output kept in ``results/NAME.log``. The contract for a script: accept
``--quick`` and ``--output PATH``, and write there a JSON object with ``date``,
``machine``, ``versions`` and ``results`` (a list of flat dicts, one per table row);
optionally ``targets`` (a list of ``{"target", "measured", "met"}``) and ``notes``
(a list of strings). Scripts that are missing are skipped (the power-flow and motor
benchmarks belong to their modules' owners).
"""

from __future__ import annotations

import argparse
import ast
import datetime
import json
import math
import subprocess
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
RESULTS = HERE / "results"
SCRIPTS = [
    ("bench_zip.py", "zip"),
    ("bench_stream.py", "stream"),
    ("bench_powerflow.py", "powerflow"),
    ("bench_im.py", "im"),
    ("bench_composite.py", "composite"),
    ("bench_cli.py", "cli"),
    ("bench_drift.py", "drift"),
    ("bench_fleet.py", "fleet"),
    ("bench_predict.py", "predict"),
    ("bench_rest.py", "rest"),
    ("bench_archive_pool.py", "archive_pool"),
    ("bench_archive.py", "archive"),
]

#: Everything after this line of the README is kept as written (the sections of scripts
#: that run_all.py does not render yet).
HAND_WRITTEN = "<!-- hand-written below: kept by run_all.py -->"


def script_options(path: Path) -> set[str]:
    """The long options a script's argparse declares (read from its source)."""
    opts = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Call) and getattr(node.func, "attr", "") == "add_argument":
            for arg in node.args:
                if isinstance(arg, ast.Constant) and str(arg.value).startswith("--"):
                    opts.add(arg.value)
    return opts


def run_scripts(quick: bool, only: list[str] | None) -> dict[str, dict]:
    out_dir = RESULTS / "quick" if quick else RESULTS
    out_dir.mkdir(parents=True, exist_ok=True)
    status = {}
    for script, name in SCRIPTS:
        if only and name not in only:
            continue
        path = HERE / script
        if not path.exists():
            status[name] = {"status": "absent"}
            print(f"{script}: absent, skipped", flush=True)
            continue
        opts = script_options(path)
        if quick and "--quick" not in opts:
            status[name] = {"status": "no --quick"}
            print(f"{script}: has no --quick option, skipped", flush=True)
            continue
        out_opt = "--output" if "--output" in opts else "--out"
        cmd = [sys.executable, str(path), out_opt, str(out_dir / f"{name}.json")]
        if quick:
            cmd.append("--quick")
        print(f"{script}: running {' '.join(cmd[1:])}", flush=True)
        t0 = time.perf_counter()
        with open(out_dir / f"{name}.log", "w") as log:
            proc = subprocess.run(cmd, stdout=log, stderr=subprocess.STDOUT, cwd=HERE.parent)
        seconds = time.perf_counter() - t0
        status[name] = {"status": "ok" if proc.returncode == 0 else f"exit {proc.returncode}"}
        status[name]["seconds"] = seconds
        print(f"{script}: {status[name]['status']} in {seconds:.0f} s", flush=True)
    return status


# ------------------------------------------------------------------------------ README


def _num(x, digits: int = 3) -> str:
    if x is None:
        return "-"
    if isinstance(x, (list, tuple)):
        return "[" + ", ".join(_num(v, digits) for v in x) + "]"
    if isinstance(x, bool):
        return "yes" if x else "no"
    if isinstance(x, int):
        return f"{x:,}"
    if isinstance(x, float):
        if not math.isfinite(x):
            return str(x)
        if x == 0:
            return "0"
        mag = math.floor(math.log10(abs(x)))
        if mag < -3:
            return f"{x:.{digits - 1}e}"
        if mag >= digits:
            return f"{x:,.0f}"
        return f"{x:.{max(digits - 1 - mag, 0)}f}"
    return str(x)


def _ratio(x: float) -> str:
    return f"{x:.2g}x" if x < 10 else f"{x:,.0f}x"


def _table(header: list[str], rows: list[list[str]]) -> list[str]:
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    lines += ["| " + " | ".join(r) + " |" for r in rows]
    return lines


def _title(script: str) -> str:
    path = HERE / script
    try:
        doc = ast.get_docstring(ast.parse(path.read_text())) or script
    except (OSError, SyntaxError):
        return script
    return " ".join(doc.split("\n\n")[0].split())


def _targets(info: dict) -> list[str]:
    if not info.get("targets"):
        return []
    rows = [
        [t["target"], t["measured"], "met" if t["met"] else "**not met**"] for t in info["targets"]
    ]
    return ["", *_table(["target", "measured", ""], rows)]


def _zip_section(info: dict) -> list[str]:
    header = [
        "sampler", "n", "settings", "first call s", "warm s", "ESS(a1)", "ESS/s",
        "warm ESS/s", "peak RSS MB", "a1 mean (sd)", "a2 mean (sd)", "check",
        "lb blocked ESS/s ÷ this (first / warm)",
    ]  # fmt: skip
    rows = []
    for r in info["results"]:
        if "first_s" not in r:
            why = r.get("skipped") or r.get("error", "")
            rows.append([r["sampler"], _num(r["n"]), r.get("settings", ""), f"skipped: {why}"])
            rows[-1] += [""] * (len(header) - len(rows[-1]))
            continue
        ratio = "-"
        if "ratio_first" in r:
            ratio = _ratio(r["ratio_first"])
            if r.get("ratio_warm"):
                ratio += " / " + _ratio(r["ratio_warm"])
        check = r.get("check", "")
        if "check_max_z" in r:
            check += f" (\\|z\\| {r['check_max_z']:.1f})"
        rows.append(
            [
                r["sampler"],
                _num(r["n"]),
                r.get("settings", ""),
                _num(r["first_s"]),
                _num(r.get("warm_s")),
                _num(r["ess_a1"], 2),
                _num(r["ess_per_s"]),
                _num(r.get("warm_ess_per_s")),
                _num(r["peak_rss_mb"], 2),
                f"{r['a1_mean']:.4f} ({r['a1_sd']:.4f})",
                f"{r['a2_mean']:.4f} ({r['a2_sd']:.4f})",
                check,
                ratio,
            ]
        )
    lines = _table(header, rows)
    lb = [r for r in info["results"] if r["sampler"] == "loadbayes-blocked" and "sampling_ms" in r]
    if lb:
        lines += ["", "loadbayes blocked, sampling alone (`sample_block`, one block, warm):"]
        lines += [""] + _table(
            [
                "n",
                "sufficient statistics ms (O(n))",
                "sampling ms (4 x 40,000, wall)",
                "sampling CPU ms",
            ],
            [
                [
                    _num(r["n"]),
                    _num(r["stats_ms"]),
                    _num(r["sampling_ms"]),
                    _num(r.get("sampling_cpu_ms")),
                ]
                for r in lb
            ],
        )
    return lines


def _stream_section(info: dict) -> list[str]:
    header = [
        "chunk_rows", "rows", "seconds", "rows/s", "peak RSS MB", "RSS before fit MB",
        "read s", "rows s", "gram s", "sample s", "other s", "digest",
    ]  # fmt: skip
    rows = []
    for r in info["results"]:
        if "error" in r:
            rows.append([_num(r["chunk_rows"]), "error: " + r["error"]] + [""] * 10)
            continue
        rows.append(
            [
                _num(r["chunk_rows"]),
                _num(r["n"]),
                _num(r["seconds"]),
                _num(r["rows_per_second"]),
                _num(r["peak_rss_mb"], 2),
                _num(r["rss_before_fit_mb"], 2),
                _num(r["read_s"]),
                _num(r["rows_s"]),
                _num(r["gram_s"]),
                _num(r["sample_s"]),
                _num(r["other_s"]),
                f"`{r['digest']}`",
            ]
        )
    lines = [
        f"File: {info['rows']:,} rows, {info.get('file_mb', 0):,.0f} MiB Parquet "
        f"(written in {_num(info.get('write_s'))} s).",
        "",
        *_table(header, rows),
        "",
        "Sampling time against n (the O(n) pass, then 4 chains x 40,000 of one block):",
        "",
    ]
    lines += _table(
        [
            "n",
            "rows + Gram ms (O(n))",
            "sampling ms (wall, best of 7)",
            "sampling CPU ms",
            "ns per draw",
        ],
        [
            [
                _num(r["n"]),
                _num(r["stats_ms"]),
                _num(r["sampling_ms"]),
                _num(r.get("sampling_cpu_ms")),
                _num(r["sampling_ns_per_draw"]),
            ]
            for r in info["flat_in_n"]
        ],
    )
    return lines


def _generic_section(info: dict) -> list[str]:
    rows = info.get("results")
    if isinstance(rows, list) and rows and all(isinstance(r, dict) for r in rows):
        cols: list[str] = []
        for r in rows:
            cols += [c for c in r if c not in cols and not isinstance(r[c], (list, dict))]
        return _table(cols, [[_num(r.get(c)) for c in cols] for r in rows])
    # No list of rows: show the top-level entries, one per line.
    skip = {"date", "machine", "versions", "targets", "notes", "quick", "benchmark"}
    out = []
    for key, val in info.items():
        if key in skip:
            continue
        if isinstance(val, dict):
            val = ", ".join(f"{k} {_num(v)}" for k, v in val.items() if not isinstance(v, dict))
        elif isinstance(val, list):
            val = ", ".join(_num(v) for v in val)
        out.append([key, _num(val) if not isinstance(val, str) else val])
    return _table(["quantity", "value"], out) if out else ["(no results)"]


def _composite_section(info: dict) -> list[str]:
    """Issue 35's table: per event, loadbayes' wall over seeds and each peer's ESS/s."""
    if not info.get("events"):
        return _generic_section(info)
    header = [
        "event", "n", "load (1 min, its run's start / end)",
        "loadbayes defaults wall s: median / max (CPU median)", "converged",
        "loadbayes ESS/s (R-hat)", "emcee ESS/s", "ratio: wall (CPU s)", "NUTS ESS/s",
        "NUTS R-hat", "ratio: wall (CPU s)",
    ]  # fmt: skip

    def num(x) -> str:
        return _num(x) if isinstance(x, (int, float)) and math.isfinite(x) else "-"

    def both(e: dict, key: str) -> str:
        def one(x):
            return _ratio(x) if isinstance(x, (int, float)) and math.isfinite(x) else "-"

        return f"{one(e.get(key))} ({one(e.get(key + '_cpu'))})"

    m = info.get("machine", {})
    run_load = [m.get("load_average_at_start", [math.nan])[0],
                m.get("load_average_at_end", [math.nan])[0]]  # fmt: skip
    rows = []
    for e in info["events"]:
        load = e.get("load_1min_start_end", run_load)
        if "skipped" in e:
            rows.append([e["event"], f"skipped: {e['skipped']}"] + [""] * (len(header) - 2))
            continue
        rows.append(
            [
                e["event"],
                _num(e["n"]),
                f"{load[0]:.1f} / {load[1]:.1f}",
                f"{_num(e['defaults_wall_median_s'])} / {_num(e['defaults_wall_max_s'])} "
                f"({_num(e['defaults_cpu_median_s'])})",
                f"{e['defaults_converged']} of {e['seeds']}",
                f"{_num(e['same_posterior_ess_per_s'])} ({e['same_posterior_r_hat']:.3f})",
                num(e["emcee_ess_per_s"]),
                both(e, "ratio_emcee"),
                num(e["nuts_ess_per_s"]),
                num(e["nuts_r_hat"]),
                both(e, "ratio_nuts"),
            ]
        )
    runs = [
        [
            r.get("event", ""), r["sampler"], _num(r.get("seed")), r.get("settings", ""),
            _num(r.get("wall_s")), _num(r.get("cpu_s")), _num(r.get("min_ess_bulk")),
            r.get("worst", ""), _num(r.get("max_r_hat")), _num(r.get("ess_per_s")),
        ]
        if "skipped" not in r
        else [r.get("event", ""), r["sampler"], "", f"skipped: {r['skipped']}"] + [""] * 6
        for r in info["results"]
    ]  # fmt: skip
    end = m.get("load_average_at_end")
    lines = _table(header, rows)
    if info.get("runs"):  # merged from runs made side by side: each its own load
        lines += ["", "Runs: " + "; ".join(
            f"{i}: {r['date']}, load {r['machine']['load_average_at_start'][0]:.1f} at start, "
            f"{r['machine']['load_average_at_end'][0]:.1f} at end, {_num(r['machine']['run_s'])} s"
            for i, r in enumerate(info["runs"])) + "."]  # fmt: skip
    elif end:
        lines += ["", f"Load average at the end: {', '.join(f'{x:.1f}' for x in end)}; "
                  f"the whole run took {_num(m.get('run_s'))} s."]  # fmt: skip
    lines += ["", "Every run:", ""]
    lines += _table(
        ["event", "sampler", "seed", "settings", "wall s", "CPU s", "min ESS", "worst",
         "R-hat", "ESS/s"], runs,
    )  # fmt: skip
    return lines


SECTIONS = {"zip": _zip_section, "stream": _stream_section, "composite": _composite_section}


def _machine_line(info: dict) -> str:
    m = info.get("machine", {})
    load = m.get("load_average_at_start")
    load_s = f"; load average at start {', '.join(f'{x:.1f}' for x in load)}" if load else ""
    mem = f", {m['memory_gb']} GB RAM" if m.get("memory_gb") else ""
    return (
        f"{m.get('cpu', '?')}, {m.get('cpu_count', '?')} CPUs ({m.get('cpus_usable', '?')} "
        f"usable){mem}; {m.get('platform', '?')}; Python {m.get('python', '?')}{load_s}"
    )


def write_readme(results_dir: Path, readme: Path, status: dict | None = None) -> None:
    lines = [
        "# Benchmarks",
        "",
        "Generated by `benchmarks/run_all.py` (`make bench`) from `benchmarks/results/*.json`;",
        "edit the scripts or `run_all.py`, not this file. Each section says how its times are",
        "counted. Everything ran on the machine named in its section, at the same time as",
        "any other load that machine had (the load average at start is given).",
        "",
        f"README written {datetime.datetime.now(datetime.UTC).isoformat(timespec='seconds')}.",
    ]
    summary = []
    for script, name in SCRIPTS:
        path = results_dir / f"{name}.json"
        if path.exists():
            for t in json.loads(path.read_text()).get("targets") or []:
                met = "met" if t["met"] else "**not met**"
                summary.append([script, t["target"], t["measured"], met])
    if summary:
        lines += ["", "## Targets", "", *_table(["script", "target", "measured", ""], summary)]
    for script, name in SCRIPTS:
        path = results_dir / f"{name}.json"
        lines += ["", f"## {script}", "", _title(script), ""]
        if status and status.get(name, {}).get("status") in ("absent", "no --quick"):
            lines.append(f"Not run: {status[name]['status']}.")
            continue
        if not path.exists():
            lines.append(f"No results (`{path.name}` missing).")
            continue
        info = json.loads(path.read_text())
        versions = ", ".join(f"{k} {v}" for k, v in (info.get("versions") or {}).items() if v)
        lines += [
            f"- date: {info.get('date', '?')}" + (" (--quick)" if info.get("quick") else ""),
            f"- machine: {_machine_line(info)}",
            f"- versions: {versions}",
        ]
        if status and name in status and "seconds" in status[name]:
            lines.append(f"- script run time: {status[name]['seconds']:.0f} s")
        lines += _targets(info)
        lines += ["", *SECTIONS.get(name, _generic_section)(info)]
        for note in info.get("notes") or []:
            lines += ["", note]
    if readme.exists() and HAND_WRITTEN in readme.read_text():
        kept = readme.read_text().split(HAND_WRITTEN, 1)[1].strip("\n")
        lines += ["", HAND_WRITTEN, "", kept]
    readme.write_text("\n".join(lines) + "\n")
    print(f"wrote {readme}")


def splice_sections(readme: Path, fresh: str, names: list[str]) -> None:
    """Replace in ``readme`` only the sections and target rows of the scripts ``names``.

    ``fresh`` is a README rendered whole from the results; the rest of ``readme`` (other
    scripts' sections, with any paragraph written by hand into them) is kept as it is.
    """
    scripts = [script for script, name in SCRIPTS if name in names]
    old = readme.read_text().split("\n")
    new = fresh.split("\n")

    def section(lines: list[str], script: str) -> tuple[int, int]:
        start = lines.index(f"## {script}")
        end = start + 1
        while end < len(lines) and not (lines[end].startswith("## ") or lines[end] == HAND_WRITTEN):
            end += 1
        return start, end

    for script in scripts:
        prefix = f"| {script} |"
        at = [i for i, x in enumerate(old) if x.startswith(prefix)]
        if at:  # the script's target rows, where its first one was
            rest = [x for x in old if not x.startswith(prefix)]
            old = rest[: at[0]] + [x for x in new if x.startswith(prefix)] + rest[at[0] :]
        elif "## Targets" in old:  # a script's first targets: at the end of the table
            end = old.index("## Targets") + 1
            while end < len(old) and (not old[end] or old[end].startswith("|")):
                end += 1
            while not old[end - 1]:
                end -= 1
            old = old[:end] + [x for x in new if x.startswith(prefix)] + old[end:]
        a, b = section(new, script)
        try:
            c, d = section(old, script)
        except ValueError:
            c = d = old.index(HAND_WRITTEN) if HAND_WRITTEN in old else len(old)
        old = old[:c] + new[a:b] + old[d:]
    readme.write_text("\n".join(old))
    print(f"wrote {readme} (sections: {', '.join(scripts)})")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="smoke sizes; README not touched")
    parser.add_argument("--only", nargs="*", default=None, help="zip, stream, powerflow, im")
    parser.add_argument("--readme-only", action="store_true")
    parser.add_argument(
        "--sections",
        nargs="*",
        default=None,
        help="with --readme-only: re-render only these scripts' sections and target rows "
        "(fleet, zip, ...), keeping the rest of the README as it is",
    )
    args = parser.parse_args(argv)
    if args.readme_only and args.sections:
        import tempfile

        with tempfile.TemporaryDirectory() as tmp:
            fresh = Path(tmp) / "README.md"
            write_readme(RESULTS, fresh)
            splice_sections(HERE / "README.md", fresh.read_text(), args.sections)
        return 0
    status = None
    if not args.readme_only:
        status = run_scripts(args.quick, args.only)
    if args.quick:
        write_readme(RESULTS / "quick", RESULTS / "quick" / "README.md", status)
    else:
        write_readme(RESULTS, HERE / "README.md", status)
    failed = [
        k for k, v in (status or {}).items() if v["status"] not in ("ok", "absent", "no --quick")
    ]
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
