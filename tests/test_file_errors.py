"""Mesh and image files that are truncated, corrupt, absurd or missing: a clear exception naming
the file, never a crash, a hang or a giant allocation.

All files are loaded in one child process (a crash or a hang must not take pytest down), each
under a timeout, with the peak RSS (VmHWM, reset before each file) measured around the load.
"""
from __future__ import annotations

import base64
import json
import os
import pathlib
import struct
import subprocess
import sys
import zlib

import numpy as np
import pytest
import trimesh

import softrast as sr

MAX_PEAK_GROWTH_MB = 100  # far below every size these headers claim (300 MB .. 100 GB)
TIMEOUT_S = 120  # for all files together; a normal run takes ~2 s

# The child: loads each file, prints one JSON line per file; a hang or a crash shows up as a
# missing line, a timeout or a negative return code.
CHILD = r"""
import json, sys, softrast as sr

def status(key):
    for line in open("/proc/self/status"):
        if line.startswith(key):
            return int(line.split()[1]) / 1024.0  # MB
for kind, path in json.loads(sys.argv[1]):
    print(json.dumps({"start": path}), flush=True)
    open("/proc/self/clear_refs", "w").write("5")  # reset the peak RSS (VmHWM) to the current RSS
    before = status("VmRSS:")
    try:
        (sr.load_mesh if kind == "mesh" else sr.imread)(path)
        result = {"type": None, "message": ""}
    except Exception as exc:
        result = {"type": type(exc).__name__, "message": str(exc)}
    result.update(path=path, peak_growth_mb=status("VmHWM:") - before)
    print(json.dumps(result), flush=True)
"""


def _png_chunk(kind: bytes, data: bytes) -> bytes:
    return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))


def _png_claiming(width: int, height: int, idat: bytes | None) -> bytes:
    """A valid signature and IHDR (8-bit RGB) with the given size, then ``idat`` (if any), IEND."""
    ihdr = _png_chunk(b"IHDR", struct.pack(">IIBBBBB", width, height, 8, 2, 0, 0, 0))
    body = b"" if idat is None else _png_chunk(b"IDAT", idat)
    return b"\x89PNG\r\n\x1a\n" + ihdr + body + _png_chunk(b"IEND", b"")


def _exr_with_data_window(good: bytes, box: tuple[int, int, int, int]) -> bytes:
    key = b"dataWindow\x00box2i\x00"
    at = good.index(key) + len(key) + 4  # after the attribute's size field
    return good[:at] + struct.pack("<4i", *box) + good[at + 16:]


def _ply_header(fmt: str, vertices: int, faces: int) -> bytes:
    return (f"ply\nformat {fmt} 1.0\nelement vertex {vertices}\nproperty float x\nproperty float y\n"
            f"property float z\nelement face {faces}\nproperty list uchar int vertex_indices\n"
            "end_header\n").encode()


def _gltf(uri: str, byte_length: int, count: int = 3, image_uri: str | None = None) -> str:
    """One triangle: positions (36 bytes) then uint32 indices (12 bytes) in buffer 0."""
    doc = {
        "asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": [0]}], "nodes": [{"mesh": 0}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "indices": 1}]}],
        "buffers": [{"uri": uri, "byteLength": byte_length}],
        "bufferViews": [{"buffer": 0, "byteOffset": 0, "byteLength": 36},
                        {"buffer": 0, "byteOffset": 36, "byteLength": 12}],
        "accessors": [{"bufferView": 0, "componentType": 5126, "count": count, "type": "VEC3",
                       "min": [0, 0, 0], "max": [1, 1, 0]},
                      {"bufferView": 1, "componentType": 5125, "count": 3, "type": "SCALAR"}],
    }
    if image_uri is not None:
        doc["images"] = [{"uri": image_uri}]
        doc["textures"] = [{"source": 0}]
        doc["materials"] = [{"pbrMetallicRoughness": {"baseColorTexture": {"index": 0}}}]
        doc["meshes"][0]["primitives"][0]["material"] = 0
    return json.dumps(doc)


TRIANGLE_BLOB = (np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], np.float32).tobytes()
                 + np.array([0, 1, 2], np.uint32).tobytes())

