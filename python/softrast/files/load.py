"""``load_mesh`` and ``load_scene``: a mesh file checked, parsed by trimesh, and converted, with
every failure a FileNotFoundError or a ValueError naming the file."""
from __future__ import annotations

import contextlib
import errno
import io
import os
import signal
import threading
from typing import Any, Iterator, Sequence

import numpy as np

from ..mesh import _LOADING_FILE, Mesh, _check_smooth, _mesh_of, _rgba
from ..scene import Scene, _scene_of
from .checks import check_mesh_file
from .context import FileInfo
from .convert import mesh_part
from .gltf_file import GltfFile, read_gltf
from .images import _have_pillow
from .mtl import _obj_materials

__all__ = ["load_mesh", "load_scene"]


# load_mesh / load_scene(up_axis="z"): (x, y, z) -> (x, z, -y), a proper rotation about x
UP_Z_TO_Y = np.array([[1.0, 0.0, 0.0, 0.0], [0.0, 0.0, 1.0, 0.0], [0.0, -1.0, 0.0, 0.0], [0.0, 0.0, 0.0, 1.0]])


def up_axis_matrix(up_axis: Any) -> np.ndarray | None:
    """None for "y" (as stored), the rotation for "z"; ValueError naming up_axis otherwise."""
    if isinstance(up_axis, str) and up_axis == "y":
        return None
    if isinstance(up_axis, str) and up_axis == "z":
        return UP_Z_TO_Y
    raise ValueError(f"up_axis must be 'y' or 'z', got {up_axis!r:.80}")


def _file_info(path_str: str, gltf: GltfFile | None) -> FileInfo:
    """What the file says about its materials: an OBJ's MTL file, read; a glTF's JSON, as read."""
    ext = os.path.splitext(path_str)[1].lower()
    if gltf is not None:
        info = FileInfo(path_str, srgb=False)
        mats = gltf.doc.get("materials", [])
        info.gltf = mats if isinstance(mats, list) else []
        info.gltf_doc = gltf.doc
        images = gltf.doc.get("images")
        if isinstance(images, list) and images and not _have_pillow():
            info.warn("pillow", f"Pillow is not installed, so trimesh drops this file's {len(images)} "
                                "image(s): its textures are not drawn (Pillow is a softrast "
                                "dependency: pip install pillow)")
        return info
    info = FileInfo(path_str, srgb=True, soup=ext == ".stl")
    if ext == ".obj":
        info.mtl = _obj_materials(path_str, info)
    return info


class _FileProblem(ValueError):
    """What load_mesh itself finds wrong with a loaded file (reported without a type name)."""


@contextlib.contextmanager
def _keep_ctrl_c() -> Iterator[None]:
    """Make Ctrl-C inside trimesh reach the caller.

    trimesh catches BaseException in many places (optional imports, loaders), which swallows a
    KeyboardInterrupt. While it runs, SIGINT is recorded as well as raised; if trimesh swallowed
    or converted it, KeyboardInterrupt is raised again on the way out.
    """
    if (threading.current_thread() is not threading.main_thread()
            or signal.getsignal(signal.SIGINT) is not signal.default_int_handler):
        yield  # someone else owns SIGINT => leave it alone
        return
    hit: list[int] = []

    def handler(signum: int, frame: Any) -> None:
        hit.append(signum)
        raise KeyboardInterrupt

    signal.signal(signal.SIGINT, handler)
    try:
        yield
    except KeyboardInterrupt:
        raise
    except BaseException as exc:
        if hit:
            raise KeyboardInterrupt from exc
        raise
    finally:
        signal.signal(signal.SIGINT, signal.default_int_handler)
    if hit:
        raise KeyboardInterrupt


