"""The NumPy reference (softrast.reference.shading) against closed forms computed by hand,
so that test_lighting.py tests the renderer against something known to be right."""
from __future__ import annotations

import math

import numpy as np
import pytest

import softrast as sr
from softrast.reference import shading as ref

Z = np.array([[0.0, 0.0, 1.0]])
O = np.zeros((1, 3))


pose_at = ref.pose_at


def sun(travel, color=(1.0, 1.0, 1.0), intensity=1.0):
    return sr.DirectionalLight(color, intensity)._record_fields(pose_at(travel=travel))


def unit(*v):
    v = np.asarray(v, float)
    return v / np.linalg.norm(v)


# --------------------------------------------------------------------------------------- lambert

def test_lambert_closed_form():
    mat = sr.Material(kd=(0.5, 0.4, 0.3), ka=(0.1, 0.2, 0.3), emissive=(0.01, 0.02, 0.03))
    light = sun(-unit(0, math.sin(math.radians(60)), 0.5), color=(1.0, 0.5, 0.25), intensity=2.0)
    # l is 60 degrees from n: n.l = 0.5; I = (2, 1, 0.5)
    got = ref.radiance("lambert", Z, O, (0.9, 0.9, 0.9), mat, [light], (0.5, 0.5, 1.0), (0, 0, 5))
    want = np.array([0.1 * 0.5 + 0.5 * 2 * 0.5 + 0.01,
                     0.2 * 0.5 + 0.4 * 1 * 0.5 + 0.02,
                     0.3 * 1.0 + 0.3 * 0.5 * 0.5 + 0.03])
    np.testing.assert_allclose(got[0], want, rtol=0, atol=1e-14)


def test_lambert_defaults_and_back_light():
    # No material: kd = ka = base, no specular, no emissive; a light behind adds nothing.
    base = (0.6, 0.3, 0.9)
    front = sun((0, 0, -1), intensity=0.75)
    back = sun((0, 0, 1), intensity=5.0)
    for model in ("lambert", "phong", "blinn_phong"):
        got = ref.radiance(model, Z, O, base, None, [front, back], (0.25,) * 3, (0, 0, 3))
        np.testing.assert_allclose(got[0], np.array(base) * (0.25 + 0.75), atol=1e-15)
    # material without kd / ka: both are the base colour
    mat = sr.Material(ks=None)
    got = ref.radiance("lambert", Z, O, base, mat, [front], (0.2,) * 3, (0, 0, 3))
    np.testing.assert_allclose(got[0], np.array(base) * 0.95, atol=1e-15)
    mat = sr.Material(kd=(0.1, 0.1, 0.1), ks=None)  # ka follows kd, not the base
    got = ref.radiance("lambert", Z, O, base, mat, [], (1.0,) * 3, (0, 0, 3))
    np.testing.assert_allclose(got[0], 0.1, atol=1e-15)


# ------------------------------------------------------------------------------ phong / blinn

def test_phong_mirror_direction_and_exponent():
    ks, p = (0.5, 0.25, 1.0), 8.0
    mat = sr.Material(kd=(0, 0, 0), ks=ks, shininess=p)
    l = unit(1, 0, 1)          # 45 degrees from n in the xz plane; r = (-1, 0, 1)/sqrt2
    light = sun(-l, intensity=2.0)
    r = unit(-1, 0, 1)
    got = ref.radiance("phong", Z, O, (0, 0, 0), mat, [light], (0, 0, 0), r * 4.0)
    np.testing.assert_allclose(got[0], 2.0 * np.array(ks), atol=1e-14)  # r.v = 1
    theta = math.radians(20)
    v = np.array([-math.sin(math.pi / 4 - theta), 0, math.cos(math.pi / 4 - theta)])  # 20 deg off r
    got = ref.radiance("phong", Z, O, (0, 0, 0), mat, [light], (0, 0, 0), v * 4.0)
    np.testing.assert_allclose(got[0], 2.0 * np.array(ks) * math.cos(theta) ** p, rtol=1e-13)


def test_specular_needs_a_lit_side():
    # [n.l > 0]: a light behind the surface gives no highlight even where r.v or n.h > 0,
    # even with shininess 0 (where max(0, .)^0 = 1).
    mat = sr.Material(kd=(0, 0, 0), ks=(1, 1, 1), shininess=0.0)
    back = sun(unit(0.3, 0, 1))  # travels away from the surface: l.n < 0
    for model in ("phong", "blinn_phong"):
        got = ref.radiance(model, Z, O, (0, 0, 0), mat, [back], (0, 0, 0), (0, 0, 3))
        assert np.all(got == 0.0)
    front = sun(unit(0.3, 0, -1))
    for model in ("phong", "blinn_phong"):  # shininess 0: the full ks * I
        got = ref.radiance(model, Z, O, (0, 0, 0), mat, [front], (0, 0, 0), (0, 0, 3))
        np.testing.assert_allclose(got[0], 1.0, atol=1e-15)


