"""write_dataset and cameras.json: every view written as Frame.save writes it,
equal to render(); cameras.json read back by load_cameras into cameras that project the same;
resume after an interruption rewrites only what is missing."""
from __future__ import annotations

import json
import os
import time
from pathlib import Path

import numpy as np
import pytest
import trimesh

import softrast as sr

OUTPUTS = ("color", "depth", "instance_id")


def _scene():
    tm = trimesh.creation.icosphere(subdivisions=3)
    scene = sr.Scene()
    scene.add(sr.Mesh(tm.vertices, tm.faces), instance_id=2)
    scene.add(sr.Mesh(tm.vertices * 0.4, tm.faces), pose=np.array(
        [[1, 0, 0, 1.3], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1.0]]), instance_id=6)
    return scene


def _cams(n=6, w=48, h=36):
    cams = []
    for pose in sr.orbit((0.3, 0.0, 0.0), 4.0, n, elevation=20.0):
        cam = sr.PerspectiveCamera(fov_y=45.0, width=w, height=h, near=0.1, far=20.0)
        cam.pose = pose
        cams.append(cam)
    return cams


def test_write_dataset_writes_what_render_gives(tmp_path):
    scene, cams = _scene(), _cams()
    r = sr.Renderer(48, 36, threads=2)
    paths = sr.write_dataset(scene, cams, tmp_path, outputs=OUTPUTS, renderer=r, progress=True)
    assert len(paths) == 6 and all(set(p) == set(OUTPUTS) for p in paths)
    for k, cam in enumerate(cams):
        back = sr.Frame.load(tmp_path, f"{k:06d}")
        ref = r.render(scene, cam, outputs=OUTPUTS)
        for name in OUTPUTS:
            np.testing.assert_array_equal(getattr(back, name), getattr(ref, name))
    doc = json.loads((tmp_path / "cameras.json").read_text())
    assert doc["format"] == "softrast cameras 1" and len(doc["frames"]) == 6
    assert doc["frames"][3]["files"]["color"] == "000003_color.png"
    loaded = sr.load_cameras(tmp_path)
    pts = np.random.default_rng(0).normal(size=(40, 3))
    for cam, again in zip(cams, loaded):
        assert isinstance(again, sr.IntrinsicsCamera) and again.convention == "opencv"
        np.testing.assert_allclose(again.K, cam.K, atol=1e-9)
        np.testing.assert_allclose(again.project(pts), cam.project(pts), atol=1e-9)
        # the recorded pose in either convention is the camera's
        np.testing.assert_allclose(again.view_matrix(), cam.view_matrix(), atol=1e-12)
        f1 = r.render(scene, cam, outputs=("instance_id",)).instance_id
        f2 = r.render(scene, again, outputs=("instance_id",)).instance_id
        assert (f1 == f2).mean() > 0.995


def test_orthographic_cameras_round_trip(tmp_path):
    cam = sr.OrthographicCamera(xmag=2.0, ymag=1.5, width=40, height=30, near=0.5, far=9.0)
    cam.look_at((0.0, 1.0, 4.0), (0.0, 0.0, 0.0))
    sr.write_dataset(_scene(), [cam], tmp_path, outputs=("depth",))
    (again,) = sr.load_cameras(tmp_path / "cameras.json")
    assert isinstance(again, sr.OrthographicCamera) and (again.xmag, again.ymag) == (2.0, 1.5)
    np.testing.assert_allclose(again.pose, cam.pose, atol=1e-12)
    assert (again.near, again.far, again.width, again.height) == (0.5, 9.0, 40, 30)


class _Clock:
    """The time module with a perf_counter that advances one second a call: the counts and
    seconds of a call are checked without timing anything."""

    def __init__(self) -> None:
        self.now = 0.0

    def perf_counter(self) -> float:
        self.now += 1.0
        return self.now

    def __getattr__(self, name: str):
        return getattr(time, name)


