"""Exact shadows (``shadows=True`` / ``"exact"`` on a light, or ``render(shadows=)``).

What is checked, against geometry worked out here and the float64 NumPy reference
(softrast.reference.shadow, itself checked against trimesh's ray casting below):

* a unit square over a floor under a directional light: every floor pixel is in shadow exactly
  when its point, moved toward the light, meets the square (analytic);
* no acne: floors lit at grazing angles (80 to 89 degrees from the normal), near the origin, far
  from it, very large or tilted, have no dark pixel and the bits of the unshadowed render lit
  per pixel;
* a convex sphere shadows itself exactly on the faces that face away from the light;
* point and spot lights over boxes and a sphere match the reference, with a blocker out of the
  camera's view (it still casts) and one beyond the point light (it must not);
* every lit model: a shadowed pixel has the radiance of the scene without that light (ambient,
  emissive and the other lights untouched), a lit pixel the bits of the render without shadows;
* the face frequency decides once per face (at its centroid), the vertex frequency per vertex;
* ``render(shadows=)`` overrides the lights' settings; lights default to no shadows;
* the same bits for 1, 2 and 3 threads and both instruction sets, msaa included; msaa and ssaa
  keep fully shadowed regions black;
* blended draws cast no shadow, masked draws do (by their geometry);
* a camera with lens distortion shows the shadows of its ideal view;
* bad values raise ValueError naming the argument.

A shadow decision is compared wherever it is robust: the renderer decides at its own float32
point, so pixels within a relative 1e-5 of flipping (the reference's ``margin``, or the distance
to an analytic shadow edge) are left out, and the left-out share is asserted to be small.

Lighting: ambient 0 and no emissive unless said, so a pixel whose only light is blocked has
radiance exactly 0, and a lit one the bits of the render without shadows.
"""
from __future__ import annotations

import math
import pickle

import numpy as np
import pytest
import trimesh
import trimesh.ray.ray_triangle as tm_ray

import softrast as sr
from softrast.reference import shadow as ref

W, H = 160, 120
OUT = ("radiance", "position", "instance_id", "triangle_id", "mask", "barycentric")
MARGIN = 1e-5          # decisions closer than this to flipping are not compared
MAX_LEFT_OUT = 0.005   # ... and they are at most this share of the compared pixels
LIT_MODELS = ("lambert", "phong", "blinn_phong", "pbr")


# ------------------------------------------------------------------------------------- helpers

def camera(eye, target, w=W, h=H, fov_y=50.0, far=100.0) -> sr.PerspectiveCamera:
    cam = sr.PerspectiveCamera(fov_y=fov_y, width=w, height=h, near=0.05, far=far)
    cam.look_at(eye, target)
    return cam


def render(scene, cam, shadows="default", outputs=OUT, threads=2, simd=True, **kw) -> sr.Frame:
    """Render at the camera's size; ``shadows="default"`` leaves render's argument out."""
    if shadows != "default":
        kw["shadows"] = shadows
    return sr.Renderer(cam.width, cam.height, threads=threads, simd=simd).render(
        scene, cam, outputs=outputs, **kw)


def lambert(color=(0.8, 0.8, 0.8), **kw) -> sr.Material:
    return sr.Material(model="lambert", base_color=color, **kw)


def plane_mesh(size=10.0, n=2, y=0.0, material=None) -> sr.Mesh:
    """A square in the plane y = ``y`` facing +y, ``n`` x ``n`` quads, normals (0, 1, 0)."""
    t = np.linspace(-size / 2, size / 2, n + 1)
    xx, zz = np.meshgrid(t, t)
    v = np.stack([xx.ravel(), np.full(xx.size, y), zz.ravel()], 1)
    faces = []
    for i in range(n):
        for j in range(n):
            a, b = i * (n + 1) + j, i * (n + 1) + j + 1
            c, d = (i + 1) * (n + 1) + j, (i + 1) * (n + 1) + j + 1
            faces += [(a, c, b), (b, c, d)]  # counter-clockwise seen from +y
    return sr.Mesh(v, np.array(faces), normals=np.tile([0.0, 1.0, 0.0], (len(v), 1)),
                   material=material)


def box_mesh(extents, material=None) -> sr.Mesh:
    """A closed box (flat faces), centred on the origin."""
    b = trimesh.creation.box(extents=extents)
    return sr.Mesh(np.asarray(b.vertices), np.asarray(b.faces), material=material)


def sphere_mesh(radius=1.0, subdivisions=3, material=None) -> sr.Mesh:
    """An icosphere with smooth normals (the normalised positions)."""
    s = trimesh.creation.icosphere(subdivisions=subdivisions, radius=radius)
    v = np.asarray(s.vertices)
    return sr.Mesh(v, np.asarray(s.faces), normals=v / np.linalg.norm(v, axis=1, keepdims=True),
                   material=material)


def at(x, y, z) -> np.ndarray:
    pose = np.eye(4)
    pose[:3, 3] = (x, y, z)
    return pose


def bits(a: np.ndarray) -> np.ndarray:
    return np.ascontiguousarray(a, dtype=np.float32).view(np.uint32)


