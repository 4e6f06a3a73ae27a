"""The ``softrast`` console command (also ``python -m softrast``).

    softrast render MESH -o out.png [--size 640x480] [--depth out.exr] [--mask out.png]
                    [--normal out.exr] [--eye x,y,z] [--target x,y,z] [--up x,y,z] [--fov 45]
                    [--near N] [--far F] [--cull back|none|front]
                    [--shading auto|unlit|lambert|phong|blinn_phong|pbr|normal|uv|depth]
                    [--frequency pixel|vertex|face] [--linear] [--threads N]

    softrast batch MESH [MESH ...] --out DIR [--views 24] [--orbit ELEVATION | --sphere |
                   --poses POSES.npy|.json] [--intrinsics K.npy] [--outputs color,depth,instance_id]
                   [--formats depth=npy,...] [--size 640x480] [--fov 45] [--workers W] [--no-resume]
                   [--store files|zarr]

    softrast report --out DIR [--quick]

    softrast --version

Without --eye the camera frames the whole mesh from the front (+z) and slightly above (+y).
``batch`` writes each mesh's views to DIR/<mesh file stem>/ with ``softrast.write_dataset``
(files, or with --store zarr one compressed array per output in views.zarr; cameras.json),
showing progress, and ends with a summary line; a rerun skips complete views, and the summary
counts them apart ("rendered 3 views of 1 mesh(es) in 1.2 s (2.5 frames/s), skipped 7 already
on disk; 1.4 s in all -> DIR": the rate over the rendered views alone).
Every argument, and every mesh file (each is loaded and checked first), is checked before
anything is written (the output folder included). A run holds about 8 KB a view (its camera and
file records) until its mesh is done, so --views (or --poses's count) is refused above the memory
budget's worth (softrast.limits) before any camera is made.
Errors print one line to stderr and exit with status 2; Ctrl-C prints one line and exits 130.
"""
from __future__ import annotations

import argparse
import math
import sys
import time
from typing import Sequence

import numpy as np

from . import _core

__all__ = ["main"]

_FRAME_MARGIN = 1.1  # the bounding sphere fills ~90% of the narrower field of view
_VIEW_DIRECTION = np.array([0.0, 0.25, 1.0])  # default eye: in front of the mesh, a little above


class CliError(Exception):
    """A user error: reported as one line on stderr, exit status 2."""


class _Parser(argparse.ArgumentParser):
    def error(self, message: str) -> None:  # type: ignore[override]
        raise CliError(message)  # argparse would print the usage block and sys.exit(2)


def _size(text: str) -> tuple[int, int]:
    parts = text.lower().split("x")
    try:
        w, h = (int(p) for p in parts)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected WIDTHxHEIGHT such as 640x480, got {text!r}") from None
    if w <= 0 or h <= 0:
        raise argparse.ArgumentTypeError(f"width and height must be positive, got {text!r}")
    return w, h


def _vec3(text: str) -> tuple[float, float, float]:
    try:
        x, y, z = (float(p) for p in text.split(","))
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected three comma-separated numbers x,y,z, got {text!r}") from None
    if not all(math.isfinite(v) for v in (x, y, z)):
        raise argparse.ArgumentTypeError(f"coordinates must be finite, got {text!r}")
    return x, y, z


def _rgb(text: str) -> tuple[float, float, float]:
    """r,g,b in [0, 1] (linear, as Material and render's colours)."""
    try:
        rgb = tuple(float(p) for p in text.split(","))
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected three comma-separated numbers r,g,b, got {text!r}") from None
    if len(rgb) != 3 or not all(0.0 <= v <= 1.0 for v in rgb):
        raise argparse.ArgumentTypeError(f"expected three numbers in [0, 1] as r,g,b, got {text!r}")
    return rgb


def _positive_float(text: str) -> float:
    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None
    if not math.isfinite(v) or v <= 0.0:
        raise argparse.ArgumentTypeError(f"must be positive and finite, got {text!r}")
    return v


