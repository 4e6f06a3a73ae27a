"""The ``softrast`` console command (also ``python -m softrast``).

    softrast render MESH -o out.png [--size 640x480] [--depth out.exr] [--mask out.png]
                    [--normal out.exr] [--eye x,y,z] [--target x,y,z] [--up x,y,z] [--fov 45]
                    [--near N] [--far F] [--cull back|none|front]
                    [--shading auto|unlit|lambert|phong|blinn_phong|pbr|normal|uv]
                    [--frequency pixel|vertex|face] [--linear] [--threads N]

Without --eye the camera frames the whole mesh from the front (+z) and slightly above (+y).
Errors print one line to stderr and exit with status 2; Ctrl-C prints one line and exits 130.
"""
from __future__ import annotations

import argparse
import math
import sys
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


def _positive_float(text: str) -> float:
    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None
    if not math.isfinite(v) or v <= 0.0:
        raise argparse.ArgumentTypeError(f"must be positive and finite, got {text!r}")
    return v


def _threads(text: str) -> int:
    try:
        v = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected an integer, got {text!r}") from None
    if v < 0:
        raise argparse.ArgumentTypeError(f"must be >= 0 (0 = one per core), got {text!r}")
    return v


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(prog="softrast", description="softrast: a CPU software rasterizer.")
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
    return parser


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
    from .mesh import load_mesh
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
                            texture_filter=args.texture_filter)
    for name in outputs:
        imwrite(files[name], getattr(frame, name))


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
    except (CliError, OSError, ValueError, TypeError, RuntimeError) as exc:
        # RuntimeError: the system refused a worker thread (Renderer names `threads`).
        print(f"softrast: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:  # files are written atomically => nothing partial is left behind
        print("softrast: interrupted", file=sys.stderr)
        return 130  # 128 + SIGINT, as shells report it
    return 0
