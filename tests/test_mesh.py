"""Mesh validation, trimesh conversion and file loading (checked against an independent OBJ parse)."""
from __future__ import annotations

import pathlib
import pickle
import subprocess
import sys
import types

import numpy as np
import pytest
import trimesh

import softrast as sr
from softrast import load_mesh
from softrast.mesh import Mesh

SPOT_PATH = pathlib.Path(__file__).resolve().parents[1] / "assets" / "meshes" / "spot.obj"
TRI_POS = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]
TRI_FACES = [[0, 1, 2], [0, 2, 3]]


def test_stores_float32_int32_read_only_copies():
    pos = np.array(TRI_POS, dtype=np.float64)
    faces = np.array(TRI_FACES, dtype=np.int64)
    mesh = Mesh(pos, faces)
    assert mesh.positions.dtype == np.float32 and mesh.positions.flags.c_contiguous
    assert mesh.faces.dtype == np.int32 and mesh.faces.flags.c_contiguous
    np.testing.assert_array_equal(mesh.positions, pos)
    np.testing.assert_array_equal(mesh.faces, faces)
    assert (mesh.num_vertices, mesh.num_faces) == (4, 2)
    assert mesh.normals is None and mesh.uvs is None and mesh.colors is None
    assert mesh.color == (0.8, 0.8, 0.8, 1.0)
    with pytest.raises(ValueError):
        mesh.positions[0, 0] = 5.0  # read-only: the cached C++ upload can never go stale
    with pytest.raises(ValueError):
        mesh.faces[0, 0] = 1


def test_copies_even_float32_input():
    pos = np.array(TRI_POS, dtype=np.float32)
    mesh = Mesh(pos, TRI_FACES)
    pos[0, 0] = 9.0
    assert mesh.positions[0, 0] == 0.0
    assert pos.flags.writeable  # the caller's array is untouched


def test_non_contiguous_input():
    pos = np.asfortranarray(np.array(TRI_POS))[:, [2, 1, 0]]
    faces = np.array(TRI_FACES, dtype=np.uint16)
    mesh = Mesh(pos, faces)
    assert mesh.positions.flags.c_contiguous
    np.testing.assert_array_equal(mesh.positions, pos)


def test_bounds():
    mesh = Mesh([[1, -2, 3], [4, 5, -6], [0, 0, 0]], [[0, 1, 2]])
    np.testing.assert_array_equal(mesh.bounds, [[0, -2, -6], [4, 5, 3]])
    assert mesh.bounds.dtype == np.float64 and mesh.bounds.shape == (2, 3)


def test_vertex_attributes():
    n = len(TRI_POS)
    normals = np.tile([0.0, 0.0, 1.0], (n, 1))
    uvs = np.linspace(0, 1, 2 * n).reshape(n, 2)
    mesh = Mesh(TRI_POS, TRI_FACES, normals=normals, uvs=uvs)
    assert mesh.normals.dtype == np.float32 and mesh.uvs.dtype == np.float32
    np.testing.assert_allclose(mesh.uvs, uvs, rtol=1e-7)


def test_colors_uint8_divided_by_255_and_alpha_added():
    rgb = np.array([[255, 0, 0], [0, 51, 0], [0, 0, 102], [255, 255, 255]], dtype=np.uint8)
    mesh = Mesh(TRI_POS, TRI_FACES, colors=rgb)
    assert mesh.colors.shape == (4, 4) and mesh.colors.dtype == np.float32
    np.testing.assert_allclose(mesh.colors[:, :3], rgb / 255.0, rtol=1e-6)
    np.testing.assert_array_equal(mesh.colors[:, 3], 1.0)


def test_colors_float_rgba_kept():
    rgba = np.random.default_rng(0).random((4, 4))
    mesh = Mesh(TRI_POS, TRI_FACES, colors=rgba)
    np.testing.assert_allclose(mesh.colors, rgba, rtol=1e-6)


def test_color_three_or_four_components():
    assert Mesh(TRI_POS, TRI_FACES, color=(1, 0, 0.5)).color == (1.0, 0.0, 0.5, 1.0)
    color = Mesh(TRI_POS, TRI_FACES, color=np.array([0.1, 0.2, 0.3, 0.4])).color
    assert color == (0.1, 0.2, 0.3, 0.4) and all(type(c) is float for c in color)


GOOD = {"positions": TRI_POS, "faces": TRI_FACES}


