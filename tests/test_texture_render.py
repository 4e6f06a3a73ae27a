"""Textures in renders: exact texel reproduction, mip level selection from the exact
screen derivatives, a perspective plane against Texture.sample at analytic uvs and derivatives,
the grazing checkerboard against a 256-samples-per-pixel reference, normal and emissive maps
against n.l, the textured Spot against a ray-cast reference, same bits across ISAs and threads.
(tests/test_texture_sampling.py checks the sampler itself against
softrast.reference.texture.)"""
from __future__ import annotations

import pickle
from pathlib import Path

import numpy as np
import pytest
import trimesh

import softrast as sr

ASSETS = Path(__file__).resolve().parent.parent / "assets" / "meshes"
FILTERS = ("nearest", "bilinear", "trilinear", "anisotropic")


def quad(material: sr.Material, size: float = 1.0, uv_scale: float = 1.0) -> sr.Mesh:
    """The square [-size, size]^2 at z = 0 facing +z, uv (0, 0) at its bottom-left corner."""
    s = size
    pos = np.array([[-s, -s, 0], [s, -s, 0], [s, s, 0], [-s, s, 0]], np.float32)
    uv = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], np.float32) * uv_scale
    return sr.Mesh(pos, np.array([[0, 1, 2], [0, 2, 3]]), uvs=uv, material=material)


def ortho_camera(w: int, h: int) -> sr.OrthographicCamera:
    cam = sr.OrthographicCamera(xmag=1.0, ymag=1.0, width=w, height=h)
    pose = np.eye(4)
    pose[2, 3] = 2.0
    cam.pose = pose
    return cam


def unlit(tex: sr.Texture) -> sr.Material:
    return sr.Material(base_color=(1, 1, 1, 1), base_color_texture=tex, model="unlit")


@pytest.mark.parametrize("filt", FILTERS)
@pytest.mark.parametrize("channels", [1, 3, 4])
def test_one_texel_per_pixel_is_exact(filt: str, channels: int) -> None:
    """Pixel centres on texel centres: every filter returns the texels (sRGB off), for both
    instruction sets and thread counts, forward and deferred."""
    h, w = 24, 40
    img = np.random.default_rng(channels).integers(0, 256, (h, w, channels)).astype(np.uint8)
    scene = sr.Scene()
    scene.add(quad(unlit(sr.Texture(img, srgb=False, filter=filt))))
    cam = sr.OrthographicCamera(xmag=1.0, ymag=1.0, width=w, height=h)
    cam.pose = ortho_camera(w, h).pose
    expected = img[:, :, [0, 0, 0]] if channels == 1 else img[:, :, :3]
    for threads in (1, 2):
        for simd in (True, False):
            for path in ("forward", "deferred"):
                frame = sr.Renderer(w, h, threads=threads, simd=simd).render(
                    scene, cam, outputs=("color",), srgb=False, shading_path=path)
                np.testing.assert_array_equal(frame.color, expected)


@pytest.mark.parametrize("k", [1, 2, 3])
def test_mip_level_at_known_minification(k: int) -> None:
    """A texture 2^k texels per pixel: trilinear reads exactly level k at the pixel centres
    (which sit on that level's texel centres)."""
    n = 16
    img = np.random.default_rng(k).random((n << k, n << k, 3)).astype(np.float32)
    tex = sr.Texture(img, srgb=False, filter="trilinear")
    scene = sr.Scene()
    scene.add(quad(unlit(tex)))
    frame = sr.Renderer(n, n).render(scene, ortho_camera(n, n), outputs=("radiance",))
    level = tex.mip(k)
    assert level.shape == (n, n, 4)
    np.testing.assert_allclose(frame.radiance, level[:, :, :3], rtol=0, atol=2e-6)
    # and not level k - 1 or k + 1 (distinguishable: random texels)
    assert np.abs(frame.radiance - tex.mip(k - 1)[:: 2, :: 2, :3]).max() > 0.05


