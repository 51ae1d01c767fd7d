"""The layout's rules, checked on the code's own imports (docs/architecture.md).

Arrows point down only: commands -> studies -> fit / baselines -> models & inference ->
core -> io. Models are physics (they never import a sampler, a driver or Posterior),
samplers know no physics, and the library never imports the studies or the CLI.

Eight rules are written as functions over an import map (or over the click tree, the
source files, the map's text), so a test can run each of them on a planted violation as
well as on the real code. The import map
holds every import of a module, at any depth (those inside functions and ``if`` blocks
too) and relative ones resolved; ``importlib.import_module`` strings are not seen.

- :func:`cases_importers`: only ``loadbayes.studies``, ``loadbayes.commands``,
  ``loadbayes.testing`` (and ``loadbayes.cases`` itself) import ``loadbayes.cases``:
  the synthetic data is never a dependency of the library.
- :func:`cross_package_private_imports`: no ``_private`` name (dunders aside) is imported
  from a module of another top-level package (``from loadbayes.x.y import _z`` in a
  module outside ``loadbayes.x``). The modules of one top-level package are one unit and
  may share private helpers (``io.csv_reader`` takes ``io.cells._Piece``); a top-level
  module (``posterior``, ``cli``) is a package of its own. Only ``from ... import``
  names are seen, not attribute access on an imported module.
- :func:`commands_not_one_line`: every command reachable from ``loadbayes.cli.main``
  (groups walked, the groups themselves not counted) is a
  :class:`loadbayes.commands.options.OneLineCommand`, so its usage errors are one line.
- :func:`forbidden_imports` over :data:`FORBIDDEN`, three arrows that must not exist:
  ``fit/`` imports no ``report/`` or ``plots/`` (a fit returns results; how they are
  printed or drawn is above it), ``measurements/`` imports no ``models/`` (data in know
  no physics), ``posterior.py`` imports no ``report/`` (the result type sits below its
  reports).
- :func:`silent_long_modules`: a module over :data:`LONG_MODULE` lines says in its
  docstring which "one idea" needs its length.
- :func:`map_errors`: docs/architecture.md's module table names every module file, by
  its file name in its package's row, and names none that does not exist.
- :func:`imports_by_name`: the modules reached by ``importlib.import_module`` of a
  literal name, which the import map does not see, are exactly :data:`BY_NAME` (each
  with its reason).
"""

from __future__ import annotations

import ast
import re
import textwrap
from pathlib import Path

import click
import pytest

import loadbayes

SRC = Path(loadbayes.__file__).parent


def _module_name(path: Path, root: Path) -> str:
    rel = path.relative_to(root.parent).with_suffix("")
    parts = list(rel.parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def _scan(root: Path) -> tuple[dict[str, set[str]], dict[str, set[tuple[str, str]]]]:
    """The import map of the package at ``root``, at any depth of each file.

    Returns ``imports`` (each module -> the package's modules it imports) and ``names``
    (each module -> the ``(module, name)`` pairs of its ``from <package>... import name``).
    """
    top = root.name
    out: dict[str, set[str]] = {}
    names: dict[str, set[tuple[str, str]]] = {}
    for path in root.rglob("*.py"):
        name = _module_name(path, root)
        found: set[str] = set()
        pairs: set[tuple[str, str]] = set()
        package = name.split(".") if path.name == "__init__.py" else name.split(".")[:-1]
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.ImportFrom):
                source = node.module or ""
                if node.level:  # "from ..report import text" in loadbayes.fit.x
                    base = package[: len(package) - node.level + 1]
                    source = ".".join(base + ([node.module] if node.module else []))
                if source == top or source.startswith(top + "."):
                    found.add(source)
                    for alias in node.names:  # "from loadbayes.x import y" may be a module
                        found.add(f"{source}.{alias.name}")
                        pairs.add((source, alias.name))
            elif isinstance(node, ast.Import):
                found.update(a.name for a in node.names if a.name.split(".")[0] == top)
        out[name] = found
        names[name] = pairs
    modules = set(out)
    return {k: {m for m in v if m in modules} for k, v in out.items()}, names


IMPORTS, NAMES = _scan(SRC)


def _under(module: str, *packages: str) -> bool:
    return any(module == p or module.startswith(p + ".") for p in packages)


