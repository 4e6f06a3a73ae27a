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

The parts: ``_args`` (argument parsing), ``_views`` (the default camera, ``--poses`` and
``--intrinsics``, ``batch``'s summary line); ``main`` and the subcommands are here.
"""
from __future__ import annotations

import argparse
import os
import sys
import time
from typing import Sequence

import numpy as np

from .. import _core, report
from .._zarr_store import _blosc
from ..camera import IntrinsicsCamera, PerspectiveCamera
from ..dataset import write_dataset
from ..io import imwrite
from ..limits import _human, check_budget, get_memory_budget
from ..material import Material
from ..files.load import load_mesh
from ..poses import orbit, sphere_poses
from ..render import _OUTPUT_BYTES, Renderer
from ..scene import Scene
from ..texture import load_texture
from ._args import CliError, build_parser
from ._views import (_VIEW_BYTES, _load_intrinsics, _load_poses, _mesh_bytes, batch_summary,
                     frame_camera)

__all__ = ["main"]


def _render(args: argparse.Namespace) -> None:
    width, height = args.size
    if not 0.0 < args.fov < 180.0:
        raise CliError(f"--fov must be in (0, 180) degrees, got {args.fov}")
    mesh = load_mesh(args.mesh, up_axis=args.up_axis)
    scene = Scene()
    material = None
    if args.texture is not None:
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
    renderer = Renderer(width, height, threads=args.threads)
    frame = renderer.render(scene, camera, outputs=outputs, cull=args.cull, shading=args.shading,
                            frequency=args.frequency, srgb=not args.linear,
                            texture_filter=args.texture_filter, msaa=args.msaa, ssaa=args.ssaa,
                            wireframe=args.wireframe, line_color=args.line_color,
                            line_width=args.line_width)
    for name in outputs:
        imwrite(files[name], getattr(frame, name))


def _batch(args: argparse.Namespace) -> None:
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
