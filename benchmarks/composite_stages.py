"""Where ``loadbayes fit composite`` spends its time: wall and CPU seconds per stage.

Usage (arguments as the command's, after ``fit composite``)::

    python benchmarks/composite_stages.py events/event_001.csv --quiet --json fit.json

Runs the command in this process, as ``loadbayes`` runs it (``cli.main``, its exit
included), with timers wrapped around its stages: the imports of ``loadbayes.cli`` and of
the command, reading the events, the samples' reading choice, the NLS, the sampler, the
rest of ``fit_composite``, the summaries and the JSON, the outputs. The table goes to
standard error, and with ``STAGES_OUT=path`` to that JSON file as ``[stage, wall, cpu]``
rows (CPU: this process's, every thread's). The interpreter's start and exit lie outside
the timers: ``bench_seeds.py --stages`` gets them from the whole process's times. The
numba row (its cached kernels' first calls: loading, and numba's own start) lies inside
the stages above it. Not a test: the timers are wrappers, nothing in loadbayes changes.
"""

from __future__ import annotations

import time

_MARKS = [("start", time.perf_counter(), time.process_time())]

import atexit  # noqa: E402
import importlib  # noqa: E402
import json  # noqa: E402
import os  # noqa: E402
import sys  # noqa: E402


def _mark(name: str) -> None:
    _MARKS.append((name, time.perf_counter(), time.process_time()))


_NUMBA = [0.0, 0.0, 0]

#: (module, attribute[, class]) and the stage that ends when it returns.
_STAGES = [
    ("loadbayes.measurements.events", "read_events", None, "read the events"),
    ("loadbayes.fit.composite.reading", "reading_model", None, "the samples' reading"),
    ("loadbayes.fit.composite.driver", "nls", None, "NLS"),
    ("loadbayes.fit.composite.driver", "sample", None, "sampler"),
    ("loadbayes.fit.composite.driver", "fit_composite", None, "rest of fit_composite"),
    ("loadbayes.posterior", "summary", "Posterior", "summary (R-hat, ESS, HDI)"),
    ("loadbayes.posterior", "to_dict", "Posterior", "JSON (to_dict)"),
    ("loadbayes.commands.composite", "output_transaction", None, "outputs"),
]


def _wrap(module: str, attr: str, cls: str | None, label: str) -> None:
    owner = importlib.import_module(module)
    owner = getattr(owner, cls) if cls else owner
    inner = getattr(owner, attr)

    def timed(*args, **kwargs):
        _mark(f"(before {label})")
        try:
            return inner(*args, **kwargs)
        finally:
            _mark(label)

    setattr(owner, attr, timed)


def _wrap_numba() -> None:
    from numba.core import dispatcher

    inner = dispatcher.Dispatcher._compile_for_args

    def timed(self, *args, **kwargs):
        w, c = time.perf_counter(), time.process_time()
        try:
            return inner(self, *args, **kwargs)
        finally:
            _NUMBA[0] += time.perf_counter() - w
            _NUMBA[1] += time.process_time() - c
            _NUMBA[2] += 1

    dispatcher.Dispatcher._compile_for_args = timed


def rows() -> list[tuple[str, float, float]]:
    """``[stage, wall s, cpu s]``; the gaps between two stages go to the later one."""
    out: dict[str, list[float]] = {}
    for (_, w0, c0), (name, w1, c1) in zip(_MARKS, _MARKS[1:], strict=False):
        name = "between the stages" if name.startswith("(before ") else name
        acc = out.setdefault(name, [0.0, 0.0])
        acc[0] += w1 - w0
        acc[1] += c1 - c0
    table = [(n, w, c) for n, (w, c) in out.items()]
    table.append((f"(inside the above: numba's first calls, {_NUMBA[2]})", *_NUMBA[:2]))
    return table


def _report() -> None:
    _mark("after the outputs")
    table = rows()
    path = os.environ.get("STAGES_OUT")
    if path:
        with open(path, "w", encoding="utf-8") as f:
            json.dump(table, f)
    for name, w, c in table:
        print(f"{name:45s} wall {w:7.3f}  cpu {c:7.3f}", file=sys.stderr)


def main() -> None:
    import loadbayes.cli as cli

    _mark("import loadbayes.cli")
    import loadbayes.commands.composite as command

    _mark("import the command")
    callback = command.fit_composite_cmd.callback

    def timed_command(*args, **kwargs):
        _mark("parse the options")
        _wrap_numba()
        for stage in _STAGES:
            _wrap(*stage)
        _mark("imports of the fit")
        return callback(*args, **kwargs)

    command.fit_composite_cmd.callback = timed_command
    atexit.register(_report)  # the command's own exit runs the atexit handlers
    sys.argv = ["loadbayes", "fit", "composite", *sys.argv[1:]]
    cli.main(prog_name="loadbayes")


if __name__ == "__main__":
    main()
