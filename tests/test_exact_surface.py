"""Surface outputs are exact: every visible pixel's depth, ray_depth, position, barycentric and uv
against the float64 ray caster of tests/support/exact_hit.py (the pixel's own ray on the plane of
the triangle the render says is visible there), on the cases where the snapped triangle used to be
read instead: grazing slivers (random, and a real mesh seen edge-on), ground quads of half-size 1e2
to 1e7, a receding floor at fov 1 and 170 degrees, orthographic views and msaa=4 samples.

The bounds are the README's ("Surface outputs are exact"):
- depth, ray_depth and position within 4 units in the last place of float32 (of the exact
  value; for position, of its largest coordinate);
- the barycentric point (the output weights, in float64, on the posed corners) reprojects within
  1e-4 px of the pixel centre, where the triangle spans under 1e3 px (the weights are float32:
  they carry 6e-8 of the triangle's extent);
- uv within 1e-6 (uvs of magnitude up to 1; beyond, float32's own rounding of the uv).
"""
from __future__ import annotations

import numpy as np
import pytest
import trimesh

from support import exact_hit as ex
import softrast as sr

SURFACE = ("depth", "ray_depth", "position", "barycentric", "uv", "triangle_id", "instance_id")
ULPS = 4.0


def _render(instances, camera, w, h, **kw):
    scene = sr.Scene()
    for iid, (mesh, pose) in instances.items():
        scene.add(mesh, pose=pose, instance_id=iid)
    return sr.Renderer(w, h).render(scene, camera, SURFACE, cull="none", **kw)


def _check(frame, instances, camera, w, h, sample=(0.5, 0.5), pixels=None, reproject=True,
           uv_scale=1.0):
    """Asserts the README's bounds at every visible pixel; returns the worst of each."""
    hits = ex.hits(frame, instances, camera, w, h, sample=sample, pixels=pixels)
    r, c = hits.rows, hits.cols
    assert len(r) > 0
    worst = {}
    for name in ("depth", "ray_depth"):
        u = ex.ulps(getattr(frame, name)[r, c], getattr(hits, name))
        worst[name] = float(u.max())
        assert worst[name] <= ULPS, (name, worst[name])
    pos = frame.position[r, c].astype(np.float64)
    scale = np.spacing(np.abs(hits.position).max(1).astype(np.float32)).astype(np.float64)
    worst["position"] = float((np.abs(pos - hits.position).max(1) / scale).max())
    assert worst["position"] <= ULPS, worst["position"]
    bary = frame.barycentric[r, c].astype(np.float64)
    # within 2 ulps of the exact weights, plus 1e-9 where the two float64 computations part (a
    # sliver's weights are ill-conditioned: the caster's Cramer rule and the core's plane differ)
    err = np.abs(bary - hits.barycentric)
    worst["barycentric_ulps"] = float((err / np.spacing(np.abs(hits.barycentric).astype(np.float32))).max())
    worst["barycentric_abs"] = float(err.max())
    ulp = np.spacing(np.abs(hits.barycentric).astype(np.float32)).astype(np.float64)
    assert (err <= 2 * ulp + 1e-9).all(), (worst["barycentric_ulps"], worst["barycentric_abs"])
    if reproject:
        corners = _corners(frame, instances, r, c)
        point = np.einsum("nc,ncd->nd", bary, corners)
        px = ex.reproject_px(point, camera, w, h)
        worst["reproject_px"] = float(np.abs(px - np.c_[c + sample[0], r + sample[1]]).max())
        assert worst["reproject_px"] <= 1e-4, worst["reproject_px"]
    if hits.uv is not None:
        worst["uv"] = float(np.abs(frame.uv[r, c] - hits.uv).max())
        assert worst["uv"] <= 1e-6 * max(1.0, uv_scale), worst["uv"]
    return worst


def _corners(frame, instances, r, c):
    tri, inst = frame.triangle_id[r, c], frame.instance_id[r, c]
    out = np.empty((len(r), 3, 3))
    for iid, (mesh, pose) in instances.items():
        sel = inst == iid
        local = mesh.positions[mesh.faces[tri[sel]]].astype(np.float64)
        out[sel] = local @ np.asarray(pose)[:3, :3].T + np.asarray(pose)[:3, 3]
    return out


def _ground(half: float, uv_unit: bool = True) -> sr.Mesh:
    quad = np.array([[-half, 0, -half], [half, 0, -half], [half, 0, half], [-half, 0, half]])
    return sr.Mesh(quad, [[0, 2, 1], [0, 3, 2]], uvs=quad[:, [0, 2]] / (2 * half) + 0.5)


