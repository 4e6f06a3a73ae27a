"""Conversions between pyrender and softrast scenes: ``softrast.from_pyrender`` and
``softrast.to_pyrender``.

from_pyrender never imports pyrender: its objects are read by their attributes (duck typing),
so softrast works without pyrender installed, and a pyrender scene converts without an OpenGL
context. to_pyrender imports pyrender when it is called, never at ``import softrast``.

from_pyrender
-------------
What is converted, and how (pyrender 0.1.45's attribute names):

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
  "MASK" and ``alphaCutoff`` -> ``alpha_mode="mask"``, ``alpha_cutoff`` (as a glTF file's).
  "BLEND" -> ``alpha_mode="blend"`` where some alpha the primitive reads is below 1 -- the
  ``baseColorFactor`` alpha, the base colour texture's alpha channel if it has one, the
  ``color_0`` alpha if any -- and opaque where every one is 1 (decided per primitive, silently
  either way): ``pyrender.Mesh.from_trimesh`` makes every material "BLEND", and pyrender then
  draws it opaque. softrast composites blended surfaces in exact depth order in linear light;
  pyrender blends whole meshes in its node order (farthest node origin first) in its encoded
  output (gamma 2.2 when lit, the raw factor with ``RenderFlags.FLAT``), so overlapping or
  interpenetrating translucent meshes and the encoding of a blend differ
  (tests/test_blend_vs_pyrender.py). Any other material type gets softrast's default look,
  with a UserWarning.
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
  distance of the scene's bounding-box corners (of its meshes, lines and points) along the
  viewing axis (at least 2 * znear).
  A ``metallicRoughnessTexture`` that pyrender keeps as its two channels (G, B) becomes an RGB
  texture (0, G, B), so metallic stays blue and roughness green.
* The background: ``bg_color`` (pyrender's default white) comes back as the result's
  ``background`` (its RGB clipped to [0, 1]) for ``render(background=)``: softrast, like pyrender,
  writes that colour to the image as it is (not sRGB-encoded), so the background pixels are
  pyrender's bytes (white stays 255). softrast's own default background is black, so pass it::

      conv = sr.from_pyrender(pr_scene, width, height)
      frame = sr.Renderer(width, height).render(conv.scene, conv.camera, background=conv.background)

  ``from_pyrender`` returns a ``PyrenderConversion``: the tuple ``(scene, camera)`` as before
  (``scene, camera = sr.from_pyrender(...)`` still works) with ``scene``, ``camera``,
  ``background`` and ``background_alpha`` attributes. ``bg_color``'s alpha (RGBA) is not
  rendered: softrast's ``alpha`` output is coverage (0 on the background) where pyrender's
  RGBA render holds ``bg_color``'s alpha; ``alpha + (1 - alpha) * background_alpha`` gives it.

to_pyrender
-----------
Building a ``pyrender.Scene`` needs no display and no OpenGL context, but importing pyrender
imports PyOpenGL, which fixes its platform for the whole process: set ``PYOPENGL_PLATFORM``
("egl" or "osmesa" for headless rendering) before the first call if you will render offscreen
without a display. What does not convert exactly gets one UserWarning naming it (never dropped
silently); the scene's background is black (softrast's default ``background``).

* Instances: one mesh node per instance, named ``"softrast instance <k> (id <instance_id>)"``
  with ``k`` zero-padded, so ``from_pyrender`` (which sorts nodes by name) gives them back in
  order; its pose is the instance's. pyrender's nodes hold translation, rotation and per-axis
  scale only: a pose that shears or mirrors is baked into the vertex positions (float32) and
  normals (inverse transpose) of a copy placed at the identity, with the faces' winding reversed
  for a mirror (softrast flips its facing test for a mirroring pose instead). A Mesh shared by
  several instances with the same material is one ``pyrender.Mesh``.
* Meshes: ``positions``, ``faces`` -> ``indices``, ``normals``, ``uvs`` -> ``texcoord_0``
  (same convention, v up), ``colors`` -> ``color_0``. A mesh without normals (softrast's flat
  face normals) is given per face: its vertices are unshared (three per face) and each gets its
  face's unit normal, as ``pyrender.Mesh.from_trimesh(smooth=False)`` does. pyrender 0.1.45
  keeps indices as float32: a mesh of more than 2**24 vertices warns (it would be drawn wrong).
* Materials -> ``MetallicRoughnessMaterial``: ``base_color`` -> ``baseColorFactor`` (the
  instance's colour: a ``Scene.add(color=)`` included), ``metallic``, ``roughness``,
  ``emissive`` -> ``emissiveFactor``, ``double_sided`` -> ``doubleSided`` (which also turns
  pyrender's back-face culling off; softrast culls by ``render(cull=)``), ``alpha_mode`` /
  ``alpha_cutoff`` -> ``alphaMode`` "OPAQUE" / "MASK" / "BLEND", ``alphaCutoff`` (pyrender
  0.1.45 never discards a fragment below the cutoff: a "mask" material warns; it blends "BLEND"
  meshes in its own way, see from_pyrender above), ``name``. A mesh with
  per-vertex colours gets ``baseColorFactor`` (1, 1, 1, 1): softrast's per-vertex colours
  replace the base colour, pyrender multiplies them by it (its lit shader multiplies the shaded
  colour by them, so ``pbr`` renders with vertex colours differ in the specular term). An
  instance without a material gets a two-sided one with its colour, metallic 0 and roughness
  0.5 (what softrast's ``pbr`` uses for it). What pyrender has no place for warns: a shading
  model other than "pbr" (pyrender shades every material with its metallic-roughness model;
  ``pyrender.RenderFlags.FLAT`` gives softrast's ``unlit``), ``ka`` / ``kd`` / ``ks`` /
  ``shininess`` of a material that is not "pbr" (when set), ``bump_texture``, ``specular_texture``,
  ``normal_scale`` != 1, ``occlusion_strength`` != 1. Converted as glTF defines them but shaded
  otherwise by pyrender's lit shader (PBR_NOTES.md): its emission is ``emissiveFactor`` squared,
  its occlusion map darkens the lights too, not only the ambient term.
* Textures (base colour, emissive, normal, metallic-roughness, occlusion) -> ``pyrender.Texture``
  with a ``Sampler`` (wrap -> GL repeat / clamp-to-edge / mirrored-repeat; "nearest" ->
  GL_NEAREST, "bilinear" -> GL_LINEAR, "trilinear" -> GL_LINEAR_MIPMAP_LINEAR; "anisotropic"
  warns and is trilinear). pyrender stores 8-bit textures and decodes sRGB in the base colour
  and emissive slots only: a uint8 image whose encoding is the slot's is passed as it is; any
  other (uint16, float32, or an encoding that differs, as ``srgb=False`` on a base colour
  texture) is re-encoded to 8 bits, with a warning. Images are expanded to RGBA as softrast
  reads them (grey, grey + alpha, RGB), flipped upside down for ``uv_origin="top_left"``, and
  a "directx" normal map has its green channel inverted. pyrender's ``FLAT`` render does not
  decode the base colour texture (softrast's ``unlit`` does).
* Lights: ``DirectionalLight`` / ``PointLight`` / ``SpotLight`` -> pyrender's, same colour,
  intensity and cone half-angles (radians), posed by the light's pose (made rigid if it
  scales: the position and the -z direction are kept). pyrender's point and spot lights always
  fall off as 1 / r^2: ``falloff="none"`` warns. A camera-space light (``camera_space=True``) is
  a child node of the camera's node (so it moves with the camera, and its world pose is the
  camera's times its own, as in softrast); without a camera it warns and is not converted.
  pyrender 0.1.45 shades each mesh with at most 4 lights of each type: more warn.
  ``Scene.ambient_light`` -> ``ambient_light`` (None -> 0, as softrast uses it in a scene with
  lights). A scene without lights warns: softrast's headlight is a render default, not part of
  the scene, and pyrender shows only the ambient light.
* Camera (optional; it becomes the main camera, its pose in OpenGL axes): ``PerspectiveCamera``
  -> ``PerspectiveCamera(yfov=radians(fov_y), znear, zfar, aspectRatio=aspect)`` (aspect None:
  the viewport's); ``OrthographicCamera`` -> ``OrthographicCamera(xmag, ymag, znear, zfar)``
  (pyrender renders with ymag and the viewport's aspect, ignoring xmag: a camera with a fixed
  image size whose xmag / ymag differs from it warns); ``IntrinsicsCamera`` ->
  ``IntrinsicsCamera(fx, fy, cx, cy, znear, zfar)`` with pyrender's principal point (measured
  from the image's top-left corner, as softrast's "opengl" convention: an "opencv" camera's cx
  and cy get + 0.5) and an "opencv" pose's y and z axes flipped; render it at the camera's own
  width x height (pyrender uses the viewport's size); lens distortion (``dist``) warns: pyrender's
  camera is an ideal pinhole. Any other camera warns.
* ``Points`` / ``Lines`` -> a GL_POINTS / GL_LINES primitive with their colours (vertex
  colours, alpha 1) under a node with their pose (a shear or mirror baked into the positions);
  a point size or line width other than 1 warns (pyrender has a renderer-wide point size and
  1-pixel lines), and so do their lighting (unlit in softrast; pyrender's FLAT flag shows their
  colours). ``from_pyrender`` reads points and lines primitives back as ``Points`` / ``Lines``.
"""
from __future__ import annotations

