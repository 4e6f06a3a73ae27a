"""The renderer's shading models, lights and materials against the NumPy reference
(softrast.reference.shading, itself checked by test_shading_reference.py).

The reference is evaluated with the renderer's own ``normal`` output as n and world positions
unprojected from its ``depth`` output, so the comparison isolates shading from rasterization.

Tolerances. The renderer computes in float32, the reference in float64:
  * ``rel = 1e-4`` of the expected radiance: float32 rounding (eps 6e-8) through normalisations,
    1/r^2, pow(x, shininess <= 64) (relative error ~ shininess * eps / x) and PBR's D, whose
    roughness is kept >= 0.35 in random materials (at roughness 0.04 a 1e-7 change of n.h
    moves D by percents: no float32 renderer can meet any tolerance there);
  * ``abs = 1e-6``: sums of O(1) float32 terms near zero;
  * plus twice the radiance's measured sensitivity to the position. The position from depth
    (float32, measured good to 2e-7 relative; trusted to 1e-6) lies on the ray through the
    pixel centre, but the renderer shades the point its barycentric weights give, and these
    come from vertices snapped to 1/2**SUBPIXEL_BITS of a pixel: the shaded point is up to
    ~1/512 px off the centre, which along a surface seen at an angle is
    (world size of a pixel) / 2**SUBPIXEL_BITS / |n.v| (measured: normals on a unit sphere
    differ from normalize(position) by 2e-5 frontally, 1e-3 at grazing angles). So the
    reference is re-evaluated at depth * (1 +- 1e-6) and at the position moved by that much
    along the two tangents of the surface, and the largest change is the spread.
    Directional lights give zero spread; point lights and highlights widen the bound only
    where the radiance really moves.
Pixels within 1e-4 of a discontinuity ([n.l > 0] gates the specular terms), where l + v nearly
vanishes, or seen at grazing angles (|n.v| < 0.05) are left out.
"""
from __future__ import annotations

import math

import numpy as np
import pytest
import trimesh

import softrast as sr
from softrast.reference import shading as ref

W, H = 96, 72
LIT = ("lambert", "phong", "blinn_phong", "pbr")
REL, ABS, DEPTH_REL = 1e-4, 1e-6, 1e-6
ALL = ("radiance", "color", "normal", "depth", "mask", "triangle_id", "instance_id")


# ------------------------------------------------------------------------------------- helpers

pose_at = ref.pose_at


def aim(position, target=(0.0, 0.0, 0.0)) -> np.ndarray:
    return pose_at(position, np.asarray(target, float) - np.asarray(position, float))


def camera(eye=(0.6, 1.4, 4.2), target=(0.0, -0.2, 0.0), ortho=False) -> sr.Camera:
    if ortho:
        cam = sr.OrthographicCamera(xmag=2.6, ymag=2.6 * H / W, width=W, height=H, near=0.05, far=100)
    else:
        cam = sr.PerspectiveCamera(fov_y=45.0, width=W, height=H, near=0.05, far=100)
    cam.look_at(eye, target)
    return cam


def render(scene, cam, outputs=ALL, **kw) -> sr.Frame:
    # The references shade the normal output: the normal the lighting used (normal_kind="shading";
    # the default "interpolated" is the exact surface normal, which shading by the normal alone,
    # the headlight and the normal view, reads within 1/724 px of the pixel centre).
    kw.setdefault("normal_kind", "shading")
    return sr.Renderer(W, H).render(scene, cam, outputs=outputs, **kw)


def sphere_mesh(subdivisions=5, **kw) -> sr.Mesh:
    """Unit sphere with analytic normals (the normalised positions)."""
    s = trimesh.creation.icosphere(subdivisions=subdivisions)
    v = np.asarray(s.vertices)
    return sr.Mesh(v, np.asarray(s.faces), normals=v / np.linalg.norm(v, axis=1, keepdims=True), **kw)


def plane_mesh(size=4.0, y=0.0, n=1, **kw) -> sr.Mesh:
    """A square in the plane y = ``y`` facing +y, ``n`` x ``n`` quads, normals (0, 1, 0)."""
    t = np.linspace(-size / 2, size / 2, n + 1)
    xx, zz = np.meshgrid(t, t)
    v = np.stack([xx.ravel(), np.full(xx.size, y), zz.ravel()], 1)
    faces = []
    for i in range(n):
        for j in range(n):
            a, b, c, d = i * (n + 1) + j, i * (n + 1) + j + 1, (i + 1) * (n + 1) + j, (i + 1) * (n + 1) + j + 1
            faces += [(a, c, b), (b, c, d)]  # counter-clockwise seen from +y
    return sr.Mesh(v, np.array(faces), normals=np.tile([0.0, 1.0, 0.0], (len(v), 1)), **kw)


def pixels(frame) -> tuple[np.ndarray, np.ndarray]:
    return np.nonzero(frame.mask)


def view_of(cam):
    view, proj = cam._render_matrices(W, H)
    pose = ref.camera_to_world(view)
    return view, proj, pose[:3, 3], (-pose[:3, 2] if cam.orthographic else None)


def positions(frame, cam, rows, cols, scale=1.0) -> np.ndarray:
    view, proj, _, _ = view_of(cam)
    return ref.unproject(frame.depth.astype(np.float64) * scale, view, proj, rows, cols)