def test_blinn_phong_peaks_where_n_is_h():
    mat = sr.Material(kd=(0, 0, 0), ks=(1, 1, 1), shininess=50.0)
    l = unit(0.6, 0.0, 0.8)
    light = sun(-l)
    # normals sweeping the xz plane; the viewer along z: h = normalize(l + z)
    ang = np.linspace(-0.5, 1.2, 17001)
    n = np.stack([np.sin(ang), np.zeros_like(ang), np.cos(ang)], 1)
    v = np.array([0.0, 0.0, 1.0])
    got = ref.radiance("blinn_phong", n, np.zeros_like(n), (0, 0, 0), mat, [light], (0, 0, 0),
                       None, orthographic_dir=-v)[:, 0]
    h = unit(*(l + v))
    best = ang[np.argmax(got)]
    assert abs(best - math.atan2(h[0], h[2])) < 1e-4
    np.testing.assert_allclose(got.max(), 1.0, atol=1e-7)
    # and the closed form off the peak: (n.h)^50
    np.testing.assert_allclose(got, np.maximum(0, n @ h) ** 50, rtol=1e-12, atol=1e-300)


# ---------------------------------------------------------------------------------------- pbr

def test_pbr_head_on_closed_form():
    # n = l = v: nl = nv = nh = vh = 1, F = f0, G = 1, D = 1 / (pi a2), a2 = roughness^4
    base, m, rgh = np.array([0.8, 0.5, 0.2]), 0.3, 0.6
    mat = sr.Material(base_color=tuple(base), metallic=m, roughness=rgh, emissive=(0.1, 0, 0))
    light = sun((0, 0, -1), intensity=3.0)
    got = ref.radiance("pbr", Z, O, base, mat, [light], (0.2, 0.2, 0.2), (0, 0, 2))[0]
    f0 = 0.04 * (1 - m) + base * m
    c_diff = base * 0.96 * (1 - m)
    a2 = rgh ** 4
    spec = f0 * (1 / (math.pi * a2)) / (4 + 0.001)
    want = 3.0 * ((1 - f0) * c_diff / math.pi + spec) + base * 0.2 + np.array([0.1, 0, 0])
    np.testing.assert_allclose(got, want, rtol=1e-14)


def test_pbr_grazing_terms_and_clamps():
    # l at 60 deg, v at -60 deg (mirror): h = n, nh = 1, vh = cos 60 = 0.5, nl = nv = 0.5
    base, m, rgh = np.array([0.7, 0.7, 0.7]), 0.0, 0.5
    l = np.array([math.sin(math.pi / 3), 0, 0.5])
    v = np.array([-math.sin(math.pi / 3), 0, 0.5])
    got = ref.radiance("pbr", Z, O, base, sr.Material(metallic=m, roughness=rgh), [sun(-l)],
                       (0, 0, 0), v * 10)[0]
    F = 0.04 + 0.96 * 0.5 ** 5
    k = (rgh + 1) ** 2 / 8
    g = 0.5 / (0.5 * (1 - k) + k)
    a2 = rgh ** 4
    D = 1 / (math.pi * a2)
    want = 0.5 * ((1 - F) * base * 0.96 / math.pi + F * g * g * D / (4 * 0.25 + 0.001))
    np.testing.assert_allclose(got, want, rtol=1e-13)
    # roughness below 0.04 is 0.04; a light behind still leaks through nl = 0.001
    a = ref.radiance("pbr", Z, O, base, sr.Material(roughness=0.0), [sun(-l)], O[0], v * 10)
    b = ref.radiance("pbr", Z, O, base, sr.Material(roughness=0.04), [sun(-l)], O[0], v * 10)
    np.testing.assert_array_equal(a, b)
    behind = ref.radiance("pbr", Z, O, base, sr.Material(), [sun((0, 0, 1))], O[0], (0, 0, 3))[0]
    # l = -z, v = z: l + v = 0, so h = 0 (the reference's guard, no NaN): vh = 0, F = 1,
    # diffuse 0, and the specular term through nl = 0.001 is small but positive
    assert np.all(np.isfinite(behind)) and np.all(behind > 0) and np.all(behind < 1e-3)
    behind2 = ref.radiance("pbr", Z, O, base, sr.Material(), [sun(unit(0.5, 0, 1))], O[0], (0, 0, 3))[0]
    assert np.all(behind2 > 1e-4) and np.all(behind2 < 1e-3)  # about 0.001 * c_diff / pi


