"""Mesh-file checks made before trimesh parses anything.

trimesh trusts headers: a 200-byte PLY that declares 2**31 vertices must be refused from the
header, with the file named, before any parsing. And it reads truncated or inconsistent text files
silently as partial meshes, so where a format states counts (PLY, OFF, binary STL) they are checked
against the data, and where it does not (OBJ, ASCII STL) a visibly cut file is refused. Text
formats are scanned once, 1 MiB at a time: linear in the file, bounded in memory. glTF and GLB
are checked by ``softrast.files.gltf_file``.
"""
from __future__ import annotations

import os
import re
import struct

import numpy as np

from ..limits import check_budget

__all__ = ["check_mesh_file"]


_PLY_SIZES = {"char": 1, "int8": 1, "uchar": 1, "uint8": 1, "short": 2, "int16": 2, "ushort": 2,
              "uint16": 2, "int": 4, "int32": 4, "uint": 4, "uint32": 4, "float": 4, "float32": 4,
              "double": 8, "float64": 8}


_PLY_MAX_HEADER = 1 << 20


_VALUE_BYTES = 8  # trimesh converts every parsed value to float64 / int64


_CHUNK = 1 << 20  # scans read 1 MiB at a time: memory stays bounded whatever the file's size


_MAX_ROW = 1 << 16  # a row (one line of a text format) is read whole only up to 64 KiB


def _corrupt(path_str: str, what: str) -> ValueError:
    return ValueError(f"could not load mesh {path_str!r}: {what}")


def _check_ply(path_str: str, size: int) -> int:
    with open(path_str, "rb") as f:
        head = f.read(_PLY_MAX_HEADER)
    end = head.find(b"end_header")
    if not head.startswith(b"ply") or end < 0:
        raise _corrupt(path_str, "not a PLY file or no end_header in its first 1 MiB")
    body = size - (head.index(b"\n", end) + 1 if b"\n" in head[end:] else size)
    body_start = size - body
    # (name, count, fixed bytes, number of values, list count bytes, layout: True = list)
    binary, elements = False, []
    for line in head[:end].decode("latin-1").splitlines():
        words = line.split()
        try:
            if words[:1] == ["format"]:
                binary = words[1] != "ascii"
            elif words[:1] == ["element"]:
                elements.append([words[1], int(words[2]), 0, 0, [], []])
            elif words[:1] == ["property"] and elements:
                el = elements[-1]
                el[5].append(words[1] == "list")
                if words[1] == "list":
                    el[4].append(_PLY_SIZES[words[2]])
                else:
                    el[2] += _PLY_SIZES[words[1]]
                    el[3] += 1
        except (IndexError, KeyError, ValueError):
            raise _corrupt(path_str, f"malformed PLY header line {line!r}") from None
    needed = estimate = 0
    for name, count, fixed, values, lists, _ in elements:
        if count < 0:
            raise _corrupt(path_str, f"PLY element {name!r} has a negative count {count}")
        # Smallest possible row: binary => the fixed properties and empty lists; ascii => one
        # digit and one separator per value.
        row = fixed + sum(lists) if binary else 2 * (values + len(lists))
        needed += count * row
        estimate += count * _VALUE_BYTES * (values + 4 * len(lists))  # lists: mostly triangles
        if needed > body:
            raise _corrupt(path_str, f"the PLY header declares {count} {name!r} elements, which need "
                                     f"at least {needed} bytes, but only {body} follow the header: "
                                     "truncated or corrupt")
    check_budget(estimate, f"mesh file {path_str!r} (PLY header counts)")
    if not binary:  # binary: trimesh itself requires the exact size the header implies
        _check_ply_ascii(path_str, body_start, size,
                         [(name, count, layout) for name, count, _, _, _, layout in elements])
    return sum(count for name, count, *_ in elements if name == "face")