def normals(frame, rows, cols) -> np.ndarray:
    n = frame.normal[rows, cols].astype(np.float64)
    return n / np.linalg.norm(n, axis=1, keepdims=True)


def base_and_material(scene, frame, rows, cols):
    """Per pixel: the base colour (the instance's material base colour or colour) and, per
    instance id, the material."""
    insts = {inst.instance_id: inst for inst in scene.instances}
    ids = frame.instance_id[rows, cols]
    base = np.array([insts[i].color[:3] for i in ids], dtype=np.float64)
    return ids, base, {i: insts[i].material for i in insts}


def expected(model, scene, cam, frame, rows, cols, ambient=0.25, depth_scale=1.0):
    """The reference's radiance at the given pixels (per instance, its material)."""
    view, _, eye, ortho = view_of(cam)
    lights, amb = ref.scene_lighting(scene, view, ambient)
    p = positions(frame, cam, rows, cols, depth_scale)
    n = normals(frame, rows, cols)
    ids, base, mats = base_and_material(scene, frame, rows, cols)
    out = np.empty((len(rows), 3))
    for iid, mat in mats.items():
        sel = ids == iid
        if sel.any():
            out[sel] = ref.radiance(model, n[sel], p[sel], base[sel], mat, lights, amb, eye, ortho)
    return out


def snap_step(cam, frame, rows, cols, n, p) -> np.ndarray:
    """(N,) how far (world units, along the surface) the shaded point may lie from the pixel
    centre's ray: one sub-pixel step (covering the 1/2 step vertex snap and edge rounding),
    times the world size of a pixel at that depth, over |n.v| (foreshortening)."""
    view, proj, eye, ortho = view_of(cam)
    P = np.asarray(proj, dtype=np.float64)
    wc = P[3, 2] * -frame.depth[rows, cols].astype(np.float64) + P[3, 3]
    world_px = np.maximum(2.0 * wc / (W * abs(P[0, 0])), 2.0 * wc / (H * abs(P[1, 1])))
    nv = np.abs(np.einsum("ij,ij->i", n, ref.view_vectors(p, eye, ortho)))
    return 2.0 ** -sr.SUBPIXEL_BITS * world_px / np.maximum(nv, 0.05)


def tangents(n) -> tuple[np.ndarray, np.ndarray]:
    helper = np.where(np.abs(n[:, :1]) < 0.9, [[1.0, 0.0, 0.0]], [[0.0, 1.0, 0.0]])
    t1 = np.cross(n, helper)
    t1 /= np.linalg.norm(t1, axis=1, keepdims=True)
    return t1, np.cross(n, t1)


def lateral_spread(fn, p, n, step) -> np.ndarray:
    """max |fn(p') - fn(p)| over p' = p +- step along both tangents of the plane normal to n."""
    base = fn(p)
    spread = np.zeros_like(base)
    for t in tangents(n):
        for sign in (-1.0, 1.0):
            moved = p + sign * step[:, None] * t
            spread = np.maximum(spread, np.abs(fn(moved) - base))
    return spread


def tolerance(model, scene, cam, frame, rows, cols, want, ambient=0.25):
    spread = np.zeros_like(want)
    for k in (-1.0, 1.0):
        alt = expected(model, scene, cam, frame, rows, cols, ambient, 1.0 + k * DEPTH_REL)
        spread = np.maximum(spread, np.abs(alt - want))
    view, _, eye, ortho = view_of(cam)
    lights, amb = ref.scene_lighting(scene, view, ambient)
    p = positions(frame, cam, rows, cols)
    n = normals(frame, rows, cols)
    ids, base, mats = base_and_material(scene, frame, rows, cols)
    step = snap_step(cam, frame, rows, cols, n, p)
    for iid, mat in mats.items():
        sel = ids == iid
        if sel.any():
            fn = lambda q: ref.radiance(model, n[sel], q, base[sel], mat, lights, amb, eye, ortho)  # noqa: E731
            spread[sel] = np.maximum(spread[sel], lateral_spread(fn, p[sel], n[sel], step[sel]))
    return REL * np.abs(want) + ABS + 2.0 * spread


def near_discontinuity(model, scene, cam, frame, rows, cols, ambient=0.25) -> np.ndarray:
    """Pixels where a light's n.l is within 1e-4 of 0 (the [n.l > 0] gate of the specular
    terms) or l + v nearly vanishes (h undefined)."""
    view, _, eye, ortho = view_of(cam)
    p = positions(frame, cam, rows, cols)
    n = normals(frame, rows, cols)
    v = ref.view_vectors(p, eye, ortho)
    bad = np.abs(np.einsum("ij,ij->i", n, v)) < 0.05
    if model not in ("phong", "blinn_phong", "pbr"):
        return bad
    lights, _ = ref.scene_lighting(scene, view, ambient)
    for light in lights:
        l, _ = ref.light_dir_and_radiance(light, p)
        bad |= np.abs(np.einsum("ij,ij->i", n, l)) < 1e-4
        bad |= np.linalg.norm(l + v, axis=1) < 1e-3
    return bad