def _int_at_least(minimum: int, note: str = ""):
    """An argparse type: an integer >= minimum."""
    def parse(text: str) -> int:
        try:
            v = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected an integer, got {text!r}") from None
        if v < minimum:
            raise argparse.ArgumentTypeError(f"must be >= {minimum}{note}, got {text!r}")
        return v
    return parse


_threads = _int_at_least(0, " (0 = one per core)")
_count = _int_at_least(1)


def build_parser() -> argparse.ArgumentParser:
    from . import __version__

    parser = _Parser(prog="softrast", description="softrast: a CPU software rasterizer.")
    parser.add_argument("--version", action="version", version=f"softrast {__version__}")
    sub = parser.add_subparsers(dest="command", required=True, parser_class=_Parser)
    r = sub.add_parser("render", help="render a mesh file to images",
                       description="Render a mesh file (OBJ, PLY, STL, GLB, ...) to image files.")
    r.add_argument("mesh", metavar="MESH", help="mesh file loaded with trimesh")
    r.add_argument("-o", "--output", required=True, metavar="COLOR",
                   help="colour image, (h, w, 3) uint8 (.png, .jpg, .tif, ...)")
    r.add_argument("--size", type=_size, default=(640, 480), metavar="WxH", help="image size (default 640x480)")
    r.add_argument("--depth", metavar="PATH", help="depth along the view axis, float32 (.exr or .tif); 0 = background")
    r.add_argument("--mask", metavar="PATH", help="coverage mask, 0/255 uint8 (.png)")
    r.add_argument("--normal", metavar="PATH", help="world-space unit normals, float32 (.exr or .tif)")
    r.add_argument("--eye", type=_vec3, metavar="x,y,z", help="camera position (default: frames the mesh)")
    r.add_argument("--target", type=_vec3, metavar="x,y,z", help="point looked at (default: bounds centre)")
    r.add_argument("--up-axis", choices=("y", "z"), default="y",
                   help="the file's up axis: z maps (x, y, z) to (x, z, -y) on loading (default y)")
    r.add_argument("--up", type=_vec3, default=(0.0, 1.0, 0.0), metavar="x,y,z", help="up direction (default 0,1,0)")
    r.add_argument("--fov", type=float, default=45.0, help="vertical field of view in degrees (default 45)")
    r.add_argument("--near", type=_positive_float, help="near plane distance (default: from the mesh size)")
    r.add_argument("--far", type=_positive_float, help="far plane distance (default: from the mesh size)")
    r.add_argument("--cull", choices=("back", "none", "front"), default="back", help="face culling (default back)")
    from .render import _SHADING

    r.add_argument("--shading", choices=_SHADING, default="auto",
                   help="shading model (default auto: each material's own, lambert without one)")
    r.add_argument("--frequency", choices=_core.FREQUENCIES, default="pixel",
                   help="where lighting is evaluated (default pixel)")
    r.add_argument("--linear", action="store_true",
                   help="write linear colour values (default: sRGB-encoded, as viewers expect)")
    r.add_argument("--threads", type=_threads, default=0, help="worker threads, 0 = one per core (default)")
    r.add_argument("--texture", metavar="IMAGE",
                   help="base colour texture (sRGB) sampled at the mesh's uvs; replaces the file's")
    r.add_argument("--texture-filter", choices=_core.TEXTURE_FILTERS, default=None,
                   help="one filter for every texture (default: each texture's own, trilinear)")
    r.add_argument("--wireframe", action="store_true",
                   help="draw the mesh's edges over it (front edges shown, back ones hidden)")
    r.add_argument("--line-color", type=_rgb, default=(0.0, 0.0, 0.0), metavar="r,g,b",
                   help="--wireframe's colour, linear, in [0, 1] (default 0,0,0)")
    r.add_argument("--line-width", type=_positive_float, default=1.0, metavar="PX",
                   help="--wireframe's width in pixels (default 1)")
    aa = r.add_mutually_exclusive_group()
    aa.add_argument("--msaa", type=int, choices=(1, 2, 4, 8, 16), default=1,
                    help="multisample anti-aliasing: samples per pixel (default 1: off)")
    aa.add_argument("--ssaa", type=int, choices=range(1, 9), default=1, metavar="K",
                    help="supersampling: a KxK grid of shaded samples per pixel, K in 1..8 (default 1)")

    b = sub.add_parser("batch", help="render many views of mesh files into a dataset",
                       description="Render views of each mesh file into DIR/<mesh stem>/: one file "
                       "per output and view ({view:06d}_{output}.{ext}, as Frame.save writes) and a "
                       "cameras.json (K in OpenCV's convention, poses in OpenCV and OpenGL axes); "
                       "with --store zarr, one compressed array per output in views.zarr instead "
                       "of the files. A rerun skips the views whose files are all there.")
    b.add_argument("meshes", nargs="+", metavar="MESH", help="mesh files (OBJ, PLY, GLB, ...)")
    b.add_argument("--out", required=True, metavar="DIR", help="dataset directory (created if missing)")
    b.add_argument("--views", type=_count, default=24, metavar="N", help="views per mesh (default 24)")
    where = b.add_mutually_exclusive_group()
    where.add_argument("--orbit", type=_elevation, default=None, metavar="ELEVATION",
                       help="a turntable at this elevation in degrees (the default, at 20)")
    where.add_argument("--sphere", action="store_true", help="views spread evenly over a sphere")
    where.add_argument("--poses", metavar="FILE", help="camera-to-world poses (OpenGL axes): an "
                       "(n, 4, 4) .npy, or a cameras.json; --views is then their number")
    b.add_argument("--intrinsics", metavar="K.npy", help="a (3, 3) OpenCV K for every view (default: --fov)")
    b.add_argument("--outputs", type=_outputs, default=("color", "depth", "instance_id"),
                   metavar="NAMES", help="comma-separated outputs (default color,depth,instance_id)")
    b.add_argument("--formats", type=_formats, default={}, metavar="NAME=FMT,...",
                   help="file formats by output, e.g. depth=npy,color=jpg (default: Frame.save's)")
    b.add_argument("--size", type=_size, default=(640, 480), metavar="WxH", help="image size (default 640x480)")
    b.add_argument("--fov", type=float, default=45.0, help="vertical field of view in degrees (default 45)")
    b.add_argument("--workers", type=_threads, default=0, help="render threads, 0 = one per core (default)")
    b.add_argument("--no-resume", action="store_true", help="render every view, even those already written")
    b.add_argument("--store", choices=("files", "zarr"), default="files",
                   help="files: a file per output and view (default); zarr: one chunked, "
                   "compressed array per output in DIR/<mesh stem>/views.zarr, a view a chunk "
                   "(pip install softrast[zarr])")
    b.add_argument("--up-axis", choices=("y", "z"), default="y", help="the files' up axis (default y)")

    rp = sub.add_parser("report", help="measure error against run time for each quality knob",
                        description="Sweep each quality knob (tessellation, shading frequency and "
                        "model, threads, texture filter, max_anisotropy) on reference scenes with exact "
                        "references, and write DIR/report.csv (long format), DIR/report.md and "
                        "DIR/error_vs_time.png. Needs matplotlib and scikit-image "
                        "(pip install softrast[report]).")
    rp.add_argument("--out", required=True, metavar="DIR", help="report directory (created if missing)")
    rp.add_argument("--quick", action="store_true",
                    help="fewer knob values and repetitions on 128x128 images: under a minute (CI)")
    return parser