@pytest.mark.parametrize("kwargs, error, match", [
    ({"positions": [[0, 0], [1, 0], [0, 1], [1, 1]]}, ValueError, "positions"),
    ({"positions": np.zeros((4, 3, 1))}, ValueError, "positions"),
    ({"positions": [[0, 0, 0], [1, 0, 0], [0, 1]]}, ValueError, "positions"),  # ragged
    ({"positions": np.array([["a", "b", "c"]] * 4)}, TypeError, "positions"),
    ({"positions": np.ones((4, 3), dtype=bool)}, TypeError, "positions"),
    ({"positions": np.ones((4, 3), dtype=complex)}, TypeError, "positions"),
    ({"positions": None}, TypeError, "positions"),
    ({"positions": "abc"}, TypeError, "positions"),
    ({"positions": [[0, 0, 0], [1, 0, 0], [0, np.nan, 0], [0, 0, 1]]}, ValueError,
     "positions contains NaN or inf at vertex 2"),
    ({"positions": [[0, 0, 0], [1, 0, np.inf], [0, 1, 0], [0, 0, 1]]}, ValueError, "at vertex 1"),
    ({"faces": np.array(TRI_FACES, dtype=np.float64)}, TypeError, "faces"),
    ({"faces": np.ones((2, 3), dtype=bool)}, TypeError, "faces"),
    ({"faces": [[0, 1], [1, 2]]}, ValueError, "faces"),
    ({"faces": [[0, 1, -1]]}, ValueError, "faces.*-1"),
    ({"faces": [[0, 1, 4]]}, ValueError, "faces.*4"),
    ({"faces": np.zeros((0, 3), dtype=np.int32)}, ValueError, "mesh is empty"),
    ({"positions": np.zeros((0, 3)), "faces": np.zeros((0, 3), dtype=np.int32)}, ValueError, "mesh is empty"),
    ({"normals": np.zeros((3, 3))}, ValueError, "normals"),
    ({"normals": np.full((4, 3), np.nan)}, ValueError, "normals contains NaN"),
    ({"uvs": np.zeros((4, 3))}, ValueError, "uvs"),
    ({"uvs": np.full((4, 2), np.inf)}, ValueError, "uvs"),
    ({"colors": np.zeros((4, 2))}, ValueError, "colors"),
    ({"colors": np.zeros((3, 4))}, ValueError, "colors"),
    ({"colors": np.full((4, 3), 1.5)}, ValueError, "colors"),
    ({"colors": np.full((4, 3), -0.1)}, ValueError, "colors"),
    ({"colors": np.full((4, 3), np.nan)}, ValueError, "colors"),
    ({"colors": np.full((4, 3), 255, dtype=np.int64)}, TypeError, "colors"),
    ({"color": (1.0, 0.0)}, ValueError, "color"),
    ({"color": (1.0, 0.0, 2.0)}, ValueError, "color"),
    ({"color": (1.0, 0.0, np.nan)}, ValueError, "color"),
    ({"color": "red"}, TypeError, "color"),
])
def test_bad_inputs(kwargs, error, match):
    with pytest.raises(error, match=match):
        Mesh(**{**GOOD, **kwargs})


def test_counts_above_int32_refused():
    # Broadcast views have 2**31 rows without allocating them; the count check comes first.
    huge_pos = np.broadcast_to(np.zeros(3, np.float32), (2**31, 3))
    with pytest.raises(ValueError, match="positions.*2\\*\\*31"):
        Mesh(huge_pos, TRI_FACES)
    huge_faces = np.broadcast_to(np.zeros(3, np.int32), (2**31, 3))
    with pytest.raises(ValueError, match="faces.*2\\*\\*31"):
        Mesh(TRI_POS, huge_faces)


def test_core_data_is_built_once_with_contract_arguments(monkeypatch):
    # A stand-in for the compiled module records the call (argument order of MeshData in _core.pyi).
    calls = []
    fake = types.ModuleType("softrast._core")
    fake.MeshData = lambda *args: calls.append(args) or object()
    import softrast.mesh
    monkeypatch.setattr(softrast.mesh, "_core", fake)  # the module Mesh builds its MeshData with

    colors = np.full((4, 3), 128, np.uint8)
    mesh = Mesh(TRI_POS, TRI_FACES, colors=colors, uvs=np.zeros((4, 2)))
    first = mesh._core_data()
    assert mesh._core_data() is first and len(calls) == 1
    positions, faces, normals, rgba, uvs = calls[0]
    assert positions is mesh.positions and faces is mesh.faces
    assert normals is None and rgba is mesh.colors and uvs is mesh.uvs


def test_core_data_with_compiled_core():
    from softrast import _core

    mesh = Mesh(TRI_POS, TRI_FACES)
    data = mesh._core_data()
    assert isinstance(data, _core.MeshData)
    assert (data.num_vertices, data.num_faces) == (4, 2)


# -- the core views the stored arrays in place ---------------------------------------------------

