"""Conversions from pyrender scenes (``softrast.from_pyrender``).

pyrender is never imported here: its objects are read by their attributes (duck typing), so
softrast works without pyrender installed, and a pyrender scene converts without an OpenGL
context. What is converted, and how (pyrender 0.1.45's attribute names):

* Meshes: every visible mesh node, each ``Primitive`` (mode 4, triangles) -> one ``sr.Mesh``
  (``positions``, ``normals``, ``indices`` (None: consecutive triples), ``texcoord_0`` -> uvs,
  ``color_0`` -> per-vertex colours) placed by ``scene.get_pose(node)`` (world pose), once per
  instancing pose in ``primitive.poses`` if any. Without normals softrast computes smooth ones.
* Materials: ``MetallicRoughnessMaterial`` -> ``sr.Material(model="pbr")`` with
  ``baseColorFactor``, ``metallicFactor``, ``roughnessFactor``, ``emissiveFactor`` (clipped to
  [0, 1]) and ``doubleSided``. A ``color_0`` is multiplied by ``baseColorFactor`` (glTF's rule);
  pyrender instead multiplies its shaded colour by ``color_0``, so with ``pbr`` shading and
  vertex colours the colours differ (geometry does not). Textures (``baseColorTexture``,
  ``metallicRoughnessTexture``, ``normalTexture``, ``occlusionTexture``, ``emissiveTexture``:
  pyrender ``Texture`` objects, their ``source`` an array or a PIL image) become
  ``sr.Texture`` objects in the matching slots (one per pyrender texture), with the sampler's
  wraps (GL enums) and filter (nearest / bilinear without mipmaps, else trilinear); uvs keep
  pyrender's convention, image row 0 at v = 1 (``uv_origin="bottom_left"``). ``alphaMode``
  "MASK" and ``alphaCutoff`` -> ``alpha_mode="mask"``, ``alpha_cutoff`` (as a glTF file's; "BLEND"
  is rendered opaque, with a UserWarning). Any other
  material type gets softrast's default look, with a UserWarning.
* Lights: ``DirectionalLight`` / ``PointLight`` / ``SpotLight`` -> ``sr.DirectionalLight`` /
  ``sr.PointLight`` / ``sr.SpotLight`` with the same ``color`` and ``intensity`` (spot cones:
  ``innerConeAngle`` / ``outerConeAngle``, radians in both), posed by the node's world pose
  (both shine along their local -z); point and spot lights fall off as 1 / r^2 as pyrender's
  shader does (its ``range`` is not used by pyrender's shader either). ``scene.ambient_light``
  -> ``Scene.ambient_light``. A pyrender scene without lights converts to a softrast scene
  without lights, which softrast lights with its headlight (pyrender shows only the ambient
  light): add a light for the same look.
* The main camera (``scene.main_camera_node``, pose in OpenGL axes as in both libraries):
  ``PerspectiveCamera(yfov, znear, zfar, aspectRatio)`` -> ``sr.PerspectiveCamera(fov_y=
  degrees(yfov), near=znear, far=zfar, aspect=aspectRatio)`` (pyrender's ``yfov`` is RADIANS,
  softrast's ``fov_y`` DEGREES); ``IntrinsicsCamera(fx, fy, cx, cy, znear, zfar)`` ->
  ``sr.IntrinsicsCamera(..., convention="opengl")`` (exactly pyrender's projection);
  ``OrthographicCamera(xmag, ymag, znear, zfar)`` -> ``sr.OrthographicCamera``. pyrender allows
  ``zfar=None`` (an infinite far plane); softrast needs a finite one: twice the farthest
  distance of the scene's bounding-box corners along the viewing axis (at least 2 * znear).
"""
from __future__ import annotations

import math
import warnings
from typing import Any

import numpy as np

from .camera import Camera, IntrinsicsCamera, OrthographicCamera, PerspectiveCamera
from .light import DirectionalLight, Light, PointLight, SpotLight
from .loaders import _gltf_alpha
from .material import Material
from .mesh import Mesh
from .scene import Scene

__all__ = ["from_pyrender"]

_TRIANGLES = 4  # GL_TRIANGLES, pyrender's default primitive mode
# pyrender's texture attributes and softrast's slots.
_TEXTURES = {"baseColorTexture": "base_color_texture",
             "metallicRoughnessTexture": "metallic_roughness_texture",
             "normalTexture": "normal_texture", "occlusionTexture": "occlusion_texture",
             "emissiveTexture": "emissive_texture"}
