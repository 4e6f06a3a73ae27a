"""The per-pixel kernels exist twice, for AVX2 and for generic x86-64, chosen at run time
(cpp/simd.hpp); `Renderer(simd=False)` forces the generic ones. Both must give the same bits on
every output, for small triangles (eight-lane int32 edge path), large ones (int64 / double edge
path), clipped ones, overdraw, every shading feature set and both camera types."""
from __future__ import annotations

import numpy as np
import pytest
import trimesh

import softrast as sr
from conftest import ALL_OUTPUTS, icosphere, nv_clip_scene, pixel_mesh, pixel_ortho, scene_of
from softrast.nv._raster import _rasterize_clip


def _cpu_has_avx2() -> bool:
    try:
        with open("/proc/cpuinfo") as f:
            return any(line.startswith("flags") and " avx2" in line for line in f)
    except OSError:
        return False


def _both(scene, cam, width, height, **kw):
    fast = sr.Renderer(width, height, threads=2)
    generic = sr.Renderer(width, height, threads=2, simd=False)
    assert generic.isa == "generic"
    outputs = kw.pop("outputs", ALL_OUTPUTS)
    return (fast.render(scene, cam, outputs=outputs, **kw),
            generic.render(scene, cam, outputs=outputs, **kw))


def _assert_same_bits(a, b, outputs=ALL_OUTPUTS):
    for name in outputs:
        x, y = getattr(a, name), getattr(b, name)
        assert x.dtype == y.dtype and x.shape == y.shape
        assert x.tobytes() == y.tobytes(), f"{name}: AVX2 and generic kernels differ"


def test_isa_reports_the_cpu():
    r = sr.Renderer(8, 8)
    assert r.isa == ("avx2" if _cpu_has_avx2() else "generic")
    assert sr.Renderer(8, 8, simd=False).isa == "generic"
    assert "isa=" in repr(r)


@pytest.mark.parametrize("bad", ["yes", 1, None, 0.5])
def test_simd_must_be_a_bool(bad):
    with pytest.raises(ValueError, match="simd"):
        sr.Renderer(8, 8, simd=bad)


def _perspective(eye, target=(0.0, 0.0, 0.0), fov=50.0, near=0.05, far=50.0):
    cam = sr.PerspectiveCamera(fov_y=fov, near=near, far=far)
    cam.look_at(eye=eye, target=target)
    return cam


@pytest.mark.parametrize("shading", ["lambert", "unlit"])
@pytest.mark.parametrize("cull", ["back", "none"])
@pytest.mark.parametrize("size", [(64, 64), (257, 131), (640, 480)])
def test_icosphere_same_bits(shading, cull, size):
    # Triangles from ~40 px (sub 2 at 640x480) down to sub-pixel (sub 5 at 64x64).
    scene = scene_of(icosphere(2), icosphere(5, radius=0.6))
    cam = _perspective((0.4, 0.7, 2.4))
    a, b = _both(scene, cam, *size, shading=shading, cull=cull)
    _assert_same_bits(a, b)
    assert a.mask.any() and not a.mask.all()


@pytest.mark.parametrize("size", [(1536, 1536), (1500, 1700)])
def test_streamed_large_frames_same_bits(size):
    # Frames of 12 MB and more are written with non-temporal stores (AVX2 only): whole aligned
    # rows of the tile streamed, the rest (the last tile column, a colour row not 16-byte
    # aligned at width 1500) written as usual. The same bits as the generic kernels, and as the
    # same frame written into arrays the renderer did not allocate (out=, a misaligned view).
    scene = scene_of(icosphere(4), icosphere(2, radius=0.6))
    cam = _perspective((0.4, 0.7, 2.4))
    w, h = size
    outputs = ("color", "depth", "mask")
    assert w * h * 7 >= 12 << 20
    a, b = _both(scene, cam, w, h, outputs=outputs)
    _assert_same_bits(a, b, outputs)
    assert a.mask.any() and not a.mask.all()
    buf = np.empty(4 * w * h + 4, np.uint8)
    depth = buf[4:].view(np.float32).reshape(h, w)  # 4-byte but not 16-byte aligned
    c = sr.Renderer(w, h, threads=2).render(scene, cam, outputs=outputs, out={"depth": depth})
    assert c.depth.ctypes.data == depth.ctypes.data
    _assert_same_bits(a, c, outputs)


def test_large_and_clipped_triangles_same_bits():
    # A floor reaching past the near plane and far beyond the image: triangles thousands of
    # pixels wide (the non-small edge path), clipped at near, grazing at the horizon.
    floor = trimesh.creation.box(extents=(60.0, 0.1, 60.0))
    colors = np.random.default_rng(3).random((len(floor.vertices), 3))
    mesh = sr.Mesh(floor.vertices, floor.faces, colors=colors)
    cam = _perspective((0.0, 1.0, 3.0), target=(0.0, 0.8, 0.0), near=0.01, far=100.0)
    a, b = _both(scene_of(mesh), cam, 300, 200, cull="none")
    _assert_same_bits(a, b)
    assert a.mask.mean() > 0.3