# A quad at z = -3 filling most of a 16x16 image seen by QUAD_PROJ (camera at the origin).
QUAD_POS = np.array([[-1, -1, -3], [1, -1, -3], [1, 1, -3], [-1, 1, -3]], np.float32)
QUAD_FACES = np.array([[0, 1, 2], [0, 2, 3]], np.int32)
QUAD_PROJ = np.array([[2.4, 0, 0, 0], [0, 2.4, 0, 0], [0, 0, -1, -0.2], [0, 0, -1, 0]])


def _immutable(values: np.ndarray) -> np.ndarray:
    """An array as Mesh stores them: a read-only view of a bytes object."""
    return np.frombuffer(values.tobytes(), values.dtype).reshape(values.shape)


def _bytes_under(arr: np.ndarray) -> object:
    while isinstance(arr, np.ndarray):
        arr = arr.base
    return arr


def _core_render(data) -> dict[str, np.ndarray]:
    from conftest import core_options
    from softrast import _core

    draw = _core.Draw(mesh=data, color=(1.0, 1.0, 1.0, 1.0))
    return _core.Renderer(16, 16, 1).render([draw], core_options(
        np.eye(4), QUAD_PROJ, False, 0.1, 100.0, ["depth", "triangle_id"], cull="none"))


def _attributes_mesh() -> Mesh:
    return Mesh(TRI_POS, TRI_FACES, normals=np.ones((4, 3)), uvs=np.zeros((4, 2)), colors=np.ones((4, 3)))


def test_stored_arrays_can_never_be_made_writeable():
    # The core views them: an edit after validation could send face indices out of range. A
    # read-only array owning its memory could be set writeable again; these view a bytes object.
    mesh = _attributes_mesh()
    for arr in (mesh.positions, mesh.faces, mesh.normals, mesh.uvs, mesh.colors):
        while isinstance(arr, np.ndarray):
            with pytest.raises(ValueError):
                arr.flags.writeable = True
            arr = arr.base
        assert type(arr) is bytes


def test_core_views_the_stored_arrays_instead_of_copying():
    # Each bytes object gains one reference, the core mesh's, and loses it with the core mesh.
    mesh = _attributes_mesh()
    under = [_bytes_under(a) for a in (mesh.positions, mesh.faces, mesh.normals, mesh.uvs, mesh.colors)]
    counts = [sys.getrefcount(b) for b in under]
    data = mesh._core_data()
    assert [sys.getrefcount(b) for b in under] == [c + 1 for c in counts]
    mesh._core = None
    del data
    assert [sys.getrefcount(b) for b in under] == counts


NO_COPY_CHILD = r"""
import numpy as np
from softrast import _core

def rss_mib():
    with open("/proc/self/status") as f:
        return next(int(line.split()[1]) for line in f if line.startswith("VmRSS:")) / 1024

def immutable(a):
    return np.frombuffer(a.tobytes(), a.dtype).reshape(a.shape)

n = 1 << 21  # 24 MiB per array
positions, faces = immutable(np.ones((n, 3), np.float32)), immutable(np.zeros((n, 3), np.int32))
before = rss_mib()
viewed = _core.MeshData(positions, faces)
grown_viewed = rss_mib() - before
writeable = np.ones((n, 3), np.float32)
before = rss_mib()
copied = _core.MeshData(writeable, faces)
print(grown_viewed, rss_mib() - before)
"""


