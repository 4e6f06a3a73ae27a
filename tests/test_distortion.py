"""Lens distortion: IntrinsicsCamera(dist=) renders what the distorted camera sees.

Checked against OpenCV (cv2.projectPoints, cv2.undistortPointsIter) and against exact float64
ray casting of analytic scenes: every visible point reprojects to its own pixel centre, depth is
the ray's, and coverage is the exact rays' (tests/test_distortion_exact.py: every triangle that can
reach a pixel's ray is tested; it once differed within half a sample diagonal).
"""
from __future__ import annotations

import pickle

import cv2
import numpy as np
import pytest
import trimesh

import softrast as sr
from softrast.lens import check_dist, distort, undistort

W, H = 320, 240
K = np.array([[220.0, 0.0, 161.3], [0.0, 215.0, 118.6], [0.0, 0.0, 1.0]])
CALIBRATIONS = {
    # a wide-angle barrel lens: its model folds back before the image corners
    "barrel": np.array([-0.35, 0.15, 0.001, -0.0015, -0.03]),
    "pincushion": np.array([0.22, 0.05, -0.002, 0.001, 0.0]),
    "rational": np.array([0.1, -0.05, 0.001, 0.001, 0.01, 0.3, -0.02, 0.005]),
    "thin_prism": np.array([-0.2, 0.04, 0.001, 0.0005, 0.0, 0.0, 0.0, 0.0, 0.002, -0.001, 0.0015, 0.0005]),
}


def camera(dist, oversample=2, convention="opencv"):
    cam = sr.IntrinsicsCamera.from_opencv(K, np.zeros(3), np.zeros(3), W, H, dist=dist, near=0.1,
                                          far=50.0, oversample=oversample)
    cam.look_at((0.3, 1.1, 2.1), (0.0, -0.35, 0.0), up=(0.0, 1.0, 0.0))
    if convention == "opengl":  # the same camera in pyrender's axes and pixel convention
        gl = sr.IntrinsicsCamera(K[0, 0], K[1, 1], K[0, 2] + 0.5, K[1, 2] + 0.5, W, H, near=0.1, far=50.0,
                                 convention="opengl", dist=dist, oversample=oversample)
        gl.pose = cam.pose @ np.diag([1.0, -1.0, -1.0, 1.0])
        return gl
    return cam


QUAD = np.array([[-1.3, -0.6, -1.1], [1.2, -0.6, -0.9], [1.0, -0.4, 1.2], [-1.5, -0.4, 1.0]])  # planar


def scene(unique_ids=True):
    s = sr.Scene()
    s.add(sr.Mesh(QUAD, [[0, 2, 1], [0, 3, 2]]), color=(0.2, 0.5, 0.9), instance_id=7)
    s.add(sr.Mesh.from_trimesh(trimesh.creation.icosphere(3, radius=0.45)),
          pose=trimesh.transformations.translation_matrix((0.1, 0.0, 0.2)), color=(0.9, 0.4, 0.2),
          instance_id=7 if not unique_ids else 3)
    return s


def cv_undistort(points, k, d):
    """OpenCV's iterative inverse run to convergence (OpenCV 4 names it undistortPointsIter;
    OpenCV 5 folds the criteria into undistortPoints)."""
    crit = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 300, 1e-15)
    pts = np.asarray(points, np.float64).reshape(-1, 1, 2)
    if hasattr(cv2, "undistortPointsIter"):
        return cv2.undistortPointsIter(pts, k, d, None, None, crit).reshape(-1, 2)
    return cv2.undistortPoints(pts, k, d, None, None, None, crit).reshape(-1, 2)


def cv_project(cam, points):
    k, R, t, d = cam.to_opencv()
    uv, _ = cv2.projectPoints(np.asarray(points, np.float64).reshape(-1, 1, 3), cv2.Rodrigues(R)[0], t, k, d)
    return uv.reshape(-1, 2)


