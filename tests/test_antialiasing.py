"""Anti-aliasing (render(msaa=, ssaa=)): sample positions, per-sample coverage against the NumPy
reference rasterizer, convergence to a disk's exact per-pixel area, the resolve rules (one
representative sample per pixel for ids, depth, normals and surface points; colour and radiance
the mean of the samples in linear light; alpha the covered fraction) and compositing."""
from __future__ import annotations

import numpy as np
import pytest
import trimesh

import softrast as sr
from conftest import core_options, pixel_mesh, pixel_ortho, render, scene_of
from softrast.reference import raster as ref
from softrast.reference.encoding import srgb_curve as _srgb_encode
from softrast.reference.encoding import srgb_to_linear as _srgb_decode
from softrast.report import disk_coverage

MSAA = (2, 4, 8, 16)
SSAA = (2, 3, 4, 8)
MODES = [dict(msaa=m) for m in MSAA] + [dict(ssaa=k) for k in SSAA]


def _mode_id(mode):
    return "-".join(f"{k}{v}" for k, v in mode.items())


# --- sample positions ---------------------------------------------------------------------------

# Vulkan's standardSampleLocations (the Direct3D 11 patterns), typed from the specification's
# table as fractions of a pixel from its top-left corner.
_VULKAN = {
    1: [(0.5, 0.5)],
    2: [(0.75, 0.75), (0.25, 0.25)],
    4: [(0.375, 0.125), (0.875, 0.375), (0.125, 0.625), (0.625, 0.875)],
    8: [(0.5625, 0.3125), (0.4375, 0.6875), (0.8125, 0.5625), (0.3125, 0.1875),
        (0.1875, 0.8125), (0.0625, 0.4375), (0.6875, 0.9375), (0.9375, 0.0625)],
    16: [(0.5625, 0.5625), (0.4375, 0.3125), (0.3125, 0.625), (0.75, 0.4375),
         (0.1875, 0.375), (0.625, 0.8125), (0.8125, 0.6875), (0.6875, 0.1875),
         (0.375, 0.875), (0.5, 0.0625), (0.25, 0.125), (0.125, 0.75),
         (0.0, 0.5), (0.9375, 0.25), (0.875, 0.9375), (0.0625, 0.0)],
}


@pytest.mark.parametrize("count", sorted(_VULKAN))
def test_msaa_positions_are_the_standard_ones(count):
    np.testing.assert_array_equal(sr.sample_positions(msaa=count), np.array(_VULKAN[count]))


@pytest.mark.parametrize("k", range(1, 9))
def test_ssaa_positions_are_a_centred_grid(k):
    pos = sr.sample_positions(ssaa=k)
    assert pos.shape == (k * k, 2)
    centres = (np.arange(k) + 0.5) / k
    grid = np.stack(np.meshgrid(centres, centres), axis=-1).reshape(-1, 2)  # row by row
    np.testing.assert_allclose(pos, grid, atol=0.5 / 256)  # rounded to the 1/256 px grid
    np.testing.assert_array_equal(pos * 256, np.rint(pos * 256))
    if k in (1, 2, 4, 8):
        np.testing.assert_array_equal(pos, grid)


# --- coverage per sample, against the NumPy reference ----------------------------------------

def _reference_per_sample(xy, faces, w, h, mode, cull="none"):
    """Coverage counts (n_samples, h, w) from softrast.reference.raster: sample s of pixel
    (i, j) is the pixel centre of the image shifted by (1/2 - sx, 1/2 - sy), exact in fixed
    point."""
    fixed = ref.snap(xy)
    out = []
    for sx, sy in sr.sample_positions(**mode):
        shift = np.array([ref.SUBPIXEL_HALF - round(sx * 256), ref.SUBPIXEL_HALF - round(sy * 256)])
        cov, _ = ref.rasterize(fixed + shift, faces, w, h, cull=cull, fixed=True)
        out.append(cov)
    return np.array(out)