def _scan_lines(path_str: str, start: int, size: int, wanted: list[int]) -> tuple[int, dict[int, bytes]]:
    """The number of lines in file[start:size] up to its last non-whitespace byte (so a final
    newline or trailing blank lines add none), and the text of the ``wanted`` lines (0-based,
    each cut at 64 KiB). One pass, 1 MiB at a time (measured on a 12.5 MB, 327,680-face PLY:
    17 ms and 3.3 MiB at peak, against 1.4 s for trimesh's parse)."""
    term = b"\n"  # as trimesh's PLY header reader (readline); "\r\n" ends a line too
    want = sorted(set(wanted))
    offsets: dict[int, int] = {}
    lines_before = content_lines = 0
    has_content = False
    with open(path_str, "rb") as f:
        f.seek(start)
        pos, wi = start, 0
        while pos < size:
            chunk = f.read(min(_CHUNK, size - pos))
            if not chunk:
                break
            n = chunk.count(term)
            ends = None
            while wi < len(want) and want[wi] <= lines_before + n:
                r = want[wi]  # line r starts right after the r-th line end (line 0 at `start`)
                if r == 0:
                    offsets[0] = start
                else:
                    if ends is None:
                        ends = np.flatnonzero(np.frombuffer(chunk, np.uint8) == term[0])
                    offsets[r] = pos + int(ends[r - lines_before - 1]) + 1
                wi += 1
            stripped = len(chunk.rstrip())
            if stripped:
                has_content = True
                content_lines = lines_before + chunk.count(term, 0, stripped)
            lines_before += n
            pos += len(chunk)
        rows = content_lines + 1 if has_content else 0
        text = {}
        for r, offset in offsets.items():
            if r < rows:
                f.seek(offset)
                text[r] = f.read(_MAX_ROW).split(term, 1)[0]
    return rows, text


def _row_problem(row: bytes, layout: list[bool]) -> str | None:
    """None if ``row`` holds exactly one PLY row of ``layout`` (True = a list property)."""
    words = row.split()
    try:
        values = [float(w) for w in words]
    except ValueError:
        return "a value that is not a number"
    at = 0
    for is_list in layout:
        if at >= len(values):
            return f"{len(values)} values, fewer than its properties need"
        if is_list:
            if not (values[at] >= 0 and values[at] == int(values[at])):
                return f"a list length {words[at].decode('latin-1')!r}"
            at += int(values[at])
        at += 1
    if at != len(values):
        return f"{len(values)} values where its properties need {at}"
    return None


def _check_ply_ascii(path_str: str, start: int, size: int,
                     elements: list[tuple[str, int, list[bool]]]) -> None:
    """trimesh reads an ascii PLY one element row per line and stops at the header's counts: a
    file cut at 90% loaded 241 of 320 faces, one whose header claims 50 extra vertices read face
    lines as vertices. So: the lines must number exactly what the header declares, and the first
    and last row of each element (where a cut or a wrong count shows) must parse as one row."""
    total = sum(count for _, count, _ in elements)
    bounds: dict[int, tuple[str, int, list[bool]]] = {}
    row = 0
    for name, count, layout in elements:
        if count:
            bounds[row] = (name, 0, layout)
            bounds[row + count - 1] = (name, count - 1, layout)
        row += count
    rows, text = _scan_lines(path_str, start, size, list(bounds))
    declared = ", ".join(f"{count} {name!r}" for name, count, _ in elements)
    if rows != total:
        raise _corrupt(path_str, f"the PLY header declares {declared} ({total} lines) but "
                                 f"{rows} lines follow it: "
                                 + ("truncated" if rows < total else "its counts do not match the data"))
    for r, (name, i, layout) in sorted(bounds.items()):
        problem = _row_problem(text[r], layout)
        if problem:
            raise _corrupt(path_str, f"PLY {name!r} row {i} (line {r + 1} after the header) has "
                                     f"{problem}: truncated or corrupt")