def test_overdraw_soup_same_bits(rng):
    # Random overlapping triangles of every size, with colours, in both orientations.
    p = rng.normal(size=(3000, 3)) * 0.7
    soup = sr.Mesh(p, np.arange(3000).reshape(-1, 3), colors=rng.random((3000, 4)))
    a, b = _both(scene_of(soup, icosphere(3, radius=0.4)), _perspective((0.1, 0.2, 2.0)),
                 203, 170, cull="none")
    _assert_same_bits(a, b)
    assert (a.coverage > 3).any()  # real overdraw


def test_orthographic_pixel_grid_same_bits(rng):
    # Vertices on and near pixel centres and tile borders (64 px), jittered below a subpixel.
    w, h = 150, 130
    xs, ys = np.meshgrid(np.linspace(-3.0, w + 3.0, 23), np.linspace(-3.0, h + 3.0, 19))
    xy = np.stack([xs.ravel(), ys.ravel()], axis=1) + rng.uniform(-0.01, 0.01, (xs.size, 2))
    nx = xs.shape[1]
    faces = []
    for j in range(xs.shape[0] - 1):
        for i in range(nx - 1):
            v = j * nx + i
            faces += [[v, v + nx, v + 1], [v + 1, v + nx, v + nx + 1]]
    mesh = pixel_mesh(xy, np.array(faces), w, h, colors=rng.random((len(xy), 3)))
    a, b = _both(scene_of(mesh), pixel_ortho(w, h), w, h, cull="none", shading="unlit")
    _assert_same_bits(a, b)
    assert (a.coverage == 1).all()  # the grid covers the image exactly once, on either path