# -- the model ----------------------------------------------------------------------------------
@pytest.mark.parametrize("name", CALIBRATIONS)
def test_distort_is_opencvs_and_undistort_inverts_it(name: str) -> None:
    d = CALIBRATIONS[name]
    full = check_dist(d)
    rng = np.random.default_rng(1)
    x, y = rng.uniform(-0.8, 0.8, 2000), rng.uniform(-0.6, 0.6, 2000)
    xd, yd = distort(x, y, full)
    uv, _ = cv2.projectPoints(np.c_[x, y, np.ones_like(x)].reshape(-1, 1, 3), np.zeros(3), np.zeros(3), np.eye(3), d)
    np.testing.assert_allclose(np.c_[xd, yd], uv.reshape(-1, 2), rtol=0, atol=1e-12)
    xu, yu, valid = undistort(xd, yd, full)
    assert valid.all()
    np.testing.assert_allclose(np.c_[xu, yu], np.c_[x, y], rtol=0, atol=1e-10)
    # and OpenCV's own iterative inverse, run to convergence, agrees
    ref = cv_undistort(np.c_[xd, yd], np.eye(3), d)
    np.testing.assert_allclose(np.c_[xu, yu], ref, rtol=0, atol=1e-8)


def test_undistort_marks_what_the_lens_cannot_see() -> None:
    """A barrel model's distorted radius peaks and falls (it folds): beyond the peak no ray exists."""
    d = check_dist([-0.35, 0.15, 0.0, 0.0, -0.03])
    r = np.linspace(0.0, 3.0, 300001)
    rd = r * (1 - 0.35 * r**2 + 0.15 * r**4 - 0.03 * r**6)
    peak = rd[: np.argmax(np.diff(rd) <= 0)].max()
    probe = np.linspace(0.0, 1.2, 1201)
    x, _, valid = undistort(probe, np.zeros_like(probe), d)
    assert valid[probe < peak - 1e-6].all() and not valid[probe > peak + 1e-6].any()
    assert np.isnan(x[~valid]).all()


@pytest.mark.parametrize("name", CALIBRATIONS)
def test_project_equals_cv2_projectpoints(name: str) -> None:
    cam = camera(CALIBRATIONS[name])
    pts = np.random.default_rng(2).uniform(-1, 1, (500, 3)) * [1.0, 0.6, 1.0]
    np.testing.assert_allclose(cam.project(pts), cv_project(cam, pts), rtol=0, atol=1e-9)
    k, R, t, d = cam.to_opencv()
    assert np.array_equal(d, CALIBRATIONS[name]) or np.array_equal(d[:5], CALIBRATIONS[name][:5])


# -- renders ------------------------------------------------------------------------------------
@pytest.mark.parametrize("name", CALIBRATIONS)
@pytest.mark.parametrize("convention", ["opencv", "opengl"])
def test_every_visible_point_reprojects_to_its_pixel_centre(name: str, convention: str) -> None:
    """The promised 0.05 px: the point each pixel reports lands on that pixel's centre through
    cv2.projectPoints with the same distortion (float32 positions: ~1e-4 px)."""
    cam = camera(CALIBRATIONS[name], convention=convention)
    f = sr.Renderer(W, H).render(scene(), cam, ("position", "depth", "ray_depth", "mask"))
    rows, cols = np.nonzero(f.mask)
    assert rows.size > 0.2 * W * H
    uv = cv_project(camera(CALIBRATIONS[name]), f.position[rows, cols])
    err = np.hypot(uv[:, 0] - cols, uv[:, 1] - rows)
    exact = err < 2e-3
    print(f"{name}/{convention}: {exact.mean():.2%} of the points reproject within 2e-3 px (median "
          f"{np.median(err):.1e} px); the rest, rays that pass beside a silhouette, within {err.max():.2f} px")
    assert exact.all()  # exact rays: every pixel's point is on its own ray (once 99%)
    # ... so on the ideal image, each point is its ray's point (once within half a sample diagonal).
    k, R, t, d = cam.to_opencv()
    cam_pts = f.position[rows, cols].astype(np.float64) @ R.T + t
    ideal = cam_pts[:, :2] / cam_pts[:, 2:] * [k[0, 0], k[1, 1]] + [k[0, 2], k[1, 2]]
    ray = cv_undistort(np.c_[cols, rows].astype(np.float64), k, d) * [k[0, 0], k[1, 1]] + [k[0, 2], k[1, 2]]
    off = np.hypot(*(ideal - ray).T)
    assert off.max() <= 1e-3, off.max()
    # depth is along the viewing axis to the same point; ray_depth the distance to it
    k, R, t, _ = cam.to_opencv()
    z = (f.position[rows, cols].astype(np.float64) @ R.T + t)[:, 2]
    np.testing.assert_allclose(f.depth[rows, cols], z, rtol=2e-6)
    np.testing.assert_allclose(f.ray_depth[rows, cols],
                               np.linalg.norm(f.position[rows, cols] - cam.pose[:3, 3], axis=1), rtol=2e-6)
    # on the pixel's ray, unprojecting the depth gives the point back
    np.testing.assert_allclose(cam.unproject(f.depth)[rows[exact], cols[exact]], f.position[rows[exact], cols[exact]],
                               atol=2e-5)