# ---------------------------------------------------------------------------------- floors

@pytest.mark.parametrize("half", [1e2, 1e4, 1e6, 1e7])
def test_ground_quads_are_exact_at_every_pixel(half: float) -> None:
    """A ground quad under a camera 1.7 units up, to the horizon: before, 5.2e-5 relative (1e6)
    and 1.5e-4 for position and uv; now every pixel within 4 ulps."""
    w, h = 320, 240
    cam = sr.PerspectiveCamera(fov_y=60.0, near=0.05, far=1e9)
    cam.look_at((0.3, 1.7, 0.2), (3.0, 1.2, -10.0))
    inst = {1: (_ground(half), np.eye(4))}
    frame = _render(inst, cam, w, h)
    assert (frame.triangle_id >= 0).mean() > 0.4
    # weights of a triangle 2e7 wide carry float32's 6e-8 of it: reproject only the small ones
    worst = _check(frame, inst, cam, w, h, reproject=False)
    print(f"half-size {half:g}: {worst}")


@pytest.mark.parametrize("fov", [1.0, 170.0])
@pytest.mark.filterwarnings("ignore:fov_y is in degrees")
def test_receding_floor_at_extreme_fields_of_view(fov: float) -> None:
    """Looking just below the horizon over a floor 2e4 wide: before, position, uv and ray_depth
    were off by 1.5e-4 relative and the barycentric point by 1.9e-3 px."""
    w, h = 320, 240
    cam = sr.PerspectiveCamera(fov_y=fov, near=0.05, far=1e6)
    cam.look_at((0.0, 1.0, 0.0), (0.0, 1.0 - (0.01 if fov < 10 else 0.3), -1.0))
    inst = {1: (_ground(1e4), np.eye(4))}
    frame = _render(inst, cam, w, h)
    assert (frame.triangle_id >= 0).mean() > 0.3
    print(f"fov {fov}: {_check(frame, inst, cam, w, h, reproject=False)}")


def test_orthographic_floor_and_sphere() -> None:
    w, h = 256, 192
    tm = trimesh.creation.icosphere(subdivisions=4)
    sphere = sr.Mesh(tm.vertices, tm.faces, uvs=np.asarray(tm.vertices)[:, :2] * 0.5 + 0.5)
    pose = np.eye(4)
    pose[:3, 3] = (0.0, 1.0, 0.0)
    inst = {1: (_ground(50.0), np.eye(4)), 2: (sphere, pose)}
    cam = sr.OrthographicCamera(xmag=4.0, ymag=3.0, near=0.1, far=100.0)
    cam.look_at((5.0, 2.5, 6.0), (0.0, 0.5, 0.0))
    frame = _render(inst, cam, w, h)
    print(_check(frame, inst, cam, w, h))
    np.testing.assert_array_equal(frame.ray_depth, frame.depth)


# --------------------------------------------------------------------------------- slivers

def _random_slivers(rng, n: int) -> np.ndarray:
    """The corners (3n, 3) of n random slivers, widths 1e-4 to 1e-2 of their length 0.5-3, about
    6 units in front of a camera at the origin looking down -z."""
    tris = []
    for _ in range(n):
        a = rng.uniform(-2, 2, 3) * [1, 0.2, 1] + [0, 0, -6]
        d = rng.normal(size=3)
        d /= np.linalg.norm(d)
        length = rng.uniform(0.5, 3.0)
        side = np.cross(d, rng.normal(size=3))
        side /= np.linalg.norm(side)
        width = length * 10 ** rng.uniform(-4, -2)
        tris.append([a, a + length * d, a + 0.5 * length * d + width * side])
    return np.array(tris).reshape(-1, 3)


def test_random_grazing_slivers() -> None:
    """300 random slivers (widths 1e-4 to 1e-2 of their length) on planes seen at grazing angles:
    before, depth off by up to 1.4e-3 relative."""
    rng = np.random.default_rng(34)
    n = 300
    positions = _random_slivers(rng, n)
    mesh = sr.Mesh(positions, np.arange(3 * n).reshape(-1, 3), uvs=rng.uniform(0, 1, (3 * n, 2)))
    w, h = 320, 240
    cam = sr.PerspectiveCamera(fov_y=50.0, near=0.05, far=100.0)
    cam.look_at((0.0, 0.05, 0.0), (0.0, 0.0, -6.0))
    inst = {1: (mesh, np.eye(4))}
    frame = _render(inst, cam, w, h)
    assert (frame.triangle_id >= 0).sum() > 500
    print(_check(frame, inst, cam, w, h))