@pytest.mark.parametrize("mode", MODES, ids=_mode_id)
def test_coverage_per_sample_matches_reference(rng, mode):
    # Overlapping random triangles of every size, vertices anywhere on the 1/256 grid, some on
    # sample rows and columns (edges through samples exercise the top-left rule per sample).
    w, h = 70, 66
    n = 120
    corner = rng.uniform(-5, 75, size=(n, 1, 2))
    xy = (corner + rng.uniform(-12, 12, size=(n, 3, 2))).reshape(-1, 2)
    xy[::5] = np.round(xy[::5] * 16) / 16  # on the msaa positions' 1/16 grid
    xy = np.round(xy * 256) / 256 + 1 / 1024  # no rounding ties in the snap
    faces = np.arange(3 * n).reshape(n, 3)
    frame = render(scene_of(pixel_mesh(xy, faces, w, h)), pixel_ortho(w, h), w, h,
                   outputs=("coverage", "alpha", "mask"), cull="none", **mode)
    per_sample = _reference_per_sample(xy, faces, w, h, mode)
    n_samples = len(per_sample)
    np.testing.assert_array_equal(frame.coverage, per_sample.sum(axis=0))
    np.testing.assert_array_equal(frame.alpha * n_samples, (per_sample > 0).sum(axis=0))
    np.testing.assert_array_equal(frame.mask, (per_sample > 0).any(axis=0))


def _jittered_grid(rng, nx, ny, x0, x1, y0, y1):
    xs = np.linspace(x0, x1, nx + 1)
    ys = np.linspace(y0, y1, ny + 1)
    gx, gy = np.meshgrid(xs, ys)
    jitter = rng.uniform(-0.3, 0.3, size=gx.shape + (2,)) * [(x1 - x0) / nx, (y1 - y0) / ny]
    jitter[0, :] = jitter[-1, :] = jitter[:, 0] = jitter[:, -1] = 0.0
    xy = np.stack([gx, gy], axis=-1) + jitter
    idx = np.arange((nx + 1) * (ny + 1)).reshape(ny + 1, nx + 1)
    a, b, c, d = idx[:-1, :-1], idx[:-1, 1:], idx[1:, 1:], idx[1:, :-1]
    faces = np.concatenate([np.stack([a, b, c], -1).reshape(-1, 3),
                            np.stack([a, c, d], -1).reshape(-1, 3)])
    return xy.reshape(-1, 2), faces


@pytest.mark.parametrize("mode", MODES, ids=_mode_id)
def test_jittered_grid_is_watertight_per_sample(rng, mode):
    # A mesh covering the whole image: every sample covered exactly once.
    w, h = 67, 61
    xy, faces = _jittered_grid(rng, 23, 19, -2.0, w + 2.0, -2.0, h + 2.0)
    frame = render(scene_of(pixel_mesh(xy, faces, w, h)), pixel_ortho(w, h), w, h,
                   outputs=("coverage", "alpha"), cull="none", **mode)
    n_samples = len(sr.sample_positions(**mode))
    assert (frame.coverage == n_samples).all()
    assert (frame.alpha == 1.0).all()


@pytest.mark.parametrize("mode", MODES, ids=_mode_id)
def test_closed_sphere_covers_each_sample_once(mode):
    # Back-face culled closed convex mesh: each covered sample exactly one fragment.
    w, h = 96, 80
    m = trimesh.creation.icosphere(subdivisions=3, radius=1.0)
    scene = sr.Scene()
    scene.add(sr.Mesh(m.vertices, m.faces))
    cam = sr.PerspectiveCamera(fov_y=40.0, near=0.1, far=10.0)
    cam.look_at(eye=(0.3, 0.2, 3.5), target=(0, 0, 0), up=(0, 1, 0))
    frame = sr.Renderer(w, h).render(scene, cam, outputs=("coverage", "alpha"), **mode)
    n_samples = len(sr.sample_positions(**mode))
    np.testing.assert_array_equal(frame.coverage, np.rint(frame.alpha * n_samples))
    assert 0 < frame.alpha.mean() < 1 and ((frame.alpha > 0) & (frame.alpha < 1)).any()