@pytest.mark.parametrize(
    ("package", "allowed"),
    [
        ("loadbayes.core", ("loadbayes.core",)),
        # models/ takes one type from measurements/: the recorded event its physics is
        # driven by (EventRecord, with its unit check).
        (
            "loadbayes.models",
            (
                "loadbayes.models",
                "loadbayes.core",
                "loadbayes.io.errors",
                "loadbayes.measurements.record",
            ),
        ),
        ("loadbayes.inference", ("loadbayes.inference", "loadbayes.core")),
        ("loadbayes.io", ("loadbayes.io",)),
    ],
)
def test_lower_layers_import_only_what_is_below_them(package, allowed):
    bad = {
        f"{mod} -> {dep}"
        for mod, deps in IMPORTS.items()
        if _under(mod, package)
        for dep in deps
        if dep != "loadbayes" and not _under(dep, *allowed) and dep != "loadbayes._version"
    }
    assert not bad, sorted(bad)


def test_the_library_never_imports_the_studies_or_the_cli():
    library = [m for m in IMPORTS if not _under(m, "loadbayes.studies", "loadbayes.commands")]
    bad = {
        f"{mod} -> {dep}"
        for mod in library
        if mod not in ("loadbayes.cli", "loadbayes.__main__")
        for dep in IMPORTS[mod]
        if _under(dep, "loadbayes.studies", "loadbayes.commands", "loadbayes.cli")
    }
    assert not bad, sorted(bad)


def _command(module: str) -> str:
    """The command a module belongs to: the module or package right under commands/."""
    return ".".join(module.split(".")[:3])


def test_no_command_imports_another_command_or_the_cli():
    shared = (
        "loadbayes.commands.options",
        "loadbayes.commands.output",
        "loadbayes.commands.settings",
        "loadbayes.commands.signals",
    )
    bad = {
        f"{mod} -> {dep}"
        for mod, deps in IMPORTS.items()
        if _under(mod, "loadbayes.commands") and mod != "loadbayes.commands"
        for dep in deps
        if dep == "loadbayes.cli"
        or (
            _under(dep, "loadbayes.commands")
            and dep not in shared
            and _command(dep) != _command(mod)
        )
    }
    assert not bad, sorted(bad)


def test_there_is_no_import_circle():
    graph = {m: {d for d in deps if d != m} for m, deps in IMPORTS.items()}
    # Package __init__ files re-export their children; an edge child -> package is not a
    # circle of code, so drop edges into one's own ancestors.
    graph = {m: {d for d in deps if not m.startswith(d + ".")} for m, deps in graph.items()}
    state: dict[str, int] = {}
    path: list[str] = []

    def visit(node: str) -> list[str] | None:
        state[node] = 1
        path.append(node)
        for nxt in sorted(graph.get(node, ())):
            if state.get(nxt) == 1:
                return path[path.index(nxt) :] + [nxt]
            if nxt not in state and (cycle := visit(nxt)):
                return cycle
        state[node] = 2
        path.pop()
        return None

    for start in sorted(graph):
        if start not in state and (cycle := visit(start)):
            pytest.fail(" -> ".join(cycle))


def test_every_model_offers_the_interface():
    from loadbayes.models.base import LinearModel, LoadModel
    from loadbayes.models.exponential import ExponentialModel
    from loadbayes.models.motor_fit import InductionMotorModel
    from loadbayes.models.zip import ZIPModel

    for model in (
        ZIPModel(),
        ExponentialModel(),
        ExponentialModel(noise="multiplicative"),
        InductionMotorModel(currents="measured", t0=0.6),
    ):
        assert isinstance(model, LoadModel), model
        assert model.pieces in ("linear", "power-law", "bilinear")
        if model.pieces == "linear":
            assert isinstance(model, LinearModel), model
    assert callable(ExponentialModel().power_law_blocks)


# --- Who may import the synthetic cases ----------------------------------------------

CASES_USERS = ("loadbayes.studies", "loadbayes.commands", "loadbayes.testing", "loadbayes.cases")


def cases_importers(imports: dict[str, set[str]]) -> set[str]:
    """The edges ``module -> loadbayes.cases...`` whose module may not import the cases."""
    return {
        f"{mod} -> {dep}"
        for mod, deps in imports.items()
        if not _under(mod, *CASES_USERS)
        for dep in deps
        if _under(dep, "loadbayes.cases")
    }


def test_only_studies_commands_and_testing_import_the_cases():
    assert not cases_importers(IMPORTS), sorted(cases_importers(IMPORTS))


def _plant(tmp_path: Path, files: dict[str, str]) -> Path:
    """Write a package ``loadbayes`` of ``{relative path: source}`` under tmp_path."""
    root = tmp_path / "loadbayes"
    for rel, source in files.items():
        path = root / rel
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(textwrap.dedent(source), encoding="utf-8")
    return root