def test_resume_rewrites_only_what_is_missing(tmp_path, monkeypatch):
    monkeypatch.setattr(sr.dataset, "time", _Clock())
    scene, cams = _scene(), _cams()
    first = sr.write_dataset(scene, cams, tmp_path, outputs=OUTPUTS)
    read = lambda p: Path(p).read_bytes()  # noqa: E731
    before = {p: (os.stat(p).st_mtime_ns, read(p)) for d in first for p in d.values()}
    os.remove(first[2]["depth"])  # as if interrupted while writing view 2
    # a killed run (SIGKILL) can leave hidden temporaries: they are removed, others' files are not
    stale = [tmp_path / ".000002_depth.exr.4242-0123456789ab.tmp.exr", tmp_path / "cameras.json.4242.tmp"]
    for p in stale:
        p.write_bytes(b"partial")
    (tmp_path / ".keep.tmp").write_bytes(b"not ours")
    again = sr.write_dataset(scene, cams, tmp_path, outputs=OUTPUTS)
    assert again == first
    # what each call did: a rate is rendered / seconds, over the rendered views only
    assert (first.rendered, first.skipped, first.seconds) == (len(cams), 0, 1.0)  # two reads
    assert (again.rendered, again.skipped) == (1, len(cams) - 1)
    none = sr.write_dataset(scene, cams, tmp_path, outputs=OUTPUTS)
    assert (none.rendered, none.skipped, none.seconds) == (0, len(cams), 0.0) and none == first
    assert not any(p.exists() for p in stale) and (tmp_path / ".keep.tmp").exists()
    for p, (mtime, data) in before.items():
        assert read(p) == data  # the same bytes
        if not p.startswith(os.path.join(str(tmp_path), "000002_")):
            assert os.stat(p).st_mtime_ns == mtime, p  # untouched


def test_write_dataset_checks_its_arguments(tmp_path):
    scene = _scene()
    with pytest.raises(ValueError, match="at least one camera"):
        sr.write_dataset(scene, [], tmp_path)
    with pytest.raises(ValueError, match="no image size"):
        sr.write_dataset(scene, [sr.PerspectiveCamera()], tmp_path)
    with pytest.raises(ValueError, match="one image size"):
        sr.write_dataset(scene, _cams(2) + _cams(1, 32, 24), tmp_path)
    with pytest.raises(TypeError, match=r"cameras\[0\]"):
        sr.write_dataset(scene, ["cam"], tmp_path)
    with pytest.raises(FileNotFoundError):
        sr.write_dataset(scene, _cams(1), tmp_path / "missing")
    with pytest.raises(ValueError, match="renderer is 10x10"):
        sr.write_dataset(scene, _cams(1), tmp_path, renderer=sr.Renderer(10, 10))
    (tmp_path / "bad.json").write_text('{"format": "other"}')
    with pytest.raises(ValueError, match="not a softrast cameras.json"):
        sr.load_cameras(tmp_path / "bad.json")


@pytest.mark.parametrize("outputs", [("instance_id", "depth", "color"), ("color", "normal", "depth")])
def test_cameras_json_after_an_interrupted_run_is_byte_identical(tmp_path, monkeypatch, outputs):
    """Interrupted after a few views, then resumed: cameras.json (its ``files`` included) and
    the returned paths are the uninterrupted run's, byte for byte, whatever the order of
    ``outputs``."""
    scene, cams = _scene(), _cams()
    clean, cut = tmp_path / "clean", tmp_path / "cut"
    clean.mkdir()
    cut.mkdir()
    want = sr.write_dataset(scene, cams, clean, outputs=outputs)
    save = sr.Frame.save
    calls = []

    def interrupted_save(self, *args, **kwargs):
        calls.append(1)
        if len(calls) > 3:
            raise KeyboardInterrupt
        return save(self, *args, **kwargs)

    monkeypatch.setattr(sr.Frame, "save", interrupted_save)
    with pytest.raises(KeyboardInterrupt):
        sr.write_dataset(scene, cams, cut, outputs=outputs, writers=1)
    monkeypatch.setattr(sr.Frame, "save", save)
    assert not (cut / "cameras.json").exists() and 0 < len(os.listdir(cut)) < 3 * len(cams)
    got = sr.write_dataset(scene, cams, cut, outputs=outputs)
    assert (cut / "cameras.json").read_bytes() == (clean / "cameras.json").read_bytes()
    assert [list(p) for p in got] == [list(p) for p in want]
    assert [[os.path.basename(f) for f in p.values()] for p in got] == \
        [[os.path.basename(f) for f in p.values()] for p in want]