def _elevation(text: str) -> float:
    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected degrees, got {text!r}") from None
    if not -90.0 <= v <= 90.0:
        raise argparse.ArgumentTypeError(f"must be in [-90, 90] degrees, got {text!r}")
    return v


def _outputs(text: str) -> tuple[str, ...]:
    names = tuple(n.strip() for n in text.split(",") if n.strip())
    bad = [n for n in names if n not in _core.OUTPUTS]
    if not names or bad:
        raise argparse.ArgumentTypeError(f"unknown output {bad[0] if bad else text!r}; choose from "
                                         f"{','.join(_core.OUTPUTS)}")
    return names


def _formats(text: str) -> dict[str, str]:
    from .frame import _SAVE_FORMATS

    out = {}
    for item in (t.strip() for t in text.split(",") if t.strip()):
        name, _, fmt = item.partition("=")
        if name not in _SAVE_FORMATS or fmt not in _SAVE_FORMATS[name]:
            raise argparse.ArgumentTypeError(
                f"{item!r}: expected OUTPUT=FORMAT with a format of that output "
                f"({name}: {'/'.join(_SAVE_FORMATS.get(name, ())) or 'no such output'})")
        out[name] = fmt
    return out


def frame_camera(bounds: np.ndarray, fov_y: float, width: int, height: int,
                 eye: Sequence[float] | None = None, target: Sequence[float] | None = None
                 ) -> tuple[np.ndarray, np.ndarray, float, float]:
    """Choose (eye, target, near, far) so the bounding sphere of ``bounds`` is in view.

    bounds : (2, 3) world-space AABB. fov_y : vertical field of view in degrees.
    Missing ``target`` => the bounds centre; missing ``eye`` => target + (0, 0.25, 1) * distance
    with the distance that fits the sphere in the narrower of the vertical / horizontal fov.
    near / far bracket the sphere as seen from the eye.
    """
    centre = bounds.mean(axis=0)
    radius = 0.5 * float(np.linalg.norm(bounds[1] - bounds[0]))
    if radius == 0.0:  # a single point => any scale works; pick one unit
        radius = 1.0
    target_w = centre if target is None else np.asarray(target, dtype=np.float64)
    if eye is None:
        half_fov_y = math.radians(fov_y) / 2.0
        half_fov_x = math.atan(math.tan(half_fov_y) * width / height)
        distance = _FRAME_MARGIN * radius / math.sin(min(half_fov_y, half_fov_x))
        eye_w = target_w + _VIEW_DIRECTION / np.linalg.norm(_VIEW_DIRECTION) * distance
    else:
        eye_w = np.asarray(eye, dtype=np.float64)
    to_centre = float(np.linalg.norm(centre - eye_w))
    # Outside the sphere => near just in front of it; inside => a small fraction of its size.
    near = max(0.9 * (to_centre - radius), 1e-3 * (to_centre + radius))
    far = 1.1 * (to_centre + radius)
    return eye_w, target_w, near, far


