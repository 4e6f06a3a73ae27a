"""Scenes: a flat list of mesh instances (each with a model-to-world pose, an id, a colour and a
material), the lights, and the ambient light."""
from __future__ import annotations

import itertools
from dataclasses import dataclass
from typing import Any, Callable, Iterator, Sequence, TypeVar

import numpy as np
import numpy.typing as npt

from ._checks import FLOAT32_MAX, affine_pose, flag, integer, real_array, unit_vector
from .files.context import FileInfo
from .files.convert import placements
from .light import Light
from .material import Material
from .mesh import Mesh, _check_smooth, _mesh_of, _rgba
from .primitives import Lines, Points

__all__ = ["Instance", "LightInstance", "PrimitiveInstance", "Scene"]

_ID_LIMIT = 2**31  # instance_id output is int32 (ids < 2**31); -1 is reserved for background

# Scene versions: every edit of any scene takes the next number (next() on a count is atomic, so
# two threads editing at once never get the same one, and no version is ever reused).
_VERSIONS = itertools.count(1)
_T = TypeVar("_T")


@dataclass(frozen=True)
class Instance:
    """One placement of a mesh in a scene.

    Attributes
    ----------
    mesh : Mesh
        The shared Mesh (its C++ upload is shared by every instance too).
    pose : ndarray, shape (4, 4), float64
        Model-to-world transform, read-only; may scale, last row [0, 0, 0, 1].
    instance_id : int
        In [0, 2**31), written to the "instance_id" output.
    color : tuple of 4 floats
        RGBA in [0, 1]: the ``color`` given to ``Scene.add``, else ``mesh.color``.
    material : Material or None
        The ``material`` given to ``Scene.add``, else ``mesh.material`` (may be None). A ``color``
        given to ``Scene.add`` replaces its base colour.
    """

    mesh: Mesh
    pose: npt.NDArray[np.float64]
    instance_id: int
    color: tuple[float, float, float, float]
    material: Material | None = None


@dataclass(frozen=True)
class PrimitiveInstance:
    """One placement of a ``Lines`` or ``Points`` object in a scene.

    Attributes
    ----------
    item : Lines or Points
    pose : ndarray, shape (4, 4), float64
        Model-to-world, read-only.
    instance_id : int
        Written to the "instance_id" output.
    """

    item: Lines | Points
    pose: npt.NDArray[np.float64]
    instance_id: int


@dataclass(frozen=True)
class LightInstance:
    """One light placed in a scene.

    Attributes
    ----------
    light : Light
    pose : ndarray, shape (4, 4), float64
        Light-to-world, or light-to-camera when ``camera_space``.
    camera_space : bool
        The light moves with the camera.
    """

    light: Light
    pose: npt.NDArray[np.float64]
    camera_space: bool = False


def _check_model_pose(pose: Any) -> npt.NDArray[np.float64]:
    return affine_pose(np.eye(4) if pose is None else pose)


