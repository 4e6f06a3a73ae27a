"""Frame.save / Frame.load: every output in every format it offers round-trips
exactly (jpg and png16mm, lossy by nature, within their stated error), the defaults, the id
storage (id + 1 in 16-bit PNGs, the id itself in TIFF beyond 65534), reproducible bytes."""
from __future__ import annotations

import os

import numpy as np
import pytest
import trimesh

import softrast as sr
from softrast.frame import _SAVE_FORMATS


def _frame(instance_id=5):
    tm = trimesh.creation.icosphere(subdivisions=3)
    scene = sr.Scene()
    scene.add(sr.Mesh(tm.vertices, tm.faces, uvs=np.asarray(tm.vertices)[:, :2] * 0.5 + 0.5),
              instance_id=instance_id)
    cam = sr.PerspectiveCamera(fov_y=45.0, width=40, height=30)
    cam.look_at((0.0, 0.5, 3.0), (0.0, 0.0, 0.0))
    return sr.Renderer(40, 30).render(scene, cam, outputs=sr.OUTPUTS)


def test_defaults_round_trip_exactly(tmp_path):
    frame = _frame()
    paths = frame.save(tmp_path, "000007")
    assert set(paths) == set(sr.OUTPUTS)
    exts = {name: os.path.splitext(p)[1] for name, p in paths.items()}
    assert exts["color"] == exts["mask"] == exts["instance_id"] == exts["triangle_id"] == ".png"
    assert exts["depth"] == exts["normal"] == exts["uv"] == exts["position"] == ".tif"
    assert exts["coverage"] == ".tif"
    back = sr.Frame.load(tmp_path, "000007")
    for name in sr.OUTPUTS:
        got, want = getattr(back, name), getattr(frame, name)
        assert got.dtype == want.dtype and got.shape == want.shape, name
        np.testing.assert_array_equal(got, want, err_msg=name)


@pytest.mark.parametrize("name", sr.OUTPUTS)
def test_every_format_of_every_output(tmp_path, name):
    frame = _frame()
    want = getattr(frame, name)
    for fmt in _SAVE_FORMATS[name]:
        d = tmp_path / fmt
        d.mkdir()
        frame.save(d, "f", formats={name: fmt})
        got = getattr(sr.Frame.load(d, "f"), name)
        if fmt == "jpg":
            assert np.abs(got.astype(int) - want).mean() < 3
        elif fmt == "png16mm":  # millimetres: within half a millimetre where hit
            hit = want > 0
            assert (got[~hit] == 0).all() and np.abs(got[hit] - want[hit]).max() <= 0.0005 + 1e-6
        else:
            assert got.dtype == want.dtype, (name, fmt)
            np.testing.assert_array_equal(got, want, err_msg=f"{name} as {fmt}")


def test_large_ids_go_to_tiff_and_bytes_are_reproducible(tmp_path):
    frame = _frame(instance_id=70000)
    paths = frame.save(tmp_path, "a")
    assert paths["instance_id"].endswith(".tif")
    np.testing.assert_array_equal(sr.Frame.load(tmp_path, "a").instance_id, frame.instance_id)
    with pytest.raises(ValueError, match="outside -1..65534"):
        frame.save(tmp_path, "b", formats={"instance_id": "png16"})
    (tmp_path / "again").mkdir()
    again = frame.save(tmp_path / "again", "a")
    for name, path in paths.items():
        with open(path, "rb") as f1, open(again[name], "rb") as f2:
            assert f1.read() == f2.read(), name


def test_save_checks_its_arguments(tmp_path):
    frame = sr.Renderer(8, 8).render(sr.Scene(), sr.PerspectiveCamera(width=8, height=8),
                                     outputs=("color", "depth"))
    with pytest.raises(ValueError, match="cannot be saved as 'png'"):
        frame.save(tmp_path, "x", formats={"depth": "png"})
    with pytest.raises(ValueError, match="not an output of this frame"):
        frame.save(tmp_path, "x", formats={"normal": "exr"})
    with pytest.raises(ValueError, match="stem"):
        frame.save(tmp_path, "a/b")
    with pytest.raises(FileNotFoundError):
        frame.save(tmp_path / "missing", "x")
    with pytest.raises(FileNotFoundError, match="no outputs"):
        sr.Frame.load(tmp_path, "nothing")
    assert not [p for p in os.listdir(tmp_path) if p.startswith(".")]  # no temporaries left