def _render(args: argparse.Namespace) -> None:
    import softrast as sr

    from .camera import PerspectiveCamera
    from .io import imwrite
    from .files.load import load_mesh
    from .scene import Scene

    width, height = args.size
    if not 0.0 < args.fov < 180.0:
        raise CliError(f"--fov must be in (0, 180) degrees, got {args.fov}")
    mesh = load_mesh(args.mesh, up_axis=args.up_axis)
    scene = Scene()
    material = None
    if args.texture is not None:
        from .material import Material
        from .texture import load_texture

        if mesh.uvs is None:
            raise CliError(f"--texture: {args.mesh} has no uvs (texture coordinates)")
        try:
            texture = load_texture(args.texture)
        except (OSError, ValueError) as e:
            raise CliError(f"--texture: {e}") from None
        material = (mesh.material.replace(base_color_texture=texture) if mesh.material is not None
                    else Material(base_color=(1.0, 1.0, 1.0), base_color_texture=texture,
                                  model="lambert"))
    scene.add(mesh, material=material)
    eye, target, near, far = frame_camera(scene.bounds, args.fov, width, height, args.eye, args.target)
    near = args.near if args.near is not None else near
    far = args.far if args.far is not None else far
    if far <= near:
        raise CliError(f"--far ({far:g}) must be greater than --near ({near:g})")
    camera = PerspectiveCamera(fov_y=args.fov, width=width, height=height, near=near, far=far)
    camera.look_at(eye, target, args.up)

    files = {"color": args.output, "depth": args.depth, "mask": args.mask, "normal": args.normal}
    outputs = tuple(name for name, path in files.items() if path is not None)
    renderer = sr.Renderer(width, height, threads=args.threads)
    frame = renderer.render(scene, camera, outputs=outputs, cull=args.cull, shading=args.shading,
                            frequency=args.frequency, srgb=not args.linear,
                            texture_filter=args.texture_filter, msaa=args.msaa, ssaa=args.ssaa,
                            wireframe=args.wireframe, line_color=args.line_color,
                            line_width=args.line_width)
    for name in outputs:
        imwrite(files[name], getattr(frame, name))


