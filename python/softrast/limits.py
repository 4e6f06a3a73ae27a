"""The memory budget: the most bytes softrast allocates for one framebuffer, image or mesh.

Files and arguments come from anywhere; a 69-byte PNG may claim 40000x40000 pixels. Every size
that softrast can know before allocating (the outputs of a render, an image's header, a mesh
file's declared element counts, a mesh's arrays, a texture's mip chain and decoded copy) is checked against this budget first, and a
request above it raises ValueError instead of taking the process down.
"""
from __future__ import annotations

import operator
import threading
from typing import Any

__all__ = ["DEFAULT_MEMORY_BUDGET", "check_budget", "get_memory_budget", "set_memory_budget"]

DEFAULT_MEMORY_BUDGET = 4 * 2**30  # 4 GiB, the core's own framebuffer limit (MAX_FRAMEBUFFER_BYTES)

_lock = threading.Lock()
_budget = DEFAULT_MEMORY_BUDGET


def set_memory_budget(nbytes: int) -> None:
    """Set the largest allocation (in bytes) that a render, ``imread`` or ``load_mesh`` may make.

    Process-wide. The core still refuses framebuffers above ``_core.MAX_FRAMEBUFFER_BYTES``.

    Parameters
    ----------
    nbytes : int
        Positive.

    Raises
    ------
    TypeError
        For a non-int (bool included).
    ValueError
        For nbytes <= 0.
    """
    global _budget
    if isinstance(nbytes, bool):
        raise TypeError("nbytes must be an int, got bool")
    try:
        value = operator.index(nbytes)
    except TypeError:
        raise TypeError(f"nbytes must be an int, got {type(nbytes).__name__}") from None
    if value <= 0:
        raise ValueError(f"nbytes must be positive, got {value}")
    with _lock:
        _budget = value


def get_memory_budget() -> int:
    """The current memory budget in bytes (default 4 GiB).

    Returns
    -------
    int
    """
    return _budget


def _human(nbytes: int) -> str:
    for unit, size in (("GiB", 2**30), ("MiB", 2**20), ("KiB", 2**10)):
        if nbytes >= size:
            return f"{nbytes / size:.1f} {unit}"
    return f"{nbytes} B"


def check_budget(nbytes: Any, what: str) -> None:
    """Raise ValueError if ``nbytes`` exceeds the budget.

    Parameters
    ----------
    nbytes : int
        The bytes an allocation needs.
    what : str
        Names the argument or file in the error.

    Raises
    ------
    ValueError
        If ``nbytes`` exceeds ``get_memory_budget()``.
    """
    needed, budget = int(nbytes), _budget
    if needed > budget:
        raise ValueError(
            f"{what} needs {needed} bytes ({_human(needed)}), more than the memory budget of "
            f"{budget} bytes ({_human(budget)}); raise it with softrast.set_memory_budget(nbytes) "
            "if this is intended")