def test_pbr_without_material_uses_material_defaults():
    light = sun(unit(0.2, -0.3, -1))
    a = ref.radiance("pbr", Z, O, (0.5, 0.5, 0.5), None, [light], (0.1,) * 3, (0, 0, 3))
    b = ref.radiance("pbr", Z, O, (0.5, 0.5, 0.5), sr.Material(ks=None), [light], (0.1,) * 3, (0, 0, 3))
    np.testing.assert_array_equal(a, b)


# ------------------------------------------------------------------------------------- lights

def test_inverse_square_and_no_falloff():
    p = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 3.0, 0.0]])
    n = np.tile(Z, (3, 1))
    pos = (0.0, 0.0, 2.0)
    rec = sr.PointLight(intensity=8.0)._record_fields(pose_at(pos))
    got = ref.radiance("lambert", n, p, (1, 1, 1), None, [rec], (0, 0, 0), (0, 0, 5))[:, 0]
    r2 = np.array([4.0, 5.0, 13.0])
    np.testing.assert_allclose(got, 8.0 / r2 * (2.0 / np.sqrt(r2)), rtol=1e-14)
    rec = sr.PointLight(intensity=8.0, falloff="none")._record_fields(pose_at(pos))
    got = ref.radiance("lambert", n, p, (1, 1, 1), None, [rec], (0, 0, 0), (0, 0, 5))[:, 0]
    np.testing.assert_allclose(got, 8.0 * (2.0 / np.sqrt(r2)), rtol=1e-14)


def test_spot_cone_edges():
    inner, outer = math.radians(20), math.radians(40)
    rec = sr.SpotLight(intensity=1.0, inner_cone=inner, outer_cone=outer, falloff="none")._record_fields(
        pose_at((0, 0, 1), travel=(0, 0, -1)))
    # points on the plane z = 0 at angle a from the axis: x = tan a; I = factor, n.l = cos a
    a = np.radians([0, 10, 19.99, 20.01, 25, 30, 35, 39.99, 40.01, 60, 85])
    p = np.stack([np.tan(a), np.zeros_like(a), np.zeros_like(a)], 1)
    n = np.tile(Z, (len(a), 1))
    got = ref.radiance("lambert", n, p, (1, 1, 1), None, [rec], (0, 0, 0), (0, 0, 5))[:, 0] / np.cos(a)
    t = np.clip((np.cos(a) - math.cos(outer)) / (math.cos(inner) - math.cos(outer)), 0, 1)
    np.testing.assert_allclose(got, t * t, atol=1e-13)
    assert np.all(got[a < inner] == pytest.approx(1.0, abs=1e-13))
    assert np.all(got[a > outer] == 0.0)
    mid = 0.5 * (math.cos(inner) + math.cos(outer))  # halfway in cos: factor 1/4
    am = math.acos(mid)
    g = ref.radiance("lambert", Z, [[math.tan(am), 0, 0]], (1, 1, 1), None, [rec], (0, 0, 0), (0, 0, 5))
    assert g[0, 0] / mid == pytest.approx(0.25, abs=1e-12)


def test_spot_inner_zero_and_the_0_001_floor():
    # inner = 0: a cone that fades from the axis; tiny cone differences use scale = 1/0.001
    rec = sr.SpotLight(inner_cone=0.0, outer_cone=0.01, falloff="none")._record_fields(pose_at((0, 0, 1)))
    scale, offset = rec["cone_scale"], rec["cone_offset"]
    assert scale == pytest.approx(1 / 0.001) and offset == pytest.approx(-math.cos(0.01) * 1000)
    got = ref.radiance("lambert", Z, O, (1, 1, 1), None, [rec], (0, 0, 0), (0, 0, 5))
    t = min(1.0, 1.0 * scale + offset)
    assert got[0, 0] == pytest.approx(t * t, rel=1e-12)


