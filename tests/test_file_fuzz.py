"""Mutation fuzzing of mesh files: truncated, header-inconsistent and bit-flipped copies of valid
files of every format load_mesh supports.

Valid files are made here (an icosphere through trimesh's writers, and the real asset
assets/meshes/spot.obj), then mutated with a seeded RNG, so the corpus is the same on every run
and nothing binary is committed. Every copy is loaded in one child process under a timeout (a
crash or a hang fails the test and names the file). The promise checked for each:

- truncations and header-count edits: the full mesh (the original's face count) or a ValueError /
  FileNotFoundError naming the file. The one exception is OBJ, which states no counts: a cut at a
  line end, or inside a line's last value ("v 1 2 3.25" -> "v 1 2 3.2"), leaves a valid smaller
  file that no check can tell apart, so there a smaller mesh is allowed too (never a bigger one);
- bit flips in binary payloads (STL triangles, PLY vertex data, the GLB's BIN chunk), where no
  count can change: the full mesh or a ValueError naming the file;
- bit flips anywhere else, which can make another valid file (a glTF "mode": 4 -> 5 is a triangle
  strip): any mesh, or a ValueError / FileNotFoundError naming the file;
- and never another exception type, a crash or a hang.

The outcome counts are printed (pytest -s) for the README.
"""
from __future__ import annotations

import collections
import json
import os
import pathlib
import re
import struct
import subprocess
import sys

import numpy as np
import pytest
import trimesh

ROOT = pathlib.Path(__file__).resolve().parents[1]
SEED = 20
TRUNCATIONS = 40  # per file, at random offsets, plus the structured ones below
FLIPS = 25  # single-bit flips per file, at random offsets
PAYLOAD_FLIPS = 15  # single-bit flips inside a binary payload, per binary file
TIMEOUT_S = 60  # hang guard for the whole corpus (a normal run takes ~5 s)

CHILD = r"""
import json, sys, softrast as sr
for path in json.loads(sys.stdin.read()):
    print(json.dumps({"start": path}), flush=True)
    try:
        result = {"type": None, "faces": sr.load_mesh(path).num_faces}
    except Exception as exc:
        result = {"type": type(exc).__name__, "message": str(exc)}
    result["path"] = path
    print(json.dumps(result), flush=True)
"""


def _sources() -> dict[str, tuple[dict[str, bytes], int]]:
    """name -> ({file name: bytes} (the first is the one loaded), face count)."""
    sphere = trimesh.creation.icosphere(subdivisions=1)  # 42 vertices, 80 faces: fast to load
    faces = len(sphere.faces)
    gltf = sphere.export(file_type="gltf")
    doc = json.loads(gltf["model.gltf"])
    return {
        "sphere.obj": ({"sphere.obj": sphere.export(file_type="obj").encode()}, faces),
        "spot.obj": ({"spot.obj": (ROOT / "assets/meshes/spot.obj").read_bytes()}, 5856),
        "ascii.ply": ({"ascii.ply": sphere.export(file_type="ply", encoding="ascii")}, faces),
        "binary.ply": ({"binary.ply": sphere.export(file_type="ply", encoding="binary")}, faces),
        "sphere.off": ({"sphere.off": sphere.export(file_type="off").encode()}, faces),
        "ascii.stl": ({"ascii.stl": sphere.export(file_type="stl_ascii").encode()}, faces),
        "binary.stl": ({"binary.stl": sphere.export(file_type="stl")}, faces),
        "sphere.glb": ({"sphere.glb": sphere.export(file_type="glb")}, faces),
        "sphere.gltf": ({"sphere.gltf": json.dumps(doc).encode(),
                         **{b["uri"]: gltf[b["uri"]] for b in doc["buffers"]}}, faces),
    }


def _payload(name: str, data: bytes) -> tuple[int, int] | None:
    """The byte range of a binary file's payload, where a flipped bit changes a value, not a count."""
    if name == "binary.stl":
        return 84, len(data)  # normals, vertices and the (ignored) 2-byte attribute of each triangle
    if name == "binary.ply":
        start = data.index(b"end_header\n") + len(b"end_header\n")
        vertices = int(re.search(rb"element vertex (\d+)", data).group(1))
        return start, start + 12 * vertices  # x, y, z float32: the faces' list counts are counts
    if name == "sphere.glb":
        json_length = struct.unpack("<I", data[12:16])[0]
        start = 20 + json_length + 8  # the BIN chunk's data
        doc = json.loads(data[20:20 + json_length])
        # The POSITION data only: a flipped index is refused (past the vertices) or another valid
        # face, but there the file itself would be wrong, not its reading.
        view = doc["bufferViews"][doc["meshes"][0]["primitives"][0]["attributes"]["POSITION"]]
        return start + view.get("byteOffset", 0), start + view.get("byteOffset", 0) + view["byteLength"]
    return None


