"""Order-independent alpha blending (glTF alphaMode BLEND, ``Material(alpha_mode="blend")``),
checked against softrast.reference.blend, an independent NumPy reference that finds every
fragment of every triangle at every pixel centre, sorts them and composites them front to back
in linear light.

Scenes are drawn ``unlit`` so a fragment's colour is its (interpolated) linear base or vertex
colour (times a texel). Where a colour or an alpha varies across a triangle, its corners sit on
the 1/256 px snap grid (``on_grid``), so the raster's snapped weights and the exact ones agree to
float32 rounding and the comparison can be tight (radiance to 1e-5 relative); pixel centres
within 0.01 px of an edge (the snap moves an edge by up to ~0.003 px) and pixels whose fragments'
depths are within 1e-5 of each other are left out (``Composite.ambiguous``), except in the tie
tests, where the depths are equal by construction and the reference orders them by draw, then
face. Lit shading, filtered texture alpha, lines and points are checked against softrast's own
opaque renders of each layer instead.
"""
from __future__ import annotations

from dataclasses import dataclass

import math

import numpy as np
import pytest
import trimesh

import softrast as sr
from softrast.reference import blend as bref
from softrast.reference.encoding import srgb_curve, srgb_to_linear

W, H = 64, 48
FOV = 50.0
RTOL, ATOL = 1e-5, 1e-6          # float32 arithmetic over at most ~100 layers
CHECKED = ("radiance", "alpha", "color")
SAME_OUTPUTS = ("depth", "mask", "triangle_id", "instance_id", "normal", "barycentric", "uv",
                "position", "ray_depth", "coverage")


# ----------------------------------------------------------------------------- scene building


@dataclass
class Spec:
    """One draw, described once for softrast and for the reference."""
    positions: np.ndarray
    faces: np.ndarray
    base_color: tuple = (0.8, 0.8, 0.8, 1.0)
    blend: bool = True
    colors: np.ndarray | None = None
    uvs: np.ndarray | None = None
    image: np.ndarray | None = None       # uint8 base colour texture (nearest filter)
    srgb: bool | None = None              # the texture's srgb= (None: the slot decides: sRGB)
    double_sided: bool = True
    instance_id: int = 0
    model: str = "unlit"

    def material(self) -> sr.Material:
        tex = None
        if self.image is not None:
            tex = sr.Texture(self.image, srgb=self.srgb, filter="nearest")
        return sr.Material(base_color=self.base_color, model=self.model,
                           alpha_mode="blend" if self.blend else "opaque",
                           double_sided=self.double_sided, base_color_texture=tex)

    def mesh(self) -> sr.Mesh:
        return sr.Mesh(self.positions, self.faces, colors=self.colors, uvs=self.uvs,
                       material=self.material())

    def tris(self, cam: bref.RefCamera, draw: int, cull: str) -> list[bref.Tri]:
        tex = None
        if self.image is not None:
            tex = bref.texture_linear(self.image, srgb=self.srgb is not False)
        return bref.mesh_tris(cam, self.positions, self.faces, rgba=self.colors,
                              base_color=self.base_color, blend=self.blend,
                              cull="none" if self.double_sided else cull, uvs=self.uvs,
                              texture=tex, draw=draw)


def sr_scene(specs: list[Spec]) -> sr.Scene:
    scene = sr.Scene()
    for s in specs:
        scene.add(s.mesh(), instance_id=s.instance_id)
    return scene


def ref_render(specs: list[Spec], cam: bref.RefCamera, cull: str = "back", **kw) -> bref.Composite:
    tris = [t for d, s in enumerate(specs) for t in s.tris(cam, d, cull)]
    return bref.render(tris, cam, **kw)


def cameras(w: int = W, h: int = H, fov: float = FOV) -> tuple[sr.PerspectiveCamera, bref.RefCamera]:
    cam = sr.PerspectiveCamera(fov_y=fov, width=w, height=h, near=0.5, far=60.0)
    cam.pose = np.eye(4)
    return cam, bref.RefCamera(w, h, fov_y=fov)


def ortho_cameras(w: int = W, h: int = H) -> tuple[sr.OrthographicCamera, bref.RefCamera]:
    """One world unit = one pixel; window (x, y) = (X + w/2, h/2 - Y)."""
    cam = sr.OrthographicCamera(xmag=w / 2.0, ymag=h / 2.0, width=w, height=h, near=0.5, far=60.0)
    cam.pose = np.eye(4)
    return cam, bref.RefCamera(w, h, xmag=w / 2.0, ymag=h / 2.0)


def on_grid(xy: np.ndarray) -> np.ndarray:
    return np.rint(np.asarray(xy, np.float64) * 256.0) / 256.0


def slab_triangles(rng: np.random.Generator, ref: bref.RefCamera, n: int, z0: float, dz: float,
                   tilt: float, grid: bool = False, first_id: int = 0, vertex_rgba: bool = False,
                   size: tuple = (8.0, 30.0)) -> list[Spec]:
    """``n`` random blended triangles, triangle k's corners at depths z0 + k dz +- tilt (so no
    two intersect and their depths differ by at least dz - 2 tilt), each its own draw with its
    own colour and alpha (or per-vertex RGBA)."""
    assert dz > 2 * tilt
    specs = []
    for k in range(n):
        while True:
            centre = rng.uniform([-4, -4], [ref.width + 4, ref.height + 4])
            xy = centre + rng.normal(size=(3, 2)) * rng.uniform(*size) / 2
            a = xy[1] - xy[0]
            b = xy[2] - xy[0]
            if abs(a[0] * b[1] - a[1] * b[0]) > 20.0:
                break
        if grid:
            xy = on_grid(xy)
        depth = z0 + k * dz + rng.uniform(-tilt, tilt, 3)
        pos = ref.unproject(xy, depth).astype(np.float32)
        rgba = tuple(float(v) for v in np.r_[rng.uniform(0, 1, 3), rng.uniform(0.1, 0.9)])
        colors = None
        if vertex_rgba:
            colors = rng.uniform(0, 1, (3, 4)).astype(np.float32)
            colors[rng.integers(0, 3), 3] = rng.choice([0.0, 1.0])
        specs.append(Spec(pos, np.array([[0, 1, 2]]), base_color=rgba, colors=colors,
                          instance_id=first_id + k))
    return specs


def window_quad(ref: bref.RefCamera, x0, y0, x1, y1, depth, **kw) -> Spec:
    """A quad over the window rectangle [x0, x1] x [y0, y1] at view depth ``depth`` (one value or
    one per corner: top-left, top-right, bottom-right, bottom-left), counter-clockwise on screen
    as OpenGL sees it (a front face), uv (0, 0) at its bottom-left corner."""
    xy = np.array([[x0, y0], [x1, y0], [x1, y1], [x0, y1]], np.float64)
    pos = ref.unproject(xy, np.broadcast_to(np.asarray(depth, np.float64), (4,))).astype(np.float32)
    uvs = np.array([[0, 1], [1, 1], [1, 0], [0, 0]], np.float32)
    return Spec(pos, np.array([[0, 3, 2], [0, 2, 1]]), uvs=uvs, **kw)


def render(scene: sr.Scene, cam, w: int = W, h: int = H, outputs=("radiance", "alpha", "color"),
           threads: int = 2, simd: bool = True, **kw) -> sr.Frame:
    return sr.Renderer(w, h, threads=threads, simd=simd).render(scene, cam, outputs=outputs,
                                                                  shading="auto", **kw)