# --- convergence to the exact disk -----------------------------------------------------------

def _disk_scene(w, h, radius, centre, segments=4096):
    t = np.linspace(0, 2 * np.pi, segments, endpoint=False)
    ring = np.stack([centre[0] + radius * np.cos(t), centre[1] + radius * np.sin(t)], axis=1)
    xy = np.vstack([centre, ring])
    faces = np.stack([np.zeros(segments, int), 1 + np.arange(segments),
                      1 + (np.arange(segments) + 1) % segments], axis=1)
    return scene_of(pixel_mesh(xy, faces, w, h))


def test_msaa_alpha_converges_to_exact_disk_area(capsys):
    w, h, radius, centre = 64, 64, 23.3, (31.7, 32.4)
    scene = _disk_scene(w, h, radius, centre)
    exact = disk_coverage(w, h, radius, centre)
    renderer = sr.Renderer(w, h)
    errors = {}
    for label, mode in [("msaa1", {})] + [(f"msaa{m}", dict(msaa=m)) for m in MSAA] + \
            [(f"ssaa{k}", dict(ssaa=k)) for k in (2, 4, 8)]:
        frame = renderer.render(scene, pixel_ortho(w, h), outputs=("alpha",), cull="none", **mode)
        edge = (exact > 0) & (exact < 1)
        errors[label] = float(np.abs(frame.alpha - exact)[edge].mean())
    with capsys.disabled():
        print("\nmean |alpha - exact area| on edge pixels:",
              ", ".join(f"{k} {v:.4f}" for k, v in errors.items()))
    chain = ["msaa1", "msaa2", "msaa4", "msaa8", "msaa16"]
    for a, b in zip(chain, chain[1:]):
        assert errors[b] < errors[a], errors
    assert errors["ssaa2"] > errors["ssaa4"] > errors["ssaa8"]
    # Measured: msaa 1 -> 16 cuts the edge pixels' mean error about sixfold.
    assert errors["msaa16"] < errors["msaa1"] / 5
    assert errors["ssaa8"] < 0.02
    # The disk's whole area is pi r^2 (the 4096-gon's is 4e-7 relative smaller).
    frame = renderer.render(scene, pixel_ortho(w, h), outputs=("alpha",), cull="none", ssaa=8)
    assert abs(frame.alpha.sum() / (np.pi * radius**2) - 1) < 2e-3


# --- resolve rules -----------------------------------------------------------------------------

def _half_plane_scene(w, h, x_edge, color):
    """An unlit rectangle covering x < x_edge over the whole height (two triangles)."""
    xy = np.array([[-5.0, -5.0], [x_edge, -5.0], [x_edge, h + 5.0], [-5.0, h + 5.0]])
    faces = np.array([[0, 1, 2], [0, 2, 3]])
    scene = sr.Scene()
    scene.add(pixel_mesh(xy, faces, w, h), material=sr.Material(base_color=(*color, 1.0),
                                                               model="unlit"))
    return scene


@pytest.mark.parametrize("mode", [dict(msaa=2), dict(msaa=4), dict(msaa=8), dict(msaa=16),
                                  dict(ssaa=2), dict(ssaa=4)], ids=_mode_id)