_GL_WRAP = {10497: "repeat", 33071: "clamp", 33648: "mirror"}
_GL_NEAREST, _GL_LINEAR = 9728, 9729


def _texture(tex: Any, label: str, key: str, cache: dict[int, Any]) -> Any:
    """An sr.Texture for pyrender texture ``tex`` (made once per object), or None with a warning."""
    from .texture import Texture

    if id(tex) in cache:
        return cache[id(tex)]
    source = getattr(tex, "source", None)
    sampler = getattr(tex, "sampler", None)
    try:
        image = np.asarray(source)
        if image.dtype == np.float64:
            image = image.astype(np.float32)
        wrap = tuple(_GL_WRAP.get(getattr(sampler, k, 10497), "repeat") for k in ("wrapS", "wrapT"))
        min_filter = getattr(sampler, "minFilter", None)
        filt = {_GL_NEAREST: "nearest", _GL_LINEAR: "bilinear"}.get(min_filter, "trilinear")
        result = Texture(image, filter=filt, wrap=wrap)
    except (TypeError, ValueError) as e:
        warnings.warn(f"{label}: {key} is not drawn: {e}", UserWarning, stacklevel=4)
        result = None
    cache[id(tex)] = result
    return result


def _kind(obj: Any) -> str:
    """The pyrender class name of ``obj`` or of its first pyrender base class."""
    for cls in type(obj).__mro__:
        if cls.__module__.startswith("pyrender"):
            return cls.__name__
    return type(obj).__name__


def _unit(values: Any, n: int, default: tuple[float, ...]) -> tuple[float, ...]:
    if values is None:
        return default
    arr = np.clip(np.asarray(values, dtype=np.float64).reshape(-1)[:n], 0.0, 1.0)
    return tuple(float(v) for v in arr)


def _material(mat: Any, cache: dict[int, Any] | None = None) -> Material | None:
    kind = _kind(mat)
    name = getattr(mat, "name", None)
    label = f"pyrender material {name!r}" if isinstance(name, str) else "a pyrender material"
    if kind != "MetallicRoughnessMaterial":
        warnings.warn(f"{label}: a {kind} is not converted; the primitive gets softrast's default look",
                      UserWarning, stacklevel=3)
        return None
    cache = {} if cache is None else cache
    textures = {slot: _texture(getattr(mat, key), label, key, cache)
                for key, slot in _TEXTURES.items() if getattr(mat, key, None) is not None}
    dropped: list[str] = []
    alpha = _gltf_alpha(getattr(mat, "alphaMode", None), getattr(mat, "alphaCutoff", None), dropped)
    for what in dropped:
        warnings.warn(f"{label}: {what}", UserWarning, stacklevel=3)
    return Material(**textures, **alpha, base_color=_unit(getattr(mat, "baseColorFactor", None), 4, (1.0, 1.0, 1.0, 1.0)),
                    metallic=_unit(getattr(mat, "metallicFactor", 1.0), 1, (1.0,))[0],
                    roughness=_unit(getattr(mat, "roughnessFactor", 1.0), 1, (1.0,))[0],
                    emissive=_unit(getattr(mat, "emissiveFactor", None), 3, (0.0, 0.0, 0.0)),
                    double_sided=bool(getattr(mat, "doubleSided", False)), model="pbr",
                    name=name if isinstance(name, str) else None)


def _mesh(prim: Any, cache: dict[int, Any]) -> Mesh:
    mode = getattr(prim, "mode", _TRIANGLES)
    if mode != _TRIANGLES:
        raise ValueError(f"only triangle primitives (mode 4) are converted, got mode {mode}")
    positions = np.asarray(prim.positions, dtype=np.float64)
    indices = getattr(prim, "indices", None)
    if indices is None:
        if len(positions) % 3:
            raise ValueError(f"a primitive without indices needs a multiple of 3 positions, got {len(positions)}")
        faces = np.arange(len(positions), dtype=np.int64).reshape(-1, 3)
    else:
        faces = np.asarray(indices).reshape(-1, 3).astype(np.int64)
    normals = getattr(prim, "normals", None)
    uvs = getattr(prim, "texcoord_0", None)
    material = (_material(prim.material, cache) if getattr(prim, "material", None) is not None
                else None)
    colors = getattr(prim, "color_0", None)
    if colors is not None:
        colors = np.clip(np.asarray(colors, dtype=np.float64), 0.0, 1.0)
        if colors.shape[1] == 3:
            colors = np.hstack([colors, np.ones((len(colors), 1))])
        if material is not None:
            colors = colors * np.asarray(material.base_color)
    kwargs: dict[str, Any] = dict(normals=None if normals is None else np.asarray(normals),
                                  uvs=None if uvs is None else np.asarray(uvs)[:, :2], colors=colors)
    if material is not None:
        kwargs["material"] = material
    return Mesh(positions, faces, **kwargs)