def assert_radiance(model, scene, cam, frame, rows, cols, ambient=0.25, min_pixels=200):
    keep = ~near_discontinuity(model, scene, cam, frame, rows, cols, ambient)
    rows, cols = rows[keep], cols[keep]
    assert len(rows) >= min_pixels, f"only {len(rows)} pixels to compare"
    want = expected(model, scene, cam, frame, rows, cols, ambient)
    tol = tolerance(model, scene, cam, frame, rows, cols, want, ambient)
    got = frame.radiance[rows, cols].astype(np.float64)
    err = np.abs(got - want) - tol
    worst = np.unravel_index(np.argmax(err), err.shape)
    assert err.max() <= 0, (f"{model}: pixel {(rows[worst[0]], cols[worst[0]])} radiance "
                            f"{got[worst[0]]} != reference {want[worst[0]]} (tol {tol[worst]})")


def assert_encoded(frame, srgb=True):
    """color == encode(radiance) at every covered pixel; +-1 only where the radiance lies within
    1e-6 (relative to max(1, radiance)) of a rounding boundary of the 8-bit code."""
    m = frame.mask
    rad = frame.radiance[m].astype(np.float64)
    enc = ref.srgb_encode if srgb else ref.linear_encode
    want = enc(rad).astype(int)
    eps = 1e-6 * np.maximum(1.0, np.abs(rad))
    lo, hi = enc(rad - eps).astype(int), enc(rad + eps).astype(int)
    got = frame.color[m].astype(int)
    ok = (got == want) | ((got >= lo) & (got <= hi))
    assert ok.all(), f"color != encode(radiance) at {np.argwhere(~ok)[:5].tolist()}: " \
                     f"{got[~ok][:5].tolist()} vs {want[~ok][:5].tolist()}"


# --------------------------------------------------------------------------- sphere, one light

def test_sphere_phong_without_specular_is_lambert():
    mat = sr.Material(base_color=(0.8, 0.6, 0.4), ks=None, shininess=10.0)
    scene = sr.Scene(ambient_light=(0.1, 0.1, 0.1))
    scene.add(sphere_mesh(5), material=mat)
    l_travel = np.array([-0.4, -0.7, -0.6])
    scene.add(sr.DirectionalLight(color=(1.0, 0.9, 0.8), intensity=1.5), pose=pose_at(travel=l_travel))
    cam = camera(eye=(0.3, 0.5, 3.5), target=(0, 0, 0))
    frame = render(scene, cam, shading="phong", frequency="pixel")
    rows, cols = pixels(frame)
    assert len(rows) > 1500
    kd = np.array([0.8, 0.6, 0.4])
    I = np.array([1.0, 0.9, 0.8]) * 1.5
    l = -l_travel / np.linalg.norm(l_travel)

    def closed_form(n):
        return kd * 0.1 + kd * I * np.maximum(0.0, n @ l)[:, None]

    got = frame.radiance[rows, cols].astype(np.float64)
    # n = the renderer's normal output: float32 arithmetic only
    np.testing.assert_allclose(got, closed_form(normals(frame, rows, cols)), rtol=0, atol=1e-5)
    # n = the analytic normal at the position from depth. With vertex normals = vertex positions
    # the interpolated normal is normalize(sum b_i v_i) = normalize(p) exactly, so only where
    # the shaded point lies separates them: off the pixel centre's ray by up to snap_step (the
    # sub-pixel vertex snap, larger at grazing angles); on the unit sphere the normal moves as
    # fast as the point. Per pixel: |dn| <= 2 * snap_step + 1e-5, |d radiance| <= |kd I| |dn|.
    p = positions(frame, cam, rows, cols)
    n_exact = p / np.linalg.norm(p, axis=1, keepdims=True)
    bound = 2.0 * snap_step(cam, frame, rows, cols, n_exact, p) + 1e-5
    assert np.all(np.linalg.norm(normals(frame, rows, cols) - n_exact, axis=1) <= bound)
    assert np.all(np.abs(got - closed_form(n_exact)) <= (kd * I)[None, :] * bound[:, None] + 1e-5)
    assert np.all(frame.radiance[~frame.mask] == 0)


# ----------------------------------------------------------------------------- random scenes

# Whole exponents up to 64 are taken by repeated multiplication (lighting.hpp, power_n), others
# through exp2(p log2 x): random scenes draw from both.
WHOLE_SHININESS = (0, 1, 2, 5, 16, 31, 32, 63, 64)


def random_material(rng, whole: bool = False) -> sr.Material:
    maybe = lambda: None if rng.random() < 0.3 else tuple(rng.uniform(0, 1, 3))  # noqa: E731
    shininess = float(rng.choice(WHOLE_SHININESS)) if whole else float(rng.uniform(1, 64))
    return sr.Material(base_color=tuple(rng.uniform(0.05, 1, 3)), ka=maybe(), kd=maybe(),
                       ks=tuple(rng.uniform(0, 1, 3)), shininess=shininess,
                       metallic=float(rng.uniform(0, 1)), roughness=float(rng.uniform(0.35, 1)),
                       emissive=tuple(rng.uniform(0, 0.1, 3)))