@pytest.mark.parametrize("srgb", [True, False])
def test_half_covered_pixel_is_the_expected_mix(mode, srgb):
    # The edge x = 10.5 splits column 10 in half: every pattern here has half its samples left
    # of x = 0.5 (none on it).
    w, h = 24, 8
    color, background = (0.8, 0.3, 0.1), (0.2, 0.6, 1.0)
    frame = sr.Renderer(w, h).render(_half_plane_scene(w, h, 10.5, color), pixel_ortho(w, h),
                                     outputs=("color", "radiance", "alpha", "mask", "triangle_id"),
                                     cull="none", background=background, srgb=srgb, **mode)
    assert (frame.alpha[:, :10] == 1).all() and (frame.alpha[:, 11:] == 0).all()
    assert (frame.alpha[:, 10] == 0.5).all()
    np.testing.assert_allclose(frame.radiance[:, 10], np.tile(np.float32(color) * 0.5, (h, 1)),
                               rtol=1e-6)
    np.testing.assert_array_equal(frame.radiance[:, 11:], 0.0)
    bg_byte = np.rint(np.array(background) * 255)  # the background is written as given
    bg_linear = _srgb_decode(bg_byte / 255) if srgb else bg_byte / 255
    mixed = 0.5 * np.array(color) + 0.5 * bg_linear
    expected = np.rint((_srgb_encode(mixed) if srgb else mixed) * 255)
    assert np.abs(frame.color[:, 10].astype(int) - expected).max() <= 1
    assert (frame.color[:, 11:] == bg_byte.astype(np.uint8)).all()
    full = np.rint((_srgb_encode(color) if srgb else np.array(color)) * 255)
    assert np.abs(frame.color[:, :10].astype(int) - full).max() <= 1
    assert frame.mask[:, 10].all() and (frame.triangle_id[:, 10] >= 0).all()


@pytest.mark.parametrize("mode", [dict(msaa=4), dict(msaa=16), dict(ssaa=3)], ids=_mode_id)
def test_compositing_with_alpha_has_no_fringe(mode):
    # radiance is premultiplied: radiance + (1 - alpha) * B equals the render over background B,
    # so compositing leaves no dark (or light) fringe.
    m = trimesh.creation.icosphere(subdivisions=2, radius=1.0)
    scene = sr.Scene()
    scene.add(sr.Mesh(m.vertices, m.faces), material=sr.Material(base_color=(0.9, 0.5, 0.2, 1)))
    cam = sr.PerspectiveCamera(fov_y=40.0, near=0.1, far=10.0)
    cam.look_at(eye=(0.0, 0.0, 3.2), target=(0, 0, 0), up=(0, 1, 0))
    r = sr.Renderer(80, 64)
    black = r.render(scene, cam, outputs=("radiance", "alpha", "color"), **mode)
    white = r.render(scene, cam, outputs=("color",), background=(1, 1, 1), **mode)
    composite = black.radiance + (1 - black.alpha)[..., None] * 1.0
    encoded = np.rint(_srgb_encode(composite) * 255)
    edge = (black.alpha > 0) & (black.alpha < 1)
    assert edge.sum() > 50
    assert np.abs(encoded - white.color).max() <= 1
    # The classic fringe: un-premultiplied compositing of the black render darkens the edge.
    naive = _srgb_decode(black.color / 255.0) * black.alpha[..., None] + (1 - black.alpha[..., None])
    assert (np.rint(_srgb_encode(naive) * 255) < white.color.astype(float) - 2)[edge].any()


def _sphere_frame(mode, outputs, w=72, h=60, **kw):
    m = trimesh.creation.icosphere(subdivisions=2, radius=1.0)
    scene = sr.Scene()
    scene.add(sr.Mesh(m.vertices, m.faces), instance_id=7)
    scene.add(sr.Mesh(m.vertices * 0.6 + [0.9, 0.3, 0.5], m.faces), instance_id=9)
    cam = sr.PerspectiveCamera(fov_y=45.0, near=0.1, far=10.0)
    cam.look_at(eye=(0.4, 0.3, 4.0), target=(0.2, 0.1, 0), up=(0, 1, 0))
    frame = sr.Renderer(w, h).render(scene, cam, outputs=outputs, **mode, **kw)
    return frame, cam, (m.vertices, m.faces), scene


