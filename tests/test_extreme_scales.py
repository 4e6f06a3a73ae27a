"""Extreme but valid input renders correctly: huge and tiny scales, near/far of 1e-6/1e6, slivers."""
from __future__ import annotations

import numpy as np
import pytest
import trimesh

import softrast as sr

SPHERE = trimesh.creation.icosphere(subdivisions=4)
OUTPUTS = ("depth", "mask", "coverage", "color", "normal")


def _render(scale: float, near: float, far: float) -> sr.Frame:
    scene = sr.Scene()
    scene.add(sr.Mesh(SPHERE.vertices * scale, SPHERE.faces, normals=SPHERE.vertex_normals))
    cam = sr.PerspectiveCamera(fov_y=45.0, near=near, far=far)
    cam.look_at((0.0, 0.0, 3.4 * scale), (0.0, 0.0, 0.0))
    return sr.Renderer(128, 96).render(scene, cam, outputs=OUTPUTS)


@pytest.mark.parametrize("scale, near, far", [
    (1e30, 1e29, 1e31),
    (1e-30, 1e-31, 1e-29),
    (1e-3, 1e-6, 1e6),
    (1e3, 1e-6, 1e6),
    (1.0, 1e-6, 1e6),
])
def test_scaled_scene_renders_like_the_unit_scene(scale, near, far):
    # Scaling the scene, the camera and the planes together changes nothing but depth's unit.
    ref = _render(1.0, 0.05, 100.0)
    frame = _render(scale, near, far)
    np.testing.assert_array_equal(frame.mask, ref.mask)
    np.testing.assert_array_equal(frame.coverage, ref.coverage)
    assert set(np.unique(frame.coverage)) == {0, 1}
    np.testing.assert_allclose(frame.depth[frame.mask] / scale, ref.depth[ref.mask], rtol=2e-6)
    assert np.abs(frame.color.astype(int) - ref.color).max() <= 1
    assert np.isfinite(frame.normal).all()


def test_fan_of_slivers_is_watertight():
    # 2000 triangles a fraction of a pixel wide at the rim, all meeting at the centre pixel.
    n = 2000
    angles = np.linspace(0.0, 2.0 * np.pi, n + 1)[:-1]
    positions = np.vstack([[0.0, 0.0, 0.0], np.stack([np.cos(angles), np.sin(angles), np.zeros(n)], 1)])
    faces = np.array([[0, 1 + i, 1 + (i + 1) % n] for i in range(n)])
    scene = sr.Scene()
    scene.add(sr.Mesh(positions, faces))
    cam = sr.OrthographicCamera(xmag=1.1, ymag=1.1, near=0.1, far=10.0)
    cam.look_at((0.0, 0.0, 3.0), (0.0, 0.0, 0.0))
    frame = sr.Renderer(201, 201).render(scene, cam, outputs=("coverage",), cull="none")
    i, j = np.mgrid[0:201, 0:201]
    r = np.hypot(((j + 0.5) / 201 * 2 - 1) * 1.1, (1 - (i + 0.5) / 201 * 2) * 1.1)
    assert (frame.coverage[r < 0.99] == 1).all()  # the polygon's chords stay within 1e-3 of r = 1
    assert (frame.coverage[r > 1.0] == 0).all()