def test_the_cases_rule_catches_a_planted_import(tmp_path):
    root = _plant(
        tmp_path,
        {
            "__init__.py": "",
            "cases/__init__.py": "",
            "cases/sim.py": "MOTORS = {}\n",
            "fit/__init__.py": "",
            "fit/nls.py": "def f():\n    from loadbayes.cases.sim import MOTORS\n",
            "export/__init__.py": "import loadbayes.cases.sim\n",
            "studies/__init__.py": "from loadbayes.cases import sim\n",
            "testing/__init__.py": "from loadbayes.cases.sim import MOTORS\n",
        },
    )
    imports, _ = _scan(root)
    assert cases_importers(imports) == {
        "loadbayes.fit.nls -> loadbayes.cases.sim",
        "loadbayes.export -> loadbayes.cases.sim",
    }


# --- No private name across a package line -------------------------------------------


def _package(module: str) -> str:
    """The top-level package a module belongs to: ``loadbayes.io.cells`` -> ``loadbayes.io``."""
    return ".".join(module.split(".")[:2])


def _private(name: str) -> bool:
    return name.startswith("_") and not (name.startswith("__") and name.endswith("__"))


def cross_package_private_imports(names: dict[str, set[tuple[str, str]]]) -> set[str]:
    """The imports ``module -> source._name`` of a private name across a package line."""
    return {
        f"{mod} -> {source}.{name}"
        for mod, pairs in names.items()
        for source, name in pairs
        if _private(name) and _package(source) != _package(mod)
    }


def test_no_private_name_crosses_a_package_line():
    found = cross_package_private_imports(NAMES)
    assert not found, sorted(found)


def test_the_private_name_rule_catches_a_planted_import(tmp_path):
    root = _plant(
        tmp_path,
        {
            "__init__.py": "from loadbayes._version import __version__\n",
            "_version.py": "__version__ = '0'\n",
            "posterior.py": "def _arviz():\n    pass\n",
            "io/__init__.py": "",
            "io/cells.py": "def _select():\n    pass\n",
            "io/csv_reader.py": "from loadbayes.io.cells import _select\n",  # same package
            "measurements/__init__.py": "",
            "measurements/frame.py": "def f():\n    from loadbayes.io.cells import _select\n",
            "fit/__init__.py": "from loadbayes.posterior import _arviz as arviz\n",
            "cli.py": "from loadbayes import io as _io\n",  # a private alias is no import of one
        },
    )
    _, names = _scan(root)
    assert cross_package_private_imports(names) == {
        "loadbayes.measurements.frame -> loadbayes.io.cells._select",
        "loadbayes.fit -> loadbayes.posterior._arviz",
    }


# --- Every command prints its usage errors on one line -------------------------------


def commands_not_one_line(group: click.Group, path: str = "loadbayes") -> list[str]:
    """The command paths under ``group`` (groups walked) that are not a OneLineCommand."""
    from loadbayes.commands.options import OneLineCommand

    bad = []
    for name, command in sorted(group.commands.items()):
        where = f"{path} {name}"
        if isinstance(command, click.Group):
            bad += commands_not_one_line(command, where)
        elif not isinstance(command, OneLineCommand):
            bad.append(where)
    return bad


def test_every_command_is_a_one_line_command():
    from loadbayes.cli import main

    assert commands_not_one_line(main) == []


def test_the_one_line_rule_catches_a_planted_command():
    from loadbayes.commands.options import OneLineCommand

    @click.group()
    def top() -> None: ...

    @top.group()
    def fit() -> None: ...

    @fit.command("zip", cls=OneLineCommand)
    def good() -> None: ...

    @fit.command("exp")
    def plain() -> None: ...

    @top.command("report", cls=OneLineCommand)
    def also_good() -> None: ...

    assert commands_not_one_line(top) == ["loadbayes fit exp"]


# --- Arrows that must not exist ------------------------------------------------------

#: Each rule: (the importers, what they may not import), by package or module.
FORBIDDEN: dict[str, tuple[tuple[str, ...], tuple[str, ...]]] = {
    "fit imports no report or plots": (
        ("loadbayes.fit",),
        ("loadbayes.report", "loadbayes.plots"),
    ),
    "measurements imports no models": (("loadbayes.measurements",), ("loadbayes.models",)),
    "posterior imports no report": (("loadbayes.posterior",), ("loadbayes.report",)),
}


