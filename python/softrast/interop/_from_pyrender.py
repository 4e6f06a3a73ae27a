"""``from_pyrender``: a ``pyrender.Scene`` as a softrast Scene, its main camera and background
(a ``PyrenderConversion``). pyrender is never imported: its objects are read by their
attributes (duck typing, pyrender 0.1.45's names), so no OpenGL context is needed. See
docs/interop.md."""
from __future__ import annotations

import math
import warnings
from typing import Any

import numpy as np

from ..camera import Camera, IntrinsicsCamera, OrthographicCamera, PerspectiveCamera
from ..light import DirectionalLight, Light, PointLight, SpotLight
from ..files.gltf import _gltf_alpha
from ..material import Material
from ..mesh import Mesh
from ..primitives import Lines, Points
from ..scene import Scene
from ..texture import Texture
from ._gl import _GL_LINEAR, _GL_NEAREST, _GL_WRAP, _LINES, _POINTS, _TRIANGLES

# pyrender's texture attributes and softrast's slots.
_TEXTURES = {"baseColorTexture": "base_color_texture",
             "metallicRoughnessTexture": "metallic_roughness_texture",
             "normalTexture": "normal_texture", "occlusionTexture": "occlusion_texture",
             "emissiveTexture": "emissive_texture"}


def _texture(tex: Any, label: str, key: str, cache: dict[int, Any]) -> Any:
    """An sr.Texture for pyrender texture ``tex`` (made once per object), or None with a warning."""
    if id(tex) in cache:
        return cache[id(tex)]
    source = getattr(tex, "source", None)
    sampler = getattr(tex, "sampler", None)
    try:
        image = np.asarray(source)
        if image.dtype == np.float64:
            image = image.astype(np.float32)
        if image.ndim == 3 and image.shape[2] == 2 and getattr(tex, "source_channels", None) == "GB":
            # pyrender keeps only G and B of a metallic-roughness texture: RGB (0, G, B), not
            # softrast's grey + alpha reading of two channels.
            image = np.concatenate([np.zeros_like(image[:, :, :1]), image], axis=2)
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
    # "BLEND" is opaque here: _mesh makes it "blend" where the primitive reads an alpha < 1.
    mode = getattr(mat, "alphaMode", None)
    alpha = _gltf_alpha(None if mode == "BLEND" else mode, getattr(mat, "alphaCutoff", None), dropped)
    for what in dropped:
        warnings.warn(f"{label}: {what}", UserWarning, stacklevel=3)
    return Material(**textures, **alpha, base_color=_unit(getattr(mat, "baseColorFactor", None), 4, (1.0, 1.0, 1.0, 1.0)),
                    metallic=_unit(getattr(mat, "metallicFactor", 1.0), 1, (1.0,))[0],
                    roughness=_unit(getattr(mat, "roughnessFactor", 1.0), 1, (1.0,))[0],
                    emissive=_unit(getattr(mat, "emissiveFactor", None), 3, (0.0, 0.0, 0.0)),
                    double_sided=bool(getattr(mat, "doubleSided", False)), model="pbr",
                    name=name if isinstance(name, str) else None)