def random_scene(seed: int, whole: bool = False) -> sr.Scene:
    rng = np.random.default_rng(seed)
    scene = sr.Scene(ambient_light=tuple(rng.uniform(0, 0.15, 3)))
    scene.add(sphere_mesh(3), pose=pose_at((0.0, 0.0, 0.0)), material=random_material(rng, whole), instance_id=0)
    scene.add(plane_mesh(6.0, y=-1.0, n=4), material=random_material(rng, whole), instance_id=1)
    box = trimesh.creation.box(extents=(0.8, 0.6, 1.0))
    box_pose = np.diag([1.2, 0.9, 1.0, 1.0])  # non-uniform scale: normals by the inverse transpose
    box_pose = pose_at((1.6, -0.6, 0.4), travel=(0.3, 0.0, -1.0)) @ box_pose
    # flat box: no normals given (face normals)
    scene.add(sr.Mesh(np.asarray(box.vertices), np.asarray(box.faces)), pose=box_pose,
              material=random_material(rng, whole), instance_id=2)

    def colour():
        return tuple(rng.uniform(0.3, 1.0, 3))

    for _ in range(2):
        scene.add(sr.DirectionalLight(colour(), float(rng.uniform(0.2, 1.0))),
                  pose=pose_at(travel=rng.normal(size=3) + (0, -2, 0)))
    for falloff in ("inverse_square", "none"):
        pos = rng.uniform((-2.5, 1.5, -1.0), (2.5, 3.0, 3.0))
        inten = float(rng.uniform(3, 8)) if falloff == "inverse_square" else float(rng.uniform(0.2, 0.6))
        scene.add(sr.PointLight(colour(), inten, falloff=falloff), pose=pose_at(pos))
        pos = rng.uniform((-2.5, 1.5, -1.0), (2.5, 3.0, 3.0))
        inner = float(rng.uniform(0.05, 0.4))
        scene.add(sr.SpotLight(colour(), inten, inner_cone=inner,
                               outer_cone=float(inner + rng.uniform(0.1, 0.5)), falloff=falloff),
                  pose=aim(pos, rng.uniform(-1, 1, 3) * (1, 0.5, 1)))
    # lights fixed to the camera (pose light-to-camera): a flash above the lens, a spot
    scene.add(sr.PointLight(colour(), 4.0), pose=pose_at((0.0, 0.5, 0.0)), camera_space=True)
    scene.add(sr.SpotLight(colour(), 0.5, inner_cone=0.2, outer_cone=0.5, falloff="none"),
              pose=pose_at((0.3, 0.0, 0.0), travel=(0.0, 0.0, -1.0)), camera_space=True)
    return scene


# Every model on random scenes; phong and blinn_phong again with whole exponents (0, odd, even,
# up to 64), which take the multiplying path, at the same tolerance.
@pytest.mark.parametrize("model, seed, whole",
                         [(m, seed, False) for m in ("unlit",) + LIT + ("normal",) for seed in (1, 2, 3)]
                         + [(m, seed, True) for m in ("phong", "blinn_phong") for seed in (4, 5, 6, 7)])
def test_random_scenes_match_the_reference(model, seed, whole):
    scene = random_scene(seed, whole)
    cam = camera()
    frame = render(scene, cam, shading=model, frequency="pixel")
    rows, cols = pixels(frame)
    rng = np.random.default_rng(seed + 100)
    pick = rng.choice(len(rows), size=min(len(rows), 1500), replace=False)
    assert_radiance(model, scene, cam, frame, rows[pick], cols[pick])
    assert set(np.unique(frame.instance_id[frame.mask])) == {0, 1, 2}
    assert np.all(frame.radiance[~frame.mask] == 0)
    assert_encoded(frame, srgb=True)


@pytest.mark.parametrize("model", ("phong", "blinn_phong"))
@pytest.mark.parametrize("p", [1.0, 7.0, 32.0, 64.0])
def test_whole_and_fractional_exponents_agree(model, p):
    """p (multiplied out) and the next float above it (exp2 / log2) light a sphere alike: the two
    paths of the specular power meet, to the change the exponent itself makes (|ln x| ulp(p)
    of the term) and their rounding (<= p ulps)."""
    frames = []
    for q in (p, float(np.nextafter(np.float32(p), np.float32(np.inf)))):
        scene = sr.Scene(ambient_light=(0.0, 0.0, 0.0))
        mat = sr.Material(base_color=(0.5, 0.5, 0.5), kd=(0.0, 0.0, 0.0), ks=(1.0, 1.0, 1.0), shininess=q)
        scene.add(sphere_mesh(4), material=mat)
        scene.add(sr.PointLight(intensity=9.0), pose=pose_at((1.0, 1.5, 3.0)))
        frames.append(np.array(render(scene, camera(), shading=model, frequency="pixel").radiance))
    a, b = frames
    assert a.max() > 0.5  # a highlight is in view
    np.testing.assert_allclose(a, b, rtol=1e-4, atol=1e-7)


@pytest.mark.parametrize("model", LIT)
def test_orthographic_view_vector(model):
    scene = random_scene(7)
    cam = camera(ortho=True)
    frame = render(scene, cam, shading=model)
    rows, cols = pixels(frame)
    assert_radiance(model, scene, cam, frame, rows, cols)


@pytest.mark.parametrize("model", LIT)
def test_linear_encoding(model):
    scene = random_scene(4)
    frame = render(scene, camera(), shading=model, srgb=False)
    assert_encoded(frame, srgb=False)