def test_nv_rasterize_clip_same_bits(rng):
    # softrast.nv's entry point (_core._rasterize_clip): triangles given in clip space, clipped
    # (near, far, w = 0, guard band) and rasterized by the core, in instanced and range mode.
    pos, tri = nv_clip_scene(rng)
    ranges = np.array([[0, len(tri)], [len(tri) // 3, len(tri) // 2]])
    for p, r in ((pos, np.array([[0, len(tri)]] * 2)), (pos[:1], ranges)):
        fast = _rasterize_clip(p, tri, r, 150, 230, True, threads=2)
        generic = _rasterize_clip(p, tri, r, 150, 230, True, threads=2, simd=False)
        for x, y in zip(fast, generic):
            assert x.tobytes() == y.tobytes(), "AVX2 and generic kernels differ"
        assert (fast[0][..., 3] > 0).mean() > 0.5 and len(np.unique(fast[0][..., 3])) > 100


@pytest.mark.parametrize("outputs", [("depth",), ("color",), ("normal", "mask"),
                                     ("triangle_id", "instance_id", "coverage")])
def test_each_output_subset_same_bits(outputs):
    scene = scene_of(icosphere(4))
    a, b = _both(scene, _perspective((0.0, 0.3, 2.2)), 190, 97, outputs=outputs)
    _assert_same_bits(a, b, outputs)


@pytest.mark.parametrize("simd", [True, False])
@pytest.mark.parametrize("camera", ["perspective", "orthographic"])
def test_vertex_pass_matches_the_scalar_projection(rng, simd, camera):
    # Vertices are transformed and projected, and normals taken to world space (in float, in
    # double where float would overflow or underflow), eight at a time; the last (count % 8) of a
    # mesh, any vertex outside a plane, behind the camera, past the guard band or not finite
    # after the pose go through the scalar code. One triangle per mesh puts every vertex on the
    # scalar path: the frames must equal those of one mesh holding all the triangles, to the bit.
    n, m = 1500, 1200
    p = rng.normal(size=(n, 3)) * 0.6
    p[rng.random(n) < 0.15] *= 30.0  # past the image's edges (some past the guard band), behind
    huge = rng.random(n) < 0.02  # finite here, infinite after the pose's scale
    p[huge] = np.sign(p[huge]) * rng.uniform(2e37, 3e38, size=(huge.sum(), 3))
    faces = rng.integers(0, n, size=(m, 3))
    colors = rng.random((n, 3))
    normals = rng.normal(size=(n, 3)) * rng.choice([1e-30, 1.0, 1e30], size=(n, 1))
    normals[rng.random(n) < 0.05] = 0.0  # no direction: unit() gives the zero vector
    pose = np.diag([20.0, 20.0, 20.0, 1.0])
    pose[:3, 3] = (0.0, 0.0, -1.0)
    if camera == "perspective":
        cam = sr.PerspectiveCamera(fov_y=60.0, near=0.1, far=40.0)
    else:
        cam = sr.OrthographicCamera(xmag=20.0, ymag=15.0, near=0.1, far=40.0)
    cam.look_at(eye=(0.3, 0.2, 30.0), target=(0.0, 0.0, 0.0))
    whole, split = sr.Scene(), sr.Scene()
    whole.add(sr.Mesh(p, faces, colors=colors, normals=normals), pose=pose)
    for f in faces:
        split.add(sr.Mesh(p[f], np.arange(3).reshape(1, 3), colors=colors[f], normals=normals[f]),
                  pose=pose)
    renderer = sr.Renderer(173, 131, threads=2, simd=simd)
    outputs = ("color", "depth", "mask", "normal", "coverage")
    a = renderer.render(whole, cam, outputs=outputs, cull="none")
    b = renderer.render(split, cam, outputs=outputs, cull="none")
    assert a.mask.mean() > 0.2
    _assert_same_bits(a, b, outputs)


@pytest.mark.parametrize("simd", [True, False])
@pytest.mark.parametrize("cull", ["back", "front", "none"])
@pytest.mark.parametrize("camera", ["perspective", "orthographic"])
@pytest.mark.parametrize("mirrored", [False, True])
def test_triangle_setup_matches_the_scalar_setup(rng, simd, cull, camera, mirrored):
    # Triangles are set up eight at a time (cull, bounding box, orientation, depth plane, fill
    # rule); a mesh's last (count % 8) faces and every clipped face go through the scalar
    # setup_triangle. One face per mesh puts every face there: the frames must equal those of one
    # mesh of all the faces, to the bit. Small and tiny triangles both ways round, slivers, exact
    # degenerates, triangles whose box holds no pixel centre, steep depth; some straddle the near
    # plane and the image's edges (clipped / partly outside).
    n = 900
    centres = rng.uniform(-1.2, 1.2, size=(n, 1, 3)) * (1.0, 1.0, 0.3)
    size = rng.choice([0.004, 0.02, 0.1, 0.4], size=(n, 1, 1))
    tri = centres + rng.normal(size=(n, 3, 3)) * size
    tri[: n // 8, 2] = tri[: n // 8, 0] + (tri[: n // 8, 1] - tri[: n // 8, 0]) * 2.0  # collinear
    tri[n // 8: n // 4, 2] = tri[n // 8: n // 4, 1] + rng.normal(size=(n // 4 - n // 8, 3)) * 1e-4  # slivers
    tri[n // 4: n // 4 + 20, :, 2] += 2.2  # through the near plane
    rng.shuffle(tri)
    p = tri.reshape(-1, 3)
    faces = np.arange(3 * n).reshape(-1, 3)
    colors = rng.random((3 * n, 3))
    pose = np.eye(4)
    pose[:3, 3] = (0.0, 0.0, -0.5)
    if mirrored:
        pose[0, 0] = -1.0
    if camera == "perspective":
        cam = sr.PerspectiveCamera(fov_y=50.0, near=0.5, far=10.0)
    else:
        cam = sr.OrthographicCamera(xmag=1.3, ymag=1.0, near=0.5, far=10.0)
    cam.look_at(eye=(0.1, -0.2, 2.4), target=(0.0, 0.0, 0.0))
    whole, split = sr.Scene(), sr.Scene()
    whole.add(sr.Mesh(p, faces, colors=colors), pose=pose)
    for f in faces:
        split.add(sr.Mesh(p[f], np.arange(3).reshape(1, 3), colors=colors[f]), pose=pose)
    renderer = sr.Renderer(97, 75, threads=2, simd=simd)
    outputs = ("color", "depth", "normal", "coverage")
    a = renderer.render(whole, cam, outputs=outputs, cull=cull)
    b = renderer.render(split, cam, outputs=outputs, cull=cull)
    assert (a.coverage > 0).mean() > 0.2
    _assert_same_bits(a, b, outputs)


@pytest.mark.parametrize("cull", ["back", "none"])
def test_forward_and_deferred_shading_same_bits(rng, cull):
    # Forward shading shades fragments as they win the depth test, deferred shading each visible
    # pixel after it; "auto" picks per tile. A pixel's shade depends only on its triangle and
    # itself, so all three give the same bits: small and large triangles, clipped ones, overdraw
    # (the soup, and with cull="none" the spheres' back faces), vertex colours and flat faces.
    p = rng.normal(size=(1500, 3)) * 0.7
    soup = sr.Mesh(p, np.arange(1500).reshape(-1, 3), colors=rng.random((1500, 4)))
    floor = trimesh.creation.box(extents=(60.0, 0.1, 60.0))
    scene = scene_of(icosphere(4, radius=0.5), soup, sr.Mesh(floor.vertices, floor.faces),
                     icosphere(2, radius=0.3))
    cam = _perspective((0.3, 0.9, 2.5), target=(0.0, 0.2, 0.0), near=0.01, far=100.0)
    renderer = sr.Renderer(221, 157, threads=2)
    frames = {path: renderer.render(scene, cam, outputs=ALL_OUTPUTS, cull=cull, shading_path=path)
              for path in ("forward", "deferred", "auto")}
    assert (frames["auto"].coverage > 2).any()
    _assert_same_bits(frames["forward"], frames["deferred"])
    _assert_same_bits(frames["auto"], frames["deferred"])
    for outputs in (("color",), ("normal",), ("depth", "mask")):
        a = renderer.render(scene, cam, outputs=outputs, cull=cull, shading_path="forward")
        _assert_same_bits(a, frames["deferred"], outputs)


def test_shading_path_is_checked():
    with pytest.raises(ValueError, match="shading_path"):
        sr.Renderer(8, 8).render(scene_of(icosphere(1)), _perspective((0, 0, 3)), shading_path="fast")
