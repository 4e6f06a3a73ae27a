"""softrast.displace: geometric displacement by a height texture, against closed
forms on a sphere."""
from __future__ import annotations

import numpy as np
import pytest
import trimesh

import softrast as sr


def sphere_with_uvs(subdivisions: int = 3) -> sr.Mesh:
    tm = trimesh.creation.icosphere(subdivisions=subdivisions, radius=1.0)
    p = np.asarray(tm.vertices)
    uv = np.c_[np.arctan2(p[:, 2], p[:, 0]) / (2 * np.pi) + 0.5, np.arcsin(np.clip(p[:, 1], -1, 1)) / np.pi + 0.5]
    return sr.Mesh(p, tm.faces, normals=p, uvs=uv)


def test_height_linear_in_v_moves_along_the_normal() -> None:
    """height(v) = v (a float texture linear in v, clamped): r' = 1 + scale * v exactly where
    bilinear interpolation is exact (between the first and last texel centres)."""
    h = 256
    img = (1.0 - (np.arange(h) + 0.5) / h).astype(np.float32).reshape(h, 1, 1)
    tex = sr.Texture(img, wrap="clamp")
    mesh = sphere_with_uvs()
    out = sr.displace(mesh, tex, scale=0.3)
    v = mesh.uvs[:, 1].astype(np.float64)
    inner = (v > 0.5 / h) & (v < 1 - 0.5 / h)
    r = np.linalg.norm(out.positions.astype(np.float64), axis=1)
    np.testing.assert_allclose(r[inner], 1.0 + 0.3 * v[inner], rtol=0, atol=3e-6)
    assert out.num_faces == mesh.num_faces and out.normals is not None


def test_constant_height_with_subdivision_and_midlevel() -> None:
    tex = sr.Texture(np.full((4, 4, 1), 0.75, np.float32))
    mesh = sphere_with_uvs(2)
    out = sr.displace(mesh, tex, scale=0.2, subdivisions=2, midlevel=0.25)
    assert out.num_faces == 16 * mesh.num_faces
    # the original vertices come first and stay on the sphere of radius 1 + 0.2 * 0.5
    r = np.linalg.norm(out.positions[: mesh.num_vertices].astype(np.float64), axis=1)
    np.testing.assert_allclose(r, 1.1, rtol=0, atol=2e-6)
    # every vertex moved by 0.1 along its interpolated unit normal (scale 0: the subdivided mesh)
    base = sr.displace(mesh, tex, scale=0.0, subdivisions=2)
    step = out.positions.astype(np.float64) - base.positions.astype(np.float64)
    np.testing.assert_allclose(np.linalg.norm(step, axis=1), 0.1, rtol=0, atol=2e-6)
    assert (np.einsum("ij,ij->i", step, base.positions) > 0).all()  # outward


def test_displaced_silhouette_area() -> None:
    """A sphere displaced by a constant renders a disk of the new radius (orthographic)."""
    tex = sr.Texture(np.full((2, 2, 1), 255, np.uint8), srgb=False)
    out = sr.displace(sphere_with_uvs(4), tex, scale=0.5)
    scene = sr.Scene()
    scene.add(out)
    cam = sr.OrthographicCamera(xmag=2.0, ymag=2.0, width=256, height=256)
    pose = np.eye(4)
    pose[2, 3] = 5.0
    cam.pose = pose
    mask = sr.Renderer(256, 256).render(scene, cam, outputs=("mask",)).mask
    area = mask.sum() * (4.0 / 256) ** 2
    assert abs(area - np.pi * 1.5 ** 2) / (np.pi * 1.5 ** 2) < 0.01  # icosphere(4) facets


def test_bad_arguments() -> None:
    mesh = sphere_with_uvs(1)
    tex = sr.Texture(np.zeros((2, 2, 1), np.float32))
    with pytest.raises(ValueError, match="uvs"):
        sr.displace(sr.Mesh(mesh.positions, mesh.faces), tex, 1.0)
    with pytest.raises(TypeError, match="texture"):
        sr.displace(mesh, np.zeros((2, 2)), 1.0)
    with pytest.raises(ValueError, match="scale"):
        sr.displace(mesh, tex, float("nan"))
    with pytest.raises(ValueError, match="subdivisions"):
        sr.displace(mesh, tex, 1.0, subdivisions=-1)


def test_scale_that_moves_vertices_beyond_float32_names_scale() -> None:
    """A finite scale whose displaced positions overflow float32 is an error naming
    ``scale`` (it once blamed ``positions``, an argument the caller never gave)."""
    import warnings

    mesh = sphere_with_uvs(1)
    tex = sr.Texture(np.full((2, 2, 1), 0.5, np.float32))
    for scale in (1e300, -1e300, 1e39):
        with warnings.catch_warnings():
            warnings.simplefilter("error")  # and no overflow RuntimeWarning on the way
            with pytest.raises(ValueError, match=r"^scale") as info:
                sr.displace(mesh, tex, scale)
        assert "positions" not in str(info.value)
    # a zero height difference moves nothing, whatever the scale
    out = sr.displace(mesh, tex, 1e300, midlevel=0.5)
    np.testing.assert_array_equal(out.positions, mesh.positions)