def _header_edits(name: str, data: bytes) -> list[tuple[str, bytes]]:
    """Copies whose stated counts (or, without counts, structure) disagree with the data."""
    edits: list[tuple[str, bytes]] = []

    def sub(label: str, pattern: bytes, repl) -> None:
        edits.append((label, re.sub(pattern, repl, data, count=1)))

    if name.endswith(".ply"):
        for delta in (-1, 1, 50):
            sub(f"vertex{delta:+d}", rb"element vertex (\d+)",
                lambda m, d=delta: b"element vertex %d" % (int(m.group(1)) + d))
            sub(f"face{delta:+d}", rb"element face (\d+)",
                lambda m, d=delta: b"element face %d" % (int(m.group(1)) + d))
        sub("face=0", rb"element face \d+", b"element face 0")
        sub("face=2**31", rb"element face \d+", b"element face 2147483648")
    elif name.endswith(".off"):
        for i, delta in ((0, -1), (0, 1), (1, -1), (1, 1), (1, 1000)):
            def repl(m, i=i, delta=delta):
                counts = [int(c) for c in m.group(0).split()]
                counts[i] += delta
                return b" ".join(b"%d" % c for c in counts)
            sub(f"count{i}{delta:+d}", rb"(?m)^\d+ \d+ \d+$", repl)
    elif name == "binary.stl":
        count = struct.unpack("<I", data[80:84])[0]
        for new in (count - 1, count + 1, 0, 2**32 - 1):
            edits.append((f"count={new}", data[:80] + struct.pack("<I", new) + data[84:]))
    elif name == "ascii.stl":
        lines = data.split(b"\n")
        facet = 7 * 10 + 1  # the 11th facet (line 0 is "solid")
        for k, what in enumerate(["facet", "outer loop", "vertex", "vertex", "vertex", "endloop",
                                  "endfacet"]):
            edits.append((f"no {what} line", b"\n".join(lines[:facet + k] + lines[facet + k + 1:])))
        edits.append(("extra vertex", b"\n".join(lines[:facet + 2] + lines[facet + 2:facet + 3]
                                                  + lines[facet + 2:])))
    elif name.endswith(".obj"):
        lines = data.split(b"\n")
        last_v = max(i for i, line in enumerate(lines) if line.startswith(b"v "))
        edits.append(("no last vertex", b"\n".join(lines[:last_v] + lines[last_v + 1:])))
    elif name in ("sphere.glb", "sphere.gltf"):
        if name == "sphere.glb":
            json_length = struct.unpack("<I", data[12:16])[0]
            doc, rest = json.loads(data[20:20 + json_length]), data[20 + json_length:]
            for delta in (-4, 4):
                edits.append((f"total{delta:+d}",
                              data[:8] + struct.pack("<I", len(data) + delta) + data[12:]))
                edits.append((f"json length{delta:+d}",
                              data[:12] + struct.pack("<I", json_length + delta) + data[16:]))
        else:
            doc = json.loads(data)

        def edited(path: tuple, delta: int) -> bytes:
            new = json.loads(json.dumps(doc))
            obj = new
            for key in path[:-1]:
                obj = obj[key]
            obj[path[-1]] = obj.get(path[-1], 0) + delta
            text = json.dumps(new).encode()
            if name == "sphere.gltf":
                return text
            text += b" " * (-len(text) % 4)
            return struct.pack("<4sIII4s", b"glTF", 2, 20 + len(text) + len(rest), len(text),
                               b"JSON") + text + rest

        for i in range(len(doc["accessors"])):
            for delta in (-1, 1):
                edits.append((f"accessor {i} count{delta:+d}", edited(("accessors", i, "count"), delta)))
            edits.append((f"accessor {i} byteOffset+4", edited(("accessors", i, "byteOffset"), 4)))
        for i in range(len(doc["bufferViews"])):
            edits.append((f"view {i} byteLength-4", edited(("bufferViews", i, "byteLength"), -4)))
            edits.append((f"view {i} byteOffset+4", edited(("bufferViews", i, "byteOffset"), 4)))
        edits.append(("buffer 0 byteLength+4", edited(("buffers", 0, "byteLength"), 4)))
    return edits


def _obj_cut_is_invisible(data: bytes, cut: int) -> bool:
    """True if an OBJ cut at ``cut`` leaves a file that is valid as it stands: the cut is at a line
    end, or inside the line's last value (which then reads as a shorter value)."""
    start = data.rfind(b"\n", 0, cut) + 1
    end = data.find(b"\n", cut)
    line = data[start: len(data) if end < 0 else end]
    if cut == start or not line[: cut - start].strip():
        return True  # nothing of the line is left (or only blanks)
    last_token = len(line.rstrip()) - len(line.rstrip().split()[-1])
    return cut - start > last_token


