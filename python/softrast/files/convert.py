"""trimesh objects -> softrast's arrays and Materials: parts (positions, faces, normals, uvs,
colours, material), merged or placed by node transforms. The Mesh and Scene classes build
themselves from these parts (``Mesh.from_trimesh``, ``Scene.from_trimesh``, ``load_mesh``,
``load_scene``)."""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Callable, TypeVar

import numpy as np

from .._checks import FLOAT32_MAX
from ..material import Material
from ..normals import _power_of_two_scaled, merge_exact, unit_rows, vertex_normals
from .context import FileInfo, _colors8, _normalized, srgb_to_linear
from .gltf_file import material_index
from .gltf import _GLTF_FALLBACK, _GLTF_SLOTS, _gltf_alpha, _gltf_material
from .images import _pil_texture
from .mtl import _mtl_resolve, _mtl_roughness

__all__ = ["Part", "mesh_part", "placements"]

_T = TypeVar("_T")


def _trimesh_material(mat: Any, info: FileInfo) -> tuple[Material | None, list[str], Any]:
    """(Material or None, dropped, key for warning once) for a trimesh material object."""
    from trimesh.visual import material as tmat

    if mat is None:
        return None, [], None
    if isinstance(mat, tmat.PBRMaterial):
        index = material_index(getattr(mat, "name", None))
        if info.gltf is not None and index is not None and index < len(info.gltf):
            # the file's own material, read exactly from its JSON (gltf_file names each material
            # by its index for trimesh)
            key = ("gltf", index)
            cached = info.materials.get((key, id(mat)))
            if cached is None:
                cached = info.materials[(key, id(mat))] = _gltf_material(index, info.gltf[index], info, mat)
            return cached[0], cached[1], key
        # from trimesh's values (8-bit base colour): Mesh.from_trimesh.
        # trimesh keeps no sampler, normal scale or occlusion strength: the defaults (trilinear,
        # repeat, 1, 1).
        dropped: list[str] = []
        textures: dict[str, Any] = {}
        for _, k, slot in _GLTF_SLOTS:
            image = getattr(mat, k, None)
            if image is not None:
                texture, why = _pil_texture(image, info)
                if texture is None:
                    dropped.append(f"{k} {why}: not drawn{_GLTF_FALLBACK[k]}")
                else:
                    textures[slot] = texture
        alpha = _gltf_alpha(mat.alphaMode, mat.alphaCutoff, dropped)
        base = (1.0, 1.0, 1.0, 1.0) if mat.baseColorFactor is None else tuple(
            (np.asarray(mat.baseColorFactor, dtype=np.float64) / 255.0).tolist())
        emissive = (0.0, 0.0, 0.0) if mat.emissiveFactor is None else tuple(
            np.clip(np.asarray(mat.emissiveFactor, dtype=np.float64), 0.0, 1.0).tolist())
        m = Material(base_color=base,
                     metallic=1.0 if mat.metallicFactor is None else min(max(mat.metallicFactor, 0.0), 1.0),
                     roughness=1.0 if mat.roughnessFactor is None else min(max(mat.roughnessFactor, 0.0), 1.0),
                     emissive=emissive, double_sided=bool(mat.doubleSided), model="pbr",
                     name=mat.name if isinstance(mat.name, str) and index is None else None,
                     **alpha, **textures)
        return m, dropped, ("pbr", id(mat))
    if isinstance(mat, tmat.SimpleMaterial):
        name = getattr(mat, "_name", None)
        if info.mtl is not None:  # an OBJ: the MTL file's own values, or none
            if name in info.mtl:
                m, dropped = _mtl_resolve(info.mtl[name], info)
                return m, dropped, ("mtl", name)
            return None, [], None
        if name is None and _is_empty(mat):
            return None, [], None  # trimesh's placeholder for UVs without a material
        rgb = [tuple((np.asarray(c, dtype=np.float64)[:3] / 255.0).tolist())
               for c in (mat.ambient, mat.diffuse, mat.specular)]
        alpha = float(np.asarray(mat.diffuse)[3]) / 255.0
        dropped = []
        texture = None
        if mat.image is not None and not _is_empty(mat):
            texture, why = _pil_texture(mat.image, info)
            if texture is None:
                dropped.append(f"its texture image {why}: not drawn")
        # a texture multiplies the diffuse colour: kd is the base colour then
        # the MTL rule (docs/file_formats.md, "OBJ and MTL"): pbr, metallic 0, roughness from Ks and Ns
        ns = min(max(float(mat.glossiness), 0.0), FLOAT32_MAX)  # Material's (float32) range
        # a diffuse alpha below 1 blends, as MTL's d < 1 (pyrender's from_trimesh: BLEND)
        m = Material(base_color=(*rgb[1], alpha), ka=rgb[0], kd=None if texture is not None else rgb[1],
                     ks=rgb[2], shininess=ns, metallic=0.0, roughness=_mtl_roughness(rgb[2], ns),
                     model="pbr", name=name if isinstance(name, str) else None,
                     base_color_texture=texture, alpha_mode="blend" if alpha < 1.0 else "opaque")
        return m, dropped, ("simple", id(mat))
    return None, [f"a {type(mat).__name__} is not supported"], ("other", id(mat))