# name -> (kind, expected exception, extra text the message must contain)
CASES: dict[str, tuple[str, str, str]] = {
    "truncated.obj": ("mesh", "ValueError", ""),
    "corrupt_face.obj": ("mesh", "ValueError", ""),
    "index_out_of_range.obj": ("mesh", "ValueError", "out of bounds"),
    "nan_vertex.obj": ("mesh", "ValueError", "NaN"),
    "truncated_ascii.ply": ("mesh", "ValueError", ""),
    "truncated_binary.ply": ("mesh", "ValueError", ""),
    "huge_vertex_count_ascii.ply": ("mesh", "ValueError", "2147483648"),
    "huge_vertex_count_binary.ply": ("mesh", "ValueError", "2147483648"),
    "huge_face_count_binary.ply": ("mesh", "ValueError", "2147483647"),
    "no_end_header.ply": ("mesh", "ValueError", "end_header"),
    "truncated_binary.stl": ("mesh", "ValueError", "truncated"),
    "huge_count.stl": ("mesh", "ValueError", "2147483648 triangles"),
    "truncated_ascii.stl": ("mesh", "ValueError", "truncated"),
    "truncated.glb": ("mesh", "ValueError", "truncated"),
    "bad_json.gltf": ("mesh", "ValueError", "JSON"),
    "short_buffer.gltf": ("mesh", "ValueError", "truncated"),
    "accessor_past_view.gltf": ("mesh", "ValueError", "accessor 0"),
    "missing_bin.gltf": ("mesh", "FileNotFoundError", "nothere.bin"),
    "missing_texture.gltf": ("mesh", "FileNotFoundError", "nothere.png"),
    "does_not_exist.obj": ("mesh", "FileNotFoundError", ""),
    # Truncated or header-inconsistent files that trimesh loads as partial meshes.
    "cut_at_90_percent_ascii.ply": ("mesh", "ValueError", "truncated"),
    "declares_50_more_vertices.ply": ("mesh", "ValueError", "212 'vertex'"),
    "declares_1_face_fewer.ply": ("mesh", "ValueError", "counts do not match"),
    "last_row_cut.ply": ("mesh", "ValueError", "'face' row 319"),
    "cut_at_70_percent.off": ("mesh", "ValueError", "320 faces"),
    "declares_1_face_fewer.off": ("mesh", "ValueError", "counts do not match"),
    "comment_inside_data.off": ("mesh", "ValueError", "comment inside the OFF data"),
    "cut_inside_second_solid.stl": ("mesh", "ValueError", "endsolid"),
    "cut_mid_facet_then_endsolid.stl": ("mesh", "ValueError", "'endfacet'"),
    "cut_inside_last_face.obj": ("mesh", "ValueError", "truncated"),
    "cut_inside_keyword.obj": ("mesh", "ValueError", "keyword cut short"),
    "cut_inside_number.obj": ("mesh", "ValueError", "not a number"),
    "index_count_not_multiple_of_3.gltf": ("mesh", "ValueError", "not a multiple of 3"),
    # Found by tests/test_file_fuzz.py: one corrupt face row in the middle, skipped by trimesh.
    "corrupt_face_row_mid_file.obj": ("mesh", "ValueError", "321 faces but only 320"),
    "corrupt_face_row_mid_file.off": ("mesh", "ValueError", "321 faces but only 320"),
    # Item 5: trimesh's IndexError (from a lazily computed property) escaped load_mesh.
    "face_index_past_vertices_ascii.ply": ("mesh", "ValueError", "out of bounds for 3 vertices"),
    "face_index_past_vertices_binary.ply": ("mesh", "ValueError", "out of bounds for 3 vertices"),
    "face_index_past_vertices.gltf": ("mesh", "ValueError", "out of bounds for 3 vertices"),
    "truncated.png": ("image", "ValueError", ""),
    "garbage_idat.png": ("image", "ValueError", ""),
    "claims_100000x100000_no_idat.png": ("image", "ValueError", ""),
    "claims_100000x100000_tiny_idat.png": ("image", "ValueError", ""),
    "claims_40000x40000_tiny_idat.png": ("image", "ValueError", ""),
    "claims_10000x10000_tiny_idat.png": ("image", "ValueError", "10000x10000"),
    "truncated.exr": ("image", "ValueError", ""),
    "absurd_data_window.exr": ("image", "ValueError", ""),
    "data_window_40000x40000.exr": ("image", "ValueError", ""),
    "inverted_data_window.exr": ("image", "ValueError", ""),
    "does_not_exist.png": ("image", "FileNotFoundError", ""),
}