def test_a_grazing_floor_cut_into_slivers() -> None:
    """Strips 0.002 units wide of a grazing floor (tests/test_extreme_scales.py's sliver case),
    which before kept their corners' own keys: 1e-3 relative."""
    n = 1500
    xs = np.linspace(-1.5, 1.5, n + 1)
    quads = [[[xs[k], 0, -0.5], [xs[k + 1], 0, -0.5], [xs[k + 1], 0, -60.0], [xs[k], 0, -60.0]]
             for k in range(n)]
    positions = np.array(quads).reshape(-1, 3)
    base = 4 * np.arange(n)[:, None]
    faces = np.concatenate([base + [0, 1, 2], base + [0, 2, 3]])
    mesh = sr.Mesh(positions, faces, uvs=positions[:, [0, 2]] / 60.0)
    cam = sr.PerspectiveCamera(fov_y=40.0, near=0.05, far=1e3)
    cam.look_at((0.05, 0.3, 1.0), (0.0, 0.25, -10.0))
    inst = {1: (mesh, np.eye(4))}
    frame = _render(inst, cam, 320, 240)
    print(_check(frame, inst, cam, 320, 240))


def test_a_real_mesh_seen_edge_on() -> None:
    """Spot (assets/meshes/spot.obj) from views where many of its faces are edge-on: every
    silhouette pixel too."""
    spot = sr.load_mesh(__import__("pathlib").Path(__file__).resolve().parents[1] / "assets/meshes/spot.obj")
    rng = np.random.default_rng(7)
    for k in range(4):
        d = rng.normal(size=3)
        d /= np.linalg.norm(d)
        cam = sr.PerspectiveCamera(fov_y=40.0, near=0.05, far=100.0)
        cam.look_at(np.array([0.0, 0.3, 0.0]) + 2.6 * d, (0.0, 0.3, 0.0))
        inst = {1: (spot, np.eye(4))}
        frame = _render(inst, cam, 320, 240)
        print(_check(frame, inst, cam, 320, 240))


# ----------------------------------------------------------------------------- anti-aliasing

def test_msaa4_reads_each_pixel_at_its_representative_sample() -> None:
    """Under msaa=4 a pixel's surface outputs describe its representative sample (the covered
    sample nearest the centre): each pixel's position reprojects onto one of the pattern's
    samples, and all outputs are that sample's exact hit."""
    w, h = 160, 120
    tm = trimesh.creation.icosphere(subdivisions=3)
    sphere = sr.Mesh(tm.vertices, tm.faces, uvs=np.asarray(tm.vertices)[:, :2] * 0.5 + 0.5)
    inst = {1: (sphere, np.eye(4)), 2: (_ground(30.0), np.eye(4) + np.diag([0, 0, 0, 0]))}
    inst[2][1][1, 3] = -1.0
    cam = sr.PerspectiveCamera(fov_y=50.0, near=0.05, far=1e3)
    cam.look_at((0.4, 0.6, 3.2), (0.0, -0.2, 0.0))
    frame = _render(inst, cam, w, h, msaa=4)
    vis = frame.triangle_id >= 0
    rows, cols = np.nonzero(vis)
    px = ex.reproject_px(frame.position[vis].astype(np.float64), cam, w, h) - np.c_[cols, rows]
    pattern = sr.sample_positions(msaa=4)
    dist = np.linalg.norm(px[:, None, :] - pattern[None], axis=2)
    which = dist.argmin(1)
    assert dist.min(1).max() < 1e-3
    for s, offset in enumerate(pattern):
        pixels = np.zeros_like(vis)
        pixels[rows[which == s], cols[which == s]] = True
        if pixels.any():
            print(s, _check(frame, inst, cam, w, h, sample=tuple(offset), pixels=pixels))


# --------------------------------------------------------------------------- what stays put