def _load_trimesh(path_str: str) -> tuple[Any, Any]:
    """(trimesh.Trimesh or trimesh.Scene, FileInfo) for a mesh file, checked: every failure is a
    FileNotFoundError or a ValueError naming the file. A glTF or GLB is read once: checked, then
    handed to trimesh from memory with its materials named by index (``gltf_file``)."""
    if not os.path.isfile(path_str):
        raise FileNotFoundError(errno.ENOENT, "mesh file not found", path_str)
    gltf = None
    if os.path.splitext(path_str)[1].lower() in (".gltf", ".glb"):
        gltf, stated_faces = read_gltf(path_str), 0  # meshes can be instanced: no face count
    else:
        stated_faces = check_mesh_file(path_str)
    # trimesh raises anything from KeyError to struct.error while parsing, and more later, from
    # its lazily computed properties (an IndexError for a face index past the vertices): all of
    # it is this file's failure to load, so it becomes a ValueError naming the file.
    try:
        with _keep_ctrl_c():
            import trimesh

            if gltf is None:  # process=False keeps the vertex order
                loaded = trimesh.load(path_str, process=False)
            else:
                data, kind = gltf.for_trimesh()
                loaded = trimesh.load(io.BytesIO(data), file_type=kind, process=False,
                                      resolver=trimesh.resolvers.FilePathResolver(path_str))
            if isinstance(loaded, trimesh.Scene):
                parts = [loaded.geometry.get(loaded.graph[node][1]) for node in loaded.graph.nodes_geometry]
                parts = [g for g in parts if isinstance(g, trimesh.Trimesh) and len(g.faces)]
                if not parts:
                    raise _FileProblem("the file contains no triangles")
            elif (not isinstance(loaded, trimesh.Trimesh) or len(loaded.faces) == 0
                    or len(loaded.vertices) == 0):
                raise _FileProblem("the file contains no triangles")
            else:
                parts = [loaded]
            read = sum(len(g.faces) for g in parts)
            if read < stated_faces:
                raise _FileProblem(f"it has {stated_faces} faces but only {read} "
                                   "could be read: corrupt face rows were skipped")
            for g in parts:
                faces, count = np.asarray(g.faces), len(g.vertices)
                bad = (faces < 0) | (faces >= count)
                if bad.any():
                    raise _FileProblem(f"face {int(np.flatnonzero(bad.any(axis=1))[0])} has a vertex "
                                       f"index {int(faces[bad][0])} out of bounds for {count} vertices")
    except ImportError as exc:  # trimesh imports optional modules lazily (and hides .name)
        hint = " (Pillow, a softrast dependency: pip install pillow)" if "PIL" in str(exc) else ""
        raise ValueError(f"could not load mesh {path_str!r}: trimesh needs a module that is not "
                         f"installed to read it: {exc}{hint}") from exc
    except Exception as exc:
        what = str(exc) if isinstance(exc, _FileProblem) else f"{type(exc).__name__}: {exc}"
        raise ValueError(f"could not load mesh {path_str!r}: {what}") from exc
    try:
        info = _file_info(path_str, gltf)  # the file's materials (an MTL file, the glTF JSON)
    except UserWarning:
        raise  # a warning made an error (-W error): it names the file already
    except Exception as exc:
        raise ValueError(f"could not load mesh {path_str!r}: {type(exc).__name__}: {exc}") from exc
    return loaded, info