def test_core_mesh_of_immutable_arrays_allocates_no_copy():
    # In a fresh process, so that the copy (when there is one) lands in new pages.
    proc = subprocess.run([sys.executable, "-c", NO_COPY_CHILD], capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    grown_viewed, grown_copied = map(float, proc.stdout.split())
    assert grown_copied > 20  # the measurement sees a 24 MiB copy of positions...
    assert grown_viewed < 4  # ...and there is none of 48 MiB of immutable arrays


def test_edits_to_the_inputs_after_creation_never_reach_a_render():
    # Exact dtype and C-contiguous: Mesh still copies, so the caller's arrays stay theirs.
    positions, faces = QUAD_POS.copy(), QUAD_FACES.copy()
    data = Mesh(positions, faces)._core_data()
    expected = _core_render(data)
    assert (expected["triangle_id"] >= 0).any()
    positions *= 0.5
    faces[:] = 0  # degenerate: would cover nothing
    for name, arr in _core_render(data).items():
        np.testing.assert_array_equal(arr, expected[name])


# Arrays the core must copy: (argument, an array through which its memory can still be written).
def _writeable(a):
    return a, a


def _read_only_owner(a):
    a.setflags(write=False)  # its owner may set it writeable again
    return a, a


def _read_only_view_of_writeable(a):
    view = a.view()
    view.setflags(write=False)
    return view, a


def _strided(a):
    rows = np.repeat(a, 2, axis=0)[::2]
    return rows, rows


def _fortran_order(a):
    f = np.asfortranarray(a)
    return f, f


@pytest.mark.parametrize("kind", [_writeable, _read_only_owner, _read_only_view_of_writeable, _strided,
                                  _fortran_order])
def test_core_copies_arrays_that_could_still_be_written(kind):
    from softrast import _core

    (positions, positions_memory), (faces, faces_memory) = kind(QUAD_POS.copy()), kind(QUAD_FACES.copy())
    counts = sys.getrefcount(positions), sys.getrefcount(faces)
    data = _core.MeshData(positions, faces)
    assert (sys.getrefcount(positions), sys.getrefcount(faces)) == counts  # not kept: copied
    expected = _core_render(_core.MeshData(_immutable(QUAD_POS), _immutable(QUAD_FACES)))
    for memory, values in ((positions_memory, 0.5 * QUAD_POS), (faces_memory, 0)):
        memory.setflags(write=True)
        memory[...] = values  # faces all 0: degenerate, would cover nothing
    for name, arr in _core_render(data).items():
        np.testing.assert_array_equal(arr, expected[name])


def test_core_copies_misaligned_immutable_arrays():
    # Immutable but not aligned for float / int32 loads => copied (UBSan checks the loads).
    from softrast import _core

    def misaligned(a):
        return np.frombuffer(b"\0" + a.tobytes(), a.dtype, offset=1).reshape(a.shape)

    positions, faces = misaligned(QUAD_POS), misaligned(QUAD_FACES)
    assert not positions.flags.aligned and not faces.flags.aligned
    expected = _core_render(_core.MeshData(_immutable(QUAD_POS), _immutable(QUAD_FACES)))
    for name, arr in _core_render(_core.MeshData(positions, faces)).items():
        np.testing.assert_array_equal(arr, expected[name])


@pytest.mark.parametrize("where", [0, 1, 1365, 1366, 2999])  # the core scans 4096 values a block
def test_core_validation_reports_the_first_bad_value(where):
    # The core checks what it views itself (sr.Mesh checks first, _core.MeshData may be called
    # directly); its block-wise scans must still name the first offending vertex and index.
    from softrast import _core

    n = 3000
    positions = np.zeros((n, 3), np.float32)
    faces = np.tile(np.array([[0, 1, 2]], np.int32), (n, 1))
    for value in (np.nan, np.inf, -np.inf):
        bad = positions.copy()
        bad[where, 2] = value
        bad[min(where + 700, n - 1), 0] = np.nan  # a later one is not the one reported
        with pytest.raises(ValueError, match=f"positions contains NaN or inf at vertex {where}$"):
            _core.MeshData(bad, faces)
    for index in (-1, n, 2**31 - 1, -2**31):
        bad = faces.copy()
        bad[where, 1] = index
        bad[min(where + 900, n - 1), 2] = n + 5
        with pytest.raises(ValueError, match=rf"faces: index {index} in face {where} is outside \[0, {n}\)"):
            _core.MeshData(positions, bad)
    for name, cols in (("normals", 3), ("colors", 4), ("uvs", 2)):
        values = np.zeros((n, cols), np.float32)
        values[where, cols - 1] = np.nan
        args = {"normals": None, "colors": None, "uvs": None, name: values}
        with pytest.raises(ValueError, match=f"{name} contains NaN or inf"):
            _core.MeshData(positions, faces, args["normals"], args["colors"], args["uvs"])
    _core.MeshData(positions, faces, np.ones((n, 3), np.float32), np.ones((n, 4), np.float32),
                   np.ones((n, 2), np.float32))  # all finite, all in range: accepted


# -- trimesh ------------------------------------------------------------------------------------

def test_from_trimesh_icosphere():
    tm = trimesh.creation.icosphere(subdivisions=2)
    mesh = Mesh.from_trimesh(tm)
    np.testing.assert_allclose(mesh.positions, tm.vertices, rtol=1e-6)
    np.testing.assert_array_equal(mesh.faces, tm.faces)
    # Vertex normals of a unit sphere are the positions themselves.
    np.testing.assert_allclose(mesh.normals, tm.vertices, atol=0.05)
    np.testing.assert_allclose(np.linalg.norm(mesh.normals, axis=1), 1.0, rtol=1e-5)
    assert mesh.uvs is None and mesh.colors is None
    flat = Mesh.from_trimesh(tm, smooth=False, color=(1, 0, 0))
    assert flat.normals is None and flat.color == (1.0, 0.0, 0.0, 1.0)


def test_from_trimesh_vertex_colors():
    tm = trimesh.creation.icosphere(subdivisions=1)
    rgba = np.random.default_rng(1).integers(0, 256, (len(tm.vertices), 4), dtype=np.uint8)
    tm.visual.vertex_colors = rgba
    mesh = Mesh.from_trimesh(tm)
    np.testing.assert_allclose(mesh.colors, rgba / 255.0, rtol=1e-6)


def test_from_trimesh_uvs():
    tm = trimesh.creation.box()
    uv = np.random.default_rng(2).random((len(tm.vertices), 2))
    tm.visual = trimesh.visual.TextureVisuals(uv=uv)
    mesh = Mesh.from_trimesh(tm)
    np.testing.assert_allclose(mesh.uvs, uv, rtol=1e-6)


def test_from_trimesh_scene_concatenates_with_transforms():
    box = trimesh.creation.box()
    sphere = trimesh.creation.icosphere(subdivisions=1)
    scene = trimesh.Scene()
    scene.add_geometry(box)
    scene.add_geometry(sphere, transform=trimesh.transformations.translation_matrix([10.0, 0, 0]))
    mesh = Mesh.from_trimesh(scene)
    assert mesh.num_faces == len(box.faces) + len(sphere.faces)
    assert mesh.num_vertices == len(box.vertices) + len(sphere.vertices)
    np.testing.assert_allclose(mesh.bounds, [[-0.5, -1, -1], [11, 1, 1]], atol=1e-6)


def test_from_trimesh_rejects_other_types():
    with pytest.raises(TypeError, match="tm"):
        Mesh.from_trimesh(trimesh.PointCloud(np.zeros((3, 3))))
    with pytest.raises(ValueError, match="tm"):
        Mesh.from_trimesh(trimesh.Scene())


def parse_obj(path):
    """Independent minimal OBJ reader: 'v' positions and the position index of each 'f' corner."""
    verts, faces = [], []
    with open(path) as f:
        for line in f:
            parts = line.split()
            if not parts:
                continue
            if parts[0] == "v":
                verts.append([float(x) for x in parts[1:4]])
            elif parts[0] == "f":
                faces.append([int(c.split("/")[0]) - 1 for c in parts[1:]])
    return np.array(verts), np.array(faces)


def test_load_mesh_spot():
    mesh = load_mesh(SPOT_PATH)
    verts, faces = parse_obj(SPOT_PATH)
    assert mesh.num_faces == 5856 == len(faces)
    # trimesh splits vertices at uv seams, but every triangle keeps its corners and order.
    np.testing.assert_allclose(mesh.positions[mesh.faces], verts[faces], rtol=0, atol=1e-6)
    assert mesh.uvs is not None and mesh.uvs.shape == (mesh.num_vertices, 2)
    np.testing.assert_allclose(np.linalg.norm(mesh.normals, axis=1), 1.0, rtol=1e-4)
    assert load_mesh(str(SPOT_PATH), smooth=False).normals is None


def test_load_mesh_missing(tmp_path):
    path = tmp_path / "nope.obj"
    with pytest.raises(FileNotFoundError, match="nope.obj"):
        load_mesh(path)


def test_load_mesh_corrupt(tmp_path):
    path = tmp_path / "bad.ply"
    path.write_bytes(b"garbage\x00\x01")
    with pytest.raises(ValueError, match="could not load mesh.*bad.ply.*not a PLY file"):
        load_mesh(path)
    obj = tmp_path / "bad.obj"  # no header to check => trimesh's own error, chained
    obj.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 x\n")
    with pytest.raises(ValueError, match="could not load mesh.*bad.obj") as info:
        load_mesh(obj)
    assert info.value.__cause__ is not None


@pytest.mark.parametrize("name, text", [
    ("points.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\n"),
    ("empty.stl", "solid x\nendsolid x\n"),
])
def test_load_mesh_without_triangles(tmp_path, name, text):
    path = tmp_path / name
    path.write_text(text)
    with pytest.raises(ValueError, match=name):
        load_mesh(path)


# -- values beyond float32, precision far from the origin -------------------------------------

FLT_MAX = float(np.finfo(np.float32).max)


@pytest.mark.parametrize("name, cols", [("positions", 3), ("normals", 3), ("uvs", 2)])
@pytest.mark.parametrize("value", [1e39, -1e39, 1e300, np.longdouble(FLT_MAX) * 2])
def test_finite_values_beyond_float32_are_refused_by_name_and_vertex(name, cols, value):
    # float32 would store them as inf: the mesh used to be built and fail only at render time.
    arrays = {"positions": np.array(TRI_POS), "normals": np.ones((4, 3)), "uvs": np.zeros((4, 2))}
    bad = arrays[name].astype(np.result_type(arrays[name], value))
    bad[2, cols - 1] = value
    bad[3, 0] = value  # a later one is not the one reported
    arrays[name] = bad
    with pytest.raises(ValueError, match=rf"^{name} has a value beyond float32's range .* at vertex 2: "):
        Mesh(arrays["positions"], TRI_FACES, normals=arrays["normals"], uvs=arrays["uvs"])


def test_largest_float32_is_accepted_and_values_rounding_to_it_too():
    # Round to nearest: up to half a float32 step above FLT_MAX still rounds to FLT_MAX, not inf.
    half_step = 2.0**103  # float32 steps are 2**104 in the top binade
    pos = np.array([[0.0, 0.0, 0.0], [FLT_MAX, 0.0, 0.0], [0.0, FLT_MAX + half_step * 0.99, 0.0]])
    mesh = Mesh(pos, [[0, 1, 2]])
    assert mesh.positions[1, 0] == mesh.positions[2, 1] == np.float32(FLT_MAX)
    with pytest.raises(ValueError, match="positions has a value beyond float32's range .* at vertex 2"):
        Mesh(pos + [[0, 0, 0], [0, 0, 0], [0, half_step * 1.01, 0]], [[0, 1, 2]])


def test_colors_beyond_float32_refused_as_out_of_range():
    with pytest.raises(ValueError, match="colors must be uint8 or float in \\[0, 1\\]"):
        Mesh(TRI_POS, TRI_FACES, colors=np.full((4, 3), 1e39))


def _sphere_at(offset: float, dtype=np.float64) -> np.ndarray:
    """A unit icosphere's vertices (irrational: float32 rounds every one) moved by ``offset``."""
    return (np.asarray(trimesh.creation.icosphere(subdivisions=2).vertices) + offset).astype(dtype)


@pytest.mark.parametrize("offset", [0.0, -3.0, 100.0, 1e3, 1e4, -3e4, 1e5, 1e7])
def test_precision_warning_when_float32_moves_vertices(offset):
    """PrecisionWarning exactly when a stored vertex moved by > 1e-4 of the bounding-box diagonal."""
    from softrast.mesh import PRECISION_WARNING_FRACTION

    given = _sphere_at(offset)
    faces = trimesh.creation.icosphere(subdivisions=2).faces
    moved = np.abs(given.astype(np.float32).astype(np.float64) - given).max()
    diagonal = np.linalg.norm(np.ptp(given, axis=0))
    expected = moved > PRECISION_WARNING_FRACTION * diagonal
    assert expected == (abs(offset) >= 1e4)  # the cases span both sides of the threshold
    if expected:
        with pytest.warns(sr.PrecisionWarning, match=r"positions: storing them as float32 moved vertex "
                          r"\d+ by .* bounding-box diagonal .*Centre the mesh .*pose") as record:
            mesh = Mesh(given, faces)
        assert len(record) == 1 and record[0].filename == __file__  # points at the caller
    else:  # filterwarnings = error: any warning fails the test
        mesh = Mesh(given, faces)
    np.testing.assert_array_equal(mesh.positions, given.astype(np.float32))  # stored all the same


def test_precision_warning_is_public_and_specific():
    assert "PrecisionWarning" in sr.__all__ and issubclass(sr.PrecisionWarning, UserWarning)
    with pytest.warns(sr.PrecisionWarning):
        mesh = Mesh(_sphere_at(1e7), trimesh.creation.icosphere(subdivisions=2).faces)
    # At 1e7 float32 steps are 1.0: a sphere of radius 1 has 3 values per axis left, and its 162
    # vertices collapse onto at most 3**3 points.
    assert len(np.unique(mesh.positions, axis=0)) <= 27


def test_same_offset_in_the_pose_renders_correctly():
    # What the warning suggests: the centred mesh with the offset in the (float64) pose renders
    # as the mesh at the origin does, seen from the same relative viewpoint.
    faces = trimesh.creation.icosphere(subdivisions=2).faces
    offset = np.array([1e7, -2e7, 5e6])
    renders = []
    for where in (np.zeros(3), offset):
        scene = sr.Scene()
        pose = np.eye(4)
        pose[:3, 3] = where
        scene.add(Mesh(_sphere_at(0.0), faces), pose=pose)
        cam = sr.PerspectiveCamera(fov_y=50.0)
        cam.look_at(eye=where + (0.0, 0.0, 3.0), target=where)
        renders.append(sr.Renderer(48, 48).render(scene, cam, outputs=("mask", "depth")))
    np.testing.assert_array_equal(renders[0].mask, renders[1].mask)
    np.testing.assert_allclose(renders[0].depth, renders[1].depth, atol=1e-5)


@pytest.mark.parametrize("given", [
    _sphere_at(1e7, np.float32),  # float32 input: stored exactly, nothing lost here
    np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]]) + 10**6,  # integers below 2**24 are exact
    np.array([[0.0, 0.0, 1e7], [1.0, 0.0, 1e7], [0.0, 1.0, 1e7]]),  # a plane at an exact 1e7
    np.full((3, 3), 1e7 + 0.3),  # a single point: no size to distort
])
def test_no_precision_warning_when_nothing_moves(given):
    Mesh(given, [[0, 1, 2]] if len(given) == 3 else trimesh.creation.icosphere(subdivisions=2).faces)