def _light(light: Any) -> Light:
    kind = _kind(light)
    color = tuple(float(c) for c in np.asarray(light.color, dtype=np.float64).reshape(3))
    intensity = float(light.intensity)
    if kind == "DirectionalLight":
        return DirectionalLight(color, intensity)
    if kind == "PointLight":
        return PointLight(color, intensity, falloff="inverse_square")
    if kind == "SpotLight":
        return SpotLight(color, intensity, inner_cone=float(light.innerConeAngle),
                         outer_cone=float(light.outerConeAngle), falloff="inverse_square")
    raise ValueError(f"unknown pyrender light type {kind}")


def _far(zfar: Any, znear: float, scene: Scene, cam_pose: np.ndarray) -> float:
    if zfar is not None:
        return float(zfar)
    far = 2.0 * znear
    if len(scene):
        lo, hi = scene.bounds
        corners = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])
        along = (corners - cam_pose[:3, 3]) @ -cam_pose[:3, 2]  # distance along the viewing axis
        far = max(far, 2.0 * float(along.max()))
    return far


def _camera(cam: Any, width: int, height: int, scene: Scene, pose: np.ndarray) -> Camera:
    kind = _kind(cam)
    znear = float(cam.znear)
    far = _far(getattr(cam, "zfar", None), znear, scene, pose)
    out: Camera
    if kind == "PerspectiveCamera":
        aspect = getattr(cam, "aspectRatio", None)
        out = PerspectiveCamera(fov_y=math.degrees(float(cam.yfov)), width=width, height=height,
                                near=znear, far=far, aspect=None if aspect is None else float(aspect))
    elif kind == "IntrinsicsCamera":
        out = IntrinsicsCamera(float(cam.fx), float(cam.fy), float(cam.cx), float(cam.cy), width, height,
                               near=znear, far=far, convention="opengl")
    elif kind == "OrthographicCamera":
        out = OrthographicCamera(float(cam.xmag), float(cam.ymag), width=width, height=height,
                                 near=znear, far=far)
    else:
        raise ValueError(f"unknown pyrender camera type {kind}")
    out.pose = pose
    return out


def from_pyrender(pyrender_scene: Any, width: int, height: int) -> tuple[Scene, Camera | None]:
    """Convert a ``pyrender.Scene`` to ``(softrast.Scene, camera)`` (see this module's docstring).

    width, height : the image size (pyrender cameras carry none; ``OffscreenRenderer`` takes it).
    The camera is the scene's main camera converted, or None if the scene has no camera.
    Instance ids are 0, 1, 2, ... in the order of ``pyrender_scene.mesh_nodes`` (sorted by node
    name, then primitive, then instancing pose, for a stable order: pyrender keeps them in a set).
    """
    ambient = getattr(pyrender_scene, "ambient_light", None)
    scene = Scene(ambient_light=None if ambient is None else
                  tuple(float(v) for v in np.asarray(ambient, dtype=np.float64).reshape(3)))
    nodes = sorted(pyrender_scene.mesh_nodes, key=lambda n: (str(n.name), id(n)))
    textures: dict[int, Any] = {}  # one sr.Texture per pyrender texture
    for node in nodes:
        mesh = node.mesh
        if not getattr(mesh, "is_visible", True):
            continue
        world = np.asarray(pyrender_scene.get_pose(node), dtype=np.float64)
        for prim in mesh.primitives:
            converted = _mesh(prim, textures)
            poses = getattr(prim, "poses", None)
            for local in ([np.eye(4)] if poses is None else np.asarray(poses, dtype=np.float64)):
                scene.add(converted, pose=world @ local)
    for node in sorted(pyrender_scene.light_nodes, key=lambda n: (str(n.name), id(n))):
        scene.add(_light(node.light), pose=np.asarray(pyrender_scene.get_pose(node), dtype=np.float64))
    cam_node = getattr(pyrender_scene, "main_camera_node", None)
    camera = None
    if cam_node is not None:
        camera = _camera(cam_node.camera, width, height, scene,
                         np.asarray(pyrender_scene.get_pose(cam_node), dtype=np.float64))
    return scene, camera