@pytest.mark.parametrize("mode", MODES, ids=_mode_id)
def test_a_pixels_outputs_come_from_one_covered_sample(mode):
    # Every geometric output of a pixel describes one surface point, seen through one of the
    # pixel's samples: its position projects to that sample (the representative), its depth and
    # ray depth are that point's, its normal is its face's, its ids are its triangle's.
    outs = ("position", "depth", "ray_depth", "normal", "triangle_id", "instance_id",
            "barycentric", "mask", "alpha")
    frame, cam, _, scene = _sphere_frame(mode, outs)
    w, h = 72, 60
    hit = frame.mask
    assert hit.sum() > 500
    # Project each pixel's position: it lands on one of the pattern's samples of that pixel.
    pos = frame.position[hit].astype(np.float64)
    view = np.linalg.inv(cam.pose)
    p_view = pos @ view[:3, :3].T + view[:3, 3]
    f = (h / 2) / np.tan(np.radians(45.0) / 2)
    x = w / 2 + f * p_view[:, 0] / -p_view[:, 2]
    y = h / 2 - f * p_view[:, 1] / -p_view[:, 2]
    rows, cols = np.nonzero(hit)
    offsets = np.stack([x - cols, y - rows], axis=1)
    samples = sr.sample_positions(**mode)
    d = np.linalg.norm(offsets[:, None, :] - samples[None, :, :], axis=2)
    which = d.argmin(axis=1)
    # (within the vertices' snap to 1/256 px; samples are at least 1/16 px apart)
    assert d.min(axis=1).max() < 1 / 256, d.min(axis=1).max()
    # ... the covered sample nearest the centre: no sample nearer the centre is covered by a
    # triangle nearer the camera (a nearer covered sample would have been chosen).
    dist_c = np.linalg.norm(samples - 0.5, axis=1)
    full = frame.alpha[hit] == 1.0
    nearest = np.flatnonzero(dist_c == dist_c.min()).min()
    assert (which[full] == nearest).all()
    assert np.isin(which, np.flatnonzero(dist_c <= dist_c.max())).all()
    # Depth along the axis and the ray's length are the same point's: to float rounding, but
    # for the vertices' snap (the key interpolates the snapped triangle, the position the true
    # one: up to 5e-4 relative on this coarse sphere's grazing faces without anti-aliasing too).
    # From another sample (1/8 px or more away) the median would be about 1e-3.
    for value, true in ((frame.depth[hit], -p_view[:, 2]),
                        (frame.ray_depth[hit], np.linalg.norm(pos - cam.pose[:3, 3], axis=1))):
        rel = np.abs(value / true - 1)
        assert np.median(rel) < 2e-5 and rel.max() < 2e-3, (np.median(rel), rel.max())
    # Normals (flat mesh) are the faces' of the ids; instance ids are the scene's.
    assert set(np.unique(frame.instance_id[hit])) <= {7, 9}
    assert (frame.instance_id[~hit] == -1).all() and (frame.triangle_id[~hit] == -1).all()
    m = trimesh.creation.icosphere(subdivisions=2, radius=1.0)
    face_n = m.face_normals[frame.triangle_id[hit]]
    np.testing.assert_allclose(frame.normal[hit], face_n, atol=1e-5)
    # The barycentric weights rebuild the position from that triangle.
    tri = m.vertices[m.faces[frame.triangle_id[hit]]]
    inst = frame.instance_id[hit]
    tri = np.where((inst == 9)[:, None, None], tri * 0.6 + [0.9, 0.3, 0.5], tri)
    rebuilt = np.einsum("nk,nkc->nc", frame.barycentric[hit].astype(np.float64), tri)
    np.testing.assert_allclose(rebuilt, pos, atol=1e-5)


@pytest.mark.parametrize("mode", MODES, ids=_mode_id)
def test_ids_are_never_blended(mode):
    frame, *_ = _sphere_frame(mode, ("triangle_id", "instance_id", "alpha"))
    n_faces = len(trimesh.creation.icosphere(subdivisions=2).faces)
    ids = frame.triangle_id[frame.alpha > 0]
    assert ids.min() >= 0 and ids.max() < n_faces
    assert set(np.unique(frame.instance_id[frame.alpha > 0])) == {7, 9}
    assert (frame.triangle_id[frame.alpha == 0] == -1).all()