def test_suite_and_example_meshes_do_not_warn():
    # Under filterwarnings = error any PrecisionWarning fails this: spot.obj, the primitives the
    # tests and examples use, example 01's triangle and the soak test's random grids.
    load_mesh(SPOT_PATH)
    for tm in (trimesh.creation.icosphere(subdivisions=4), trimesh.creation.box(extents=(1.2, 1.2, 1.2)),
               trimesh.creation.cylinder(radius=0.5, height=2.0)):
        Mesh.from_trimesh(tm)
    Mesh([[-0.8, -0.6, 0.0], [0.8, -0.6, 0.0], [0.0, 0.7, 0.0]], [[0, 1, 2]])
    import importlib.util

    spec = importlib.util.spec_from_file_location("soak", SPOT_PATH.parents[2] / "benchmarks" / "soak.py")
    soak = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(soak)
    rng = np.random.default_rng(5)
    for _ in range(20):
        soak.random_mesh(rng)


# -- validation in chunks: same results, first bad value named ---------------------------------

CHUNK = 2**16


@pytest.mark.parametrize("where", [0, CHUNK - 1, CHUNK, CHUNK + 1, 2 * CHUNK + 5])
def test_chunked_validation_reports_the_first_bad_value(where):
    n = 2 * CHUNK + 10
    positions = np.zeros((n, 3))
    faces = np.tile(np.array([[0, 1, 2]]), (n, 1))
    later = min(where + CHUNK, n - 1)  # a later bad value, usually in another chunk
    for value, message in ((np.nan, "contains NaN or inf"), (-np.inf, "contains NaN or inf"),
                           (1e39, "has a value beyond float32's range")):
        for name in ("positions", "normals", "uvs"):
            arrays = {"positions": positions, "normals": np.ones((n, 3)), "uvs": np.zeros((n, 2))}
            bad = arrays[name].copy()
            bad[where, 1] = value
            bad[later, 0] = np.nan
            arrays[name] = bad
            with pytest.raises(ValueError, match=rf"^{name} {message}.* at vertex {where}\b"):
                Mesh(arrays["positions"], faces, normals=arrays["normals"], uvs=arrays["uvs"])
    for index in (-1, n, 2**40, -2**40):
        bad = faces.copy()
        bad[where, 2] = index
        bad[later, 0] = n + 7
        with pytest.raises(ValueError, match=rf"^faces: index {index} in face {where} is outside \[0, {n}\)"):
            Mesh(positions, bad)
    colors = np.full((n, 4), 0.5)
    colors[where, 3] = np.nan
    with pytest.raises(ValueError, match=f"^colors contains NaN or inf at vertex {where}$"):
        Mesh(positions, faces, colors=colors)
    colors[where, 3] = 1.5
    with pytest.raises(ValueError, match="colors must be uint8 or float in \\[0, 1\\]"):
        Mesh(positions, faces, colors=colors)


