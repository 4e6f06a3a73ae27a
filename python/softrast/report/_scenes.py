"""The report's scenes: the sphere (``_Sphere``: its exact references, meshes, materials and
metrics; the sphere over a backdrop casting a shadow) and the grazing checkerboard
(``_Checker``), with the colour metrics both use."""
from __future__ import annotations

import math
from typing import Any, Sequence

import numpy as np

from ..camera import PerspectiveCamera
from ..light import DirectionalLight
from ..material import Material
from ..mesh import Mesh
from ..scene import Scene
from ..texture import Texture
from ._common import _require
from ._references import (GrazingPlane, checker_box_filter, disk_coverage, shade, sphere_hit,
                          sphere_radius_px)


# The sphere scene: a unit sphere 5 units in front of the camera (its silhouette fills ~3/4 of
# the image height), one grey directional light from the upper left front and an ambient light,
# so a white lambert sphere's radiance is in [0.2, 1] on its lit side.
_FOV = 30.0
_DISTANCE = 5.0
_LIGHT_DIR = tuple(np.array([-1.0, 1.0, 1.0]) / math.sqrt(3.0))  # towards the light
_LIGHT = 0.8
_AMBIENT = 0.2
_MODELS = ("lambert", "phong", "blinn_phong", "pbr", "normal")  # those with a closed form here


def _light_pose(direction: Sequence[float]) -> np.ndarray:
    """A light pose whose +z axis is ``direction`` (unit, towards the light): lights shine
    along their -z."""
    z = np.asarray(direction, dtype=np.float64)
    x = np.cross((0.0, 1.0, 0.0), z)
    x /= np.linalg.norm(x)
    pose = np.eye(4)
    pose[:3, 0], pose[:3, 1], pose[:3, 2] = x, np.cross(z, x), z
    return pose