def test_light_record_radiance_and_direction():
    rec = ref.as_tuple(sr.DirectionalLight((0.5, 1.0, 0.25), 4.0)._record_fields(pose_at(travel=(1, 2, 2))))
    assert rec[0] == ref.DIRECTIONAL
    np.testing.assert_allclose(rec[1], (2.0, 4.0, 1.0))
    np.testing.assert_allclose(rec[3], unit(1, 2, 2), atol=1e-15)
    l, I = ref.light_dir_and_radiance(rec, np.zeros((2, 3)))
    np.testing.assert_allclose(l, np.tile(-unit(1, 2, 2), (2, 1)), atol=1e-15)


def test_headlight_and_scene_lighting():
    cam = sr.PerspectiveCamera()
    cam.look_at((1.0, 2.0, 3.0), (0.0, 0.5, 0.0))
    lights, amb = ref.headlight(cam.view_matrix(), 0.25)
    assert amb == (0.25, 0.25, 0.25) and len(lights) == 1
    kind, rgb, _, d, inv_sq, scale, offset = lights[0]
    assert kind == ref.DIRECTIONAL and not inv_sq and rgb == (0.75, 0.75, 0.75)
    np.testing.assert_allclose(d, unit(-1.0, -1.5, -3.0), atol=1e-14)
    # headlight lambert = base * (ambient + (1 - ambient) * max(0, n . -d)), today's shading
    n = np.array([unit(1, 1.5, 3), unit(0, 1, 0)])
    got = ref.radiance("lambert", n, np.zeros((2, 3)), (0.4, 0.6, 0.8), None, lights, amb, (1, 2, 3))
    want = np.outer(0.25 + 0.75 * np.maximum(0, n @ unit(1, 1.5, 3)), (0.4, 0.6, 0.8))
    np.testing.assert_allclose(got, want, atol=1e-15)
    # scene_lighting: no lights => headlight; lights => their records and ambient 0 by default
    s = sr.Scene()
    assert ref.scene_lighting(s, cam.view_matrix(), 0.3)[1] == (0.3, 0.3, 0.3)
    s.add(sr.PointLight(), pose=pose_at((0, 5, 0)))
    s.add(sr.DirectionalLight(), pose=pose_at(travel=(0, 0, -1)), camera_space=True)
    lights, amb = ref.scene_lighting(s, cam.view_matrix(), 0.3)
    assert amb == (0.0, 0.0, 0.0) and len(lights) == 2
    np.testing.assert_allclose(lights[0][2], (0, 5, 0))
    np.testing.assert_allclose(lights[1][3], unit(-1.0, -1.5, -3.0), atol=1e-14)  # camera's -z


def test_view_vector_perspective_and_orthographic():
    mat = sr.Material(kd=(0, 0, 0), ks=(1, 1, 1), shininess=1.0)
    light = sun((0, 0, -1))
    p = np.array([[0.0, 0.0, 0.0], [3.0, 0.0, 0.0]])
    n = np.tile(Z, (2, 1))
    persp = ref.radiance("phong", n, p, (0, 0, 0), mat, [light], (0, 0, 0), (0, 0, 4))[:, 0]
    np.testing.assert_allclose(persp, [1.0, 0.8], atol=1e-15)  # r = z; v = (−3, 0, 4)/5 at x = 3
    ortho = ref.radiance("phong", n, p, (0, 0, 0), mat, [light], (0, 0, 0), (0, 0, 4),
                         orthographic_dir=(0, 0, -2))[:, 0]
    np.testing.assert_allclose(ortho, [1.0, 1.0], atol=1e-15)


def test_unlit_and_normal_models():
    n = np.array([unit(1, 2, 3), unit(-1, 0, 0)])
    lights = [sun((0, 0, -1), intensity=3.0), sr.PointLight()._record_fields(pose_at((0, 0, 1)))]
    mat = sr.Material(emissive=(0.5, 0.5, 0.5))
    got = ref.radiance("unlit", n, np.zeros((2, 3)), [[0.1, 0.2, 0.3], [0.4, 0.5, 0.6]], mat,
                       lights, (1, 1, 1), (0, 0, 3))
    np.testing.assert_array_equal(got, [[0.1, 0.2, 0.3], [0.4, 0.5, 0.6]])
    got = ref.radiance("normal", n, np.zeros((2, 3)), (0, 0, 0), mat, lights, (1, 1, 1), (0, 0, 3))
    np.testing.assert_allclose(got, (n + 1) / 2, atol=1e-16)
    with pytest.raises(ValueError):
        ref.radiance("toon", n, np.zeros((2, 3)), (0, 0, 0), None, [], (0, 0, 0), (0, 0, 3))