def _check_off(path_str: str, size: int) -> int:
    """OFF states its vertex and face counts; trimesh reads that many non-blank lines and
    ignores the rest (a file cut at 70% loaded 62 of 320 faces). As for ascii PLY, the lines
    must number exactly what the counts say and the rows at each boundary must parse (a face
    row in the middle that trimesh skips is caught by the face count, in load_mesh). Comments
    (#) and blank lines are skipped, as trimesh does. One pass over the lines (13.5 MB, 327,680
    faces: 0.2 s, against 2.7 s for trimesh's parse)."""
    found_off, counts, rows, nv, nf = False, None, 0, 0, 0
    want: dict[int, str] = {}
    text: dict[int, bytes] = {}
    # trimesh's comment_strip repeats the text between the first line end and the first '#'
    # right after it, unless the file starts with '#': a comment inside the data shifts every
    # row after it ("OFF\n4 2 0\n0 0 0\n# c\n..." gave the vertex (4, 2, 0) and no faces).
    # So what matters is the first '#': harmless on line 0 or with nothing but blanks and
    # comments between it and line 0, else it must come after the last row trimesh reads.
    first_text = None  # the first line after line 0 with anything but a comment on it
    comment_row = None  # data rows before the first '#', if trimesh repeats text there
    hash_seen = False
    with open(path_str, "rb") as f:
        for number, line in enumerate(f):
            if b"#" in line:
                before = line.split(b"#", 1)[0]
                if not hash_seen and number > 0 and (first_text is not None or before.strip()):
                    comment_row = rows if counts is not None else -1
                hash_seen = True
                line = before
            content = line.strip()
            if not content:
                continue
            if first_text is None and number > 0:
                first_text = number
            if not found_off:
                at = content.find(b"OFF")
                if at < 0:
                    return 0  # not an OFF file: trimesh reports that
                found_off = True
                content = content[at + 3:].strip()  # "OFF 8 6 0" on one line is valid
                if not content:
                    continue
            if counts is None:
                try:
                    counts = [int(w) for w in content.split()]
                except ValueError:
                    counts = []
                if len(counts) < 2 or min(counts[:2]) < 0:
                    raise _corrupt(path_str, f"malformed OFF counts line {content[:80]!r}")
                nv, nf = counts[:2]
                want = {0: "vertex", nv - 1: "vertex", nv: "face", nv + nf - 1: "face"}
                continue
            if rows in want:
                text[rows] = content[:_MAX_ROW]
            rows += 1
    if counts is None:
        return 0  # no counts line: trimesh reports that
    if comment_row is not None and comment_row < nv + nf:
        raise _corrupt(path_str, "a comment inside the OFF data, which trimesh misreads (it repeats "
                                 "the lines before it): move it before the OFF line or remove it")
    if rows != nv + nf:
        raise _corrupt(path_str, f"the OFF header declares {nv} vertices and {nf} faces "
                                 f"({nv + nf} lines) but {rows} lines follow it: "
                                 + ("truncated" if rows < nv + nf else "its counts do not match the data"))
    for r, kind in sorted(want.items()):
        if r < 0 or r not in text:
            continue
        words = text[r].split()
        try:
            if kind == "vertex":
                ok = len(words) >= 3
                [float(w) for w in words[:3]]  # raises ValueError if one is not a number
            else:
                n = int(words[0])
                ok = n >= 1 and len(words) >= n + 1 and all(int(w) >= 0 for w in words[1:n + 1])
        except (ValueError, IndexError):
            ok = False
        if not ok:
            raise _corrupt(path_str, f"OFF {kind} line {text[r][:80]!r} is incomplete or not "
                                     "numbers: truncated or corrupt")
    return nf


# Every OBJ statement keyword (the Wavefront spec's, plus trimesh's extensions).
_OBJ_KEYWORDS = frozenset(
    "v vt vn vp f l p o g s mg usemtl mtllib cstype deg bmat step curv curv2 surf parm trim "
    "hole scrv sp end con call csh maplib usemap lod shadow_obj trace_obj ctech stech bevel "
    "c_interp d_interp".split())


_OBJ_REF = re.compile(rb"^-?\d+(?:/-?\d+(?:/-?\d+)?|//-?\d+)?$")


_OBJ_NUMBERS = {b"v": (3, 4, 6, 7), b"vn": (3,), b"vt": (1, 2, 3), b"vp": (1, 2, 3)}


_OBJ_REFS = {b"f": 3, b"l": 2, b"p": 1}