# A ground quad under a camera 1.7 units up: the common dataset idiom, cut by the near plane (and by
# the guard band when it is wide). The points clipping creates are computed from the corners
# transformed in double, so the cut quad keeps its plane: with float32 corners, a quad 1e6 wide read
# 1e-3 relative off at 50 units, 1e7 wide 1.4e-2, 1e4 wide 3.8e-6. The float32 window positions of
# the far corners (within a thousandth of a pixel of the horizon) then left 1.1e-4 and 5e-5; keys
# and positions from the vertex in double leave float32 rounding: 4 ulps, under 5e-7 relative
# (tests/test_exact_surface.py checks every pixel).
@pytest.mark.parametrize("half, bound", [(1e2, 5e-7), (1e4, 5e-7), (1e6, 5e-7), (1e7, 5e-7)])
def test_ground_plane_depth_is_exact_to_the_stated_bound(half: float, bound: float) -> None:
    w, h = 640, 480
    quad = np.array([[-half, 0, -half], [half, 0, -half], [half, 0, half], [-half, 0, half]])
    scene = sr.Scene()
    scene.add(sr.Mesh(quad, [[0, 2, 1], [0, 3, 2]]))
    cam = sr.PerspectiveCamera(fov_y=60.0, near=0.05, far=1e8)
    cam.look_at((0.3, 1.7, 0.2), (3.0, 1.2, -10.0), up=(0.0, 1.0, 0.0))
    depth = sr.Renderer(w, h).render(scene, cam, "depth", cull="none").depth
    # the exact ray-plane (y = 0) distance along the viewing axis at each pixel centre
    p = cam.projection_matrix(w, h)
    j, i = np.meshgrid(np.arange(w) + 0.5, np.arange(h) + 0.5)
    ray = np.stack([(j * 2 / w - 1 + p[0, 2]) / p[0, 0], (1 - i * 2 / h + p[1, 2]) / p[1, 1], -np.ones((h, w))], -1)
    to_world = np.linalg.inv(cam.view_matrix())
    dy = ray @ to_world[1, :3]
    with np.errstate(divide="ignore"):
        t = -to_world[1, 3] / dy
    seen = (t > 0) & (t < 50.0)
    assert seen.sum() > 0.4 * w * h and (depth[seen] > 0).all()
    rel = np.abs(depth[seen] - t[seen]) / t[seen]
    print(f"half-size {half:g}: depth within 50 units, max relative error {rel.max():.2e}")
    assert rel.max() <= bound


def _coplanar_triangles(rng: np.random.Generator, n: int) -> np.ndarray:
    """n random overlapping triangles on one tilted plane through the origin, (n, 3, 3)."""
    normal = np.array([0.2, 1.0, 0.3]) / np.linalg.norm([0.2, 1.0, 0.3])
    u = np.cross(normal, [1.0, 0.0, 0.0])
    u /= np.linalg.norm(u)
    v = np.cross(normal, u)
    centres = rng.uniform(-0.6, 0.6, (n, 1, 2))
    pts = centres + rng.normal(0.0, 0.45, (n, 3, 2))
    return pts[..., :1] * u + pts[..., 1:] * v


@pytest.mark.parametrize("orthographic", [False, True])
def test_coplanar_triangles_keep_the_one_drawn_first(orthographic: bool) -> None:
    """Keys of one plane computed from different triangles differ by rounding; the tie rule
    (a surface must be nearer by 2^-20 of its depth) gives every overlap to the first drawn."""
    rng = np.random.default_rng(5)
    tris = _coplanar_triangles(rng, 300)
    w, h = 256, 192
    cam = (sr.OrthographicCamera(xmag=1.6, ymag=1.2, near=0.05, far=100.0) if orthographic
           else sr.PerspectiveCamera(fov_y=50.0, near=0.05, far=100.0))
    cam.look_at((0.5, 2.0, 3.0), (0.0, 0.0, 0.0), up=(0.0, 1.0, 0.0))
    r = sr.Renderer(w, h)
    first = np.full((h, w), -1)
    for k in range(len(tris) - 1, -1, -1):  # each alone: where it covers, the earliest so far
        s = sr.Scene()
        s.add(sr.Mesh(tris[k], [[0, 1, 2]]))
        first[r.render(s, cam, "mask", cull="none").mask] = k
    s = sr.Scene()
    s.add(sr.Mesh(tris.reshape(-1, 3), np.arange(3 * len(tris)).reshape(-1, 3)))
    got = r.render(s, cam, "triangle_id", cull="none").triangle_id
    overlap = first >= 0
    lost = int((got[overlap] != first[overlap]).sum())
    print(f"{'orthographic' if orthographic else 'perspective'}: {int(overlap.sum())} pixels, "
          f"{lost} not won by the first triangle drawn")
    assert overlap.sum() > 0.2 * w * h and lost == 0