def exact_quad_rays(cam):
    """For each pixel: does its exact ray hit QUAD (float64), the ray parameter, and the distance
    in ideal (undistorted) pixels from the ray's ideal image point to the quad's outline."""
    k, R, t, d = cam.to_opencv()
    jj, ii = np.meshgrid(np.arange(W, dtype=float), np.arange(H, dtype=float))
    pts = np.c_[jj.ravel(), ii.ravel()].reshape(-1, 1, 2)
    und = cv_undistort(pts, k, d).reshape(H, W, 2)
    ideal = und * [k[0, 0], k[1, 1]] + [k[0, 2], k[1, 2]]
    corners = (QUAD @ R.T + t)
    cpx = corners[:, :2] / corners[:, 2:] * [k[0, 0], k[1, 1]] + [k[0, 2], k[1, 2]]
    inside = np.ones((H, W), bool)
    dist = np.full((H, W), np.inf)
    e01, e02 = cpx[1] - cpx[0], cpx[2] - cpx[0]
    area = e01[0] * e02[1] - e01[1] * e02[0]
    for a, b in zip(cpx, np.roll(cpx, -1, axis=0)):
        e = b - a
        side = (e[0] * (ideal[..., 1] - a[1]) - e[1] * (ideal[..., 0] - a[0])) * np.sign(area) / np.hypot(*e)
        inside &= side > 0
        dist = np.minimum(dist, np.abs(side))
    n = np.cross(corners[1] - corners[0], corners[2] - corners[0])
    rays = np.dstack([und, np.ones((H, W))])
    depth = (corners[0] @ n) / (rays @ n)
    return inside, depth, dist


@pytest.mark.parametrize("oversample", [1, 2, 4])
@pytest.mark.parametrize("name", ["barrel", "pincushion", "thin_prism"])
def test_coverage_matches_exact_rays_within_the_stated_bound(name: str, oversample: int) -> None:
    cam = camera(CALIBRATIONS[name], oversample=oversample)
    s = sr.Scene()
    s.add(sr.Mesh(QUAD, [[0, 2, 1], [0, 3, 2]]))
    f = sr.Renderer(W, H).render(s, cam, ("mask", "depth", "triangle_id"), cull="none")
    inside, depth, dist = exact_quad_rays(cam)
    wrong = f.mask != inside
    bound = 1e-6  # exact rays: exact (it once was half a sample diagonal, 0.71 / oversample)
    print(f"{name} oversample {oversample}: {int(wrong.sum())} of {int(inside.sum())} pixels differ from "
          f"the exact rays, all within {dist[wrong].max() if wrong.any() else 0:.3f} ideal px of the outline "
          f"(bound {bound:.3f})")
    assert inside.sum() > 0.15 * W * H
    assert (dist[wrong] <= bound + 1e-9).all()
    both = f.mask & inside
    np.testing.assert_allclose(f.depth[both], depth[both], rtol=1e-6)


def test_coverage_is_exact_at_every_oversampling() -> None:
    """Exact rays: each pixel's ray is cast at every triangle that can reach it, so coverage
    no longer depends on oversample (it once shrank with it: 1, 2, 4, 8 missed fewer and fewer)."""
    counts = []
    inside = None
    for s_ in (1, 2, 4, 8):
        cam = camera(CALIBRATIONS["barrel"], oversample=s_)
        s = sr.Scene()
        s.add(sr.Mesh(QUAD, [[0, 2, 1], [0, 3, 2]]))
        mask = sr.Renderer(W, H).render(s, cam, "mask", cull="none").mask
        if inside is None:
            inside, _, dist = exact_quad_rays(cam)
        counts.append(int(((mask != inside) & (dist > 1e-6)).sum()))
    print("pixels differing from the exact rays at oversample 1, 2, 4, 8:", counts)
    assert counts == [0, 0, 0, 0]