import math
import warnings
from typing import Any

import numpy as np

from .camera import _GL_FROM_CV, Camera, IntrinsicsCamera, OrthographicCamera, PerspectiveCamera
from .light import DirectionalLight, Light, PointLight, SpotLight
from .normals import face_normals, unit_rows
from .files.gltf import _gltf_alpha
from .material import Material
from .mesh import Mesh
from .primitives import Lines, Points
from .scene import Scene

__all__ = ["PyrenderConversion", "from_pyrender", "to_pyrender"]

_TRIANGLES = 4  # GL_TRIANGLES, pyrender's default primitive mode
_POINTS, _LINES = 0, 1  # GL_POINTS, GL_LINES
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
    """What ``from_pyrender`` returns: the pair ``(scene, camera)`` -- a tuple, so ``scene,
    camera = sr.from_pyrender(...)`` works as it always has -- that also carries the pyrender
    scene's background colour, which softrast takes as a render argument.

    scene : the ``softrast.Scene`` (also ``conversion[0]``).
    camera : the main camera converted, or None (also ``conversion[1]``).
    background : ``bg_color``'s RGB clipped to [0, 1] (as OpenGL clears pyrender's 8-bit
        framebuffer), for ``render(..., background=conversion.background)``. Both libraries write
        it to the colour image as it is (not sRGB-encoded, whatever ``srgb=``), so the background
        pixels are pyrender's bytes (its default white: 255).
    background_alpha : ``bg_color``'s alpha (1 if it has none), which softrast does not render:
        its ``alpha`` output is coverage, 0 on the background, where pyrender's RGBA render
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
        return self[0]  # type: ignore[no-any-return]

    @property
    def camera(self) -> Camera | None:
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
    """Convert a ``pyrender.Scene`` to ``(softrast.Scene, camera)`` (see this module's docstring).

    width, height : the image size (pyrender cameras carry none; ``OffscreenRenderer`` takes it).
    Returns a ``PyrenderConversion``: the tuple ``(scene, camera)``, where the camera is the
    scene's main camera converted, or None if the scene has no camera, with the scene's
    ``bg_color`` as ``.background`` (RGB) and ``.background_alpha``. softrast renders a black
    background unless told otherwise: render as pyrender does with
    ``renderer.render(conv.scene, conv.camera, background=conv.background)``.
    Instance ids are 0, 1, 2, ... in the order of ``pyrender_scene.mesh_nodes`` (sorted by node
    name, then primitive, then instancing pose, for a stable order: pyrender keeps them in a set).
    A primitive whose material has alphaMode "BLEND" gets ``alpha_mode="blend"`` where an
    alpha it reads is below 1, else it is opaque (``pyrender.Mesh.from_trimesh`` marks its
    materials "BLEND", and pyrender draws them opaque then).
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


# -- to_pyrender -------------------------------------------------------------------------------

_GL_LINEAR_MIPMAP_LINEAR = 9987
_WRAP_GL = {name: enum for enum, name in _GL_WRAP.items()}
# softrast slot -> (pyrender attribute, the channels pyrender keeps, pyrender decodes sRGB).
_TO_PYRENDER_TEXTURES = {
    "base_color_texture": ("baseColorTexture", "RGBA", True),
    "emissive_texture": ("emissiveTexture", "RGB", True),
    "normal_texture": ("normalTexture", "RGB", False),
    "metallic_roughness_texture": ("metallicRoughnessTexture", "GB", False),
    "occlusion_texture": ("occlusionTexture", "R", False),
}
_COLOR_SLOTS = ("base_color_texture", "emissive_texture")  # softrast decodes sRGB here by default
_PYRENDER_MAX_LIGHTS = 4  # pyrender 0.1.45's MAX_N_LIGHTS, per light type
_NON_PBR_DEFAULTS = {"ka": None, "kd": None, "ks": (0.5, 0.5, 0.5), "shininess": 32.0}
_MODEL_ONLY = ("lambert", "phong", "blinn_phong", "unlit", "normal")


def _import_pyrender() -> Any:
    try:
        import pyrender
    except Exception as exc:  # ImportError, or PyOpenGL failing to load its platform's library
        raise ImportError(
            "softrast.to_pyrender needs pyrender (pip install pyrender) and a PyOpenGL platform "
            "it can load; without a display set PYOPENGL_PLATFORM=egl or osmesa before the "
            f"first import ({type(exc).__name__}: {exc})") from exc
    return pyrender


def _srgb_encode(c: np.ndarray) -> np.ndarray:
    c = np.clip(c, 0.0, 1.0)
    return np.where(c <= 0.0031308, 12.92 * c, 1.055 * np.power(c, 1.0 / 2.4) - 0.055)


def _rgba8(tex: Any, slot: str, pr_srgb: bool, label: str, notes: list[str]) -> np.ndarray:
    """``tex``'s image as (h, w, 4) uint8 in the encoding pyrender's slot reads, expanded to
    RGBA as softrast reads it; a warning when that is not the image's own bytes."""
    from .texture import srgb_decode

    image = tex.image
    sr_srgb = tex._decodes_srgb(slot in _COLOR_SLOTS)
    h, w, c = image.shape
    if image.dtype == np.uint8 and sr_srgb == pr_srgb:
        data = image
    else:
        if image.dtype == np.uint8:
            values = image / 255.0
        elif image.dtype == np.uint16:
            values = image / 65535.0
        else:
            values = image.astype(np.float64)
        color = c if c in (1, 3) else c - 1
        if sr_srgb:
            values[:, :, :color] = srgb_decode(values[:, :, :color])
        if pr_srgb:
            values[:, :, :color] = _srgb_encode(values[:, :, :color])
        clipped = bool((values < 0.0).any() or (values > 1.0).any())
        data = np.floor(np.clip(values, 0.0, 1.0) * 255.0 + 0.5).astype(np.uint8)
        notes.append(f"{label}: {slot} ({image.dtype}, {'sRGB' if sr_srgb else 'linear'}) is "
                     f"stored as 8-bit {'sRGB' if pr_srgb else 'linear'} values for pyrender "
                     "(its only texture format): rounded to 1/255"
                     + (", values outside [0, 1] clipped" if clipped else ""))
    if c == 1:
        data = np.concatenate([data, data, data, np.full_like(data, 255)], axis=2)
    elif c == 2:
        data = np.concatenate([data[:, :, :1]] * 3 + [data[:, :, 1:]], axis=2)
    elif c == 3:
        data = np.concatenate([data, np.full((h, w, 1), 255, np.uint8)], axis=2)
    if tex.uv_origin == "top_left":  # pyrender's uvs put image row 0 at v = 1
        data = data[::-1]
    return np.ascontiguousarray(data)


def _pr_texture(pyrender: Any, tex: Any, slot: str, flip_green: bool, label: str,
                notes: list[str], cache: dict[Any, Any]) -> Any:
    key = (id(tex), slot, flip_green)
    if key in cache:
        return cache[key][1]
    _, channels, pr_srgb = _TO_PYRENDER_TEXTURES[slot]
    data = _rgba8(tex, slot, pr_srgb, label, notes)
    if flip_green:  # a DirectX normal map (green = -v): OpenGL's is 1 - green
        data = data.copy()
        data[:, :, 1] = 255 - data[:, :, 1]
    if tex.filter == "anisotropic":
        notes.append(f"{label}: {slot}'s filter 'anisotropic' is not converted: pyrender has no "
                     "anisotropic filtering (trilinear is used)")
    mag = _GL_NEAREST if tex.filter == "nearest" else _GL_LINEAR
    minf = {"nearest": _GL_NEAREST, "bilinear": _GL_LINEAR}.get(tex.filter, _GL_LINEAR_MIPMAP_LINEAR)
    sampler = pyrender.Sampler(magFilter=mag, minFilter=minf, wrapS=_WRAP_GL[tex.wrap[0]],
                               wrapT=_WRAP_GL[tex.wrap[1]])
    out = pyrender.Texture(name=tex.name, sampler=sampler, source=data, source_channels=channels)
    cache[key] = (tex, out)  # keeps tex alive so its id stays unique while converting
    return out


def _pr_material(pyrender: Any, mat: Material | None, base: tuple[float, ...], has_colors: bool,
                 label: str, notes: list[str], tex_cache: dict[Any, Any]) -> Any:
    factor = (1.0, 1.0, 1.0, 1.0) if has_colors else tuple(base)
    if mat is None:  # softrast's plain material: two-sided, metallic 0, roughness 0.5
        return pyrender.MetallicRoughnessMaterial(baseColorFactor=factor, metallicFactor=0.0,
                                                  roughnessFactor=0.5, doubleSided=True)
    if mat.model in _MODEL_ONLY:
        notes.append(f"{label}: shading model {mat.model!r} is not converted: pyrender shades every "
                     "material with its metallic-roughness model (pyrender.RenderFlags.FLAT "
                     "renders softrast's 'unlit')")
    if mat.model != "pbr":
        lost = [k for k, default in _NON_PBR_DEFAULTS.items() if getattr(mat, k) != default]
        if lost:
            notes.append(f"{label}: {', '.join(lost)} not converted: pyrender's metallic-roughness "
                         "material has no such parameters")
    if mat.bump_texture is not None:
        notes.append(f"{label}: bump_texture is not converted: pyrender has no bump maps")
    if mat.specular_texture is not None:
        notes.append(f"{label}: specular_texture is not converted: pyrender has no specular maps")
    if mat.normal_texture is not None and mat.normal_scale != 1.0:
        notes.append(f"{label}: normal_scale {mat.normal_scale} is not converted: pyrender reads "
                     "normal maps unscaled")
    if mat.occlusion_texture is not None and mat.occlusion_strength != 1.0:
        notes.append(f"{label}: occlusion_strength {mat.occlusion_strength} is not converted: "
                     "pyrender applies occlusion maps at full strength")
    if mat.alpha_mode == "mask":
        notes.append(f"{label}: alpha_mode 'mask' is converted to alphaMode 'MASK' (alphaCutoff "
                     f"{mat.alpha_cutoff}), but pyrender 0.1.45 never discards a fragment below "
                     "the cutoff: it draws the whole surface")
    textures = {}
    for slot, (attr, _, _) in _TO_PYRENDER_TEXTURES.items():
        tex = getattr(mat, slot)
        if tex is not None:
            flip = slot == "normal_texture" and mat.normal_map_convention == "directx"
            textures[attr] = _pr_texture(pyrender, tex, slot, flip, label, notes, tex_cache)
    return pyrender.MetallicRoughnessMaterial(
        name=mat.name, baseColorFactor=factor, metallicFactor=mat.metallic,
        roughnessFactor=mat.roughness, emissiveFactor=mat.emissive, doubleSided=mat.double_sided,
        alphaMode=mat.alpha_mode.upper(), alphaCutoff=mat.alpha_cutoff,
        **textures)


def _trs_pose(pose: np.ndarray) -> bool:
    """True if pyrender's Node (translation, rotation, per-axis scale) holds ``pose``: its
    columns, normalized, form a proper rotation."""
    m3 = pose[:3, :3]
    norms = np.linalg.norm(m3, axis=0)
    if not (norms > 0.0).all():
        return False
    r = m3 / norms
    return bool(np.abs(r.T @ r - np.eye(3)).max() <= 1e-9 and np.linalg.det(r) > 0.0)


def _pr_primitive(pyrender: Any, mesh: Mesh, material: Any, bake: np.ndarray | None, label: str,
                  notes: list[str]) -> Any:
    positions = mesh.positions.astype(np.float64)
    faces = mesh.faces
    normals = None if mesh.normals is None else mesh.normals.astype(np.float64)
    uvs, colors = mesh.uvs, mesh.colors
    if bake is not None:
        m3 = bake[:3, :3]
        positions = positions @ m3.T + bake[:3, 3]
        if normals is not None:
            with np.errstate(divide="ignore", invalid="ignore"):
                normals = normals @ np.linalg.pinv(m3)  # (inverse transpose) applied to rows
        if np.linalg.det(m3) < 0.0:  # a mirror: keep the outside counter-clockwise
            faces = faces[:, ::-1]
    if normals is None:  # softrast's flat face normals: unshare the vertices, one normal per face
        corners = positions[faces]  # (m, 3, 3)
        n, _ = face_normals(positions, faces)  # unit at any scale (corners scaled, float64)
        positions = corners.reshape(-1, 3)
        normals = np.repeat(n, 3, axis=0)
        uvs = None if uvs is None else uvs[faces].reshape(-1, 2)
        colors = None if colors is None else colors[faces].reshape(-1, 4)
        faces = np.arange(len(positions), dtype=np.int32).reshape(-1, 3)
    if len(positions) > 2**24:
        notes.append(f"{label}: {len(positions)} vertices: pyrender 0.1.45 stores indices as "
                     "float32, which rounds those above 2**24 (16,777,216): the mesh is drawn wrong")
    normals = unit_rows(normals)  # (a NaN row from a singular bake's pinv: 0)
    return pyrender.Primitive(positions=positions.astype(np.float32),
                              normals=normals.astype(np.float32),
                              texcoord_0=None if uvs is None else np.array(uvs, np.float32),
                              color_0=None if colors is None else np.array(colors, np.float32),
                              indices=np.ascontiguousarray(faces, dtype=np.int32),
                              material=material, mode=_TRIANGLES)


def _rigid(pose: np.ndarray) -> np.ndarray:
    """``pose`` if it is rigid, else a rigid pose with its position and its -z direction."""
    r = pose[:3, :3]
    if np.abs(r.T @ r - np.eye(3)).max() <= 1e-9 and np.linalg.det(r) > 0.0:
        return pose
    z = pose[:3, 2] / np.linalg.norm(pose[:3, 2])
    helper = np.eye(3)[int(np.argmin(np.abs(z)))]
    x = np.cross(helper, z)
    x /= np.linalg.norm(x)
    out = np.eye(4)
    out[:3, 0], out[:3, 1], out[:3, 2], out[:3, 3] = x, np.cross(z, x), z, pose[:3, 3]
    return out


def _pr_light(pyrender: Any, light: Light, label: str, notes: list[str]) -> Any:
    color, intensity = list(light.color), float(light.intensity)
    if getattr(light, "falloff", "inverse_square") == "none":
        notes.append(f"{label}: falloff='none' is not converted: pyrender's point and spot lights "
                     "always fall off as 1 / r^2")
    if isinstance(light, SpotLight):
        return pyrender.SpotLight(color=color, intensity=intensity, innerConeAngle=light.inner_cone,
                                  outerConeAngle=light.outer_cone)
    if isinstance(light, PointLight):
        return pyrender.PointLight(color=color, intensity=intensity)
    if isinstance(light, DirectionalLight):
        return pyrender.DirectionalLight(color=color, intensity=intensity)
    notes.append(f"{label}: a {type(light).__name__} is not converted")
    return None


def _pr_camera(pyrender: Any, camera: Camera, notes: list[str]) -> tuple[Any, np.ndarray]:
    """pyrender's camera and its pose (OpenGL axes), or (None, None) with a warning."""
    near, far = camera.near, camera.far
    pose = camera.pose @ _GL_FROM_CV if camera.convention == "opencv" else camera.pose
    if isinstance(camera, PerspectiveCamera):
        return pyrender.PerspectiveCamera(yfov=math.radians(camera.fov_y), znear=near, zfar=far,
                                          aspectRatio=camera.aspect), pose
    if isinstance(camera, OrthographicCamera):
        w, h = camera.width, camera.height
        if w is not None and h is not None and not math.isclose(camera.xmag / camera.ymag, w / h,
                                                                rel_tol=1e-9):
            notes.append(f"camera: xmag / ymag ({camera.xmag} / {camera.ymag}) differs from the "
                         f"image's aspect ({w} x {h}): pyrender renders with ymag and the "
                         "viewport's aspect (xmag = ymag * width / height)")
        return pyrender.OrthographicCamera(xmag=camera.xmag, ymag=camera.ymag, znear=near,
                                           zfar=far), pose
    if isinstance(camera, IntrinsicsCamera):
        half = 0.5 if camera.convention == "opencv" else 0.0  # OpenCV's pixel centres: j, i
        if getattr(camera, "dist", None) is not None:
            notes.append(f"camera: lens distortion (dist {np.asarray(camera.dist).tolist()}) is not "
                         "converted: pyrender's IntrinsicsCamera is an ideal pinhole")
        return pyrender.IntrinsicsCamera(fx=camera.fx, fy=camera.fy, cx=camera.cx + half,
                                         cy=camera.cy + half, znear=near, zfar=far), pose
    notes.append(f"camera: a {type(camera).__name__} is not converted")
    return None, None


def to_pyrender(scene: Scene, camera: Camera | None = None) -> Any:
    """Convert a ``softrast.Scene`` (and optionally its camera) to a ``pyrender.Scene``: the
    reverse of ``from_pyrender`` (what converts and what warns: this module's docstring).

    Imports pyrender (and so PyOpenGL: set ``PYOPENGL_PLATFORM`` first for headless rendering);
    needs no display or OpenGL context. ``camera`` becomes the scene's main camera; render an
    ``IntrinsicsCamera`` at its own width x height. The scene's background is black, as
    softrast's default. Everything that does not convert exactly warns (UserWarning, once per
    cause), naming the instance, material, texture slot, light or camera.
    """
    if not isinstance(scene, Scene):
        raise TypeError(f"scene must be a softrast.Scene, got {type(scene).__name__}")
    if camera is not None and not isinstance(camera, Camera):
        raise TypeError(f"camera must be a softrast camera or None, got {type(camera).__name__}")
    pyrender = _import_pyrender()
    notes: list[str] = []
    ambient = scene.ambient_light if scene.ambient_light is not None else (0.0, 0.0, 0.0)
    out = pyrender.Scene(ambient_light=np.asarray(ambient, dtype=np.float64),
                         bg_color=[0.0, 0.0, 0.0, 1.0])
    tex_cache: dict[Any, Any] = {}
    materials: dict[Any, Any] = {}
    meshes: dict[Any, Any] = {}
    instances = scene.instances
    digits = len(str(max(len(instances) - 1, 0)))
    for k, inst in enumerate(instances):
        mat, mesh = inst.material, inst.mesh
        has_colors = mesh.colors is not None
        if mat is not None:
            label = (f"material {mat.name!r} (instance {k})" if mat.name
                     else f"the material of instance {k}")
            mkey: Any = (id(mat), has_colors)
        else:
            label, mkey = f"instance {k}", ("plain", inst.color, has_colors)
        if mkey not in materials:
            materials[mkey] = (mat, _pr_material(pyrender, mat, inst.color, has_colors, label,
                                                 notes, tex_cache))
        pr_mat = materials[mkey][1]
        name = f"softrast instance {k:0{digits}d} (id {inst.instance_id})"
        pose = np.asarray(inst.pose, dtype=np.float64)
        if _trs_pose(pose):
            key = (id(mesh), id(pr_mat))
            if key not in meshes:
                prim = _pr_primitive(pyrender, mesh, pr_mat, None, f"instance {k}", notes)
                meshes[key] = (mesh, pyrender.Mesh(primitives=[prim]))
            out.add(meshes[key][1], pose=pose, name=name)
        else:  # shear or mirror: pyrender's node cannot hold it
            prim = _pr_primitive(pyrender, mesh, pr_mat, pose, f"instance {k}", notes)
            out.add(pyrender.Mesh(primitives=[prim]), pose=np.eye(4), name=name)
    for k, pinst in enumerate(scene.primitives):
        item, pose = pinst.item, np.asarray(pinst.pose, dtype=np.float64)
        kind = "points" if isinstance(item, Points) else "lines"
        label = f"{kind} {k} (id {pinst.instance_id})"
        positions = item.positions.astype(np.float64)
        if not _trs_pose(pose):  # bake a shear or mirror into the positions
            positions = positions @ pose[:3, :3].T + pose[:3, 3]
            pose = np.eye(4)
        rgb = (item.colors.astype(np.float64) if item.colors is not None
               else np.tile(np.asarray(item.color, dtype=np.float64), (len(positions), 1)))
        rgba = np.hstack([rgb, np.ones((len(rgb), 1))])
        if isinstance(item, Points):
            prim = pyrender.Primitive(positions=positions, color_0=rgba, mode=_POINTS)
            if item.size != 1.0:
                notes.append(f"{label}: size {item.size:g} is not converted (pyrender draws every "
                             "point at its renderer's point_size)")
        else:
            ends = item.segments.reshape(-1)
            prim = pyrender.Primitive(positions=positions[ends], color_0=rgba[ends], mode=_LINES)
            if item.width != 1.0:
                notes.append(f"{label}: width {item.width:g} is not converted (pyrender draws "
                             "1-pixel lines)")
        notes.append("lines and points are unlit in softrast; pyrender shades them like meshes "
                     "(RenderFlags.FLAT shows their colours)")
        out.add(pyrender.Mesh(primitives=[prim]), pose=pose,
                name=f"softrast {kind} {k} (id {pinst.instance_id})")
    cam_node = None
    if camera is not None:
        pr_cam, cam_pose = _pr_camera(pyrender, camera, notes)
        if pr_cam is not None:
            cam_node = out.add(pr_cam, pose=cam_pose, name="camera")
    lights = scene.lights
    if not lights:
        notes.append("the scene has no lights: softrast lights it with its headlight (a render "
                     "default, not part of the scene), pyrender shows only the ambient light "
                     f"{tuple(ambient)}")
    counts: dict[str, int] = {}
    for k, li in enumerate(lights):
        kind = type(li.light).__name__
        label = f"light {k} ({kind})"
        pr_light = _pr_light(pyrender, li.light, label, notes)
        if pr_light is None:
            continue
        if li.light.shadows:
            notes.append(f"{label} casts shadows ({li.light.shadows!r}): pyrender takes them per "
                         "render, as RenderFlags.SHADOWS_DIRECTIONAL / SHADOWS_SPOT (shadow maps; "
                         "none for point lights)")
        pose = _rigid(np.asarray(li.pose, dtype=np.float64))
        if li.camera_space:
            if cam_node is None:
                notes.append(f"{label} is in camera space (camera_space=True) and no camera was "
                             "converted: the light is not converted")
                continue
            # Its pose is light-to-view in OpenGL axes (softrast's inverse view matrix times
            # it): the camera node's axes, for either camera convention.
            out.add(pr_light, pose=pose, name=f"softrast light {k}", parent_node=cam_node)
        else:
            out.add(pr_light, pose=pose, name=f"softrast light {k}")
        counts[kind] = counts.get(kind, 0) + 1
    for kind, n in counts.items():
        if n > _PYRENDER_MAX_LIGHTS:
            notes.append(f"{n} {kind}s: pyrender 0.1.45 shades each mesh with at most "
                         f"{_PYRENDER_MAX_LIGHTS} of each light type (the nearest ones)")
    for note in dict.fromkeys(notes):
        warnings.warn(f"to_pyrender: {note}", UserWarning, stacklevel=2)
    return out