@pytest.mark.parametrize("name, array, match", [
    ("depth", np.zeros((30, 40), np.float64), "float32"),             # wrong dtype
    ("depth", np.zeros((30, 40, 3), np.float32), r"\(30, 40, 3\)"),   # wrong shape
    ("color", np.zeros((30, 40), np.uint8), r"\(30, 40\)"),            # colour without channels
    ("color", np.zeros((30, 40, 4), np.uint8), r"\(30, 40, 4\)"),
    ("instance_id", np.zeros((30, 40), np.int64), "int64"),
    ("mask", np.zeros((30, 40), np.uint8), "uint8"),
    ("uv", np.zeros((30, 40, 3), np.float32), r"\(30, 40, 3\)"),
    ("depth", np.zeros((12, 40), np.float32), r"\(12, 40\)"),          # not the frame's (h, w)
    ("depth", np.zeros((5,), np.float32), r"\(5,\)"),
    ("depth", np.array(["a", "b"]), "<U1"),
])
def test_load_checks_npy_files_against_the_output_table(tmp_path, name, array, match):
    """A .npy of the wrong dtype, shape or size is refused, naming the file."""
    _frame().save(tmp_path, "f")
    for p in tmp_path.glob(f"f_{name}.*"):  # only the .npy holds this output
        p.unlink()
    np.save(tmp_path / f"f_{name}.npy", array)
    with pytest.raises(ValueError, match=rf"f_{name}\.npy.*{match}"):
        sr.Frame.load(tmp_path, "f")


@pytest.mark.parametrize("content", [b"", b"\x93NUMPY", b"not a npy file at all", "truncated", "pickle"])
def test_load_refuses_broken_npy_files(tmp_path, content):
    frame = _frame()
    frame.save(tmp_path, "f", formats={"depth": "npy"})
    path = tmp_path / "f_depth.npy"
    if content == "truncated":
        content = path.read_bytes()[:-10]
    elif content == "pickle":
        np.save(path, np.array([{"a": 1}], dtype=object), allow_pickle=True)
        content = path.read_bytes()
    path.write_bytes(content)
    with pytest.raises(ValueError, match=r"f_depth\.npy"):
        sr.Frame.load(tmp_path, "f")


def test_load_checks_images_against_the_output_table(tmp_path):
    """An image file of the wrong pixel type, channel count or size is refused, naming it."""
    frame = _frame()
    frame.save(tmp_path, "f", formats={"depth": "exr"})
    sr.imwrite(tmp_path / "f_depth.exr", np.zeros((30, 40, 3), np.float32))
    with pytest.raises(ValueError, match=r"f_depth\.exr.*\(30, 40, 3\)"):
        sr.Frame.load(tmp_path, "f")
    os.remove(tmp_path / "f_depth.exr")  # the default save writes f_depth.tif
    frame.save(tmp_path, "f")
    sr.imwrite(tmp_path / "f_color.png", np.zeros((30, 40, 3), np.uint16))  # 16-bit colour
    with pytest.raises(ValueError, match=r"f_color\.png.*uint16"):
        sr.Frame.load(tmp_path, "f")
    frame.save(tmp_path, "f")
    sr.imwrite(tmp_path / "f_mask.png", np.zeros((20, 40), np.uint8))  # another size
    with pytest.raises(ValueError, match=r"f_mask\.png.*\(20, 40\)"):
        sr.Frame.load(tmp_path, "f")
    frame.save(tmp_path, "f")
    sr.imwrite(tmp_path / "f_normal.png", np.zeros((30, 40, 3), np.uint8))  # a format save never uses
    with pytest.raises(ValueError, match=r"f_normal\.png"):
        sr.Frame.load(tmp_path, "f")


def test_load_refuses_two_files_of_one_output(tmp_path):
    """A stale .png beside the .tif of the same output (saved again in another format): which
    one is the frame's is ambiguous, so Frame.load names both rather than pick one."""
    frame = _frame()
    frame.save(tmp_path, "f")
    frame.save(tmp_path, "f", formats={"instance_id": "tif"})
    with pytest.raises(ValueError, match=r"f_instance_id\.png.*f_instance_id\.tif|"
                                         r"f_instance_id\.tif.*f_instance_id\.png"):
        sr.Frame.load(tmp_path, "f")
    os.remove(tmp_path / "f_instance_id.png")
    np.testing.assert_array_equal(sr.Frame.load(tmp_path, "f").instance_id, frame.instance_id)