def same_bits(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Per pixel: all channels bit-identical."""
    return (bits(a) == bits(b)).all(axis=-1)


def observed(shadowed_frame, plain_frame, sel) -> tuple[np.ndarray, np.ndarray]:
    """The render's own shadow decision at the selected pixels, with one light and no ambient:
    (in_shadow, lit_ok) where in_shadow = radiance 0 (the light reaches it without shadows),
    lit_ok = bit-identical to the render without shadows. Asserts that every selected pixel
    is one or the other."""
    rs, ru = shadowed_frame.radiance[sel], plain_frame.radiance[sel]
    lit = same_bits(rs, ru)
    dark = (rs == 0.0).all(axis=-1)
    assert (ru > 0.0).any(axis=-1).all(), "a compared pixel is not lit even without shadows"
    bad = ~(lit | dark)
    assert not bad.any(), (f"{bad.sum()} pixels neither lit (the unshadowed bits) nor dark (0): "
                           f"e.g. {rs[bad][:3].tolist()} vs unshadowed {ru[bad][:3].tolist()}")
    return dark, lit


def compare(expect_dark, got_dark, margin, what: str, where=None) -> None:
    """Expected vs rendered shadow decisions where the margin allows; the left-out share small."""
    keep = margin >= MARGIN
    left_out = int((~keep).sum())
    assert left_out <= MAX_LEFT_OUT * max(len(keep), 1), (
        f"{what}: {left_out} of {len(keep)} pixels within {MARGIN} of a shadow edge")
    wrong = keep & (expect_dark != got_dark)
    if wrong.any():
        k = np.flatnonzero(wrong)[:5]
        loc = "" if where is None else f" at (row, col) {[tuple(map(int, where[i])) for i in k]}"
        pytest.fail(f"{what}: {wrong.sum()} of {keep.sum()} pixels wrong{loc}: expected dark "
                    f"{expect_dark[k].tolist()}, got dark {got_dark[k].tolist()}, margins "
                    f"{margin[k].tolist()}")


def reference_at_pixels(scene, frame, sel, light_index=0, tris=None):
    """The reference's (blocked, margin) at the selected pixels' ``position`` output."""
    p = frame.position[sel].astype(np.float64)
    if tris is None:
        tris = ref.scene_triangles(scene)
    light = ref.scene_lights(scene)[light_index]
    return ref.shadow_rays(tris, p, light)


# ---------------------------------------------------------------------- directional, analytic

SQUARE_H = 1.0
SQUARE_C = (0.2, 0.1)   # (x, z) centre of the unit square
SUN_TRAVEL = np.array([0.45, -1.0, 0.3])


def square_scene(shadows=True, **square_kw) -> sr.Scene:
    scene = sr.Scene(ambient_light=(0.0, 0.0, 0.0))
    scene.add(plane_mesh(10.0, 2, material=lambert()), instance_id=0)
    scene.add(plane_mesh(1.0, 1, material=square_kw.pop("material", lambert((0.3, 0.6, 0.9)))),
              pose=at(SQUARE_C[0], SQUARE_H, SQUARE_C[1]), instance_id=1)
    scene.add(sr.DirectionalLight(intensity=2.0, shadows=shadows),
              pose=ref.light_pose((0.0, 5.0, 0.0), SUN_TRAVEL))
    return scene


SQUARE_CAM = dict(eye=(-1.0, 3.3, 3.0), target=(0.5, 0.0, 0.3))


def test_directional_square_shadow_is_analytic():
    """A unit square at height 1 over a floor, a slanted sun: a floor pixel is dark exactly when
    its point p (the position output) meets the square going toward the light,
    p + t * (-light_direction) inside the square at its height; and the reference agrees."""
    scene = square_scene()
    cam = camera(**SQUARE_CAM)
    fs = render(scene, cam)
    fu = render(scene, cam, shadows=False)
    floor = fs.instance_id == 0
    dark, _ = observed(fs, fu, floor)
    p = fs.position[floor].astype(np.float64)
    toward = -SUN_TRAVEL / np.linalg.norm(SUN_TRAVEL)
    t = (SQUARE_H - p[:, 1]) / toward[1]
    q = p + t[:, None] * toward
    inner = np.minimum(0.5 - np.abs(q[:, 0] - SQUARE_C[0]), 0.5 - np.abs(q[:, 2] - SQUARE_C[1]))
    expect = inner > 0.0
    assert expect.sum() > 400 and (~expect).sum() > 4000, "the shadow is not well in view"
    compare(expect, dark, np.abs(inner), "analytic square shadow", np.argwhere(floor))
    # The reference says the same.
    blocked, margin = reference_at_pixels(scene, fs, floor)
    keep = (np.abs(inner) >= MARGIN) & (margin >= MARGIN)
    assert (blocked[keep] == expect[keep]).all()
    # The square itself (its top faces the light) is lit, and nothing else is dark.
    square = fs.instance_id == 1
    assert square.sum() > 100
    assert same_bits(fs.radiance[square], fu.radiance[square]).all()


# ------------------------------------------------------------------------------------ no acne

def _grazing_scene(angle_deg, where, kind):
    """A floor (8 x 8 quads) lit at ``angle_deg`` from its normal, nothing else, and a camera
    that sees it: ``where`` = "origin" (10 wide at the origin), "far" (the same at 1e4 from the
    origin), "big" (1e4 wide) or "tilted" (rotated off the axes, at (3, -2, 5))."""
    rot = np.eye(4)
    offset = np.zeros(3)
    size = 10.0
    if where == "far":
        offset = np.array([1e4, 1e4, -1e4])
    elif where == "big":
        size = 1e4
    elif where == "tilted":
        rng = np.random.default_rng(5)
        q, r = np.linalg.qr(rng.normal(size=(3, 3)))
        q = q * np.sign(np.diag(r))
        if np.linalg.det(q) < 0:
            q[:, 0] = -q[:, 0]
        rot[:3, :3] = q
        offset = np.array([3.0, -2.0, 5.0])
    pose = rot.copy()
    pose[:3, 3] = offset
    R = rot[:3, :3]
    scene = sr.Scene(ambient_light=(0.0, 0.0, 0.0))
    scene.add(plane_mesh(size, 8, material=lambert()), pose=pose)
    a = math.radians(angle_deg)
    travel_local = np.array([math.sin(a), -math.cos(a), 0.3 * math.sin(a)])
    travel_local /= np.linalg.norm(travel_local)
    if kind == "directional":
        scene.add(sr.DirectionalLight(intensity=3.0, shadows=True),
                  pose=ref.light_pose(offset + R @ [0.0, 1.0, 0.0], R @ travel_local))
    else:
        # A point light far to the side, at the angle seen from the floor's centre.
        reach = 3.0 * size
        light_at = offset + R @ (-travel_local * reach / math.sin(a))
        scene.add(sr.PointLight(intensity=3.0 * reach ** 2, shadows=True),
                  pose=ref.light_pose(light_at, R @ travel_local))
    span = 3.0 if where != "big" else 20.0
    eye = offset + R @ np.array([0.5, 0.6 * span, 1.2 * span])
    target = offset + R @ np.array([0.0, 0.0, -0.2 * span])
    up = R @ np.array([0.0, 1.0, 0.0])
    cam = sr.PerspectiveCamera(fov_y=50.0, width=W, height=H, near=0.05,
                               far=(2e4 if where == "big" else 100.0))
    cam.look_at(eye, target, up=up)
    return scene, cam


@pytest.mark.parametrize("where", ["origin", "far", "big", "tilted"])
@pytest.mark.parametrize("angle", [80.0, 85.0, 89.0])
@pytest.mark.parametrize("kind", ["directional", "point"])
def test_no_acne_at_grazing_light(kind, angle, where):
    """A lone floor lit at a grazing angle casts no shadow on itself: no pixel goes dark, and the
    shadowed render has the bits of the unshadowed one lit the same way (no bias is tuned for
    it: the floor's triangles pass through the shaded points).

    A shadowed light is evaluated at every pixel (its ray starts there), whereas a flat face under
    directional lights alone is otherwise lit once per face. So against the plain unshadowed
    render a tilted flat floor may differ in the last bits (within a few float32 ulps). Against
    an unshadowed render that also lights each pixel (a dark point light, which reads positions)
    the bits are the same."""
    scene, cam = _grazing_scene(angle, where, kind)
    outputs = ("radiance", "color", "mask")
    fs = render(scene, cam, outputs=outputs)
    fu = render(scene, cam, shadows=False, outputs=outputs)
    assert fu.mask.mean() > 0.3, "the floor is not in view"
    assert (fu.radiance[fu.mask] > 0).any(axis=-1).mean() > 0.95, "the floor is not lit"
    acne = fu.mask & (fu.radiance > 0).any(axis=-1) & (fs.radiance == 0).all(axis=-1)
    assert not acne.any(), f"{acne.sum()} floor pixels dark (acne), e.g. {np.argwhere(acne)[:3].tolist()}"
    lit = fu.mask
    rel = np.abs(fs.radiance[lit].astype(np.float64) - fu.radiance[lit]) / \
        np.maximum(np.abs(fu.radiance[lit].astype(np.float64)), 1e-30)
    assert rel.max() <= 4e-6, rel.max()
    if kind == "directional":
        scene.add(sr.PointLight(intensity=0.0), pose=np.eye(4))  # lights each pixel, adds nothing
        fs = render(scene, cam, outputs=outputs)
        fu = render(scene, cam, shadows=False, outputs=outputs)
    wrong = ~same_bits(fs.radiance, fu.radiance)
    assert not wrong.any(), (f"{wrong.sum()} of {fu.mask.sum()} floor pixels differ from the "
                             f"render without shadows, e.g. at {np.argwhere(wrong)[:3].tolist()}")
    assert (fs.color == fu.color).all()


# ------------------------------------------------------------------------------ convex sphere

def test_convex_sphere_shadows_itself_by_face_normal():
    """An icosphere (smooth normals) under a sun: a pixel whose face faces the light (face normal
    . to_light > 0) has the unshadowed bits; one whose face faces away gets no direct light
    (radiance 0), even where its smooth normal still faces the light."""
    scene = sr.Scene(ambient_light=(0.0, 0.0, 0.0))
    mesh = sphere_mesh(1.0, 3, material=lambert())
    scene.add(mesh, instance_id=0)
    travel = np.array([-1.0, -0.3, -0.2])
    scene.add(sr.DirectionalLight(intensity=2.0, shadows=True),
              pose=ref.light_pose((3.0, 1.0, 1.0), travel))
    cam = camera((0.3, 0.5, 3.5), (0.0, 0.0, 0.0))
    fs = render(scene, cam)
    fu = render(scene, cam, shadows=False)
    tris = ref.mesh_triangles(mesh.positions, mesh.faces)
    fn = np.cross(tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0])
    fn /= np.linalg.norm(fn, axis=1, keepdims=True)
    to_light = -travel / np.linalg.norm(travel)
    facing = fn @ to_light                           # per face
    sel = fs.mask
    fid = fs.triangle_id[sel]
    f = facing[fid]
    # Points within a hair of an edge toward a lit neighbour may legitimately be lit (that
    # neighbour's plane passes within eps of them), as may faces almost parallel to the light.
    edge = fs.barycentric[sel].min(axis=1) < 1e-3
    blocked, margin = reference_at_pixels(scene, fs, sel, tris=tris)
    keep = (np.abs(f) > 1e-3) & ~edge & (margin >= MARGIN)
    assert (~keep).mean() < 0.05
    # The reference agrees with the face-normal rule wherever it is robust.
    assert (blocked[keep] == (f[keep] < 0)).all()
    rs, ru = fs.radiance[sel], fu.radiance[sel]
    lit_faces = keep & (f > 0)
    away = keep & (f < 0)
    # Smooth normals light some faces that face away: those must go dark.
    assert ((ru[away] > 0).any(axis=-1)).sum() > 20, "no smooth-lit faces facing away in view"
    assert lit_faces.sum() > 1000 and away.sum() > 1000
    bad_lit = lit_faces & ~same_bits(rs, ru)
    assert not bad_lit.any(), f"{bad_lit.sum()} pixels of faces facing the light differ"
    bad_dark = away & ~(rs == 0).all(axis=-1)
    assert not bad_dark.any(), (f"{bad_dark.sum()} pixels of faces facing away are lit, e.g. "
                                f"{np.argwhere(sel)[bad_dark][:5].tolist()}")


# ------------------------------------------------------------------ point and spot vs reference

LAMP = np.array([-3.0, 6.0, 4.0])        # above and behind the camera
OFFVIEW = np.array([-2.6, 5.0, 3.6])     # a blocker near the lamp, behind the camera
BEYOND = LAMP + np.array([0.0, 1.5, 0.0])  # a lid over the lamp: beyond it for the floor


def blockers_scene(light, material=None, extra_lights=(), ambient=(0.0, 0.0, 0.0),
                   light_pose=None) -> sr.Scene:
    """A floor, a floating box, a box standing on the floor, a sphere, a small box near the lamp
    but out of view, and a lid above the lamp; ``light`` (None: none) at ``light_pose`` (default:
    at LAMP aimed at (0, 0, -1)), then ``extra_lights`` ((light, pose) pairs)."""
    mat = material or lambert()
    scene = sr.Scene(ambient_light=ambient)
    scene.add(plane_mesh(14.0, 6, material=mat), instance_id=0)
    scene.add(box_mesh((1.0, 0.8, 1.0), mat), pose=at(-0.8, 0.6, 0.2), instance_id=1)
    scene.add(box_mesh((0.6, 1.2, 0.6), mat), pose=at(1.2, 0.6, -0.8), instance_id=2)
    scene.add(sphere_mesh(0.5, 2, mat), pose=at(0.6, 1.6, 1.0), instance_id=3)
    scene.add(box_mesh((0.3, 0.3, 0.3), mat), pose=at(*OFFVIEW), instance_id=4)
    scene.add(box_mesh((4.0, 0.2, 4.0), mat), pose=at(*BEYOND), instance_id=5)
    if light is not None:
        if light_pose is None:
            light_pose = ref.light_pose(LAMP, np.array([0.0, 0.0, -1.0]) - LAMP)
        scene.add(light, pose=light_pose)
    for li, pose in extra_lights:
        scene.add(li, pose=pose)
    return scene


BLOCKERS_CAM = dict(eye=(0.0, 3.0, 3.0), target=(0.0, 0.0, -1.0))


def _punctual(kind, shadows=True, **kw):
    if kind == "point":
        return sr.PointLight(intensity=60.0, shadows=shadows, **kw)
    return sr.SpotLight(intensity=60.0, inner_cone=0.35, outer_cone=0.7, shadows=shadows, **kw)


@pytest.mark.parametrize("kind", ["point", "spot"])
def test_point_and_spot_shadows_match_reference(kind):
    """Point and spot lights over boxes and a sphere: at every pixel the light reaches, the
    render is dark exactly where the reference is blocked. The blocker out of view still casts
    into view; the lid beyond the lamp (which an unlimited ray would meet) casts nothing."""
    scene = blockers_scene(_punctual(kind))
    cam = camera(**BLOCKERS_CAM)
    fs = render(scene, cam)
    fu = render(scene, cam, shadows=False)
    ids = set(np.unique(fs.instance_id).tolist())
    assert {0, 1, 2, 3} <= ids and not ({4, 5} & ids), f"unexpected view: ids {ids}"
    sel = (fu.radiance > 0).any(axis=-1)
    assert (fs.radiance[~sel] == 0).all()
    dark, _ = observed(fs, fu, sel)
    tris = ref.scene_triangles(scene)
    blocked, margin = reference_at_pixels(scene, fs, sel, tris=tris)
    assert blocked.sum() > 300 and (~blocked).sum() > 3000
    compare(blocked, dark, margin, f"{kind} light", np.argwhere(sel))
    # The test is meaningful: the out-of-view box shadows pixels alone, and the lid would.
    _, owner = ref.scene_triangles(scene, return_owner=True)
    p = fs.position[sel].astype(np.float64)
    light = ref.scene_lights(scene)[0]
    without_offview = ref.shadow_rays(tris[owner[:, 0] != 4], p, light)[0]
    only_offview = blocked & ~without_offview
    assert only_offview.sum() > 30, "the out-of-view blocker shadows nothing in view"
    assert dark[only_offview & (margin >= MARGIN)].all()
    unlimited = ref.shadow_rays(tris, p, light, unlimited=True)[0]
    assert (unlimited & ~blocked).sum() > 1000, "the lid would not shadow anything anyway"


@pytest.mark.parametrize("floor", [14.0, 4.0e4], ids=["floor_14", "floor_4e4"])
def test_directional_shadows_match_reference(floor):
    """A slanted sun over the blockers: at every pixel it reaches, the render is dark exactly
    where the reference is blocked (the lid and the out-of-view box cast too: a directional
    light's rays are unlimited). Directional rays are looked up in a grid across the light
    (shadow.hpp); under a floor 4e4 wide the detail crowds a few cells, which are left to the
    hierarchy. The decisions are the rule's either way."""
    mat = lambert()
    scene = sr.Scene(ambient_light=(0.0, 0.0, 0.0))
    scene.add(plane_mesh(floor, 6, material=mat), instance_id=0)
    scene.add(box_mesh((1.0, 0.8, 1.0), mat), pose=at(-0.8, 0.6, 0.2), instance_id=1)
    scene.add(box_mesh((0.6, 1.2, 0.6), mat), pose=at(1.2, 0.6, -0.8), instance_id=2)
    scene.add(sphere_mesh(0.5, 2, mat), pose=at(0.6, 1.6, 1.0), instance_id=3)
    scene.add(box_mesh((0.3, 0.3, 0.3), mat), pose=at(2.6, 2.2, 0.9), instance_id=4)
    scene.add(sr.DirectionalLight(intensity=2.0, shadows=True),
              pose=ref.light_pose((0.0, 5.0, 0.0), np.array([-0.55, -1.0, -0.35])))
    cam = camera(**BLOCKERS_CAM)
    fs = render(scene, cam)
    fu = render(scene, cam, shadows=False)
    sel = (fu.radiance > 0).any(axis=-1)
    dark, _ = observed(fs, fu, sel)
    blocked, margin = reference_at_pixels(scene, fs, sel)
    assert blocked.sum() > 1000 and (~blocked).sum() > 3000
    compare(blocked, dark, margin, f"directional light, floor {floor}", np.argwhere(sel))


# ---------------------------------------------------------------------------- every lit model

def _model_material(model):
    return sr.Material(model=model, base_color=(0.7, 0.6, 0.5), ks=(0.6, 0.6, 0.6), shininess=20.0,
                       metallic=0.3, roughness=0.45, emissive=(0.01, 0.02, 0.0))


@pytest.mark.parametrize("model", LIT_MODELS)
def test_every_lit_model(model):
    """Each lit model with ambient light, emissive and a second, unshadowed light: a pixel the
    reference puts in the shadowed light's shadow has the bits of the scene without that light;
    a lit one the bits of the render without shadows."""
    mat = _model_material(model)
    ambient = (0.05, 0.05, 0.06)
    other = [(sr.PointLight(color=(0.4, 0.5, 1.0), intensity=3.0, shadows=False),
              ref.light_pose((2.0, 2.5, 1.0), (-1.0, -1.0, -1.0)))]
    sun = sr.DirectionalLight(color=(1.0, 0.95, 0.9), intensity=2.0, shadows=True)
    scene = blockers_scene(sun, mat, other, ambient, ref.light_pose((0, 5, 0), SUN_TRAVEL))
    no_sun = blockers_scene(None, mat, other, ambient)
    cam = camera(**BLOCKERS_CAM)
    fs = render(scene, cam)
    fu = render(scene, cam, shadows=False)
    fn = render(no_sun, cam)
    sel = fs.mask
    blocked, margin = reference_at_pixels(scene, fs, sel)
    keep = margin >= MARGIN
    assert (~keep).mean() < MAX_LEFT_OUT
    rs = fs.radiance[sel]
    dark = keep & blocked
    lit = keep & ~blocked
    assert dark.sum() > 300 and lit.sum() > 3000
    bad_dark = dark & ~same_bits(rs, fn.radiance[sel])
    bad_lit = lit & ~same_bits(rs, fu.radiance[sel])
    where = np.argwhere(sel)
    assert not bad_dark.any(), (
        f"{model}: {bad_dark.sum()} of {dark.sum()} shadowed pixels differ from the scene without "
        f"the sun, e.g. at {where[bad_dark][:3].tolist()}: {rs[bad_dark][:3].tolist()} vs "
        f"{fn.radiance[sel][bad_dark][:3].tolist()}")
    assert not bad_lit.any(), (
        f"{model}: {bad_lit.sum()} of {lit.sum()} lit pixels differ from the unshadowed render, "
        f"e.g. at {where[bad_lit][:3].tolist()}: {rs[bad_lit][:3].tolist()} vs "
        f"{fu.radiance[sel][bad_lit][:3].tolist()}")
    # The shadow really removes something in this model (the sun reaches the shadowed pixels).
    assert (fu.radiance[sel][dark] != rs[dark]).any()


# -------------------------------------------------------------------------------- frequencies

def _frequency_scene(kind):
    scene = sr.Scene(ambient_light=(0.0, 0.0, 0.0))
    scene.add(plane_mesh(8.0, 16, material=lambert()), instance_id=0)
    scene.add(plane_mesh(1.5, 1, material=lambert((0.3, 0.6, 0.9))),
              pose=at(SQUARE_C[0], SQUARE_H, SQUARE_C[1]), instance_id=1)
    scene.add(box_mesh((0.7, 0.7, 0.7), lambert((0.9, 0.5, 0.3))), pose=at(-1.2, 0.35, -0.6),
              instance_id=2)
    if kind == "directional":
        scene.add(sr.DirectionalLight(intensity=2.0, shadows=True),
                  pose=ref.light_pose((0.0, 5.0, 0.0), SUN_TRAVEL))
    else:
        scene.add(sr.PointLight(intensity=30.0, shadows=True),
                  pose=ref.light_pose((-1.5, 3.5, 1.0), (0.0, -1.0, 0.0)))
    return scene


@pytest.mark.parametrize("kind", ["directional", "point"])
def test_face_frequency_decides_at_the_centroid(kind):
    """frequency="face": every face's pixels are all dark or all with the unshadowed bits, as
    the reference decides at the face's centroid (world, float64)."""
    scene = _frequency_scene(kind)
    cam = camera(**SQUARE_CAM)
    fs = render(scene, cam, frequency="face")
    fu = render(scene, cam, shadows=False, frequency="face")
    tris, owner = ref.scene_triangles(scene, return_owner=True)
    blocked, margin = ref.shadow_rays(tris, ref.face_centroids(tris), ref.scene_lights(scene)[0])
    checked = dark_faces = 0
    for k, inst in enumerate(scene.instances):
        rows = np.flatnonzero(owner[:, 0] == k)
        for f in np.unique(fs.triangle_id[fs.instance_id == inst.instance_id]):
            px = (fs.instance_id == inst.instance_id) & (fs.triangle_id == f)
            ru = fu.radiance[px]
            if not (ru > 0).any():
                continue  # faces away from the light
            row = rows[f]
            rs = fs.radiance[px]
            dark = (rs == 0).all(axis=-1)
            lit = same_bits(rs, ru)
            assert dark.all() or lit.all(), f"instance {k} face {f}: mixed shadow in one face"
            if margin[row] < MARGIN:
                continue
            checked += 1
            dark_faces += bool(blocked[row])
            assert dark.all() == blocked[row], (
                f"instance {k} face {f} (centroid {ref.face_centroids(tris[row:row + 1])[0]}): "
                f"reference blocked={blocked[row]}, render dark={dark.all()}")
    assert checked > 200 and dark_faces > 10


def test_vertex_frequency_decides_at_the_vertices():
    """frequency="vertex": a floor face whose three corners the reference puts in shadow is dark,
    one whose corners are all lit has the unshadowed bits, and a face in between lies between."""
    scene = _frequency_scene("directional")
    cam = camera(**SQUARE_CAM)
    fs = render(scene, cam, frequency="vertex")
    fu = render(scene, cam, shadows=False, frequency="vertex")
    floor = scene.instances[0]
    tris = ref.scene_triangles(scene)
    vw = ref.mesh_triangles(floor.mesh.positions, np.arange(floor.mesh.num_vertices)[:, None],
                            floor.pose)[:, 0]
    blocked, margin = ref.shadow_rays(tris, vw, ref.scene_lights(scene)[0])
    faces = np.asarray(floor.mesh.faces)
    counts = {"dark": 0, "lit": 0, "mixed": 0}
    for f in np.unique(fs.triangle_id[fs.instance_id == 0]):
        px = (fs.instance_id == 0) & (fs.triangle_id == f)
        vb, vm = blocked[faces[f]], margin[faces[f]]
        rs, ru = fs.radiance[px], fu.radiance[px]
        if (vm < MARGIN).any():
            continue
        if vb.all():
            counts["dark"] += 1
            assert (rs == 0).all(), f"floor face {f}: all corners shadowed, radiance not 0"
        elif not vb.any():
            counts["lit"] += 1
            assert same_bits(rs, ru).all(), f"floor face {f}: all corners lit, bits differ"
        else:
            counts["mixed"] += 1
            assert (rs >= 0).all() and (rs <= ru * (1 + 1e-5) + 1e-7).all(), f"floor face {f}"
            assert (rs < ru).any(), f"floor face {f}: a shadowed corner darkens nothing"
    assert counts["dark"] > 3 and counts["lit"] > 100 and counts["mixed"] > 5, counts


# ---------------------------------------------------------------------------------- overrides

def test_light_attributes_and_defaults():
    """Lights default to shadows=False; True and "exact" both mean "exact"; pickling keeps it."""
    for make in (sr.DirectionalLight, sr.PointLight, sr.SpotLight):
        assert make().shadows is False
        assert make(shadows=False).shadows is False
        assert make(shadows=True).shadows == "exact"
        assert make(shadows="exact").shadows == "exact"
        light = make(shadows=True, shadow_resolution=512, shadow_bias=0.01)
        back = pickle.loads(pickle.dumps(light))
        assert back == light and back.shadows == "exact"
        assert make(shadows=True) != make(shadows=False)


def test_render_shadows_overrides_the_lights():
    """render(shadows=False) on shadowed lights gives the bits of lights without shadows;
    render(shadows=True / "exact") on unshadowed lights gives the shadowed bits; render(shadows=
    None) and the default follow each light."""
    cam = camera(**BLOCKERS_CAM)
    outputs = ("radiance", "color", "depth", "normal", "instance_id")
    two = lambda s: blockers_scene(_punctual("point", shadows=s), extra_lights=[  # noqa: E731
        (sr.DirectionalLight(intensity=0.5, shadows=s), ref.light_pose((0, 5, 0), SUN_TRAVEL))])
    on, off = two(True), two(False)
    base_on = render(on, cam, outputs=outputs)
    base_off = render(off, cam, outputs=outputs)
    assert not same_bits(base_on.radiance, base_off.radiance).all(), "no shadow in view"
    for frame in (render(on, cam, shadows=False, outputs=outputs),
                  render(off, cam, shadows=None, outputs=outputs),
                  render(off, cam, outputs=outputs)):
        for name in outputs:
            assert np.array_equal(getattr(frame, name), getattr(base_off, name)), name
    for frame in (render(off, cam, shadows=True, outputs=outputs),
                  render(off, cam, shadows="exact", outputs=outputs),
                  render(on, cam, shadows=None, outputs=outputs)):
        for name in outputs:
            assert np.array_equal(getattr(frame, name), getattr(base_on, name)), name
    # One light with shadows, one without: render(None) shadows only the first.
    mixed = blockers_scene(_punctual("point", shadows=True), extra_lights=[
        (sr.DirectionalLight(intensity=0.5, shadows=False), ref.light_pose((0, 5, 0), SUN_TRAVEL))])
    fm = render(mixed, cam, outputs=outputs)
    assert not same_bits(fm.radiance, base_on.radiance).all()
    assert not same_bits(fm.radiance, base_off.radiance).all()


# ---------------------------------------------------------------------------------- same bits

def test_same_bits_for_threads_and_instruction_sets():
    """Shadowed renders (point, spot and directional lights, all with shadows) are bit-identical
    for 1, 2 and 3 threads and for AVX2 and generic kernels, at every frequency; msaa=4 too."""
    scene = blockers_scene(_punctual("spot"), extra_lights=[
        (sr.DirectionalLight(intensity=0.7, shadows=True), ref.light_pose((0, 5, 0), SUN_TRAVEL)),
        (sr.PointLight(intensity=5.0, shadows=True), ref.light_pose((1.5, 2.0, 0.5), (0, -1, 0)))],
        ambient=(0.02, 0.02, 0.02))
    cam = camera(**BLOCKERS_CAM)
    outputs = ("radiance", "color")
    for kw in (dict(), dict(frequency="vertex"), dict(frequency="face"), dict(msaa=4)):
        frames = [render(scene, cam, outputs=outputs, threads=t, simd=simd, **kw)
                  for simd in (True, False) for t in (1, 2, 3)]
        for f in frames[1:]:
            assert np.array_equal(bits(f.radiance), bits(frames[0].radiance)), kw
            assert np.array_equal(f.color, frames[0].color), kw
        assert not same_bits(frames[0].radiance,
                             render(scene, cam, shadows=False, outputs=outputs, **kw).radiance).all()


@pytest.mark.parametrize("aa", [dict(msaa=4), dict(ssaa=2)])
def test_antialiased_shadows_stay_black(aa):
    """With msaa=4 or ssaa=2 the shadowed render runs, and a region the reference puts deep in
    shadow (the pixel and its 8 neighbours all blocked, floor only) has radiance 0."""
    scene = square_scene()
    cam = camera(**SQUARE_CAM)
    f1 = render(scene, cam)
    fa = render(scene, cam, **aa)
    fu = render(scene, cam, shadows=False, **aa)
    floor = f1.instance_id == 0
    blocked = np.zeros((H, W), bool)
    b, m = reference_at_pixels(scene, f1, floor)
    blocked[floor] = b & (m > 1e-3)
    deep = blocked.copy()
    for dy in (-1, 0, 1):
        for dx in (-1, 0, 1):
            deep[1:-1, 1:-1] &= blocked[1 + dy:H - 1 + dy, 1 + dx:W - 1 + dx]
    deep[0, :] = deep[-1, :] = deep[:, 0] = deep[:, -1] = False
    assert deep.sum() > 200
    assert (fa.radiance[deep] == 0).all()
    assert (fu.radiance[deep] > 0).any(axis=-1).all()
    # Deep in the light, the same as without shadows.
    lit = np.zeros((H, W), bool)
    lit[floor] = ~b & (m > 1e-2)
    deep_lit = lit.copy()
    for dy in (-1, 0, 1):
        for dx in (-1, 0, 1):
            deep_lit[1:-1, 1:-1] &= lit[1 + dy:H - 1 + dy, 1 + dx:W - 1 + dx]
    deep_lit[0, :] = deep_lit[-1, :] = deep_lit[:, 0] = deep_lit[:, -1] = False
    assert same_bits(fa.radiance[deep_lit], fu.radiance[deep_lit]).all()


# --------------------------------------------------------------------------- blend and mask

def test_blended_draws_cast_no_shadow_masked_draws_do():
    """A blended square (alpha 0.5) over the floor casts nothing: the whole image has the bits of
    the render without shadows. The same square masked (alpha 1 >= cutoff) casts the reference's
    shadow, which is its geometry's."""
    blend = sr.Material(model="lambert", base_color=(0.3, 0.6, 0.9, 0.5), alpha_mode="blend",
                        double_sided=True)
    scene = square_scene(material=blend)
    cam = camera(**SQUARE_CAM)
    outputs = ("radiance", "color", "instance_id")
    fs = render(scene, cam, outputs=outputs)
    fu = render(scene, cam, shadows=False, outputs=outputs)
    assert same_bits(fs.radiance, fu.radiance).all(), "a blended draw casts a shadow"
    assert np.array_equal(fs.color, fu.color)
    assert ref.scene_triangles(scene).shape[0] == 8  # the floor's only

    mask = sr.Material(model="lambert", base_color=(0.3, 0.6, 0.9, 1.0), alpha_mode="mask",
                       alpha_cutoff=0.5, double_sided=True)
    scene = square_scene(material=mask)
    fs = render(scene, cam)
    fu = render(scene, cam, shadows=False)
    floor = fs.instance_id == 0
    dark, _ = observed(fs, fu, floor)
    blocked, margin = reference_at_pixels(scene, fs, floor)
    assert blocked.sum() > 400
    compare(blocked, dark, margin, "masked square", np.argwhere(floor))


# --------------------------------------------------------------------------------- bad values

def test_a_renderer_reused_across_scene_edits_matches_a_fresh_one():
    """A renderer keeps its occluder hierarchy while the casting meshes and their poses stay the
    same (a dataset's views build it once). Moving the square, removing the
    square and adding another mesh: each render equals a fresh renderer's, bit for bit, and the
    shadow moves."""
    scene = square_scene()
    cam = camera(**SQUARE_CAM)
    kept = sr.Renderer(W, H, threads=2)

    def check(what):
        got = kept.render(scene, cam, outputs=("radiance",)).radiance
        want = sr.Renderer(W, H, threads=2).render(scene, cam, outputs=("radiance",)).radiance
        assert got.tobytes() == want.tobytes(), what
        return got

    first = check("first")
    assert check("again").tobytes() == first.tobytes()
    scene.set_pose(1, at(SQUARE_C[0] + 0.7, SQUARE_H, SQUARE_C[1]))
    moved = check("square moved")
    assert moved.tobytes() != first.tobytes()
    scene.remove(1)
    gone = check("square removed")
    assert (gone > 0).any(-1).sum() > (moved > 0).any(-1).sum()  # no shadow left: more lit
    scene.add(box_mesh((0.5, 0.5, 0.5), material=lambert()), pose=at(0.5, 0.6, 0.3), instance_id=2)
    check("a box added")


def test_distorted_camera_shows_the_shadows():
    """A camera with lens distortion renders colour from an ideal pinhole view: the shadows come
    with it, and render(shadows=False) passes through to that view."""
    scene = square_scene()
    cam = camera((0.6, 3.0, 2.5), (0.0, 0.0, 0.0))
    dist = sr.IntrinsicsCamera(150.0, 150.0, 80.0, 60.0, W, H, convention="opengl",
                               dist=(-0.2, 0.05, 0.0, 0.0, 0.0))
    dist.pose = cam.pose
    shadowed = render(scene, dist, outputs=("radiance", "mask"))
    plain = render(scene, dist, shadows=False, outputs=("radiance", "mask"))
    pin = render(scene, cam, outputs=("radiance", "mask"))
    pin_plain = render(scene, cam, shadows=False, outputs=("radiance", "mask"))
    dark = (shadowed.radiance < plain.radiance).any(-1)
    pin_dark = (pin.radiance < pin_plain.radiance).any(-1)
    assert pin_dark.sum() > 100
    # the same shadow, a little displaced by the lens: a comparable area
    assert 0.5 * pin_dark.sum() < dark.sum() < 1.5 * pin_dark.sum()
    assert not (shadowed.radiance > plain.radiance).any()


@pytest.mark.parametrize("make", [sr.DirectionalLight, sr.PointLight, sr.SpotLight])
def test_bad_light_values(make):
    """Unknown shadow methods, a resolution < 1, a negative or non-finite bias: ValueError naming
    the argument."""
    for value in ("bogus", "maps", ""):
        with pytest.raises(ValueError, match="shadows"):
            make(shadows=value)
    for value in (0, -3):
        with pytest.raises(ValueError, match="shadow_resolution"):
            make(shadows=True, shadow_resolution=value)
    for value in (-1.0, -1e-9, math.inf, math.nan):
        with pytest.raises(ValueError, match="shadow_bias"):
            make(shadows=True, shadow_bias=value)


def test_bad_render_values():
    """render(shadows=) takes None, False, True, "exact" or "map"; anything else raises
    ValueError naming shadows."""
    scene = square_scene()
    cam = camera(**SQUARE_CAM, w=32, h=24)
    for value in ("x", "maps", "bogus"):
        with pytest.raises(ValueError, match="shadows"):
            render(scene, cam, shadows=value, outputs=("color",))


# ------------------------------------------------------------------ the reference, cross-checked

class _AllTriangles:
    """A broad phase for trimesh's ray_triangle_id without rtree: each ray's box against every
    triangle's box (trimesh's narrow phase, the plane hit and its barycentrics, does the rest)."""

    def __init__(self, triangles):
        lo, hi = triangles.min(axis=1), triangles.max(axis=1)
        self.boxes = np.hstack([lo, hi])
        self.bounds = np.concatenate([lo.min(axis=0), hi.max(axis=0)])

    def intersection(self, box):
        box = np.asarray(box)
        ok = (self.boxes[:, :3] <= box[3:]).all(axis=1) & (self.boxes[:, 3:] >= box[:3]).all(axis=1)
        return np.flatnonzero(ok).tolist()


@pytest.mark.parametrize("kind", ["directional", "point"])
def test_reference_agrees_with_trimesh(kind):
    """The NumPy reference against trimesh's ray casting (plane hits and barycentrics, an
    independent implementation) for points on the floor of the blockers scene well away from
    any edge: the same shadowed set."""
    if kind == "directional":
        light = sr.DirectionalLight(shadows=True)
        scene = blockers_scene(light)
        # blockers_scene aims the light from LAMP at (0, 0, -1): a steep sun.
    else:
        scene = blockers_scene(_punctual("point"))
    rl = ref.scene_lights(scene)[0]
    tris, owner = ref.scene_triangles(scene, return_owner=True)
    rng = np.random.default_rng(11)
    pts = np.column_stack([rng.uniform(-4, 4, 3000), np.zeros(3000), rng.uniform(-5, 3, 3000)])
    blocked, margin = ref.shadow_rays(tris, pts, rl)
    casters = tris[owner[:, 0] != 0]  # the floor's points meet only the blockers
    if kind == "directional":
        dirs = np.broadcast_to(-rl.direction, pts.shape).copy()
    else:
        dirs = rl.position - pts
    hit_tri, hit_ray, loc = tm_ray.ray_triangle_id(casters, pts, dirs, tree=_AllTriangles(casters))
    t = np.einsum("ij,ij->i", loc - pts[hit_ray], dirs[hit_ray]) / np.einsum(
        "ij,ij->i", dirs[hit_ray], dirs[hit_ray])
    ok = t > 1e-9 if kind == "directional" else (t > 1e-9) & (t < 1.0)
    tm_blocked = np.zeros(len(pts), bool)
    tm_blocked[hit_ray[ok]] = True
    keep = margin > 1e-4
    assert keep.mean() > 0.99
    assert blocked[keep].sum() > 100 and (~blocked[keep]).sum() > 1000
    assert np.array_equal(blocked[keep], tm_blocked[keep])


def test_reference_rule_details():
    """The reference itself: a triangle whose plane passes within eps of the point does not
    block, one just beyond does; a point light's blockers lie strictly between point and light;
    a blocker's edges give a small margin."""
    tri = np.array([[[-1.0, 1.0, -1.0], [1.0, 1.0, -1.0], [0.0, 1.0, 2.0]]])  # plane y = 1
    up = ref.RefLight("directional", np.zeros(3), np.array([0.0, -1.0, 0.0]))
    eps = 2.0 ** -19
    pts = np.array([[0.0, 1.0 - 0.5 * eps, 0.0], [0.0, 1.0 - 8 * eps, 0.0], [0.0, 0.0, 0.0],
                    [5.0, 0.0, 0.0], [2.0 / 3.0 - 1e-7, 0.0, 0.0]])
    blocked, margin = ref.shadow_rays(tri, pts, up)
    assert blocked.tolist() == [False, True, True, False, True]
    assert margin[2] > 0.1 and margin[3] > 1.0 and margin[4] < 1e-6
    lamp = ref.RefLight("point", np.array([0.0, 3.0, 0.0]), np.array([0.0, -1.0, 0.0]))
    below = ref.RefLight("point", np.array([0.0, 0.5, 0.0]), np.array([0.0, -1.0, 0.0]))
    assert ref.shadow_rays(tri, pts[2:3], lamp)[0].tolist() == [True]
    assert ref.shadow_rays(tri, pts[2:3], below)[0].tolist() == [False]
    assert ref.shadow_rays(tri, pts[2:3], below, unlimited=True)[0].tolist() == [True]
