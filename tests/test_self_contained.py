"""The product stands alone: nothing under tests/, examples/, benchmarks/, python/ or
.ci/ reads anything outside the repository, and every asset path they build under assets/ exists.

Three checks over every text file in those folders (binary files and Markdown prose, such as
benchmarks/RESULTS.md, a record of past runs on the team's machine that nothing reads, are
skipped):

* a text scan for references out of the tree: a relative path into the team's sibling folder
  beside the repository (SIBLING below: two dots, a slash, its name; or os.path.join of the two),
  and absolute paths into
  this machine's workspace (the folders "work" and "root" at the filesystem root, and the baseline
  venv "vbase" in "tmp"). Longer words that begin with the sibling's name do not match. This file
  spells those paths and that name in pieces, so that it passes its own scan with no exemption.
* in Python files, every path built from ``__file__`` (``Path(__file__).resolve().parents[n]``,
  ``.parent``, ``/``, ``os.path.join`` / ``dirname`` / ``abspath``, through module and function
  variables) is evaluated, and must stay inside the repository; a statement that navigates to a
  parent and names the sibling folder as a path component is flagged even where it cannot be
  evaluated.
* every evaluated path under ``assets/``, and every literal ``assets/...`` file path, exists.
"""
from __future__ import annotations

import ast
import functools
import os
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
SCANNED = ("tests", "examples", "benchmarks", "python", ".ci")
SKIP_DIRS = {"__pycache__", ".pytest_cache", "build"}
SKIP_SUFFIXES = {".md", ".pyc", ".so", ".npz", ".npy", ".png", ".exr", ".jpg"}

# Outside references, each with what it means. The paths are spelt in pieces (UP, WORK, ...) so
# that this file does not match itself. The look-behinds keep the workspace paths from matching
# inside a longer path or a URL, the look-aheads keep longer names ("workers", "rootfs") out;
# the sibling's name must be a whole path component (longer words that begin with it never match).
UP, WORK, ROOTDIR, VBASE = "." + ".", "/" + "work", "/" + "root", "/" + "tmp/vbase"
SIBLING = "sha" + "red"  # the team's folder beside the repository, which a user's clone lacks
NOT_AFTER, NOT_BEFORE = r"(?<![\w.:/~$-])", r"(?![\w.-])"
OUTSIDE = [
    (re.compile(re.escape(UP) + r"[/\\]+" + SIBLING + NOT_BEFORE),
     "a relative path into the team's folder beside the repository"),
    (re.compile(r"""(['"])""" + re.escape(UP) + r"""\1\s*,\s*(['"])""" + SIBLING + r"\2"),
     "a path joined from the parent and the team's folder"),
    (re.compile(NOT_AFTER + WORK + NOT_BEFORE), "an absolute path into this machine's workspace"),
    (re.compile(NOT_AFTER + VBASE + NOT_BEFORE), "an absolute path into the baseline venv"),
    (re.compile(NOT_AFTER + ROOTDIR + NOT_BEFORE), "an absolute path into root's home"),
]
ASSET_LITERAL = re.compile(r"(?<![\w./-])assets/[\w./-]*\w\.\w+")


def scanned_files() -> list[Path]:
    """Every text file under the scanned folders, walked on disk (new, untracked files count)."""
    files = []
    for top in SCANNED:
        for dirpath, dirnames, filenames in os.walk(ROOT / top):
            dirnames[:] = sorted(d for d in dirnames if d not in SKIP_DIRS and not d.endswith(".egg-info"))
            for name in sorted(filenames):
                path = Path(dirpath) / name
                if path.suffix.lower() in SKIP_SUFFIXES:
                    continue
                data = path.read_bytes()
                if b"\0" in data[:8192]:
                    continue
                try:
                    data.decode("utf-8")
                except UnicodeDecodeError:
                    continue
                files.append(path)
    return files


FILES = scanned_files()


def rel(path: Path) -> str:
    return path.relative_to(ROOT).as_posix()


def inside(path: str) -> bool:
    p = Path(os.path.normpath(path))
    return p == ROOT or ROOT in p.parents


# ------------------------------------------------------------------ evaluating Python paths