def forbidden_imports(imports: dict[str, set[str]], rule: str) -> set[str]:
    """The edges ``module -> dep`` that :data:`FORBIDDEN`'s ``rule`` forbids."""
    importers, banned = FORBIDDEN[rule]
    return {
        f"{mod} -> {dep}"
        for mod, deps in imports.items()
        if _under(mod, *importers)
        for dep in deps
        if _under(dep, *banned)
    }


@pytest.mark.parametrize("rule", sorted(FORBIDDEN))
def test_no_forbidden_arrow(rule):
    found = forbidden_imports(IMPORTS, rule)
    assert not found, sorted(found)


def test_the_forbidden_arrows_are_caught_when_planted(tmp_path):
    root = _plant(
        tmp_path,
        {
            "__init__.py": "",
            "posterior.py": "def view(p):\n    from loadbayes.report.text import fmt\n",
            "report/__init__.py": "",
            "report/text.py": "from loadbayes.posterior import view\nfmt = str\n",
            "plots/__init__.py": "",
            "plots/fit.py": "from loadbayes.fit.naming import names\n",  # downward: fine
            "models/__init__.py": "",
            "models/composite.py": "from loadbayes.measurements.record import Event\n",
            "measurements/__init__.py": "",
            "measurements/record.py": "Event = tuple\n",
            "measurements/events.py": "if True:\n    from ..models import composite\n",
            "fit/__init__.py": "",
            "fit/naming.py": "names = ()\n",
            "fit/table.py": "def table():\n    import loadbayes.plots.fit\n",
            "fit/composite/__init__.py": "from ...report import text\n",
        },
    )
    imports, _ = _scan(root)
    found = {rule: forbidden_imports(imports, rule) for rule in FORBIDDEN}
    assert found == {
        "fit imports no report or plots": {
            "loadbayes.fit.table -> loadbayes.plots.fit",
            "loadbayes.fit.composite -> loadbayes.report",
            "loadbayes.fit.composite -> loadbayes.report.text",
        },
        "measurements imports no models": {
            "loadbayes.measurements.events -> loadbayes.models",
            "loadbayes.measurements.events -> loadbayes.models.composite",
        },
        "posterior imports no report": {"loadbayes.posterior -> loadbayes.report.text"},
    }


# --- No long module without the one idea that needs it ------------------------------

#: A module longer than this says, in its docstring, which one idea needs its length.
LONG_MODULE = 450


def silent_long_modules(root: Path, limit: int = LONG_MODULE) -> list[str]:
    """The modules under ``root`` over ``limit`` lines whose docstring has no "one idea"."""
    bad = []
    for path in sorted(root.rglob("*.py")):
        text = path.read_text(encoding="utf-8")
        if len(text.splitlines()) <= limit:
            continue
        doc = ast.get_docstring(ast.parse(text)) or ""
        if "one idea" not in " ".join(doc.lower().split()):
            bad.append(path.relative_to(root).as_posix())
    return bad


def test_every_long_module_says_which_one_idea_needs_it():
    assert silent_long_modules(SRC) == []


def test_the_long_module_rule_catches_a_planted_module(tmp_path):
    body = "x = 1\n" * (LONG_MODULE + 1)
    root = _plant(
        tmp_path,
        {
            "__init__.py": "",
            "fit/__init__.py": "",
            "fit/short.py": '"""Short."""\n' + "x = 1\n" * 10,
            "fit/said.py": '"""Long.\n\nONE IDEA needs these lines: the sampler.\n"""\n' + body,
            "fit/wrapped.py": '"""Long.\n\nIts length is one\nidea: the sampler.\n"""\n' + body,
            "fit/silent.py": '"""Long, and silent on why."""\n' + body,
            "fit/comment.py": "# one idea, but in a comment\n" + body,
            "io/tables.py": body,
            "io/edge.py": "x = 1\n" * LONG_MODULE,  # at the limit: not over it
        },
    )
    assert silent_long_modules(root) == ["fit/comment.py", "fit/silent.py", "io/tables.py"]


# --- The map names every module, and only modules that exist -------------------------

MAP = Path(__file__).parents[2] / "docs" / "architecture.md"
MAP_SECTION = "## The packages and top-level modules"
#: Files that are no module of their own to name: a package, its ``-m`` entry, the version.
UNNAMED = ("__init__.py", "__main__.py", "_version.py")


