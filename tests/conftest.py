"""Shared fixtures and small geometry helpers for the rendering tests.

Coordinate conventions (from softrast/_core.pyi): view space x right, y up, looking down -z;
window x = (ndc_x + 1) / 2 * W, y = (1 - ndc_y) / 2 * H; pixel (i, j) centre = (j + 0.5, i + 0.5).
"""
from __future__ import annotations

import math
import pathlib

import numpy as np
import pytest
import trimesh

import softrast as sr

ROOT = pathlib.Path(__file__).resolve().parents[1]
SPOT_PATH = ROOT / "assets" / "meshes" / "spot.obj"
ALL_OUTPUTS = sr.OUTPUTS  # from the core's output table
Z_PLANE = -10.0  # depth of geometry drawn in "pixel space" with pixel_ortho()


@pytest.fixture
def rng() -> np.random.Generator:
    return np.random.default_rng(20240607)


@pytest.fixture(scope="session")
def spot() -> sr.Mesh:
    return sr.load_mesh(str(SPOT_PATH))


def icosphere(subdivisions: int, radius: float = 1.0) -> sr.Mesh:
    """A closed convex mesh with outward (counter-clockwise) faces, vertices on the sphere."""
    m = trimesh.creation.icosphere(subdivisions=subdivisions, radius=radius)
    return sr.Mesh(np.asarray(m.vertices), np.asarray(m.faces))


def pixel_ortho(width: int, height: int) -> sr.OrthographicCamera:
    """Orthographic camera at the origin (identity pose) where one world unit = one pixel.

    A world point (X, Y, Z) lands at window (X + W/2, H/2 - Y); see window_to_world.
    """
    cam = sr.OrthographicCamera(xmag=width / 2.0, ymag=height / 2.0, near=1.0, far=100.0)
    cam.pose = np.eye(4)
    return cam


def window_to_world(xy_window: np.ndarray, width: int, height: int, z: float = Z_PLANE) -> np.ndarray:
    """Inverse of pixel_ortho's projection: (n, 2) window coordinates -> (n, 3) world points."""
    xy = np.asarray(xy_window, dtype=np.float64)
    return np.stack([xy[:, 0] - width / 2.0, height / 2.0 - xy[:, 1], np.full(len(xy), z)], axis=1)


def pixel_mesh(xy_window: np.ndarray, faces: np.ndarray, width: int, height: int, **kw) -> sr.Mesh:
    return sr.Mesh(window_to_world(xy_window, width, height), np.asarray(faces, dtype=np.int64), **kw)


def scene_of(*meshes: sr.Mesh) -> sr.Scene:
    scene = sr.Scene()
    for k, m in enumerate(meshes):
        scene.add(m, instance_id=k)
    return scene


def render(scene, cam, width: int, height: int, outputs=ALL_OUTPUTS, threads: int = 0, **kw):
    return sr.Renderer(width, height, threads=threads).render(scene, cam, outputs=outputs, **kw)


def look_at_gl(eye, target, up=(0.0, 1.0, 0.0)) -> np.ndarray:
    """Independent OpenGL camera-to-world pose: columns x right, y up, z back, translation eye."""
    eye, target, up = (np.asarray(v, dtype=np.float64) for v in (eye, target, up))
    z = eye - target
    z /= np.linalg.norm(z)
    x = np.cross(up, z)
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    pose = np.eye(4)
    pose[:3, 0], pose[:3, 1], pose[:3, 2], pose[:3, 3] = x, y, z, eye
    return pose


def random_rotation(rng: np.random.Generator) -> np.ndarray:
    q, r = np.linalg.qr(rng.normal(size=(3, 3)))
    q = q * np.sign(np.diag(r))
    if np.linalg.det(q) < 0:
        q[:, 0] = -q[:, 0]
    return q


