"""The ``softrast render`` command: argument errors, auto-framing geometry, files it writes."""
from __future__ import annotations

import math
import os
import pathlib
import subprocess
import sys

import numpy as np
import pytest

import softrast as sr
from softrast.cli import frame_camera, main
from softrast.io import imread

SPOT_PATH = pathlib.Path(__file__).resolve().parents[1] / "assets" / "meshes" / "spot.obj"
FUZE_PATH = pathlib.Path(__file__).resolve().parents[1] / "assets" / "meshes" / "fuze" / "fuze.obj"


@pytest.mark.parametrize("argv, match", [
    (["render", str(SPOT_PATH)], "-o"),  # missing output
    (["render", str(SPOT_PATH), "-o", "x.png", "--size", "0x48"], "--size"),
    (["render", str(SPOT_PATH), "-o", "x.png", "--size", "64by48"], "--size"),
    (["render", str(SPOT_PATH), "-o", "x.png", "--eye", "1,2"], "--eye"),
    (["render", str(SPOT_PATH), "-o", "x.png", "--up", "0,nan,1"], "--up"),
    (["render", str(SPOT_PATH), "-o", "x.png", "--cull", "sideways"], "--cull"),
    (["render", str(SPOT_PATH), "-o", "x.png", "--shading", "toon"], "--shading"),  # phong is valid
    (["render", str(SPOT_PATH), "-o", "x.png", "--threads", "-1"], "--threads"),
    (["render", str(SPOT_PATH), "-o", "x.png", "--msaa", "3"], "--msaa"),
    (["render", str(SPOT_PATH), "-o", "x.png", "--ssaa", "9"], "--ssaa"),
    (["render", str(SPOT_PATH), "-o", "x.png", "--msaa", "4", "--ssaa", "2"], "--ssaa"),
    (["render", str(SPOT_PATH), "-o", "x.png", "--near", "0"], "--near"),
    (["render", str(SPOT_PATH), "-o", "x.png", "--wireframe", "--line-color", "1,0"], "--line-color"),
    (["render", str(SPOT_PATH), "-o", "x.png", "--wireframe", "--line-color", "2,0,0"], "--line-color"),
    (["render", str(SPOT_PATH), "-o", "x.png", "--wireframe", "--line-width", "0"], "--line-width"),
    (["render", str(SPOT_PATH), "-o", "x.png", "--wireframe", "--line-width", "nan"], "--line-width"),
    (["render", str(SPOT_PATH), "-o", "x.png", "--fov", "180"], "--fov"),
    (["render", str(SPOT_PATH), "-o", "x.png", "--near", "2", "--far", "1"], "--far"),
    (["render", "missing.obj", "-o", "x.png"], "missing.obj"),
    (["bake"], "bake"),
    ([], "command"),
])
def test_errors_are_one_line_and_exit_2(tmp_path, monkeypatch, capsys, argv, match):
    monkeypatch.chdir(tmp_path)
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.startswith("softrast: error: ") and err.count("\n") == 1, err
    assert match in err
    assert "Traceback" not in err
    assert os.listdir(tmp_path) == []


def test_output_format_error_is_reported(tmp_path, capsys):
    # Depth is float32: a .png would quantize it, so imwrite refuses and the CLI reports it.
    code = main(["render", str(SPOT_PATH), "-o", str(tmp_path / "c.png"),
                 "--depth", str(tmp_path / "d.png"), "--size", "16x12"])
    assert code == 2
    assert ".exr" in capsys.readouterr().err


def test_help_exits_0(capsys):
    assert main(["render", "--help"]) == 0
    assert "--depth" in capsys.readouterr().out


@pytest.mark.parametrize("width, height", [(64, 48), (48, 64), (100, 10)])
def test_frame_camera_fits_bounding_sphere(width, height):
    bounds = np.array([[-1.0, 2.0, 3.0], [3.0, 4.0, 4.0]])
    fov_y = 45.0
    eye, target, near, far = frame_camera(bounds, fov_y, width, height)
    centre = bounds.mean(axis=0)
    radius = 0.5 * np.linalg.norm(bounds[1] - bounds[0])
    np.testing.assert_allclose(target, centre)
    offset = eye - target
    np.testing.assert_allclose(offset / np.linalg.norm(offset), np.array([0, 0.25, 1]) / np.linalg.norm([0, 0.25, 1]))
    # The sphere's angular radius fits inside both half-fields of view.
    half_y = math.radians(fov_y) / 2
    half_x = math.atan(math.tan(half_y) * width / height)
    angular_radius = math.asin(radius / np.linalg.norm(offset))
    assert angular_radius < min(half_x, half_y)
    assert angular_radius > 0.8 * min(half_x, half_y)  # ... without leaving it tiny
    # Every point of the sphere lies between near and far.
    assert 0 < near < np.linalg.norm(offset) - radius
    assert far > np.linalg.norm(offset) + radius


