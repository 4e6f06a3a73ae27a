"""``to_pyrender``: a softrast Scene (and optionally its camera) as a ``pyrender.Scene``.
pyrender is imported when it is called, never at ``import softrast``; what does not convert
exactly gets one UserWarning naming it. See docs/interop.md."""
from __future__ import annotations

import math
import warnings
from typing import Any

import numpy as np

from ..camera import _GL_FROM_CV, Camera, IntrinsicsCamera, OrthographicCamera, PerspectiveCamera
from ..light import DirectionalLight, Light, PointLight, SpotLight
from ..normals import face_normals, unit_rows
from ..material import Material
from ..mesh import Mesh
from ..primitives import Points
from ..scene import Scene
from ..texture import srgb_decode
from ._gl import (_GL_LINEAR, _GL_LINEAR_MIPMAP_LINEAR, _GL_NEAREST, _LINES, _POINTS, _TRIANGLES,
                  _WRAP_GL)


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
    """Convert a ``softrast.Scene`` (and optionally its camera) to a ``pyrender.Scene``.

    The reverse of ``from_pyrender`` (what converts and what warns: docs/interop.md). Imports
    pyrender (and so PyOpenGL: set ``PYOPENGL_PLATFORM`` first for headless rendering); needs no
    display or OpenGL context. The scene's background is black, as softrast's default.

    Parameters
    ----------
    scene : Scene
        The scene to convert.
    camera : Camera, optional
        Becomes the scene's main camera; render an ``IntrinsicsCamera`` at its own width x height.

    Returns
    -------
    pyrender.Scene

    Raises
    ------
    TypeError
        For a scene or camera of another type.
    ImportError
        Without pyrender, or a PyOpenGL platform it can load.

    Warns
    -----
    UserWarning
        Everything that does not convert exactly warns (once per cause), naming the instance,
        material, texture slot, light or camera.
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