@pytest.mark.parametrize("n", [5, CHUNK, 3 * CHUNK + 17])
def test_chunked_conversion_is_bit_identical_to_a_plain_cast(n, rng):
    positions = rng.normal(size=(n, 3)) * 10.0
    faces = rng.integers(0, n, size=(2 * n, 3), dtype=np.int64)
    normals = rng.normal(size=(n, 3))
    uvs = rng.random((n, 2)).astype(np.float16)
    rgb8 = rng.integers(0, 256, size=(n, 3), dtype=np.uint8)
    rgba = rng.random((n, 4))
    mesh = Mesh(positions[::-1].astype(">f8"), faces.astype(">i8"), normals=np.asfortranarray(normals),
                uvs=uvs, colors=rgb8)  # byte-swapped, reversed, Fortran-ordered, float16
    np.testing.assert_array_equal(mesh.positions, positions[::-1].astype(np.float32))
    np.testing.assert_array_equal(mesh.faces, faces.astype(np.int32))
    np.testing.assert_array_equal(mesh.normals, normals.astype(np.float32))
    np.testing.assert_array_equal(mesh.uvs, uvs.astype(np.float32))
    expected = np.ones((n, 4), np.float32)
    expected[:, :3] = rgb8.astype(np.float32) / np.float32(255.0)
    np.testing.assert_array_equal(mesh.colors, expected)
    np.testing.assert_array_equal(Mesh(positions, faces, colors=rgba).colors, rgba.astype(np.float32))
    for arr in (mesh.positions, mesh.faces, mesh.normals, mesh.uvs, mesh.colors):
        assert arr.flags.c_contiguous and not arr.flags.writeable and type(_bytes_under(arr)) is bytes
        with pytest.raises(ValueError):
            arr.flags.writeable = True