def check_against_reference(frame: sr.Frame, ref: bref.Composite, background=(0.0, 0.0, 0.0),
                            min_layers: int = 2, min_pixels: int = 50) -> np.ndarray:
    """radiance (1e-5 relative), alpha (1e-6) and color (within one step) on every pixel the
    reference can decide; returns that mask. Requires at least ``min_pixels`` decided pixels
    with ``min_layers`` or more blended layers, so a scene that blends nothing cannot pass."""
    ok = ~ref.ambiguous
    assert ok.mean() > 0.85, f"only {ok.mean():.1%} of the pixels are decidable"
    assert (ok & (ref.layers >= min_layers)).sum() >= min_pixels, "the scene blends too little"
    got = frame.radiance.astype(np.float64)
    bad = ~np.isclose(got, ref.radiance, rtol=RTOL, atol=ATOL).all(axis=-1) & ok
    if bad.any():
        i, j = np.argwhere(bad)[0]
        raise AssertionError(
            f"radiance differs at {bad.sum()} of {ok.sum()} pixels; first (row {i}, col {j}): "
            f"got {got[i, j].tolist()}, expected {ref.radiance[i, j].tolist()} "
            f"({ref.layers[i, j]} blended layers, opaque fragment {ref.opaque[i, j]}); "
            f"max |diff| {np.abs(got - ref.radiance)[ok].max():.3g}")
    np.testing.assert_allclose(frame.alpha[ok], ref.alpha[ok], rtol=0, atol=ATOL,
                               err_msg="alpha = 1 where opaque, else 1 - T_n")
    expected = ref.color(background)
    diff = np.abs(frame.color.astype(np.int64) - expected)[ok]
    assert diff.max() <= 1, f"color off by {diff.max()} steps"
    return ok


# ----------------------------------------------------------------------------- 1. random triangles


def random_scene(seed: int, n: int = 30, backdrop: bool = True):
    cam, ref = cameras()
    rng = np.random.default_rng(seed)
    specs = slab_triangles(rng, ref, n, z0=2.0, dz=0.12, tilt=0.04)
    if backdrop:  # opaque, in the middle of the triangles' depths: the farther ones are hidden
        xy = on_grid([[-8, -8], [0.6 * W, -8], [0.6 * W, H + 8], [-8, H + 8]])
        quad = window_quad(ref, *xy[0], *xy[2], depth=2.0 + 14.5 * 0.12, blend=False,
                           instance_id=100)
        quad.colors = np.array([[0.9, 0.1, 0.1, 1], [0.1, 0.9, 0.1, 1], [0.1, 0.1, 0.9, 1],
                                [0.9, 0.9, 0.1, 1]], np.float32)
        specs.append(quad)
    return cam, ref, specs


@pytest.mark.parametrize("backdrop", [True, False], ids=["over_opaque", "over_nothing"])
def test_random_triangles_match_the_reference_in_any_draw_order(backdrop: bool) -> None:
    cam, ref_cam, specs = random_scene(11, backdrop=backdrop)
    background = (0.2, 0.5, 0.7)
    rng = np.random.default_rng(3)
    frames = []
    for trial in range(3):
        order = rng.permutation(len(specs)) if trial else np.arange(len(specs))
        ordered = [specs[k] for k in order]
        frame = render(sr_scene(ordered), cam, background=background)
        ref = ref_render(ordered, ref_cam)
        ok = check_against_reference(frame, ref, background, min_layers=3)
        if trial == 0:  # a linear colour output composites over the background's byte / 255
            linear = render(sr_scene(ordered), cam, outputs=("color",), background=background,
                            srgb=False)
            diff = np.abs(linear.color.astype(np.int64) - ref.color(background, srgb=False))[ok]
            assert diff.max() <= 1
        if backdrop:
            hidden = (ref.opaque >= 0) & ok
            assert hidden.sum() > 100
        frames.append(frame)
    for f in frames[1:]:
        for name in CHECKED:
            np.testing.assert_array_equal(getattr(f, name), getattr(frames[0], name),
                                          err_msg=f"{name} depends on the draw order")


def test_one_mesh_of_face_coloured_triangles_in_any_face_order() -> None:
    """The same triangles as one blended mesh (per-face RGBA through unshared vertices): the
    faces' order within the draw does not change the composite either."""
    cam, ref_cam, specs = random_scene(12, n=24, backdrop=False)
    pos = np.concatenate([s.positions for s in specs])
    cols = np.concatenate([np.tile(np.asarray(s.base_color, np.float32), (3, 1)) for s in specs])
    frames = []
    for perm in (np.arange(len(specs)), np.random.default_rng(1).permutation(len(specs))):
        faces = (perm[:, None] * 3 + np.arange(3)).astype(np.int64)
        one = Spec(pos, faces, colors=cols, base_color=(1, 1, 1, 0.5))
        frame = render(sr_scene([one]), cam)
        check_against_reference(frame, ref_render([one], ref_cam), min_layers=3)
        frames.append(frame)
    for name in CHECKED:
        np.testing.assert_array_equal(getattr(frames[1], name), getattr(frames[0], name))


# ----------------------------------------------------------------------------- 2. interpenetrating


def test_interpenetrating_quads_swap_order_across_their_intersection() -> None:
    cam, ref_cam = cameras()
    # P leans one way, Q the other: they cross along a vertical line near the middle.
    p = window_quad(ref_cam, -6, -6, W + 6, H + 6, depth=[2.5, 4.5, 4.5, 2.5],
                    base_color=(0.9, 0.2, 0.1, 0.55), instance_id=1)
    q = window_quad(ref_cam, -6, -6, W + 6, H + 6, depth=[4.2, 2.8, 2.8, 4.2],
                    base_color=(0.1, 0.3, 0.9, 0.8), instance_id=2)
    back = window_quad(ref_cam, 10, -6, W + 6, 30, depth=6.0, blend=False,
                       base_color=(0.2, 0.8, 0.3, 1.0), instance_id=3)
    for specs in ([p, q, back], [q, back, p]):
        ref = ref_render(specs, ref_cam)
        frame = render(sr_scene(specs), cam, background=(0.3, 0.3, 0.3))
        ok = check_against_reference(frame, ref, (0.3, 0.3, 0.3), min_pixels=500)
        # both sides of the intersection are present and decided
        d_p = bref.fragments(p.tris(ref_cam, 0, "back"), ref_cam).nearest_depth()
        d_q = bref.fragments(q.tris(ref_cam, 0, "back"), ref_cam).nearest_depth()
        assert (ok & (d_p < d_q)).sum() > 300 and (ok & (d_q < d_p)).sum() > 300


# ----------------------------------------------------------------------------- 3. sphere


def sphere_spec(ref_cam: bref.RefCamera, rng: np.random.Generator | None, double_sided: bool,
                centre=(0.0, 0.0, -3.0), radius: float = 1.0, alpha: float = 0.45,
                subdivisions: int = 2, instance_id: int = 5) -> Spec:
    """An icosphere; with ``rng``, each face its own RGBA (unshared vertices, so colours are
    constant over each face)."""
    m = trimesh.creation.icosphere(subdivisions=subdivisions, radius=radius)
    v = np.asarray(m.vertices) + np.asarray(centre)
    f = np.asarray(m.faces)
    if rng is None:
        return Spec(v.astype(np.float32), f, base_color=(0.9, 0.6, 0.2, alpha),
                    double_sided=double_sided, instance_id=instance_id)
    pos = v[f].reshape(-1, 3).astype(np.float32)
    face_rgba = np.c_[rng.uniform(0, 1, (len(f), 3)), rng.uniform(0.2, 0.8, len(f))]
    cols = np.repeat(face_rgba, 3, axis=0).astype(np.float32)
    return Spec(pos, np.arange(len(pos)).reshape(-1, 3), colors=cols, base_color=(1, 1, 1, 1),
                double_sided=double_sided, instance_id=instance_id)


@pytest.mark.parametrize("variant", ["double_sided", "face_rgba_cull_none", "face_rgba_cull_back"])
def test_self_overlapping_sphere_composites_front_and_back_faces(variant: str) -> None:
    w = h = 64
    cam, ref_cam = cameras(w, h)
    rng = None if variant == "double_sided" else np.random.default_rng(7)
    sphere = sphere_spec(ref_cam, rng, double_sided=variant == "double_sided")
    back = window_quad(ref_cam, -4, 20, w + 4, h + 4, depth=6.0, blend=False,
                       base_color=(0.1, 0.2, 0.3, 1.0), instance_id=9)
    cull = "back" if variant in ("double_sided", "face_rgba_cull_back") else "none"
    specs = [sphere, back]
    ref = ref_render(specs, ref_cam, cull=cull)
    frame = render(sr_scene(specs), cam, w, h, cull=cull)
    layers = 1 if variant == "face_rgba_cull_back" else 2
    ok = check_against_reference(frame, ref, min_layers=layers, min_pixels=400)
    assert ref.layers[ok].max() == layers


# ----------------------------------------------------------------------------- 4. 100 layers