# --- against renders shifted by each sample's offset ---------------------------------------

def _shifted_renders(scene, w, h, mode, outputs, **kw):
    """Single-sample renders whose pixel centre sits where each of mode's samples does: the
    geometry moved by (1/2 - sx, 1/2 - sy) px, exact in fixed point for these offsets."""
    frames = []
    for sx, sy in sr.sample_positions(**mode):
        cam = pixel_ortho(w, h)
        pose = np.eye(4)
        pose[0, 3] = -(0.5 - sx)  # moving the camera left moves the image right
        pose[1, 3] = (0.5 - sy)
        cam.pose = pose
        frames.append(sr.Renderer(w, h).render(scene, cam, outputs=outputs, **kw))
    return frames


@pytest.mark.parametrize("mode", [dict(ssaa=2), dict(ssaa=4), dict(msaa=4), dict(msaa=8)],
                         ids=_mode_id)
def test_resolve_equals_mean_of_shifted_renders(rng, mode):
    # Vertex-coloured overlapping triangles (colour varies across each one), unlit: ssaa's
    # radiance is the mean of the single-sample renders at each sample; msaa's equals it where
    # one triangle owns the whole pixel only if shaded at the same point, so for msaa compare
    # coverage and alpha everywhere and radiance where each triangle's colour is constant.
    w, h = 40, 36
    n = 30
    xy = (rng.uniform(-4, 44, size=(n, 1, 2)) + rng.uniform(-10, 10, size=(n, 3, 2))).reshape(-1, 2)
    xy = np.round(xy * 256) / 256 + 1 / 1024
    faces = np.arange(3 * n).reshape(n, 3)
    z = np.repeat(rng.uniform(-20, -2, size=n), 3)  # a depth per triangle: no ties
    world = np.stack([xy[:, 0] - w / 2, h / 2 - xy[:, 1], z], axis=1)
    per_triangle = "msaa" in mode
    colors = (np.repeat(rng.uniform(0, 1, size=(n, 3)), 3, axis=0) if per_triangle
              else rng.uniform(0, 1, size=(3 * n, 3)))
    mesh = sr.Mesh(world, faces, colors=colors)
    scene = sr.Scene()
    scene.add(mesh, material=sr.Material(model="unlit"))
    outs = ("radiance", "mask", "coverage", "triangle_id", "depth")
    frame = sr.Renderer(w, h).render(scene, pixel_ortho(w, h), outputs=outs + ("alpha",),
                                     cull="none", **mode)
    shifted = _shifted_renders(scene, w, h, mode, outs, cull="none")
    np.testing.assert_array_equal(frame.alpha, np.mean([f.mask for f in shifted], axis=0))
    np.testing.assert_array_equal(frame.coverage, np.sum([f.coverage for f in shifted], axis=0))
    np.testing.assert_allclose(frame.radiance, np.mean([f.radiance for f in shifted], axis=0),
                               atol=2e-6)
    # Ids and depth are the representative sample's: the covered one nearest the centre.
    samples = sr.sample_positions(**mode)
    order = np.lexsort((np.arange(len(samples)), np.linalg.norm(samples - 0.5, axis=1)))
    rep_id = np.full((h, w), -1)
    rep_depth = np.zeros((h, w), np.float32)
    for s in order[::-1]:  # the nearest sample last: it wins
        f = shifted[s]
        rep_id = np.where(f.mask, f.triangle_id, rep_id)
        rep_depth = np.where(f.mask, f.depth, rep_depth)
    assert (frame.alpha < 1).sum() > 50 and len(np.unique(rep_id)) > 20
    np.testing.assert_array_equal(frame.triangle_id, rep_id)
    np.testing.assert_array_equal(frame.depth, rep_depth)