class Anchored(str):
    """A path string derived from __file__ (so from where the file is in the repository)."""


def is_component_sibling(value: str) -> bool:
    return SIBLING in re.split(r"[/\\]+", value)


class PathEvaluator:
    """Evaluates the path expressions of one Python file that are built from ``__file__``, in
    source order, through module and function variables. Anything else evaluates to None (a
    plain str constant to itself)."""

    def __init__(self, path: Path, tree: ast.Module) -> None:
        self.path = path
        self.found: list[tuple[int, str]] = []  # (line, normalised path) of every anchored value
        self.flagged: list[tuple[int, str]] = []
        self.scopes: list[dict[str, object]] = [{}]
        self.body(tree.body)

    # scopes and statements
    def lookup(self, name: str):
        for scope in reversed(self.scopes):
            if name in scope:
                return scope[name]
        return None

    def body(self, stmts) -> None:
        for stmt in stmts:
            self.stmt(stmt)

    def stmt(self, node: ast.stmt) -> None:
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.Lambda)):
            for d in node.decorator_list:
                self.expr(d)
            scope = {a.arg: None for a in ast.walk(node.args) if isinstance(a, ast.arg)}
            for default in node.args.defaults + [d for d in node.args.kw_defaults if d]:
                self.expr(default)
            self.scopes.append(scope)
            self.body(node.body)
            self.scopes.pop()
            return
        if isinstance(node, ast.ClassDef):
            self.scopes.append({})
            self.body(node.body)
            self.scopes.pop()
            return
        self.check_sibling_statement(node)
        own = [c for c in ast.iter_child_nodes(node) if not isinstance(c, ast.stmt)]
        if isinstance(node, (ast.Assign, ast.AnnAssign)) and node.value is not None:
            value = self.expr(node.value)
            targets = node.targets if isinstance(node, ast.Assign) else [node.target]
            for t in targets:
                self.bind(t, value)
            own = [c for c in own if c is not node.value]
        for child in own:
            self.expr(child)
        for field in ("body", "orelse", "finalbody"):
            self.body(getattr(node, field, []) or [])
        for handler in getattr(node, "handlers", []) or []:
            self.body(handler.body)

    def bind(self, target, value) -> None:
        if isinstance(target, ast.Name):
            self.scopes[-1][target.id] = value
        elif isinstance(target, (ast.Tuple, ast.List)):
            for t in target.elts:
                self.bind(t, None)

    def check_sibling_statement(self, node: ast.stmt) -> None:
        """A statement (without its nested statements) that goes to a parent and names SIBLING."""
        nodes, stack = [], [c for c in ast.iter_child_nodes(node) if not isinstance(c, ast.stmt)]
        while stack:
            n = stack.pop()
            nodes.append(n)
            stack.extend(c for c in ast.iter_child_nodes(n) if not isinstance(c, ast.stmt))
        strings = [n.value for n in nodes if isinstance(n, ast.Constant) and isinstance(n.value, str)]
        up = any(isinstance(n, ast.Attribute) and n.attr in ("parent", "parents", "pardir", "dirname")
                 or isinstance(n, ast.Name) and n.id in ("dirname", "pardir") for n in nodes)
        up = up or any(s == ".." or s.startswith(("../", "..\\")) for s in strings)
        if up and any(is_component_sibling(s) for s in strings):
            self.flagged.append((node.lineno, "a path from a parent directory into the team's folder"))

    # expressions
    def expr(self, node):
        """The value of node: an Anchored path, a str constant, or None. Visits every subexpression."""
        value = self._expr(node)
        if isinstance(value, Anchored):
            self.found.append((getattr(node, "lineno", 0), os.path.normpath(value)))
        return value

    def _expr(self, node):
        if isinstance(node, ast.Constant):
            return node.value if isinstance(node.value, str) else None
        if isinstance(node, ast.Name):
            if node.id == "__file__":
                return Anchored(self.path)
            return self.lookup(node.id)
        if isinstance(node, ast.BinOp) and isinstance(node.op, ast.Div):
            left, right = self.expr(node.left), self.expr(node.right)
            if isinstance(left, Anchored) and isinstance(right, str):
                return Anchored(os.path.join(left, right))
            return None
        if isinstance(node, ast.Attribute):
            base = self.expr(node.value)
            if isinstance(base, Anchored) and node.attr == "parent":
                return Anchored(os.path.dirname(os.path.normpath(base)))
            if isinstance(base, Anchored) and node.attr == "parents":
                return ("parents", base)
            return None
        if isinstance(node, ast.Subscript):
            base = self.expr(node.value)
            index = node.slice  # Python >= 3.9: the index expression itself
            self.expr(index)
            if isinstance(base, tuple) and isinstance(index, ast.Constant) and isinstance(index.value, int):
                return Anchored(os.path.normpath(os.path.join(base[1], *[".."] * (index.value + 1))))
            return None
        if isinstance(node, ast.Call):
            func = node.func
            args = [self.expr(a) for a in node.args]
            for k in node.keywords:
                self.expr(k.value)
            name = func.attr if isinstance(func, ast.Attribute) else func.id if isinstance(func, ast.Name) else ""
            if isinstance(func, ast.Attribute) and name in ("resolve", "absolute", "expanduser"):
                base = self.expr(func.value)
                return base if isinstance(base, Anchored) else None
            self.expr(func)
            if name in ("Path", "PurePath", "abspath", "realpath", "normpath", "str", "fspath") and len(args) == 1:
                return args[0] if isinstance(args[0], Anchored) else None
            if name == "dirname" and len(args) == 1 and isinstance(args[0], Anchored):
                return Anchored(os.path.dirname(os.path.normpath(args[0])))
            if name == "join" and args and isinstance(args[0], Anchored) and all(isinstance(a, str) for a in args):
                return Anchored(os.path.join(*args))
            return None
        for child in ast.iter_child_nodes(node):
            if isinstance(child, ast.expr):
                self.expr(child)
            elif isinstance(child, ast.comprehension):
                for c in ast.iter_child_nodes(child):
                    self.expr(c)
            elif isinstance(child, ast.arguments):
                pass
        if isinstance(node, ast.Lambda):
            self.expr(node.body)
        return None