def test_shading_auto_uses_each_material_model():
    scene = random_scene(5)
    models = ("pbr", "phong", "unlit")
    fresh = sr.Scene(ambient_light=scene.ambient_light)
    for inst, model in zip(scene.instances, models):
        fresh.add(inst.mesh, pose=inst.pose, instance_id=inst.instance_id,
                  material=inst.material.replace(model=model))
    for li in scene.lights:
        fresh.add(li.light, pose=li.pose, camera_space=li.camera_space)
    cam = camera()
    auto = render(fresh, cam, shading="auto")
    for iid, model in enumerate(models):
        one = render(fresh, cam, shading=model)
        m = auto.instance_id == iid
        np.testing.assert_array_equal(auto.radiance[m], one.radiance[m])


# ------------------------------------------------------------------------- specific features

def peak_on_sphere(eye, l) -> np.ndarray:
    """The point of the unit sphere where n = h = normalize(l + normalize(eye - n))."""
    n = (l + eye / np.linalg.norm(eye))
    n /= np.linalg.norm(n)
    for _ in range(200):
        v = eye - n
        h = l + v / np.linalg.norm(v)
        n = h / np.linalg.norm(h)
    return n


def test_blinn_phong_highlight_peaks_where_n_is_h():
    mat = sr.Material(base_color=(0.5, 0.5, 0.5), ka=(0, 0, 0), kd=(0, 0, 0), ks=(1, 1, 1),
                      shininess=200.0)
    scene = sr.Scene(ambient_light=(0, 0, 0))
    scene.add(sphere_mesh(5), material=mat)
    l = np.array([0.5, 0.6, 0.62])
    l /= np.linalg.norm(l)
    scene.add(sr.DirectionalLight(intensity=1.0), pose=pose_at(travel=-l))
    eye = np.array([0.2, 0.3, 3.0])
    cam = camera(eye=tuple(eye), target=(0, 0, 0))
    frame = render(scene, cam, shading="blinn_phong")
    rad = frame.radiance[..., 0]
    i, j = np.unravel_index(np.argmax(rad), rad.shape)
    n_peak = peak_on_sphere(eye, l)
    view, proj, _, _ = view_of(cam)
    clip = proj @ view @ np.append(n_peak, 1.0)
    x = (clip[0] / clip[3] + 1) / 2 * W
    y = (1 - clip[1] / clip[3]) / 2 * H
    assert math.hypot(j + 0.5 - x, i + 0.5 - y) <= 1.5, ((i, j), (y, x))
    # the brightest pixel is within a pixel of the peak: (n.h)^200 there is close to 1
    assert 0.9 <= rad.max() <= 1.0 + 1e-5


def test_inverse_square_across_a_plane():
    h = 1.5
    scene = sr.Scene(ambient_light=(0, 0, 0))
    scene.add(plane_mesh(8.0, y=0.0, n=8), material=sr.Material(base_color=(1, 1, 1), ks=None))
    light = scene.add(sr.PointLight(intensity=2.0), pose=pose_at((0.0, h, 0.0)))
    assert light == 0
    cam = camera(eye=(0.0, 4.0, 4.5), target=(0.0, 0.0, 0.0))
    frame = render(scene, cam, shading="lambert")
    rows, cols = pixels(frame)
    p = positions(frame, cam, rows, cols)
    r = np.linalg.norm(p - (0.0, h, 0.0), axis=1)
    cos = h / r  # n.l on the plane
    falloff = frame.radiance[rows, cols, 0] / (2.0 * cos)
    # radiance / (I n.l) = 1 / r^2 at every pixel: float32 (2e-5 relative) plus the shaded
    # point's distance from the pixel centre's ray (snap_step): 1/r^2 moves by 2/r^3 per unit
    n = np.tile([0.0, 1.0, 0.0], (len(rows), 1))
    step = snap_step(cam, frame, rows, cols, n, p)
    assert np.all(np.abs(falloff * r ** 2 - 1.0) <= 2e-5 + 2.0 * (2.0 / r) * step)
    assert r.max() / r.min() > 2.0  # the plane spans a real range of distances
    slope = np.polyfit(np.log(r), np.log(falloff), 1)[0]
    assert slope == pytest.approx(-2.0, abs=1e-3)

    flat = sr.Scene(ambient_light=(0, 0, 0))
    flat.add(plane_mesh(8.0, y=0.0, n=8), material=sr.Material(base_color=(1, 1, 1), ks=None))
    flat.add(sr.PointLight(intensity=0.7, falloff="none"), pose=pose_at((0.0, h, 0.0)))
    frame = render(flat, cam, shading="lambert")
    rows, cols = pixels(frame)
    p = positions(frame, cam, rows, cols)
    cos = h / np.linalg.norm(p - (0.0, h, 0.0), axis=1)
    # no falloff: radiance / n.l is the light's radiance everywhere (n.l is divided out with
    # the position from depth: its error, h / r^2 per unit of snap_step, enters the bound)
    step = snap_step(cam, frame, rows, cols, np.tile([0.0, 1.0, 0.0], (len(rows), 1)), p)
    r = np.linalg.norm(p - (0.0, h, 0.0), axis=1)
    assert np.all(np.abs(frame.radiance[rows, cols, 0] / cos / 0.7 - 1.0) <= 2e-5 + 2.0 * step / r)


