"""The package layout: dependencies point one way and the public surface stays light.

Every import counts here, module-level, function-level and under ``TYPE_CHECKING``: a cycle
hidden in a function is still a cycle a reader has to untangle.
"""

from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

import blendspace_pipeline

PACKAGE = Path(blendspace_pipeline.__file__).parent
RULES = PACKAGE.parent / "rules"

# Lower layers never import higher ones (motion ← space ← checks ← build ← commands).
LAYERS = ["motion", "space", "checks", "pipeline", "commands"]


def _modules() -> dict[str, Path]:
    found = {}
    for path in PACKAGE.rglob("*.py"):
        parts = list(path.relative_to(PACKAGE.parent).with_suffix("").parts)
        if parts[-1] == "__init__":
            parts = parts[:-1]
        found[".".join(parts)] = path
    return found


def _imports(name: str, path: Path, modules: dict[str, Path]) -> set[str]:
    tree = ast.parse(path.read_text(encoding="utf-8"))
    is_package = path.name == "__init__.py"
    base = name if is_package else name.rpartition(".")[0]
    targets: set[str] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            targets.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                anchor = base.split(".")
                anchor = anchor[: len(anchor) - (node.level - 1)]
                module = ".".join([*anchor, node.module] if node.module else anchor)
            else:
                module = node.module or ""
            targets.add(module)
            targets.update(f"{module}.{alias.name}" for alias in node.names)
    edges = set()
    for target in targets:
        # Importing a.b.c runs a/__init__ and a/b/__init__ too.
        parts = target.split(".")
        for end in range(1, len(parts) + 1):
            candidate = ".".join(parts[:end])
            if candidate in modules and candidate != name and not name.startswith(candidate + "."):
                edges.add(candidate)
    return edges


def _graph() -> dict[str, set[str]]:
    modules = _modules()
    return {name: _imports(name, path, modules) for name, path in modules.items()}


def _cycle(graph: dict[str, set[str]]) -> list[str] | None:
    state: dict[str, int] = {}
    stack: list[str] = []

    def visit(node: str) -> list[str] | None:
        state[node] = 1
        stack.append(node)
        for nxt in sorted(graph.get(node, ())):
            if state.get(nxt) == 1:
                return [*stack[stack.index(nxt) :], nxt]
            if nxt not in state and (found := visit(nxt)):
                return found
        stack.pop()
        state[node] = 2
        return None

    for node in sorted(graph):
        if node not in state and (found := visit(node)):
            return found
    return None


def test_no_import_cycle_among_the_package_modules() -> None:
    cycle = _cycle(_graph())
    assert cycle is None, " -> ".join(cycle or [])


def test_the_cycle_finder_finds_a_cycle() -> None:
    assert _cycle({"a": {"b"}, "b": {"c"}, "c": {"a"}}) == ["a", "b", "c", "a"]
    assert _cycle({"a": {"b"}, "b": set()}) is None


def test_stage_packages_depend_downwards_only() -> None:
    graph = _graph()
    bad = []
    for name, targets in graph.items():
        parts = name.split(".")
        if len(parts) < 2 or parts[1] not in LAYERS:
            continue
        level = LAYERS.index(parts[1])
        for target in targets:
            tparts = target.split(".")
            if len(tparts) > 1 and tparts[1] in LAYERS and LAYERS.index(tparts[1]) > level:
                bad.append(f"{name} imports {target}")
    assert not bad, "\n".join(sorted(bad))


def test_every_stage_folder_says_what_lives_there() -> None:
    for folder in [*LAYERS, "readers", "writers", "exporters", "report", "manifest"]:
        init = PACKAGE / folder / "__init__.py"
        doc = ast.get_docstring(ast.parse(init.read_text(encoding="utf-8")))
        assert doc, f"{init} has no docstring"


def test_the_rule_api_imports_no_reader_writer_or_report() -> None:
    code = (
        "import sys, blendspace_pipeline.api;"
        "print('\\n'.join(m for m in sys.modules if m.startswith('blendspace_pipeline')))"
    )
    loaded = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    modules = loaded.stdout.split()
    heavy = [
        m
        for m in modules
        if m.split(".")[1:2] and m.split(".")[1] in {"readers", "writers", "report", "exporters", "pipeline"}
    ]
    assert not heavy, heavy
    assert "pxr" not in loaded.stdout


def test_every_package_folder_is_installed() -> None:
    """pyproject.toml lists the packages one by one: a new folder missing there works from the
    checkout and fails in every installed copy (a pre-commit environment, a wheel)."""
    import tomllib

    listed = set(
        tomllib.loads((PACKAGE.parent / "pyproject.toml").read_text(encoding="utf-8"))["tool"]["setuptools"][
            "packages"
        ]
    )
    folders = {
        ".".join(init.parent.relative_to(PACKAGE.parent).parts)
        for init in PACKAGE.rglob("__init__.py")
        if "__pycache__" not in init.parts
    }
    assert folders - listed == set(), (
        f"add to [tool.setuptools] packages in pyproject.toml: {sorted(folders - listed)}"
    )