def _opencv_look_at(K, eye, target, up, w, h, near, far):
    """An OpenCV-convention camera at `eye` looking at `target` (x right, y down, z forward),
    and its world-to-camera R, t."""
    eye, target = np.asarray(eye, float), np.asarray(target, float)
    z = target - eye
    z /= np.linalg.norm(z)
    x = np.cross(z, up)
    x /= np.linalg.norm(x)
    R = np.stack([x, np.cross(z, x), z])
    t = -R @ eye
    return sr.IntrinsicsCamera.from_opencv(K, R, t, w, h, near=near, far=far), R, t


def _light_toward(l: np.ndarray) -> np.ndarray:
    """A light pose whose -z axis travels along -l (it lights surfaces facing l)."""
    pose = np.eye(4)
    xax = np.cross([0, 1.0, 0], l)
    xax /= np.linalg.norm(xax)
    pose[:3, 0], pose[:3, 1], pose[:3, 2] = xax, np.cross(l, xax), l
    return pose


def _opencv_plane_camera(w: int, h: int) -> tuple[sr.IntrinsicsCamera, np.ndarray, np.ndarray, np.ndarray]:
    """A camera looking down at the plane z = 0 at about 60 degrees from its normal."""
    K = np.array([[1.1 * w, 0, w / 2 - 0.3], [0, 1.1 * w, h / 2 + 0.2], [0, 0, 1.0]])
    cam, R, t = _opencv_look_at(K, (0.3, -2.2, 1.3), (0.05, 0.1, 0.0), [0, 0, 1.0], w, h, 0.1, 20.0)
    return cam, K, R, t


def _plane_uv(K: np.ndarray, R: np.ndarray, t: np.ndarray, px: np.ndarray, py: np.ndarray,
              size: float) -> np.ndarray:
    """uv of the plane z = 0 (quad of half-size `size`, uv = (p + size) / (2 size)) seen
    through pixel coordinates (px, py) (OpenCV: pixel centres at integers), float64."""
    d_cam = np.linalg.solve(K, np.stack([px, py, np.ones_like(px)]).reshape(3, -1))
    d = R.T @ d_cam
    o = -R.T @ t
    s = -o[2] / d[2]
    p = o[:, None] + s * d
    return ((p[:2] + size) / (2 * size)).T.reshape(px.shape + (2,))


@pytest.mark.parametrize("filt", ["bilinear", "trilinear", "anisotropic"])
def test_perspective_plane_matches_sampler_at_analytic_uvs(filt: str) -> None:
    """A tilted textured plane: each pixel's radiance is Texture.sample at the pixel's exact uv
    and exact screen derivatives (analytic, float64): the renderer's perspective-correct uvs
    and its plane-equation derivatives (the level of detail) are right."""
    w, h, size = 96, 72, 1.5
    yy, xx = np.mgrid[0:64, 0:64] / 64.0
    img = np.stack([0.5 + 0.4 * np.sin(2 * np.pi * (3 * xx + yy)),
                    0.5 + 0.4 * np.cos(2 * np.pi * 5 * yy),
                    0.5 + 0.3 * np.sin(2 * np.pi * (2 * xx - 4 * yy))], -1).astype(np.float32)
    tex = sr.Texture(img, srgb=False, filter=filt, wrap="repeat")
    scene = sr.Scene()
    scene.add(quad(unlit(tex), size=size, uv_scale=4.0))  # 4 repeats: strong minification far off
    cam, K, R, t = _opencv_plane_camera(w, h)
    frame = sr.Renderer(w, h).render(scene, cam, outputs=("radiance", "triangle_id"))
    rows, cols = np.nonzero(frame.triangle_id >= 0)
    assert rows.size > 0.4 * w * h
    px, py = cols.astype(np.float64), rows.astype(np.float64)
    uv = 4.0 * _plane_uv(K, R, t, px, py, size)
    e = 1e-3  # central differences of the analytic uv(x, y): error ~e^2
    dx = 4.0 * (_plane_uv(K, R, t, px + e, py, size) - _plane_uv(K, R, t, px - e, py, size)) / (2 * e)
    dy = 4.0 * (_plane_uv(K, R, t, px, py + e, size) - _plane_uv(K, R, t, px, py - e, size)) / (2 * e)
    inside = ((uv > 0.02) & (uv < 3.98)).all(axis=1)  # away from the quad's edges
    duv = np.stack([dx[:, 0], dx[:, 1], dy[:, 0], dy[:, 1]], 1)
    expected = tex.sample(uv[inside], duv[inside])[:, :3]
    got = frame.radiance[rows[inside], cols[inside]]
    err = np.abs(got - expected)
    # The rasterizer snaps vertices to 1/256 pixel, which moves uvs by up to ~1e-4 here: on this
    # smooth texture (slope <= ~8 per uv unit) that is a few 1e-4 at most
    assert err.max() < 5e-3, err.max()
    assert np.mean(err) < 5e-4, np.mean(err)
    if filt != "bilinear":  # the test has power: a level of detail off by one is far worse
        wrong = tex.sample(uv[inside], 2.0 * duv[inside])[:, :3]
        assert np.mean(np.abs(got - wrong)) > 5 * np.mean(err), (np.mean(np.abs(got - wrong)), np.mean(err))