def _write_cases(d: pathlib.Path) -> None:
    sphere = trimesh.creation.icosphere(subdivisions=2)
    obj = sphere.export(file_type="obj").encode()
    (d / "truncated.obj").write_bytes(obj[: len(obj) // 2 + 3])  # cut inside a line
    (d / "corrupt_face.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 x\n")
    (d / "index_out_of_range.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 99\n")
    (d / "nan_vertex.obj").write_text("v nan 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    for enc in ("ascii", "binary"):
        data = sphere.export(file_type="ply", encoding=enc)
        (d / f"truncated_{enc}.ply").write_bytes(data[: len(data) // 2])
    tri = b"0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n"
    (d / "huge_vertex_count_ascii.ply").write_bytes(_ply_header("ascii", 2**31, 1) + tri)
    tri_bin = np.zeros(9, np.float32).tobytes() + b"\x03" + np.arange(3, dtype=np.int32).tobytes()
    (d / "huge_vertex_count_binary.ply").write_bytes(_ply_header("binary_little_endian", 2**31, 1) + tri_bin)
    (d / "huge_face_count_binary.ply").write_bytes(_ply_header("binary_little_endian", 3, 2**31 - 1) + tri_bin)
    (d / "no_end_header.ply").write_bytes(b"ply\nformat ascii 1.0\nelement vertex 3\n" + b"0 " * 1000)
    stl = sphere.export(file_type="stl")
    (d / "truncated_binary.stl").write_bytes(stl[: len(stl) // 2])
    (d / "huge_count.stl").write_bytes(stl[:80] + struct.pack("<I", 2**31) + stl[84:])
    stl_ascii = sphere.export(file_type="stl_ascii").encode()
    (d / "truncated_ascii.stl").write_bytes(stl_ascii[: len(stl_ascii) // 2])
    glb = sphere.export(file_type="glb")
    (d / "truncated.glb").write_bytes(glb[: len(glb) // 2])
    (d / "bad_json.gltf").write_text('{"asset": {"version": "2.0"}, "meshes": [')
    (d / "short.bin").write_bytes(TRIANGLE_BLOB[:20])
    (d / "short_buffer.gltf").write_text(_gltf("short.bin", len(TRIANGLE_BLOB)))
    inline = "data:application/octet-stream;base64," + base64.b64encode(TRIANGLE_BLOB).decode()
    (d / "accessor_past_view.gltf").write_text(_gltf(inline, len(TRIANGLE_BLOB), count=1000))
    (d / "missing_bin.gltf").write_text(_gltf("nothere.bin", len(TRIANGLE_BLOB)))
    (d / "triangle.bin").write_bytes(TRIANGLE_BLOB)
    (d / "missing_texture.gltf").write_text(_gltf("triangle.bin", len(TRIANGLE_BLOB), image_uri="nothere.png"))

    _write_inconsistent_meshes(d, sphere)

    rng = np.random.default_rng(5)
    sr.imwrite(d / "good.png", rng.integers(0, 256, (64, 64, 3), dtype=np.uint8))
    png = (d / "good.png").read_bytes()
    (d / "truncated.png").write_bytes(png[: len(png) // 2])
    idat = png.index(b"IDAT")
    garbage = rng.integers(0, 256, 500, dtype=np.uint8).tobytes()
    (d / "garbage_idat.png").write_bytes(png[: idat - 4] + _png_chunk(b"IDAT", garbage) + _png_chunk(b"IEND", b""))
    tiny = zlib.compress(b"\x00" * 100)
    (d / "claims_100000x100000_no_idat.png").write_bytes(_png_claiming(100000, 100000, None))
    (d / "claims_100000x100000_tiny_idat.png").write_bytes(_png_claiming(100000, 100000, tiny))
    (d / "claims_40000x40000_tiny_idat.png").write_bytes(_png_claiming(40000, 40000, tiny))
    (d / "claims_10000x10000_tiny_idat.png").write_bytes(_png_claiming(10000, 10000, tiny))
    sr.imwrite(d / "good.exr", rng.random((64, 64, 3)).astype(np.float32))
    exr = (d / "good.exr").read_bytes()
    (d / "truncated.exr").write_bytes(exr[: len(exr) // 2])
    (d / "absurd_data_window.exr").write_bytes(_exr_with_data_window(exr, (0, 0, 10**9 - 1, 10**9 - 1)))
    (d / "data_window_40000x40000.exr").write_bytes(_exr_with_data_window(exr, (0, 0, 39999, 39999)))
    (d / "inverted_data_window.exr").write_bytes(_exr_with_data_window(exr, (100, 100, 0, 0)))


def _gltf_blob(indices: list[int], count: int | None = None) -> str:
    """_gltf's triangle with ``indices`` (uint32) and an index accessor of ``count`` (default all)."""
    blob = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], np.float32).tobytes() \
        + np.array(indices, np.uint32).tobytes()
    doc = json.loads(_gltf("data:application/octet-stream;base64," + base64.b64encode(blob).decode(),
                           len(blob)))
    doc["bufferViews"][1]["byteLength"] = 4 * len(indices)
    doc["accessors"][1]["count"] = len(indices) if count is None else count
    return json.dumps(doc)


def _write_inconsistent_meshes(d: pathlib.Path, sphere: trimesh.Trimesh) -> None:
    """Truncated and inconsistent meshes (the sphere has 162 vertices and 320 faces)."""
    ply = sphere.export(file_type="ply", encoding="ascii")
    (d / "cut_at_90_percent_ascii.ply").write_bytes(ply[: int(len(ply) * 0.9)])  # loaded 241 faces
    (d / "declares_50_more_vertices.ply").write_bytes(  # read face lines as vertices
        ply.replace(b"element vertex 162", b"element vertex 212"))
    (d / "declares_1_face_fewer.ply").write_bytes(ply.replace(b"element face 320", b"element face 319"))
    (d / "last_row_cut.ply").write_bytes(ply[: ply.rstrip().rindex(b" ")])  # "3 a b c" -> "3 a b"
    off = sphere.export(file_type="off").encode()
    (d / "cut_at_70_percent.off").write_bytes(off[: int(len(off) * 0.7)])  # loaded 62 of 320
    (d / "declares_1_face_fewer.off").write_bytes(off.replace(b"162 320 0", b"162 319 0"))
    # trimesh repeats the lines before the first '#' after it: a face line read as 162 indices.
    (d / "comment_inside_data.off").write_bytes(off.replace(b"\n3 ", b"\n# a face\n3 ", 1))
    stl = sphere.export(file_type="stl_ascii").encode()
    two = stl + stl.replace(b"solid", b"solid second")  # two solids; the cut is 2 facets into the second
    (d / "cut_inside_second_solid.stl").write_bytes(two[: len(stl) + 600])
    (d / "cut_mid_facet_then_endsolid.stl").write_bytes(stl[: len(stl) // 2] + b"\nendsolid\n")
    obj = sphere.export(file_type="obj").encode().rstrip()
    last = obj.rindex(b" ")
    (d / "cut_inside_last_face.obj").write_bytes(obj[:last])  # "f a b c" -> "f a b"
    (d / "cut_inside_keyword.obj").write_bytes(obj + b"\nusem")
    (d / "cut_inside_number.obj").write_bytes(obj + b"\nv 0.5 1.5 2.5e-")
    (d / "index_count_not_multiple_of_3.gltf").write_text(_gltf_blob([0, 1, 2, 0]))
    (d / "corrupt_face_row_mid_file.obj").write_bytes(obj.replace(b"\nf ", b"\nf 30 33010\nf ", 1))
    rows = off.replace(b"162 320 0", b"162 321 0").split(b"\n")
    (d / "corrupt_face_row_mid_file.off").write_bytes(b"\n".join(rows[:200] + [b"3 9$32 28"] + rows[200:]))
    (d / "face_index_past_vertices_ascii.ply").write_bytes(
        _ply_header("ascii", 3, 1) + b"0 0 0\n1 0 0\n0 1 0\n3 0 1 7\n")
    tri_bin = np.array([0, 0, 0, 1, 0, 0, 0, 1, 0], np.float32).tobytes() + b"\x03" \
        + np.array([0, 1, 7], np.int32).tobytes()
    (d / "face_index_past_vertices_binary.ply").write_bytes(
        _ply_header("binary_little_endian", 3, 1) + tri_bin)
    (d / "face_index_past_vertices.gltf").write_text(_gltf_blob([0, 1, 5]))


@pytest.fixture(scope="module")
def results(tmp_path_factory) -> dict[str, dict]:
    d = tmp_path_factory.mktemp("bad_files")
    _write_cases(d)
    jobs = [(kind, str(d / name)) for name, (kind, _, _) in CASES.items()]
    # Under AddressSanitizer (.ci/sanitize sets SOFTRAST_ASAN) freed memory is held in a 256 MB
    # quarantine to catch use-after-free, which shows up here as peak RSS growth: the child turns
    # it off so the peak measures what was allocated.
    env = dict(os.environ)
    if env.get("SOFTRAST_ASAN"):
        env["ASAN_OPTIONS"] = env.get("ASAN_OPTIONS", "") + ":quarantine_size_mb=0"
    try:
        proc = subprocess.run([sys.executable, "-c", CHILD, json.dumps(jobs)], capture_output=True,
                              text=True, timeout=TIMEOUT_S, env=env)
    except subprocess.TimeoutExpired as exc:
        started = [json.loads(line)["start"] for line in (exc.stdout or b"").decode().splitlines()
                   if line.startswith('{"start"')]
        pytest.fail(f"loading bad files hung (last started: {started[-1:] or 'none'})")
    lines = [json.loads(line) for line in proc.stdout.splitlines()]
    done = {r["path"]: r for r in lines if "path" in r}
    started = [r["start"] for r in lines if "start" in r]
    # A crash (negative return code = killed by a signal) names the file it happened on.
    assert proc.returncode == 0, (proc.returncode, started[-1:], proc.stderr[-2000:])
    return {pathlib.Path(p).name: r for p, r in done.items()}


@pytest.mark.parametrize("name", list(CASES))
def test_bad_file_raises_clear_error(results, name):
    _, expected_type, text = CASES[name]
    result = results[name]
    assert result["type"] == expected_type, result
    assert name in result["message"], result  # the message names the file
    assert text in result["message"], result
    # Refused from the header: no buffer of the claimed size was allocated, not even briefly.
    assert result["peak_growth_mb"] < MAX_PEAK_GROWTH_MB, result


def test_files_are_valid_apart_from_the_defect(tmp_path):
    # The defects are what the loaders react to: the same writers' intact output loads fine.
    _write_cases(tmp_path)
    (tmp_path / "triangle.gltf").write_text(_gltf("triangle.bin", len(TRIANGLE_BLOB)))
    assert sr.load_mesh(tmp_path / "triangle.gltf").num_faces == 1
    assert sr.imread(tmp_path / "good.png").shape == (64, 64, 3)
    assert sr.imread(tmp_path / "good.exr").shape == (64, 64, 3)
    sphere = trimesh.creation.icosphere(subdivisions=2)
    for ext, kw in ((".ply", {"encoding": "ascii"}), (".ply", {"encoding": "binary"}), (".stl", {}),
                    (".glb", {}), (".obj", {})):
        path = tmp_path / f"sphere{ext}"
        sphere.export(path, **kw)
        assert sr.load_mesh(path).num_faces == len(sphere.faces)
    ascii_stl = tmp_path / "sphere_ascii.stl"
    ascii_stl.write_bytes(sphere.export(file_type="stl_ascii").encode())
    assert sr.load_mesh(ascii_stl).num_faces == len(sphere.faces)
    # A highly compressible PNG (ratio ~650:1) is legitimate and is not mistaken for a bomb.
    sr.imwrite(tmp_path / "white.png", np.full((2000, 2000), 255, np.uint8))
    assert sr.imread(tmp_path / "white.png").shape == (2000, 2000)


def _unpadded_glb(mesh: trimesh.Trimesh) -> bytes:
    """The GLB trimesh writes, with its JSON chunk re-written compactly to a length that is not a
    multiple of 4 (no padding): trimesh reads such files."""
    glb = mesh.export(file_type="glb")
    json_length = struct.unpack("<I", glb[12:16])[0]
    text = json.dumps(json.loads(glb[20:20 + json_length]), separators=(",", ":")).encode()
    text += b" " * (len(text) % 4 == 0)
    rest = glb[20 + json_length:]
    return struct.pack("<4sIII4s", b"glTF", 2, 20 + len(text) + len(rest), len(text), b"JSON") + text + rest


def test_odd_but_valid_mesh_files_load(tmp_path):
    # The other side of the truncation checks: files that are unusual but complete load in full.
    sphere = trimesh.creation.icosphere(subdivisions=2)  # 320 faces
    n = len(sphere.faces)
    obj = sphere.export(file_type="obj").encode().rstrip()
    tri = b"v 0 0 0\nv 1 0 0\nv 0 1 0\n"
    ply = sphere.export(file_type="ply", encoding="ascii")
    off = sphere.export(file_type="off").encode()
    stl = sphere.export(file_type="stl_ascii").encode()
    files = {
        # OBJ: a complete last line needs no newline after it, whatever the statement.
        "no_final_newline.obj": (obj, n),
        "last_line_comment.obj": (obj + b"\n# the end", n),
        "last_line_unknown_statement.obj": (obj + b"\nshadow_obj sphere.obj", n),
        "last_line_group_without_name.obj": (obj + b"\ng", n),
        "last_line_vt_one_value.obj": (tri + b"f 1 2 3\nvt 0.5", 1),
        "last_line_refs_with_uv_and_normal.obj": (tri + b"vt 0 0\nvn 0 0 1\nf 1/1/1 2/1/1 3/1/1", 1),
        # PLY: CRLF line ends, trailing blank lines, no final newline.
        "crlf.ply": (ply.replace(b"\n", b"\r\n"), n),
        "trailing_blank_lines.ply": (ply + b"\n\n  \n", n),
        "no_final_newline.ply": (ply.rstrip(), n),
        # OFF: comments (in a file that starts with one: see comment_inside_data.off) and blank
        # lines anywhere, counts on the OFF line, colours after a face.
        "comments_and_blank_lines.off": (b"# sphere\n" + off.replace(b"\n3 ", b"\n# a face\n\n3 ", 5), n),
        "comment_on_off_line.off": (b"OFF # cube\n3 1 0\n0 0 0\n1 0 0 # x\n0 1 0\n3 0 1 2 # f\n", 1),
        "counts_on_off_line.off": (b"OFF 3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2 255 0 0", 1),
        # STL: upper case (trimesh ignores case), keywords in solid names, two solids, CRLF.
        "upper_case.stl": (stl.upper(), n),
        "keywords_in_names.stl": (stl.replace(b"solid", b"solid facet loop endloop"), n),
        "two_solids.stl": (stl + stl.replace(b"solid", b"solid second"), 2 * n),
        "crlf.stl": (stl.replace(b"\n", b"\r\n").rstrip(), n),
    }
    for name, (data, faces) in files.items():
        path = tmp_path / name
        path.write_bytes(data)
        assert trimesh.load(path, process=False) is not None  # trimesh reads it
        assert sr.load_mesh(path).num_faces == faces, name


def test_glb_with_unpadded_json_chunk_loads(tmp_path):
    # The spec pads chunks to 4 bytes, but trimesh writes and reads GLBs whose
    # JSON chunk is not padded; the pre-check looked for the BIN chunk at the padded offset.
    sphere = trimesh.creation.icosphere(subdivisions=2)
    path = tmp_path / "unpadded_json.glb"
    path.write_bytes(_unpadded_glb(sphere))
    assert struct.unpack("<I", path.read_bytes()[12:16])[0] % 4 != 0
    assert len(trimesh.load(path, process=False).dump()[0].faces) == len(sphere.faces)
    assert sr.load_mesh(path).num_faces == len(sphere.faces)


def test_obj_whose_textured_parts_need_pillow(tmp_path):
    # Two materials (one missing from the file), with uvs: trimesh merges the
    # parts' textures with Pillow, and without it ModuleNotFoundError escaped load_mesh. Pillow
    # is a dependency now; without it, the ValueError names the file and the module.
    v = b"v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nvt 0 0\nvt 1 0\nvt 0 1\nvt 1 1\n"
    path = tmp_path / "usemtl_missing_material.obj"
    path.write_bytes(v + b"usemtl a\nf 1/1 2/2 3/3\nusemtl b\nf 2/2 4/4 3/3\n")
    try:
        import PIL  # noqa: F401
    except ImportError:
        with pytest.raises(ValueError, match="usemtl_missing_material.obj.*PIL.*pip install pillow"):
            sr.load_mesh(path)
    else:
        assert sr.load_mesh(path).num_faces == 2