def _obj_line_problem(line: bytes) -> str | None:
    """Why a last line without a newline after it is visibly incomplete, or None.

    OBJ states no counts, so a cut at a line end (or inside a line's last number) leaves a valid,
    smaller file that nothing can tell apart. What can be told: a statement with too few
    values ("f 1 2", "v 0.5 1"), a value cut in half ("1.5e-", "3/"), a keyword cut short
    ("usem"). Unknown keywords are left alone: they are legal, and trimesh skips them."""
    words = line.split(b"#", 1)[0].split()
    if not words:
        return None
    key, args = words[0], words[1:]
    if args and args[-1] == b"\\":
        return "ends in a line continuation"
    if key in _OBJ_NUMBERS:
        try:
            [float(a) for a in args]
        except ValueError:
            return "has a value that is not a number"
        if len(args) not in _OBJ_NUMBERS[key]:
            return f"has {len(args)} values"
    elif key in _OBJ_REFS:
        if len(args) < _OBJ_REFS[key]:
            return f"has {len(args)} vertex references"
        if not all(_OBJ_REF.match(a) for a in args):
            return "has a malformed vertex reference"
        if len({a.count(b"/") + (b"//" in a) for a in args}) > 1:
            return "mixes vertex reference forms (v, v/vt, v/vt/vn, v//vn)"
    elif key in (b"usemtl", b"mtllib") and not args:
        return "has no name"
    elif key.decode("latin-1") not in _OBJ_KEYWORDS and any(
            k.startswith(key.decode("latin-1")) for k in _OBJ_KEYWORDS):
        return "starts with a keyword cut short"
    return None


def _count_obj_faces(path_str: str) -> int:
    """The number of face statements ("f" lines): each gives trimesh at least one triangle.
    One pass, 1 MiB at a time (12.8 MB, 327,680 faces: 32 ms with the last-line check, against
    0.7 s for trimesh's parse; 3 MiB at peak)."""
    faces = 0
    with open(path_str, "rb") as f:
        buf = b"\n"  # so that a face on the first line counts too
        while True:
            chunk = f.read(_CHUNK)
            if not chunk:
                break
            buf = buf[-2:] + chunk  # a 3-byte match across chunks is counted once: here
            faces += buf.count(b"\nf ") + buf.count(b"\nf\t")
    return faces


def _check_obj(path_str: str, size: int) -> int:
    """Refuse an OBJ cut mid-line: its last line has no newline and is visibly incomplete.
    Returns the number of face statements."""
    faces = _count_obj_faces(path_str)
    with open(path_str, "rb") as f:
        f.seek(max(0, size - _MAX_ROW))
        tail = f.read()
    if not tail or tail[-1:] in (b"\n", b"\r"):
        return faces  # ends at a line end: complete (or cut exactly there, which no check can see)
    cut = max(tail.rfind(b"\n"), tail.rfind(b"\r"))
    if cut < 0 and size > _MAX_ROW:
        return faces  # a last line longer than 64 KiB: not judged
    line = tail[cut + 1:]
    problem = _obj_line_problem(line)
    if problem:
        raise _corrupt(path_str, f"its last line {line[:80].decode('latin-1')!r} {problem} and no "
                                 "newline follows it: truncated")
    return faces


# trimesh reads only the vertices; "outer loop" / "endloop" are not counted (each count is
# another full pass: ~25 ms per 10 MB).
_STL_KEYS = (b"facet", b"endfacet", b"vertex")