@pytest.mark.parametrize("gap", [1e-4, 4e-6])
@pytest.mark.parametrize("near_first", [True, False])
def test_parallel_planes_a_little_apart_keep_the_nearer_in_front(gap: float, near_first: bool) -> None:
    """Beyond the tie rule's 2^-20 (9.5e-7) of the depth, the nearer surface wins in any order:
    planes 1e-4 and 4e-6 apart (relative) at distance 1000, near/far 1e-6 / 1e6."""
    cam = sr.PerspectiveCamera(fov_y=4.0, near=1e-6, far=1e6)
    cam.look_at((0.0, 0.0, 1000.0), (0.0, 0.0, 0.0), up=(0.0, 1.0, 0.0))
    s = sr.Scene()
    quad = np.array([[-60.0, -60, 0], [60, -60, 0], [60, 60, 0], [-60, 60, 0]])
    planes = [(1, 1000.0 * gap), (2, 0.0)] if near_first else [(2, 0.0), (1, 1000.0 * gap)]
    for iid, z in planes:  # instance 1 is the nearer plane
        s.add(sr.Mesh(quad + [0, 0, z], [[0, 1, 2], [0, 2, 3]]), instance_id=iid)
    ids = sr.Renderer(64, 48).render(s, cam, "instance_id").instance_id
    assert (ids == 1).all()


def test_sliver_depth_is_exact() -> None:
    """Slivers (strips of a grazing ground plane, 0.002 units wide: under a pixel far away) keep
    their corners' own depth keys, which were off by up to the true depth's change over the
    1/512 px snap (1e-3 relative here); their depth now comes from the exact step:
    float32 rounding of the true distance at every pixel."""
    w, h, n = 320, 240, 1500
    xs = np.linspace(-1.5, 1.5, n + 1)
    quads = [[[xs[k], 0, -0.5], [xs[k + 1], 0, -0.5], [xs[k + 1], 0, -60.0], [xs[k], 0, -60.0]] for k in range(n)]
    positions = np.array(quads).reshape(-1, 3)
    base = 4 * np.arange(n)[:, None]
    faces = np.concatenate([base + [0, 1, 2], base + [0, 2, 3]])
    scene = sr.Scene()
    scene.add(sr.Mesh(positions, faces))
    cam = sr.PerspectiveCamera(fov_y=40.0, near=0.05, far=1e3)
    cam.look_at((0.05, 0.3, 1.0), (0.0, 0.25, -10.0), up=(0.0, 1.0, 0.0))
    depth = sr.Renderer(w, h).render(scene, cam, "depth", cull="none").depth
    p = cam.projection_matrix(w, h)
    to_world = np.linalg.inv(cam.view_matrix())

    def exact(x, y):  # ray-plane (y = 0) depth through window point (x, y)
        ray = np.stack([(x * 2 / w - 1 + p[0, 2]) / p[0, 0], (1 - y * 2 / h + p[1, 2]) / p[1, 1],
                        -np.ones_like(x)], -1)
        with np.errstate(divide="ignore"):
            return -to_world[1, 3] / (ray @ to_world[1, :3])

    x, y = np.meshgrid(np.arange(w) + 0.5, np.arange(h) + 0.5)
    t = exact(x, y)
    snap = 1.0 / 512.0
    change = np.abs(exact(x + snap, y) - exact(x - snap, y)) / 2 + np.abs(exact(x, y + snap) - exact(x, y - snap)) / 2
    seen = (depth > 0) & (t > 0)
    assert seen.sum() > 10000
    err = np.abs(depth - t)
    print(f"slivers: max relative depth error {(err / t)[seen].max():.2e}, "
          f"max error / bound {(err / (change + 4e-7 * t))[seen].max():.3f}")
    assert (err[seen] <= 5e-7 * t[seen]).all()