def _primitive(prim: Any) -> Points | Lines:
    """pyrender points (mode 0) or lines (mode 1: each pair of positions, or of indices, a
    segment) as softrast Points / Lines, with their vertex colours (RGB; 1 px, unlit)."""
    positions = np.asarray(prim.positions, dtype=np.float64)
    colors = getattr(prim, "color_0", None)
    if colors is not None:
        colors = np.asarray(colors)
        colors = colors[:, :3] if colors.dtype == np.uint8 else np.clip(colors[:, :3].astype(np.float64), 0, 1)
    if prim.mode == _POINTS:
        return Points(positions, colors=colors)
    indices = getattr(prim, "indices", None)
    segments = (np.arange(len(positions) // 2 * 2) if indices is None
                else np.asarray(indices, dtype=np.int64).reshape(-1)).reshape(-1, 2)
    return Lines(positions, segments, colors=colors)


def _mesh(prim: Any, cache: dict[int, Any], alpha_cache: dict[int, float]) -> Mesh:
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
    if material is not None and _blend_alpha(prim, cache, alpha_cache):
        material = material.replace(alpha_mode="blend")  # "BLEND" with an alpha below 1
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


def _alpha_min(values: Any) -> float:
    """The smallest alpha of ``values`` (the last axis' last channel) scaled to [0, 1]."""
    a = np.asarray(values)
    full = float(np.iinfo(a.dtype).max) if np.issubdtype(a.dtype, np.integer) else 1.0
    return float(a.min()) / full if a.size else 1.0


def _blend_alpha(prim: Any, cache: dict[int, Any], alpha_cache: dict[int, float]) -> list[str]:
    """What makes a primitive with alphaMode "BLEND" translucent, as pyrender reads it (the
    ``baseColorFactor`` alpha, the base colour texture's alpha channel, the ``color_0`` alpha
    below 1): it is then blended; empty: every alpha is 1 and the primitive is opaque (pyrender
    draws it so too)."""
    mat = getattr(prim, "material", None)
    if getattr(mat, "alphaMode", None) != "BLEND":
        return []
    found = []
    factor = getattr(mat, "baseColorFactor", None)
    if factor is not None:
        arr = np.asarray(factor, dtype=np.float64).reshape(-1)
        if len(arr) >= 4 and arr[3] < 1.0:
            found.append(f"baseColorFactor alpha {arr[3]:.4g}")
    tex = getattr(mat, "baseColorTexture", None)
    if tex is not None and id(tex) in cache and cache[id(tex)] is not None:
        if id(tex) not in alpha_cache:
            image = cache[id(tex)].image  # softrast's reading: 2 channels grey + alpha, 4 RGBA
            alpha_cache[id(tex)] = _alpha_min(image[:, :, -1]) if image.shape[2] in (2, 4) else 1.0
        if alpha_cache[id(tex)] < 1.0:
            found.append(f"baseColorTexture alpha down to {alpha_cache[id(tex)]:.4g}")
    colors = getattr(prim, "color_0", None)
    if colors is not None:
        colors = np.asarray(colors)
        least = _alpha_min(colors[:, 3]) if colors.ndim == 2 and colors.shape[1] == 4 else 1.0
        if least < 1.0:
            found.append(f"color_0 alpha down to {least:.4g}")
    return found


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
    if len(scene) or scene.primitives:  # bounds of meshes, lines and points
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


class PyrenderConversion(tuple):
    """What ``from_pyrender`` returns: the pair ``(scene, camera)``, with pyrender's background.

    A tuple, so ``scene, camera = sr.from_pyrender(...)`` works as it always has, that also
    carries the pyrender scene's background colour, which softrast takes as a render argument.

    Parameters
    ----------
    scene : Scene
    camera : Camera or None
    background : sequence of 3 floats, optional
    background_alpha : float, optional

    Attributes
    ----------
    scene : Scene
        The ``softrast.Scene`` (also ``conversion[0]``).
    camera : Camera or None
        The main camera converted, or None (also ``conversion[1]``).
    background : tuple of 3 floats
        ``bg_color``'s RGB clipped to [0, 1] (as OpenGL clears pyrender's 8-bit framebuffer), for
        ``render(..., background=conversion.background)``. Both libraries write it to the colour
        image as it is (not sRGB-encoded, whatever ``srgb=``), so the background pixels are
        pyrender's bytes (its default white: 255).
    background_alpha : float
        ``bg_color``'s alpha (1 if it has none), which softrast does not render: its ``alpha``
        output is coverage, 0 on the background, where pyrender's RGBA render
        (``RenderFlags.RGBA``) has this value: ``alpha + (1 - alpha) * background_alpha`` is
        pyrender's.
    """

    background: tuple[float, float, float]
    background_alpha: float

    def __new__(cls, scene: Scene, camera: Camera | None,
                background: Any = (0.0, 0.0, 0.0), background_alpha: float = 1.0) -> PyrenderConversion:
        self = super().__new__(cls, (scene, camera))
        r, g, b = (float(v) for v in background)
        self.background, self.background_alpha = (r, g, b), float(background_alpha)
        return self

    @property
    def scene(self) -> Scene:
        """The ``softrast.Scene`` (``conversion[0]``)."""
        return self[0]  # type: ignore[no-any-return]

    @property
    def camera(self) -> Camera | None:
        """The main camera converted, or None (``conversion[1]``)."""
        return self[1]  # type: ignore[no-any-return]

    def __reduce__(self) -> tuple[Any, ...]:
        return (type(self), (self.scene, self.camera, self.background, self.background_alpha))

    def __repr__(self) -> str:
        return (f"PyrenderConversion(scene={self.scene!r}, camera={self.camera!r}, "
                f"background={self.background}, background_alpha={self.background_alpha})")


def _background(pyrender_scene: Any) -> tuple[tuple[float, float, float], float]:
    """pyrender's ``bg_color`` as (RGB, alpha) in [0, 1]; pyrender's default (white, 1) without one."""
    bg = getattr(pyrender_scene, "bg_color", None)
    rgba = np.ones(4) if bg is None else np.asarray(bg, dtype=np.float64).reshape(-1)
    if not 3 <= len(rgba) <= 4:
        raise ValueError(f"bg_color must be 3 or 4 numbers (RGB[A]), got {rgba.tolist()}")
    rgba = np.clip(np.nan_to_num(np.append(rgba, 1.0)[:4], nan=0.0), 0.0, 1.0)
    return (float(rgba[0]), float(rgba[1]), float(rgba[2])), float(rgba[3])


def from_pyrender(pyrender_scene: Any, width: int, height: int) -> PyrenderConversion:
    """Convert a ``pyrender.Scene`` to ``(softrast.Scene, camera)`` (see docs/interop.md).

    softrast renders a black background unless told otherwise: render as pyrender does with
    ``renderer.render(conv.scene, conv.camera, background=conv.background)``. Instance ids are
    0, 1, 2, ... in the order of ``pyrender_scene.mesh_nodes`` (sorted by node name, then
    primitive, then instancing pose, for a stable order: pyrender keeps them in a set). A
    primitive whose material has alphaMode "BLEND" gets ``alpha_mode="blend"`` where an alpha it
    reads is below 1, else it is opaque (``pyrender.Mesh.from_trimesh`` marks its materials
    "BLEND", and pyrender draws them opaque then).

    Parameters
    ----------
    pyrender_scene : pyrender.Scene
        The scene to convert (pyrender itself is not imported).
    width, height : int
        The image size (pyrender cameras carry none; ``OffscreenRenderer`` takes it).

    Returns
    -------
    PyrenderConversion
        The tuple ``(scene, camera)``, where the camera is the scene's main camera converted, or
        None if the scene has no camera, with the scene's ``bg_color`` as ``.background`` (RGB)
        and ``.background_alpha``.

    Warns
    -----
    UserWarning
        For what does not convert exactly (docs/interop.md lists it).
    """
    ambient = getattr(pyrender_scene, "ambient_light", None)
    scene = Scene(ambient_light=None if ambient is None else
                  tuple(float(v) for v in np.asarray(ambient, dtype=np.float64).reshape(3)))
    background, background_alpha = _background(pyrender_scene)
    nodes = sorted(pyrender_scene.mesh_nodes, key=lambda n: (str(n.name), id(n)))
    textures: dict[int, Any] = {}  # one sr.Texture per pyrender texture
    alphas: dict[int, float] = {}  # the least alpha of each base colour texture
    for node in nodes:
        mesh = node.mesh
        if not getattr(mesh, "is_visible", True):
            continue
        world = np.asarray(pyrender_scene.get_pose(node), dtype=np.float64)
        for prim in mesh.primitives:
            mode = getattr(prim, "mode", _TRIANGLES)
            converted = (_primitive(prim) if mode in (_POINTS, _LINES)
                         else _mesh(prim, textures, alphas))
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
    return PyrenderConversion(scene, camera, background, background_alpha)