# -- copy and pickle ---------------------------------------------------------------------------

def _render_all(mesh: Mesh) -> dict[str, np.ndarray]:
    scene = sr.Scene()
    scene.add(mesh)
    cam = sr.PerspectiveCamera(fov_y=50.0)
    cam.look_at(eye=(0.5, 0.4, 3.5), target=(0.0, 0.0, 0.0))
    return sr.Renderer(64, 48).render(scene, cam, outputs=sr.OUTPUTS).as_dict()


def _full_mesh() -> Mesh:
    tm = trimesh.creation.icosphere(subdivisions=3)
    n = len(tm.vertices)
    return Mesh(tm.vertices, tm.faces, normals=tm.vertex_normals, uvs=tm.vertices[:, :2] * 0.5 + 0.5,
                colors=np.linspace(0, 255, 3 * n).reshape(n, 3).astype(np.uint8), color=(0.2, 0.4, 0.6))


def test_copy_and_deepcopy_return_the_immutable_mesh_itself():
    import copy

    mesh = _full_mesh()
    assert copy.copy(mesh) is mesh and copy.deepcopy(mesh) is mesh
    scene = sr.Scene()
    scene.add(mesh)
    assert copy.deepcopy(scene).instances[0].mesh is mesh  # meshes are shared, never duplicated
    assert copy.deepcopy([mesh, mesh])[1] is mesh