@functools.lru_cache(maxsize=None)  # three checks read every file's paths: parsed once
def python_paths(path: Path) -> PathEvaluator:
    return PathEvaluator(path, ast.parse(path.read_text(encoding="utf-8"), filename=str(path)))


PY_FILES = [p for p in FILES if p.suffix in (".py", ".pyi")]


def outside_references(path: Path) -> list[str]:
    """Every reference out of the repository in one file, as 'file:line: what: text'."""
    text = path.read_text(encoding="utf-8")
    lines = text.splitlines()
    hits = []
    for no, line in enumerate(lines, 1):
        for pattern, what in OUTSIDE:
            if pattern.search(line):
                hits.append(f"{rel(path)}:{no}: {what}: {line.strip()}")
    if path.suffix in (".py", ".pyi"):
        ev = python_paths(path)
        for no, what in ev.flagged:
            hits.append(f"{rel(path)}:{no}: {what}: {lines[no - 1].strip()}")
        outside: dict[int, str] = {}  # per line, the longest path outside (the outermost value)
        for no, value in ev.found:
            if not inside(value) and len(value) > len(outside.get(no, "")):
                outside[no] = value
        for no, value in outside.items():
            hits.append(f"{rel(path)}:{no}: a path built from __file__ outside the repository "
                        f"({value}): {lines[no - 1].strip()}")
    return sorted(set(hits))


# ------------------------------------------------------------------ the checks


def test_the_scan_covers_the_tree():
    names = {rel(p) for p in FILES}
    assert "tests/test_self_contained.py" in names and "benchmarks/bench_vs_pyrender.py" in names
    assert any(n.startswith(".ci/") for n in names) and any(n.startswith("python/softrast/") for n in names)
    assert any(n.startswith("examples/") for n in names)


@pytest.mark.parametrize("path", FILES, ids=rel)
def test_nothing_reaches_outside_the_repository(path):
    hits = outside_references(path)
    assert not hits, "reads outside the repository:\n" + "\n".join(hits)