def test_visibility_is_the_rasters_and_threads_do_not_change_bits() -> None:
    """The exact step changes where on its triangle a pixel lands, not which triangle: ids,
    mask and coverage are the raster's (the golden hashes pin them to before the step), and
    every output is the same for any thread count and instruction set."""
    spot = sr.load_mesh(__import__("pathlib").Path(__file__).resolve().parents[1] / "assets/meshes/spot.obj")
    scene = sr.Scene()
    scene.add(spot)
    scene.add(_ground(1e5), pose=np.diag([1.0, 1.0, 1.0, 1.0]))
    cam = sr.PerspectiveCamera(fov_y=50.0, near=0.05, far=1e7)
    cam.look_at((1.8, 0.5, 2.2), (0.0, 0.3, 0.0))
    outs = SURFACE + ("mask", "coverage", "color", "normal")
    ref = sr.Renderer(200, 150, threads=1, simd=False).render(scene, cam, outs, cull="none")
    for threads, simd in ((2, True), (3, False), (1, True)):
        f = sr.Renderer(200, 150, threads=threads, simd=simd).render(scene, cam, outs, cull="none")
        for name in outs:
            np.testing.assert_array_equal(getattr(f, name), getattr(ref, name), err_msg=name)


# ------------------------------------------------------ the normal output and shading's inputs

def _tilted_ground(half: float) -> sr.Mesh:
    """A ground quad whose vertex normals lean differently at each corner, so that the
    interpolated normal varies across it (a flat one would hide where the weights land)."""
    quad = np.array([[-half, 0, -half], [half, 0, -half], [half, 0, half], [-half, 0, half]])
    n = np.array([[0.3, 1, 0.1], [-0.2, 1, 0.3], [0.1, 1, -0.3], [-0.3, 1, -0.1]])
    return sr.Mesh(quad, [[0, 2, 1], [0, 3, 2]], normals=n / np.linalg.norm(n, axis=1, keepdims=True),
                   uvs=quad[:, [0, 2]] / (2 * half) + 0.5)


def _smooth_sphere() -> sr.Mesh:
    tm = trimesh.creation.icosphere(subdivisions=3)
    return sr.Mesh(tm.vertices, tm.faces, normals=tm.vertex_normals,
                   uvs=np.asarray(tm.vertices)[:, :2] * 0.4 + 0.5)


def _exact_normals(hits, frame, instances) -> np.ndarray:
    """The mesh's vertex normals, posed (inverse transpose) and unit, interpolated in float64
    with the exact hit's weights, unit: the normal output's exact value (sign: the visible
    side, taken from the output)."""
    r, c = hits.rows, hits.cols
    tri, inst = frame.triangle_id[r, c], frame.instance_id[r, c]
    out = np.zeros((len(r), 3))
    for iid, (mesh, pose) in instances.items():
        sel = inst == iid
        n = np.asarray(mesh.normals, np.float64) @ np.linalg.inv(np.asarray(pose)[:3, :3])
        n /= np.linalg.norm(n, axis=1, keepdims=True)
        out[sel] = np.einsum("nc,ncd->nd", hits.barycentric[sel], n[np.asarray(mesh.faces)[tri[sel]]])
    out /= np.linalg.norm(out, axis=1, keepdims=True)
    return out * np.sign((out * frame.normal[r, c]).sum(1))[:, None]


def _normal_cases():
    cam_floor = sr.PerspectiveCamera(fov_y=60.0, near=0.05, far=1e9)
    cam_floor.look_at((0.3, 1.7, 0.2), (3.0, 1.2, -10.0))
    cam_spot = sr.PerspectiveCamera(fov_y=40.0, near=0.05, far=100.0)
    cam_spot.look_at((1.7, 0.9, -2.3), (0.0, 0.05, 0.15))
    spot = sr.load_mesh(__import__("pathlib").Path(__file__).resolve().parents[1] / "assets/meshes/spot.obj")
    return {"receding floor": ({1: (_tilted_ground(1e4), np.eye(4))}, cam_floor),
            "spot": ({1: (spot, np.eye(4))}, cam_spot),
            "sphere": ({1: (_smooth_sphere(), np.eye(4))}, cam_spot)}


@pytest.mark.parametrize("case", ["receding floor", "spot", "sphere"])
@pytest.mark.parametrize("shading", ["auto", "normal", "pbr"])
def test_the_normal_output_is_interpolated_at_the_exact_hit(case: str, shading: str) -> None:
    """normal (normal_kind="interpolated", the default) is the vertex normals interpolated with
    the exact step's weights, whatever the draw's model: within 3e-7 of float64 (before, the
    snapped triangle's weights put it up to 4.6e-3 off on Spot, 3e-4 on a smooth sphere)."""
    instances, cam = _normal_cases()[case]
    w, h = 320, 240
    scene = sr.Scene()
    for iid, (mesh, pose) in instances.items():
        scene.add(mesh, pose=pose, instance_id=iid)
    frame = sr.Renderer(w, h).render(scene, cam, ("normal", "triangle_id", "instance_id"),
                                     cull="none", shading=shading)
    hits = ex.hits(frame, instances, cam, w, h)
    assert len(hits.rows) > 2000
    err = np.abs(frame.normal[hits.rows, hits.cols] - _exact_normals(hits, frame, instances)).max()
    print(f"{case} ({shading}): normal within {err:.3g}")
    assert err <= 3e-7, err