class Scene:
    """An ordered collection of mesh instances, lines and points, and lights.

    The camera is a render argument, not part of the scene.

    Parameters
    ----------
    ambient_light : sequence of 3 floats, optional
        RGB >= 0 (linear, at most float32's 3.4e38), the ambient light ``Ia`` every lit model
        multiplies by ``ka``; None (default) => the render's ``ambient`` in a scene without lights
        (the headlight's ambient term) and 0 in a scene with lights.

    Raises
    ------
    ValueError
        For an ``ambient_light`` that is not 3 numbers in that range.
    """

    def __init__(self, ambient_light: Sequence[float] | None = None) -> None:
        self._instances: list[Instance] = []
        self._lights: list[LightInstance] = []
        self._primitives: list[PrimitiveInstance] = []  # lines and points, in the order added
        # What render.py derives from the scene for the core (draw and light records), kept
        # until the scene changes (see _cached): every change goes through _changed.
        self._render_cache: dict[Any, Any] = {}
        self._version = 0
        self.ambient_light = ambient_light  # checked by the property

    def _changed(self) -> None:
        """Called after every edit, once the scene holds its new state: a new version, and the
        records derived from the old one dropped."""
        self._version = next(_VERSIONS)
        self._render_cache.clear()

    def _cached(self, key: Any, build: Callable[[], _T]) -> _T:
        """``build()``, kept in the scene for ``key`` until it changes. Safe while another thread
        edits the scene: each entry is stored with the version read *before* ``build`` read the
        scene, and used only while that is still the scene's version, so records built from a
        state that an edit has since replaced are never used again (whenever they are stored)."""
        version = self.__dict__.get("_version", 0)  # (scenes pickled before versions)
        entry = self._render_cache.get(key)
        if entry is not None and entry[0] == version:
            return entry[1]
        value = build()
        self._render_cache[key] = (version, value)
        return value

    def __getstate__(self) -> dict[str, Any]:
        """Pickled without what renders derived from it (the core's records, rebuilt on use)."""
        state = self.__dict__.copy()
        state["_render_cache"] = {}
        return state

    @property
    def ambient_light(self) -> tuple[float, float, float] | None:
        """RGB ambient light (linear, >= 0), or None (see Scene); settable, checked as the constructor's."""
        return self._ambient_light

    @ambient_light.setter
    def ambient_light(self, value: Sequence[float] | None) -> None:
        if value is None:
            self._ambient_light = None
            self._changed()
            return
        arr = real_array(value, "ambient_light")
        if arr.shape != (3,):
            raise ValueError(f"ambient_light must be 3 numbers (RGB), got shape {arr.shape}")
        if not ((arr >= 0.0).all() and (arr <= FLOAT32_MAX).all()):  # NaN fails too
            raise ValueError(f"ambient_light must be >= 0 and at most {FLOAT32_MAX:.8g} (float32's "
                             f"range), got {arr.tolist()}")
        self._ambient_light = (float(arr[0]), float(arr[1]), float(arr[2]))
        self._changed()

    def add(self, item: Mesh | Light | Lines | Points, pose: npt.ArrayLike | None = None,
            instance_id: int | None = None, color: Sequence[float] | None = None,
            material: Material | None = None, camera_space: bool = False) -> int:
        """Add a mesh, a light, or lines or points placed by ``pose``.

        Lines and points (``softrast.Lines``, ``softrast.Points``) are drawn after the triangles,
        depth-tested against them, in the order added; they take ``pose`` and ``instance_id`` only.

        Parameters
        ----------
        item : Mesh, Light, Lines or Points
            What to add.
        pose : array_like, shape (4, 4), optional
            Model-to-world (light-to-world) transform (finite, last row [0, 0, 0, 1]); None =>
            identity. A light's pose must keep its z axis (the way it shines).
        instance_id : int, optional
            In [0, 2**31); None => the number of instances (meshes, lines and points) already in the
            scene. Ids need not be unique (several parts can share one object id). Not for lights.
        color : sequence of 3 or 4 floats, optional
            In [0, 1], overriding ``mesh.color`` (and the material's base colour); None =>
            ``mesh.color``. Meshes only.
        material : Material, optional
            A material for this instance, overriding ``mesh.material``. Meshes only.
        camera_space : bool, optional
            Lights only: ``pose`` is light-to-camera, so the light moves with the camera (a headlight,
            a flash).

        Returns
        -------
        int
            The instance id; for a light, its index among the scene's lights.

        Raises
        ------
        TypeError, ValueError
            For an item that is none of these, a bad pose or id, or an argument its item does not take.
        """
        if isinstance(item, Light):
            if instance_id is not None or color is not None or material is not None:
                raise ValueError("instance_id, color and material are for meshes, not lights")
            flag(camera_space, "camera_space")
            light_pose = _check_model_pose(pose)
            if unit_vector(light_pose[:3, 2]) is None:  # scaled: 1e-200 is a direction
                raise ValueError("pose: a light's pose must keep its z axis (the way it shines): "
                                 "its third column is zero")
            self._lights.append(LightInstance(item, light_pose, bool(camera_space)))
            self._changed()
            return len(self._lights) - 1
        if camera_space:
            raise ValueError("camera_space is for lights, not meshes")
        default_id = len(self._instances) + len(getattr(self, "_primitives", ()))
        if isinstance(item, (Lines, Points)):
            if color is not None or material is not None:
                raise ValueError("color and material are for meshes: give Lines / Points their "
                                 "own colors")
            model = _check_model_pose(pose)
            iid = default_id if instance_id is None else integer(instance_id, "instance_id")
            if not 0 <= iid < _ID_LIMIT:
                raise ValueError(f"instance_id must be in [0, 2**31), got {iid}")
            self.__dict__.setdefault("_primitives", []).append(  # (scenes pickled before lines)
                PrimitiveInstance(item, model, int(iid)))
            self._changed()
            return int(iid)
        mesh = item
        if material is not None and not isinstance(material, Material):
            raise TypeError(f"material must be a softrast.Material or None, got {type(material).__name__}")
        if not isinstance(mesh, Mesh):
            raise TypeError(f"mesh must be a softrast.Mesh, got {type(mesh).__name__} "
                            "(use softrast.Mesh.from_trimesh or softrast.load_mesh)")
        model = _check_model_pose(pose)
        iid = default_id if instance_id is None else integer(instance_id, "instance_id")
        if not 0 <= iid < _ID_LIMIT:
            raise ValueError(f"instance_id must be in [0, 2**31), got {iid}")
        mat = mesh.material if material is None else material
        if color is None:
            rgba = mesh.color if mat is None else mat.base_color
        else:
            rgba = _rgba(color, "color")
            if mat is not None:
                mat = mat.replace(base_color=rgba)
        self._instances.append(Instance(mesh, model, int(iid), rgba, mat))
        self._changed()
        return int(iid)

    @classmethod
    def from_trimesh(cls, tm: Any, smooth: bool | str = True, srgb_colors: bool = False) -> "Scene":
        """A Scene from a ``trimesh.Scene`` (or a ``trimesh.Trimesh``: one instance), keeping its parts.

        One instance per placement of each triangle geometry, in trimesh's graph order
        (``graph.nodes_geometry``), posed by the node's world transform, each with its own Mesh and
        Material (a geometry placed by several nodes is one shared Mesh). Instance ids are 0, 1, 2, ...
        Exactly what ``softrast.load_scene`` does with a loaded file, but with trimesh's values: its
        materials hold colours as 8 bits (``load_scene`` reads the file's exact values).

        Parameters
        ----------
        tm : trimesh.Scene or trimesh.Trimesh
            The geometry.
        smooth : bool or str, optional
            As for ``Mesh.from_trimesh``.
        srgb_colors : bool, optional
            As for ``Mesh.from_trimesh``.

        Returns
        -------
        Scene

        Raises
        ------
        ValueError
            If there is no triangle geometry.
        """
        _check_smooth(smooth)
        scene = _scene_of(tm, smooth, FileInfo(None, srgb=bool(srgb_colors)))
        if not len(scene):
            raise ValueError("tm holds no triangle geometry")
        return scene

    @property
    def lights(self) -> list[LightInstance]:
        """The lights in the order they were added (a copy of the list)."""
        return list(self._lights)

    @property
    def primitives(self) -> list[PrimitiveInstance]:
        """The lines and points in the order they were added (a copy of the list)."""
        return list(getattr(self, "_primitives", ()))

    @property
    def instances(self) -> list[Instance]:
        """The instances in the order they were added (a copy of the list)."""
        return list(self._instances)

    def __len__(self) -> int:
        return len(self._instances)

    def __iter__(self) -> Iterator[Instance]:
        return iter(list(self._instances))

    def _find(self, instance: Instance | PrimitiveInstance | int) -> tuple[list, int]:
        """(the list holding it, its position): ``instance`` is an Instance (a mesh's) or a
        PrimitiveInstance (lines' or points') of this scene, or an instance id that names exactly
        one of them."""
        primitives = self.__dict__.setdefault("_primitives", [])  # (scenes pickled before lines)
        if isinstance(instance, (Instance, PrimitiveInstance)):
            where = self._instances if isinstance(instance, Instance) else primitives
            for k, inst in enumerate(where):
                if inst is instance:
                    return where, k
            raise ValueError("instance is not in this scene (or was replaced: set_pose returns "
                             "the new Instance)")
        iid = integer(instance, "instance")
        found = [(where, k) for where in (self._instances, primitives)
                 for k, inst in enumerate(where) if inst.instance_id == iid]
        if not found:
            raise ValueError(f"instance: no instance has id {iid}")
        if len(found) > 1:
            raise ValueError(f"instance: id {iid} names {len(found)} instances; pass one of "
                             "scene.instances or scene.primitives instead")
        return found[0]

    def _index(self, instance: Instance | int) -> int:
        """The position of a mesh ``instance`` in ``scene.instances`` (see _find)."""
        where, k = self._find(instance)
        if where is not self._instances:
            raise ValueError("instance: that id names lines or points, not a mesh instance")
        return k

    def set_pose(self, instance: Instance | PrimitiveInstance | int,
                 pose: npt.ArrayLike) -> Instance | PrimitiveInstance:
        """Move one instance to ``pose``.

        Editing a scene between views costs less than rebuilding it.

        Parameters
        ----------
        instance : Instance, PrimitiveInstance or int
            An ``Instance`` of ``scene.instances``, a ``PrimitiveInstance`` of ``scene.primitives``, or
            a unique instance id.
        pose : array_like, shape (4, 4)
            Checked as ``add``'s.

        Returns
        -------
        Instance or PrimitiveInstance
            Its new instance (the scene keeps its place in the drawing order).

        Raises
        ------
        ValueError
            If the instance is not in the scene (or was replaced), or the id names none or several.
        """
        where, k = self._find(instance)
        model = _check_model_pose(pose)
        old = where[k]
        if isinstance(old, Instance):
            where[k] = Instance(old.mesh, model, old.instance_id, old.color, old.material)
        else:
            where[k] = PrimitiveInstance(old.item, model, old.instance_id)
        self._changed()
        return where[k]

    def remove(self, instance: Instance | PrimitiveInstance | int) -> Instance | PrimitiveInstance:
        """Remove one instance and return it.

        Parameters
        ----------
        instance : Instance, PrimitiveInstance or int
            An ``Instance``, a ``PrimitiveInstance``, or a unique instance id.

        Returns
        -------
        Instance or PrimitiveInstance
            The removed instance.

        Raises
        ------
        ValueError
            As ``set_pose``.
        """
        where, k = self._find(instance)
        removed = where.pop(k)
        self._changed()
        return removed

    def clear(self) -> None:
        """Remove every instance, line, point and light."""
        self._instances.clear()
        self._primitives = []
        self._lights.clear()
        self._changed()

    @property
    def bounds(self) -> npt.NDArray[np.float64]:
        """World-space AABB of every transformed vertex, of meshes, lines and points.

        Returns
        -------
        ndarray, shape (2, 3), float64
            Row 0 min, row 1 max.

        Raises
        ------
        ValueError
            For an empty scene.
        """
        posed = [(inst.mesh.positions, inst.pose) for inst in self._instances]
        posed += [(inst.item.positions, inst.pose) for inst in getattr(self, "_primitives", ())]
        if not posed:
            raise ValueError("scene is empty: it has no bounds")
        lo = np.full(3, np.inf)
        hi = np.full(3, -np.inf)
        for positions, pose in posed:
            if len(positions) == 0:
                continue
            p_world = positions.astype(np.float64) @ pose[:3, :3].T + pose[:3, 3]
            lo = np.minimum(lo, p_world.min(axis=0))
            hi = np.maximum(hi, p_world.max(axis=0))
        if not np.isfinite(lo).all():
            raise ValueError("scene is empty: it has no bounds")
        return np.stack([lo, hi])

    def __repr__(self) -> str:
        primitives = len(getattr(self, "_primitives", ()))
        extra = f", {primitives} lines/points" if primitives else ""
        return f"Scene({len(self._instances)} instances{extra}, {len(self._lights)} lights)"


def _scene_of(loaded: Any, smooth: bool | str, info: FileInfo, root: Any = None) -> Scene:
    """A Scene with one instance per placement of each triangle geometry of a trimesh.Scene or
    Trimesh (``files.convert.placements``), a geometry placed by several nodes one shared Mesh;
    ``root`` moves every pose. May be empty."""
    scene = Scene()
    for mesh, pose in placements(loaded, smooth, info, root, lambda part: _mesh_of(part, None)):
        scene.add(mesh, pose=pose)
    return scene