def _without_textures(material: Material | None, uvs: Any, where: str, key: Any, info: FileInfo,
                      plain: Material | None = None) -> Material | None:
    """``material`` without its textures (or ``plain``, the file's material without them) if the
    mesh has no uvs to sample them at, with a warning."""
    if material is None or uvs is not None or not material.textured:
        return material
    slots = [k for k in Material._TEXTURE_SLOTS if getattr(material, k) is not None]
    info.warn(("no uvs", key), f"{where}: the mesh has no uvs, so its {', '.join(slots)} "
                               "cannot be drawn: dropped")
    return plain if plain is not None else material.replace(**{k: None for k in slots})


def _u8(value: Any) -> tuple[int, ...] | None:
    if value is None:
        return None
    return tuple(int(v) for v in np.asarray(value).reshape(-1))


def _is_empty(mat: Any) -> bool:
    """trimesh's empty_material(): unnamed, default colours, a 2x2 placeholder image."""
    from trimesh.visual.color import DEFAULT_COLOR

    image = getattr(mat, "image", None)
    return (getattr(mat, "_name", None) is None
            and all(_u8(getattr(mat, k)) == _u8(DEFAULT_COLOR) for k in ("ambient", "diffuse", "specular"))
            and (image is None or getattr(image, "size", None) == (2, 2)))


# -- trimesh geometry -> arrays -------------------------------------------------------------------
@dataclass
class Part:
    positions: np.ndarray
    faces: np.ndarray
    normals: np.ndarray | None
    uvs: np.ndarray | None
    colors: np.ndarray | None  # (n, 4) float64 linear RGBA
    material: Material | None


def _part(tm: Any, smooth: bool | str, info: FileInfo) -> Part:
    """One trimesh.Trimesh as arrays, its colours linear, its material resolved (warning about
    what is dropped, once per material)."""
    import trimesh

    faces = np.asarray(tm.faces)
    positions = np.asarray(tm.vertices)
    first = None  # merged vertex -> the file's vertex it came from (STL with smooth normals)
    if info.soup and smooth is not False:
        positions, faces, first = merge_exact(positions, faces)
        normals = vertex_normals(trimesh.Trimesh(positions, faces, process=False), smooth)
    else:
        normals = vertex_normals(tm, smooth)
    uvs = colors = face_colors = None
    material = None
    visual = getattr(tm, "visual", None)
    if isinstance(visual, trimesh.visual.texture.TextureVisuals):
        if visual.uv is not None and len(visual.uv) == len(positions):
            uvs = np.asarray(visual.uv)[:, :2]
        material, dropped, key = _trimesh_material(visual.material, info)
        if material is not None and material.name:
            where = f"material {material.name!r}"
        else:
            where = f"material {key[1]}" if key is not None and key[0] == "gltf" else "material"
        if dropped and key is not None:
            info.warn(key, f"{where}: " + "; ".join(dropped))
        if key is not None and key[0] == "mtl" and uvs is None and material is not None and material.textured:
            material = _without_textures(material, uvs, where, key, info, info.mtl[key[1]].material)
        material = _without_textures(material, uvs, where, key, info)
        raw = getattr(visual, "vertex_attributes", {}).get("color")  # glTF COLOR_0 with a material
        if raw is not None and len(raw) == len(positions):
            colors = _normalized(raw)
            if info.srgb and np.issubdtype(np.asarray(raw).dtype, np.integer):
                colors[:, :3] = srgb_to_linear(colors[:, :3])
    elif visual is not None:
        kind = visual.kind
        if kind == "vertex":
            colors = _colors8(visual.vertex_colors, info.srgb)
        elif kind == "face":
            face_colors = _colors8(visual.face_colors, info.srgb)
    if first is not None:  # per-vertex data of the file's vertices, to the merged ones
        uvs = None if uvs is None or len(uvs) != len(tm.vertices) else uvs[first]
        colors = None if colors is None or len(colors) != len(tm.vertices) else colors[first]
    if colors is not None and material is not None and info.gltf is not None:
        colors = colors * np.asarray(material.base_color)  # glTF: COLOR_0 x baseColorFactor
    if face_colors is not None:
        # A Mesh colours vertices: each face gets three vertices of its own, in face order.
        corners = faces.reshape(-1)
        positions = positions[corners]
        normals = None if normals is None else normals[corners]
        uvs = None if uvs is None else uvs[corners]
        colors = np.repeat(face_colors, 3, axis=0)
        faces = np.arange(3 * len(faces), dtype=np.int64).reshape(-1, 3)
    return Part(positions, faces, normals, uvs, colors, material)