@pytest.mark.parametrize("case", ["receding floor", "spot", "sphere"])
def test_shading_reads_the_exact_uv_and_position(case: str) -> None:
    """What shading reads of a draw whose model reads uvs or positions comes from the exact
    weights: the uv view's radiance is the exact hit's uv (within 3e-7, as the uv output; before,
    2e-4 off on Spot), the depth view's its view depth (6 ulps), and normal_kind="shading" gives the
    normal the lighting used, which for such draws is the exact one."""
    instances, cam = _normal_cases()[case]
    w, h = 320, 240
    scene = sr.Scene()
    for iid, (mesh, pose) in instances.items():
        scene.add(mesh, pose=pose, instance_id=iid)
    r = sr.Renderer(w, h)
    outs = ("radiance", "normal", "triangle_id", "instance_id", "uv", "depth")
    uv_view = r.render(scene, cam, outs, cull="none", shading="uv", normal_kind="shading")
    hits = ex.hits(uv_view, instances, cam, w, h)
    rr, cc = hits.rows, hits.cols
    inside = (hits.uv > 1e-3).all(1) & (hits.uv < 1 - 1e-3).all(1)  # (the view clamps to [0, 1])
    assert inside.sum() > 1000
    err_uv = np.abs(uv_view.radiance[rr, cc, :2] - hits.uv)[inside].max()
    assert err_uv <= 3e-7, err_uv
    assert np.abs(uv_view.normal[rr, cc] - _exact_normals(hits, uv_view, instances)).max() <= 3e-7
    # the depth view: grey = (far - depth) / (far - near), clamped; a near/far pair that keeps
    # the hits inside makes grey a function of the shading position's depth alone
    near, far = float(hits.depth.min()) * 0.5, float(hits.depth.max()) * 2.0
    cam_d = type(cam)(**{k: getattr(cam, k) for k in ("fov_y",)}, near=near, far=far)
    cam_d.pose = cam.pose
    grey = r.render(scene, cam_d, ("radiance", "triangle_id"), cull="none", shading="depth").radiance[rr, cc, 0]
    want = (far - hits.depth) / (far - near)
    # grey's own rounding is that of (far - depth) / (far - near) in float32: ulps of far - near
    err_grey = np.abs(grey - want).max() / (np.spacing(np.float32(far)) / (far - near))
    print(f"{case}: uv within {err_uv:.3g}, depth grey within {err_grey:.2f} ulps")
    assert err_grey <= 6, err_grey


def test_the_normal_output_of_slivers_is_exact_too() -> None:
    """Slivers keep the raster's weights in shading (ill-conditioned unsnapped form: kExactDepth);
    their normal output is recomputed from the exact step's weights instead."""
    rng = np.random.default_rng(35)
    n = 300
    positions = _random_slivers(rng, n)
    normals = rng.normal(size=(3 * n, 3))
    mesh = sr.Mesh(positions, np.arange(3 * n).reshape(-1, 3),
                   normals=normals / np.linalg.norm(normals, axis=1, keepdims=True))
    cam = sr.PerspectiveCamera(fov_y=50.0, near=0.05, far=100.0)
    cam.look_at((0.0, 0.05, 0.0), (0.0, 0.0, -6.0))
    inst = {1: (mesh, np.eye(4))}
    frame = sr.Renderer(320, 240).render(_scene(inst), cam,
                                         ("normal", "triangle_id", "instance_id"), cull="none")
    hits = ex.hits(frame, inst, cam, 320, 240)
    assert len(hits.rows) > 500
    err = np.abs(frame.normal[hits.rows, hits.cols] - _exact_normals(hits, frame, inst)).max(1)
    print(f"slivers: normal within {err.max():.3g}")
    assert err.max() <= 1e-6, err.max()


def _scene(instances) -> sr.Scene:
    scene = sr.Scene()
    for iid, (mesh, pose) in instances.items():
        scene.add(mesh, pose=pose, instance_id=iid)
    return scene
