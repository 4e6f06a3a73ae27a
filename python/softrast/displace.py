"""True geometric displacement: ``softrast.displace(mesh, texture, scale)`` subdivides a mesh and
moves each vertex along its normal by the height the texture holds at its uv (in Python with
NumPy and trimesh, before rendering; the core renders the result like any mesh).

    p' = p + n * scale * (height(uv) - midlevel)

``height`` is the texture's first channel (grey, or red), sampled bilinearly at level 0 and read
as linear data unless the texture says ``srgb=True``. Normals of the displaced mesh are
recomputed (area-weighted, as ``load_mesh`` does). A vertex the file duplicates along a uv seam
is moved by its own uv's height, so a height map that differs across a seam opens a crack there,
as in any displacement by vertex.

(The shading-only variants of the course notes, bump mapping and moving the shading point along
the normal, are ``Material(bump_texture=)``; this function changes the geometry: silhouettes and
depth follow the heights.)
"""
from __future__ import annotations

from typing import Any

import numpy as np

from ._checks import FLOAT32_MAX, finite_real, integer
from .mesh import Mesh
from .normals import vertex_normals
from .texture import Texture

__all__ = ["displace"]


def displace(mesh: Mesh, texture: Texture, scale: float, subdivisions: int = 0,
             midlevel: float = 0.0) -> Mesh:
    """Displace a mesh's geometry: subdivide it, then move each vertex along its normal.

    Each vertex moves along its unit normal by ``scale * (height - midlevel)``, the height being
    the texture's first channel at its uv (bilinear, level 0, linear unless the texture says
    ``srgb=True``). The material is kept.

    Parameters
    ----------
    mesh : Mesh
        Needs uvs; without normals, the area-weighted vertex normals are used.
    texture : Texture
        The height map (first channel).
    scale : float
        Finite; scene units per unit of height.
    subdivisions : int, optional
        In [0, 8] (default 0): each splits every triangle into four; uvs, normals and colours are
        interpolated linearly.
    midlevel : float, optional
        Finite; the height that does not move (default 0).

    Returns
    -------
    Mesh
        A new Mesh (``mesh`` is unchanged).

    Raises
    ------
    TypeError
        For a mesh or texture of another type.
    ValueError
        For a mesh without uvs, a bad number, too many faces, or a vertex moved beyond float32's
        range.
    """
    import trimesh

    if not isinstance(mesh, Mesh):
        raise TypeError(f"mesh must be a softrast.Mesh, got {type(mesh).__name__}")
    if not isinstance(texture, Texture):
        raise TypeError(f"texture must be a softrast.Texture, got {type(texture).__name__}")
    s = finite_real(scale, "scale")
    mid = finite_real(midlevel, "midlevel")
    n_sub = integer(subdivisions, "subdivisions")
    if not 0 <= n_sub <= 8:
        raise ValueError(f"subdivisions must be in [0, 8], got {subdivisions!r}")
    if mesh.uvs is None:
        raise ValueError("mesh has no uvs: displacement reads the texture at each vertex's uv")
    if mesh.num_faces and 4 ** n_sub * mesh.num_faces > 50_000_000:
        raise ValueError(f"subdivisions={n_sub} would make {4 ** n_sub * mesh.num_faces:,} faces "
                         "(at most 50,000,000)")
    v = mesh.positions.astype(np.float64)
    f = mesh.faces.astype(np.int64)
    attrs: dict[str, Any] = {"uv": mesh.uvs.astype(np.float64)}
    if mesh.normals is not None:
        attrs["normal"] = mesh.normals.astype(np.float64)
    if mesh.colors is not None:
        attrs["color"] = mesh.colors.astype(np.float64)
    for _ in range(n_sub):
        v, f, attrs = trimesh.remesh.subdivide(v, f, vertex_attributes=attrs)
    if "normal" in attrs:
        normals = attrs["normal"]
        length = np.linalg.norm(normals, axis=1, keepdims=True)
        normals = np.divide(normals, length, out=np.zeros_like(normals), where=length > 0)
    else:
        normals = vertex_normals(trimesh.Trimesh(v, f, process=False), True)
    heights = texture if texture.srgb is not None else texture.replace(srgb=False)
    h = heights.sample(attrs["uv"], filter="bilinear")[:, 0].astype(np.float64)
    with np.errstate(over="ignore", invalid="ignore"):  # checked below, naming scale
        moved = v + normals * (s * (h - mid))[:, None]
    beyond = ~(np.abs(moved) <= FLOAT32_MAX).all(axis=1)
    if beyond.any():
        k = int(np.argmax(beyond))
        raise ValueError(f"scale={scale!r} moves vertex {k} to {moved[k].tolist()}, beyond float32's "
                         f"range (+-{FLOAT32_MAX:.8g}), a Mesh's vertex type: use a "
                         "smaller scale")
    new_normals = vertex_normals(trimesh.Trimesh(moved, f, process=False), True)
    return Mesh(moved, f, normals=new_normals, uvs=attrs["uv"],
                colors=attrs.get("color"), color=mesh.color, material=mesh.material)