def test_every_asset_path_exists():
    missing = []
    for path in FILES:
        text = path.read_text(encoding="utf-8")
        for no, line in enumerate(text.splitlines(), 1):
            for m in ASSET_LITERAL.finditer(line):
                if not (ROOT / m.group(0)).exists():
                    missing.append(f"{rel(path)}:{no}: {m.group(0)}")
        if path.suffix in (".py", ".pyi"):
            for no, value in python_paths(path).found:
                p = Path(value)
                if (ROOT / "assets") in [p, *p.parents] and not p.exists():
                    missing.append(f"{rel(path)}:{no}: {p.relative_to(ROOT).as_posix()}")
    assert not missing, "asset paths that do not exist:\n" + "\n".join(sorted(set(missing)))


def test_the_tests_do_read_the_assets():
    """The evaluator sees the asset paths the tests are known to build (it is not blind)."""
    seen = {Path(v).relative_to(ROOT).as_posix() for p in PY_FILES for _, v in python_paths(p).found
            if inside(v) and Path(v) != ROOT}
    assert {"assets/meshes/spot.obj", "assets/meshes/spot_texture.png"} <= seen
    assert "benchmarks/soak.py" in seen  # tests/test_mesh.py: SPOT_PATH.parents[2] / "benchmarks"


# ------------------------------------------------------------------ the scan itself

# Probes, with @UP@, @WORK@, @VBASE@ and @ROOT@ for the paths (see OUTSIDE).
PROBE = ROOT / "tests" / "_probe_self_contained.py"  # evaluated as if it were a file in tests/


def spell(text: str) -> str:
    return (text.replace("@UP@", UP).replace("@WORK@", WORK).replace("@VBASE@", VBASE)
            .replace("@ROOT@", ROOTDIR).replace("@SIB@", SIBLING))


def probe_hits(text: str) -> list[str]:
    """What the scan flags in a probe: text matches, parent-and-sibling statements, paths outside."""
    hits = [what for line in text.splitlines() for pattern, what in OUTSIDE if pattern.search(line)]
    try:
        tree = ast.parse(text)
    except SyntaxError:
        return hits
    ev = PathEvaluator(PROBE, tree)
    return hits + [w for _, w in ev.flagged] + [v for _, v in ev.found if not inside(v)]


@pytest.mark.parametrize("text", [
    'SIB = ROOT.parent / "@SIB@" / "assets"',  # ROOT unknown here: the parent-statement rule
    'box = pathlib.Path(__file__).resolve().parents[2] / "@SIB@" / "assets" / "x.gltf"',
    'A = os.path.join(os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__)))),\n'
    '                 "@SIB@", "assets")',
    'p = Path("@UP@/@SIB@/assets/spot.obj")',
    'p = os.path.join("@UP@", "@SIB@", "assets")',
    'v = "@WORK@/venv-base/bin/python"',
    'cd @WORK@/main && make',
    'PY = "@VBASE@/bin/python"',
    "cfg = '@ROOT@/.config/x'",
    'here = Path(__file__).resolve().parent\nup = here.parent.parent / "data"',  # any folder outside
    'def f(root):\n    return os.path.dirname(root) + "/@SIB@"\n',
])
def test_the_scan_flags(text):
    assert probe_hits(spell(text)), spell(text)


@pytest.mark.parametrize("text", [
    "// std::shared_ptr<Tile> tile;",
    "# a Mesh shared by its instances; shared edges clipped identically",
    'path = tmp_path / "shared.glb"',
    'SPOT = Path(__file__).resolve().parents[1] / "assets" / "meshes" / "spot.obj"',
    'SPOT = Path(__file__).resolve().parents[1] / "assets" / "meshes" / "spot.obj"\n'
    'soak = SPOT.parents[2] / "benchmarks" / "soak.py"',
    'parent = str(pathlib.Path(sr.__file__).resolve().parent.parent)',
    'venv="${SOFTRAST_ASAN_VENV:-/tmp/softrast-asan}"',
    'url = "https://example.org@WORK@@ROOT@/x"; d = "data/network@ROOT@fs"; n = "@WORK@ers"',
    "from this file's @UP@/python (the new build)",
])
def test_the_scan_passes(text):
    assert not probe_hits(spell(text)), spell(text)
