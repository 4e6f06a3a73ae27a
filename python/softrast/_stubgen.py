"""Writes ``_core.pyi``, the type stub of the compiled module, from the module itself.

    python -m softrast._stubgen [PATH]           # writes the stub (default: the repository's
                                                 # python/softrast/_core.pyi, run from its root)
    python -m softrast._stubgen --check [PATH]   # exit 1 when the stub at PATH differs

Nothing in the stub is written by hand, so it cannot drift from the bindings (cpp/bind/):
constants and their comments come from ``_core.CONSTANT_DOCS``; the records (Material, Light,
Draw, Primitive) from ``_core.RECORDS`` (each field's name, type and doc, as bind.hpp's Record
declares it); the render's options from ``_core.RENDER_OPTIONS`` (a TypedDict); functions,
methods and properties from the signatures pybind11 writes into their docstrings.
tests/test_stub.py fails when the committed stub is not what this writes.
"""
from __future__ import annotations

import pathlib
import re
import sys
from typing import Any

from . import _core

STUB = pathlib.Path("python/softrast/_core.pyi")  # from the repository's root

_HEADER = '''"""Type stub for the private compiled module ``softrast._core`` (cpp/bind/).

Written by ``python -m softrast._stubgen`` from the module itself (signatures as pybind11 {pybind11}
spells them): do not edit.
Users do not call this module directly: ``softrast.Renderer`` and ``softrast.Mesh`` wrap it.

Conventions shared with the Python layer
----------------------------------------
* view space is OpenGL's: x right, y up, the camera looks down -z.
* ``proj`` maps view space to clip space; NDC = clip.xyz / clip.w with x right, y up.
* window (pixel) space: x_win = (ndc_x + 1) / 2 * width, y_win = (1 - ndc_y) / 2 * height,
  so row 0 is the top of the image and the centre of pixel (row i, col j) is (j + 0.5, i + 0.5).
* depth output = distance along the camera's viewing axis (-z_view) in scene units; 0 = background.
"""
import collections.abc
import typing
from typing import Any, TypedDict

import numpy
import numpy.typing
'''


def pybind11_version() -> str:
    """The installed pybind11's version (the build's, as .ci/install builds without isolation)."""
    try:
        from importlib.metadata import version

        return version("pybind11")
    except Exception:  # not installed beside the package
        return "unknown"


def _clean(sig: str) -> str:
    """A pybind11 signature's types as a stub spells them."""
    sig = sig.replace("softrast._core.", "")
    sig = sig.replace("typing.SupportsInt | typing.SupportsIndex", "int")
    sig = sig.replace("typing.SupportsFloat | typing.SupportsIndex", "float")
    sig = sig.replace("typing.SupportsFloat", "float")
    return sig


def _signatures(func: Any) -> list[str]:
    """The ``name(args) -> ret`` lines pybind11 wrote into ``func.__doc__`` (one per overload)."""
    doc = getattr(func, "__doc__", None) or ""
    name = getattr(func, "__name__", "")
    sigs = [line for line in doc.splitlines()
            if re.match(rf"^(\d+\. )?{re.escape(name)}\(.*\) -> .*$", line)]
    sigs = [re.sub(r"^\d+\. ", "", s) for s in sigs]
    if len(sigs) > 1:  # "name(*args, **kwargs)" heads an overloaded function's docstring
        sigs = [s for s in sigs if "*args, **kwargs" not in s]
    return [_clean(s) for s in sigs]


def _doc_text(func: Any) -> str:
    """The first paragraph of a docstring after its signatures."""
    lines = (getattr(func, "__doc__", None) or "").splitlines()
    text = [line for line in lines if line.strip() and "->" not in line
            and line.strip() != "Overloaded function." and "(*args, **kwargs)" not in line]
    return text[0].strip() if text else ""


def _function(func: Any, indent: str) -> list[str]:
    sigs = _signatures(func)
    doc = _doc_text(func)
    out = [f"{indent}# {doc}"] if doc and sigs else []
    for sig in sigs:
        if len(sigs) > 1:
            out.append(f"{indent}@typing.overload")
        out.append(f"{indent}def {sig}: ...")
    return out