def _merge(parts: list[Part], info: FileInfo) -> Part:
    """Concatenate parts into one; different materials => the first part's, with a warning."""
    if len(parts) == 1:
        return parts[0]
    materials: list[Material | None] = []
    for p in parts:
        if p.material not in materials:
            materials.append(p.material)
    material = parts[0].material
    if len(materials) > 1:
        info.warn("merged", f"{len(parts)} parts with {len(materials)} different materials were merged "
                            "into one mesh with the first part's material; use softrast.load_scene "
                            "to keep each part's material")
    if not all(p.uvs is not None for p in parts):
        material = _without_textures(material, None, "the merged mesh", "merged uvs", info)
    offsets = np.cumsum([0] + [len(p.positions) for p in parts[:-1]])
    faces = np.concatenate([p.faces + o for p, o in zip(parts, offsets)])
    positions = np.concatenate([p.positions for p in parts])
    normals = (np.concatenate([p.normals for p in parts])
               if all(p.normals is not None for p in parts) else None)
    uvs = np.concatenate([p.uvs for p in parts]) if all(p.uvs is not None for p in parts) else None
    colors = None
    if any(p.colors is not None for p in parts):
        fill = material.base_color if material is not None else (0.8, 0.8, 0.8, 1.0)
        colors = np.concatenate([
            p.colors if p.colors is not None else np.tile(np.asarray(fill, dtype=np.float64), (len(p.positions), 1))
            for p in parts])
    return Part(positions, faces, normals, uvs, colors, material)


def _transformed(part: Part, matrix: Any) -> Part:
    """``part`` moved by the (4, 4) ``matrix`` as trimesh's apply_transform moves a mesh: normals
    by the adjugate, and a mirroring matrix reverses each face's corners (keeping faces in order)
    so front faces stay counter-clockwise."""
    m = np.asarray(matrix, dtype=np.float64)
    if np.array_equal(m, np.eye(4)):
        return part
    linear = m[:3, :3]
    positions = part.positions @ linear.T + m[:3, 3]
    faces, normals = part.faces, part.normals
    # The matrix scaled by a power of two to a largest |entry| in [1, 2) for the determinant's
    # sign and the adjugate: exact, the same directions, no overflow for a node scaled by 1e200.
    unit_linear = _power_of_two_scaled(linear[None], np.abs(linear).max(keepdims=True).ravel())[0][0]
    flip = np.linalg.det(unit_linear) < 0
    if normals is not None:
        adjugate = np.cross(unit_linear.T[[1, 2, 0]], unit_linear.T[[2, 0, 1]])
        normals = unit_rows(normals @ (-adjugate if flip else adjugate))
    if flip:
        faces = np.ascontiguousarray(faces[:, ::-1])
    return Part(positions, faces, normals, part.uvs, part.colors, part.material)


def mesh_part(tm: Any, smooth: bool | str, info: FileInfo, root: Any = None) -> Part:
    """Mesh.from_trimesh's and load_mesh's work: a Trimesh, or a Scene merged with its
    transforms, as one part (then moved by ``root``, if given)."""
    import trimesh

    if isinstance(tm, trimesh.Scene):
        # Each placement of each geometry, in trimesh's graph order (as Scene.dump() lists them);
        # not dump() itself: its copies lose vertex attributes such as glTF COLOR_0.
        parts, converted = [], {}
        for node in tm.graph.nodes_geometry:
            transform, name = tm.graph[node]
            geom = tm.geometry.get(name)
            if isinstance(geom, trimesh.Trimesh) and len(geom.faces):
                if name not in converted:  # geometry placed by several nodes: converted once
                    converted[name] = _part(geom, smooth, info)
                parts.append(_transformed(converted[name], transform))
        if not parts:
            raise ValueError("tm is a trimesh.Scene without any triangle geometry")
    elif isinstance(tm, trimesh.Trimesh):
        parts = [_part(tm, smooth, info)]
    else:
        raise TypeError(f"tm must be a trimesh.Trimesh or trimesh.Scene, got {type(tm).__name__}")
    merged = _merge(parts, info)
    return merged if root is None else _transformed(merged, root)


def placements(loaded: Any, smooth: bool | str, info: FileInfo, root: Any,
               make: Callable[[Part], _T]) -> list[tuple[_T, np.ndarray | None]]:
    """load_scene's and Scene.from_trimesh's work: (``make(part)``, pose) for each placement of
    each triangle geometry of a trimesh.Scene (trimesh's graph order, ``graph.nodes_geometry``),
    posed by its node's world transform; a geometry placed by several nodes is made once. A
    trimesh.Trimesh is one placement at ``root``. May be empty."""
    import trimesh

    if isinstance(loaded, trimesh.Trimesh):
        return [(make(_part(loaded, smooth, info)), root)] if len(loaded.faces) else []
    if not isinstance(loaded, trimesh.Scene):
        raise TypeError(f"expected a trimesh.Scene or trimesh.Trimesh, got {type(loaded).__name__}")
    made: dict[str, _T] = {}
    out = []
    for node in loaded.graph.nodes_geometry:
        transform, name = loaded.graph[node]
        geom = loaded.geometry.get(name)
        if not isinstance(geom, trimesh.Trimesh) or len(geom.faces) == 0:
            continue
        if name not in made:
            made[name] = make(_part(geom, smooth, info))
        pose = np.asarray(transform, dtype=np.float64)
        out.append((made[name], pose if root is None else root @ pose))
    return out