def load_mesh(path: str | os.PathLike[str], smooth: bool | str = True, color: Sequence[float] | None = None,
              up_axis: str = "y") -> Mesh:
    """Load a triangle mesh file (OBJ, PLY, STL, GLB, OFF, ...) with trimesh, keeping vertex order.

    A multi-object file is concatenated into one Mesh (with its node transforms applied).
    Keeps the file's per-vertex and per-face colours and its materials (OBJ + MTL, glTF), exactly
    as written in the file (docs/file_formats.md states the conventions). Colour spaces: 8-bit
    colours in PLY, OBJ, OFF and STL files are sRGB and are decoded to linear (exact IEC
    61966-2-1 curve), so an ``unlit`` render with the default sRGB output gives back the file's
    bytes; glTF ``COLOR_0`` and factors, and MTL colours, are linear. A per-face colour gives each
    face three vertices of its own (faces keep their order).

    Textures are drawn (``softrast.Texture``; details in docs/file_formats.md): glTF
    ``baseColorTexture``, ``emissiveTexture``, ``normalTexture`` (its ``scale``),
    ``metallicRoughnessTexture`` and ``occlusionTexture`` (its ``strength``), each with its
    sampler's filter and wraps; MTL ``map_Kd``, ``map_Ke``, ``map_Ks`` (read by "phong" and
    "blinn_phong"), ``norm`` (``-bm``: normal scale) and ``map_Bump`` / ``bump`` height maps
    (``-bm``: bump scale; an RGB one that looks like a normal map is drawn as the normal map, with
    a warning; next to a ``norm`` map a height map is kept but the normal map is drawn, with a
    warning). Transparency is drawn: glTF ``alphaMode`` MASK -> ``alpha_mode="mask"`` and BLEND
    -> ``alpha_mode="blend"``; MTL ``d`` < 1 (or, without ``d``, ``Tr`` strictly between 0 and 1,
    read as d = 1 - Tr; ``Tr 1``, Meshlab's opaque, stays opaque) -> ``alpha_mode="blend"`` with
    base colour alpha d.

    Parameters
    ----------
    path : str or os.PathLike
        The mesh file.
    smooth : bool or str, optional
        As for ``Mesh.from_trimesh``. STL files store no shared vertices: with ``smooth`` other
        than False, vertices at exactly the same position are merged first (as trimesh's
        ``merge_vertices``, without its rounding; faces keep their order, vertices are in order of
        first use), so the normals are smooth; ``smooth=False`` keeps the file's vertices.
    color : sequence of 3 or 4 floats, optional
        As for ``Mesh.from_trimesh``.
    up_axis : str, optional
        "y" (default): the file's axes are used as stored (softrast and glTF are y-up); "z": a
        z-up file (most CAD and STL exports, Blender's own axes) is turned y-up by mapping
        (x, y, z) -> (x, z, -y), positions and normals (a rotation about x, as Blender's glTF
        exporter does).

    Returns
    -------
    Mesh

    Raises
    ------
    FileNotFoundError
        If ``path`` (or a buffer or texture file a glTF references) does not exist.
    ValueError
        Naming the file, for every other failure: it cannot be parsed, holds no triangles, is
        truncated or disagrees with its own counts (PLY, OFF, STL, glTF; an OBJ or ASCII STL cut
        mid-line), has a face index out of range, or its header declares more data than
        ``softrast.get_memory_budget()`` (checked before parsing).

    Warns
    -----
    UserWarning
        If the parts have different materials: the mesh gets the first part's
        (``softrast.load_scene`` keeps each part's material). And naming the file, the material
        and what, for whatever softrast cannot draw yet, which is dropped: textures read through
        ``texCoord`` other than 0, ``KHR_texture_transform`` and other unknown extensions; MTL's
        other maps (``map_Ka``, ``map_Ns``, ``map_d``, ``disp``, ``decal``, ``refl``, the PBR maps)
        and map options other than ``-clamp`` and ``-bm``; textures that cannot be read, and every
        texture of a mesh without uvs.
    """
    path_str = os.fspath(path)
    if color is not None:
        _rgba(color, "color")  # a wrong argument names the argument, not the file
    _check_smooth(smooth)
    root = up_axis_matrix(up_axis)
    loaded, info = _load_trimesh(path_str)
    token = _LOADING_FILE.set(path_str)  # a PrecisionWarning then names the file
    try:
        with _keep_ctrl_c():
            return _mesh_of(mesh_part(loaded, smooth, info, root), color)
    except UserWarning:
        raise  # a warning made an error (-W error): it names the file already
    except Exception as exc:  # NaN vertices and the like: say which file they came from
        what = str(exc) if type(exc) is ValueError else f"{type(exc).__name__}: {exc}"
        raise ValueError(f"could not load mesh {path_str!r}: {what}") from exc
    finally:
        _LOADING_FILE.reset(token)


def load_scene(path: str | os.PathLike[str], smooth: bool | str = True, up_axis: str = "y") -> Scene:
    """Load a mesh file as a ``softrast.Scene``: one instance per part.

    Each part has its own Mesh and Material, placed by the file's node transforms (glTF nodes;
    identity for formats without a scene graph). Geometry that several nodes instance is one
    shared Mesh. Instance ids are 0, 1, 2, ... in the order of trimesh's scene graph
    (``graph.nodes_geometry``). Colours, materials and what is dropped (with a warning) are as
    described in docs/file_formats.md and ``load_mesh``.

    Parameters
    ----------
    path : str or os.PathLike
        The mesh file.
    smooth : bool or str, optional
        As for ``load_mesh``.
    up_axis : str, optional
        As for ``load_mesh``; "z" rotates every instance's pose, the meshes stay as stored.

    Returns
    -------
    Scene

    Raises
    ------
    FileNotFoundError
        For a missing file (or a buffer or texture a glTF references).
    ValueError
        Naming the file, for every other failure (as ``load_mesh``).
    """
    path_str = os.fspath(path)
    _check_smooth(smooth)
    root = up_axis_matrix(up_axis)
    loaded, info = _load_trimesh(path_str)
    token = _LOADING_FILE.set(path_str)
    try:
        scene = _scene_of(loaded, smooth, info, root)
        if not len(scene):
            raise _FileProblem("the file contains no triangles")
        return scene
    except UserWarning:
        raise  # a warning made an error (-W error): it names the file already
    except Exception as exc:
        what = str(exc) if type(exc) in (ValueError, _FileProblem) else f"{type(exc).__name__}: {exc}"
        raise ValueError(f"could not load mesh {path_str!r}: {what}") from exc
    finally:
        _LOADING_FILE.reset(token)