@pytest.mark.parametrize("protocol", range(2, pickle.HIGHEST_PROTOCOL + 1))
@pytest.mark.parametrize("rendered_first", [False, True])
def test_pickle_round_trip_is_read_only_and_renders_identically(protocol, rendered_first):
    mesh = _full_mesh()
    before = _render_all(mesh) if rendered_first else None  # the core upload is not pickled
    clone = pickle.loads(pickle.dumps(mesh, protocol=protocol))
    assert type(clone) is Mesh and clone is not mesh and clone.color == mesh.color
    for name in ("positions", "faces", "normals", "uvs", "colors"):
        arr, original = getattr(clone, name), getattr(mesh, name)
        assert arr.dtype == original.dtype and arr.flags.c_contiguous
        np.testing.assert_array_equal(arr, original)
        assert not arr.flags.writeable
        with pytest.raises(ValueError):
            arr[0, 0] = 0
        with pytest.raises(ValueError):
            arr.flags.writeable = True
        assert type(_bytes_under(arr)) is bytes  # so the core views it in place
    for name, want in (before or _render_all(mesh)).items():
        np.testing.assert_array_equal(_render_all(clone)[name], want, err_msg=name)


def test_unpickled_mesh_is_validated():
    # Unpickling goes through the constructor: a tampered pickle cannot reach the core.
    mesh = Mesh(TRI_POS, TRI_FACES)
    state = pickle.dumps(mesh, protocol=4)
    good = np.asarray(TRI_FACES, np.int32).tobytes()
    bad = np.array([[0, 1, 2], [0, 2, 9]], np.int32).tobytes()
    assert state.count(good) == 1
    with pytest.raises(ValueError, match=r"faces: index 9 in face 1 is outside \[0, 4\)"):
        pickle.loads(state.replace(good, bad))


def test_precision_warning_for_coordinates_too_small_for_float32():
    # 1e-43 is subnormal in float32 (steps of 1.4e-45): the triangle is distorted, not far away.
    with pytest.warns(sr.PrecisionWarning, match=r"too small for float32\. Scale the mesh up"):
        Mesh(np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.3, 1.0, 0.0]]) * 1.234567e-43, [[0, 1, 2]])
    with pytest.warns(sr.PrecisionWarning, match=r"too small"):  # 1e-300 rounds to 0: collapses
        Mesh(np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]) * 1e-300, [[0, 1, 2]])


def test_precision_warning_from_load_mesh_names_the_file(tmp_path):
    # A mesh file in world coordinates (a 1-unit triangle fan 1e7 units out): the warning says
    # which file, since it is raised from inside the package.
    path = tmp_path / "far.obj"
    path.write_text("v 1e7 1e7 0\nv 10000001.3 1e7 0\nv 1e7 10000001.7 0\nv 10000001.1 10000001.9 0.5\n"
                    "f 1 2 3\nf 2 4 3\n")
    with pytest.warns(sr.PrecisionWarning, match=r"far\.obj: positions"):
        sr.load_mesh(path)
    with pytest.warns(sr.PrecisionWarning) as caught:  # a Mesh made directly names no file
        sr.Mesh(np.array([[1e7, 1e7, 0], [1e7 + 1.3, 1e7, 0], [1e7, 1e7 + 1.7, 0]]), [[0, 1, 2]])
    assert "far.obj" not in str(caught[0].message)