@pytest.mark.parametrize("backdrop", [True, False], ids=["over_opaque", "over_nothing"])
def test_a_hundred_layers_on_one_pixel(backdrop: bool) -> None:
    w, h = 24, 18
    cam, ref_cam = cameras(w, h)
    rng = np.random.default_rng(100)
    specs = []
    for k in range(100):  # rectangles on pixel boundaries, each containing pixel (9, 12)
        x0, y0 = rng.integers(-2, 12), rng.integers(-2, 9)
        x1, y1 = rng.integers(13, w + 3), rng.integers(10, h + 3)
        rgb = rng.uniform(0, 1, 3)
        specs.append(window_quad(ref_cam, x0, y0, x1, y1, depth=2.0 + 0.03 * k,
                                 base_color=(*rgb, 0.05), instance_id=k))
    if backdrop:
        specs.append(window_quad(ref_cam, -3, -3, w + 3, h + 3, depth=6.0, blend=False,
                                 base_color=(0.7, 0.7, 0.2, 1.0), instance_id=200))
    order = rng.permutation(len(specs))
    specs = [specs[k] for k in order]
    ref = ref_render(specs, ref_cam)
    assert ref.layers[9, 12] == 100 and not ref.ambiguous.any()
    frame = render(sr_scene(specs), cam, w, h, background=(0.0, 0.0, 0.0))
    check_against_reference(frame, ref, min_layers=50, min_pixels=20)


