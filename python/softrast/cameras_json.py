"""``cameras.json``: the cameras of a dataset, with K and poses in OpenCV's and OpenGL's axes
(``camera_record``, ``load_cameras``; written by ``write_dataset``)."""
from __future__ import annotations

import json
import os
from typing import Any, Sequence

import numpy as np

from . import _core
from .camera import Camera, IntrinsicsCamera, OrthographicCamera

__all__ = ["camera_record", "load_cameras"]


_GL_FROM_CV = np.diag([1.0, -1.0, -1.0, 1.0])


_OUTPUT_INDEX = {name: k for k, name in enumerate(_core.OUTPUTS)}


_FORMAT = "softrast cameras 1"


_CONVENTIONS = ("K: OpenCV, the centre of pixel (row i, col j) at (u, v) = (j, i). pose_opencv: "
                "camera-to-world, camera axes x right, y down, z forward; pose_opengl: the same "
                "pose with axes x right, y up, z backward (pyrender's, softrast's default). "
                "near, far: clipping distances along the viewing axis; depth images hold the "
                "distance along it.")


def camera_record(camera: Camera, width: int | None = None, height: int | None = None) -> dict[str, Any]:
    """The ``cameras.json`` entry of one camera (without ``stem`` and ``files``).

    Parameters
    ----------
    camera : Camera
    width, height : int, optional
        The image size; default: the camera's own.

    Returns
    -------
    dict
        ``width``, ``height``, ``near``, ``far``, ``orthographic``, ``K`` and ``dist`` (OpenCV's;
        None if orthographic or none), ``xmag`` and ``ymag`` (orthographic only), ``pose_opencv``
        and ``pose_opengl`` (docs/file_formats.md, "``cameras.json``").
    """
    w, h = camera._render_size(width, height)
    pose_cv = camera.pose @ _GL_FROM_CV if camera.convention == "opengl" else camera.pose
    pose_gl = pose_cv @ _GL_FROM_CV
    rec: dict[str, Any] = {"width": w, "height": h, "near": camera.near, "far": camera.far,
                           "orthographic": bool(camera.orthographic), "K": None, "dist": None,
                           "xmag": None, "ymag": None}
    if camera.orthographic:
        p = camera.projection_matrix(w, h)
        rec["xmag"], rec["ymag"] = 1.0 / p[0, 0], 1.0 / p[1, 1]
    else:
        rec["K"] = camera.intrinsics(w, h).tolist()
        dist = getattr(camera, "dist", None)
        rec["dist"] = None if dist is None else dist.tolist()
    rec["pose_opencv"] = pose_cv.tolist()
    rec["pose_opengl"] = pose_gl.tolist()
    return rec


def load_cameras(path: str | os.PathLike[str]) -> list[Camera]:
    """The cameras of a ``cameras.json``, in frame order.

    Parameters
    ----------
    path : str or os.PathLike
        A file, or the dataset directory holding one.

    Returns
    -------
    list of Camera
        ``IntrinsicsCamera(convention="opencv")`` from K (the same projection as the camera that
        rendered the frame, to float64 rounding) or ``OrthographicCamera``, posed, with the
        frame's image size, near and far.

    Raises
    ------
    ValueError
        Naming the file, for a file that is not a softrast cameras.json (not UTF-8 JSON, no
        ``frames`` list, a record that is not a camera).
    """
    p = os.fspath(path)
    if os.path.isdir(p):
        p = os.path.join(p, "cameras.json")
    with open(p, "rb") as f:
        data = f.read()
    try:
        doc = json.loads(data.decode("utf-8"))
    except UnicodeDecodeError as e:
        raise ValueError(f"{p}: not a softrast cameras.json (not UTF-8 text: {e})") from None
    except json.JSONDecodeError as e:
        raise ValueError(f"{p}: not a softrast cameras.json (invalid JSON: {e})") from None
    except RecursionError:
        raise ValueError(f"{p}: not a softrast cameras.json (JSON nested too deeply)") from None
    if not isinstance(doc, dict) or doc.get("format") != _FORMAT:
        raise ValueError(f"{p}: not a softrast cameras.json (format {_FORMAT!r})")
    frames = doc.get("frames")
    if not isinstance(frames, list):
        raise ValueError(f"{p}: \"frames\" must be a list of camera records, got "
                         f"{'nothing' if 'frames' not in doc else type(frames).__name__}")
    cams: list[Camera] = []
    for k, rec in enumerate(frames):
        try:
            if rec["orthographic"]:
                cam: Camera = OrthographicCamera(rec["xmag"], rec["ymag"], width=rec["width"],
                                                 height=rec["height"], near=rec["near"], far=rec["far"])
                cam.pose = np.asarray(rec["pose_opengl"], dtype=np.float64)
            else:
                K = np.asarray(rec["K"], dtype=np.float64)
                cam = IntrinsicsCamera(K[0, 0], K[1, 1], K[0, 2], K[1, 2], rec["width"], rec["height"],
                                       near=rec["near"], far=rec["far"], convention="opencv",
                                       dist=rec.get("dist"))
                cam.pose = np.asarray(rec["pose_opencv"], dtype=np.float64)
        except (KeyError, TypeError, ValueError, IndexError, RecursionError) as e:
            raise ValueError(f"{p}: frame {k} is not a valid camera record: {e!s:.200}") from None
        cams.append(cam)
    return cams


def _atomic_json(path: str, doc: Any) -> None:
    tmp = f"{path}.{os.getpid()}.tmp"
    with open(tmp, "w", encoding="utf-8") as f:
        json.dump(doc, f, indent=1)
    os.replace(tmp, path)


def _in_output_order(files: dict[str, str]) -> dict[str, str]:
    """``files`` ({output: path}) in one canonical order, softrast.OUTPUTS' (the order of
    Frame.save), whether a view was written now or found by resume."""
    return {n: files[n] for n in sorted(files, key=_OUTPUT_INDEX.__getitem__)}


def _write_cameras_json(directory: str, cams: Sequence[Camera], stems: Sequence[str],
                        paths: Sequence[dict[str, str]]) -> None:
    doc = {"format": _FORMAT, "conventions": _CONVENTIONS,
           "frames": [dict(camera_record(c), stem=stem,
                           files={n: _relative(p, directory)
                                  for n, p in _in_output_order(files).items()})
                      for c, stem, files in zip(cams, stems, paths)]}
    _atomic_json(os.path.join(directory, "cameras.json"), doc)


def _relative(path: str, directory: str) -> str:
    """``path`` (a file of the dataset, or a zarr store's ``views.zarr/color[12]``) relative to
    the dataset directory, with / between its parts, as cameras.json names it."""
    head = os.path.join(directory, "")
    rel = path[len(head):] if path.startswith(head) else os.path.relpath(path, directory)
    return rel.replace(os.sep, "/")