def batch_summary(rendered: int, skipped: int, meshes: int, render_seconds: float,
                  total_seconds: float, out: str) -> str:
    """``batch``'s last line: the views rendered, in the time rendering and writing them took
    (``write_dataset``'s ``seconds``) with the rate over them alone; the views a resumed run
    skipped as already on disk; the run's whole wall time (loading meshes, checking files)."""
    line = (f"softrast batch: rendered {rendered} view{'s' if rendered != 1 else ''} of {meshes} "
            f"mesh(es)")
    if rendered:
        line += f" in {render_seconds:.1f} s ({rendered / max(render_seconds, 1e-9):.1f} frames/s)"
    if skipped:
        line += f", skipped {skipped} already on disk"
    return f"{line}; {total_seconds:.1f} s in all -> {out}"


# What one view of a batch holds in memory until its mesh is done, an upper estimate: its camera
# (~0.7 KB), its file paths (~0.5 KB), its cameras.json record (~3 KB while the file is written),
# and write_dataset's lists. ``--views`` is checked against the memory budget with it before any
# camera is made (a billion views once grew to 24 GB before the kernel killed the process).
_VIEW_BYTES = 8 * 1024


def _mesh_bytes(mesh) -> int:
    """The bytes of a mesh's arrays (what keeping it loaded costs, textures aside)."""
    arrays = (mesh.positions, mesh.faces, mesh.normals, mesh.uvs, mesh.colors)
    return sum(int(a.nbytes) for a in arrays if a is not None)


def _load_poses(path: str) -> np.ndarray:
    """``--poses``: (n, 4, 4) camera-to-world poses (OpenGL axes), each checked as a camera pose,
    their number checked against the memory budget before they are read."""
    from .camera_base import _check_pose
    from .dataset import load_cameras
    from .limits import _human, get_memory_budget

    try:
        if path.endswith(".json"):
            poses = np.stack([c.view_matrix() for c in load_cameras(path)])
            poses = np.linalg.inv(poses)  # camera-to-world, OpenGL axes
        else:
            poses = np.load(path, mmap_mode="r", allow_pickle=False)  # the header only, so far
    except (OSError, ValueError) as e:
        raise CliError(f"--poses: {e}") from None
    if not isinstance(poses, np.ndarray) or poses.dtype.kind not in "iuf":
        raise CliError(f"--poses: expected an array of numbers, got {getattr(poses, 'dtype', type(poses))}")
    if poses.ndim != 3 or poses.shape[1:] != (4, 4) or poses.shape[0] == 0:
        raise CliError(f"--poses: expected (n, 4, 4) camera-to-world poses with n >= 1, got shape "
                       f"{poses.shape}")
    if poses.shape[0] * _VIEW_BYTES > get_memory_budget():  # before they are read
        raise CliError(f"--poses: {poses.shape[0]} views need about "
                       f"{_human(poses.shape[0] * _VIEW_BYTES)} for their cameras and file records, "
                       f"more than the memory budget of {_human(get_memory_budget())}: at most "
                       f"{get_memory_budget() // _VIEW_BYTES} views a run (split the poses)")
    poses = np.array(poses, dtype=np.float64)
    for k, pose in enumerate(poses):
        try:
            _check_pose(pose)
        except ValueError as e:
            raise CliError(f"--poses: pose {k}: {e}") from None
    return poses