def test_frame_camera_with_eye_inside_bounds():
    bounds = np.array([[-1.0, -1.0, -1.0], [1.0, 1.0, 1.0]])
    eye, target, near, far = frame_camera(bounds, 45.0, 64, 48, eye=(0.1, 0, 0), target=(1, 0, 0))
    np.testing.assert_array_equal(eye, [0.1, 0, 0])
    np.testing.assert_array_equal(target, [1, 0, 0])
    assert 0 < near < 0.01 and far > 0.1 + math.sqrt(3)


def check_render_outputs(tmp_path):
    color = imread(tmp_path / "color.png")
    depth = imread(tmp_path / "depth.exr")
    mask = imread(tmp_path / "mask.png")
    normal = imread(tmp_path / "normal.exr")
    assert color.shape == (48, 64, 3) and color.dtype == np.uint8
    assert depth.shape == (48, 64) and depth.dtype == np.float32
    assert mask.shape == (48, 64) and mask.dtype == np.uint8 and set(np.unique(mask)) <= {0, 255}
    assert normal.shape == (48, 64, 3) and normal.dtype == np.float32
    hit = mask == 255
    assert 0.05 < hit.mean() < 0.95  # the auto-framed cow fills part of the image
    assert np.all(depth[hit] > 0) and np.all(depth[~hit] == 0)
    np.testing.assert_allclose(np.linalg.norm(normal[hit], axis=-1), 1.0, atol=1e-3)
    assert np.all(color[hit].max(axis=-1) > 0)  # lit (ambient > 0) where covered
    # Framed: the object touches neither the image border nor escapes the view.
    assert not hit[0].any() and not hit[-1].any() and not hit[:, 0].any() and not hit[:, -1].any()


def test_render_writes_all_outputs(tmp_path):
    code = main([
        "render", str(SPOT_PATH), "-o", str(tmp_path / "color.png"), "--size", "64x48",
        "--depth", str(tmp_path / "depth.exr"), "--mask", str(tmp_path / "mask.png"),
        "--normal", str(tmp_path / "normal.exr"), "--threads", "2",
    ])
    assert code == 0
    check_render_outputs(tmp_path)
    assert sorted(os.listdir(tmp_path)) == ["color.png", "depth.exr", "mask.png", "normal.exr"]


def test_render_antialiased_matches_the_api(tmp_path):
    # --msaa 4 writes what render(msaa=4) gives for the same camera (framed as without it).
    for flag in (["--msaa", "4"], ["--ssaa", "2"]):
        path = tmp_path / f"{flag[0][2:]}.png"
        code = main(["render", str(SPOT_PATH), "-o", str(path), "--size", "64x48", "--eye", "1.7,0.9,-2.3",
                     "--target", "0,0.05,0.15", "--near", "0.05", "--far", "20", *flag])
        assert code == 0
        scene = sr.Scene()
        scene.add(sr.load_mesh(SPOT_PATH))
        cam = sr.PerspectiveCamera(fov_y=45.0, width=64, height=48, near=0.05, far=20.0)
        cam.look_at((1.7, 0.9, -2.3), (0, 0.05, 0.15), (0, 1, 0))
        frame = sr.Renderer(64, 48).render(scene, cam, outputs=("color",), **{flag[0][2:]: int(flag[1])})
        np.testing.assert_array_equal(imread(path), frame.color)
        partial = frame.color[(frame.color > 0).any(axis=-1)]
        assert len(np.unique(partial.reshape(-1, 3), axis=0)) > 10


def test_render_wireframe_matches_the_api(tmp_path):
    # --wireframe (with --line-color, --line-width) writes what render(wireframe=True, ...) gives.
    path = tmp_path / "wire.png"
    code = main(["render", str(SPOT_PATH), "-o", str(path), "--size", "96x72", "--eye", "1.7,0.9,-2.3",
                 "--target", "0,0.05,0.15", "--near", "0.05", "--far", "20", "--wireframe",
                 "--line-color", "1,0,0", "--line-width", "2"])
    assert code == 0
    scene = sr.Scene()
    scene.add(sr.load_mesh(SPOT_PATH))
    cam = sr.PerspectiveCamera(fov_y=45.0, width=96, height=72, near=0.05, far=20.0)
    cam.look_at((1.7, 0.9, -2.3), (0, 0.05, 0.15), (0, 1, 0))
    r = sr.Renderer(96, 72)
    want = r.render(scene, cam, outputs=("color",), wireframe=True, line_color=(1.0, 0.0, 0.0), line_width=2.0).color
    np.testing.assert_array_equal(imread(path), want)
    plain = r.render(scene, cam, outputs=("color",)).color
    red = (want[..., 0] == 255) & (want[..., 1] == 0) & (want[..., 2] == 0)
    assert red.sum() > 200 and not ((plain[..., 0] == 255) & (plain[..., 1] == 0)).any()