def test_deep_layers_with_alpha_zero_and_one_over_whole_tiles() -> None:
    """100 rectangles over 2 x 2 tiles, each a blended draw with vertex colours (so never drawn
    opaque), some of alpha exactly 0 or exactly 1: a fragment of alpha 1 hides every blended
    one behind it (the transmittance reaches 0) without changing depth or ids."""
    w, h = 96, 72
    cam, ref_cam = cameras(w, h)
    rng = np.random.default_rng(101)
    specs = []
    for k in range(100):
        x0, y0 = rng.integers(-3, w // 2), rng.integers(-3, h // 2)
        x1, y1 = rng.integers(w // 2, w + 3), rng.integers(h // 2, h + 3)
        alpha = rng.choice([0.0, 1.0, rng.uniform(0.02, 0.3)], p=[0.05, 0.03, 0.92])
        q = window_quad(ref_cam, x0, y0, x1, y1, depth=2.0 + 0.05 * k, instance_id=k)
        q.colors = np.tile(np.r_[rng.uniform(0, 1, 3), alpha], (4, 1)).astype(np.float32)
        specs.append(q)
    specs.append(window_quad(ref_cam, 20, 10, w + 3, h + 3, depth=4.1, blend=False,
                             base_color=(0.3, 0.6, 0.9, 1.0), instance_id=500))
    specs = [specs[k] for k in rng.permutation(len(specs))]
    ref = ref_render(specs, ref_cam)
    frame = render(sr_scene(specs), cam, w, h, outputs=("radiance", "alpha", "color", "depth",
                                                         "instance_id"))
    check_against_reference(frame, ref, min_layers=20, min_pixels=500)
    opaque = render(sr_scene([s for s in specs if not s.blend]), cam, w, h,
                    outputs=("depth", "instance_id"))
    np.testing.assert_array_equal(frame.depth, opaque.depth)
    np.testing.assert_array_equal(frame.instance_id, opaque.instance_id)
    assert ((ref.transmittance == 0) & ~ref.ambiguous).sum() > 500


@pytest.mark.parametrize("filt", ["bilinear", "trilinear", "anisotropic"])
def test_texture_alpha_is_sampled_as_the_colour_is(filt: str) -> None:
    """A receding blended plane with a minified RGBA texture over a constant opaque backdrop B:
    radiance = a c + (1 - a) B, where c is the same draw rendered opaque and a the texture's
    alpha rendered as a colour (a texture whose rgb is the alpha): the alpha is the one the
    filter samples for the colour (the same uv, level of detail and texels)."""
    cam, ref_cam = cameras()
    yy, xx = np.mgrid[0:64, 0:64] / 64.0
    alpha = 0.5 + 0.45 * np.sin(2 * np.pi * (3 * xx + yy)) * np.cos(2 * np.pi * 2 * yy)
    rgb = np.stack([0.5 + 0.5 * np.sin(2 * np.pi * (k + 1) * xx) * np.cos(2 * np.pi * yy * (3 - k))
                    for k in range(3)], axis=-1)
    image = np.concatenate([rgb, alpha[..., None]], axis=-1).astype(np.float32)
    alpha_image = np.repeat(alpha[..., None], 4, axis=-1).astype(np.float32)
    alpha_image[..., 3] = 1.0
    backdrop = (0.2, 0.4, 0.6)

    def scene_of(img, blend):
        plane = window_quad(ref_cam, -4, -4, W + 4, H + 4, depth=[9.0, 9.0, 2.5, 2.5],
                            base_color=(1, 1, 1, 1), blend=blend, instance_id=1)
        plane.uvs = plane.uvs * 4.0
        mat = sr.Material(base_color=(1, 1, 1, 1), model="unlit",
                          alpha_mode="blend" if blend else "opaque",
                          base_color_texture=sr.Texture(img, srgb=False, filter=filt))
        s = sr.Scene()
        s.add(sr.Mesh(plane.positions, plane.faces, uvs=plane.uvs, material=mat), instance_id=1)
        back = window_quad(ref_cam, -4, -4, W + 4, H + 4, depth=20.0, blend=False,
                           base_color=(*backdrop, 1.0), instance_id=2)
        s.add(back.mesh(), instance_id=2)
        return s

    blended = render(scene_of(image, True), cam)
    c = render(scene_of(image, False), cam).radiance.astype(np.float64)
    a = render(scene_of(alpha_image, False), cam).radiance[..., :1].astype(np.float64)
    assert a.min() < 0.3 and a.max() > 0.7
    expected = a * c + (1 - a) * np.array(backdrop, np.float32)
    np.testing.assert_allclose(blended.radiance, expected, rtol=RTOL, atol=ATOL)
    np.testing.assert_allclose(blended.alpha, 1.0)


# ----------------------------------------------------------------------------- ties


def _coplanar(rng: np.random.Generator, n: int) -> np.ndarray:
    """n random overlapping triangles on one tilted plane through the origin, (n, 3, 3)."""
    normal = np.array([0.2, 1.0, 0.3]) / np.linalg.norm([0.2, 1.0, 0.3])
    u = np.cross(normal, [1.0, 0.0, 0.0])
    u /= np.linalg.norm(u)
    v = np.cross(normal, u)
    pts = rng.uniform(-0.6, 0.6, (n, 1, 2)) + rng.normal(0.0, 0.45, (n, 3, 2))
    return pts[..., :1] * u + pts[..., 1:] * v


@pytest.mark.parametrize("orthographic", [False, True], ids=["perspective", "orthographic"])
def test_coplanar_blended_faces_composite_in_face_order(orthographic: bool) -> None:
    """Random triangles of one plane (their corners rounded to float32, so their depths at a
    pixel differ by ~1e-9 relative, far inside the depth test's 2^-20 tie): coplanar blended
    fragments composite in draw order (the earlier face in front), as the depth test gives
    every overlap of such opaque triangles to the first drawn (test_extreme_scales.py)."""
    w, h, n = 96, 72, 60
    rng = np.random.default_rng(31)
    tris = _coplanar(rng, n)
    if orthographic:
        cam = sr.OrthographicCamera(xmag=1.6, ymag=1.2, width=w, height=h, near=0.05, far=100.0)
        ref_cam = bref.RefCamera(w, h, xmag=1.6, ymag=1.2)
    else:
        cam = sr.PerspectiveCamera(fov_y=50.0, width=w, height=h, near=0.05, far=100.0)
        ref_cam = bref.RefCamera(w, h, fov_y=50.0)
    cam.look_at((0.5, 2.0, 3.0), (0.0, 0.0, 0.0), up=(0.0, 1.0, 0.0))
    pos = tris.reshape(-1, 3).astype(np.float32)
    faces = np.arange(3 * n).reshape(-1, 3)
    cols = np.repeat(np.c_[rng.uniform(0, 1, (n, 3)), rng.uniform(0.2, 0.8, n)], 3, axis=0)
    one = Spec(pos, faces, colors=cols.astype(np.float32), base_color=(1, 1, 1, 1))
    frame = render(sr_scene([one]), cam, w, h)
    frags = bref.fragments(bref.mesh_tris(ref_cam, pos, faces, rgba=cols, blend=True,
                                          pose=np.linalg.inv(cam.pose)), ref_cam)
    frags.depth = np.ones_like(frags.depth)  # one plane: every depth ties
    ref = bref.composite(frags, depth_tol=0.0)
    check_against_reference(frame, ref, min_layers=4, min_pixels=100)


@pytest.mark.parametrize("rotated", [False, True], ids=["same_corner_order", "rotated_corners"])
@pytest.mark.parametrize("tilted", [False, True], ids=["parallel", "tilted"])
def test_layers_of_one_geometry_composite_in_draw_order(tilted: bool, rotated: bool) -> None:
    """Eight draws of the same quad (the same corners, so the same depths to the bit) and a mesh
    repeating one of its triangles six times (its corners listed as the quad lists them, or in
    another cyclic order: the same triangle): composited in draw order, then face order."""
    cam, ref_cam = cameras()
    rng = np.random.default_rng(41)
    depth = [2.5, 4.5, 4.5, 2.5] if tilted else 3.0
    specs = [window_quad(ref_cam, 3, 4, 50, 40, depth=depth, instance_id=k,
                         base_color=(*rng.uniform(0, 1, 3), rng.uniform(0.2, 0.8)))
             for k in range(8)]
    # the quads' upper-right half, face [0, 2, 1]
    pos = np.tile(specs[0].positions[[1, 0, 2] if rotated else [0, 2, 1]], (6, 1))
    cols = np.repeat(np.c_[rng.uniform(0, 1, (6, 3)), rng.uniform(0.2, 0.8, 6)], 3, axis=0)
    specs.append(Spec(pos, np.arange(18).reshape(-1, 3), colors=cols.astype(np.float32),
                      instance_id=20))
    for order in (np.arange(len(specs)), rng.permutation(len(specs))):
        ordered = [specs[k] for k in order]
        frame = render(sr_scene(ordered), cam)
        frags = bref.fragments([t for d, s in enumerate(ordered) for t in s.tris(ref_cam, d, "back")],
                               ref_cam)
        frags.depth = np.ones_like(frags.depth)  # (exact ties by construction)
        ref = bref.composite(frags, depth_tol=0.0)
        check_against_reference(frame, ref, min_layers=9, min_pixels=300)


@pytest.mark.parametrize("tilted", [False, True], ids=["parallel", "tilted"])
def test_a_coplanar_decal_shows_only_if_drawn_before_the_surface(tilted: bool) -> None:
    """A blended quad on an opaque one's plane ties with it in the depth test: drawn first it is
    in front (composited over it), drawn after it is behind (hidden), as for two opaque draws;
    also against another triangulation of the plane, whose keys differ by rounding."""
    cam, ref_cam = cameras()
    depth = [2.5, 4.5, 4.5, 2.5] if tilted else 3.0
    decal = window_quad(ref_cam, 5, 5, 50, 40, depth=depth, base_color=(1, 0.5, 0, 0.4),
                        instance_id=1)
    wall = window_quad(ref_cam, 5, 5, 50, 40, depth=depth, base_color=(0, 0, 1, 1), blend=False,
                       instance_id=2)
    other = window_quad(ref_cam, 5, 5, 50, 40, depth=depth, base_color=(0, 0.7, 0.2, 1),
                        blend=False, instance_id=3)
    other.faces = np.array([[0, 3, 1], [1, 3, 2]])
    for surface in (wall, other):
        for specs in ([decal, surface], [surface, decal]):
            frame = render(sr_scene(specs), cam, outputs=("radiance", "alpha", "color", "instance_id"))
            frags = bref.fragments([t for d, s in enumerate(specs) for t in s.tris(ref_cam, d, "back")],
                                   ref_cam)
            frags.depth = np.ones_like(frags.depth)
            ref = bref.composite(frags, depth_tol=0.0)
            check_against_reference(frame, ref, min_layers=1 if specs[0] is decal else 0,
                                    min_pixels=500)
            assert (frame.instance_id[ref.opaque >= 0] == surface.instance_id).all()


def test_lines_and_points_are_opaque_surfaces_for_blending() -> None:
    """Lines and points are depth-tested against the opaque triangles, then blended fragments in
    front of them are composited over them; a line in front hides what is blended behind it."""
    cam, ref_cam = cameras()
    a, rgb = 0.4, np.array([1.0, 0.2, 0.0])
    quad = window_quad(ref_cam, 5, 5, 50, 40, depth=3.0, base_color=(*rgb, a), instance_id=1)
    scene = sr_scene([quad])
    behind = ref_cam.unproject(np.array([[0.0, 20.5], [W, 20.5]]), 5.0)
    front = ref_cam.unproject(np.array([[0.0, 30.5], [W, 30.5]]), 2.0)
    scene.add(sr.Lines(np.r_[behind, front], [[0, 1], [2, 3]], color=(0, 1, 0)), instance_id=7)
    scene.add(sr.Points(ref_cam.unproject(np.array([[12.5, 12.5]]), 5.0), color=(0, 0, 1), size=3),
              instance_id=8)
    f = render(scene, cam, outputs=("radiance", "alpha", "instance_id", "depth"))
    green, blue = np.array([0.0, 1.0, 0.0]), np.array([0.0, 0.0, 1.0])
    np.testing.assert_allclose(f.radiance[20, 10:45], np.tile(a * rgb + (1 - a) * green, (35, 1)),
                               rtol=RTOL, atol=ATOL)
    np.testing.assert_allclose(f.radiance[11:14, 11:14], np.tile(a * rgb + (1 - a) * blue, (3, 3, 1)),
                               rtol=RTOL, atol=ATOL)
    np.testing.assert_array_equal(f.radiance[30, 10:45], np.tile(green, (35, 1)).astype(np.float32))
    np.testing.assert_allclose(f.radiance[25, 10:45], np.tile(a * rgb, (35, 1)), rtol=RTOL, atol=ATOL)
    assert (f.instance_id[20, :] == 7).all() and (f.instance_id[30, :] == 7).all()
    assert (f.alpha[20, :] == 1).all() and (f.alpha[11:14, 11:14] == 1).all()
    np.testing.assert_allclose(f.alpha[25, 10:45], a, rtol=0, atol=ATOL)
    np.testing.assert_allclose(f.depth[20, 10:45], 5.0, rtol=1e-6)


# ----------------------------------------------------------------------------- 5. vertex and texture alpha


def test_vertex_alpha_replaces_the_base_alpha_and_is_perspective_correct() -> None:
    w, h = 80, 60
    cam, ref_cam = cameras(w, h)
    rng = np.random.default_rng(55)
    specs = slab_triangles(rng, ref_cam, 12, z0=2.0, dz=0.3, tilt=0.12, grid=True,
                           vertex_rgba=True, size=(15.0, 45.0))
    # a steeply receding blended quad behind them (depth 7 at the top, 20 at the bottom) with
    # per-vertex RGBA: perspective-correct interpolation differs from screen-linear by far more
    # than the tolerance
    tilted = window_quad(ref_cam, -5, -5, w + 5, h + 5, depth=[7.0, 7.0, 20.0, 20.0],
                         base_color=(1, 1, 1, 0.3), instance_id=50)
    tilted.colors = np.array([[1, 0, 0, 0.9], [0, 1, 0, 0.1], [0, 0, 1, 0.7], [1, 1, 0, 0.2]],
                             np.float32)
    back = window_quad(ref_cam, -5, -5, w + 5, h + 5, depth=25.0, blend=False,
                       base_color=(0.3, 0.3, 0.3, 1.0), instance_id=60)
    for s in specs:
        s.base_color = (0.5, 0.5, 0.5, 0.3)  # its alpha must be replaced by the vertices'
    specs += [tilted, back]
    specs = [specs[k] for k in rng.permutation(len(specs))]
    ref = ref_render(specs, ref_cam)
    exact = ref_render(specs, ref_cam, weights="exact")
    decided = ~ref.ambiguous
    # on-grid corners: the snapped and the exact weights agree, so the choice does not matter
    np.testing.assert_allclose(ref.radiance[decided], exact.radiance[decided], rtol=1e-6, atol=1e-7)
    frame = render(sr_scene(specs), cam, w, h)
    check_against_reference(frame, ref, min_layers=2, min_pixels=200)
    # the test can tell perspective-correct from screen-linear interpolation
    linear = ref_render(specs, ref_cam, weights="screen")
    assert np.abs(linear.radiance - ref.radiance)[decided].max() > 0.02


def test_texture_alpha_times_base_and_vertex_alpha() -> None:
    """Pixel-aligned quads under an orthographic camera, one texel per pixel (texel centres on
    pixel centres, nearest filter): RGBA sRGB-decoded, grey + alpha, RGBA times vertex RGBA, and
    an RGB texture (no alpha channel: the base colour's alpha alone)."""
    w, h = W, H
    cam, ref_cam = ortho_cameras(w, h)
    rng = np.random.default_rng(8)

    def img(x0, y0, x1, y1, c):
        im = rng.integers(0, 256, (y1 - y0, x1 - x0, c)).astype(np.uint8)
        if c in (2, 4):
            im[0, :, -1] = 0      # fully transparent and fully opaque texels too
            im[1, :, -1] = 255
        return im

    rects = {"rgba": (2, 3, 40, 30), "ga": (20, 10, 60, 44), "rgba_vertex": (10, 20, 50, 46),
             "rgb": (0, 25, 30, 48)}
    q1 = window_quad(ref_cam, *rects["rgba"], depth=5.0, base_color=(0.9, 0.7, 1.0, 0.8),
                     image=img(*rects["rgba"], 4), instance_id=1)
    q2 = window_quad(ref_cam, *rects["ga"], depth=7.0, base_color=(1, 1, 1, 1),
                     image=img(*rects["ga"], 2), srgb=False, instance_id=2)
    q3 = window_quad(ref_cam, *rects["rgba_vertex"], depth=6.0, base_color=(1, 1, 1, 1),
                     image=img(*rects["rgba_vertex"], 4), srgb=False, instance_id=3)
    q3.colors = np.array([[1, 0.2, 0.2, 0.9], [0.2, 1, 0.2, 0.3], [0.2, 0.2, 1, 0.6],
                          [1, 1, 1, 1.0]], np.float32)
    q4 = window_quad(ref_cam, *rects["rgb"], depth=4.0, base_color=(0.6, 0.9, 0.4, 0.5),
                     image=img(*rects["rgb"], 3), instance_id=4)
    back = window_quad(ref_cam, 32, -2, w + 2, h + 2, depth=9.0, blend=False,
                       base_color=(0.25, 0.5, 0.75, 1.0), instance_id=5)
    specs = [q1, q2, q3, q4, back]
    ref = ref_render(specs, ref_cam)
    assert not ref.ambiguous.any()
    frame = render(sr_scene(specs), cam, w, h, background=(0.1, 0.1, 0.1))
    check_against_reference(frame, ref, (0.1, 0.1, 0.1), min_layers=3, min_pixels=100)
    # the texture's alpha matters: without it the composite would differ
    q1_rect = (slice(3, 30), slice(2, 40))
    assert (ref.alpha[q1_rect] < 0.99).mean() > 0.3


# ----------------------------------------------------------------------------- 6. outputs rule


def _mixed_scene(seed: int = 21):
    cam, ref_cam, specs = random_scene(seed, n=30, backdrop=True)
    tilted = window_quad(ref_cam, 30, 10, W + 8, H - 6, depth=[3.0, 4.5, 4.5, 3.0], blend=False,
                         base_color=(0.5, 0.5, 0.9, 1.0), instance_id=101)
    specs.append(tilted)
    return cam, ref_cam, specs


def test_other_outputs_follow_the_nearest_opaque_surface() -> None:
    cam, ref_cam, specs = _mixed_scene()
    outputs = sr.OUTPUTS
    frame = render(sr_scene(specs), cam, outputs=outputs, background=(0.2, 0.2, 0.2))
    opaque_only = render(sr_scene([s for s in specs if not s.blend]), cam, outputs=outputs,
                         background=(0.2, 0.2, 0.2))
    for name in SAME_OUTPUTS:
        np.testing.assert_array_equal(getattr(frame, name), getattr(opaque_only, name),
                                      err_msg=f"{name} must ignore blended draws")
    ref = ref_render(specs, ref_cam)
    ok = check_against_reference(frame, ref, (0.2, 0.2, 0.2), min_layers=2)
    seen = opaque_only.mask
    assert (frame.alpha[seen] == 1.0).all()
    assert ((~seen) & (ref.layers > 0) & ok).sum() > 100
    np.testing.assert_allclose(frame.alpha[~seen & ok], 1.0 - ref.transmittance[~seen & ok],
                               rtol=0, atol=ATOL)
    # a render reading no colour (nothing blended is read) gives the same
    for outs in (("depth",), ("depth", "instance_id", "triangle_id", "mask")):
        f = render(sr_scene(specs), cam, outputs=outs)
        for name in outs:
            np.testing.assert_array_equal(getattr(f, name), getattr(opaque_only, name), err_msg=name)
    # where no blended fragment lies in front, nothing changes at all
    clear = (ref.layers == 0) & ok
    assert clear.sum() > 50
    np.testing.assert_array_equal(frame.radiance[clear], opaque_only.radiance[clear])
    np.testing.assert_array_equal(frame.color[clear], opaque_only.color[clear])
    empty = clear & ~seen
    assert (frame.alpha[empty] == 0).all() and (frame.radiance[empty] == 0).all()
    assert (frame.color[empty] == 51).all()


def test_a_lens_distorted_camera_sees_opaque_surfaces_through_blended_ones() -> None:
    """With lens distortion (geometry by ray casting, colour gathered from an ideal view):
    depth, ids and mask are the opaque-only scene's; inside the quads the composite is exact,
    and alpha where only the blended quad is seen is its alpha."""
    w, h = W, H
    _, ref_cam = cameras(w, h)
    K = np.array([[50.0, 0, 32], [0, 50.0, 24], [0, 0, 1]])
    cam = sr.IntrinsicsCamera.from_opencv(K, np.eye(3), np.zeros(3), w, h,
                                          dist=[-0.2, 0.05, 0, 0], near=0.5, far=60.0)

    def opencv_axes(spec: Spec) -> Spec:  # OpenGL view axes -> OpenCV's (y down, z forward)
        spec.positions = (spec.positions * np.array([1, -1, -1], np.float32)).astype(np.float32)
        return spec

    rgb, a = np.array([1.0, 0.3, 0.0]), 0.4
    quad = opencv_axes(window_quad(ref_cam, 10, 8, 50, 40, depth=3.0, base_color=(*rgb, a),
                                   instance_id=1))
    back = opencv_axes(window_quad(ref_cam, -2, -2, 30, h + 2, depth=6.0, blend=False,
                                   base_color=(0, 0, 1, 1), instance_id=2))
    outs = ("radiance", "alpha", "depth", "instance_id", "mask", "triangle_id")
    f = sr.Renderer(w, h).render(sr_scene([quad, back]), cam, outputs=outs, cull="none")
    g = sr.Renderer(w, h).render(sr_scene([back]), cam, outputs=outs, cull="none")
    for name in ("depth", "instance_id", "mask", "triangle_id"):
        np.testing.assert_array_equal(getattr(f, name), getattr(g, name), err_msg=name)
    np.testing.assert_allclose(f.radiance[22:27, 16:21], np.tile(a * rgb + (1 - a) * np.array([0, 0, 1]),
                               (5, 5, 1)), rtol=RTOL, atol=ATOL)
    np.testing.assert_allclose(f.radiance[22:27, 40:45], np.tile(a * rgb, (5, 5, 1)), rtol=RTOL, atol=ATOL)
    np.testing.assert_allclose(f.alpha[22:27, 40:45], a, rtol=0, atol=ATOL)
    assert (f.alpha[f.mask] == 1).all() and (f.alpha[0, 60:] == 0).all()


# ----------------------------------------------------------------------------- alpha threshold


def _threshold_reference(specs: list[Spec], ref_cam: bref.RefCamera, threshold: float):
    """The reference's surface at ``threshold`` as (instance_id, triangle_id, depth) images."""
    tris = [t for d, s in enumerate(specs) for t in s.tris(ref_cam, d, "back")]
    tri, depth = bref.threshold_surface(bref.fragments(tris, ref_cam), threshold)
    ids = np.array([specs[t.draw].instance_id for t in tris] + [-1])
    faces = np.array([t.face for t in tris] + [-1])
    return ids[tri], faces[tri], depth


@pytest.mark.parametrize("threshold", [0.0, 0.3, 0.5, 0.75, 0.95])
def test_alpha_threshold_takes_the_nearest_fragment_reaching_it(threshold: float) -> None:
    """alpha_threshold=t: depth, ids and mask are the nearest fragment's, blended or opaque,
    whose alpha is >= t (the reference sorts every fragment); colour, radiance, alpha and
    coverage are the same bits as without a threshold; a render of ids or depth alone (no
    colour) gives the same; the same bits for any thread count and instruction set."""
    cam, ref_cam, specs = _mixed_scene()
    alphas = np.array([s.base_color[3] for s in specs if s.blend])
    assert np.abs(alphas - threshold).min() > 1e-3  # (no fragment's alpha is a near tie)
    scene = sr_scene(specs)
    outs = ("color", "radiance", "alpha", "coverage", "depth", "mask", "instance_id", "triangle_id")
    plain = render(scene, cam, outputs=outs, background=(0.2, 0.2, 0.2))
    frame = render(scene, cam, outputs=outs, background=(0.2, 0.2, 0.2), alpha_threshold=threshold)
    for name in ("color", "radiance", "alpha", "coverage"):
        assert getattr(frame, name).tobytes() == getattr(plain, name).tobytes(), name
    ref = ref_render(specs, ref_cam)
    ok = ~ref.ambiguous
    ids, faces, depth = _threshold_reference(specs, ref_cam, threshold)
    np.testing.assert_array_equal(frame.instance_id[ok], ids[ok])
    np.testing.assert_array_equal(frame.triangle_id[ok], faces[ok])
    np.testing.assert_array_equal(frame.mask[ok], ids[ok] >= 0)
    seen = ok & (ids >= 0)
    np.testing.assert_allclose(frame.depth[seen], depth[seen], rtol=1e-5)
    blended_ids = {s.instance_id for s in specs if s.blend}
    taken = np.isin(frame.instance_id, list(blended_ids))
    if threshold > alphas.max():  # (0.95: above every blended alpha: the opaque surfaces alone)
        assert not taken.any() and frame.depth.tobytes() == plain.depth.tobytes()
    else:
        assert taken.sum() > 200
    for kw in (dict(outputs=("depth",)), dict(outputs=("instance_id", "triangle_id", "mask")),
               dict(threads=3), dict(simd=False, threads=2), dict(shading_path="deferred")):
        kw = {"outputs": outs, **kw}
        again = render(scene, cam, background=(0.2, 0.2, 0.2), alpha_threshold=threshold, **kw)
        for name in kw["outputs"]:
            assert getattr(again, name).tobytes() == getattr(frame, name).tobytes(), (name, kw)


def test_alpha_threshold_surface_outputs_are_the_fragments_own() -> None:
    """Where a blended fragment stands for the surface, normal and the surface outputs
    (barycentric, uv, position, ray_depth) are the ones its draw gives rendered alone, opaque;
    ids and depth too."""
    cam, ref_cam, specs = _mixed_scene(22)
    scene = sr_scene(specs)
    frame = render(scene, cam, outputs=sr.OUTPUTS, alpha_threshold=0.0)
    checked = 0
    for d, spec in enumerate(specs):
        if not spec.blend:
            continue
        mine = frame.instance_id == spec.instance_id
        if not mine.any():
            continue
        alone = Spec(**{**spec.__dict__, "blend": False})
        single = render(sr_scene([alone]), cam, outputs=sr.OUTPUTS)
        for name in ("normal", "barycentric", "uv", "position", "ray_depth", "depth", "triangle_id"):
            assert getattr(frame, name)[mine].tobytes() == getattr(single, name)[mine].tobytes(), (name, d)
        checked += int(mine.sum())
    assert checked > 300


@pytest.mark.parametrize("aa", [dict(msaa=4), dict(msaa=8), dict(ssaa=2)])
def test_alpha_threshold_with_antialiasing_takes_the_nearest_sample_that_sees_a_surface(aa) -> None:
    """With msaa / ssaa, ids and mask come from the pixel's representative sample: of its
    samples nearest the pixel centre first (ties: the lower index), the first that sees an opaque
    surface or a blended fragment reaching the threshold. Checked against single-sample renders
    at each sample (the principal point moved by the sample's offset). Colour, radiance and alpha
    are the same bits as without a threshold."""
    _, _, specs = random_scene(13, backdrop=True)
    scene = sr_scene(specs)
    cam = _shifted_camera(0.0, 0.0)
    outs = ("radiance", "alpha", "instance_id", "triangle_id", "mask")
    frame = render(scene, cam, outputs=outs, alpha_threshold=0.5, **aa)
    plain = render(scene, cam, outputs=outs, **aa)
    for name in ("radiance", "alpha"):
        assert getattr(frame, name).tobytes() == getattr(plain, name).tobytes(), name
    if "msaa" in aa:
        offsets = [(ox / 16.0, oy / 16.0) for ox, oy in MSAA_OFFSETS[aa["msaa"]]]
    else:
        k = aa["ssaa"]
        grid = [((2 * i + 1) * 256 + k) // (2 * k) / 256.0 - 0.5 for i in range(k)]
        offsets = [(ox, oy) for oy in grid for ox in grid]
    # representative order: nearest the centre first, ties to the lower index (stable sort)
    order = sorted(range(len(offsets)), key=lambda s: offsets[s][0] ** 2 + offsets[s][1] ** 2)
    ids = np.full((H, W), -1)
    faces = np.full((H, W), -1)
    for s in reversed(order):  # the most preferred last: it wins
        one = render(scene, _shifted_camera(-offsets[s][0], -offsets[s][1]),
                     outputs=("instance_id", "triangle_id", "mask"), alpha_threshold=0.5)
        ids = np.where(one.mask, one.instance_id, ids)
        faces = np.where(one.mask, one.triangle_id, faces)
    np.testing.assert_array_equal(frame.instance_id, ids)
    np.testing.assert_array_equal(frame.triangle_id, faces)
    np.testing.assert_array_equal(frame.mask, ids >= 0)
    blended = {s.instance_id for s in specs if s.blend}
    assert np.isin(frame.instance_id, list(blended)).sum() > 200
    assert (frame.instance_id != plain.instance_id).sum() > 200


def test_alpha_threshold_is_checked() -> None:
    cam, ref_cam = cameras()
    scene = sr_scene([window_quad(ref_cam, 5, 5, 40, 30, depth=3.0, base_color=(1, 0, 0, 0.5))])
    for bad in (-0.1, 1.5, float("nan"), float("inf")):
        with pytest.raises(ValueError, match="alpha_threshold"):
            render(scene, cam, alpha_threshold=bad)
    for bad in ("0.5", True, [0.5]):
        with pytest.raises(TypeError, match="alpha_threshold"):
            render(scene, cam, alpha_threshold=bad)
    K = np.array([[50.0, 0, 32], [0, 50.0, 24], [0, 0, 1]])
    lens = sr.IntrinsicsCamera.from_opencv(K, np.eye(3), np.zeros(3), W, H, dist=[-0.2, 0.05, 0, 0])
    with pytest.raises(ValueError, match="alpha_threshold"):
        render(scene, lens, alpha_threshold=0.5)
    render(scene, lens, alpha_threshold=None)
    assert render(scene, cam, alpha_threshold=0.5, outputs=("mask",)).mask.sum() > 500


# ----------------------------------------------------------------------------- 7. same bits


def test_same_bits_for_any_thread_count_instruction_set_and_shading_path() -> None:
    w, h = 150, 100  # 3 x 2 tiles
    cam, ref_cam = cameras(w, h)
    rng = np.random.default_rng(70)
    specs = slab_triangles(rng, ref_cam, 40, z0=2.0, dz=0.05, tilt=0.02, size=(20, 70))
    specs.append(sphere_spec(ref_cam, np.random.default_rng(71), double_sided=False,
                             centre=(0.3, -0.2, -4.0), instance_id=80))
    specs.append(window_quad(ref_cam, 40, -5, w + 5, 70, depth=3.1, blend=False,
                             base_color=(0.8, 0.3, 0.3, 1.0), instance_id=90))
    specs[-1].colors = np.array([[1, 0, 0, 1], [0, 1, 0, 1], [0, 0, 1, 1], [1, 1, 1, 1]], np.float32)
    specs = [specs[k] for k in rng.permutation(len(specs))]
    scene = sr_scene(specs)
    common = dict(cull="none", background=(0.1, 0.2, 0.3))
    first = render(scene, cam, w, h, outputs=sr.OUTPUTS, threads=1, simd=True, **common)
    ref = ref_render(specs, ref_cam, cull="none")
    check_against_reference(first, ref, (0.1, 0.2, 0.3), min_layers=4, min_pixels=300)
    configs = [dict(simd=simd, threads=t) for simd in (True, False) for t in (1, 2, 3)][1:]
    configs += [dict(threads=2, shading_path="forward"), dict(simd=False, shading_path="deferred"),
                dict(threads=3, shading_path="deferred"), dict(raster="scanline"),
                dict(simd=False, raster="scanline", threads=3)]
    # into arrays holding another render's values (out=), and fewer outputs
    junk = render(sr_scene(specs[::2]), cam, w, h, outputs=sr.OUTPUTS, cull="back")
    configs += [dict(out=junk), dict(outputs=("alpha",)), dict(outputs=("radiance",), threads=3),
                dict(outputs=("color", "depth"), simd=False)]
    for kw in configs:
        kw = {"outputs": sr.OUTPUTS, **kw}
        f = render(scene, cam, w, h, **common, **kw)
        for name in kw["outputs"]:
            np.testing.assert_array_equal(getattr(f, name), getattr(first, name),
                                          err_msg=f"{name}: {kw}")


# ----------------------------------------------------------------------------- 8. refusals


def _check_resolved(scene, frame, radiance, alpha, background, **aa) -> None:
    """An anti-aliased blended frame against the mean of single-sample renders (radiance and
    alpha within 1e-6; colour that mean plus (1 - alpha) times the background's linear value,
    encoded, within one step), and the same bits for 1, 2 and 3 threads, both instruction sets,
    and for alpha asked alone."""
    np.testing.assert_allclose(frame.radiance, radiance, rtol=0, atol=1e-6)
    np.testing.assert_allclose(frame.alpha, alpha, rtol=0, atol=1e-6)
    # (the background's linear value: its byte, decoded as the colour output is encoded)
    byte = np.floor(np.asarray(background) * 255.0 + 0.5) / 255.0
    bg = srgb_to_linear(byte)
    lin = np.clip(radiance + (1.0 - alpha)[..., None] * bg, 0.0, 1.0)
    enc = srgb_curve(lin)
    assert np.abs(frame.color.astype(np.int64) - np.floor(enc * 255.0 + 0.5)).max() <= 1
    for threads, simd in ((1, True), (3, True), (2, False)):
        again = render(scene, _shifted_camera(0.0, 0.0), background=background,
                       outputs=("radiance", "alpha", "color"), threads=threads, simd=simd, **aa)
        for name in ("radiance", "alpha", "color"):
            assert getattr(again, name).tobytes() == getattr(frame, name).tobytes(), (name, threads, simd)
    alone = render(scene, _shifted_camera(0.0, 0.0), outputs=("alpha",), **aa)
    assert alone.alpha.tobytes() == frame.alpha.tobytes()


# msaa's sample offsets in 1/16 px from the pixel centre, y down (multisample.cpp, Direct3D's)
MSAA_OFFSETS = {2: [(4, 4), (-4, -4)], 4: [(-2, -6), (6, -2), (-6, 2), (2, 6)],
                8: [(1, -3), (-1, 3), (5, 1), (-3, -5), (-5, 5), (-7, -1), (3, 7), (7, -7)]}


@pytest.mark.parametrize("k", [2, 4, 8])
@pytest.mark.parametrize("backdrop", [True, False], ids=["over_opaque", "over_nothing"])
def test_msaa_composites_every_sample_before_the_resolve(k: int, backdrop: bool) -> None:
    """msaa = k: each sample composites the blended fragments in front of it (shaded at the
    sample) over its own opaque surface, and the samples are averaged. Over a backdrop of one
    colour (so msaa's shared opaque shade is every sample's), radiance and alpha are the mean of
    k single-sample renders whose pixel centres sit at the samples. The same bits for 1, 2 and 3
    threads and both instruction sets, and for alpha asked alone."""
    _, _, specs = random_scene(11, backdrop=backdrop)
    if backdrop:
        specs[-1].colors = None
        specs[-1].base_color = (0.3, 0.6, 0.2, 1.0)
    scene = sr_scene(specs)
    background = (0.2, 0.5, 0.7)
    frame = render(scene, _shifted_camera(0.0, 0.0), msaa=k, background=background,
                   outputs=("radiance", "alpha", "color"))
    radiance = np.zeros((H, W, 3))
    alpha = np.zeros((H, W))
    for ox, oy in MSAA_OFFSETS[k]:
        one = render(scene, _shifted_camera(-ox / 16.0, -oy / 16.0), outputs=("radiance", "alpha"))
        radiance += one.radiance
        alpha += one.alpha
    radiance /= k
    alpha /= k
    partial = (alpha > 0) & (alpha < 1)
    assert partial.sum() > 300 and (alpha > 0).mean() > 0.3
    _check_resolved(scene, frame, radiance, alpha, background, msaa=k)


@pytest.mark.parametrize("k", [4, 8])
def test_msaa_weights_the_shared_opaque_shade_by_each_samples_transmittance(k: int) -> None:
    """msaa shades an opaque triangle once per pixel and shares it among its samples; behind a
    blended quad of alpha a over the whole view, every sample lets 1 - a through. So radiance is
    a c + (1 - a) times the opaque scene's own msaa radiance, over a backdrop of varying
    colour and random opaque triangles (edges inside pixels); where nothing blended lies in
    front, the bits are the opaque scene's."""
    _, ref_cam, specs = random_scene(12, n=20)
    for spec in specs:
        spec.blend = False  # every triangle opaque: pixels shared by several triangles
    rgb, a = np.array([0.9, 0.4, 0.1]), 0.35
    veil = window_quad(ref_cam, -4, -4, W + 4, H + 4, depth=1.5, base_color=(*rgb, a), instance_id=7)
    cam = _shifted_camera(0.0, 0.0)
    opaque = render(sr_scene(specs), cam, msaa=k, outputs=("radiance", "alpha", "depth"))
    assert ((opaque.alpha > 0) & (opaque.alpha < 1)).sum() > 100
    frame = render(sr_scene([veil] + specs), cam, msaa=k, outputs=("radiance", "alpha", "depth"))
    np.testing.assert_allclose(frame.radiance, a * rgb + (1 - a) * opaque.radiance, rtol=0, atol=1e-6)
    np.testing.assert_allclose(frame.alpha, a + (1 - a) * opaque.alpha, rtol=0, atol=1e-6)
    np.testing.assert_array_equal(frame.depth, opaque.depth)
    # a blended quad over part of the view: outside it, the opaque scene's bits
    part = window_quad(ref_cam, 20, 10, 44, 30, depth=1.5, base_color=(*rgb, a), instance_id=7)
    frame = render(sr_scene([part] + specs), cam, msaa=k, outputs=("radiance", "alpha"))
    outside = np.ones((H, W), bool)
    outside[9:31, 19:45] = False
    assert frame.radiance[outside].tobytes() == opaque.radiance[outside].tobytes()
    assert frame.alpha[outside].tobytes() == opaque.alpha[outside].tobytes()
    assert not np.array_equal(frame.radiance[~outside], opaque.radiance[~outside])


def _shifted_camera(dx: float, dy: float, w: int = W, h: int = H) -> sr.IntrinsicsCamera:
    """cameras()'s view with its principal point moved by (dx, dy) pixels: pixel centre
    (x + 1/2, y + 1/2) then sees what the unshifted camera sees at (x + 1/2 - dx, y + 1/2 - dy)."""
    f = (h / 2.0) / math.tan(math.radians(FOV) / 2.0)
    cam = sr.IntrinsicsCamera(f, f, w / 2.0 + dx, h / 2.0 + dy, w, h, near=0.5, far=60.0,
                              convention="opengl")
    cam.pose = np.eye(4)
    return cam


@pytest.mark.parametrize("k", [2, 3])
@pytest.mark.parametrize("backdrop", [True, False], ids=["over_opaque", "over_nothing"])
def test_ssaa_composites_every_sample_before_the_resolve(k: int, backdrop: bool) -> None:
    """ssaa = k: every one of a pixel's k x k samples composites its own blended fragments over
    its own opaque surface, then the samples are averaged. So radiance and alpha are the mean
    of k^2 single-sample renders whose pixel centres sit at the samples (the principal point
    moved by each sample's offset, on the pattern's 1/256 grid), and colour is that mean plus
    (1 - alpha) times the background's linear value, encoded. The same bits for 1, 2 and 3 threads and both
    instruction sets, and for alpha asked alone."""
    _, _, specs = random_scene(11, backdrop=backdrop)
    scene = sr_scene(specs)
    background = (0.2, 0.5, 0.7)
    frame = render(scene, _shifted_camera(0.0, 0.0), ssaa=k, background=background,
                   outputs=("radiance", "alpha", "color"))
    offsets = [((2 * i + 1) * 256 + k) // (2 * k) / 256.0 for i in range(k)]  # (ssaa_pattern)
    radiance = np.zeros((H, W, 3))
    alpha = np.zeros((H, W))
    for oy in offsets:
        for ox in offsets:
            one = render(scene, _shifted_camera(0.5 - ox, 0.5 - oy), outputs=("radiance", "alpha"))
            radiance += one.radiance
            alpha += one.alpha
    radiance /= k * k
    alpha /= k * k
    partial = (alpha > 0) & (alpha < 1)
    assert partial.sum() > 50 and (alpha > 0).mean() > 0.3
    _check_resolved(scene, frame, radiance, alpha, background, ssaa=k)


def test_unknown_alpha_mode_is_refused() -> None:
    with pytest.raises(ValueError, match="alpha_mode"):
        sr.Material(alpha_mode="bogus")


# ----------------------------------------------------------------------------- 9. alpha 1 and 0


@pytest.mark.parametrize("model", ["unlit", "blinn_phong"])
def test_a_blended_draw_of_alpha_one_is_drawn_opaque(model: str) -> None:
    cam, ref_cam = cameras()
    rng = np.random.default_rng(4)
    sphere = sphere_spec(ref_cam, None, double_sided=False, alpha=1.0)
    sphere.model = model
    tri = slab_triangles(rng, ref_cam, 1, z0=2.2, dz=1.0, tilt=0.3, first_id=30)[0]
    tri.base_color = (0.3, 0.6, 0.9, 1.0)
    tri.model = model
    rgb_tex = window_quad(ref_cam, 0, 30, 40, 48, depth=2.5, base_color=(1, 1, 1, 1),
                          image=rng.integers(0, 256, (18, 40, 3)).astype(np.uint8), instance_id=31)
    rgb_tex.model = model
    back = window_quad(ref_cam, -4, -4, W + 4, H + 4, depth=8.0, blend=False,
                       base_color=(0.2, 0.2, 0.2, 1.0), instance_id=32)
    specs = [sphere, tri, rgb_tex, back]
    blended = render(sr_scene(specs), cam, outputs=sr.OUTPUTS)
    for s in specs:
        s.blend = False
    opaque = render(sr_scene(specs), cam, outputs=sr.OUTPUTS)
    for name in sr.OUTPUTS:
        np.testing.assert_array_equal(getattr(blended, name), getattr(opaque, name), err_msg=name)


def test_a_blended_draw_of_alpha_zero_is_not_drawn() -> None:
    cam, ref_cam = cameras()
    ghost = sphere_spec(ref_cam, None, double_sided=True, alpha=0.0)
    back = window_quad(ref_cam, -4, -4, 50, H + 4, depth=8.0, blend=False,
                       base_color=(0.2, 0.7, 0.2, 1.0), instance_id=32)
    with_ghost = render(sr_scene([ghost, back]), cam, outputs=sr.OUTPUTS, background=(0.4, 0.4, 0.4))
    without = render(sr_scene([back]), cam, outputs=sr.OUTPUTS, background=(0.4, 0.4, 0.4))
    for name in sr.OUTPUTS:
        np.testing.assert_array_equal(getattr(with_ghost, name), getattr(without, name), err_msg=name)


# ----------------------------------------------------------------------------- 10. lit fragments


def test_lit_fragments_composite_their_shaded_radiance() -> None:
    """c_i is the fragment's shaded radiance, whatever the model: a blended lambert sphere under
    a point light over an opaque pbr quad gives a L_sphere + (1 - a) L_behind where only one
    sphere face is in front (cull back), from softrast's own opaque renders of each layer."""
    cam, ref_cam = cameras()
    a = 0.35
    sphere = sphere_spec(ref_cam, None, double_sided=False, alpha=a, subdivisions=3)
    sphere.model = "lambert"
    back = window_quad(ref_cam, -4, -4, W + 4, H + 4, depth=[5, 5, 8, 8], blend=False,
                       base_color=(0.6, 0.5, 0.4, 1.0), instance_id=9)
    back.model = "pbr"
    light = np.eye(4)
    light[:3, 3] = (1.5, 2.0, 0.5)

    def scene_of(specs):
        s = sr_scene(specs)
        s.add(sr.PointLight(color=(1, 1, 1), intensity=8.0), pose=light)
        return s

    blended = render(scene_of([sphere, back]), cam, outputs=("radiance", "instance_id"))
    behind = render(scene_of([back]), cam, outputs=("radiance", "instance_id"))
    sphere.blend = False
    front = render(scene_of([sphere, back]), cam, outputs=("radiance", "instance_id"))
    on_sphere = front.instance_id == sphere.instance_id
    edges = bref.fragments([t for t in sphere.tris(ref_cam, 0, "back")], ref_cam).near_edge
    ok = on_sphere & ~edges
    assert ok.sum() > 200
    expected = a * front.radiance.astype(np.float64) + (1 - a) * behind.radiance
    np.testing.assert_allclose(blended.radiance[ok], expected[ok], rtol=RTOL, atol=ATOL)
    np.testing.assert_array_equal(blended.instance_id, behind.instance_id)


# ----------------------------------------------------------------------------- the reference itself


def test_reference_composites_by_hand() -> None:
    """softrast.reference.blend on a hand-derived pixel: two blended layers (drawn far one first) over an
    opaque one, and the same without it."""
    ref_cam = bref.RefCamera(4, 4, xmag=2.0, ymag=2.0)

    def square(depth, rgba, blend, draw):
        xy = np.array([[-1, -1], [5, -1], [5, 5], [-1, 5]], float)
        pos = ref_cam.unproject(xy, depth)
        return bref.mesh_tris(ref_cam, pos, [[0, 3, 2], [0, 2, 1]], base_color=rgba, blend=blend,
                              draw=draw)

    far = square(3.0, (0.0, 1.0, 0.0, 0.25), True, 0)
    near = square(2.0, (1.0, 0.0, 0.0, 0.5), True, 1)
    wall = square(5.0, (0.0, 0.0, 1.0, 1.0), False, 2)
    c = bref.render(far + near + wall, ref_cam)
    r, g, b = bref.f32(0.5), bref.f32(0.25) * (1 - bref.f32(0.5)), (1 - 0.5) * (1 - bref.f32(0.25))
    np.testing.assert_allclose(c.radiance[1, 2], [r, g, b], rtol=1e-15)
    assert c.alpha[1, 2] == 1.0 and c.layers[1, 2] == 2 and c.opaque[1, 2] == 5  # face [0, 2, 1]
    c = bref.render(far + near, ref_cam)
    np.testing.assert_allclose(c.radiance[1, 2], [r, g, 0.0], rtol=1e-15)
    np.testing.assert_allclose(c.alpha[1, 2], 1 - b, rtol=1e-15)
    assert c.opaque[1, 2] == -1 and not c.ambiguous.any()
    # behind the wall nothing counts
    c = bref.render(wall + near, ref_cam)
    np.testing.assert_allclose(c.radiance[1, 2], [0.5, 0.0, 0.5], rtol=1e-15)