def _checker_reference(K, R, t, w, h, size, checks, spp=16):
    """Mean of the analytic checkerboard over spp x spp samples per pixel (256 per pixel)."""
    offs = (np.arange(spp) + 0.5) / spp - 0.5
    acc = np.zeros((h, w))
    hit = np.zeros((h, w))
    yy, xx = np.mgrid[0:h, 0:w].astype(np.float64)
    for oy in offs:
        for ox in offs:
            uv = _plane_uv(K, R, t, xx + ox, yy + oy, size)
            inside = ((uv >= 0) & (uv <= 1)).all(-1)
            c = (np.floor(uv[..., 0] * checks) + np.floor(uv[..., 1] * checks)) % 2
            acc += np.where(inside, c, 0.0)
            hit += inside
    return acc / spp ** 2, hit == spp ** 2


def test_grazing_checkerboard_error_ordering(capsys) -> None:
    """RMSE against a 256-samples-per-pixel reference of the analytic checkerboard on a plane
    at a grazing angle: anisotropic < trilinear < bilinear < nearest."""
    w, h, size, checks, texels = 160, 100, 4.0, 64, 8
    n = checks * texels
    yy, xx = np.mgrid[0:n, 0:n] // texels
    # row 0 is v = 1: the texel (row r, col j) has v index n - 1 - r
    img = (((n - 1 - np.mgrid[0:n, 0:n][0]) // texels + xx) % 2).astype(np.float32)[:, :, None]
    K = np.array([[0.9 * w, 0, w / 2], [0, 0.9 * w, h / 2], [0, 0, 1.0]])
    cam, R, t = _opencv_look_at(K, (0.0, -4.3, 0.35), (0.0, 1.0, 0.0), [0, 0, 1.0], w, h, 0.05, 50.0)
    ref, full = _checker_reference(K, R, t, w, h, size, checks)
    scene = sr.Scene()
    scene.add(quad(unlit(sr.Texture(img, srgb=False)), size=size))
    r = sr.Renderer(w, h)
    rmse = {}
    for filt in FILTERS:
        frame = r.render(scene, cam, outputs=("radiance", "triangle_id"), texture_filter=filt)
        mask = full & (frame.triangle_id >= 0)
        rmse[filt] = float(np.sqrt(np.mean((frame.radiance[..., 0][mask] - ref[mask]) ** 2)))
    with capsys.disabled():
        print("\ngrazing checkerboard RMSE vs 256 spp:", {k: round(v, 4) for k, v in rmse.items()})
    assert rmse["anisotropic"] < rmse["trilinear"] < rmse["bilinear"] < rmse["nearest"], rmse


def _side_light_scene(tex: sr.Texture, convention: str = "opengl", scale: float = 1.0) -> sr.Scene:
    m = sr.Material(base_color=(1, 1, 1, 1), normal_texture=tex, model="lambert", ka=(0, 0, 0),
                    normal_map_convention=convention, normal_scale=scale)
    scene = sr.Scene()
    scene.add(quad(m))
    scene.add(sr.DirectionalLight(intensity=1.0), pose=_light_toward(np.array([1.0, 0.5, 1.0]) / 1.5))
    return scene


@pytest.mark.parametrize("convention", ["opengl", "directx"])
def test_normal_map_relief_follows_n_dot_l(convention: str) -> None:
    """A normal-mapped quad facing the camera, lit from the side: each pixel's radiance is
    max(0, n.l) of the map's normal in the frame (t, b, n) = (+x, +y, +z)."""
    h = w = 16
    rng = np.random.default_rng(3)
    n_ts = rng.normal(size=(h, w, 3)) * [0.4, 0.4, 0.0] + [0, 0, 1.0]
    n_ts /= np.linalg.norm(n_ts, axis=-1, keepdims=True)
    stored = n_ts.copy()
    if convention == "directx":
        stored[..., 1] *= -1
    img = ((stored + 1) / 2).astype(np.float32)
    scene = _side_light_scene(sr.Texture(img, filter="nearest"), convention)
    frame = sr.Renderer(w, h).render(scene, ortho_camera(w, h), outputs=("radiance",))
    l = np.array([1.0, 0.5, 1.0]) / 1.5
    decoded = img.astype(np.float64) * 2 - 1  # what the core decodes (float32 texels)
    if convention == "directx":
        decoded[..., 1] *= -1
    decoded /= np.linalg.norm(decoded, axis=-1, keepdims=True)
    expected = np.maximum(decoded @ l, 0.0)
    np.testing.assert_allclose(frame.radiance[..., 0], expected, rtol=0, atol=2e-6)
    # the relief is really there: far from the flat quad's constant n.l
    assert np.abs(expected - l[2]).max() > 0.2


def test_normal_scale_zero_is_the_flat_normal() -> None:
    h = w = 8
    img = np.random.default_rng(1).random((h, w, 3)).astype(np.float32) * 0.5 + 0.5
    scene = _side_light_scene(sr.Texture(img, filter="nearest"), scale=0.0)
    frame = sr.Renderer(w, h).render(scene, ortho_camera(w, h), outputs=("radiance",))
    np.testing.assert_allclose(frame.radiance[..., 0], 1.0 / 1.5, rtol=0, atol=2e-6)


def test_emissive_texture_is_added_per_pixel() -> None:
    h = w = 8
    img = np.random.default_rng(2).random((h, w, 3)).astype(np.float32)
    m = sr.Material(base_color=(0, 0, 0, 1), emissive=(0.5, 0.25, 1.0), model="lambert",
                    emissive_texture=sr.Texture(img, srgb=False, filter="nearest"))
    scene = sr.Scene()
    scene.add(quad(m))
    frame = sr.Renderer(w, h).render(scene, ortho_camera(w, h), outputs=("radiance",))
    np.testing.assert_allclose(frame.radiance, img * [0.5, 0.25, 1.0], rtol=0, atol=1e-6)


@pytest.mark.parametrize("frequency", ["vertex", "face"])
def test_vertex_and_face_frequency_modulate(frequency: str) -> None:
    """Gouraud and flat lighting are computed without the texture, then multiplied by it."""
    h = w = 8
    img = np.random.default_rng(4).random((h, w, 3)).astype(np.float32)
    tex = sr.Texture(img, srgb=False, filter="nearest")
    scene = sr.Scene()
    scene.add(quad(sr.Material(base_color=(1, 1, 1, 1), base_color_texture=tex, model="lambert")))
    plain = sr.Scene()
    plain.add(quad(sr.Material(base_color=(1, 1, 1, 1), model="lambert")))
    r = sr.Renderer(w, h)
    got = r.render(scene, ortho_camera(w, h), outputs=("radiance",), frequency=frequency).radiance
    lit = r.render(plain, ortho_camera(w, h), outputs=("radiance",), frequency=frequency).radiance
    np.testing.assert_allclose(got, lit * img, rtol=1e-6, atol=1e-7)


def _spot_scene(filt: str = "trilinear") -> tuple[sr.Scene, sr.Mesh, sr.Texture]:
    tm = trimesh.load(ASSETS / "spot.obj", process=False)
    tex = sr.load_texture(ASSETS / "spot_texture.png", filter=filt)
    mesh = sr.Mesh(tm.vertices, tm.faces, normals=tm.vertex_normals, uvs=tm.visual.uv,
                   material=sr.Material(base_color=(1, 1, 1, 1), base_color_texture=tex,
                                        model="unlit"))
    scene = sr.Scene()
    scene.add(mesh)
    return scene, mesh, tex


def test_textured_spot_against_ray_cast_reference() -> None:
    """Pixels of the textured Spot (unlit, bilinear, linear output) against a NumPy reference:
    the pixel's ray intersected with its triangle (triangle_id), barycentric uvs, then
    Texture.sample."""
    w, h = 160, 120
    scene, mesh, tex = _spot_scene("bilinear")
    K = np.array([[150.0, 0, w / 2], [0, 150.0, h / 2], [0, 0, 1.0]])
    eye = np.array([2.2, 0.6, 1.5])
    cam, R, t = _opencv_look_at(K, eye, (0.0, 0.0, 0.3), [0, 1.0, 0], w, h, 0.05, 20.0)
    frame = sr.Renderer(w, h).render(scene, cam, outputs=("radiance", "triangle_id"))
    rows, cols = np.nonzero(frame.triangle_id >= 0)
    assert rows.size > 2000
    pick = np.random.default_rng(0).choice(rows.size, 400, replace=False)
    rows, cols = rows[pick], cols[pick]
    tri = frame.triangle_id[rows, cols]
    tm = trimesh.load(ASSETS / "spot.obj", process=False)
    p = tm.vertices[tm.faces[tri]]  # (n, 3, 3)
    uvs = tm.visual.uv[tm.faces[tri]]
    d = (R.T @ np.linalg.solve(K, np.stack([cols, rows, np.ones_like(cols)]).astype(float))).T
    # Moller-Trumbore barycentrics of the ray eye + s d
    e1, e2 = p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]
    pv = np.cross(d, e2)
    det = np.einsum("ij,ij->i", e1, pv)
    tv = eye - p[:, 0]
    b1 = np.einsum("ij,ij->i", tv, pv) / det
    qv = np.cross(tv, e1)
    b2 = np.einsum("ij,ij->i", d, qv) / det
    bary = np.stack([1 - b1 - b2, b1, b2], 1)
    uv = np.einsum("ik,ikj->ij", bary, uvs)
    expected = tex.sample(uv, filter="bilinear")[:, :3]
    got = frame.radiance[rows, cols]
    err = np.abs(got - expected).max(axis=1)
    # uv agrees to ~1e-5 (float32 pipeline): at 1024 texels that is ~0.01 texel of a bilinear
    # blend; the texture's sharpest edges change ~0.5 per texel
    assert np.median(err) < 1e-3, np.median(err)
    assert np.quantile(err, 0.98) < 2e-2, np.quantile(err, 0.98)


@pytest.mark.parametrize("filt", FILTERS)
def test_textured_spot_same_bits(filt: str) -> None:
    """Textured shading (lit, every filter) gives the same bits for AVX2 and generic kernels,
    one or two threads, forward or deferred."""
    scene, mesh, tex = _spot_scene(filt)
    lit = sr.Scene(ambient_light=(0.1, 0.1, 0.1))
    lit.add(mesh, material=mesh.material.replace(model="blinn_phong", ks=(0.3, 0.3, 0.3)))
    lit.add(sr.PointLight(intensity=3.0), pose=np.array([[1, 0, 0, 1.0], [0, 1, 0, 1.5],
                                                       [0, 0, 1, 2.0], [0, 0, 0, 1]]))
    cam = sr.PerspectiveCamera(fov_y=45.0, width=200, height=150)
    cam.look_at(eye=(1.8, 0.6, 1.6), target=(0, 0, 0.3))
    frames = []
    for threads in (1, 2):
        for simd in (True, False):
            for path in ("forward", "deferred"):
                frames.append(sr.Renderer(200, 150, threads=threads, simd=simd).render(
                    lit, cam, outputs=("color", "radiance"), shading_path=path))
    covered = (frames[0].radiance > 0).any(-1).sum()
    assert covered > 5000
    for f in frames[1:]:
        np.testing.assert_array_equal(f.color, frames[0].color)
        np.testing.assert_array_equal(f.radiance.view(np.uint32), frames[0].radiance.view(np.uint32))


def test_untextured_render_unchanged_by_uvs() -> None:
    """A mesh with uvs but no texture renders exactly as without them (no texture work)."""
    scene_a, mesh, _ = _spot_scene()
    tm = trimesh.load(ASSETS / "spot.obj", process=False)
    m = sr.Material(model="blinn_phong")
    a, b = sr.Scene(), sr.Scene()
    a.add(sr.Mesh(tm.vertices, tm.faces, normals=tm.vertex_normals, uvs=tm.visual.uv, material=m))
    b.add(sr.Mesh(tm.vertices, tm.faces, normals=tm.vertex_normals, material=m))
    cam = sr.PerspectiveCamera(fov_y=45.0, width=64, height=48)
    cam.look_at(eye=(1.8, 0.6, 1.6), target=(0, 0, 0.3))
    r = sr.Renderer(64, 48)
    fa = r.render(a, cam, outputs=("radiance",))
    fb = r.render(b, cam, outputs=("radiance",))
    np.testing.assert_array_equal(fa.radiance, fb.radiance)


def test_texture_filter_option_checked() -> None:
    scene, _, _ = _spot_scene()
    cam = sr.PerspectiveCamera(fov_y=45.0, width=8, height=8)
    r = sr.Renderer(8, 8)
    with pytest.raises(ValueError, match="texture_filter"):
        r.render(scene, cam, texture_filter="cubic")
    with pytest.raises(TypeError, match="texture_filter"):
        r.render(scene, cam, texture_filter=2)


def test_material_texture_slots_checked() -> None:
    with pytest.raises(TypeError, match="base_color_texture"):
        sr.Material(base_color_texture=np.zeros((2, 2, 3), np.uint8))
    with pytest.raises(TypeError, match="normal_texture"):
        sr.Material(normal_texture="normal.png")
    with pytest.raises(ValueError, match="normal_scale"):
        sr.Material(normal_scale=float("nan"))
    with pytest.raises(ValueError, match="normal_map_convention"):
        sr.Material(normal_map_convention="metal")


def test_texture_and_material_pickle_and_render_the_same() -> None:
    scene, mesh, tex = _spot_scene()
    tex2 = pickle.loads(pickle.dumps(tex))
    assert tex2.filter == tex.filter and tex2.wrap == tex.wrap
    np.testing.assert_array_equal(tex2.image, tex.image)
    mat2 = pickle.loads(pickle.dumps(mesh.material))
    assert mat2.base_color_texture is not None
    other = sr.Scene()
    tm = trimesh.load(ASSETS / "spot.obj", process=False)
    other.add(sr.Mesh(tm.vertices, tm.faces, normals=tm.vertex_normals, uvs=tm.visual.uv,
                      material=mat2))
    cam = sr.PerspectiveCamera(fov_y=45.0, width=64, height=48)
    cam.look_at(eye=(1.8, 0.6, 1.6), target=(0, 0, 0.3))
    r = sr.Renderer(64, 48)
    np.testing.assert_array_equal(r.render(scene, cam).color, r.render(other, cam).color)


def _pbr_quad_scene(material: sr.Material) -> sr.Scene:
    scene = sr.Scene(ambient_light=(0.2, 0.2, 0.2))
    scene.add(quad(material))
    scene.add(sr.PointLight(intensity=3.0), pose=np.array([[1, 0, 0, 0.7], [0, 1, 0, 0.4],
                                                         [0, 0, 1, 1.5], [0, 0, 0, 1.0]]))
    return scene


def test_metallic_roughness_texture_per_pixel() -> None:
    """Left half (g, b) = (0.25, 1.0), right half (1.0, 0.5): each half renders as the untextured
    material with roughness x g and metallic x b (the same formulas, per pixel)."""
    w = h = 16
    img = np.zeros((h, w, 3), np.float32)
    img[:, : w // 2] = (0, 0.25, 1.0)
    img[:, w // 2:] = (0, 1.0, 0.5)
    base = sr.Material(base_color=(0.8, 0.5, 0.3), metallic=0.8, roughness=0.6, model="pbr")
    textured = base.replace(metallic_roughness_texture=sr.Texture(img, filter="nearest"))
    r = sr.Renderer(w, h)
    cam = ortho_camera(w, h)
    got = r.render(_pbr_quad_scene(textured), cam, outputs=("radiance",)).radiance
    left = r.render(_pbr_quad_scene(base.replace(roughness=0.15, metallic=0.8)), cam, outputs=("radiance",)).radiance
    right = r.render(_pbr_quad_scene(base.replace(roughness=0.6, metallic=0.4)), cam, outputs=("radiance",)).radiance
    np.testing.assert_allclose(got[:, : w // 2], left[:, : w // 2], rtol=1e-5, atol=1e-6)
    np.testing.assert_allclose(got[:, w // 2:], right[:, w // 2:], rtol=1e-5, atol=1e-6)
    assert np.abs(left - right).max() > 0.05  # the halves really differ


@pytest.mark.parametrize("model", ["lambert", "blinn_phong", "pbr"])
def test_occlusion_texture_scales_only_the_ambient_term(model: str) -> None:
    w = h = 8
    ao = np.random.default_rng(5).random((h, w, 1)).astype(np.float32)
    base = sr.Material(base_color=(0.8, 0.5, 0.3), model=model)
    occluded = base.replace(occlusion_texture=sr.Texture(ao, filter="nearest"), occlusion_strength=0.75)
    r = sr.Renderer(w, h)
    cam = ortho_camera(w, h)
    got = r.render(_pbr_quad_scene(occluded), cam, outputs=("radiance",)).radiance
    plain = r.render(_pbr_quad_scene(base), cam, outputs=("radiance",)).radiance
    ambient = np.array([0.8, 0.5, 0.3]) * 0.2  # ka = kd = base colour (pbr: base) times Ia
    expected = plain + ambient * (0.75 * (ao - 1.0))
    np.testing.assert_allclose(got, expected, rtol=1e-5, atol=1e-6)


def test_bump_map_of_a_ramp_tilts_the_normal() -> None:
    """h(u) = a u (float texture, exact under bilinear between texel centres): dU = k a / w,
    the tangent-space normal (-dU, 0, 1) normalised, radiance max(0, n.l) (lambert, no ambient)."""
    w = h = 32
    a, k = 4.0, 2.0
    ramp = (a * (np.arange(w) + 0.5) / w).astype(np.float32)
    img = np.tile(ramp, (h, 1))[:, :, None]
    m = sr.Material(base_color=(1, 1, 1), ka=(0, 0, 0), model="lambert",
                    bump_texture=sr.Texture(img, filter="bilinear", wrap="clamp"), bump_scale=k)
    scene = sr.Scene()
    scene.add(quad(m))
    l = np.array([1.0, 0.5, 1.0]) / 1.5
    scene.add(sr.DirectionalLight(intensity=1.0), pose=_light_toward(l))
    frame = sr.Renderer(w, h).render(scene, ortho_camera(w, h), outputs=("radiance",))
    du = k * a / w
    n = np.array([-du, 0.0, 1.0]) / np.hypot(du, 1.0)
    inner = frame.radiance[:, 1:-2, 0]  # away from the clamped edge texels
    np.testing.assert_allclose(inner, max(0.0, n @ l), rtol=0, atol=1e-5)
    assert abs(n @ l - l[2]) > 0.1


def test_load_texture_bad_files(tmp_path: Path) -> None:
    with pytest.raises(FileNotFoundError, match="nope.png"):
        sr.load_texture(tmp_path / "nope.png")
    bad = tmp_path / "corrupt.png"
    bad.write_bytes(b"\x89PNG\r\n\x1a\n" + b"\x00" * 40)
    with pytest.raises(ValueError, match="corrupt.png"):
        sr.load_texture(bad)
    good = tmp_path / "t.png"
    img = np.random.default_rng(0).integers(0, 256, (5, 7, 3)).astype(np.uint8)
    sr.imwrite(good, img)
    tex = sr.load_texture(good, filter="nearest", wrap="clamp")
    np.testing.assert_array_equal(tex.image, img)
    assert tex.name == "t.png" and tex.filter == "nearest" and tex.wrap == ("clamp", "clamp")
    with pytest.raises(ValueError, match="filter"):
        sr.load_texture(good, filter="box")