def _load_intrinsics(path: str, width: int, height: int) -> np.ndarray:
    """``--intrinsics``: a (3, 3) OpenCV K, [[fx, 0, cx], [0, fy, cy], [0, 0, 1]], fx, fy > 0."""
    from .camera import IntrinsicsCamera

    try:
        K = np.load(path, allow_pickle=False)
    except (OSError, ValueError) as e:
        raise CliError(f"--intrinsics: {e}") from None
    if not isinstance(K, np.ndarray) or K.dtype.kind not in "iuf" or K.shape != (3, 3) \
            or not np.isfinite(K).all():
        raise CliError(f"--intrinsics: expected a finite (3, 3) K of numbers, got "
                       f"{getattr(K, 'shape', type(K).__name__)}")
    K = K.astype(np.float64)
    if K[0, 1] != 0.0 or K[1, 0] != 0.0 or K[2, 0] != 0.0 or K[2, 1] != 0.0 or K[2, 2] != 1.0:
        raise CliError(f"--intrinsics: K must be [[fx, 0, cx], [0, fy, cy], [0, 0, 1]] (no skew), "
                       f"got {K.tolist()}")
    try:
        IntrinsicsCamera(K[0, 0], K[1, 1], K[0, 2], K[1, 2], width, height, convention="opencv")
    except ValueError as e:
        raise CliError(f"--intrinsics: {e}") from None
    return K


def _batch(args: argparse.Namespace) -> None:
    import os

    from .camera import IntrinsicsCamera, PerspectiveCamera
    from .dataset import write_dataset
    from .limits import _human, check_budget, get_memory_budget
    from .files.load import load_mesh
    from .poses import orbit, sphere_poses
    from .render import _OUTPUT_BYTES, Renderer
    from .scene import Scene

    width, height = args.size
    # Everything is checked before anything is written: the arguments, then every mesh file.
    if not (1 <= width <= _core.MAX_IMAGE_SIDE and 1 <= height <= _core.MAX_IMAGE_SIDE):
        raise CliError(f"--size: width and height must be in [1, {_core.MAX_IMAGE_SIDE}] pixels, "
                       f"got {width}x{height}")
    if args.workers > _core.MAX_THREADS:
        raise CliError(f"--workers must be in [0, {_core.MAX_THREADS}] (0 = one per core), got "
                       f"{args.workers}")
    if not 0.0 < args.fov < 180.0:
        raise CliError(f"--fov must be in (0, 180) degrees, got {args.fov}")
    for path in args.meshes:
        if not os.path.isfile(path):
            raise CliError(f"mesh file not found: {path}")
    stems = [os.path.splitext(os.path.basename(p))[0] for p in args.meshes]
    if len(set(stems)) != len(stems):
        raise CliError("two mesh files have the same name: their datasets would share a directory")
    if args.store == "zarr" and args.formats:
        raise CliError("--formats: for --store files only (zarr keeps each output in its own dtype)")
    if args.store == "zarr":
        from ._zarr_store import _blosc

        try:
            _blosc()
        except ImportError as e:
            raise CliError(f"--store zarr: {e}") from None
    for name, fmt in args.formats.items():
        if name not in args.outputs:
            raise CliError(f"--formats: {name} is not in --outputs ({','.join(args.outputs)})")
    frame_bytes = width * height * sum(_OUTPUT_BYTES[n] for n in args.outputs)
    try:
        check_budget(frame_bytes, f"--size {width}x{height} with --outputs {','.join(args.outputs)}")
    except ValueError as e:
        raise CliError(str(e)) from None
    poses = _load_poses(args.poses) if args.poses is not None else None
    K = _load_intrinsics(args.intrinsics, width, height) if args.intrinsics is not None else None
    views = len(poses) if poses is not None else args.views
    if views * _VIEW_BYTES > get_memory_budget():  # before any camera (or pose) is made
        raise CliError(f"--views {views}: {views} views need about {_human(views * _VIEW_BYTES)} "
                       f"for their cameras and file records ({_VIEW_BYTES} bytes a view), more "
                       f"than the memory budget of {_human(get_memory_budget())}: at most "
                       f"{get_memory_budget() // _VIEW_BYTES} views a run (split the poses into "
                       "several runs with --poses)")

    def cameras(bounds: np.ndarray, count: int) -> list:
        """The first ``count`` views' cameras for a mesh with these bounds."""
        eye, target, near, far = frame_camera(bounds, args.fov, width, height)
        radius = float(np.linalg.norm(eye - target))
        if poses is not None:
            view_poses = poses[:count]
        elif args.sphere:
            view_poses = sphere_poses(target, radius, args.views)[:count]
        else:
            view_poses = orbit(target, radius, args.views,
                               elevation=20.0 if args.orbit is None else args.orbit)[:count]
        near = min(near, 1e-3 * radius) if poses is not None else near
        far = max(far, 10.0 * radius) if poses is not None else far
        cams = []
        for pose in view_poses:
            if K is not None:
                cam = IntrinsicsCamera(K[0, 0], K[1, 1], K[0, 2], K[1, 2], width, height, near=near,
                                       far=far, convention="opencv")
                cam.pose = pose @ np.diag([1.0, -1.0, -1.0, 1.0])  # OpenGL axes -> OpenCV's
            else:
                cam = PerspectiveCamera(fov_y=args.fov, width=width, height=height, near=near, far=far)
                cam.pose = pose
            cams.append(cam)
        return cams

    start = time.perf_counter()  # the summary's time "in all" includes loading the meshes
    # Every mesh is loaded and checked (and its first camera made) before anything is written;
    # the meshes stay loaded while they fit in half the memory budget, the others are loaded
    # again in their turn.
    loaded: list = []
    kept = 0
    for path in args.meshes:
        try:
            mesh = load_mesh(path, up_axis=args.up_axis)
            scene = Scene()
            scene.add(mesh, instance_id=0)
            bounds = scene.bounds
            cameras(bounds, 1)
        except (OSError, ValueError) as e:
            raise CliError(str(e) if path in str(e) else f"{path}: {e}") from None
        size = _mesh_bytes(mesh)
        keep = kept + size <= get_memory_budget() // 2
        kept += size if keep else 0
        loaded.append((scene if keep else None, bounds))
    renderer = Renderer(width, height, threads=args.workers)

    try:
        os.makedirs(args.out, exist_ok=True)
    except OSError as e:
        raise CliError(f"--out: {e}") from None
    rendered = skipped = 0
    render_seconds = 0.0
    for k, (path, stem) in enumerate(zip(args.meshes, stems)):
        scene, bounds = loaded[k]
        loaded[k] = None  # a mesh is let go once its views are written
        if scene is None:
            scene = Scene()
            scene.add(load_mesh(path, up_axis=args.up_axis), instance_id=0)
        cams = cameras(bounds, views)
        directory = os.path.join(args.out, stem)
        os.makedirs(directory, exist_ok=True)
        written = write_dataset(scene, cams, directory, outputs=args.outputs, formats=args.formats,
                                renderer=renderer, progress=True, resume=not args.no_resume,
                                store=args.store)
        del scene, cams
        rendered, skipped = rendered + written.rendered, skipped + written.skipped
        render_seconds += written.seconds
    print(batch_summary(rendered, skipped, len(args.meshes), render_seconds,
                        time.perf_counter() - start, args.out))