def test_pixels_the_lens_cannot_see_are_background_in_every_output() -> None:
    # a shorter focal length puts the image corners beyond the barrel model's fold
    cam = sr.IntrinsicsCamera(170.0, 170.0, 160.0, 120.0, W, H, near=0.1, far=50.0,
                              dist=CALIBRATIONS["barrel"])
    outputs = ("color", "depth", "mask", "normal", "triangle_id", "instance_id", "position", "barycentric",
               "uv", "ray_depth", "radiance", "coverage")
    big = sr.Scene()
    big.add(sr.Mesh.from_trimesh(trimesh.creation.box((40, 40, 40))), color=(0.5, 0.5, 0.5))
    f = sr.Renderer(W, H).render(big, cam, outputs, cull="none", background=(0.0, 1.0, 0.0))
    k = cam.K
    jj, ii = np.meshgrid(np.arange(W, dtype=float), np.arange(H, dtype=float))
    _, _, valid = undistort((jj - k[0, 2]) / k[0, 0], (ii - k[1, 2]) / k[1, 1], cam.dist_coefficients)
    assert (~valid).sum() > 100 and valid.sum() > 0.9 * W * H  # the corners
    assert f.mask[valid].all() and not f.mask[~valid].any()  # inside a box: every seen ray hits
    assert (f.color[~valid] == [0, 255, 0]).all()
    assert (f.triangle_id[~valid] == -1).all() and (f.instance_id[~valid] == -1).all()
    for name in ("depth", "normal", "position", "barycentric", "uv", "ray_depth", "radiance", "coverage"):
        assert not getattr(f, name)[~valid].any(), name


def test_ids_are_the_scenes_and_triangles_the_rays_hit() -> None:
    cam = camera(CALIBRATIONS["pincushion"])
    for unique in (True, False):
        sc = scene(unique_ids=unique)
        f = sr.Renderer(W, H).render(sc, cam, ("instance_id", "triangle_id", "barycentric", "position", "mask"))
        assert set(np.unique(f.instance_id)) == ({-1, 7, 3} if unique else {-1, 7})
        if not unique:  # both instances report 7; the renders are otherwise the same
            assert np.array_equal(f.triangle_id, first.triangle_id)
            assert np.array_equal(f.instance_id, np.where(first.instance_id == 3, 7, first.instance_id))
            continue
        first = f
        # barycentrics of the reported face rebuild the reported point
        rows, cols = np.nonzero(f.mask)
        for inst in sc.instances:
            sel = f.instance_id[rows, cols] == inst.instance_id
            r, c = rows[sel], cols[sel]
            tri = inst.mesh.positions[inst.mesh.faces[f.triangle_id[r, c]]].astype(np.float64)
            world = tri @ inst.pose[:3, :3].T + inst.pose[:3, 3]
            rebuilt = np.einsum("ij,ijk->ik", f.barycentric[r, c].astype(np.float64), world)
            err = np.linalg.norm(rebuilt - f.position[r, c], axis=1)
            # exact inside the face; where a ray passes just outside it (its edges), clamping
            # the weights moves the point by at most the silhouette bound's worth
            print(f"instance {inst.instance_id}: rebuilt point error median {np.median(err):.1e}, max {err.max():.1e}")
            assert np.median(err) < 1e-6 and err.max() < 1e-5  # exact rays: once 0.02 at edges
            b = f.barycentric[r, c]
            assert (b >= 0).all() and (b <= 1).all()
            np.testing.assert_allclose(b.sum(axis=1), 1.0, atol=1e-6)


def test_colour_is_the_bilinear_remap_of_an_unlit_view() -> None:
    cam = camera(CALIBRATIONS["barrel"])
    f = sr.Renderer(W, H).render(scene(), cam, ("color", "radiance", "instance_id", "mask"), shading="unlit",
                                 srgb=False)
    quad = np.round(np.array([0.2, 0.5, 0.9]) * 255)
    interior = cv2.erode((f.instance_id == 7).astype(np.uint8), np.ones((3, 3), np.uint8)) > 0
    assert interior.sum() > 1000 and (f.color[interior] == quad).all()
    np.testing.assert_allclose(f.radiance[interior], np.broadcast_to([0.2, 0.5, 0.9], (interior.sum(), 3)),
                               atol=1e-6)
    # silhouette pixels are mixes: each channel between the background (0) and the two colours
    assert (f.color.astype(int) <= np.maximum(quad, np.round(np.array([0.9, 0.4, 0.2]) * 255)) + 1).all()
    edge = f.mask & ~interior & (f.instance_id == 7)
    assert ((f.color[edge] != quad).any(axis=1)).any()