def test_msaa_shades_once_per_pixel_per_triangle():
    # A smooth gradient across one big triangle: msaa gives each fully covered pixel one shade,
    # at its representative sample (the same value as a single-sample render there), where ssaa
    # averages the samples' shades.
    w, h = 32, 32
    xy = np.array([[-40.0, -40.0], [120.0, -40.0], [-40.0, 120.0]])
    colors = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
    scene = sr.Scene()
    scene.add(pixel_mesh(xy, np.array([[0, 1, 2]]), w, h, colors=colors),
              material=sr.Material(model="unlit"))
    frame = sr.Renderer(w, h).render(scene, pixel_ortho(w, h), outputs=("radiance",), cull="none",
                                     msaa=16)
    # msaa=16's sample nearest the centre is sample 0, at (+1/16, +1/16) from it.
    (shifted,) = _shifted_renders(scene, w, h, dict(msaa=1), ("radiance",), cull="none")
    at_rep = _shifted_renders(scene, w, h, dict(msaa=16), ("radiance",), cull="none")[0]
    np.testing.assert_allclose(frame.radiance, at_rep.radiance, atol=1e-6)
    assert np.abs(frame.radiance - shifted.radiance).max() > 1e-4  # not the centre's value


# --- same bits, options, errors ------------------------------------------------------------------

@pytest.mark.parametrize("mode", [dict(msaa=4), dict(msaa=16), dict(ssaa=3)], ids=_mode_id)
def test_same_bits_across_threads_and_instruction_sets(spot, mode):
    scene = sr.Scene()
    scene.add(spot, material=sr.Material(base_color=(0.7, 0.6, 0.5, 1), ks=(0.3, 0.3, 0.3),
                                          shininess=30))
    cam = sr.PerspectiveCamera(fov_y=45.0, near=0.05, far=100.0)
    cam.look_at(eye=(1.7, 0.9, -2.3), target=(0.0, 0.05, 0.15), up=(0, 1, 0))
    outs = tuple(sr.OUTPUTS)
    frames = [sr.Renderer(130, 100, threads=t, simd=s).render(scene, cam, outputs=outs, **mode)
              for t, s in [(1, True), (2, True), (3, True), (2, False)]]
    for other in frames[1:]:
        for name in outs:
            np.testing.assert_array_equal(getattr(frames[0], name), getattr(other, name),
                                          err_msg=name)


def test_msaa1_and_ssaa1_are_the_plain_render(spot):
    scene = sr.Scene()
    scene.add(spot)
    cam = sr.PerspectiveCamera(fov_y=45.0, near=0.05, far=100.0)
    cam.look_at(eye=(1.7, 0.9, -2.3), target=(0.0, 0.05, 0.15), up=(0, 1, 0))
    r = sr.Renderer(90, 70)
    outs = tuple(sr.OUTPUTS)
    plain = r.render(scene, cam, outputs=outs)
    for mode in (dict(msaa=1), dict(ssaa=1), dict(msaa=1, ssaa=1)):
        other = r.render(scene, cam, outputs=outs, **mode)
        for name in outs:
            np.testing.assert_array_equal(getattr(plain, name), getattr(other, name))
    assert set(np.unique(plain.alpha)) == {0.0, 1.0}
    np.testing.assert_array_equal(plain.alpha, plain.mask)


def test_out_arrays_and_render_many_take_antialiasing(spot):
    scene = sr.Scene()
    scene.add(spot)
    cams = []
    for eye in [(1.7, 0.9, -2.3), (-1.5, 0.8, 2.0)]:
        cam = sr.PerspectiveCamera(fov_y=45.0, near=0.05, far=100.0)
        cam.look_at(eye=eye, target=(0.0, 0.05, 0.15), up=(0, 1, 0))
        cams.append(cam)
    r = sr.Renderer(64, 48)
    first = r.render(scene, cams[0], outputs=("color", "alpha"), msaa=4)
    again = r.render(scene, cams[0], outputs=("color", "alpha"), msaa=4, out=first)
    assert again.alpha is first.alpha
    many = list(r.render_many(scene, cams, outputs=("color", "alpha"), msaa=4))
    for cam, frame in zip(cams, many):
        one = r.render(scene, cam, outputs=("color", "alpha"), msaa=4)
        np.testing.assert_array_equal(one.color, frame.color)
        np.testing.assert_array_equal(one.alpha, frame.alpha)


