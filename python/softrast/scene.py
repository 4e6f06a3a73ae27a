"""Scenes: a flat list of mesh instances, each with a model-to-world pose, an id and a colour."""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Iterator, Sequence

import numpy as np
import numpy.typing as npt

from ._checks import affine_pose, integer
from .mesh import Mesh, _rgba

__all__ = ["Instance", "Scene"]

_ID_LIMIT = 2**31  # instance_id output is int32 (ids < 2**31); -1 is reserved for background


@dataclass(frozen=True)
class Instance:
    """One placement of a mesh in a scene.

    mesh : the shared Mesh (its C++ upload is shared by every instance too).
    pose : (4, 4) float64 model-to-world transform, read-only; may scale, last row [0, 0, 0, 1].
    instance_id : int in [0, 2**31), written to the "instance_id" output.
    color : RGBA floats in [0, 1]: the ``color`` given to ``Scene.add``, else ``mesh.color``.
    """

    mesh: Mesh
    pose: npt.NDArray[np.float64]
    instance_id: int
    color: tuple[float, float, float, float]


def _check_model_pose(pose: Any) -> npt.NDArray[np.float64]:
    return affine_pose(np.eye(4) if pose is None else pose)


class Scene:
    """An ordered collection of mesh instances (no cameras or lights: those are render arguments)."""

    def __init__(self) -> None:
        self._instances: list[Instance] = []

    def add(self, mesh: Mesh, pose: npt.ArrayLike | None = None, instance_id: int | None = None,
            color: Sequence[float] | None = None) -> int:
        """Add ``mesh`` placed by ``pose`` and return its instance id.

        pose : (4, 4) model-to-world transform (finite, last row [0, 0, 0, 1]); None => identity.
        instance_id : int in [0, 2**31); None => the number of instances already in the scene.
            Ids need not be unique (several parts can share one object id).
        color : 3 or 4 floats in [0, 1] overriding ``mesh.color``; None => ``mesh.color``.
        """
        if not isinstance(mesh, Mesh):
            raise TypeError(f"mesh must be a softrast.Mesh, got {type(mesh).__name__} "
                            "(use softrast.Mesh.from_trimesh or softrast.load_mesh)")
        model = _check_model_pose(pose)
        iid = len(self._instances) if instance_id is None else integer(instance_id, "instance_id")
        if not 0 <= iid < _ID_LIMIT:
            raise ValueError(f"instance_id must be in [0, 2**31), got {iid}")
        rgba = mesh.color if color is None else _rgba(color, "color")
        self._instances.append(Instance(mesh, model, int(iid), rgba))
        return int(iid)

    @property
    def instances(self) -> list[Instance]:
        """The instances in the order they were added (a copy of the list)."""
        return list(self._instances)

    def __len__(self) -> int:
        return len(self._instances)

    def __iter__(self) -> Iterator[Instance]:
        return iter(list(self._instances))

    def clear(self) -> None:
        """Remove every instance."""
        self._instances.clear()

    @property
    def bounds(self) -> npt.NDArray[np.float64]:
        """(2, 3) float64 world-space AABB (row 0 min, row 1 max) of every transformed vertex."""
        if not self._instances:
            raise ValueError("scene is empty: it has no bounds")
        lo = np.full(3, np.inf)
        hi = np.full(3, -np.inf)
        for inst in self._instances:
            p_world = inst.mesh.positions.astype(np.float64) @ inst.pose[:3, :3].T + inst.pose[:3, 3]
            lo = np.minimum(lo, p_world.min(axis=0))
            hi = np.maximum(hi, p_world.max(axis=0))
        return np.stack([lo, hi])

    def __repr__(self) -> str:
        return f"Scene({len(self._instances)} instances)"
