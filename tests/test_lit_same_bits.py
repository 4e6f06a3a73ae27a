"""The lit model's kernels (every reflectance model, frequency and light kind, forward and
deferred, sRGB and linear colour) give the same bits for AVX2 and generic x86-64 and for any
thread count, as every other kernel does (cpp/simd.hpp, cpp/lighting.hpp)."""
from __future__ import annotations

import math

import numpy as np
import pytest
import trimesh

import softrast as sr
from softrast.reference.encoding import srgb_encode, srgb_to_linear
from conftest import ALL_OUTPUTS

MODELS = ("lambert", "phong", "blinn_phong", "pbr", "unlit", "normal")


def _pose(t, look=(0.0, 0.0, 0.0)):
    """A light pose at t whose -z axis points at `look`."""
    t = np.asarray(t, float)
    z = t - np.asarray(look, float)
    z /= np.linalg.norm(z)
    x = np.cross([0.0, 1.0, 0.0], z)
    if np.linalg.norm(x) < 1e-9:
        x = np.array([1.0, 0.0, 0.0])
    x /= np.linalg.norm(x)
    m = np.eye(4)
    m[:3, 0], m[:3, 1], m[:3, 2], m[:3, 3] = x, np.cross(z, x), z, t
    return m


def _lit_scene(model_auto: bool = True) -> sr.Scene:
    rng = np.random.default_rng(7)
    scene = sr.Scene(ambient_light=(0.05, 0.04, 0.03))
    mats = [sr.Material(base_color=tuple(rng.uniform(0.2, 1.0, 3)), ks=tuple(rng.uniform(0, 1, 3)),
                        shininess=float(rng.uniform(1, 200)), metallic=float(rng.uniform()),
                        roughness=float(rng.uniform(0.05, 1)), emissive=(0.02, 0.0, 0.01),
                        double_sided=bool(k % 2), model=MODELS[k % len(MODELS)])
            for k in range(6)]
    for k, m in enumerate(mats):
        tm = trimesh.creation.icosphere(subdivisions=2 + k % 3, radius=0.35)
        mesh = sr.Mesh(tm.vertices, tm.faces, normals=tm.vertex_normals, material=m)
        pose = np.eye(4)
        pose[:3, 3] = ((k % 3) - 1.0, (k // 3) - 0.5, 0.0)
        scene.add(mesh, pose=pose)
    # A vertex-coloured mesh without a material, and a flat-shaded one (no normals).
    tm = trimesh.creation.icosphere(subdivisions=3, radius=0.3)
    colors = (np.abs(tm.vertices) / 0.3).clip(0, 1)
    pose = np.eye(4); pose[:3, 3] = (0.0, 0.0, 0.6)
    scene.add(sr.Mesh(tm.vertices, tm.faces, normals=tm.vertex_normals, colors=colors), pose=pose)
    flat = sr.Mesh(tm.vertices, tm.faces, material=sr.Material(model="blinn_phong"))
    pose = np.eye(4); pose[:3, 3] = (0.6, 0.6, 0.3)
    scene.add(flat, pose=pose)
    scene.add(sr.DirectionalLight(color=(1.0, 0.9, 0.8), intensity=1.5), pose=_pose((1, 2, 3)))
    scene.add(sr.PointLight(intensity=4.0), pose=_pose((-1.5, 1.0, 2.0)))
    scene.add(sr.PointLight(color=(0.3, 0.5, 1.0), intensity=0.7, falloff="none"),
              pose=_pose((1.0, -1.0, 1.5)))
    scene.add(sr.SpotLight(intensity=6.0, inner_cone=0.2, outer_cone=0.5), pose=_pose((0, 0, 2.5)))
    scene.add(sr.SpotLight(intensity=1.0, inner_cone=0.1, outer_cone=0.3, falloff="none"),
              pose=_pose((0.2, 0.3, 0.5), look=(0.2, 0.3, -1.0)), camera_space=True)
    return scene


def _camera(orthographic: bool) -> sr.Camera:
    cam = sr.OrthographicCamera(xmag=1.6, ymag=1.2) if orthographic else sr.PerspectiveCamera(fov_y=50.0)
    cam.look_at((0.3, 0.4, 3.0), (0.0, 0.0, 0.0))
    return cam


OUTPUTS = tuple(ALL_OUTPUTS) + (("radiance",) if "radiance" not in ALL_OUTPUTS else ())


@pytest.mark.parametrize("shading", ("auto",) + MODELS)
@pytest.mark.parametrize("frequency", ["pixel", "vertex", "face"])
def test_lit_models_same_bits_for_both_isas_and_threads(shading, frequency):
    scene = _lit_scene()
    cam = _camera(orthographic=False)
    frames = [sr.Renderer(160, 120, threads=t, simd=simd).render(
                  scene, cam, outputs=OUTPUTS, shading=shading, frequency=frequency, cull="none")
              for simd in (True, False) for t in (1, 2, 3)]
    ref = frames[0]
    assert ref.mask.mean() > 0.2 and np.isfinite(ref.radiance).all()
    for f in frames[1:]:
        for name in OUTPUTS:
            assert getattr(f, name).tobytes() == getattr(ref, name).tobytes(), name


@pytest.mark.parametrize("shading", ("auto", "phong", "pbr"))
@pytest.mark.parametrize("frequency", ["pixel", "vertex", "face"])
def test_shadowed_lit_models_same_bits_for_both_isas_and_threads(shading, frequency):
    """Exact shadows (every light of the scene, render(shadows=True)) keep the same bits across
    instruction sets and thread counts, and darken some pixels the unshadowed render lights."""
    scene = _lit_scene()
    cam = _camera(orthographic=False)
    frames = [sr.Renderer(160, 120, threads=t, simd=simd).render(
                  scene, cam, outputs=OUTPUTS, shading=shading, frequency=frequency, cull="none",
                  shadows=True)
              for simd in (True, False) for t in (1, 2, 3)]
    ref = frames[0]
    for f in frames[1:]:
        for name in OUTPUTS:
            assert getattr(f, name).tobytes() == getattr(ref, name).tobytes(), name
    plain = sr.Renderer(160, 120).render(scene, cam, outputs=OUTPUTS, shading=shading,
                                         frequency=frequency, cull="none")
    darker = (ref.radiance < plain.radiance).any(-1)
    assert darker.sum() > 50 and not (ref.radiance > plain.radiance).any()
    for name in OUTPUTS:  # shadows change colour and radiance only
        if name not in ("color", "radiance"):
            assert getattr(plain, name).tobytes() == getattr(ref, name).tobytes(), name


@pytest.mark.parametrize("path", ["forward", "deferred"])
@pytest.mark.parametrize("orthographic", [False, True])
@pytest.mark.parametrize("srgb", [True, False])
def test_lit_paths_cameras_and_encodings_same_bits(path, orthographic, srgb):
    scene = _lit_scene()
    cam = _camera(orthographic)
    for shadows in (None, True):
        a, b = (sr.Renderer(211, 97, threads=2, simd=simd).render(
                    scene, cam, outputs=OUTPUTS, shading_path=path, srgb=srgb, shadows=shadows)
                for simd in (True, False))
        auto = sr.Renderer(211, 97, threads=2).render(scene, cam, outputs=OUTPUTS, srgb=srgb,
                                                      shadows=shadows)
        for name in OUTPUTS:
            assert getattr(a, name).tobytes() == getattr(b, name).tobytes(), name
            assert getattr(a, name).tobytes() == getattr(auto, name).tobytes(), name


def test_output_subsets_do_not_change_colour_or_radiance():
    scene = _lit_scene()
    cam = _camera(False)
    r = sr.Renderer(128, 96, threads=2)
    full = r.render(scene, cam, outputs=OUTPUTS)
    for outputs in (("color",), ("radiance",), ("color", "normal"), ("radiance", "depth")):
        part = r.render(scene, cam, outputs=outputs)
        for name in outputs:
            assert getattr(part, name).tobytes() == getattr(full, name).tobytes(), (outputs, name)


def test_srgb_colour_is_the_exact_curve_of_the_radiance():
    """Every float32 at the code boundaries encodes as round(255 * encode(x)) does in float64."""
    scene = _lit_scene()
    cam = _camera(False)
    for simd in (True, False):
        f = sr.Renderer(160, 120, threads=2, simd=simd).render(
            scene, cam, outputs=("color", "radiance", "mask"))
        want = srgb_encode(f.radiance.astype(np.float64))  # floor(255 curve(clamp(x)) + 0.5)
        np.testing.assert_array_equal(f.color[f.mask], want[f.mask])
        assert (f.color[~f.mask] == 0).all() and (f.radiance[~f.mask] == 0).all()
    # And at the thresholds themselves: an unlit mesh of vertex colours just below / above each
    # code's threshold (float32 neighbours), one pixel per colour.
    codes = np.arange(1, 256)
    t = (codes - 0.5) / 255.0
    lin = srgb_to_linear(t).astype(np.float32)
    vals = np.concatenate([np.nextafter(lin, np.float32(0)), lin, np.nextafter(lin, np.float32(1)),
                           np.float32([0.0, 1.0, 2.0, 1e-30, 1.1e-4, 0.5, 0.99999994])])
    n = len(vals)
    w = 32
    h = math.ceil(n / w)
    positions, faces, colors = [], [], []
    for k, v in enumerate(vals):
        i, j = divmod(k, w)
        base = len(positions)
        positions += [(j, -i, 0.0), (j + 1, -i, 0.0), (j + 1, -i - 1, 0.0), (j, -i - 1, 0.0)]
        faces += [(base, base + 3, base + 2), (base, base + 2, base + 1)]
        colors += [(min(float(v), 1.0),) * 3 + (1.0,)] * 4
    pos = np.array(positions, float)
    f_ = np.array(faces)
    # counter-clockwise seen from +z
    a, b, c = pos[f_[:, 0]], pos[f_[:, 1]], pos[f_[:, 2]]
    flip = np.cross(b - a, c - a)[:, 2] < 0
    f_[flip] = f_[flip][:, [0, 2, 1]]
    mesh = sr.Mesh(pos, f_, colors=np.array(colors, np.float32))
    cam = sr.OrthographicCamera(xmag=w / 2, ymag=h / 2)
    m = np.eye(4); m[:3, 3] = (w / 2, -h / 2, 5.0)
    cam.pose = m
    sc = sr.Scene(); sc.add(mesh)
    for simd in (True, False):
        f = sr.Renderer(w, h, threads=1, simd=simd).render(sc, cam, outputs=("color",), shading="unlit")
        got = f.color[..., 0].reshape(-1)[:n].astype(float)
        clipped = np.minimum(vals, 1.0).astype(np.float64)
        np.testing.assert_array_equal(got, srgb_encode(clipped))


def test_light_pass_lights_each_pixel_with_its_own_draws_material():
    """The tile's light pass (cpp/shade_kernels.hpp, light_tile) lights groups of eight pixels that
    belong to different draws, each lane with its own draw's material and model. A pixel's shade
    depends only on its triangle and the pixel, so a scene of finely interleaved strips of four
    materials (every group of eight mixes them) must give, at each pixel, the same bits as that
    material's strips rendered alone."""
    rng = np.random.default_rng(3)
    n = 64  # strips, one or two pixels wide: groups of eight lanes span several draws
    mats = [sr.Material(base_color=(0.8, 0.4, 0.2), ks=(0.6, 0.6, 0.6), shininess=40.0, model="blinn_phong"),
            sr.Material(base_color=(0.2, 0.7, 0.3), metallic=0.3, roughness=0.35, model="pbr"),
            sr.Material(base_color=(0.3, 0.3, 0.9), ks=(0.4, 0.2, 0.1), shininess=9.0, model="phong",
                        emissive=(0.05, 0.0, 0.0)),
            sr.Material(base_color=(0.9, 0.9, 0.6), model="lambert")]
    strips = [[] for _ in mats]
    for k in range(n):
        x0, x1 = -1.0 + 2.0 * k / n, -1.0 + 2.0 * (k + 1) / n
        # a slightly bumpy strip: its vertex normals differ, so lighting varies per pixel
        z = rng.uniform(-0.05, 0.05, 4)
        v = np.array([[x0, -1, z[0]], [x1, -1, z[1]], [x1, 1, z[2]], [x0, 1, z[3]]], float)
        nrm = np.column_stack([rng.uniform(-0.3, 0.3, (4, 2)), np.ones(4)])
        strips[k % len(mats)].append((v, nrm))

    def scene_of(which):
        scene = sr.Scene(ambient_light=(0.05, 0.05, 0.05))
        for m in which:
            verts = np.concatenate([v for v, _ in strips[m]])
            normals = np.concatenate([nr for _, nr in strips[m]])
            faces = np.concatenate([np.array([[0, 1, 2], [0, 2, 3]]) + 4 * j for j in range(len(strips[m]))])
            scene.add(sr.Mesh(verts, faces, normals=normals, material=mats[m]))
        scene.add(sr.PointLight(intensity=3.0), pose=_pose((0.5, 0.5, 1.5)))
        scene.add(sr.PointLight(color=(0.4, 0.6, 1.0), intensity=2.0), pose=_pose((-0.7, -0.3, 1.0)))
        scene.add(sr.DirectionalLight(intensity=0.8), pose=_pose((1, 1, 2)))
        scene.add(sr.SpotLight(intensity=5.0, inner_cone=0.2, outer_cone=0.6), pose=_pose((0, 0, 2.0)))
        return scene

    cam = sr.PerspectiveCamera(fov_y=60.0)
    cam.look_at((0.1, 0.2, 2.2), (0.0, 0.0, 0.0))
    for path in ("forward", "deferred"):
        r = sr.Renderer(200, 150, threads=2)
        outs = ("radiance", "instance_id")
        full = r.render(scene_of(range(len(mats))), cam, outputs=outs, shading_path=path)
        ids = np.array(full.instance_id)
        rad = np.array(full.radiance)
        assert len(np.unique(ids[ids >= 0])) == len(mats)
        for m in range(len(mats)):
            alone = sr.Renderer(200, 150, threads=1).render(scene_of([m]), cam, outputs=outs, shading_path=path)
            here = ids == m
            assert here.sum() > 500
            np.testing.assert_array_equal(rad[here], np.array(alone.radiance)[here], err_msg=f"{path} material {m}")
        # every eight-pixel group of a row holds several materials somewhere
        row = ids[75]
        assert max(len(set(row[x:x + 8]) - {-1}) for x in range(0, 200, 8)) >= 3