@pytest.mark.parametrize("kw, match", [
    (dict(msaa=3), "msaa"), (dict(msaa=0), "msaa"), (dict(msaa=32), "msaa"),
    (dict(ssaa=0), "ssaa"), (dict(ssaa=9), "ssaa"), (dict(ssaa=-1), "ssaa"),
    (dict(msaa=4, ssaa=2), "msaa and ssaa"),
])
def test_bad_counts_raise_value_error(kw, match):
    scene = scene_of(pixel_mesh(np.array([[1.0, 1.0], [9.0, 1.0], [1.0, 9.0]]),
                                np.array([[0, 1, 2]]), 10, 10))
    with pytest.raises(ValueError, match=match):
        sr.Renderer(10, 10).render(scene, pixel_ortho(10, 10), msaa=kw.get("msaa", 1),
                                   ssaa=kw.get("ssaa", 1))


@pytest.mark.parametrize("kw, match", [(dict(msaa=4.0), "msaa"), (dict(ssaa="2"), "ssaa"),
                                       (dict(msaa=True), "msaa")])
def test_bad_types_raise_type_error(kw, match):
    scene = scene_of(pixel_mesh(np.array([[1.0, 1.0], [9.0, 1.0], [1.0, 9.0]]),
                                np.array([[0, 1, 2]]), 10, 10))
    with pytest.raises(TypeError, match=match):
        sr.Renderer(10, 10).render(scene, pixel_ortho(10, 10), **kw)


def test_distorted_camera_refuses_antialiasing(spot):
    scene = sr.Scene()
    scene.add(spot)
    cam = sr.IntrinsicsCamera(50, 50, 32, 24, 64, 48, dist=[-0.2, 0.05, 0, 0])
    with pytest.raises(ValueError, match="msaa"):
        sr.Renderer(64, 48).render(scene, cam, msaa=4)


def test_core_refuses_bad_counts_too():
    # The core checks what it is given (a spec built by hand bypasses render.py's checks).
    r = sr.Renderer(8, 8)
    scene = scene_of(pixel_mesh(np.array([[1.0, 1.0], [7.0, 1.0], [1.0, 7.0]]),
                                np.array([[0, 1, 2]]), 8, 8))
    from softrast.render import _draws
    cam = pixel_ortho(8, 8)
    draws = _draws(scene)
    view, proj = cam._render_matrices(8, 8)
    for msaa, ssaa in [(3, 1), (1, 0), (1, 9), (4, 4)]:
        spec = core_options(view, proj, True, cam.near, cam.far, ["color"], msaa=msaa, ssaa=ssaa)
        with pytest.raises(ValueError):
            r._core.render(draws, spec)


@pytest.mark.parametrize("mode", [dict(msaa=4), dict(ssaa=3)], ids=_mode_id)
def test_scanline_fill_gives_the_same_bits_per_sample(rng, mode):
    # raster="scanline" fills each sample pass by edge walking: the same samples, the same bits.
    w, h = 70, 66
    n = 150
    xy = (rng.uniform(-5, 75, size=(n, 1, 2)) + rng.uniform(-15, 15, size=(n, 3, 2))).reshape(-1, 2)
    faces = np.arange(3 * n).reshape(n, 3)
    colors = rng.uniform(0, 1, size=(3 * n, 3))
    scene = scene_of(pixel_mesh(xy, faces, w, h, colors=colors))
    outs = tuple(sr.OUTPUTS)
    a, b = (sr.Renderer(w, h).render(scene, pixel_ortho(w, h), outputs=outs, cull="none",
                                     raster=raster, **mode) for raster in ("edge", "scanline"))
    for name in outs:
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name), err_msg=name)
