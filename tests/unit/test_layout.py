"""The layout's rules, checked on the code's own imports (docs/architecture.md).

Arrows point down only: commands -> studies -> fit / baselines -> models & inference ->
core -> io. Models are physics (they never import a sampler, a driver or Posterior),
samplers know no physics, and the library never imports the studies or the CLI.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

import loadbayes

SRC = Path(loadbayes.__file__).parent


def _module_name(path: Path) -> str:
    rel = path.relative_to(SRC.parent).with_suffix("")
    parts = list(rel.parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def _imports() -> dict[str, set[str]]:
    """Every ``loadbayes.*`` module each module imports, at any depth of the file."""
    out: dict[str, set[str]] = {}
    for path in SRC.rglob("*.py"):
        name = _module_name(path)
        found: set[str] = set()
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
                if node.module.startswith("loadbayes"):
                    found.add(node.module)
                    for alias in node.names:  # "from loadbayes.x import y" may be a module
                        found.add(f"{node.module}.{alias.name}")
            elif isinstance(node, ast.Import):
                found.update(a.name for a in node.names if a.name.startswith("loadbayes"))
        out[name] = found
    modules = set(out)
    return {k: {m for m in v if m in modules} for k, v in out.items()}


IMPORTS = _imports()


def _under(module: str, *packages: str) -> bool:
    return any(module == p or module.startswith(p + ".") for p in packages)


@pytest.mark.parametrize(
    ("package", "allowed"),
    [
        ("loadbayes.core", ("loadbayes.core",)),
        ("loadbayes.models", ("loadbayes.models", "loadbayes.core", "loadbayes.io.errors")),
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