def test_render_explicit_camera_depth(tmp_path):
    # Looking down -z from z = 5 at spot (bounds within ~[-1, 1]): depth along the axis ~ 5 - z.
    code = main([
        "render", str(SPOT_PATH), "-o", str(tmp_path / "c.png"), "--size", "64x48",
        "--depth", str(tmp_path / "d.exr"), "--eye", "0,0,5", "--target", "0,0,0",
        "--near", "0.5", "--far", "20", "--cull", "none", "--shading", "unlit",
    ])
    assert code == 0
    depth = imread(tmp_path / "d.exr")
    hit = depth > 0
    assert hit.any()
    from softrast import load_mesh
    z = load_mesh(SPOT_PATH).bounds[:, 2]
    assert depth[hit].min() >= 5 - z[1] - 1e-4 and depth[hit].max() <= 5 - z[0] + 1e-4


def test_python_dash_m(tmp_path):
    result = subprocess.run(
        [sys.executable, "-m", "softrast", "render", str(SPOT_PATH), "-o", str(tmp_path / "color.png"),
         "--size", "64x48", "--depth", str(tmp_path / "depth.exr"), "--mask", str(tmp_path / "mask.png"),
         "--normal", str(tmp_path / "normal.exr")],
        capture_output=True, text=True, timeout=120,
    )
    assert result.returncode == 0, result.stderr
    check_render_outputs(tmp_path)
    bad = subprocess.run([sys.executable, "-m", "softrast", "render", str(SPOT_PATH), "-o", "x.png",
                          "--size", "x"], capture_output=True, text=True, timeout=120, cwd=tmp_path)
    assert bad.returncode == 2 and bad.stderr.startswith("softrast: error:") and bad.stderr.count("\n") == 1


def test_refused_worker_thread_is_a_clean_error(tmp_path, capsys):
    # The system refusing a worker thread (here injected: the first one asked for) is reported
    # like any other error, naming `threads`, with no traceback.
    from softrast import _core

    _core._fail_thread_start(1)
    try:
        status = main(["render", str(SPOT_PATH), "-o", str(tmp_path / "x.png"), "--threads", "2",
                       "--size", "32x24"])
    finally:
        _core._fail_thread_start(0)
    err = capsys.readouterr().err
    assert status == 2
    assert err.startswith("softrast: error:") and "threads" in err and "Traceback" not in err
    assert not (tmp_path / "x.png").exists()


def test_render_with_texture_as_the_readme_does(tmp_path):
    """The README's first command: Spot with its texture. The colour equals a Python render of
    the same scene, and the texture shows (the cow's black patches and pink nose: many distinct
    colours, unlike the untextured grey)."""
    import softrast as sr

    tex_path = SPOT_PATH.parent / "spot_texture.png"
    argv = ["render", str(SPOT_PATH), "--texture", str(tex_path), "-o", str(tmp_path / "c.png"),
            "--size", "160x120", "--eye", "1.7,0.9,-2.3", "--target", "0,0.05,0.15", "--msaa", "4"]
    assert main(argv) == 0
    color = imread(tmp_path / "c.png")
    mesh = sr.load_mesh(SPOT_PATH)
    scene = sr.Scene()
    scene.add(mesh, material=sr.Material(base_color=(1, 1, 1), model="lambert",
                                         base_color_texture=sr.load_texture(tex_path)))
    eye, target, near, far = frame_camera(scene.bounds, 45.0, 160, 120, (1.7, 0.9, -2.3), (0, 0.05, 0.15))
    cam = sr.PerspectiveCamera(fov_y=45.0, width=160, height=120, near=near, far=far)
    cam.look_at(eye, target, (0.0, 1.0, 0.0))
    np.testing.assert_array_equal(color, sr.Renderer(160, 120).render(scene, cam, msaa=4).color)
    hit = color.max(-1) > 0
    assert len(np.unique(color[hit] // 32, axis=0)) > 8  # more than shades of one grey
    dark = (color[hit].max(-1) < 60).mean()
    assert dark > 0.005  # the black patches and eyes (untextured, nothing is below ~120)


def test_texture_errors(tmp_path, capsys):
    assert main(["render", str(SPOT_PATH), "--texture", str(tmp_path / "missing.png"),
                 "-o", str(tmp_path / "c.png")]) == 2
    assert "--texture" in capsys.readouterr().err


def test_render_mtl_with_ns_0_is_not_washed_out(tmp_path):
    # fuze.obj's MTL (Ks 1 1 1, Ns 0) rendered as a white blob under shading "auto"
    # (Blinn-Phong with exponent 0 adds ks everywhere). MTL materials render as pbr now: the lit
    # bottle is no brighter than its texture, unlit.
    lit, unlit = tmp_path / "lit.png", tmp_path / "unlit.png"
    assert main(["render", str(FUZE_PATH), "-o", str(lit), "--size", "160x120", "--up-axis", "z"]) == 0
    assert main(["render", str(FUZE_PATH), "-o", str(unlit), "--size", "160x120", "--up-axis", "z",
                 "--shading", "unlit"]) == 0
    lit_rgb, unlit_rgb = imread(lit).astype(int), imread(unlit).astype(int)
    covered = (unlit_rgb > 0).any(-1)
    assert covered.sum() > 1000
    assert (lit_rgb[covered] >= 250).all(-1).mean() < 0.01
    assert lit_rgb[covered].mean() <= unlit_rgb[covered].mean()