def pixel_rays_view(width: int, height: int, fov_y_deg: float) -> np.ndarray:
    """(h, w, 3) view-space ray directions through pixel centres, scaled so that z = -1.

    A point at parameter t on the ray has depth (-z_view) exactly t.
    """
    t = math.tan(math.radians(fov_y_deg) / 2.0)
    jj, ii = np.meshgrid(np.arange(width) + 0.5, np.arange(height) + 0.5)
    dx = (2.0 * jj / width - 1.0) * t * (width / height)
    dy = (1.0 - 2.0 * ii / height) * t
    return np.stack([dx, dy, -np.ones_like(dx)], axis=-1)


def view_to_window_persp(p_view: np.ndarray, width: int, height: int, fov_y_deg: float) -> np.ndarray:
    """(n, 3) view-space points -> (n, 2) window coordinates for a gluPerspective camera."""
    t = math.tan(math.radians(fov_y_deg) / 2.0)
    p = np.asarray(p_view, dtype=np.float64)
    ndc_x = p[:, 0] / (-p[:, 2]) / (t * width / height)
    ndc_y = p[:, 1] / (-p[:, 2]) / t
    return np.stack([(ndc_x + 1.0) / 2.0 * width, (1.0 - ndc_y) / 2.0 * height], axis=1)


def window_to_view_persp(xy_window: np.ndarray, depth: np.ndarray, width: int, height: int,
                         fov_y_deg: float) -> np.ndarray:
    """Inverse of view_to_window_persp: window points at given depths (-z_view) -> view space."""
    t = math.tan(math.radians(fov_y_deg) / 2.0)
    xy = np.asarray(xy_window, dtype=np.float64)
    d = np.asarray(depth, dtype=np.float64) * np.ones(len(xy))
    ndc_x = 2.0 * xy[:, 0] / width - 1.0
    ndc_y = 1.0 - 2.0 * xy[:, 1] / height
    return np.stack([ndc_x * t * width / height * d, ndc_y * t * d, -d], axis=1)


def core_options(view, proj, orthographic: bool, near: float, far: float, outputs, **kw) -> dict:
    """A render's options as the core reads them (``_core.RENDER_OPTIONS``): the required ones,
    and any others by name (the core gives the rest their defaults). For tests that call
    ``_core.Renderer.render`` directly, bypassing render.py's checks."""
    return dict(view=np.asarray(view, np.float64), proj=np.asarray(proj, np.float64),
                orthographic=bool(orthographic), near=float(near), far=float(far),
                outputs=list(outputs), **kw)


def nv_clip_scene(rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """softrast.nv's input (pos (2, n, 4) float32 clip space, tri (m, 3) int32) exercising every
    raster path of ``_core._rasterize_clip``: an icosphere's small triangles at two poses, random
    triangles of every size crossing the near and far planes and w = 0 (clipped), and a floor
    reaching far past the image (the guard band) and behind the eye."""
    t = 1.0 / math.tan(math.radians(30.0))
    n, f = 0.1, 20.0
    proj = np.array([[t, 0, 0, 0], [0, t, 0, 0], [0, 0, -(f + n) / (f - n), -2 * f * n / (f - n)],
                     [0, 0, -1, 0]])
    sphere = trimesh.creation.icosphere(subdivisions=4)
    floor = np.array([[-500.0, -1.0, -500.0], [500.0, -1.0, -500.0], [500.0, -1.0, 50.0], [-500.0, -1.0, 50.0]])
    soup = (rng.uniform([-2.0, -1.5, -6.0], [2.0, 1.5, 0.5], (30, 1, 3))
            + rng.uniform(-1.5, 1.5, (30, 3, 3))).reshape(90, 3)
    points = np.concatenate([sphere.vertices + [0.3, 0.0, -3.0], floor, soup])
    tri = np.concatenate([sphere.faces, np.array([[0, 1, 2], [0, 2, 3]]) + len(sphere.vertices),
                          np.arange(90).reshape(-1, 3) + len(sphere.vertices) + 4]).astype(np.int32)
    pos = []
    for angle in (0.0, 0.4):
        c, s = math.cos(angle), math.sin(angle)
        model = np.array([[c, 0, s, 0], [0, 1, 0, 0], [-s, 0, c, 0], [0, 0, 0, 1]])
        pos.append(np.c_[points, np.ones(len(points))] @ (proj @ model).T)
    return np.asarray(pos, np.float32), tri