def test_spot_cone_on_a_plane():
    h, inner, outer = 2.0, math.radians(15), math.radians(30)
    kd, ia = 0.9, 0.05
    scene = sr.Scene(ambient_light=(ia, ia, ia))
    scene.add(plane_mesh(8.0, y=0.0, n=8), material=sr.Material(base_color=(kd, kd, kd), ks=None))
    scene.add(sr.SpotLight(intensity=1.0, inner_cone=inner, outer_cone=outer, falloff="none"),
              pose=pose_at((0.0, h, 0.0), travel=(0.0, -1.0, 0.0)))
    cam = camera(eye=(0.0, 5.0, 3.0), target=(0.0, 0.0, 0.0))
    frame = render(scene, cam, shading="lambert")
    rows, cols = pixels(frame)
    p = positions(frame, cam, rows, cols)
    angle = np.arctan2(np.hypot(p[:, 0], p[:, 2]), h - p[:, 1])
    got = frame.radiance[rows, cols, 0].astype(np.float64)
    cos = np.cos(angle)  # n.l = the cosine to the axis here
    margin = 1e-3  # radians: keeps position float error from moving a pixel across an edge
    full = angle < inner - margin
    dark = angle > outer + margin
    mid = ~full & ~dark
    assert full.sum() > 50 and dark.sum() > 50 and mid.sum() > 50
    np.testing.assert_allclose(got[dark], kd * ia, rtol=1e-5)  # only the ambient term, exactly
    full_ok = np.abs(got - (kd * ia + kd * cos)) <= 1e-5 * got + 2.0 * kd * snap_step(
        cam, frame, rows, cols, np.tile([0.0, 1.0, 0.0], (len(rows), 1)), p) / h
    assert np.all(full_ok[full])  # the full intensity (n.l = cos moves by <= step / h)
    def curve(q):
        c = np.cos(np.arctan2(np.hypot(q[:, 0], q[:, 2]), h - q[:, 1]))
        t = np.clip((c - math.cos(outer)) / (math.cos(inner) - math.cos(outer)), 0, 1)
        return kd * ia + kd * c * t * t

    # the glTF curve between, to float32 plus its change over the shaded point's offset
    n = np.tile([0.0, 1.0, 0.0], (len(rows), 1))
    spread = lateral_spread(curve, p, n, snap_step(cam, frame, rows, cols, n, p))
    assert np.all(np.abs(got - curve(p)) <= 1e-4 * curve(p) + 1e-6 + 2.0 * spread)


def barycentric(p, a, b, c) -> np.ndarray:
    """(N, 3) barycentric coordinates of points p in the triangles (a, b, c) (all (N, 3))."""
    e0, e1, d = b - a, c - a, p - a
    d00, d01, d11 = (e0 * e0).sum(1), (e0 * e1).sum(1), (e1 * e1).sum(1)
    d20, d21 = (d * e0).sum(1), (d * e1).sum(1)
    den = d00 * d11 - d01 * d01
    v = (d11 * d20 - d01 * d21) / den
    w = (d00 * d21 - d01 * d20) / den
    return np.stack([1 - v - w, v, w], 1)


@pytest.mark.parametrize("model", LIT)
def test_vertex_frequency_interpolates_the_vertex_radiance(model):
    """frequency="vertex" (Gouraud): the reference at each vertex (its normal, its position),
    interpolated with the pixel's barycentric coordinates, found from the position unprojected
    from depth in the world triangle (which is perspective-correct interpolation). At the
    vertices themselves this is exactly the per-pixel shading there."""
    rng = np.random.default_rng(21)
    s = trimesh.creation.icosphere(subdivisions=2)
    v_model = np.asarray(s.vertices)
    n_model = v_model / np.linalg.norm(v_model, axis=1, keepdims=True)
    mesh = sr.Mesh(v_model, np.asarray(s.faces), normals=n_model)
    pose = pose_at((0.1, 0.0, -0.2), travel=(0.2, -0.3, -1.0))
    mat = random_material(rng)
    scene = sr.Scene(ambient_light=(0.05, 0.04, 0.03))
    scene.add(mesh, pose=pose, material=mat)
    scene.add(sr.DirectionalLight((1.0, 0.9, 0.8), 0.8), pose=pose_at(travel=(-0.3, -1.0, -0.5)))
    scene.add(sr.PointLight((0.6, 0.8, 1.0), 5.0), pose=pose_at((1.5, 1.5, 2.0)))
    scene.add(sr.SpotLight((1.0, 1.0, 0.7), 6.0, inner_cone=0.1, outer_cone=0.6),
              pose=aim((-1.5, 1.0, 2.0), (0.0, 0.0, 0.0)))
    cam = camera(eye=(0.3, 0.6, 3.0), target=(0.0, 0.0, 0.0))
    frame = render(scene, cam, shading=model, frequency="vertex")
    rows, cols = pixels(frame)
    view, _, eye, _ = view_of(cam)
    lights, amb = ref.scene_lighting(scene, view, 0.25)
    v_world = v_model @ pose[:3, :3].T + pose[:3, 3]
    n_world = n_model @ np.linalg.inv(pose[:3, :3])  # inverse transpose (rigid here)
    n_world /= np.linalg.norm(n_world, axis=1, keepdims=True)
    at_vertices = ref.radiance(model, n_world, v_world, mat.base_color[:3], mat, lights, amb, eye)
    faces = np.asarray(s.faces)[frame.triangle_id[rows, cols]]
    p = positions(frame, cam, rows, cols)
    a, b, c = v_world[faces[:, 0]], v_world[faces[:, 1]], v_world[faces[:, 2]]

    def gouraud(q):
        return np.einsum("nk,nkc->nc", barycentric(q, a, b, c), at_vertices[faces])

    bary = barycentric(p, a, b, c)
    assert bary.min() > -1e-2 and bary.max() < 1 + 1e-2  # inside, up to the sub-pixel snap
    want = gouraud(p)
    got = frame.radiance[rows, cols].astype(np.float64)
    # the barycentrics of the position from depth differ from the renderer's by the shaded
    # point's offset from the pixel centre (snap_step, along the face): the interpolated
    # radiance's change over that offset is the spread; float32 arithmetic: 1e-4 relative
    fn = np.cross(b - a, c - a)
    fn /= np.linalg.norm(fn, axis=1, keepdims=True)
    spread = lateral_spread(gouraud, p, fn, snap_step(cam, frame, rows, cols, fn, p))
    assert np.all(np.abs(got - want) <= 1e-4 * np.abs(want) + 1e-6 + 2.0 * spread)