def map_names(text: str) -> set[str]:
    """The module paths (relative to the package) that the map's module table names.

    Each row of the table under :data:`MAP_SECTION` is one package: its first cell names it
    in backticks ending in ``/`` (``fit/composite/``; no such name: the top level), and
    its second cell names each of its modules by file name in backticks (``driver.py``).
    """
    section = text.split(MAP_SECTION, 1)[1].split("\n## ", 1)[0]
    names = set()
    for line in section.splitlines():
        cells = line.split("|")
        if not line.startswith("|") or len(cells) < 4 or set(cells[1].strip()) <= set("-"):
            continue
        package = next((t for t in re.findall(r"`([^`]+)`", cells[1]) if t.endswith("/")), "")
        names |= {
            package + t
            for t in re.findall(r"`([^`]+)`", "|".join(cells[2:]))
            if re.fullmatch(r"\w+\.py", t)
        }
    return names


def module_files(root: Path) -> set[str]:
    """Every module file under ``root`` (relative paths), :data:`UNNAMED` aside."""
    return {p.relative_to(root).as_posix() for p in root.rglob("*.py") if p.name not in UNNAMED}


def map_errors(text: str, root: Path) -> dict[str, list[str]]:
    """The modules the map leaves out, and the names in it that are no module."""
    named, files = map_names(text), module_files(root)
    return {"not named": sorted(files - named), "no such module": sorted(named - files)}


def test_the_map_names_every_module_and_no_other():
    errors = map_errors(MAP.read_text(encoding="utf-8"), SRC)
    assert errors == {"not named": [], "no such module": []}


def test_the_map_rule_catches_a_planted_module_and_a_stale_name(tmp_path):
    root = _plant(
        tmp_path,
        {
            "__init__.py": "",
            "__main__.py": "",
            "_version.py": "",
            "cli.py": "",
            "fit/__init__.py": "",
            "fit/core.py": "",
            "fit/composite/__init__.py": "",
            "fit/composite/driver.py": "",
            "fit/composite/new.py": "",  # not in the map
            "models/zip.py": "",  # its package has no row
        },
    )
    text = textwrap.dedent(
        """\
        ## The packages and top-level modules

        | package | its modules |
        | --- | --- |
        | top level | `cli.py` (the commands) |
        | `fit/` | `core.py`, and `composite/` below; `models/zip.py` is not named here |
        | `fit/composite/` | `driver.py`, `table.py` (gone) |

        ## One composite fit

        | `models/` | `zip.py` (outside the section: not counted) |
        """
    )
    assert map_errors(text, root) == {
        "not named": ["fit/composite/new.py", "models/zip.py"],
        "no such module": ["fit/composite/table.py"],
    }


#: Modules reached by name (``importlib.import_module("loadbayes. ...")``), which the
#: import map does not see, each with why: a plugin or backend looked up at the call.
#: A new one must be added here with its reason (and to docs/architecture.md's arrows).
BY_NAME = {
    ("loadbayes.posterior", "loadbayes.plots"): "Posterior.plot() reaches its drawing "
    "backend at the call, as pandas' .plot does: plots/ reads a Posterior, so a plain "
    "import would be an import circle",
}


def imports_by_name(root) -> set[tuple[str, str]]:
    """``(importer, module)`` of every ``importlib.import_module("loadbayes...")`` literal."""
    out = set()
    for path in sorted(root.rglob("*.py")):
        rel = path.relative_to(root.parent).with_suffix("")
        module = ".".join(p for p in rel.parts if p != "__init__")
        for m in re.finditer(r'import_module\(\s*"(loadbayes[\w.]*)"', path.read_text("utf-8")):
            out.add((module, m.group(1)))
    return out


def test_modules_reached_by_name_are_the_listed_ones():
    import loadbayes

    root = Path(loadbayes.__file__).parent
    assert imports_by_name(root) == set(BY_NAME)


def test_the_by_name_rule_catches_a_planted_lookup(tmp_path):
    pkg = tmp_path / "loadbayes"
    (pkg / "fit").mkdir(parents=True)
    (pkg / "fit" / "x.py").write_text('importlib.import_module("loadbayes.report.text")\n')
    assert imports_by_name(pkg) == {("loadbayes.fit.x", "loadbayes.report.text")}


def test_the_griddyn_harness_imports_nothing_else_of_loadbayes():
    # GridDyn is the tests' independent simulator: its harness writes GridDyn's input from
    # its own description of the load and never reaches the package's models or fits.
    harness = {m: deps for m, deps in IMPORTS.items() if m.startswith("loadbayes.cases.griddyn")}
    assert len(harness) >= 3
    for module, deps in harness.items():
        other = {d for d in deps if d.startswith("loadbayes") and
                 not d.startswith("loadbayes.cases.griddyn")}  # fmt: skip
        assert not other, (module, sorted(other))