def _property(name: str, prop: property, indent: str) -> list[str]:
    sig = _clean((prop.fget.__doc__ or "").splitlines()[0]) if prop.fget is not None else ""
    ret = sig.split("->", 1)[1].strip() if "->" in sig else "Any"
    return [f"{indent}@property", f"{indent}def {name}(self) -> {ret}: ..."]


def _record(name: str, cls: type, fields: list[tuple[str, str, str]]) -> list[str]:
    out = [f"class {name}:", f'    """{cls.__doc__}"""', "    def __init__(self, *,"]
    for field, typ, _ in fields:
        out.append(f"                 {field}: {typ} = ...,")
    out.append("                 ) -> None: ...")
    for field, typ, doc in fields:
        out.append(f"    {field}: {typ}  # {doc}")
    return out


def _class(name: str, cls: type) -> list[str]:
    out = [f"class {name}:"]
    if cls.__doc__:
        out.append(f'    """{cls.__doc__}"""')
    for attr, value in cls.__dict__.items():
        if attr.startswith("_") and attr not in ("__init__", "__reduce__"):
            continue
        if isinstance(value, property):
            out += _property(attr, value, "    ")
        elif callable(value):
            out += _function(value, "    ")
    return out


def _literal_type(value: Any) -> str:
    if isinstance(value, bool):
        return "bool"
    if isinstance(value, int):
        return "int"
    if isinstance(value, float):
        return "float"
    if isinstance(value, str):
        return "str"
    if isinstance(value, tuple):
        if value and all(isinstance(v, tuple) for v in value):
            return "tuple[tuple[Any, ...], ...]"
        if value and all(isinstance(v, str) for v in value):
            return "tuple[str, ...]"
        if value and all(isinstance(v, dict) for v in value):
            return "tuple[dict[str, Any], ...]"
        return "tuple[Any, ...]"
    if isinstance(value, dict):
        return "dict[str, Any]"
    return "Any"


# The tables this generator reads, which document the rest.
_TABLE_DOCS = {
    "CONSTANT_DOCS": "constant name -> its doc (the comments here)",
    "RECORDS": "record name -> its fields: (name, type, doc) tuples, in order",
    "RENDER_OPTIONS": "a render's options: (name, type, required, doc) tuples (RenderOptions)",
}


def generate() -> str:
    """The stub's text."""
    out = [_HEADER.replace("{pybind11}", pybind11_version())]
    docs = dict(_core.CONSTANT_DOCS, **_TABLE_DOCS)
    names = sorted(n for n in dir(_core) if not n.startswith("__"))
    for n in names:
        value = getattr(_core, n)
        if isinstance(value, type) or callable(value):
            continue
        line = f"{n}: {_literal_type(value)}"
        out.append(f"{line}  # {docs[n]}" if n in docs else line)
    out.append("")
    out.append("class RenderOptions(TypedDict, total=False):")
    out.append('    """Renderer.render\'s options, by name (RENDER_OPTIONS); the required ones first."""')
    for name, typ, required, doc in _core.RENDER_OPTIONS:
        t = f"typing.Required[{typ}]" if required else typ
        out.append(f"    {name}: {t}  # {doc}")
    out.append("")
    for n in names:
        value = getattr(_core, n)
        if isinstance(value, type):
            if n in _core.RECORDS:
                out += _record(n, value, list(_core.RECORDS[n]))
            else:
                out += _class(n, value)
            out.append("")
    for n in names:
        value = getattr(_core, n)
        if callable(value) and not isinstance(value, type):
            out += _function(value, "")
    text = "\n".join(out).rstrip() + "\n"
    return text.replace("draws: collections.abc.Sequence, options: dict",
                        "draws: collections.abc.Sequence[Draw], options: RenderOptions")


def main(argv: list[str] | None = None) -> int:
    args = sys.argv[1:] if argv is None else argv
    paths = [a for a in args if not a.startswith("--")]
    stub = pathlib.Path(paths[0]) if paths else STUB
    text = generate()
    if "--check" in args:
        if not stub.is_file() or stub.read_text() != text:
            print(f"{stub} is out of date: run python -m softrast._stubgen", file=sys.stderr)
            return 1
        return 0
    if not stub.parent.is_dir():
        print(f"{stub.parent} does not exist: run from the repository's root, or give a path",
              file=sys.stderr)
        return 2
    stub.write_text(text)
    print(f"wrote {stub}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