def test_face_frequency_one_colour_per_face():
    scene = random_scene(9)
    cam = camera()
    for model in LIT:
        frame = render(scene, cam, shading=model, frequency="face")
        key = frame.instance_id.astype(np.int64) * 2**32 + frame.triangle_id
        m = frame.mask
        keys, inverse = np.unique(key[m], return_inverse=True)
        rad = frame.radiance[m]
        first = np.zeros((len(keys), 3), np.float32)
        first[inverse] = rad
        assert np.array_equal(rad, first[inverse]), f"{model}: a face has several colours"
        assert len(keys) > 30


def test_face_frequency_lambert_uses_the_face_normal():
    # directional lights only: lambert does not depend on the position, so the face's colour is
    # the reference with the geometric face normal (a mesh without normals: pixel shading uses
    # the same normal, so "pixel" must agree too)
    s = trimesh.creation.icosphere(subdivisions=2)
    v, f = np.asarray(s.vertices), np.asarray(s.faces)
    scene = sr.Scene(ambient_light=(0.1, 0.1, 0.1))
    scene.add(sr.Mesh(v, f), material=sr.Material(base_color=(0.7, 0.5, 0.3), ks=None))
    scene.add(sr.DirectionalLight((1.0, 1.0, 0.9), 0.9), pose=pose_at(travel=(-0.4, -0.8, -0.5)))
    scene.add(sr.DirectionalLight((0.3, 0.4, 1.0), 0.5), pose=pose_at(travel=(0.9, 0.1, -0.3)))
    cam = camera(eye=(0.3, 0.6, 3.0), target=(0.0, 0.0, 0.0))
    view, _, eye, _ = view_of(cam)
    lights, amb = ref.scene_lighting(scene, view, 0.25)
    fn = np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])
    fn /= np.linalg.norm(fn, axis=1, keepdims=True)
    want_face = ref.radiance("lambert", fn, v[f].mean(1), (0.7, 0.5, 0.3), scene.instances[0].material,
                             lights, amb, eye)
    for freq in ("face", "pixel"):
        frame = render(scene, cam, shading="lambert", frequency=freq)
        rows, cols = pixels(frame)
        np.testing.assert_allclose(frame.radiance[rows, cols], want_face[frame.triangle_id[rows, cols]],
                                   rtol=0, atol=1e-5)


def test_no_lights_is_the_headlight():
    scene = sr.Scene()
    scene.add(sphere_mesh(4, color=(0.9, 0.6, 0.3)))
    scene.add(plane_mesh(5.0, y=-1.0, n=2, color=(0.4, 0.7, 0.5)), instance_id=1)
    cam = camera()
    frame = render(scene, cam, shading="lambert", ambient=0.25)
    rows, cols = pixels(frame)
    view, _, eye, _ = view_of(cam)
    lights, amb = ref.headlight(view, 0.25)
    ids, base, _ = base_and_material(scene, frame, rows, cols)
    want = ref.radiance("lambert", normals(frame, rows, cols), positions(frame, cam, rows, cols),
                        base, None, lights, amb, eye)
    np.testing.assert_allclose(frame.radiance[rows, cols], want, rtol=0, atol=1e-5)
    # which is today's shading: base * (ambient + (1 - ambient) * max(0, n . -view axis))
    d = -ref.camera_to_world(view)[:3, 2]
    today = base * (0.25 + 0.75 * np.maximum(0.0, normals(frame, rows, cols) @ -d))[:, None]
    np.testing.assert_allclose(frame.radiance[rows, cols], today, rtol=0, atol=1e-5)