def _flip(data: bytes) -> bytes:
    out = bytearray(data)  # a run of flipped bits in the middle (pixel data, past the header)
    for k in range(len(out) // 2, len(out) // 2 + 16):
        out[k] ^= 0x5A
    return bytes(out)


def test_resume_rewrites_damaged_files(tmp_path):
    """resume keeps only files that decode to the view's output: a truncated, an empty, a
    corrupt file, one of another size or pixel type, are rendered again."""
    scene, cams = _scene(), _cams(8)
    formats = {"depth": "npy"}
    outputs = OUTPUTS + ("normal",)
    clean = tmp_path / "clean"
    cut = tmp_path / "cut"
    clean.mkdir()
    cut.mkdir()
    paths = sr.write_dataset(scene, cams, clean, outputs=outputs, formats=formats)
    cut_paths = sr.write_dataset(scene, cams, cut, outputs=outputs, formats=formats)
    files = lambda d: {p.name: p.read_bytes() for p in sorted(d.iterdir())}  # noqa: E731
    want = files(clean)
    assert files(cut) == want
    name = lambda k, output: os.path.basename(paths[k][output])  # noqa: E731
    damage = {
        name(0, "color"): lambda b: b[: len(b) // 2],          # truncated PNG
        name(1, "depth"): lambda b: b"",                       # empty .npy
        name(2, "instance_id"): _flip,                         # corrupt PNG (CRC)
        name(3, "normal"): lambda b: b[: len(b) - 40],         # truncated EXR
        name(4, "depth"): lambda b: b[:-8],                    # truncated .npy
        name(5, "normal"): _flip,                              # corrupt EXR (zip)
    }
    for n, f in damage.items():
        (cut / n).write_bytes(f(want[n]))
    # a valid image of another size, and one of another pixel type
    sr.imwrite(cut / name(4, "color"), np.zeros((10, 12, 3), np.uint8))
    sr.imwrite(cut / name(5, "instance_id"), np.zeros((36, 48), np.uint8))
    kept = {n: os.stat(cut / n).st_mtime_ns for n in want if n.startswith(("000006_", "000007_"))}
    assert sr.write_dataset(scene, cams, cut, outputs=outputs, formats=formats) == cut_paths
    assert files(cut) == want
    assert len(kept) == 8
    for n, mtime in kept.items():  # the intact views are not written again
        assert os.stat(cut / n).st_mtime_ns == mtime, n


_HEAD = b'{"format": "softrast cameras 1"'
_BAD_CAMERAS = {  # name: (content, what the error says)
    "truncated": (None, "invalid JSON"),
    "empty": (b"", "invalid JSON"),
    "binary": (b"\x89PNG\r\n\x1a\n\x00\x00\xff\xfe\x80binary", "UTF-8"),
    "no_frames": (_HEAD + b"}", "frames"),
    "frames_number": (_HEAD + b', "frames": 5}', "frames"),
    "frames_object": (_HEAD + b', "frames": {"a": 1}}', "frames"),
    "frame_number": (_HEAD + b', "frames": [5]}', "frame 0"),
    "deep_frames": (_HEAD + b', "frames": ' + b"[" * 100000 + b"]" * 100000 + b"}", "nested"),
    "deep_unclosed": (b"[" * 100000, "nested|invalid JSON"),
}


@pytest.mark.parametrize("case", list(_BAD_CAMERAS))
def test_load_cameras_refuses_bad_files_naming_them(tmp_path, case):
    """Every broken cameras.json is a ValueError naming the file."""
    content, match = _BAD_CAMERAS[case]
    if content is None:
        sr.write_dataset(_scene(), _cams(2), tmp_path, outputs=("depth",))
        content = (tmp_path / "cameras.json").read_bytes()
        content = content[: len(content) // 2]
    path = tmp_path / "cameras.json"
    path.write_bytes(content)
    for arg in (path, tmp_path, str(path)):
        with pytest.raises(ValueError, match=rf"cameras\.json.*({match})") as info:
            sr.load_cameras(arg)
        assert str(path) in str(info.value)