def _angle_deg(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Angles in degrees between rows of unit vectors: 2 atan2(|a - b|, |a + b|), accurate for
    small angles (arccos of the dot product is not, below ~0.03 degrees)."""
    return np.degrees(2.0 * np.arctan2(np.linalg.norm(a - b, axis=-1), np.linalg.norm(a + b, axis=-1)))


def _sphere_camera(width: int, height: int) -> Any:
    """The sphere scene's camera: at (0, 0, _DISTANCE) looking down -z at the origin."""
    camera = PerspectiveCamera(fov_y=_FOV, width=width, height=height, near=0.1, far=100.0)
    pose = np.eye(4)
    pose[2, 3] = _DISTANCE
    camera.pose = pose
    return camera


def _icosphere(subdivisions: int, uvs: bool = False) -> Any:
    """A trimesh icosphere as a softrast Mesh with its exact normals (its vertices, which lie on
    the unit sphere) and, if asked, longitude-latitude uvs."""
    import trimesh

    tm = trimesh.creation.icosphere(subdivisions=subdivisions)
    v = np.asarray(tm.vertices)
    uv = None
    if uvs:
        uv = np.stack([np.arctan2(v[:, 0], v[:, 2]) / (2.0 * math.pi) + 0.5,
                       np.arcsin(np.clip(v[:, 1], -1.0, 1.0)) / math.pi + 0.5], axis=1)
    return Mesh(v, tm.faces, normals=v, uvs=uv)


class _Sphere:
    """The sphere scene at one image size: its exact references (computed once) and meshes."""

    reference_coverage = "exact disk area per pixel"
    reference_points = "exact disk, pixel centres"
    reference_hit = "exact ray-sphere hit, pixel centres"

    def __init__(self, width: int, height: int) -> None:
        self.width, self.height = width, height
        self.radius_px = sphere_radius_px(_FOV, height, _DISTANCE)
        self.coverage = disk_coverage(width, height, self.radius_px)
        self.depth, self.position, self.normal = sphere_hit(width, height, _FOV, _DISTANCE)
        self.inside = self.depth > 0.0
        self.camera = _sphere_camera(width, height)
        self._meshes: dict[int, Any] = {}
        self._colour: dict[str, np.ndarray] = {}

    def mesh(self, subdivisions: int) -> Any:
        """The icosphere (trimesh) as a softrast Mesh with its exact normals (the vertices)."""
        if subdivisions not in self._meshes:
            self._meshes[subdivisions] = _icosphere(subdivisions)
        return self._meshes[subdivisions]

    @staticmethod
    def material(model: str = "lambert") -> Any:
        return Material(base_color=(1.0, 1.0, 1.0), ks=(0.5, 0.5, 0.5), shininess=32.0,
                        roughness=0.5, metallic=0.0, model=model)

    def scene(self, subdivisions: int, model: str = "lambert") -> Any:
        scene = Scene(ambient_light=(_AMBIENT,) * 3)
        scene.add(self.mesh(subdivisions), material=self.material(model))
        scene.add(DirectionalLight(intensity=_LIGHT), pose=_light_pose(_LIGHT_DIR))
        return scene

    def colour(self, model: str) -> np.ndarray:
        """(h, w, 3) float64: the model's closed form at each pixel centre's hit, 0 = miss."""
        if model not in self._colour:
            c = shade(model, self.normal, self.position, (0.0, 0.0, _DISTANCE), _LIGHT_DIR, _LIGHT,
                      _AMBIENT, self.material(model))
            self._colour[model] = np.where(self.inside[..., None], c, 0.0)
        return self._colour[model]

    def camera_args(self) -> dict[str, Any]:
        f = (self.height / 2.0) / math.tan(math.radians(_FOV) / 2.0)
        return {"fx": f, "fy": f, "cx": self.width / 2.0, "cy": self.height / 2.0,
                "width": self.width, "height": self.height, "near": 0.1, "far": 100.0,
                "pose": np.asarray(self.camera.pose)}

    def geometry_metrics(self, frame: Any) -> list[tuple[str, float, str, str, str]]:
        """(metric, error, unit, reference, better) of coverage, depth and normals."""
        mask = frame.mask
        err = np.abs(mask - self.coverage)
        considered = ((self.coverage > 0.0) & (self.coverage < 1.0)) | (err > 0.0)
        area = math.pi * self.radius_px ** 2
        both = mask & self.inside
        d_err = np.abs(frame.depth[both].astype(np.float64) - self.depth[both])
        n_render = frame.normal[both].astype(np.float64)
        n_render /= np.linalg.norm(n_render, axis=-1, keepdims=True)
        angles = _angle_deg(n_render, self.normal[both])
        cov, pts, hit = self.reference_coverage, self.reference_points, self.reference_hit
        return [
            ("coverage_mean", float(err[considered].mean()), "pixel fraction", cov, "lower"),
            ("coverage_max", float(err.max()), "pixel fraction", cov, "lower"),
            ("area_rel", abs(float(mask.sum()) - area) / area, "relative", cov, "lower"),
            ("mask_mismatch_px", float(np.count_nonzero(mask != self.inside)), "pixels", pts, "lower"),
            ("depth_mean", float(d_err.mean()), "scene units", hit, "lower"),
            ("depth_max", float(d_err.max()), "scene units", hit, "lower"),
            ("depth_rel_max", float((d_err / self.depth[both]).max()), "relative", hit, "lower"),
            ("normal_mean_deg", float(angles.mean()), "degrees", hit, "lower"),
            ("normal_max_deg", float(angles.max()), "degrees", hit, "lower"),
        ]


def _colour_metrics(image: np.ndarray, reference: np.ndarray, label: str,
                    region: np.ndarray | None = None) -> list[tuple[str, float, str, str, str]]:
    """(metric, error, unit, reference, better): RMSE, max error, PSNR and SSIM (scikit-image)
    of a grey linear image against its reference, over ``region`` (default: every pixel).

    The scenes are grey (white light, white or black-and-white materials), so one channel is
    compared. data_range is the reference's range. SSIM is computed on the region's bounding
    box with the pixels outside the region taken from the reference (they add no error)."""
    metrics = _require("skimage.metrics", "scikit-image")
    img = np.asarray(image, dtype=np.float64)
    ref = np.asarray(reference, dtype=np.float64)
    img = img[..., 0] if img.ndim == 3 else img
    ref = ref[..., 0] if ref.ndim == 3 else ref
    if region is None:
        region = np.ones(ref.shape, dtype=bool)
    data_range = float(ref[region].max() - min(ref[region].min(), 0.0))
    diff = img[region] - ref[region]
    psnr = metrics.peak_signal_noise_ratio(ref[region], img[region], data_range=data_range)
    rows, cols = np.nonzero(region)
    box = (slice(rows.min(), rows.max() + 1), slice(cols.min(), cols.max() + 1))
    ssim = metrics.structural_similarity(ref[box], np.where(region, img, ref)[box], data_range=data_range)
    return [("rmse", float(np.sqrt(np.mean(diff ** 2))), "linear radiance", label, "lower"),
            ("max_abs", float(np.abs(diff).max()), "linear radiance", label, "lower"),
            ("psnr_db", float(psnr), "dB", label, "higher"),
            ("ssim", float(ssim), "", label, "higher")]


class _Checker:
    """The grazing checkerboard at one image size: the exact box-filtered reference and a scene
    per texture (one per max_anisotropy)."""

    reference = "exact box filter of the checker function"

    def __init__(self, width: int, height: int) -> None:
        self.plane = GrazingPlane()
        self.width, self.height = width, height
        self.image, self.full = checker_box_filter(self.plane, width, height)
        self.camera = PerspectiveCamera(fov_y=self.plane.fov_y, width=width, height=height, near=0.05, far=50.0)
        self.camera.pose = self.plane.pose()
        self._texels = self.plane.texture_image()

    def scene(self, max_anisotropy: int = 16) -> Any:
        h = self.plane.half
        texture = Texture(self._texels, srgb=False, max_anisotropy=max_anisotropy)
        plane = Mesh([[-h, 0, -h], [h, 0, -h], [h, 0, h], [-h, 0, h]], [[0, 2, 1], [0, 3, 2]],
                     uvs=[[0, 1], [1, 1], [1, 0], [0, 0]],
                     material=Material(base_color=(1, 1, 1), base_color_texture=texture, model="unlit"))
        scene = Scene()
        scene.add(plane)
        return scene

    def metrics(self, frame: Any) -> list[tuple[str, float, str, str, str]]:
        return _colour_metrics(frame.radiance, self.image, self.reference, region=self.full)


def _shadow_scene(sphere: _Sphere, subdivisions: int, shadows: Any, resolution: int = 2048) -> Any:
    """The sphere (lambert) over a backdrop plane at z = -1.2 facing the camera, its light
    casting ``shadows``: the sphere's shadow falls on the backdrop's lower right."""
    scene = Scene(ambient_light=(_AMBIENT,) * 3)
    scene.add(sphere.mesh(subdivisions), material=sphere.material("lambert"))
    h, z = 3.0, -1.2
    scene.add(Mesh([[-h, -h, z], [h, -h, z], [h, h, z], [-h, h, z]], [[0, 1, 2], [0, 2, 3]]),
              material=Material(base_color=(1.0, 1.0, 1.0), model="lambert"))
    scene.add(DirectionalLight(intensity=_LIGHT, shadows=shadows, shadow_resolution=resolution),
              pose=_light_pose(_LIGHT_DIR))
    return scene