def _check_stl_ascii(path_str: str, size: int) -> int:
    """An ASCII STL states no counts but has a fixed structure: trimesh takes every 'vertex' of
    each solid...endsolid block, so a file cut inside a solid whose earlier solid ended loaded
    half the mesh. Count the keywords as trimesh reads them (case-insensitively) in one pass:
    solids must be closed, every facet needs its endfacet and 3 vertices, and
    the file must end on an endsolid line. Words in solid names are not counted. 98 MB, 327,680
    facets: 0.25-0.6 s and 6 MiB at peak, against 3.8 s for trimesh's parse."""
    counts = dict.fromkeys(_STL_KEYS, 0)
    solids = ends = 0
    last = b""
    with open(path_str, "rb") as f:
        carry = b""
        while True:
            chunk = f.read(_CHUNK)
            buf = (carry + chunk).lower()
            cut = len(buf) if not chunk else buf.rfind(b"\n") + 1
            if chunk and cut == 0:
                if len(buf) > _CHUNK:
                    raise _corrupt(path_str, "not an ASCII STL (a line longer than 1 MiB) nor a "
                                             "binary one (its size does not match its triangle count)")
                carry = buf
                continue
            block, carry = buf[:cut], buf[cut:]
            for key in _STL_KEYS:
                counts[key] += block.count(key)
            at = block.find(b"solid")
            while at >= 0:  # the few solid / endsolid lines (a regex over every line is 10x slower)
                start = block.rfind(b"\n", 0, at) + 1
                end = block.find(b"\n", at) + 1 or len(block)
                line = block[start:end].lstrip()
                if line.startswith(b"solid") or line.startswith(b"endsolid"):
                    if line.startswith(b"solid"):
                        solids += 1
                    else:
                        ends += 1
                    name = line[5 if line.startswith(b"solid") else 8:]
                    for key in _STL_KEYS:
                        counts[key] -= name.count(key)
                at = block.find(b"solid", end)
            content = block.rstrip()
            if content:
                last = content[content.rfind(b"\n") + 1:]
            if not chunk:
                break
    facets = counts[b"facet"] - counts[b"endfacet"]
    if not last.strip().startswith(b"endsolid"):
        raise _corrupt(path_str, "the ASCII STL does not end with 'endsolid': truncated")
    if solids != ends or facets != counts[b"endfacet"] or counts[b"vertex"] != 3 * facets:
        raise _corrupt(path_str, f"the ASCII STL has {solids} 'solid' and {ends} 'endsolid', "
                                 f"{facets} 'facet', {counts[b'endfacet']} 'endfacet' and "
                                 f"{counts[b'vertex']} 'vertex' (3 per facet): truncated or corrupt")
    return facets


def _check_stl(path_str: str, size: int) -> int:
    with open(path_str, "rb") as f:
        head = f.read(84)
    ascii_head = head.lstrip().lower().startswith(b"solid")  # trimesh ignores the case
    if size < 84 and not ascii_head:
        raise _corrupt(path_str, f"{size} bytes is too short for a binary STL (84-byte header)")
    if size >= 84:
        (count,) = struct.unpack("<I", head[80:84])
        if size == 84 + 50 * count:  # binary: 50 bytes per triangle
            check_budget(count * 3 * 3 * _VALUE_BYTES * 2, f"mesh file {path_str!r} (STL triangle count)")
            return count
        if not ascii_head:
            raise _corrupt(path_str, f"the binary STL header declares {count} triangles "
                                     f"({84 + 50 * count} bytes) but the file has {size} bytes: "
                                     "truncated or corrupt")
    return _check_stl_ascii(path_str, size)


def check_mesh_file(path_str: str) -> int:
    """Refuse files that are truncated, inconsistent with their own counts, or would make trimesh
    allocate more than the memory budget (raises ValueError or FileNotFoundError naming the file).

    glTF and GLB files are read and checked by ``gltf_file.read_gltf`` instead.

    Returns the number of faces the file states or holds (0 where unknown): trimesh must return at least that many triangles (a polygon
    gives one or more). Fewer means it skipped rows it could not read ("f 30 33010" in an OBJ,
    "3 9$32 28" in an OFF), without a word.
    """
    size = os.path.getsize(path_str)
    check_budget(size, f"mesh file {path_str!r}")  # trimesh reads the whole file into memory
    ext = os.path.splitext(path_str)[1].lower()
    if ext == ".ply":
        return _check_ply(path_str, size)
    if ext == ".stl":
        return _check_stl(path_str, size)
    if ext == ".off":
        return _check_off(path_str, size)
    elif ext == ".obj":
        return _check_obj(path_str, size)
    return 0