def test_unlit_ignores_lights_and_emissive_adds():
    mat = sr.Material(base_color=(0.3, 0.6, 0.9), metallic=0.5, roughness=0.6)
    glowing = mat.replace(emissive=(0.2, 0.1, 0.05))
    cam = camera()

    def scene_with(material, lit):
        s = sr.Scene(ambient_light=(0.2, 0.2, 0.2) if lit else None)
        s.add(sphere_mesh(4), material=material)
        if lit:
            s.add(sr.DirectionalLight(intensity=2.0), pose=pose_at(travel=(0.2, -1.0, -0.4)))
            s.add(sr.PointLight(intensity=5.0), pose=pose_at((1.0, 2.0, 2.0)))
            s.add(sr.SpotLight(intensity=5.0), pose=aim((-1.0, 1.0, 2.0)))
        return s

    dark = render(scene_with(mat, False), cam, shading="unlit")
    lit = render(scene_with(mat, True), cam, shading="unlit")
    np.testing.assert_array_equal(dark.radiance, lit.radiance)
    np.testing.assert_array_equal(dark.color, lit.color)
    m = lit.mask
    np.testing.assert_allclose(lit.radiance[m], np.broadcast_to((0.3, 0.6, 0.9), (int(m.sum()), 3)),
                               rtol=0, atol=1e-7)
    for model in LIT:
        a = render(scene_with(mat, True), cam, shading=model)
        b = render(scene_with(glowing, True), cam, shading=model)
        np.testing.assert_array_equal(a.mask, b.mask)
        np.testing.assert_allclose(b.radiance[m] - a.radiance[m],
                                   np.broadcast_to((0.2, 0.1, 0.05), (int(m.sum()), 3)),
                                   rtol=0, atol=1e-5)


# ------------------------------------------------------------------------------------- errors

def test_bad_values_name_the_argument():
    with pytest.raises(ValueError, match="intensity"):
        sr.DirectionalLight(intensity=-1.0)
    with pytest.raises(ValueError, match="intensity"):
        sr.PointLight(intensity=float("nan"))
    with pytest.raises(ValueError, match="color"):
        sr.PointLight(color=(float("nan"), 0.0, 0.0))
    with pytest.raises(ValueError, match="base_color"):
        sr.Material(base_color=(0.5, float("nan"), 0.5))
    with pytest.raises(ValueError, match="shininess"):
        sr.Material(shininess=-1.0)
    for name in ("roughness", "metallic"):
        for bad in (-0.1, 1.5, float("nan")):
            with pytest.raises(ValueError, match=name):
                sr.Material(**{name: bad})
    with pytest.raises(ValueError, match="inner_cone"):
        sr.SpotLight(inner_cone=0.8, outer_cone=0.5)
    with pytest.raises(ValueError, match="outer_cone"):
        sr.SpotLight(outer_cone=2.0)
    with pytest.raises(ValueError, match="falloff"):
        sr.PointLight(falloff="linear")
    with pytest.raises(ValueError, match="ambient_light"):
        sr.Scene(ambient_light=(-1.0, 0.0, 0.0))
    scene = sr.Scene()
    scene.add(sphere_mesh(1))
    cam = camera()
    with pytest.raises(ValueError, match="shading"):
        render(scene, cam, outputs=("color",), shading="toon")
    with pytest.raises(ValueError, match="frequency"):
        render(scene, cam, outputs=("color",), frequency="foo")


def test_values_beyond_float32_are_refused_when_made():
    """Values the core holds in float32 are checked against its range by the
    constructors, naming the field (they once failed at render: "material of draw 0 is out of
    range", "a light has a value that is not finite", "ambient_light is not finite")."""
    big = 3.5e38  # finite in float64, inf in float32
    for name in ("shininess", "normal_scale", "bump_scale", "alpha_cutoff"):
        with pytest.raises(ValueError, match=name):
            sr.Material(**{name: big})
    for name in ("normal_scale", "bump_scale", "alpha_cutoff"):
        with pytest.raises(ValueError, match=name):
            sr.Material(**{name: -big})
    for cls in (sr.DirectionalLight, sr.PointLight, sr.SpotLight):
        with pytest.raises(ValueError, match="intensity"):
            cls(intensity=big)
        cls(color=(1.0, 1.0, 1.0), intensity=float(np.finfo(np.float32).max))  # the largest is fine
    with pytest.raises(ValueError, match="ambient_light"):
        sr.Scene(ambient_light=(1e300, 0.0, 0.0))
    scene = sr.Scene()
    with pytest.raises(ValueError, match="ambient_light"):
        scene.ambient_light = (0.0, big, 0.0)
    # the largest values still render (no error at render time)
    scene = sr.Scene(ambient_light=(3e38, 0.0, 0.0))
    scene.add(sphere_mesh(1), material=sr.Material(shininess=3e38))
    scene.add(sr.DirectionalLight(intensity=3e38), pose=aim((1.0, 2.0, 3.0)))
    frame = render(scene, camera(), outputs=("color",))
    assert frame.color.any()


@pytest.mark.parametrize("length", [1e-200, 1e-30, 1e30, 1e300])
@pytest.mark.parametrize("camera_space", [False, True])
def test_light_pose_z_axis_of_any_finite_length(length, camera_space):
    """A light's direction is its pose's z axis normalised; a tiny (1e-200) or huge
    (1e300) but nonzero column is a valid direction (its norm once under/overflowed to 0 / inf and
    was refused as "zero length")."""
    cam = camera()
    frames = []
    for scale in (1.0, length):
        scene = sr.Scene()
        scene.add(sphere_mesh(2), material=sr.Material(model="blinn_phong"))
        for light in (sr.DirectionalLight(intensity=2.0), sr.SpotLight(intensity=30.0, outer_cone=1.2)):
            pose = aim((1.0, 2.0, 3.0)).copy()
            pose[:3, 2] *= scale
            scene.add(light, pose=pose, camera_space=camera_space)
        frames.append(render(scene, cam, outputs=("radiance",)).radiance)
    assert frames[0].any()
    np.testing.assert_allclose(frames[1], frames[0], rtol=1e-5, atol=1e-6)  # float64 rounding only