def test_emissive_adds_to_every_lit_model():
    mat0 = sr.Material(metallic=0.4, roughness=0.7)
    mat1 = mat0.replace(emissive=(0.1, 0.2, 0.3))
    lights = [sun(unit(0.1, -0.2, -1), intensity=0.7)]
    for model in ("lambert", "phong", "blinn_phong", "pbr"):
        a = ref.radiance(model, Z, O, (0.5, 0.5, 0.5), mat0, lights, (0.1,) * 3, (0, 1, 3))
        b = ref.radiance(model, Z, O, (0.5, 0.5, 0.5), mat1, lights, (0.1,) * 3, (0, 1, 3))
        np.testing.assert_allclose(b - a, [[0.1, 0.2, 0.3]], atol=1e-15)


# -------------------------------------------------------------------------------- encodings

def test_srgb_curve_known_points():
    assert ref.srgb_encode(0.0) == 0 and ref.srgb_encode(1.0) == 255
    assert ref.srgb_encode(-1.0) == 0 and ref.srgb_encode(7.0) == 255
    assert ref.srgb_encode(0.5) == 188       # 0.7353569 * 255 = 187.52
    assert abs(int(ref.srgb_encode(0.214)) - 128) <= 1              # 0.214 -> 0.50002
    assert ref.srgb_encode(0.18) == 118                             # middle grey: 0.4613561
    # the linear segment and the knee: both branches give 0.040450 at x = 0.0031308
    assert ref.srgb_encode(0.0031308) == 10                         # 10.315
    lin = 12.92 * 0.0031308
    pw = 1.055 * 0.0031308 ** (1 / 2.4) - 0.055
    assert abs(lin - pw) < 1e-7
    assert ref.srgb_encode(0.001) == 3                              # 12.92e-3 * 255 = 3.29
    # monotone, every code reached
    codes = ref.srgb_encode(np.linspace(0, 1, 200001))
    assert np.all(np.diff(codes.astype(int)) >= 0) and len(np.unique(codes)) == 256
    # the inverse (decode) of each code, re-encoded, is the code
    c = np.arange(256) / 255.0
    dec = np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)
    np.testing.assert_array_equal(ref.srgb_encode(dec), np.arange(256))


def test_linear_and_pyrender_encodings():
    assert ref.linear_encode(0.5) == 128 and ref.linear_encode(0.5 / 255) == 1
    assert ref.linear_encode(0.49 / 255) == 0 and ref.linear_encode(2.0) == 255
    assert ref.linear_encode(-0.5) == 0
    np.testing.assert_array_equal(ref.linear_encode(np.arange(256) / 255.0), np.arange(256))
    assert ref.pyrender_encode(0.5) == round(255 * 0.5 ** (1 / 2.2))  # 186
    assert ref.srgb_encode(np.float32(0.5)).dtype == np.uint8


# ------------------------------------------------------------------------------- unproject

@pytest.mark.parametrize("kind", ["perspective", "orthographic", "intrinsics"])
def test_unproject_round_trip(kind):
    w, h = 64, 48
    if kind == "perspective":
        cam = sr.PerspectiveCamera(fov_y=50.0, near=0.1, far=20.0)
    elif kind == "orthographic":
        cam = sr.OrthographicCamera(xmag=2.0, ymag=1.5, near=0.1, far=20.0)
    else:
        cam = sr.IntrinsicsCamera(fx=70.0, fy=65.0, cx=30.0, cy=26.0, width=w, height=h,
                                  near=0.1, far=20.0)
    cam.look_at((0.3, 1.0, 4.0), (0.0, 0.0, 0.0))
    view, proj = cam._render_matrices(w, h)
    rng = np.random.default_rng(0)
    rows, cols = rng.integers(0, h, 50), rng.integers(0, w, 50)
    depth = np.zeros((h, w))
    depth[rows, cols] = rng.uniform(1.0, 8.0, 50)
    pw = ref.unproject(depth, view, proj, rows, cols)
    # project back: the pixel centre and the depth
    pv = np.c_[pw, np.ones(50)] @ np.asarray(view).T
    clip = pv @ np.asarray(proj).T
    ndc = clip[:, :2] / clip[:, 3:]
    np.testing.assert_allclose((ndc[:, 0] + 1) / 2 * w, cols + 0.5, atol=1e-9)
    np.testing.assert_allclose((1 - ndc[:, 1]) / 2 * h, rows + 0.5, atol=1e-9)
    np.testing.assert_allclose(-pv[:, 2], depth[rows, cols], atol=1e-12)