def _report(args: argparse.Namespace) -> None:
    from . import report

    start = time.perf_counter()
    try:
        paths = report.run(args.out, quick=args.quick,
                           log=lambda message: print(f"softrast report: {message}", flush=True))
    except ImportError as e:  # matplotlib or scikit-image missing: the message names it
        raise CliError(str(e)) from None
    print(f"softrast report: {'quick' if args.quick else 'full'} sweep in "
          f"{time.perf_counter() - start:.1f} s -> {', '.join(paths.values())}")


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command line; returns the exit status (0 ok, 2 error, 130 interrupted)."""
    parser = build_parser()
    try:
        args = parser.parse_args(argv)
    except CliError as exc:
        print(f"softrast: error: {exc}", file=sys.stderr)
        return 2
    except SystemExit as exc:  # --help / --version
        return int(exc.code or 0)
    try:
        if args.command == "render":
            _render(args)
        elif args.command == "batch":
            _batch(args)
        elif args.command == "report":
            _report(args)
    except (CliError, OSError, ValueError, TypeError, RuntimeError) as exc:
        # RuntimeError: the system refused a worker thread (Renderer names `threads`).
        print(f"softrast: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:  # files are written atomically => nothing partial is left behind
        print("softrast: interrupted", file=sys.stderr)
        return 130  # 128 + SIGINT, as shells report it
    return 0
