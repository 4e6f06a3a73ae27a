"""The package's structure: no import circles, no module over 500 lines, and no function-local
imports of the package's own modules (except the CLI's documented start-up laziness). Each module
is imported alone in a fresh interpreter, without ``softrast/__init__`` pulling in the rest, and
must load exactly the modules its imports name."""
from __future__ import annotations

import ast
import json
import pathlib
import subprocess
import sys

import pytest

import softrast

PACKAGE = pathlib.Path(softrast.__file__).resolve().parent
MAX_LINES = 500
LAZY_ALLOWED = {"softrast.cli"}  # `softrast --help` must not import the renderer


def _modules() -> dict[str, pathlib.Path]:
    out = {}
    for path in sorted(PACKAGE.rglob("*.py")):
        parts = path.relative_to(PACKAGE).with_suffix("").parts
        if parts[-1] == "__init__":
            parts = parts[:-1]
        out[".".join(("softrast",) + parts)] = path
    return out


MODULES = _modules()


def _resolve(module: str, is_package: bool, node: ast.ImportFrom) -> list[str]:
    """The package modules an ``from ... import ...`` statement in ``module`` loads."""
    if node.level:
        base = module.split(".") if is_package else module.split(".")[:-1]
        base = base[: len(base) - (node.level - 1)]
        target = ".".join(base + ([node.module] if node.module else []))
    else:
        target = node.module or ""
    if not target.startswith("softrast"):
        return []
    found = [target] if target in MODULES or target == "softrast._core" else []
    for alias in node.names:  # `from . import _core`, `from .files import load`
        sub = f"{target}.{alias.name}"
        if sub in MODULES or sub == "softrast._core":
            found.append(sub)
    return found


def _imports(module: str) -> tuple[set[str], list[tuple[int, str]]]:
    """(package modules imported at module level, [(line, module)] imported inside functions)."""
    path = MODULES[module]
    tree = ast.parse(path.read_text(encoding="utf-8"))
    top: set[str] = set()
    local: list[tuple[int, str]] = []

    def visit(node: ast.AST, in_function: bool) -> None:
        for child in ast.iter_child_nodes(node):
            inner = in_function or isinstance(child, (ast.FunctionDef, ast.AsyncFunctionDef, ast.Lambda))
            if isinstance(child, ast.ImportFrom):
                names = _resolve(module, path.name == "__init__.py", child)
            elif isinstance(child, ast.Import):
                names = [a.name for a in child.names if a.name.startswith("softrast")]
            else:
                visit(child, inner)
                continue
            for name in names:
                (local.append((child.lineno, name)) if in_function else top.add(name))

    visit(tree, False)
    return top - {module}, local


GRAPH = {m: _imports(m)[0] for m in MODULES}


def test_no_function_local_imports_of_the_package():
    found = [f"{m}:{line} imports {name}" for m in MODULES if m not in LAZY_ALLOWED
             for line, name in _imports(m)[1]]
    assert not found, "\n".join(found)


def test_no_import_circles():
    # Tarjan-free check: a depth-first search that meets a module on its own stack found a circle.
    state: dict[str, int] = {}
    circles = []

    def dfs(m: str, stack: list[str]) -> None:
        state[m] = 1
        for n in sorted(GRAPH.get(m, ())):
            if n == "softrast" or n not in GRAPH:
                continue
            if state.get(n) == 1:
                circles.append(stack[stack.index(n):] + [n])
            elif n not in state:
                dfs(n, stack + [n])
        state[m] = 2

    for m in sorted(GRAPH):
        if m not in state:
            dfs(m, [m])
    assert not circles, "\n".join(" -> ".join(c) for c in circles)


@pytest.mark.parametrize("module", sorted(MODULES))
def test_module_size(module):
    lines = MODULES[module].read_text(encoding="utf-8").count("\n")
    assert lines <= MAX_LINES, f"{MODULES[module].name}: {lines} lines"


def _closure(module: str) -> set[str]:
    seen: set[str] = set()
    todo = [module]
    while todo:
        m = todo.pop()
        if m in seen:
            continue
        seen.add(m)
        parts = m.split(".")
        todo += [".".join(parts[:k]) for k in range(2, len(parts))]  # parent packages load first
        todo += [n for n in GRAPH.get(m, ()) if n != "softrast"]
    return seen


_ALONE = """
import importlib, json, sys, types
pkg = types.ModuleType("softrast")
pkg.__path__ = [sys.argv[1]]
sys.modules["softrast"] = pkg  # the package without its __init__: nothing else is pulled in
for name in sys.argv[2:]:
    importlib.import_module(name)
print(json.dumps(sorted(m for m in sys.modules if m.startswith("softrast."))))
"""


def test_each_module_imports_alone_and_loads_only_what_it_names():
    checked = [m for m in sorted(MODULES) if m not in ("softrast", "softrast.__main__")]
    wrong = []
    for module in checked:
        run = subprocess.run([sys.executable, "-c", _ALONE, str(PACKAGE), module],
                             capture_output=True, text=True, timeout=120)
        if run.returncode != 0:
            wrong.append(f"{module}: {run.stderr.strip().splitlines()[-1]}")
            continue
        loaded = set(json.loads(run.stdout.strip().splitlines()[-1]))
        expected = _closure(module) - {"softrast"}
        if loaded != expected:
            wrong.append(f"{module}: loads {sorted(loaded - expected)} it does not name, "
                         f"misses {sorted(expected - loaded)}")
    assert not wrong, "\n".join(wrong)