def test_zero_distortion_is_the_pinhole_render_bit_for_bit() -> None:
    plain = camera(None)
    zero = camera(np.zeros(8))
    assert zero.dist is None and zero.dist_coefficients is None
    r = sr.Renderer(W, H)
    a = r.render(scene(), plain, ("color", "depth", "triangle_id"))
    b = r.render(scene(), zero, ("color", "depth", "triangle_id"))
    for n in a.outputs:
        assert np.array_equal(getattr(a, n), getattr(b, n))


def test_same_bits_across_threads_isa_and_out() -> None:
    cam = camera(CALIBRATIONS["rational"])
    outputs = ("color", "depth", "normal", "position", "instance_id")
    ref = sr.Renderer(W, H, threads=1, simd=False).render(scene(), cam, outputs)
    for r in (sr.Renderer(W, H, threads=3), sr.Renderer(W, H, threads=2, simd=True)):
        f = r.render(scene(), cam, outputs)
        for n in outputs:
            assert np.array_equal(getattr(f, n), getattr(ref, n)), n
        again = r.render(scene(), cam, outputs, out=f)
        assert again.color is f.color
        for n in outputs:
            assert np.array_equal(getattr(again, n), getattr(ref, n)), n


def test_pickles_and_round_trips_through_cameras_json(tmp_path) -> None:
    cam = camera(CALIBRATIONS["thin_prism"], oversample=3)
    r = sr.Renderer(W, H)
    before = r.render(scene(), cam, "depth").depth
    back = pickle.loads(pickle.dumps(cam))
    assert back.oversample == 3 and np.array_equal(back.dist, cam.dist) and back.dist.shape == (12,)
    assert np.array_equal(r.render(scene(), back, "depth").depth, before)
    sr.write_dataset(scene(), [cam], tmp_path, outputs=("depth",))
    loaded = sr.load_cameras(tmp_path)[0]
    np.testing.assert_array_equal(loaded.dist, cam.dist)
    pts = np.random.default_rng(3).uniform(-1, 1, (50, 3))
    np.testing.assert_allclose(loaded.project(pts), cam.project(pts), atol=1e-9)


def test_bad_distortion_input_names_the_argument() -> None:
    for bad, match in (([0.1, 0.0, 0.0], "dist must hold"), ([np.nan, 0, 0, 0], "dist must be finite"),
                       ([0.0] * 12 + [0.1, 0.0], "tilted sensor")):
        with pytest.raises(ValueError, match=match):
            sr.IntrinsicsCamera(200, 200, 160, 120, W, H, dist=bad)
    for bad in (0, 17):
        with pytest.raises(ValueError, match="oversample"):
            sr.IntrinsicsCamera(200, 200, 160, 120, W, H, dist=[0.1, 0, 0, 0], oversample=bad)
    with pytest.raises(TypeError, match="oversample"):
        sr.IntrinsicsCamera(200, 200, 160, 120, W, H, dist=[0.1, 0, 0, 0], oversample=2.5)
    # a lens whose rays reach too far for a pinhole view of the allowed size: a clear error
    cam = sr.IntrinsicsCamera(600, 600, 600, 450, 1200, 900, dist=[-0.01, 0, 0, 0], oversample=16)
    with pytest.raises(ValueError, match="MAX_IMAGE_SIDE"):
        sr.Renderer(1200, 900).render(scene(), cam, "depth")


def test_oversampled_view_over_the_budget_is_refused_before_rendering(spot):
    """oversample=16 once rendered the huge undistorted view (22 s) before the budget
    refused it; now the view's outputs are checked first, naming oversample."""
    before = sr.get_memory_budget()
    scene = sr.Scene()
    scene.add(spot)
    r = sr.Renderer(W, H)
    cam = camera(CALIBRATIONS["barrel"], oversample=16)
    need = r.render(scene, camera(CALIBRATIONS["barrel"], oversample=1), outputs=("depth",))  # fine
    assert need.depth is not None
    try:
        sr.set_memory_budget(64 * 2**20)
        with pytest.raises(ValueError, match=r"oversample=16: the undistorted view's outputs"):
            r.render(scene, cam, outputs=("color", "depth"))
        assert not r.__dict__.get("_distortion_renderers", {}).get((16 * W, 16 * H))
    finally:
        sr.set_memory_budget(before)