def _corpus(d: pathlib.Path) -> list[dict]:
    """Writes every mutated file; returns one job per file to load: path, kind, full face count
    and whether a smaller mesh is allowed."""
    rng = np.random.default_rng(SEED)
    jobs = []
    for name, (files, faces) in _sources().items():
        main = next(iter(files))
        extras = dict(list(files.items())[1:])

        def write(label: str, data: bytes, kind: str, smaller_ok: bool = False,
                  extra: dict[str, bytes] | None = None) -> None:
            sub = d / f"{name}-{len(jobs):04d}"
            sub.mkdir()
            for other, blob in {**extras, **(extra or {})}.items():
                (sub / other).write_bytes(blob)
            path = sub / main
            path.write_bytes(data)
            jobs.append({"path": str(path), "kind": kind, "expected": faces, "smaller_ok": smaller_ok,
                         "label": f"{name} {label}"})

        data = files[main]
        write("intact", data, "intact")
        cuts = set(rng.integers(1, len(data), TRUNCATIONS).tolist())
        cuts |= {1, 19, 20, 83, 84, 85, len(data) // 2, len(data) - 1, len(data) - 2}
        for cut in sorted(c for c in cuts if 0 < c < len(data)):
            invisible = name.endswith(".obj") and _obj_cut_is_invisible(data, cut)
            write(f"cut at {cut}", data[:cut], "truncation", smaller_ok=invisible)
        for other, blob in extras.items():  # the glTF's external buffer, cut short
            for cut in sorted(set(rng.integers(0, len(blob), 8).tolist())):
                write(f"{other} cut at {cut}", data, "truncation", extra={other: blob[:cut]})
        for label, edited in _header_edits(name, data):
            write(label, edited, "header")
        payload = _payload(name, data)
        for flip in range(FLIPS + (PAYLOAD_FLIPS if payload else 0)):
            lo, hi = payload if payload and flip >= FLIPS else (0, len(data))
            at, bit = int(rng.integers(lo, hi)), int(rng.integers(0, 8))
            flipped = bytearray(data)
            flipped[at] ^= 1 << bit
            write(f"bit {bit} of byte {at} flipped", bytes(flipped),
                  "payload flip" if flip >= FLIPS else "flip")
    return jobs


@pytest.fixture(scope="module")
def outcomes(tmp_path_factory) -> list[dict]:
    d = tmp_path_factory.mktemp("file_fuzz")
    jobs = _corpus(d)
    try:
        proc = subprocess.run([sys.executable, "-c", CHILD], input=json.dumps([j["path"] for j in jobs]),
                              capture_output=True, text=True, timeout=TIMEOUT_S)
    except subprocess.TimeoutExpired as exc:
        started = [json.loads(line)["start"] for line in (exc.stdout or b"").decode().splitlines()
                   if line.startswith('{"start"')]
        pytest.fail(f"loading the fuzzed files hung (last started: {started[-1:] or 'none'})")
    lines = [json.loads(line) for line in proc.stdout.splitlines()]
    started = [r["start"] for r in lines if "start" in r]
    # A crash (negative return code: killed by a signal) names the file it happened on.
    assert proc.returncode == 0, (proc.returncode, started[-1:], proc.stderr[-2000:])
    done = {r["path"]: r for r in lines if "path" in r}
    assert len(done) == len(jobs)
    return [{**job, **done[job["path"]]} for job in jobs]


def _verdict(o: dict) -> str:
    """'full', 'smaller', 'other mesh' or 'refused' if the outcome keeps the promise, else why not."""
    if o["type"] is None:
        if o["faces"] == o["expected"]:
            return "full"
        if o["kind"] == "flip":
            return "other mesh"
        if o["smaller_ok"] and o["faces"] < o["expected"]:
            return "smaller"
        return f"loaded {o['faces']} faces, not {o['expected']}"
    if o["type"] in ("ValueError", "FileNotFoundError"):
        if o["path"] not in o["message"]:
            return "the message does not name the file"
        return "refused"
    return f"{o['type']} escaped"


def test_fuzzed_mesh_files_load_whole_or_fail_clearly(outcomes):
    table: dict[str, collections.Counter] = collections.defaultdict(collections.Counter)
    broken = []
    for o in outcomes:
        verdict = _verdict(o)
        table[o["kind"]][verdict] += 1
        if verdict not in ("full", "smaller", "other mesh", "refused"):
            broken.append((o["label"], verdict, o.get("message", "")[:300]))
    print(f"\n{len(outcomes)} files:", {kind: dict(c) for kind, c in table.items()})
    assert not broken, broken
    intact = [o for o in outcomes if o["kind"] == "intact"]
    assert len(intact) == 9 and all(_verdict(o) == "full" for o in intact)
    # The corpus exercises both sides: most mutations are refused, and every kind occurs.
    assert table["truncation"]["refused"] > 300 and table["header"]["refused"] > 50
    assert table["payload flip"]["full"] > 0
